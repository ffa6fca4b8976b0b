//! Procedural periodic surfaces, written as ordinary meshes (and OBJ files) so every
//! generated sample can be shared and re-imported.

use super::mesh::Mesh;
use crate::rng::Rng;

/// A regular height field over the periodic tile `[0, Lx) x [0, Ly)`: `cells[0] x
/// cells[1]` grid cells, two triangles each, normals pointing up (+z). The boundary rows
/// repeat the opposite side's heights, so opposite edges coincide and the tile repeats
/// seamlessly provided `height` is periodic.
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
            // Wrap the sampling position so both boundary rows use bit-identical heights.
            let (iw, jw) = (i % nx, j % ny);
            let (xs, ys) = (
                iw as f64 * tile_nm[0] / nx as f64,
                jw as f64 * tile_nm[1] / ny as f64,
            );
            let x = i as f64 * tile_nm[0] / nx as f64;
            let y = j as f64 * tile_nm[1] / ny as f64;
            positions_nm.push([x, y, height(xs, ys)]);
        }
    }
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
/// tiles), random phases and a 1/|q| amplitude fall-off, scaled to the given RMS height
/// (nm). Deterministic in `seed`.
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
        let phase = rng.range(0.0, std::f64::consts::TAU);
        terms.push((
            std::f64::consts::TAU * f64::from(m) / tile_nm[0],
            std::f64::consts::TAU * f64::from(n) / tile_nm[1],
            1.0 / q,
            phase,
        ));
    }
    // RMS of a sum of cosines with distinct (m, n) is sqrt(sum a^2 / 2); distinct pairs are
    // not enforced, so normalise by that nominal value (close for few repeats).
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
