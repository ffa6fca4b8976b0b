//! A peer on the same work (issue 31): Mitsuba 3's ray intersection against goniospec's on
//! the same mesh and rays, so the fraction of a production ray tracer's speed is a printed
//! figure. Mitsuba runs in a Python process (`scripts/bench-peer-mitsuba.py`, the `mitsuba`
//! wheel from PyPI); the mesh and rays reach it as raw little-endian arrays.

use std::path::{Path, PathBuf};
use std::time::Instant;

use super::BenchError;
use crate::accel::workload::{random_rays, trace_all};
use crate::accel::{Accel, Backend, Hit};
use crate::sample::{Mesh, Sample};

/// Settings of `bench peer`.
#[derive(Clone, Debug)]
pub struct PeerConfig {
    /// Random rays over the mesh (the raw comparison).
    pub rays: usize,
    /// Trees of the tracer's run (one wavelength).
    pub trees: u64,
    /// The Python with `mitsuba` and `numpy` (`make interop`'s `.venv-interop`).
    pub python: PathBuf,
    /// `scripts/bench-peer-mitsuba.py`.
    pub script: PathBuf,
    pub threads: usize,
    pub backend: Backend,
    pub seed: u64,
}

/// Writes `values` as little-endian bytes to `path`.
fn write_le<const N: usize, T: Copy>(
    path: &Path,
    values: &[[T; N]],
    bytes: impl Fn(T) -> [u8; 4],
) -> Result<(), BenchError> {
    let mut out = Vec::with_capacity(values.len() * N * 4);
    for v in values {
        for &x in v {
            out.extend_from_slice(&bytes(x));
        }
    }
    std::fs::write(path, out).map_err(super::large::io(path))
}

/// Measures the three figures on `sample`'s interfaces: Mitsuba's closest hits per second,
/// goniospec's raw closest hits per second on the same rays (same thread count), and the
/// goniospec tracer's segments per second at one wavelength (what the tracer does per ray
/// besides the intersection: fields, phases, splits, the estimator), then their ratios.
pub fn peer_bench(
    sample: &Sample,
    cfg: &PeerConfig,
    dir: &Path,
    mut log: impl FnMut(&str),
) -> Result<(), BenchError> {
    let mut mesh = Mesh::default();
    for i in &sample.interfaces {
        mesh.append(&i.mesh);
    }
    let soup = mesh.to_soup();
    let rays = random_rays(&mesh, cfg.rays, cfg.seed);
    std::fs::create_dir_all(dir).map_err(super::large::io(dir))?;
    write_le(&dir.join("vertices.f32"), &soup.vertices, f32::to_le_bytes)?;
    write_le(&dir.join("faces.u32"), &soup.triangles, u32::to_le_bytes)?;
    let flat: Vec<[f32; 6]> = rays
        .iter()
        .map(|r| {
            let (o, d) = (r.origin, r.dir);
            [o[0], o[1], o[2], d[0], d[1], d[2]]
        })
        .collect();
    write_le(&dir.join("rays.f32"), &flat, f32::to_le_bytes)?;
    log(&format!(
        "peer: {} triangles, {} random rays, {} threads",
        soup.triangles.len(),
        rays.len(),
        cfg.threads
    ));

    // Mitsuba, in its own process.
    let out = std::process::Command::new(&cfg.python)
        .arg(&cfg.script)
        .arg(dir)
        .arg(cfg.threads.to_string())
        .output()
        .map_err(|e| {
            BenchError::Peer(format!(
                "cannot run the peer's Python {}: {e} (`make interop` makes .venv-interop with mitsuba and numpy; or pass --python)",
                cfg.python.display()
            ))
        })?;
    if !out.status.success() {
        return Err(BenchError::Peer(format!(
            "{} {} failed (it needs the mitsuba and numpy wheels: `make interop` makes .venv-interop with them, or pass --python): {}",
            cfg.python.display(),
            cfg.script.display(),
            String::from_utf8_lossy(&out.stderr).trim()
        )));
    }
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    let figure = |name: &str| -> Result<f64, BenchError> {
        text.lines()
            .find_map(|l| l.strip_prefix(name)?.strip_prefix(':'))
            .and_then(|v| v.split_whitespace().next()?.parse().ok())
            .ok_or_else(|| BenchError::Peer(format!("no '{name}' in the peer's output: {text}")))
    };
    for line in text.lines() {
        log(line);
    }
    let mitsuba = figure("mitsuba_rays_per_s")?;
    let mitsuba_hits = figure("mitsuba_hits")?;

    // goniospec's intersector on the same rays.
    let accel = Accel::build(cfg.backend, &soup)?;
    let mut hits = vec![Hit::MISS; rays.len()];
    trace_all(&accel, &rays, &mut hits);
    let ours_hits = hits.iter().filter(|h| h.is_hit()).count() as f64;
    // Ray by ray: the same triangle, or both missed.
    let path = dir.join("hits.u32");
    let theirs = std::fs::read(&path).map_err(super::large::io(&path))?;
    if theirs.len() != 4 * rays.len() {
        return Err(BenchError::Peer(format!(
            "{}: {} bytes for {} rays",
            path.display(),
            theirs.len(),
            rays.len()
        )));
    }
    let same = theirs
        .chunks_exact(4)
        .zip(&hits)
        .filter(|(b, h)| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) == h.prim)
        .count();
    let raw = super::raw_rate(&accel, &rays, &mut hits, 5);
    log(&format!("goniospec_{}_hits: {ours_hits}", cfg.backend));
    log(&format!(
        "hit_count_difference: {:.2e} (fraction of rays)",
        (ours_hits - mitsuba_hits).abs() / rays.len().max(1) as f64
    ));
    log(&format!(
        "same_triangle_fraction: {:.6} (ray by ray; the rest are ties on shared edges or f32 rounding)",
        same as f64 / rays.len().max(1) as f64
    ));
    log(&format!("goniospec_raw_rays_per_s: {raw:.0} rays/s"));
    log(&format!("raw_over_mitsuba: {:.2} x", raw / mitsuba));

    // The tracer at one wavelength.
    let mut c = crate::simulate::SimConfig::new(
        vec![30.0],
        crate::simulate::Wavelengths::Monochromatic(vec![550.0]),
        cfg.trees,
    );
    c.backend = cfg.backend;
    let t0 = Instant::now();
    let (_, st) = crate::simulate::simulate(sample, &c, &|_| {})?;
    let wall = t0.elapsed().as_secs_f64();
    let seg = st.segments as f64 / st.trace_seconds();
    log(&format!(
        "tracer: {} trees, {} segments in {:.2} s of tracing ({wall:.2} s in all)",
        st.trees,
        st.segments,
        st.trace_seconds()
    ));
    log(&format!(
        "goniospec_tracer_segments_per_s: {seg:.0} segments/s"
    ));
    log(&format!(
        "tracer_fraction_of_mitsuba: {:.1} %",
        100.0 * seg / mitsuba
    ));
    Ok(())
}
