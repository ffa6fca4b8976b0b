//! Benchmarks printed by `goniospec bench …`: raw intersector throughput of each backend
//! on the same rays, in random and in position-sorted order, and agreement between them.
//!
//! Speed goals are checked here, never in timed tests.

mod converge;
mod eval;
mod large;
mod peer;
pub mod rigorous;
mod simulate;

pub use converge::{ConvergeConfig, ConvergeFigure, bucket_noise, converge, seed_check};
pub use eval::{analytic_brdf, analytic_buckets, eval_bench};
pub use large::{BenchError, LargeSample, large_case, large_sample};
pub use peer::{PeerConfig, peer_bench};
pub use simulate::{SimulateBenchConfig, simulate_bench};

use std::time::Instant;

use crate::accel::workload::{Agreement, agreement, coherent_order, random_rays, trace_all};
use crate::accel::{Accel, AccelError, Backend, Hit, Ray, TriangleSoup};
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
