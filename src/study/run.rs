//! Running a study: the simulation of every point, its reference (TMM or a high-budget
//! run), the sampled-area sweep, and the summaries (convergence slope, verdicts).

use super::*;
use crate::geom::from_spherical;
use crate::simulate::SimSettings;

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
pub fn run_area(st: &Study, mut log: impl FnMut(&str)) -> Result<Vec<AreaPoint>, StudyError> {
    let Some(a) = &st.area else {
        return Ok(Vec::new());
    };
    let sample: Sample =
        sample::load(&st.sample_path, MeshOptions::default()).map_err(|e| e.to_string())?;
    if sample.guard_nm.is_some() {
        return Err(StudyError::from(format!(
            "{}: the sampled-area experiment repeats the tile, which needs periodic sides; this sample's sides are open (guard band)",
            st.sample_path.display()
        )));
    }
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

/// Peak resident memory of this process so far, MB (0 where unknown).
pub(super) fn peak_mem_mb() -> f64 {
    crate::io::peak_rss_mb().unwrap_or(0.0)
}

pub(super) fn config(st: &Study, rays: u64, v: &Variant, seed: u64) -> SimConfig {
    let settings = SimSettings {
        theta_i_deg: st.theta_i.clone(),
        rays,
        backend: Some(v.backend),
        seed,
        coherence: v.coherence,
        coherence_radius_nm: v.radius,
        cutoff: v.cutoff,
        max_depth: v.max_depth,
        theta_o_bins: v.theta_o_bins,
        // The study compares methods, some of them known to fail (bucket, global, f32):
        // an impossible result is recorded as a failure of the point, not an abort.
        allow_unphysical: true,
        ..SimSettings::default()
    };
    // The study's own experiments, beyond a user's settings: bin edges as parsed, the
    // sample moved in the world, uniform entry points and f32 phases. Its variants were
    // validated when the study was read.
    SimConfig {
        origin_nm: glam::DVec3::new(v.origin_nm, v.origin_nm, 0.0),
        random_entry: st.random_entry,
        precision: v.precision,
        ..settings.config(Wavelengths::Bins(st.edges.clone()))
    }
}

/// Directional reflectance per (incident angle, bin) of an accumulator.
pub(super) fn r_table(acc: &Accumulator) -> Vec<Vec<f64>> {
    let s = &acc.header.settings;
    (0..s.theta_i_deg.len())
        .map(|i| {
            (0..s.wavelength_count())
                .map(|j| acc.cell(i, j).totals(s.coherence_mode(), &s.buckets()).0)
                .collect()
        })
        .collect()
}

/// The reflected distribution over the buckets per (incident angle, bin), each normalised
/// to 1 (all zeros where nothing is reflected).
pub(super) fn distribution_table(acc: &Accumulator) -> Vec<Vec<Vec<f64>>> {
    let s = &acc.header.settings;
    let (mode, buckets) = (s.coherence_mode(), s.buckets());
    (0..s.theta_i_deg.len())
        .map(|i| {
            (0..s.wavelength_count())
                .map(|j| {
                    let c = acc.cell(i, j);
                    let f: Vec<f64> = (0..buckets.len())
                        .map(|b| c.fraction(2 * b, mode))
                        .collect();
                    let total: f64 = f.iter().sum();
                    f.into_iter()
                        .map(|x| if total > 0.0 { x / total } else { 0.0 })
                        .collect()
                })
                .collect()
        })
        .collect()
}

/// Mean L1 distance of two [`distribution_table`]s over incident angles and bins; `None`
/// when their shapes differ (another bucket layout).
pub(super) fn distribution_l1(a: &[Vec<Vec<f64>>], b: &[Vec<Vec<f64>>]) -> Option<f64> {
    let (mut sum, mut n) = (0.0, 0usize);
    if a.len() != b.len() {
        return None;
    }
    for (ra, rb) in a.iter().zip(b) {
        if ra.len() != rb.len() {
            return None;
        }
        for (da, db) in ra.iter().zip(rb) {
            if da.len() != db.len() {
                return None;
            }
            sum += da.iter().zip(db).map(|(x, y)| (x - y).abs()).sum::<f64>();
            n += 1;
        }
    }
    (n > 0).then(|| sum / n as f64)
}

/// What a study measures against: R per (incident angle, bin), the reflected distribution
/// where the reference has one, and a description.
pub(super) struct Reference {
    pub r: Vec<Vec<f64>>,
    pub distribution: Option<Vec<Vec<Vec<f64>>>>,
    pub kind: String,
}

/// The study's reference ([`ReferenceKind`]).
pub(super) fn reference(
    st: &Study,
    sample: &Sample,
    log: &mut impl FnMut(&str),
) -> Result<Reference, StudyError> {
    let kind = match st.reference {
        ReferenceKind::Auto if sample.stack.is_some() => "tmm",
        ReferenceKind::Auto | ReferenceKind::Run => "run",
        ReferenceKind::LocalFilm => "local-film",
        ReferenceKind::Diffraction => "diffraction",
    };
    match kind {
        "tmm" => {
            for &l in [st.edges[0], st.edges[st.edges.len() - 1]].iter() {
                crate::reference::stack_indices(sample, l)?;
            }
            let r = st
                .theta_i
                .iter()
                .map(|t| {
                    st.edges
                        .windows(2)
                        .map(|w| {
                            tmm::solve_band(
                                |l| {
                                    crate::reference::stack_indices(sample, l)
                                        .expect("range checked")
                                },
                                w[0],
                                w[1],
                                t.to_radians(),
                            )
                            .r()
                        })
                        .collect()
                })
                .collect();
            Ok(Reference {
                r,
                distribution: None,
                kind: "analytic TMM (bin-averaged)".into(),
            })
        }
        "local-film" => {
            let entries = 48;
            let r = st
                .theta_i
                .iter()
                .map(|&t| crate::reference::local_film::reflectance(sample, t, &st.edges, entries))
                .collect::<Result<Vec<_>, _>>()?;
            Ok(Reference {
                r,
                distribution: None,
                kind: format!(
                    "local-film (tangent-plane) TMM reference, {entries} x {entries} entry points"
                ),
            })
        }
        _ => {
            log(&format!(
                "reference: {} rays per direction",
                st.reference_rays
            ));
            // Low-discrepancy entry points and default settings for the reference whatever
            // the study sweeps: its error falls about as 1/N, far below the points'.
            let diffraction = kind == "diffraction";
            let v = Variant {
                coherence: if diffraction {
                    Coherence::Diffraction
                } else {
                    Coherence::Beamlet
                },
                radius: crate::simulate::defaults::COHERENCE_RADIUS_NM,
                cutoff: TraceLimits::default().cutoff,
                max_depth: TraceLimits::default().max_depth,
                precision: PhasePrecision::F64,
                origin_nm: 0.0,
                ..st.variants[0]
            };
            let mut cfg = config(st, st.reference_rays, &v, st.seed.wrapping_add(1_000_003));
            cfg.random_entry = false;
            let acc = simulate(sample, &cfg, &|_| {})
                .map_err(|e| e.to_string())?
                .0;
            Ok(Reference {
                r: r_table(&acc),
                distribution: Some(distribution_table(&acc)),
                kind: format!(
                    "high-budget {} run ({} rays per direction, radius 5 um)",
                    if diffraction {
                        "diffraction"
                    } else {
                        "beamlet"
                    },
                    st.reference_rays
                ),
            })
        }
    }
}

/// Runs the study; `log` receives progress lines.
pub fn run(st: &Study, mut log: impl FnMut(&str)) -> Result<(Vec<Point>, String), StudyError> {
    let sample: Sample =
        sample::load(&st.sample_path, MeshOptions::default()).map_err(|e| e.to_string())?;
    let Reference {
        r: reference,
        distribution: reference_distribution,
        kind: reference_kind,
    } = reference(st, &sample, &mut log)?;
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
                if let Err(e) = crate::simulate::check_physical(&acc, &sample.name, Some(&stats)) {
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
            let spread = reference_distribution
                .as_ref()
                .and_then(|d| distribution_l1(&distribution_table(&acc), d));
            let data = BucketData::from_accumulator(&acc);
            for &repr in &st.representation {
                let rep = Representation::build(repr, &data, &crate::brdf::BuildOptions::default())
                    .expect("the study's kinds are stored kinds with default options");
                let mut out = vec![0.0; data.lambda_nm.len()];
                let q0 = Instant::now();
                let m = 2000;
                for k in 0..m {
                    let a = k as f64 / m as f64;
                    rep.eval(
                        from_spherical(1.2 * a, 0.0),
                        from_spherical(1.3 * (1.0 - a), 3.0 + a),
                        &mut out,
                    );
                    std::hint::black_box(&out);
                }
                let query_ns = q0.elapsed().as_nanos() as f64 / m as f64;
                let (mut re2, mut rn) = (0.0f64, 0.0f64);
                for (i, t) in st.theta_i.iter().enumerate() {
                    let h = crate::brdf::hemispherical_reflectance(
                        &rep,
                        from_spherical(t.to_radians(), 0.0),
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
                    representation: repr,
                    wall_s: wall,
                    traced_rays: stats.traces,
                    peak_mem_mb: peak_mem_mb(),
                    error: (e2 / n).sqrt(),
                    stderr: (s2 / n).sqrt(),
                    dropped: dropped / dn,
                    query_ns,
                    repr_error: (re2 / rn).sqrt(),
                    distribution_l1: spread,
                    unphysical: unphysical.clone(),
                };
                log(&format!(
                    "{} rays {}: error {:.2e} (+- {:.1e}), distribution L1 {}, dropped {:.1e}, {:.2} s, query {:.0} ns",
                    method(&p),
                    rays,
                    p.error,
                    p.stderr,
                    p.distribution_l1
                        .map_or("-".to_string(), |d| format!("{d:.3}")),
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
