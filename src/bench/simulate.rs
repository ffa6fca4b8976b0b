//! `bench simulate`: the tracer against the raw intersector, the sharing modes, the
//! diffraction method's and the particle media's cost and the flat film's accuracy.

use std::time::Instant;

use crate::accel::workload::{random_rays, trace_all};
use crate::accel::{Accel, Backend, Hit};
use crate::sample::Mesh;

use super::{RAW_PASSES, raw_rate};

/// Settings of `bench simulate`.
#[derive(Clone, Debug)]
pub struct SimulateBenchConfig {
    pub rays: u64,
    pub theta_i_deg: f64,
    pub bins: Vec<f64>,
    pub backends: Vec<Backend>,
    pub seed: u64,
}

/// Runs `bench simulate` on `sample`, on the flat soap film `flat` and on the particle
/// medium `paint`, printing through `log`.
pub fn simulate_bench(
    sample: &crate::sample::Sample,
    flat: &crate::sample::Sample,
    paint: &crate::sample::Sample,
    cfg: &SimulateBenchConfig,
    mut log: impl FnMut(&str),
) -> Result<(), crate::simulate::SimError> {
    use crate::simulate::{SimConfig, Wavelengths};
    // Checked before any work: the particle figure needs a particle medium.
    if paint.media.iter().all(|m| m.scattering.is_none()) {
        return Err(crate::simulate::SimError::Config(format!(
            "bench simulate: '{}' has no particle medium to measure (--paint)",
            paint.name
        )));
    }
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
        shared_time.push(backend_rates(sample, &base, cfg, backend, &mut log)?);
    }
    if shared_time.len() == 2 && shared_time.iter().all(|t| t.is_finite()) {
        log(&format!(
            "obvhs/embree end-to-end time: {:.2}",
            shared_time[1] / shared_time[0]
        ));
    }

    diffraction_cost(sample, &base, cfg, &mut log)?;
    particle_cost(paint, &base, cfg, &mut log)?;
    flat_film_accuracy(flat, &base, cfg, &mut log)?;
    Ok(())
}

/// One backend on `sample`: the raw intersector rate on its own geometry, then path
/// sharing (one tree for every wavelength), wavelength sharing (every wavelength at once,
/// exact per-wavelength results) and each wavelength alone. Returns the path-sharing
/// trace time, s (NaN where the sample cannot share one tree).
fn backend_rates(
    sample: &crate::sample::Sample,
    base: &crate::simulate::SimConfig,
    cfg: &SimulateBenchConfig,
    backend: Backend,
    log: &mut impl FnMut(&str),
) -> Result<f64, crate::simulate::SimError> {
    use crate::simulate::simulate;
    let nbins = cfg.bins.len() - 1;
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
    Ok(times[0])
}

/// The diffraction method against rays on the same sample, trees and bins (issue 31: at
/// most 3x). Its trees sit on a lattice and every wavelength is a bin's centre; the figure
/// is the whole run's wall time, transform included.
fn diffraction_cost(
    sample: &crate::sample::Sample,
    base: &crate::simulate::SimConfig,
    cfg: &SimulateBenchConfig,
    log: &mut impl FnMut(&str),
) -> Result<(), crate::simulate::SimError> {
    use crate::accumulate::Coherence;
    let nbins = cfg.bins.len() - 1;
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
        let st;
        (secs[k], st) = timed(sample, &c)?;
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

    Ok(())
}

/// Particle media against rays in the same layers (issue 31): `paint` as shipped and with
/// its particles taken out (the binder clear), at the same trees (at most 2,048) and bins.
/// The figure is the whole run's wall time: a particle tree walks hundreds of scattering
/// events where the clear binder's walks a few segments.
fn particle_cost(
    paint: &crate::sample::Sample,
    base: &crate::simulate::SimConfig,
    cfg: &SimulateBenchConfig,
    log: &mut impl FnMut(&str),
) -> Result<(), crate::simulate::SimError> {
    let mut clear = paint.clone();
    for m in &mut clear.media {
        m.scattering = None;
    }
    let mut c = base.clone();
    c.backend = cfg.backends[0];
    c.rays = cfg.rays.min(2048);
    let mut secs = [0.0; 2];
    let mut segments = [0.0; 2];
    for (k, s) in [&clear, paint].into_iter().enumerate() {
        let st;
        (secs[k], st) = timed(s, &c)?;
        segments[k] = st.segments as f64 / st.traces.max(1) as f64;
    }
    log(&format!(
        "particle media on '{}', {} trees x {} bins: {:.2} s against {:.2} s for rays in the clear binder ({:.0} against {:.0} segments per tree)",
        paint.name,
        c.rays,
        cfg.bins.len() - 1,
        secs[1],
        secs[0],
        segments[1],
        segments[0]
    ));
    log(&format!("particles_seconds: {:.3} s", secs[1]));
    log(&format!("particles_clear_binder_seconds: {:.3} s", secs[0]));
    log(&format!("particles_over_rays: {:.2} x", secs[1] / secs[0]));
    log(&format!(
        "particles_segments_per_tree: {:.0} segments",
        segments[1]
    ));
    // What bounds the ratio: the walk's length (physics: a tree scatters hundreds of
    // times before it leaves the paint) times the cost of a segment against a clear one's
    // (the tracer's); the first is the segments' ratio, the second this.
    log(&format!(
        "particles_clear_segments_per_tree: {:.1} segments",
        segments[0]
    ));
    log(&format!(
        "particles_per_segment_over_rays: {:.2} x",
        (secs[1] / segments[1].max(1e-9)) / (secs[0] / segments[0].max(1e-9))
    ));
    Ok(())
}

/// One simulation's wall time, s, and its statistics.
fn timed(
    sample: &crate::sample::Sample,
    cfg: &crate::simulate::SimConfig,
) -> Result<(f64, crate::simulate::SimStats), crate::simulate::SimError> {
    let t0 = Instant::now();
    let (_, st) = crate::simulate::simulate(sample, cfg, &|_| {})?;
    Ok((t0.elapsed().as_secs_f64(), st))
}

/// The flat-film goal: 40 bins x 10 incident angles, error against the TMM, at the default
/// beamlet radius and in the plane-wave limit.
fn flat_film_accuracy(
    flat: &crate::sample::Sample,
    base: &crate::simulate::SimConfig,
    cfg: &SimulateBenchConfig,
    log: &mut impl FnMut(&str),
) -> Result<(), crate::simulate::SimError> {
    use crate::accumulate::Coherence;
    use crate::simulate::{Wavelengths, simulate};
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
    let default_radius = crate::simulate::defaults::COHERENCE_RADIUS_NM;
    for rho in [default_radius, f64::INFINITY] {
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
