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
use crate::accumulate::{Buckets, Coherence, PhasePrecision};
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
    /// Tilings: `k` (k x k) or `[kx, ky]`.
    pub tiles: Vec<Tiling>,
    /// Rays per direction at one tile (scaled by k^2).
    pub rays: u64,
    #[serde(default = "all_estimators")]
    pub coherence: Vec<String>,
}

/// How often the sample repeats along x and y in the area experiment.
#[derive(Deserialize, Debug, Clone, Copy, PartialEq, Eq)]
#[serde(untagged)]
pub enum Tiling {
    Square(usize),
    Rect([usize; 2]),
}

impl Tiling {
    pub fn counts(self) -> [usize; 2] {
        match self {
            Tiling::Square(k) => [k, k],
            Tiling::Rect(k) => k,
        }
    }
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
    /// "auto" (the analytic TMM for `[stack]` samples, else a high-budget run),
    /// "local-film" (the tangent-plane film reference of curved and wedged films) or
    /// "run" (a high-budget beamlet run).
    #[serde(default = "default_reference")]
    reference: String,
    /// The largest error (absolute, in R) at which the report says a method holds
    /// (default 1e-3).
    #[serde(default = "default_tolerance")]
    tolerance: f64,
    /// What the study stresses, printed at the top of the report.
    #[serde(default)]
    notes: String,
}

fn default_tolerance() -> f64 {
    1e-3
}

fn default_reference() -> String {
    "auto".into()
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
    /// Power cutoff of the ray trees (fraction of launched power).
    #[serde(default = "default_cutoff")]
    cutoff: Vec<f64>,
    /// Depth limit of the ray trees (interactions).
    #[serde(default = "default_max_depth")]
    max_depth: Vec<u32>,
    /// Phase precision: "f64" or "f32".
    #[serde(default = "default_phase")]
    phase: Vec<String>,
    /// Where the sample sits in the world: offset (nm) along x and y of its frame.
    #[serde(default = "default_origin")]
    origin_nm: Vec<f64>,
}

fn default_cutoff() -> Vec<f64> {
    vec![TraceLimits::default().cutoff]
}
fn default_max_depth() -> Vec<u32> {
    vec![TraceLimits::default().max_depth]
}
fn default_phase() -> Vec<String> {
    vec!["f64".into()]
}
fn default_origin() -> Vec<f64> {
    vec![0.0]
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
    pub reference: ReferenceKind,
    pub tolerance: f64,
    pub notes: String,
    pub rays: Vec<u64>,
    /// Every combination of the swept settings other than rays and representation.
    pub variants: Vec<Variant>,
    pub representation: Vec<String>,
    pub area: Option<AreaSweep>,
}

/// What the errors are measured against.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReferenceKind {
    /// The analytic TMM for `[stack]` samples, else a high-budget run.
    Auto,
    /// [`crate::optics::local_film`].
    LocalFilm,
    /// A high-budget beamlet run with the default settings.
    Run,
}

/// One setting of everything a study sweeps except rays and representation (a line in
/// the charts).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Variant {
    pub backend: Backend,
    pub coherence: Coherence,
    /// Beamlet radius, nm.
    pub radius: f64,
    pub theta_o_bins: u32,
    pub cutoff: f64,
    pub max_depth: u32,
    pub precision: PhasePrecision,
    /// Offset of the sample's frame along x and y, nm.
    pub origin_nm: f64,
}

/// One row of the sampled-area experiment.
#[derive(Clone, Debug)]
pub struct AreaPoint {
    pub coherence: Coherence,
    /// Repeats along x and y.
    pub tiles: [usize; 2],
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
        for t in &a.tiles {
            let k = t.counts();
            let big = sample.tiled(k);
            let rays = a.rays * (k[0] * k[1]) as u64;
            let v = Variant {
                coherence,
                ..st.variants[0]
            };
            let cfg = config(st, rays, &v, st.seed);
            let (acc, _) = simulate(&big, &cfg, &|_| {}).map_err(|e| e.to_string())?;
            let rt = r_table(&acc);
            let r =
                rt.iter().flatten().sum::<f64>() / rt.iter().map(|v| v.len()).sum::<usize>() as f64;
            log(&format!(
                "area {}x{}: {} with {rays} rays: R = {r:.4e}",
                k[0],
                k[1],
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
                "{},{}x{},{},{},{:.6e}",
                p.coherence.name(),
                p.tiles[0],
                p.tiles[1],
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
    let title = "Total reflectance against sampled area (rays in proportion)";
    chart_file(&png, |tmp| {
        draw_chart(
            BitMapBackend::new(tmp, (900, 600)).into_drawing_area(),
            title,
            "sampled area (um^2)",
            "total reflectance R",
            &series,
            None,
        )
    })?;
    chart_file(&svg, |tmp| {
        draw_chart(
            SVGBackend::new(tmp, (900, 600)).into_drawing_area(),
            title,
            "sampled area (um^2)",
            "total reflectance R",
            &series,
            None,
        )
    })?;
    Ok(vec![png, svg])
}

/// One measured point.
#[derive(Clone, Debug)]
pub struct Point {
    pub variant: Variant,
    pub rays: u64,
    pub representation: String,
    pub wall_s: f64,
    pub traced_rays: u64,
    pub peak_mem_mb: f64,
    /// RMS over incident angles and bins of `R - R_reference`.
    pub error: f64,
    /// RMS of the point's own standard errors of R (its error bars; NaN-free: 0 when
    /// undefined).
    pub stderr: f64,
    /// Mean power dropped by the cutoff and limits per tree (fraction of launched power).
    pub dropped: f64,
    pub query_ns: f64,
    /// RMS over incident angles and bins of the representation's hemispherical integral
    /// `integral f cos(theta_o) dw_o` against the reference reflectance.
    pub repr_error: f64,
    /// Why a repetition's result was physically impossible (`simulate::check_physical`):
    /// such a point never holds, whatever its error.
    pub unphysical: Option<String>,
}

/// Reads and validates a study file; errors name the file and line.
pub fn load(path: &Path) -> Result<Study, String> {
    let text = crate::io::read_text(path)
        .map_err(|e| format!("{}: cannot read file: {e}", path.display()))?;
    parse(path, &text)
}

/// Parses and validates the text of a study file read from `path` (named in errors;
/// samples are resolved beside it).
pub fn parse(path: &Path, text: &str) -> Result<Study, String> {
    let raw: StudyFile = toml::from_str(text).map_err(|e| {
        let line = e.span().map(|s| crate::sample::line_of(text, s.start));
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
        ("cutoff", sw.cutoff.is_empty()),
        ("max_depth", sw.max_depth.is_empty()),
        ("phase", sw.phase.is_empty()),
        ("origin_nm", sw.origin_nm.is_empty()),
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
    if let Some(c) = sw
        .cutoff
        .iter()
        .find(|c| !(c.is_finite() && **c >= 0.0 && **c < 1.0))
    {
        return bad(format!("[sweep] cutoff {c} must lie in [0, 1)"));
    }
    if sw.max_depth.contains(&0) {
        return bad("[sweep] max_depth must be positive".into());
    }
    if let Some(r) = sw
        .coherence_radius_nm
        .iter()
        .find(|r| r.is_nan() || **r <= 0.0)
    {
        return bad(format!(
            "[sweep] coherence_radius_nm {r} must be positive (or inf)"
        ));
    }
    if let Some(o) = sw.origin_nm.iter().find(|o| !o.is_finite()) {
        return bad(format!("[sweep] origin_nm {o} must be finite"));
    }
    if sw.theta_o_bins.contains(&0) {
        return bad("[sweep] theta_o_bins must be positive".into());
    }
    let precision = sw
        .phase
        .iter()
        .map(|p| {
            PhasePrecision::parse(p).ok_or_else(|| {
                format!(
                    "{}: unknown phase precision '{p}' (f64 or f32)",
                    path.display()
                )
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    let reference = match raw.study.reference.as_str() {
        "auto" => ReferenceKind::Auto,
        "local-film" => ReferenceKind::LocalFilm,
        "run" => ReferenceKind::Run,
        other => {
            return bad(format!(
                "reference '{other}' must be \"auto\", \"local-film\" or \"run\""
            ));
        }
    };
    if !(raw.study.tolerance >= 0.0 && raw.study.tolerance.is_finite()) {
        return bad(format!(
            "[study] tolerance {} must be a non-negative number",
            raw.study.tolerance
        ));
    }
    if let Some(t) = raw.study.theta_i.iter().find(|t| !(0.0..90.0).contains(*t)) {
        return bad(format!("[study] theta_i {t} must lie in [0, 90) degrees"));
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
    let mut variants = Vec::new();
    for &backend in &backend {
        for &coherence in &coherence {
            // The beamlet radius only enters the beamlet estimator.
            let radii = if coherence == Coherence::Beamlet {
                &sw.coherence_radius_nm[..]
            } else {
                &sw.coherence_radius_nm[..1]
            };
            for &radius in radii {
                for &theta_o_bins in &sw.theta_o_bins {
                    for &cutoff in &sw.cutoff {
                        for &max_depth in &sw.max_depth {
                            for &precision in &precision {
                                for &origin_nm in &sw.origin_nm {
                                    variants.push(Variant {
                                        backend,
                                        coherence,
                                        radius,
                                        theta_o_bins,
                                        cutoff,
                                        max_depth,
                                        precision,
                                        origin_nm,
                                    });
                                }
                            }
                        }
                    }
                }
            }
        }
    }
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
        reference,
        tolerance: raw.study.tolerance,
        notes: raw.study.notes,
        rays: sw.rays.clone(),
        variants,
        representation: sw.representation.clone(),
        area: match raw.area {
            Some(a) if a.tiles.is_empty() || a.tiles.iter().any(|t| t.counts().contains(&0)) => {
                return bad("[area] tiles must be a non-empty list of positive counts".into());
            }
            Some(a) if a.coherence.iter().any(|c| Coherence::parse(c).is_none()) => {
                return bad("[area] coherence must name beamlet, bucket or global".into());
            }
            other => other,
        },
    })
}

/// Peak resident memory of this process so far, MB (0 where unknown).
fn peak_mem_mb() -> f64 {
    crate::io::peak_rss_mb().unwrap_or(0.0)
}

fn config(st: &Study, rays: u64, v: &Variant, seed: u64) -> SimConfig {
    SimConfig {
        backend: v.backend,
        seed,
        coherence: v.coherence,
        rho_nm: v.radius,
        limits: TraceLimits {
            cutoff: v.cutoff,
            max_depth: v.max_depth,
            ..TraceLimits::default()
        },
        buckets: Buckets {
            theta_bins: v.theta_o_bins,
            phi_bins: 36,
        },
        origin_nm: [v.origin_nm, v.origin_nm, 0.0],
        random_entry: st.random_entry,
        precision: v.precision,
        // The study compares methods, some of them known to fail (bucket, global, f32):
        // an impossible result is recorded as a failure of the point, not an abort.
        allow_unphysical: true,
        ..SimConfig::new(
            st.theta_i.clone(),
            Wavelengths::Bins(st.edges.clone()),
            rays,
        )
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

/// The reference reflectance per (incident angle, bin) and a description of it.
fn reference(
    st: &Study,
    sample: &Sample,
    log: &mut impl FnMut(&str),
) -> Result<(Vec<Vec<f64>>, String), String> {
    let kind = match st.reference {
        ReferenceKind::Auto if sample.stack.is_some() => "tmm",
        ReferenceKind::Auto | ReferenceKind::Run => "run",
        ReferenceKind::LocalFilm => "local-film",
    };
    match kind {
        "tmm" => {
            for &l in [st.edges[0], st.edges[st.edges.len() - 1]].iter() {
                tmm::stack_indices(sample, l)?;
            }
            let r = st
                .theta_i
                .iter()
                .map(|t| {
                    st.edges
                        .windows(2)
                        .map(|w| {
                            tmm::solve_band(
                                |l| tmm::stack_indices(sample, l).expect("range checked"),
                                w[0],
                                w[1],
                                t.to_radians(),
                            )
                            .r()
                        })
                        .collect()
                })
                .collect();
            Ok((r, "analytic TMM (bin-averaged)".into()))
        }
        "local-film" => {
            let entries = 48;
            let r = st
                .theta_i
                .iter()
                .map(|&t| crate::optics::local_film::reflectance(sample, t, &st.edges, entries))
                .collect::<Result<Vec<_>, _>>()?;
            Ok((
                r,
                format!(
                    "local-film (tangent-plane) TMM reference, {entries} x {entries} entry points"
                ),
            ))
        }
        _ => {
            log(&format!(
                "reference: {} rays per direction",
                st.reference_rays
            ));
            // Low-discrepancy entry points and default settings for the reference whatever
            // the study sweeps: its error falls about as 1/N, far below the points'.
            let v = Variant {
                coherence: Coherence::Beamlet,
                radius: 5000.0,
                cutoff: TraceLimits::default().cutoff,
                max_depth: TraceLimits::default().max_depth,
                precision: PhasePrecision::F64,
                origin_nm: 0.0,
                ..st.variants[0]
            };
            let mut cfg = config(st, st.reference_rays, &v, st.seed.wrapping_add(1_000_003));
            cfg.random_entry = false;
            let r = r_table(
                &simulate(sample, &cfg, &|_| {})
                    .map_err(|e| e.to_string())?
                    .0,
            );
            Ok((
                r,
                format!(
                    "high-budget beamlet run ({} rays per direction, radius 5 um)",
                    st.reference_rays
                ),
            ))
        }
    }
}

/// Runs the study; `log` receives progress lines.
pub fn run(st: &Study, mut log: impl FnMut(&str)) -> Result<(Vec<Point>, String), String> {
    let sample: Sample =
        sample::load(&st.sample_path, MeshOptions::default()).map_err(|e| e.to_string())?;
    let (reference, reference_kind) = reference(st, &sample, &mut log)?;
    let mut points = Vec::new();
    for v in &st.variants {
        for &rays in &st.rays {
            let (mut e2, mut s2, mut n, mut wall) = (0.0, 0.0, 0.0, 0.0);
            let (mut dropped, mut dn) = (0.0, 0.0);
            let mut last = None;
            let mut unphysical = None;
            for rep in 0..st.repeats {
                let cfg = config(st, rays, v, st.seed + rep);
                let t0 = Instant::now();
                let (acc, stats) = simulate(&sample, &cfg, &|_| {}).map_err(|e| e.to_string())?;
                wall += t0.elapsed().as_secs_f64() / st.repeats as f64;
                if let Err(e) =
                    crate::simulate::check_physical(&acc, &sample.name, Some(&stats.limit_dropped))
                {
                    unphysical.get_or_insert(e.to_string());
                }
                let r = r_table(&acc);
                for (i, row) in r.iter().enumerate() {
                    for (j, x) in row.iter().enumerate() {
                        let c = acc.cell(i, j);
                        e2 += (x - reference[i][j]).powi(2);
                        s2 += c.r_stderr(v.coherence).unwrap_or(0.0).powi(2);
                        n += 1.0;
                        dropped += c.dropped / c.trees.max(1) as f64;
                        dn += 1.0;
                    }
                }
                last = Some((acc, stats));
            }
            let (acc, stats) = last.expect("at least one repetition");
            let data = BucketData::from_accumulator(&acc);
            for repr in &st.representation {
                let rep = match repr.as_str() {
                    "kdtree" => Representation::KdTree(crate::brdf::kdtree::KdTreeBrdf::build(
                        &data, 4, true, false,
                    )),
                    "subdivided" => Representation::Subdivided(
                        crate::brdf::subdivided::SubdividedBrdf::build(&data, 0.05),
                    ),
                    _ => Representation::Table(crate::brdf::table::TableBrdf::build(&data)),
                };
                let mut out = vec![0.0; data.wavelengths_nm.len()];
                let q0 = Instant::now();
                let m = 2000;
                for k in 0..m {
                    let a = k as f64 / m as f64;
                    rep.eval(dir(1.2 * a, 0.0), dir(1.3 * (1.0 - a), 3.0 + a), &mut out);
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
                    for (j, x) in h.iter().enumerate() {
                        re2 += (x - reference[i][j]).powi(2);
                        rn += 1.0;
                    }
                }
                let p = Point {
                    variant: *v,
                    rays,
                    representation: repr.clone(),
                    wall_s: wall,
                    traced_rays: stats.traces,
                    peak_mem_mb: peak_mem_mb(),
                    error: (e2 / n).sqrt(),
                    stderr: (s2 / n).sqrt(),
                    dropped: dropped / dn,
                    query_ns,
                    repr_error: (re2 / rn).sqrt(),
                    unphysical: unphysical.clone(),
                };
                log(&format!(
                    "{} rays {}: error {:.2e} (+- {:.1e}), dropped {:.1e}, {:.2} s, query {:.0} ns",
                    method(&p),
                    rays,
                    p.error,
                    p.stderr,
                    p.dropped,
                    wall,
                    query_ns,
                ));
                points.push(p);
            }
        }
    }
    Ok((points, reference_kind))
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

/// Whether a point's error is within the study's tolerance. The error bars are not added:
/// they are the spread of single trees, which stratified wavelengths and R2 entry points
/// beat by far, so they would excuse real bias.
pub fn holds(p: &Point, tolerance: f64) -> bool {
    p.error <= tolerance && p.unphysical.is_none()
}

/// Draws a chart into `path` atomically (`draw` renders to the temporary path it is given).
fn chart_file(path: &Path, draw: impl FnOnce(&Path) -> Result<(), String>) -> Result<(), String> {
    crate::io::write_atomic_path(path, |tmp| draw(tmp).map_err(std::io::Error::other))
        .map_err(|e| format!("{}: {e}", path.display()))
}

/// Writes `points.csv` and `report.md` into `dir` (atomically each).
pub fn write(st: &Study, points: &[Point], reference: &str, dir: &Path) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    crate::io::write_atomic(&dir.join("points.csv"), |w| {
        writeln!(
            w,
            "backend,coherence,coherence_radius_nm,theta_o_bins,cutoff,max_depth,phase,origin_nm,rays,representation,wall_s,traced_rays,peak_mem_mb,error,error_stderr,dropped,holds,query_ns,repr_error"
        )?;
        for p in points {
            let v = &p.variant;
            writeln!(
                w,
                "{},{},{},{},{:e},{},{},{:e},{},{},{:.4},{},{:.1},{:.6e},{:.6e},{:.3e},{},{:.0},{:.6e}",
                v.backend,
                v.coherence.name(),
                v.radius,
                v.theta_o_bins,
                v.cutoff,
                v.max_depth,
                v.precision.name(),
                v.origin_nm,
                p.rays,
                p.representation,
                p.wall_s,
                p.traced_rays,
                p.peak_mem_mb,
                p.error,
                p.stderr,
                p.dropped,
                holds(p, st.tolerance),
                p.query_ns,
                p.repr_error
            )?;
        }
        Ok(())
    })?;
    crate::io::write_atomic(&dir.join("report.md"), |w| {
        writeln!(w, "# Study: {}\n", st.name)?;
        if !st.notes.trim().is_empty() {
            writeln!(w, "{}\n", st.notes.trim())?;
        }
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
            "Error: RMS over incident angles and bins of the directional reflectance against the {reference}. \
             A point holds when its error is at most {} (the study's tolerance).\n",
            st.tolerance
        )?;
        writeln!(
            w,
            "| method | rays | wall s | error | error bars | dropped | holds | query ns | representation error |"
        )?;
        writeln!(w, "|---|---|---|---|---|---|---|---|---|")?;
        for p in points {
            writeln!(
                w,
                "| {} | {} | {:.3} | {:.2e} | {:.1e} | {:.1e} | {} | {:.0} | {:.2e} |",
                method(p),
                p.rays,
                p.wall_s,
                p.error,
                p.stderr,
                p.dropped,
                if holds(p, st.tolerance) {
                    "yes"
                } else {
                    "**no**"
                },
                p.query_ns,
                p.repr_error
            )?;
        }
        // Where each method breaks: its verdict at the largest ray count.
        let mut methods: Vec<String> = points.iter().map(method).collect();
        methods.sort();
        methods.dedup();
        let (mut ok, mut broken) = (Vec::new(), Vec::new());
        for m in &methods {
            if let Some(p) = points
                .iter()
                .filter(|p| &method(p) == m)
                .max_by_key(|p| p.rays)
            {
                let mut line = format!(
                    "`{m}` (error {:.2e}, error bars {:.1e} at {} rays)",
                    p.error, p.stderr, p.rays
                );
                if p.unphysical.is_some() {
                    line.push_str(": impossible values (R > 1 or energy created)");
                }
                if holds(p, st.tolerance) {
                    ok.push(line);
                } else {
                    broken.push(line);
                }
            }
        }
        writeln!(
            w,
            "\nWhere methods break (verdict at each method's largest ray count):\n"
        )?;
        for l in &broken {
            writeln!(w, "- breaks: {l}")?;
        }
        for l in &ok {
            writeln!(w, "- holds: {l}")?;
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
        if methods.len() == 1
            && let Some(s) = convergence_slope(points)
        {
            writeln!(
                w,
                "\nLeast-squares slope of log(error) against log(rays): {s:.3} (Monte Carlo: -0.5)."
            )?;
        }
        Ok(())
    })
}

/// A method: everything in a point but the ray count (one line per method in the charts).
/// Settings at their defaults are left out of the name.
fn method(p: &Point) -> String {
    let v = &p.variant;
    let rho = if v.radius.is_infinite() {
        "inf".to_string()
    } else {
        format!("{}", v.radius)
    };
    let mut s = format!(
        "{} rho={} bins={} {} {}",
        v.coherence.name(),
        rho,
        v.theta_o_bins,
        v.backend,
        p.representation
    );
    let d = TraceLimits::default();
    if v.cutoff != d.cutoff {
        s.push_str(&format!(" cutoff={:e}", v.cutoff));
    }
    if v.max_depth != d.max_depth {
        s.push_str(&format!(" depth={}", v.max_depth));
    }
    if v.precision != PhasePrecision::F64 {
        s.push_str(&format!(" {}", v.precision.name()));
    }
    if v.origin_nm != 0.0 {
        s.push_str(&format!(" origin={:e}nm", v.origin_nm));
    }
    s
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
        // The bitmap backend picks its format from the extension: the temporary keeps it.
        chart_file(&png, |tmp| {
            draw_loglog(
                BitMapBackend::new(tmp, (900, 600)).into_drawing_area(),
                title,
                xlabel,
                data,
                g.clone(),
            )
        })?;
        chart_file(&svg, |tmp| {
            draw_loglog(
                SVGBackend::new(tmp, (900, 600)).into_drawing_area(),
                title,
                xlabel,
                data,
                g.clone(),
            )
        })?;
        written.push(png);
        written.push(svg);
    }
    Ok(written)
}
