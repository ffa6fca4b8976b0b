//! Workloads for measuring and comparing intersectors: a reference surface, reproducible
//! ray sets, coherent (Morton) ray order, batch tracing, and agreement between two
//! backends' hits. Shared by `goniospec bench` and the accelerator tests.

use glam::DVec3;
use rayon::prelude::*;

use crate::accel::{Accel, Hit, Intersector, Ray};
use crate::rng::Rng;
use crate::sample::{Mesh, generate};

/// Rays per parallel work item; large enough to amortise scheduling, small enough to
/// balance two threads.
pub const CHUNK: usize = 4096;

/// The default benchmark surface: a periodic height field over a 20 µm tile with about
/// `triangles` triangles (2 per grid cell) and 300 nm RMS height.
pub fn default_surface(triangles: usize, seed: u64) -> Mesh {
    let tile = [20_000.0, 20_000.0];
    let cells = ((triangles as f64 / 2.0).sqrt().round() as usize).max(1);
    let h = generate::cosine_surface(seed, tile, 300.0, 24, 8);
    generate::height_field([cells, cells], tile, h)
}

/// `count` rays aimed down at the mesh: origins uniform over its xy bounds, a little above
/// its top, directions uniform in solid angle within 75° of -z. Deterministic in `seed`.
pub fn random_rays(mesh: &Mesh, count: usize, seed: u64) -> Vec<Ray> {
    let (lo, hi) = mesh.bounds().unwrap_or((DVec3::ZERO, DVec3::ONE));
    let extent = (hi - lo).max_element().max(1e-9);
    let z0 = hi.z + 0.01 * extent;
    let cos_max = 75f64.to_radians().cos();
    (0..count)
        .into_par_iter()
        .with_min_len(CHUNK)
        .map(|i| {
            let mut r = Rng::new(seed, i as u64);
            let x = r.range(lo[0], hi[0]);
            let y = r.range(lo[1], hi[1]);
            let cos_t = r.range(cos_max, 1.0);
            let sin_t = (1.0 - cos_t * cos_t).sqrt();
            let phi = r.range(0.0, std::f64::consts::TAU);
            Ray::new(
                [x as f32, y as f32, z0 as f32],
                [
                    (sin_t * phi.cos()) as f32,
                    (sin_t * phi.sin()) as f32,
                    -cos_t as f32,
                ],
            )
        })
        .collect()
}

/// Interleaves the bits of a 16-bit x and y (Morton / Z-order code).
fn morton2(x: u32, y: u32) -> u32 {
    fn spread(mut v: u32) -> u32 {
        v &= 0xFFFF;
        v = (v | (v << 8)) & 0x00FF_00FF;
        v = (v | (v << 4)) & 0x0F0F_0F0F;
        v = (v | (v << 2)) & 0x3333_3333;
        v = (v | (v << 1)) & 0x5555_5555;
        v
    }
    spread(x) | (spread(y) << 1)
}

/// The permutation that orders rays along a Z-order curve of their origins' xy, so
/// neighbouring rays visit neighbouring BVH nodes (stable: ties keep input order).
pub fn coherent_order(rays: &[Ray]) -> Vec<u32> {
    let (mut lo, mut hi) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
    for r in rays {
        for a in 0..2 {
            lo[a] = lo[a].min(r.origin[a]);
            hi[a] = hi[a].max(r.origin[a]);
        }
    }
    let q = |v: f32, a: usize| {
        let span = (hi[a] - lo[a]).max(f32::MIN_POSITIVE);
        (((v - lo[a]) / span) * 65535.0).clamp(0.0, 65535.0) as u32
    };
    let mut keys: Vec<(u32, u32)> = rays
        .iter()
        .enumerate()
        .map(|(i, r)| (morton2(q(r.origin[0], 0), q(r.origin[1], 1)), i as u32))
        .collect();
    keys.par_sort_unstable();
    keys.into_iter().map(|(_, i)| i).collect()
}

/// Traces `rays` in parallel chunks on the current rayon pool.
pub fn trace_all(accel: &Accel, rays: &[Ray], hits: &mut [Hit]) {
    rays.par_chunks(CHUNK)
        .zip(hits.par_chunks_mut(CHUNK))
        .for_each(|(r, h)| accel.closest_hits(r, h));
}

/// How two backends' closest hits compare on the same rays.
#[derive(Clone, Debug, Default)]
pub struct Agreement {
    pub rays: usize,
    /// Same triangle, or both missed.
    pub identical: usize,
    /// Different triangles at the same distance (within 1e-5 relative): edge ties.
    pub ties: usize,
}

/// Compares two hit lists for the same rays.
pub fn agreement(a: &[Hit], b: &[Hit]) -> Agreement {
    let mut out = Agreement {
        rays: a.len(),
        ..Default::default()
    };
    for (x, y) in a.iter().zip(b) {
        if x.prim == y.prim {
            out.identical += 1;
        } else if x.is_hit() && y.is_hit() && (x.t - y.t).abs() <= 1e-5 * x.t.abs().max(1.0) {
            out.ties += 1;
        }
    }
    out
}
