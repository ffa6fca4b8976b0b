//! Benchmarks printed by `goniospec bench …`: raw intersector throughput of each backend
//! on the same rays, in random and in position-sorted order, and agreement between them.
//!
//! Speed goals are checked here, never in timed tests.

use std::time::Instant;

use glam::DVec3;

use crate::accel::workload::{Agreement, agreement, coherent_order, random_rays, trace_all};
use crate::accel::{Accel, AccelError, Backend, Hit, Ray, TriangleSoup};
use crate::rng::Rng;
use crate::sample::Mesh;

/// One throughput figure.
#[derive(Clone, Debug)]
pub struct Throughput {
    pub backend: Backend,
    pub order: &'static str,
    pub threads: usize,
    pub mrays_per_s: f64,
}

/// Settings of `bench trace`.
#[derive(Clone, Debug)]
pub struct TraceBenchConfig {
    pub rays: usize,
    pub threads: Vec<usize>,
    pub backends: Vec<Backend>,
    pub seed: u64,
}

/// Everything `bench trace` measured.
#[derive(Clone, Debug)]
pub struct TraceBenchReport {
    pub triangles: usize,
    pub rays: usize,
    pub build_s: Vec<(Backend, f64)>,
    pub throughput: Vec<Throughput>,
    pub hit_fraction: f64,
    /// Between the first two backends, when two were run.
    pub agreement: Option<Agreement>,
}

/// Builds each backend on `mesh`, traces the same rays in random and in sorted order at
/// each thread count, and compares the backends' hits. `log` receives progress lines.
pub fn trace_bench(
    mesh: &Mesh,
    cfg: &TraceBenchConfig,
    mut log: impl FnMut(&str),
) -> Result<TraceBenchReport, AccelError> {
    let soup: TriangleSoup = mesh.to_soup();
    let rays = random_rays(mesh, cfg.rays, cfg.seed);
    let order = coherent_order(&rays);
    let sorted: Vec<Ray> = order.iter().map(|&i| rays[i as usize]).collect();

    let mut report = TraceBenchReport {
        triangles: soup.triangles.len(),
        rays: rays.len(),
        build_s: Vec::new(),
        throughput: Vec::new(),
        hit_fraction: 0.0,
        agreement: None,
    };
    let mut first_hits: Vec<Vec<Hit>> = Vec::new();
    for &backend in &cfg.backends {
        let t0 = Instant::now();
        let accel = Accel::build(backend, &soup)?;
        let build = t0.elapsed().as_secs_f64();
        log(&format!("{backend} build: {build:.2} s"));
        report.build_s.push((backend, build));

        let mut hits = vec![Hit::MISS; rays.len()];
        for &(name, set) in &[("random", &rays), ("sorted", &sorted)] {
            for &threads in &cfg.threads {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .expect("a rayon pool of a few threads");
                // Warm caches and page in the structure once before timing.
                let warm = set.len().min(20_000);
                pool.install(|| trace_all(&accel, &set[..warm], &mut hits[..warm]));
                let t0 = Instant::now();
                pool.install(|| trace_all(&accel, set, &mut hits));
                let dt = t0.elapsed().as_secs_f64();
                let m = set.len() as f64 / dt / 1e6;
                log(&format!("{backend} {name} {threads}T: {m:.2} Mrays/s"));
                report.throughput.push(Throughput {
                    backend,
                    order: name,
                    threads,
                    mrays_per_s: m,
                });
            }
            if name == "random" {
                first_hits.push(hits.clone());
            }
        }
        #[cfg(embree)]
        if let Accel::Embree(scene) = &accel {
            // Embree's 8-wide packets on one thread, for comparison with the default
            // one-ray-at-a-time batch path.
            let mut packet_hits = vec![Hit::MISS; rays.len()];
            for &(name, set) in &[("random", &rays), ("sorted", &sorted)] {
                let t0 = Instant::now();
                use crate::accel::workload::CHUNK;
                for (r, h) in set.chunks(CHUNK).zip(packet_hits.chunks_mut(CHUNK)) {
                    scene.closest_hits_packet8(r, h);
                }
                let m = set.len() as f64 / t0.elapsed().as_secs_f64() / 1e6;
                log(&format!("embree-packet8 {name} 1T: {m:.2} Mrays/s"));
            }
        }
    }
    if let Some(h) = first_hits.first() {
        report.hit_fraction =
            h.iter().filter(|x| x.is_hit()).count() as f64 / h.len().max(1) as f64;
    }
    if first_hits.len() >= 2 {
        report.agreement = Some(agreement(&first_hits[0], &first_hits[1]));
    }
    Ok(report)
}

/// Settings of `bench simulate`.
#[derive(Clone, Debug)]
pub struct SimulateBenchConfig {
    pub rays: u64,
    pub theta_i_deg: f64,
    pub bins: Vec<f64>,
    pub backends: Vec<Backend>,
    pub seed: u64,
}

/// Passes over the random rays for the raw intersector rate (`simulate_bench`).
const RAW_PASSES: usize = 7;

/// Rays per second of `accel` on `rays`, the best of `passes` passes. One pass can take only
/// tens of milliseconds, and thread wake-ups or a neighbour on the machine only ever slow
/// it down, so the best pass is the stable figure (and fractions of it are conservative).
fn raw_rate(accel: &Accel, rays: &[Ray], hits: &mut [Hit], passes: usize) -> f64 {
    let best = (0..passes)
        .map(|_| {
            let t0 = Instant::now();
            trace_all(accel, rays, hits);
            t0.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min);
    rays.len() as f64 / best
}

/// Runs `bench simulate` on `sample` and on the flat soap film `flat`, printing through `log`.
pub fn simulate_bench(
    sample: &crate::sample::Sample,
    flat: &crate::sample::Sample,
    cfg: &SimulateBenchConfig,
    mut log: impl FnMut(&str),
) -> Result<(), crate::simulate::SimError> {
    use crate::accumulate::Coherence;
    use crate::simulate::{SimConfig, Wavelengths, simulate};
    let threads = rayon::current_num_threads();
    let base = SimConfig {
        seed: cfg.seed,
        backend: Backend::Obvhs,
        ..SimConfig::new(
            vec![cfg.theta_i_deg],
            Wavelengths::Bins(cfg.bins.clone()),
            cfg.rays,
        )
    };
    let nbins = cfg.bins.len() - 1;
    log(&format!(
        "bench simulate: '{}' ({} triangles), {} trees at theta_i {} deg x {} wavelength bins, {threads} threads",
        sample.name,
        sample.triangle_count(),
        cfg.rays,
        cfg.theta_i_deg,
        nbins
    ));
    let mut shared_time = Vec::new();
    for &backend in &cfg.backends {
        // Raw intersector rate on this sample's own geometry, same thread count.
        let mesh = {
            let mut m = Mesh::default();
            for i in &sample.interfaces {
                m.append(&i.mesh);
            }
            m
        };
        let soup = mesh.to_soup();
        let accel = Accel::build(backend, &soup).map_err(crate::trace::SceneError::from)?;
        let rays = random_rays(&mesh, 400_000, cfg.seed);
        let mut hits = vec![Hit::MISS; rays.len()];
        trace_all(&accel, &rays[..20_000], &mut hits[..20_000]);
        let raw = raw_rate(&accel, &rays, &mut hits, RAW_PASSES);
        log(&format!(
            "{backend} raw intersector: {:.2} Mrays/s (random rays, best of {RAW_PASSES} passes)",
            raw / 1e6
        ));
        log(&format!("{backend}_raw_rays_per_s: {raw:.0} rays/s"));
        // Path sharing (one tree for every wavelength), wavelength sharing (every
        // wavelength at once, exact per-wavelength results) and each wavelength alone.
        let mut times = [0.0; 3];
        for (m, (what, key, sharing, lanes)) in [
            ("path sharing on          ", "path_sharing", true, false),
            (
                "wavelength sharing       ",
                "wavelength_sharing",
                false,
                true,
            ),
            ("each wavelength traced   ", "per_wavelength", false, false),
        ]
        .into_iter()
        .enumerate()
        {
            let mut c = base.clone();
            c.backend = backend;
            c.path_sharing = Some(sharing);
            c.wavelength_sharing = lanes;
            let st = match simulate(sample, &c, &|_| {}) {
                Ok((_, st)) => st,
                // Dispersive or coated samples cannot share one tree.
                Err(crate::simulate::SimError::Config(e)) if sharing => {
                    log(&format!("{backend} {what}: not applicable: {e}"));
                    times[m] = f64::NAN;
                    continue;
                }
                Err(e) => return Err(e),
            };
            let seg_rate = st.segments as f64 / st.trace_seconds();
            times[m] = st.trace_seconds();
            log(&format!(
                "{backend} {what}: {:.2} s, {:.0} launched rays/s ({:.0} ray-wavelengths/s), {:.2} M segments/s = {:.0} % of raw",
                st.trace_seconds(),
                st.trees as f64 / st.trace_seconds(),
                (st.trees * nbins as u64) as f64 / st.trace_seconds(),
                seg_rate / 1e6,
                100.0 * seg_rate / raw
            ));
            log(&format!(
                "{backend}_{key}_segments_per_s: {:.0} segments/s",
                seg_rate
            ));
            log(&format!(
                "{backend}_{key}_fraction_of_raw: {:.1} %",
                100.0 * seg_rate / raw
            ));
        }
        shared_time.push(times[0]);
        if times[0].is_finite() {
            log(&format!(
                "{backend}_path_sharing_speedup: {:.2} x",
                times[2] / times[0]
            ));
        }
        log(&format!(
            "{backend}_wavelength_sharing_speedup: {:.2} x",
            times[2] / times[1]
        ));
    }
    if shared_time.len() == 2 && shared_time.iter().all(|t| t.is_finite()) {
        log(&format!(
            "obvhs/embree end-to-end time: {:.2}",
            shared_time[1] / shared_time[0]
        ));
    }

    // The diffraction method against rays on the same sample, trees and bins (issue 31: at
    // most 3x). Its trees sit on a lattice and every wavelength is a bin's centre; the
    // figure is the whole run's wall time, transform included.
    let mut c = base.clone();
    c.backend = cfg.backends[0];
    c.rays = cfg.rays.min(16_384);
    let mut secs = [0.0; 2];
    let mut kept = f64::NAN;
    for (k, mode) in [Coherence::Beamlet, Coherence::Diffraction]
        .into_iter()
        .enumerate()
    {
        c.coherence = mode;
        let t0 = Instant::now();
        let (_, st) = simulate(sample, &c, &|_| {})?;
        secs[k] = t0.elapsed().as_secs_f64();
        if mode == Coherence::Diffraction {
            kept = st
                .diffraction
                .iter()
                .map(|d| d.ratio())
                .filter(|r| r.is_finite())
                .fold(f64::NAN, |a, r| {
                    if (r - 1.0).abs() > (a - 1.0).abs() || a.is_nan() {
                        r
                    } else {
                        a
                    }
                });
        }
    }
    log(&format!(
        "diffraction method on '{}', {} trees x {nbins} bins: {:.2} s against {:.2} s for rays",
        sample.name, c.rays, secs[1], secs[0]
    ));
    log(&format!("diffraction_seconds: {:.3} s", secs[1]));
    log(&format!("rays_seconds: {:.3} s", secs[0]));
    log(&format!(
        "diffraction_over_rays: {:.2} x",
        secs[1] / secs[0]
    ));
    log(&format!("diffraction_power_kept_worst: {kept:.4}"));

    // The flat-film goal: 40 bins x 10 incident angles, error against the TMM, at the
    // default beamlet radius and in the plane-wave limit.
    let thetas: Vec<f64> = (0..10).map(|i| 8.0 * i as f64).collect();
    let edges: Vec<f64> = (0..=40).map(|i| 380.0 + 10.0 * i as f64).collect();
    let stack_at = |l: f64| {
        crate::reference::stack_indices(flat, l).expect("the flat film is a [stack] within range")
    };
    let reference: Vec<Vec<f64>> = thetas
        .iter()
        .map(|th| {
            (0..40)
                .map(|j| {
                    crate::optics::tmm::solve_band(
                        stack_at,
                        edges[j],
                        edges[j + 1],
                        th.to_radians(),
                    )
                    .r()
                })
                .collect()
        })
        .collect();
    for rho in [5000.0, f64::INFINITY] {
        let mut c = base.clone();
        c.backend = cfg.backends[0];
        c.theta_i_deg = thetas.clone();
        c.wavelengths = Wavelengths::Bins(edges.clone());
        c.rays = 256;
        c.rho_nm = rho;
        let t0 = Instant::now();
        let (acc, _) = simulate(flat, &c, &|_| {})?;
        let wall = t0.elapsed().as_secs_f64();
        let (mut max_err, mut at) = (0.0f64, (0.0, 0.0));
        for (i, th) in thetas.iter().enumerate() {
            for j in 0..40 {
                let (r, _) = acc.cell(i, j).totals(Coherence::Beamlet, &c.buckets);
                let e = (r - reference[i][j]).abs();
                if e > max_err {
                    max_err = e;
                    at = (*th, 0.5 * (edges[j] + edges[j + 1]));
                }
            }
        }
        log(&format!(
            "flat film '{}', 40 bins x 10 angles (0..72 deg) x 256 rays, radius {rho} nm: {wall:.2} s wall, max |R - TMM| = {max_err:.2e} (at {} deg, {} nm)",
            flat.name, at.0, at.1
        ));
    }
    Ok(())
}

/// A smooth analytic BRDF for `bench eval` (1/sr): a Lambertian base plus a broad
/// Blinn-Phong lobe (Blinn 1977, normalised as in Akenine-Moeller et al., Real-Time
/// Rendering, 4th ed., eq. 9.47 without Fresnel), with a mild wavelength tilt.
pub fn analytic_brdf(wi: DVec3, wo: DVec3, lambda_nm: f64) -> f64 {
    let h = (wi + wo).normalize();
    let n = 20.0;
    let spec = (n + 8.0) / (8.0 * std::f64::consts::PI) * h[2].max(0.0).powf(n);
    let tilt = 1.0 + 0.3 * (lambda_nm - 550.0) / 200.0;
    0.2 / std::f64::consts::PI * tilt + 0.05 * spec
}

/// Bucket data sampled exactly from [`analytic_brdf`] on a grid of `ni` incident angles
/// (0..80 deg) and `tb x pb` outgoing buckets.
pub fn analytic_buckets(ni: usize, tb: u32, pb: u32, lambdas: &[f64]) -> crate::brdf::BucketData {
    use crate::accumulate::Buckets;
    use crate::brdf::{BucketData, BucketSample, Meta};
    use crate::geom::from_spherical;
    let b = Buckets {
        theta_bins: tb,
        phi_bins: pb,
    };
    let theta_i: Vec<f64> = (0..ni)
        .map(|i| (80.0 * i as f64 / (ni.max(2) - 1) as f64).to_radians())
        .collect();
    let samples = theta_i
        .iter()
        .map(|&ti| {
            (0..b.len())
                .map(|k| {
                    let (t, p) = b.centre(k);
                    let omega = b.projected_solid_angle(k);
                    let f: Vec<f64> = lambdas
                        .iter()
                        .map(|&l| analytic_brdf(from_spherical(ti, 0.0), from_spherical(t, p), l))
                        .collect();
                    BucketSample {
                        theta_i_rad: ti,
                        phi_i_rad: 0.0,
                        theta_o_rad: t,
                        phi_o_rad: p,
                        flux: f.iter().map(|x| x * omega).collect(),
                        f,
                        omega,
                        rel_stderr: None,
                    }
                })
                .collect()
        })
        .collect();
    BucketData {
        theta_i_rad: theta_i,
        phi_i_rad: 0.0,
        buckets: b,
        wavelengths_nm: lambdas.to_vec(),
        samples,
        meta: Meta {
            repr: crate::brdf::Kind::Analytic,
            wavelengths_nm: lambdas.to_vec(),
            spectrum: Some(crate::spectrum::Wavelengths::Monochromatic(
                lambdas.to_vec(),
            )),
            sample_name: "analytic Lambert + Blinn-Phong".into(),
            sample_hash: "analytic".into(),
            simulation: String::new(),
            isotropic: false,
            reciprocal: false,
            median_rel_stderr: None,
        },
    }
}

/// Median and 99th percentile of query times (ns) of `eval` over `queries`.
fn query_times(b: &dyn crate::brdf::Brdf, queries: &[(DVec3, DVec3)]) -> (f64, f64) {
    let mut out = vec![0.0; b.meta().wavelengths_nm.len()];
    let mut t: Vec<f64> = queries
        .iter()
        .map(|&(wi, wo)| {
            let t0 = Instant::now();
            b.eval(wi, wo, &mut out);
            std::hint::black_box(&out);
            t0.elapsed().as_nanos() as f64
        })
        .collect();
    t.sort_by(f64::total_cmp);
    (t[t.len() / 2], t[(t.len() * 99) / 100])
}

/// A benchmark's default input, a path relative to the goniospec checkout: as given when
/// it exists from the working directory, otherwise in the checkout this binary was built
/// from, so `goniospec bench ...` runs from any directory.
pub fn shipped(path: &std::path::Path) -> std::path::PathBuf {
    if path.is_relative() && !path.exists() {
        let there = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(path);
        if there.exists() {
            return there;
        }
    }
    path.to_path_buf()
}

/// `bench eval`: query time, memory, build time and accuracy of each representation.
pub fn eval_bench(
    rough: Option<(&crate::brdf::BucketData, &crate::brdf::BucketData)>,
    mut log: impl FnMut(&str),
) {
    use crate::brdf::Brdf;
    use crate::brdf::kdtree::KdTreeBrdf;
    use crate::brdf::subdivided::SubdividedBrdf;
    use crate::brdf::table::TableBrdf;
    use crate::geom::from_spherical;
    let lambdas = [450.0, 550.0, 650.0];
    let mut rng = Rng::new(3, 3);
    let queries: Vec<(DVec3, DVec3)> = (0..20_000)
        .map(|_| {
            (
                from_spherical(
                    rng.range(0.0, 80f64.to_radians()),
                    rng.range(0.0, std::f64::consts::TAU),
                ),
                from_spherical(
                    rng.range(0.0, 85f64.to_radians()),
                    rng.range(0.0, std::f64::consts::TAU),
                ),
            )
        })
        .collect();
    log(
        "repr        buckets   build_s   memory_MB  median_ns  p99_ns   max_rel_err_vs_analytic  mean_rel_err",
    );
    for (ni, tb, pb) in [(10usize, 25u32, 40u32), (20, 50, 100), (40, 125, 200)] {
        let data = analytic_buckets(ni, tb, pb, &lambdas);
        let n = ni * (tb * pb) as usize;
        let nb = lambdas.len();
        let mut reps: Vec<(&str, Box<dyn Brdf>, f64, f64)> = Vec::new();
        let t0 = Instant::now();
        let kd = KdTreeBrdf::build(&data, 4, true, false);
        let bt = t0.elapsed().as_secs_f64();
        let mem = (kd.tree.heap_bytes() + kd.points.len() * 32 + kd.values.len() * 8) as f64 / 1e6;
        reps.push(("kdtree", Box::new(kd), bt, mem));
        let t0 = Instant::now();
        let sub = SubdividedBrdf::build(&data, 0.05);
        let bt = t0.elapsed().as_secs_f64();
        let cells: usize = sub.cells.iter().map(|c| c.len()).sum();
        let mem =
            (cells * (std::mem::size_of::<crate::brdf::subdivided::Cell>() + 8 * nb)) as f64 / 1e6;
        reps.push(("subdivided", Box::new(sub), bt, mem));
        let t0 = Instant::now();
        let table = TableBrdf::build(&data);
        let bt = t0.elapsed().as_secs_f64();
        let mem = (table.values.len() * 8) as f64 / 1e6;
        reps.push(("table", Box::new(table), bt, mem));
        let mut out = vec![0.0; nb];
        for (name, b, bt, mem) in &reps {
            let (med, p99) = query_times(b.as_ref(), &queries);
            let (mut maxe, mut sume) = (0.0f64, 0.0);
            for &(wi, wo) in &queries[..5000] {
                b.eval(wi, wo, &mut out);
                let want = analytic_brdf(wi, wo, lambdas[1]);
                let e = (out[1] / want - 1.0).abs();
                maxe = maxe.max(e);
                sume += e;
            }
            log(&format!(
                "{name:<11} {n:<9} {bt:<9.3} {mem:<10.1} {med:<10.0} {p99:<8.0} {maxe:<24.4} {:.4}",
                sume / 5000.0
            ));
            log(&format!("{name}_{n}_median_ns: {med:.0} ns"));
            log(&format!("{name}_{n}_p99_ns: {p99:.0} ns"));
        }
        // Brute-force nearest search over the same points, for the kd-tree's speed-up.
        let kd = KdTreeBrdf::build(&data, 4, true, false);
        // Queries in the tree's isotropic frame (phi_i = 0), as eval makes them.
        let rotated: Vec<(DVec3, DVec3)> = queries
            .iter()
            .map(|&(wi, wo)| {
                let (ti, pi) = crate::geom::angles(wi);
                let (to, po) = crate::geom::angles(wo);
                (from_spherical(ti, 0.0), from_spherical(to, po - pi))
            })
            .collect();
        let queries = &rotated;
        let m = 50.min(queries.len());
        let t0 = Instant::now();
        for &(wi, wo) in &queries[..m] {
            std::hint::black_box(kd.tree.nearest_brute(wi, wo, 4));
        }
        let queries = &queries[..];
        let brute = t0.elapsed().as_nanos() as f64 / m as f64;
        let mut near = Vec::new();
        let t0 = Instant::now();
        for &(wi, wo) in queries {
            kd.tree.nearest(wi, wo, 4, &mut near);
            std::hint::black_box(&near);
        }
        let tree = t0.elapsed().as_nanos() as f64 / queries.len() as f64;
        log(&format!(
            "  {n} buckets: kd-tree 4-nearest {tree:.0} ns/query against brute force {brute:.0} ns/query ({:.0}x)",
            brute / tree
        ));
    }
    if let Some((low, high)) = rough {
        let reference = TableBrdf::build(high);
        let reps: Vec<(&str, Box<dyn Brdf>)> = vec![
            ("kdtree", Box::new(KdTreeBrdf::build(low, 4, true, false))),
            ("subdivided", Box::new(SubdividedBrdf::build(low, 0.05))),
            ("table", Box::new(TableBrdf::build(low))),
        ];
        let nb = low.wavelengths_nm.len();
        let (mut a, mut r) = (vec![0.0; nb], vec![0.0; nb]);
        for (name, b) in &reps {
            let (mut num, mut den) = (0.0, 0.0);
            for &ti in &low.theta_i_rad {
                for t in 0..30 {
                    for p in 0..24 {
                        let wi = from_spherical(ti, 0.0);
                        let wo = from_spherical(
                            (t as f64 + 0.5) * 3f64.to_radians(),
                            (p as f64 + 0.5) * 15f64.to_radians(),
                        );
                        b.eval(wi, wo, &mut a);
                        reference.eval(wi, wo, &mut r);
                        let w = wo[2];
                        num += w * (a[0] - r[0]).abs();
                        den += w * r[0].abs();
                    }
                }
            }
            log(&format!(
                "rough sample: {name:<11} cosine-weighted relative L1 error against the high-sample table: {:.4}",
                num / den
            ));
        }
    }
}

/// A sample of `goniospec bench large`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LargeSample {
    /// Rough gold, Gaussian heights (0.2 um RMS, 2.5 um correlation length), 89 nm cells:
    /// about 1M triangles on a 63 um tile.
    Gold1M,
    /// The same surface statistics, about 10M triangles on a 200 um tile.
    Gold10M,
    /// The seed's wavy soap film (600 nm, both surfaces rough) on a 200 um tile, 708^2
    /// cells per surface: about 2M triangles.
    Film2M,
}

impl LargeSample {
    pub const ALL: [LargeSample; 3] = [
        LargeSample::Gold1M,
        LargeSample::Film2M,
        LargeSample::Gold10M,
    ];

    pub fn name(self) -> &'static str {
        match self {
            LargeSample::Gold1M => "gold_1m",
            LargeSample::Gold10M => "gold_10m",
            LargeSample::Film2M => "film_2m",
        }
    }

    pub fn parse(s: &str) -> Option<LargeSample> {
        LargeSample::ALL
            .into_iter()
            .find(|k| k.name() == s.replace('-', "_"))
    }
}

/// Writes the sample `which` into `dir` (OBJ meshes and a TOML description), unless it is
/// already there; returns the TOML's path.
pub fn large_sample(
    dir: &std::path::Path,
    which: LargeSample,
    mut log: impl FnMut(&str),
) -> Result<std::path::PathBuf, String> {
    use crate::sample::generate::GeneratorSpec;
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let name = which.name();
    let toml = dir.join(format!("{name}.toml"));
    if toml.exists() {
        return Ok(toml);
    }
    let (tile_um, surfaces): (f64, Vec<(String, Vec<String>)>) = match which {
        LargeSample::Gold1M | LargeSample::Gold10M => {
            let (tile, res) = if which == LargeSample::Gold1M {
                (63.0, 707)
            } else {
                (200.0, 2236)
            };
            (
                tile,
                vec![(
                    "gaussian".into(),
                    vec![
                        "rms=0.2".into(),
                        "correlation_length=2.5".into(),
                        format!("resolution={res}"),
                        "seed=1".into(),
                    ],
                )],
            )
        }
        LargeSample::Film2M => (
            200.0,
            ["top", "bottom"]
                .iter()
                .map(|s| {
                    (
                        "wavy-film".to_string(),
                        vec![
                            format!("surface={s}"),
                            "thickness=0.6".into(),
                            "thickness_rms=0.008".into(),
                            "roughness_rms=0.06".into(),
                            "correlation_length=2".into(),
                            "resolution=708".into(),
                            "seed=7".into(),
                        ],
                    )
                })
                .collect(),
        ),
    };
    let mut meshes = Vec::new();
    for (k, (kind, params)) in surfaces.iter().enumerate() {
        let path = dir.join(format!("{name}-{k}.obj"));
        log(&format!(
            "# generating {} ({kind} {})",
            path.display(),
            params.join(" ")
        ));
        let spec = GeneratorSpec::from_key_values(kind, params).map_err(|e| e.to_string())?;
        let out = spec
            .generate([tile_um * 1000.0; 2], 1000.0)
            .map_err(|e| e.to_string())?;
        let (mesh, _) = out.merged();
        mesh.write_obj(
            &path,
            1000.0,
            &format!("goniospec bench large: {kind} {}", params.join(" ")),
        )
        .map_err(|e| format!("{}: {e}", path.display()))?;
        meshes.push(path);
    }
    let interfaces = match which {
        LargeSample::Film2M => format!(
            "[media.soap]\nn = 1.33\n[[interface]]\nmesh = \"{name}-0.obj\"\nfront = \"air\"\nback = \"soap\"\n[[interface]]\nmesh = \"{name}-1.obj\"\nfront = \"soap\"\nback = \"air\"\n"
        ),
        _ => format!(
            "[media.gold]\ntable = \"{}\"\n[[interface]]\nmesh = \"{name}-0.obj\"\nfront = \"air\"\nback = \"gold\"\n",
            std::path::absolute(shipped(std::path::Path::new("data/au-johnson.csv")))
                .unwrap_or_default()
                .display()
        ),
    };
    let text = format!(
        "# goniospec bench large\n[sample]\nname = \"{name}\"\nunit = \"um\"\ntile = [{tile_um}, {tile_um}]\n[media.air]\nn = 1.0\n{interfaces}"
    );
    crate::io::write_atomic(&toml, |w| std::io::Write::write_all(w, text.as_bytes()))
        .map_err(|e| format!("{}: {e}", toml.display()))?;
    Ok(toml)
}

/// Measures one large sample, in this process (so the peak memory is this sample's):
/// reading its mesh files once, loading it without and with the mesh cache, building the
/// Embree scene, the raw intersector's random-ray rate on its geometry, and a simulation
/// of `rays` trees at 30 degrees over 40 bins (380-780 nm); one `name: value unit` line
/// per figure, prefixed with `key`.
pub fn large_case(
    sample_path: &std::path::Path,
    key: &str,
    rays: u64,
    mut log: impl FnMut(&str),
) -> Result<(), String> {
    use crate::sample::{self, MeshOptions, cache};
    use crate::simulate::{SimConfig, Wavelengths, simulate};
    let err = |e: &dyn std::fmt::Display| e.to_string();
    // Which mesh files the sample names: every interface's source.
    let first = sample::load(
        sample_path,
        MeshOptions {
            cache: cache::CachePolicy::Off,
            ..Default::default()
        },
    )
    .map_err(|e| err(&e))?;
    let meshes: Vec<std::path::PathBuf> = first
        .interfaces
        .iter()
        .map(|i| i.mesh_path.clone())
        .filter(|p| p.is_file())
        .collect();
    drop(first);
    let bytes: u64 = meshes
        .iter()
        .map(|p| std::fs::metadata(p).map(|m| m.len()).unwrap_or(0))
        .sum();
    let t0 = Instant::now();
    for p in &meshes {
        std::hint::black_box(std::fs::read(p).map_err(|e| err(&e))?);
    }
    let read_s = t0.elapsed().as_secs_f64();
    for p in &meshes {
        let _ = std::fs::remove_file(cache::cache_path(p));
    }
    let opts = MeshOptions {
        cache: cache::CachePolicy::Always,
        ..Default::default()
    };
    let t0 = Instant::now();
    drop(sample::load(sample_path, opts).map_err(|e| err(&e))?);
    let cold_s = t0.elapsed().as_secs_f64();
    let t0 = Instant::now();
    let s = sample::load(sample_path, opts).map_err(|e| err(&e))?;
    let cached_s = t0.elapsed().as_secs_f64();
    let triangles = s.triangle_count();
    let t0 = Instant::now();
    let scene = crate::trace::Scene::new(&s, Backend::Embree).map_err(|e| err(&e))?;
    let build_s = t0.elapsed().as_secs_f64();
    drop(scene);
    // The raw intersector on the same geometry: random rays through the tile.
    let mut mesh = Mesh::default();
    for i in &s.interfaces {
        mesh.append(&i.mesh);
    }
    let accel = Accel::build(Backend::Embree, &mesh.to_soup()).map_err(|e| err(&e))?;
    let rays_raw = random_rays(&mesh, 1_000_000, 1);
    drop(mesh);
    let mut hits = vec![Hit::MISS; rays_raw.len()];
    trace_all(&accel, &rays_raw[..50_000], &mut hits[..50_000]);
    let raw = raw_rate(&accel, &rays_raw, &mut hits, 3);
    drop((accel, rays_raw, hits));
    let edges: Vec<f64> = (0..=40).map(|k| 380.0 + 10.0 * f64::from(k)).collect();
    let cfg = SimConfig {
        backend: Backend::Embree,
        ..SimConfig::new(vec![30.0], Wavelengths::Bins(edges), rays)
    };
    let (_, st) = simulate(&s, &cfg, &|_| {}).map_err(|e| err(&e))?;
    let seg_rate = st.segments as f64 / st.trace_seconds();
    let peak = crate::io::peak_rss_mb().unwrap_or(f64::NAN);
    for (name, value, unit) in [
        ("triangles", triangles as f64, "triangles"),
        ("mesh_file_bytes", bytes as f64, "B"),
        ("read_files_once_s", read_s, "s"),
        ("load_parse_s", cold_s, "s"),
        ("load_cached_s", cached_s, "s"),
        ("build_embree_s", build_s, "s"),
        ("load_cached_plus_build_s", cached_s + build_s, "s"),
        ("raw_embree_rays_per_s", raw, "rays/s"),
        ("simulate_rays", rays as f64, "trees"),
        ("simulate_s", st.seconds, "s"),
        ("simulate_setup_s", st.setup_seconds, "s"),
        (
            "trees_per_s",
            st.trees as f64 / st.trace_seconds(),
            "trees/s",
        ),
        ("segments_per_s", seg_rate, "segments/s"),
        ("fraction_of_raw_embree", 100.0 * seg_rate / raw, "%"),
        (
            "projected_1e7_rays_s",
            st.setup_seconds + 1e7 * st.trace_seconds() / st.trees as f64,
            "s",
        ),
        ("peak_rss_mb", peak, "MB"),
    ] {
        let v = if value.fract() == 0.0 && value.abs() < 1e15 {
            format!("{value:.0}")
        } else {
            format!("{value:.4}")
        };
        log(&format!("{key}_{name}: {v} {unit}"));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::shipped;
    use std::path::Path;

    #[test]
    fn shipped_inputs_are_found_from_any_directory() {
        let checkout = Path::new(env!("CARGO_MANIFEST_DIR"));
        // Tests run in the checkout, where the relative path names the checkout's file
        // (from elsewhere the fallback gives the same file: `bench eval` run from /tmp).
        let rel = Path::new("meshes/rough-glass.toml");
        assert!(shipped(rel).exists());
        assert_eq!(
            std::fs::canonicalize(shipped(rel)).unwrap(),
            std::fs::canonicalize(checkout.join(rel)).unwrap()
        );
        // A path found nowhere is returned as given, for the loader's error to name.
        let nowhere = Path::new("meshes/no-such-sample.toml");
        assert_eq!(shipped(nowhere), nowhere);
        // Absolute paths are never redirected.
        let abs = Path::new("/no/such/file.toml");
        assert_eq!(shipped(abs), abs);
    }
}
