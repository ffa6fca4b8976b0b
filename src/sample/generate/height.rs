//! Height fields over the periodic tile: the grid mesh, Gaussian random heights
//! (spectral synthesis), the cosine sheet, V-grooves and the flat plane.

use super::GenerateError;
use std::collections::HashMap;
use std::f64::consts::{PI, TAU};

use super::super::mesh::Mesh;
use super::MAX_GENERATED_TRIANGLES;
use crate::rng::Rng;
use glam::DVec3;

/// A regular height field over the periodic tile: `cells[0] x cells[1]` grid cells, two
/// triangles each, normals pointing up (+z). The last row and column repeat the first
/// one's heights (sampled at the wrapped position), so opposite edges coincide.
///
/// # Panics
/// When a cell count is zero.
pub fn height_field(
    cells: [usize; 2],
    tile_nm: [f64; 2],
    height: impl Fn(f64, f64) -> f64,
) -> Mesh {
    let [nx, ny] = cells;
    assert!(nx > 0 && ny > 0, "a height field needs at least one cell");
    let mut positions_nm = Vec::with_capacity((nx + 1) * (ny + 1));
    for j in 0..=ny {
        for i in 0..=nx {
            let (xs, ys) = (
                (i % nx) as f64 * tile_nm[0] / nx as f64,
                (j % ny) as f64 * tile_nm[1] / ny as f64,
            );
            let x = i as f64 * tile_nm[0] / nx as f64;
            let y = j as f64 * tile_nm[1] / ny as f64;
            positions_nm.push(DVec3::new(x, y, height(xs, ys)));
        }
    }
    height_field_from_grid(cells, positions_nm)
}

/// Triangulates a `(nx+1) x (ny+1)` grid of points (row-major, x fastest).
pub(crate) fn height_field_from_grid(cells: [usize; 2], positions_nm: Vec<DVec3>) -> Mesh {
    let [nx, ny] = cells;
    let idx = |i: usize, j: usize| (j * (nx + 1) + i) as u32;
    let mut triangles = Vec::with_capacity(2 * nx * ny);
    for j in 0..ny {
        for i in 0..nx {
            let (a, b, c, d) = (idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1));
            // Counter-clockwise seen from above: normals point to +z.
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    Mesh {
        positions_nm,
        triangles,
    }
}

/// A smooth periodic surface: a sum of `modes` cosines with integer wave numbers (so it
/// tiles), random phases and a 1/|q| amplitude fall-off, scaled to about the given RMS
/// height (nm). Deterministic in `seed`. Used for benchmarks.
pub fn cosine_surface(
    seed: u64,
    tile_nm: [f64; 2],
    rms_nm: f64,
    modes: usize,
    max_wavenumber: i32,
) -> impl Fn(f64, f64) -> f64 {
    let mut rng = Rng::new(seed, 0x5EED);
    let mut terms: Vec<(f64, f64, f64, f64)> = Vec::with_capacity(modes);
    while terms.len() < modes {
        let m = (rng.uniform() * f64::from(2 * max_wavenumber + 1)).floor() as i32 - max_wavenumber;
        let n = (rng.uniform() * f64::from(2 * max_wavenumber + 1)).floor() as i32 - max_wavenumber;
        if m == 0 && n == 0 {
            continue;
        }
        let q = f64::from(m * m + n * n).sqrt();
        let phase = rng.range(0.0, TAU);
        terms.push((
            TAU * f64::from(m) / tile_nm[0],
            TAU * f64::from(n) / tile_nm[1],
            1.0 / q,
            phase,
        ));
    }
    // RMS of a sum of cosines with distinct (m, n) is sqrt(sum a^2 / 2).
    let nominal = (terms.iter().map(|t| t.2 * t.2).sum::<f64>() / 2.0).sqrt();
    let scale = if nominal > 0.0 { rms_nm / nominal } else { 0.0 };
    move |x, y| {
        scale
            * terms
                .iter()
                .map(|&(kx, ky, a, p)| a * (kx * x + ky * y + p).cos())
                .sum::<f64>()
    }
}

/// A periodic Gaussian random surface on a grid, by random-phase spectral synthesis.
///
/// Target: RMS height `rms_nm` and Gaussian autocorrelation
/// `C(r) = rms^2 exp(-r^2 / l^2)` with correlation length `l = corr_nm`, whose 2-D power
/// spectrum is `W(q) = rms^2 l^2 / (4 pi) exp(-q^2 l^2 / 4)` (Ogilvy, Theory of Wave
/// Scattering from Random Rough Surfaces, 1991, §2.2). Each wave vector `q = 2 pi (m/Lx,
/// n/Ly)` of the half plane gets amplitude `sqrt(4 W(q) dqx dqy)` (it stands for `q` and
/// `-q`) and a random phase, so the
/// tile-averaged autocorrelation is exactly the discretised `C(r)`; the sum is then
/// normalised to the exact requested RMS. Returns heights on the `(n+1) x (n+1)` grid.
pub fn gaussian_heights(
    seed: u64,
    tile_nm: [f64; 2],
    resolution: usize,
    rms_nm: f64,
    corr_nm: f64,
) -> Result<Vec<f64>, GenerateError> {
    if !(rms_nm.is_finite() && rms_nm >= 0.0) {
        return Err(GenerateError::from(format!(
            "rms must be finite and >= 0, got {rms_nm}"
        )));
    }
    if !(corr_nm.is_finite() && corr_nm > 0.0) {
        return Err(GenerateError::from(format!(
            "correlation_length must be positive, got {corr_nm}"
        )));
    }
    let n = resolution;
    let spacing = tile_nm[0].max(tile_nm[1]) / n as f64;
    if corr_nm < 3.0 * spacing {
        return Err(GenerateError::from(format!(
            "resolution {n} gives a grid spacing of {spacing:.1} nm, too coarse for a correlation length of {corr_nm} nm (need spacing <= l/3: resolution >= {})",
            (3.0 * tile_nm[0].max(tile_nm[1]) / corr_nm).ceil()
        )));
    }
    let (dqx, dqy) = (TAU / tile_nm[0], TAU / tile_nm[1]);
    // Modes up to the grid's Nyquist limit.
    let mmax = (n / 2) as i64;
    let w = |q2: f64| {
        rms_nm * rms_nm * corr_nm * corr_nm / (4.0 * PI) * (-q2 * corr_nm * corr_nm / 4.0).exp()
    };
    let mut rng = Rng::new(seed, 0x6A055);
    // (m, n, amplitude, phase) over the half plane: m > 0, or m == 0 and n > 0.
    let mut modes = Vec::new();
    let mut total = 0.0;
    for m in 0..=mmax {
        for k in -mmax..=mmax {
            if m == 0 && k <= 0 {
                continue;
            }
            let q2 = (m as f64 * dqx).powi(2) + (k as f64 * dqy).powi(2);
            let a2 = 4.0 * w(q2) * dqx * dqy;
            let phase = rng.range(0.0, TAU);
            total += a2 / 2.0;
            if a2 > 1e-16 * rms_nm * rms_nm {
                modes.push((m, k, a2.sqrt(), phase));
            }
        }
    }
    if rms_nm > 0.0 && total < 0.95 * rms_nm * rms_nm {
        return Err(GenerateError::from(format!(
            "the tile or the resolution is too small for correlation length {corr_nm} nm: only {:.0} % of the height variance fits (make the tile at least a few correlation lengths wide and resolution >= 6 L / l)",
            100.0 * total / (rms_nm * rms_nm)
        )));
    }
    let scale = if total > 0.0 {
        rms_nm / total.sqrt()
    } else {
        0.0
    };
    // Separable evaluation: h(x_i, y_j) = Re sum_m e^{i qx_m x_i} G_m(y_j).
    let mut h = vec![0.0; (n + 1) * (n + 1)];
    let mut by_m: HashMap<i64, Vec<(i64, f64, f64)>> = HashMap::new();
    for &(m, k, a, p) in &modes {
        by_m.entry(m).or_default().push((k, a, p));
    }
    let mut ms: Vec<i64> = by_m.keys().copied().collect();
    ms.sort_unstable();
    for m in ms {
        let list = &by_m[&m];
        // G_m(y_j) = sum_k a e^{i (qy_k y_j + phase)}
        let g: Vec<(f64, f64)> = (0..=n)
            .map(|j| {
                let y = (j % n) as f64 * tile_nm[1] / n as f64;
                list.iter().fold((0.0, 0.0), |(re, im), &(k, a, p)| {
                    let arg = k as f64 * dqy * y + p;
                    (re + a * arg.cos(), im + a * arg.sin())
                })
            })
            .collect();
        for i in 0..=n {
            let x = (i % n) as f64 * tile_nm[0] / n as f64;
            let (c, s) = ((m as f64 * dqx * x).cos(), (m as f64 * dqx * x).sin());
            for (j, &(gr, gi)) in g.iter().enumerate() {
                h[j * (n + 1) + i] += c * gr - s * gi;
            }
        }
    }
    for v in &mut h {
        *v *= scale;
    }
    Ok(h)
}

/// Grid positions for heights from [`gaussian_heights`] plus a constant offset.
pub fn grid_mesh(tile_nm: [f64; 2], n: usize, heights: &[f64], z0: f64) -> Mesh {
    let mut p = Vec::with_capacity((n + 1) * (n + 1));
    for j in 0..=n {
        for i in 0..=n {
            p.push(DVec3::new(
                i as f64 * tile_nm[0] / n as f64,
                j as f64 * tile_nm[1] / n as f64,
                z0 + heights[j * (n + 1) + i],
            ));
        }
    }
    height_field_from_grid([n, n], p)
}

/// Symmetric V-grooves along y: `count` grooves across the tile in x, with opening angle
/// `angle_deg` between the two faces (180° is flat), the ridges at height `z0`.
pub fn v_grooves(tile_nm: [f64; 2], count: usize, angle_deg: f64, z0: f64) -> Result<Mesh, String> {
    if count == 0 {
        return Err("count must be at least 1".into());
    }
    let max = MAX_GENERATED_TRIANGLES / 4;
    if count as u64 > max {
        return Err(format!(
            "count {count} exceeds {max}: {MAX_GENERATED_TRIANGLES} triangles are the most a generator makes"
        ));
    }
    let res = crate::sample::f32_resolution_nm(tile_nm[0].max(tile_nm[1]));
    if tile_nm[0] / (count as f64) < 64.0 * res {
        return Err(format!(
            "count {count} makes grooves {:.3e} nm wide, below what f32 geometry resolves in this tile (64 x {res:.2e} nm)",
            tile_nm[0] / count as f64
        ));
    }
    if !(angle_deg > 0.0 && angle_deg < 180.0) {
        return Err(format!("angle_deg must be in (0, 180), got {angle_deg}"));
    }
    let w = tile_nm[0] / count as f64;
    // Face slope from horizontal is (180° - angle)/2; depth = (w/2) tan(slope).
    let depth = 0.5 * w * ((180.0 - angle_deg) * 0.5).to_radians().tan();
    let nx = 2 * count;
    let mut p = Vec::with_capacity((nx + 1) * 2);
    for j in 0..=1 {
        for i in 0..=nx {
            let z = if i % 2 == 0 { z0 } else { z0 - depth };
            p.push(DVec3::new(i as f64 * 0.5 * w, j as f64 * tile_nm[1], z));
        }
    }
    Ok(height_field_from_grid([nx, 1], p))
}

/// A flat plane at height `z` over the tile (two triangles, normal +z).
pub fn flat(tile_nm: [f64; 2], z: f64) -> Mesh {
    height_field([1, 1], tile_nm, |_, _| z)
}
