//! `goniospec study`: sweeps rays, bucket resolution, estimator, beamlet radius, backend
//! and representation for one sample, and measures each point's wall time, rays, peak
//! memory, error against the best available reference (the analytic TMM for `[stack]`
//! samples, else a high-budget run) and BRDF query time. Writes a CSV and a `report.md`.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Deserialize;

use crate::accel::Backend;
use crate::accumulate::file::Accumulator;
use crate::accumulate::{Buckets, Coherence};
use crate::brdf::{Brdf, BucketData, Representation, dir};
use crate::optics::tmm;
use crate::sample::{self, MeshOptions, Sample};
use crate::simulate::{SimConfig, Wavelengths, simulate};
use crate::trace::TraceLimits;

#[derive(Deserialize, Debug, Clone)]
#[serde(deny_unknown_fields)]
struct StudyFile {
    study: Header,
    sweep: Sweep,
    area: Option<AreaSweep>,
}

/// The seed's experiment: the sample tiled `k x k` with rays in proportion, per estimator.
#[derive(Deserialize, Debug, Clone)]
#[serde(deny_unknown_fields)]
pub struct AreaSweep {
    pub tiles: Vec<usize>,
    /// Rays per direction at one tile (scaled by k^2).
    pub rays: u64,
    #[serde(default = "all_estimators")]
    pub coherence: Vec<String>,
}

fn all_estimators() -> Vec<String> {
    vec!["beamlet".into(), "bucket".into(), "global".into()]
}

#[derive(Deserialize, Debug, Clone)]
#[serde(deny_unknown_fields)]
struct Header {
    name: String,
    /// The sample, relative to the study file.
    sample: String,
    theta_i: Vec<f64>,
    /// Bin edges `A:B:STEP` (nm).
    wavelengths: String,
    #[serde(default = "default_reference_rays")]
    reference_rays: u64,
    #[serde(default = "default_seed")]
    seed: u64,
    /// "r2" (low-discrepancy entry points, the default) or "random" (plain Monte Carlo).
    #[serde(default = "default_sampling")]
    sampling: String,
    /// Independent repetitions (seeds) per point; the error is their RMS.
    #[serde(default = "default_repeats")]
    repeats: u64,
}

fn default_repeats() -> u64 {
    1
}

fn default_sampling() -> String {
    "r2".into()
}

fn default_reference_rays() -> u64 {
    65_536
}
fn default_seed() -> u64 {
    1
}

#[derive(Deserialize, Debug, Clone)]
#[serde(deny_unknown_fields)]
struct Sweep {
    rays: Vec<u64>,
    #[serde(default = "default_theta_bins")]
    theta_o_bins: Vec<u32>,
    #[serde(default = "default_coherence")]
    coherence: Vec<String>,
    #[serde(default = "default_radius")]
    coherence_radius_nm: Vec<f64>,
    #[serde(default = "default_backend")]
    backend: Vec<String>,
    #[serde(default = "default_repr")]
    representation: Vec<String>,
}

fn default_theta_bins() -> Vec<u32> {
    vec![45]
}
fn default_coherence() -> Vec<String> {
    vec!["beamlet".into()]
}
fn default_radius() -> Vec<f64> {
    vec![5000.0]
}
fn default_backend() -> Vec<String> {
    vec![Backend::default_available().name().into()]
}
fn default_repr() -> Vec<String> {
    vec!["table".into()]
}

/// A parsed, validated study.
#[derive(Debug, Clone)]
pub struct Study {
    pub name: String,
    pub sample_path: PathBuf,
    pub theta_i: Vec<f64>,
    pub edges: Vec<f64>,
    pub reference_rays: u64,
    pub seed: u64,
    pub random_entry: bool,
    pub repeats: u64,
    pub rays: Vec<u64>,
    pub theta_o_bins: Vec<u32>,
    pub coherence: Vec<Coherence>,
    pub radius: Vec<f64>,
    pub backend: Vec<Backend>,
    pub representation: Vec<String>,
    pub area: Option<AreaSweep>,
}

/// One row of the sampled-area experiment.
#[derive(Clone, Debug)]
pub struct AreaPoint {
    pub coherence: Coherence,
    pub tiles: usize,
    pub area_um2: f64,
    pub rays: u64,
    /// Directional reflectance averaged over incident angles and bins.
    pub r: f64,
}

/// Runs the sampled-area experiment of a study (empty when it has none).
pub fn run_area(st: &Study, mut log: impl FnMut(&str)) -> Result<Vec<AreaPoint>, String> {
    let Some(a) = &st.area else {
        return Ok(Vec::new());
    };
    let sample: Sample =
        sample::load(&st.sample_path, MeshOptions::default()).map_err(|e| e.to_string())?;
    let mut out = Vec::new();
    for name in &a.coherence {
        let coherence =
            Coherence::parse(name).ok_or_else(|| format!("unknown coherence '{name}'"))?;
        for &k in &a.tiles {
            let big = sample.tiled(k);
            let rays = a.rays * (k * k) as u64;
            let cfg = config(
                st,
                rays,
                st.theta_o_bins[0],
                coherence,
                st.radius[0],
                st.backend[0],
                st.seed,
            );
            let (acc, _) = simulate(&big, &cfg, &|_| {}).map_err(|e| e.to_string())?;
            let rt = r_table(&acc);
            let r =
                rt.iter().flatten().sum::<f64>() / rt.iter().map(|v| v.len()).sum::<usize>() as f64;
            log(&format!(
                "area {k}x{k}: {} with {rays} rays: R = {r:.4e}",
                coherence.name()
            ));
            out.push(AreaPoint {
                coherence,
                tiles: k,
                area_um2: big.tile_nm[0] * big.tile_nm[1] * 1e-6,
                rays,
                r,
            });
        }
    }
    Ok(out)
}

/// Writes `area.csv` and the chart of total reflectance against sampled area.
pub fn write_area(points: &[AreaPoint], dir: &Path) -> Result<Vec<PathBuf>, String> {
    use plotters::prelude::*;
    if points.is_empty() {
        return Ok(Vec::new());
    }
    std::fs::create_dir_all(dir).map_err(|e| e.to_string())?;
    crate::io::write_atomic(&dir.join("area.csv"), |w| {
        writeln!(w, "coherence,tiles,area_um2,rays,R")?;
        for p in points {
            writeln!(
                w,
                "{},{},{},{},{:.6e}",
                p.coherence.name(),
                p.tiles,
                p.area_um2,
                p.rays,
                p.r
            )?;
        }
        Ok(())
    })
    .map_err(|e| e.to_string())?;
    register_font();
    let mut names: Vec<&str> = points.iter().map(|p| p.coherence.name()).collect();
    names.dedup();
    let series: Vec<(String, Vec<(f64, f64)>)> = names
        .iter()
        .map(|n| {
            (
                n.to_string(),
                points
                    .iter()
                    .filter(|p| p.coherence.name() == *n)
                    .map(|p| (p.area_um2, p.r))
                    .collect(),
            )
        })
        .collect();
    let png = dir.join("reflectance-vs-area.png");
    let svg = dir.join("reflectance-vs-area.svg");
    let tmp_png = dir.join(format!(
        ".reflectance-vs-area.tmp-{}.png",
        std::process::id()
    ));
    let title = "Total reflectance against sampled area (rays in proportion)";
    draw_chart(
        BitMapBackend::new(&tmp_png, (900, 600)).into_drawing_area(),
        title,
        "sampled area (um^2)",
        "total reflectance R",
        &series,
        None,
    )?;
    std::fs::rename(&tmp_png, &png).map_err(|e| e.to_string())?;
    let tmp_svg = crate::io::temp_path(&svg);
    draw_chart(
        SVGBackend::new(&tmp_svg, (900, 600)).into_drawing_area(),
        title,
        "sampled area (um^2)",
        "total reflectance R",
        &series,
        None,
    )?;
    std::fs::rename(&tmp_svg, &svg).map_err(|e| e.to_string())?;
    Ok(vec![png, svg])
}

/// One measured point.
#[derive(Clone, Debug)]
pub struct Point {
    pub rays: u64,
    pub theta_o_bins: u32,
    pub coherence: Coherence,
    pub radius: f64,
    pub backend: Backend,
    pub representation: String,
    pub wall_s: f64,
    pub traced_rays: u64,
    pub peak_mem_mb: f64,
    /// RMS over incident angles and bins of `R - R_reference`.
    pub error: f64,
    /// RMS of the point's own standard errors of R (its error bars; NaN-free: 0 when
    /// undefined).
    pub stderr: f64,
    pub query_ns: f64,
    /// RMS over incident angles and bins of the representation's hemispherical integral
    /// `integral f cos(theta_o) dw_o` against the reference reflectance.
    pub repr_error: f64,
}

/// Reads and validates a study file; errors name the file and line.
pub fn load(path: &Path) -> Result<Study, String> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| format!("{}: cannot read file: {e}", path.display()))?;
    let raw: StudyFile = toml::from_str(&text).map_err(|e| {
        let line = e.span().map(|s| crate::sample::line_of(&text, s.start));
        match line {
            Some(l) => format!(
                "{}:{l}: invalid study: {}",
                path.display(),
                e.message().trim()
            ),
            None => format!("{}: invalid study: {}", path.display(), e.message().trim()),
        }
    })?;
    let bad = |m: String| Err(format!("{}: {m}", path.display()));
    let sw = &raw.sweep;
    for (name, empty) in [
        ("rays", sw.rays.is_empty()),
        ("theta_o_bins", sw.theta_o_bins.is_empty()),
        ("coherence", sw.coherence.is_empty()),
        ("coherence_radius_nm", sw.coherence_radius_nm.is_empty()),
        ("backend", sw.backend.is_empty()),
        ("representation", sw.representation.is_empty()),
    ] {
        if empty {
            return bad(format!("[sweep] {name} is empty: give at least one value"));
        }
    }
    if raw.study.theta_i.is_empty() {
        return bad("[study] theta_i is empty".into());
    }
    if sw.rays.contains(&0) {
        return bad("[sweep] rays must be positive".into());
    }
    let coherence = sw
        .coherence
        .iter()
        .map(|c| {
            Coherence::parse(c).ok_or_else(|| {
                format!(
                    "{}: unknown coherence '{c}' (beamlet, bucket or global)",
                    path.display()
                )
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    let backend = sw
        .backend
        .iter()
        .map(|b| {
            b.parse::<Backend>()
                .map_err(|e| format!("{}: {e}", path.display()))
        })
        .collect::<Result<Vec<_>, _>>()?;
    if let Some(b) = backend.iter().find(|b| !b.is_available()) {
        return bad(format!("backend {b} is not available in this build"));
    }
    if let Some(r) = sw
        .representation
        .iter()
        .find(|r| !["kdtree", "subdivided", "table"].contains(&r.as_str()))
    {
        return bad(format!(
            "unknown representation '{r}' (kdtree, subdivided or table)"
        ));
    }
    let w = &raw.study.wavelengths;
    let parts: Vec<f64> = w
        .split(':')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("{}: wavelengths '{w}' must be A:B:STEP", path.display()))?;
    if parts.len() != 3 || parts[2] <= 0.0 || parts[1] <= parts[0] {
        return bad(format!(
            "wavelengths '{w}' must be A:B:STEP with A < B and STEP > 0"
        ));
    }
    let n = ((parts[1] - parts[0]) / parts[2]).round() as usize;
    let random_entry = match raw.study.sampling.as_str() {
        "r2" => false,
        "random" => true,
        other => return bad(format!("sampling '{other}' must be \"r2\" or \"random\"")),
    };
    Ok(Study {
        name: raw.study.name,
        sample_path: path
            .parent()
            .unwrap_or(Path::new(""))
            .join(&raw.study.sample),
        theta_i: raw.study.theta_i,
        edges: (0..=n).map(|i| parts[0] + i as f64 * parts[2]).collect(),
        reference_rays: raw.study.reference_rays,
        seed: raw.study.seed,
        random_entry,
        repeats: raw.study.repeats.max(1),
        rays: sw.rays.clone(),
        theta_o_bins: sw.theta_o_bins.clone(),
        coherence,
        radius: sw.coherence_radius_nm.clone(),
        backend,
        representation: sw.representation.clone(),
        area: match raw.area {
            Some(a) if a.tiles.is_empty() || a.tiles.contains(&0) => {
                return bad("[area] tiles must be a non-empty list of positive counts".into());
            }
            Some(a) if a.coherence.iter().any(|c| Coherence::parse(c).is_none()) => {
                return bad("[area] coherence must name beamlet, bucket or global".into());
            }
            other => other,
        },
    })
}

/// Peak resident memory of this process so far, MB (Linux `VmHWM`; 0 elsewhere).
fn peak_mem_mb() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse::<f64>().ok())
        })
        .map_or(0.0, |kb| kb / 1024.0)
}

fn config(
    st: &Study,
    rays: u64,
    bins: u32,
    coherence: Coherence,
    radius: f64,
    backend: Backend,
    seed: u64,
) -> SimConfig {
    SimConfig {
        theta_i_deg: st.theta_i.clone(),
        phi_i_deg: 0.0,
        rays,
        wavelengths: Wavelengths::Bins(st.edges.clone()),
        backend,
        seed,
        coherence,
        rho_nm: radius,
        limits: TraceLimits::default(),
        buckets: Buckets {
            theta_bins: bins,
            phi_bins: 36,
        },
        path_sharing: None,
        origin_nm: [0.0; 3],
        tolerance: None,
        max_rays: 0,
        random_entry: st.random_entry,
    }
}

/// Directional reflectance per (incident angle, bin) of an accumulator.
fn r_table(acc: &Accumulator) -> Vec<Vec<f64>> {
    let s = &acc.header.settings;
    (0..s.theta_i_deg.len())
        .map(|i| {
            (0..s.wavelength_count())
                .map(|j| acc.cell(i, j).totals(s.coherence_mode(), &s.buckets()).0)
                .collect()
        })
        .collect()
}

/// Runs the study; `log` receives progress lines.
pub fn run(st: &Study, mut log: impl FnMut(&str)) -> Result<(Vec<Point>, String), String> {
    let sample: Sample =
        sample::load(&st.sample_path, MeshOptions::default()).map_err(|e| e.to_string())?;
    // Reference: the bin-averaged TMM for a stack, else a high-budget beamlet run.
    let reference: Vec<Vec<f64>> = if sample.stack.is_some() {
        for &l in [st.edges[0], st.edges[st.edges.len() - 1]].iter() {
            tmm::stack_indices(&sample, l)?;
        }
        st.theta_i
            .iter()
            .map(|t| {
                st.edges
                    .windows(2)
                    .map(|w| {
                        tmm::solve_band(
                            |l| tmm::stack_indices(&sample, l).expect("range checked"),
                            w[0],
                            w[1],
                            t.to_radians(),
                        )
                        .r()
                    })
                    .collect()
            })
            .collect()
    } else {
        log(&format!(
            "reference: {} rays per direction",
            st.reference_rays
        ));
        // Low-discrepancy entry points for the reference whatever the study samples with:
        // its error falls about as 1/N, far below the points'.
        let mut cfg = config(
            st,
            st.reference_rays,
            st.theta_o_bins[0],
            Coherence::Beamlet,
            5000.0,
            st.backend[0],
            st.seed.wrapping_add(1_000_003),
        );
        cfg.random_entry = false;
        r_table(
            &simulate(&sample, &cfg, &|_| {})
                .map_err(|e| e.to_string())?
                .0,
        )
    };
    let reference_kind = if sample.stack.is_some() {
        "analytic TMM (bin-averaged)"
    } else {
        "high-budget beamlet run"
    };
    let mut points = Vec::new();
    for &backend in &st.backend {
        for &coherence in &st.coherence {
            for &radius in &st.radius {
                for &bins in &st.theta_o_bins {
                    for &rays in &st.rays {
                        let (mut e2, mut s2, mut n, mut wall) = (0.0, 0.0, 0.0, 0.0);
                        let mut last = None;
                        for rep in 0..st.repeats {
                            let cfg =
                                config(st, rays, bins, coherence, radius, backend, st.seed + rep);
                            let t0 = Instant::now();
                            let (acc, stats) =
                                simulate(&sample, &cfg, &|_| {}).map_err(|e| e.to_string())?;
                            wall += t0.elapsed().as_secs_f64() / st.repeats as f64;
                            let r = r_table(&acc);
                            for (i, row) in r.iter().enumerate() {
                                for (j, v) in row.iter().enumerate() {
                                    e2 += (v - reference[i][j]).powi(2);
                                    s2 += acc.cell(i, j).r_stderr(coherence).unwrap_or(0.0).powi(2);
                                    n += 1.0;
                                }
                            }
                            last = Some((acc, stats));
                        }
                        let (acc, stats) = last.expect("at least one repetition");
                        let data = BucketData::from_accumulator(&acc);
                        for repr in &st.representation {
                            let rep = match repr.as_str() {
                                "kdtree" => Representation::KdTree(
                                    crate::brdf::kdtree::KdTreeBrdf::build(&data, 4, true, false),
                                ),
                                "subdivided" => Representation::Subdivided(
                                    crate::brdf::subdivided::SubdividedBrdf::build(&data, 0.05),
                                ),
                                _ => Representation::Table(crate::brdf::table::TableBrdf::build(
                                    &data,
                                )),
                            };
                            let mut out = vec![0.0; data.wavelengths_nm.len()];
                            let q0 = Instant::now();
                            let m = 2000;
                            for k in 0..m {
                                let a = k as f64 / m as f64;
                                rep.eval(
                                    dir(1.2 * a, 0.0),
                                    dir(1.3 * (1.0 - a), 3.0 + a),
                                    &mut out,
                                );
                                std::hint::black_box(&out);
                            }
                            let query_ns = q0.elapsed().as_nanos() as f64 / m as f64;
                            let (mut re2, mut rn) = (0.0f64, 0.0f64);
                            for (i, t) in st.theta_i.iter().enumerate() {
                                let h = crate::brdf::hemispherical_reflectance(
                                    &rep,
                                    dir(t.to_radians(), 0.0),
                                    45,
                                    72,
                                );
                                for (j, v) in h.iter().enumerate() {
                                    re2 += (v - reference[i][j]).powi(2);
                                    rn += 1.0;
                                }
                            }
                            let p = Point {
                                rays,
                                theta_o_bins: bins,
                                coherence,
                                radius,
                                backend,
                                representation: repr.clone(),
                                wall_s: wall,
                                traced_rays: stats.traces,
                                peak_mem_mb: peak_mem_mb(),
                                error: (e2 / n).sqrt(),
                                stderr: (s2 / n).sqrt(),
                                query_ns,
                                repr_error: (re2 / rn).sqrt(),
                            };
                            log(&format!(
                                "{} {} rho {} bins {} rays {}: error {:.2e} (+- {:.1e}), {:.2} s, query {:.0} ns ({})",
                                backend,
                                coherence.name(),
                                radius,
                                bins,
                                rays,
                                p.error,
                                p.stderr,
                                wall,
                                query_ns,
                                repr
                            ));
                            points.push(p);
                        }
                    }
                }
            }
        }
    }
    Ok((points, reference_kind.to_string()))
}

/// Least-squares slope of log(error) against log(rays) over points with positive error.
pub fn convergence_slope(points: &[Point]) -> Option<f64> {
    let xy: Vec<(f64, f64)> = points
        .iter()
        .filter(|p| p.error > 0.0)
        .map(|p| ((p.rays as f64).ln(), p.error.ln()))
        .collect();
    if xy.len() < 2 {
        return None;
    }
    let n = xy.len() as f64;
    let (sx, sy) = (
        xy.iter().map(|p| p.0).sum::<f64>(),
        xy.iter().map(|p| p.1).sum::<f64>(),
    );
    let sxx = xy.iter().map(|p| p.0 * p.0).sum::<f64>();
    let sxy = xy.iter().map(|p| p.0 * p.1).sum::<f64>();
    Some((n * sxy - sx * sy) / (n * sxx - sx * sx))
}

/// Writes `points.csv` and `report.md` into `dir` (atomically each).
pub fn write(st: &Study, points: &[Point], reference: &str, dir: &Path) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    crate::io::write_atomic(&dir.join("points.csv"), |w| {
        writeln!(
            w,
            "backend,coherence,coherence_radius_nm,theta_o_bins,rays,representation,wall_s,traced_rays,peak_mem_mb,error,error_stderr,query_ns,repr_error"
        )?;
        for p in points {
            writeln!(
                w,
                "{},{},{},{},{},{},{:.4},{},{:.1},{:.6e},{:.6e},{:.0},{:.6e}",
                p.backend,
                p.coherence.name(),
                p.radius,
                p.theta_o_bins,
                p.rays,
                p.representation,
                p.wall_s,
                p.traced_rays,
                p.peak_mem_mb,
                p.error,
                p.stderr,
                p.query_ns,
                p.repr_error
            )?;
        }
        Ok(())
    })?;
    crate::io::write_atomic(&dir.join("report.md"), |w| {
        writeln!(w, "# Study: {}\n", st.name)?;
        writeln!(
            w,
            "Sample `{}`, incident angles {:?} deg, {} wavelength bins {}..{} nm.",
            st.sample_path.display(),
            st.theta_i,
            st.edges.len() - 1,
            st.edges[0],
            st.edges[st.edges.len() - 1]
        )?;
        writeln!(
            w,
            "Error: RMS over incident angles and bins of the directional reflectance against the {reference}.\n"
        )?;
        writeln!(
            w,
            "| backend | estimator | radius nm | theta bins | rays | representation | wall s | error | error bars | query ns | representation error |"
        )?;
        writeln!(w, "|---|---|---|---|---|---|---|---|---|---|---|")?;
        for p in points {
            writeln!(
                w,
                "| {} | {} | {} | {} | {} | {} | {:.3} | {:.2e} | {:.1e} | {:.0} | {:.2e} |",
                p.backend,
                p.coherence.name(),
                p.radius,
                p.theta_o_bins,
                p.rays,
                p.representation,
                p.wall_s,
                p.error,
                p.stderr,
                p.query_ns,
                p.repr_error
            )?;
        }
        // The Pareto front: points no faster point beats in error.
        let mut order: Vec<&Point> = points.iter().collect();
        order.sort_by(|a, b| {
            a.wall_s
                .total_cmp(&b.wall_s)
                .then(a.error.total_cmp(&b.error))
        });
        let mut best = f64::INFINITY;
        writeln!(
            w,
            "\nPareto front (each point is more accurate than every faster one):\n"
        )?;
        for p in order {
            if p.error < best {
                best = p.error;
                writeln!(
                    w,
                    "- {:.3} s: error {:.2e} with {} at {} rays",
                    p.wall_s,
                    p.error,
                    method(p),
                    p.rays
                )?;
            }
        }
        if let Some(s) = convergence_slope(points) {
            writeln!(
                w,
                "\nLeast-squares slope of log(error) against log(rays): {s:.3} (Monte Carlo: -0.5)."
            )?;
        }
        Ok(())
    })
}

/// A method: everything in a point but the ray count (one line per method in the charts).
fn method(p: &Point) -> String {
    let rho = if p.radius.is_infinite() {
        "inf".to_string()
    } else {
        format!("{}", p.radius)
    };
    format!(
        "{} rho={} bins={} {} {}",
        p.coherence.name(),
        rho,
        p.theta_o_bins,
        p.backend,
        p.representation
    )
}

/// Registers the embedded DejaVu Sans (the `dejavu` crate) once: no system font library.
fn register_font() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let _ = plotters::style::register_font(
            "sans-serif",
            plotters::style::FontStyle::Normal,
            dejavu::sans::regular(),
        );
    });
}

/// One log-log chart of `y` against `x` with a line per method, drawn on any backend.
fn draw_loglog<DB: plotters::prelude::DrawingBackend>(
    root: plotters::prelude::DrawingArea<DB, plotters::coord::Shift>,
    title: &str,
    xlabel: &str,
    series: &[(String, Vec<(f64, f64)>)],
    guide: Option<(&str, Vec<(f64, f64)>)>,
) -> Result<(), String> {
    draw_chart(
        root,
        title,
        xlabel,
        "error (RMS of R - reference)",
        series,
        guide,
    )
}

/// A log-log chart with a line per series and an optional guide line.
fn draw_chart<DB: plotters::prelude::DrawingBackend>(
    root: plotters::prelude::DrawingArea<DB, plotters::coord::Shift>,
    title: &str,
    xlabel: &str,
    ylabel: &str,
    series: &[(String, Vec<(f64, f64)>)],
    guide: Option<(&str, Vec<(f64, f64)>)>,
) -> Result<(), String> {
    use plotters::prelude::*;
    let err = |e: &dyn std::fmt::Display| e.to_string();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let all: Vec<(f64, f64)> = series
        .iter()
        .flat_map(|s| s.1.iter().copied())
        .chain(guide.iter().flat_map(|g| g.1.iter().copied()))
        .filter(|p| p.0 > 0.0 && p.1 > 0.0)
        .collect();
    if all.is_empty() {
        return Err("nothing to plot (no positive values)".into());
    }
    let (x0, x1) = all
        .iter()
        .fold((f64::MAX, f64::MIN), |a, p| (a.0.min(p.0), a.1.max(p.0)));
    let (y0, y1) = all
        .iter()
        .fold((f64::MAX, f64::MIN), |a, p| (a.0.min(p.1), a.1.max(p.1)));
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(
            (x0 / 1.5..x1 * 1.5).log_scale(),
            (y0 / 2.0..y1 * 2.0).log_scale(),
        )
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .x_desc(xlabel)
        .y_desc(ylabel)
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(|e| err(&e))?;
    for (i, (name, pts)) in series.iter().enumerate() {
        let colour = Palette99::pick(i).to_rgba();
        let pts: Vec<(f64, f64)> = pts
            .iter()
            .copied()
            .filter(|p| p.0 > 0.0 && p.1 > 0.0)
            .collect();
        chart
            .draw_series(LineSeries::new(pts.clone(), colour.stroke_width(2)))
            .map_err(|e| err(&e))?
            .label(name.clone())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(2))
            });
        chart
            .draw_series(pts.iter().map(|&p| Circle::new(p, 3, colour.filled())))
            .map_err(|e| err(&e))?;
    }
    if let Some((name, pts)) = guide {
        chart
            .draw_series(LineSeries::new(pts, BLACK.stroke_width(1)))
            .map_err(|e| err(&e))?
            .label(name.to_string())
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], BLACK));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font(("sans-serif", 13))
        .draw()
        .map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

/// Draws the charts as PNG and SVG into `dir`: error against time (the Pareto view) and
/// error against rays with the 1/sqrt(N) slope.
pub fn charts(points: &[Point], dir: &Path) -> Result<Vec<PathBuf>, String> {
    use plotters::prelude::*;
    register_font();
    let mut methods: Vec<String> = points.iter().map(method).collect();
    methods.dedup();
    methods.sort();
    methods.dedup();
    let series = |x: &dyn Fn(&Point) -> f64| -> Vec<(String, Vec<(f64, f64)>)> {
        methods
            .iter()
            .map(|m| {
                let mut v: Vec<(f64, f64)> = points
                    .iter()
                    .filter(|p| &method(p) == m)
                    .map(|p| (x(p), p.error))
                    .collect();
                v.sort_by(|a, b| a.0.total_cmp(&b.0));
                (m.clone(), v)
            })
            .collect()
    };
    let by_time = series(&|p| p.wall_s.max(1e-4));
    // Representations: query time against the error of their hemispherical integral.
    let mut reprs: Vec<&str> = points.iter().map(|p| p.representation.as_str()).collect();
    reprs.sort();
    reprs.dedup();
    let by_repr: Vec<(String, Vec<(f64, f64)>)> = reprs
        .iter()
        .map(|r| {
            let mut v: Vec<(f64, f64)> = points
                .iter()
                .filter(|p| p.representation == *r)
                .map(|p| (p.query_ns.max(1.0), p.repr_error.max(1e-12)))
                .collect();
            v.sort_by(|a, b| a.0.total_cmp(&b.0));
            (r.to_string(), v)
        })
        .collect();
    let by_rays = series(&|p| p.rays as f64);
    // The 1/sqrt(N) guide through the first method's first point.
    let guide = by_rays
        .first()
        .and_then(|s| s.1.first().copied())
        .map(|(n0, e0)| {
            let n1 = points.iter().map(|p| p.rays as f64).fold(n0, f64::max);
            ("1/sqrt(N)", vec![(n0, e0), (n1, e0 * (n0 / n1).sqrt())])
        });
    let mut written = Vec::new();
    for (stem, title, xlabel, data, g) in [
        (
            "error-vs-time",
            "Error against wall time (lower left is better)",
            "wall time (s)",
            &by_time,
            None,
        ),
        (
            "error-vs-rays",
            "Error against rays per direction",
            "rays per direction",
            &by_rays,
            guide.clone(),
        ),
        (
            "eval-time-vs-accuracy",
            "BRDF query time against the error of its hemispherical integral",
            "query time (ns)",
            &by_repr,
            None,
        ),
    ] {
        let png = dir.join(format!("{stem}.png"));
        let svg = dir.join(format!("{stem}.svg"));
        // The bitmap backend picks its format from the extension: keep ".png" last.
        let tmp_png = dir.join(format!(".{stem}.tmp-{}.png", std::process::id()));
        draw_loglog(
            BitMapBackend::new(&tmp_png, (900, 600)).into_drawing_area(),
            title,
            xlabel,
            data,
            g.clone(),
        )?;
        std::fs::rename(&tmp_png, &png).map_err(|e| e.to_string())?;
        let tmp_svg = crate::io::temp_path(&svg);
        draw_loglog(
            SVGBackend::new(&tmp_svg, (900, 600)).into_drawing_area(),
            title,
            xlabel,
            data,
            g,
        )?;
        std::fs::rename(&tmp_svg, &svg).map_err(|e| e.to_string())?;
        written.push(png);
        written.push(svg);
    }
    Ok(written)
}
