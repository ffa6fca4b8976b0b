//! Procedural periodic microgeometry, written as ordinary meshes (and OBJ files) so every
//! generated sample can be shared and re-imported.
//!
//! Every generator works on the periodic tile `[0, Lx) x [0, Ly)` in nanometres. Sheets
//! (height fields, films, microfacets, grooves) span the whole tile and their opposite
//! boundary edges coincide after a shift by the tile size; bodies (pigments, flakes) are
//! closed meshes kept inside the tile. Every generator is deterministic in its seed.
//!
//! Resolution parameters say what they control: `resolution` is grid cells per tile side
//! for height fields (the mesh has `2 * resolution^2` triangles), `subdivisions` the
//! icosphere level of a pigment (20 * 4^level triangles).

use std::collections::HashMap;
use std::f64::consts::{PI, TAU};

use serde::Deserialize;

use super::mesh::Mesh;
use crate::rng::Rng;

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
            positions_nm.push([x, y, height(xs, ys)]);
        }
    }
    height_field_from_grid(cells, positions_nm)
}

/// Triangulates a `(nx+1) x (ny+1)` grid of points (row-major, x fastest).
fn height_field_from_grid(cells: [usize; 2], positions_nm: Vec<[f64; 3]>) -> Mesh {
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
) -> Result<Vec<f64>, String> {
    if !(rms_nm.is_finite() && rms_nm >= 0.0) {
        return Err(format!("rms must be finite and >= 0, got {rms_nm}"));
    }
    if !(corr_nm.is_finite() && corr_nm > 0.0) {
        return Err(format!(
            "correlation_length must be positive, got {corr_nm}"
        ));
    }
    let n = resolution;
    let spacing = tile_nm[0].max(tile_nm[1]) / n as f64;
    if corr_nm < 3.0 * spacing {
        return Err(format!(
            "resolution {n} gives a grid spacing of {spacing:.1} nm, too coarse for a correlation length of {corr_nm} nm (need spacing <= l/3: resolution >= {})",
            (3.0 * tile_nm[0].max(tile_nm[1]) / corr_nm).ceil()
        ));
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
        return Err(format!(
            "the tile or the resolution is too small for correlation length {corr_nm} nm: only {:.0} % of the height variance fits (make the tile at least a few correlation lengths wide and resolution >= 6 L / l)",
            100.0 * total / (rms_nm * rms_nm)
        ));
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
            p.push([
                i as f64 * tile_nm[0] / n as f64,
                j as f64 * tile_nm[1] / n as f64,
                z0 + heights[j * (n + 1) + i],
            ]);
        }
    }
    height_field_from_grid([n, n], p)
}

/// Which microfacet normal distribution.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Distribution {
    /// Trowbridge–Reitz / GGX (Walter et al., EGSR 2007, eq. 33).
    Ggx,
    /// Beckmann (Walter et al. 2007, eq. 25).
    Beckmann,
}

impl Distribution {
    /// The normal distribution D(m) (1/sr) at `cos_theta_m` for roughness `alpha`.
    /// Walter et al. 2007, eqs. 25 and 33.
    pub fn d(self, alpha: f64, cos_theta_m: f64) -> f64 {
        if cos_theta_m <= 0.0 {
            return 0.0;
        }
        let c2 = cos_theta_m * cos_theta_m;
        let tan2 = (1.0 - c2) / c2;
        let a2 = alpha * alpha;
        match self {
            Distribution::Beckmann => (-tan2 / a2).exp() / (PI * a2 * c2 * c2),
            Distribution::Ggx => a2 / (PI * c2 * c2 * (a2 + tan2).powi(2)),
        }
    }

    /// Samples a microfacet normal with density `D(m) cos(theta_m)` per solid angle
    /// (Walter et al. 2007, eqs. 28–29 and 35–36).
    pub fn sample(self, alpha: f64, u1: f64, u2: f64) -> [f64; 3] {
        let tan2 = match self {
            Distribution::Beckmann => -alpha * alpha * (1.0 - u1).ln(),
            Distribution::Ggx => alpha * alpha * u1 / (1.0 - u1),
        };
        let cos_t = 1.0 / (1.0 + tan2).sqrt();
        let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
        let phi = TAU * u2;
        [sin_t * phi.cos(), sin_t * phi.sin(), cos_t]
    }
}

/// A microfacet surface as a periodic height field (no vertical walls, watertight, and its
/// facets' projected-area-weighted normals follow `D(m) cos(theta_m)`): the projected-area
/// density of a height field's facet normals is the density of its slopes over the plane,
/// and the slope densities are, for slope `s` (Walter et al. 2007, eqs. 25 and 33 with
/// `D(m) cos^4(theta_m) = P22(tan theta_m)`):
///
/// ```text
/// Beckmann: P22(s) = exp(-|s|^2 / alpha^2) / (pi alpha^2)     P(|s| <= r) = 1 - exp(-r^2 / alpha^2)
/// GGX:      P22(s) = 1 / (pi alpha^2 (1 + |s|^2 / alpha^2)^2) P(|s| <= r) = r^2 / (alpha^2 + r^2)
/// ```
///
/// Construction, by alternating projections: a Gaussian random field with a Gaussian
/// autocorrelation of length `corr_nm` ([`gaussian_heights`]) fixes the spatial
/// correlation; then `ROUNDS` times, (1) the facet slopes' magnitudes are replaced, rank for
/// rank, by the target distribution's stratified quantiles, keeping their directions (the
/// amplitude adjustment of Schreiber & Schmitz, "Improved surrogate data for nonlinearity
/// tests", PRL 77 (1996) 635), and (2) the heights are re-solved as the periodic height
/// field whose facet slopes are nearest to those in least squares (the integrability
/// projection of Frankot & Chellappa, IEEE PAMI 10 (1988) 439), by conjugate gradients, and
/// on a square tile made invariant under 90-degree rotations ([`symmetrise`]). For
/// Beckmann the Gaussian field's slopes are already Gaussian, so this only fixes `alpha`
/// exactly; for GGX's heavy-tailed slopes the projection trims the extreme tail the grid
/// cannot hold. Heights and slopes stay uncorrelated as in a stationary random process, the
/// assumption of the Smith masking function (Smith 1967; Heitz 2014, JCGT 3(2) §5).
///
/// The grid has `cells x cells` squares of two triangles each; `corr_nm` must span at least
/// `MIN_CELLS_PER_CORRELATION` cells, and the tile should hold several correlation
/// lengths (the default is `tile / 8`: 64 correlation areas).
pub fn microfacet_surface(
    seed: u64,
    tile_nm: [f64; 2],
    cells: usize,
    dist: Distribution,
    alpha: f64,
    corr_nm: f64,
    z0: f64,
) -> Result<Mesh, String> {
    if cells == 0 {
        return Err("resolution must be at least 1".into());
    }
    if !(alpha.is_finite() && alpha > 0.0) {
        return Err(format!("alpha must be positive, got {alpha}"));
    }
    let n = cells;
    let spacing = [tile_nm[0] / n as f64, tile_nm[1] / n as f64];
    let h_nm = spacing[0].max(spacing[1]);
    if !(corr_nm.is_finite() && corr_nm >= MIN_CELLS_PER_CORRELATION * h_nm) {
        return Err(format!(
            "correlation_length {corr_nm} nm spans fewer than {MIN_CELLS_PER_CORRELATION} grid cells of {h_nm:.1} nm: raise resolution to at least {} or the correlation length",
            (MIN_CELLS_PER_CORRELATION * tile_nm[0].max(tile_nm[1]) / corr_nm).ceil()
        ));
    }
    // Start: a Gaussian field (any RMS: only its shape matters), periodic n x n.
    let g = gaussian_heights(seed, tile_nm, n, 1.0, corr_nm)?;
    let mut h: Vec<f64> = (0..n * n).map(|k| g[(k / n) * (n + 1) + k % n]).collect();
    let square = (tile_nm[0] - tile_nm[1]).abs() <= 1e-12 * tile_nm[0];
    if square {
        symmetrise(&mut h, n);
    }
    let quantile = |u: f64| match dist {
        Distribution::Beckmann => alpha * (-(1.0 - u).ln()).sqrt(),
        Distribution::Ggx => alpha * (u / (1.0 - u)).sqrt(),
    };
    let m = 2 * n * n;
    let target_r: Vec<f64> = (0..m)
        .map(|k| quantile((k as f64 + 0.5) / m as f64))
        .collect();
    let mut slopes = vec![[0.0; 2]; m];
    let mut order: Vec<u32> = (0..m as u32).collect();
    for _ in 0..ROUNDS {
        facet_slopes(&h, n, spacing, &mut slopes);
        order.sort_unstable_by(|&a, &b| {
            let r = |k: u32| slopes[k as usize][0].hypot(slopes[k as usize][1]);
            r(a).total_cmp(&r(b))
        });
        for (rank, &k) in order.iter().enumerate() {
            let s = &mut slopes[k as usize];
            let r = s[0].hypot(s[1]);
            let f = if r > 0.0 { target_r[rank] / r } else { 0.0 };
            *s = [s[0] * f, s[1] * f];
        }
        integrate_slopes(&slopes, n, spacing, &mut h);
        if square {
            symmetrise(&mut h, n);
        }
    }
    // The grid with the last row and column repeating the first (periodic edges coincide).
    let mut grid = vec![0.0; (n + 1) * (n + 1)];
    for j in 0..=n {
        for i in 0..=n {
            grid[j * (n + 1) + i] = h[(j % n) * n + i % n];
        }
    }
    Ok(grid_mesh(tile_nm, n, &grid, z0))
}

/// Averages the periodic square height field with its copies rotated by 90, 180 and 270
/// degrees about the grid origin, `(i, j) -> (-j, i)`: the surface becomes invariant under
/// those rotations, so its slope directions are isotropic to 4-fold symmetry by
/// construction (a tile of a few dozen correlation areas is visibly anisotropic by chance),
/// while heights and slopes stay a linear, integrable field.
fn symmetrise(h: &mut [f64], n: usize) {
    let at = |h: &[f64], i: usize, j: usize| h[j * n + i];
    let old = h.to_vec();
    for j in 0..n {
        for i in 0..n {
            let (ni, nj) = ((n - i) % n, (n - j) % n);
            h[j * n + i] =
                0.25 * (at(&old, i, j) + at(&old, nj, i) + at(&old, ni, nj) + at(&old, j, ni));
        }
    }
}

/// Rounds of slope adjustment and integration in [`microfacet_surface`].
const ROUNDS: usize = 12;
/// Grid cells a microfacet surface's correlation length must span at least.
pub const MIN_CELLS_PER_CORRELATION: f64 = 4.0;

/// Facet slopes `(dz/dx, dz/dy)` of the periodic height field `h` (`n x n`, spacings `d`):
/// per cell `(i, j)` the triangles `[(i,j), (i+1,j), (i+1,j+1)]` and `[(i,j), (i+1,j+1),
/// (i,j+1)]` of [`grid_mesh`], at index `2 (j n + i)` and the next.
fn facet_slopes(h: &[f64], n: usize, d: [f64; 2], out: &mut [[f64; 2]]) {
    let at = |i: usize, j: usize| h[(j % n) * n + i % n];
    for j in 0..n {
        for i in 0..n {
            let (a, b, c, e) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            out[2 * (j * n + i)] = [(b - a) / d[0], (c - b) / d[1]];
            out[2 * (j * n + i) + 1] = [(c - e) / d[0], (e - a) / d[1]];
        }
    }
}

/// `A^T s`: the adjoint of [`facet_slopes`] with unit spacings, into `out`.
fn facet_slopes_adjoint(s: &[[f64; 2]], n: usize, out: &mut [f64]) {
    out.iter_mut().for_each(|v| *v = 0.0);
    let idx = |i: usize, j: usize| (j % n) * n + i % n;
    for j in 0..n {
        for i in 0..n {
            let [t1x, t1y] = s[2 * (j * n + i)];
            let [t2x, t2y] = s[2 * (j * n + i) + 1];
            // t1x = b - a, t1y = c - b, t2x = c - e, t2y = e - a.
            out[idx(i, j)] -= t1x + t2y;
            out[idx(i + 1, j)] += t1x - t1y;
            out[idx(i + 1, j + 1)] += t1y + t2x;
            out[idx(i, j + 1)] += t2y - t2x;
        }
    }
}

/// Least-squares heights for target facet slopes: with `A` the height differences along
/// each facet's edges, solves `A^T A h = A^T (d s)` (target differences) on the periodic
/// grid, as Frankot & Chellappa (1988) do, by FFT: `A^T A` is a convolution whose symbol
/// for this triangulation is `2 (2 - 2 cos u) + 2 (2 - 2 cos v)` (each cell holds two x
/// and two y differences), so the solution is exact in one step. The mean height is 0.
fn integrate_slopes(s: &[[f64; 2]], n: usize, d: [f64; 2], h: &mut [f64]) {
    use rustfft::FftPlanner;
    use rustfft::num_complex::Complex;
    let scaled: Vec<[f64; 2]> = s.iter().map(|v| [v[0] * d[0], v[1] * d[1]]).collect();
    let mut rhs = vec![0.0; n * n];
    facet_slopes_adjoint(&scaled, n, &mut rhs);
    let mut planner = FftPlanner::<f64>::new();
    let (fwd, inv) = (planner.plan_fft_forward(n), planner.plan_fft_inverse(n));
    let mut grid: Vec<Complex<f64>> = rhs.iter().map(|&v| Complex::new(v, 0.0)).collect();
    let transform = |grid: &mut Vec<Complex<f64>>, fft: &dyn rustfft::Fft<f64>| {
        // Rows (x), then columns (y) through a transpose.
        fft.process(grid);
        let mut t = vec![Complex::new(0.0, 0.0); n * n];
        for j in 0..n {
            for i in 0..n {
                t[i * n + j] = grid[j * n + i];
            }
        }
        fft.process(&mut t);
        for j in 0..n {
            for i in 0..n {
                grid[j * n + i] = t[i * n + j];
            }
        }
    };
    transform(&mut grid, fwd.as_ref());
    for j in 0..n {
        for i in 0..n {
            let (u, v) = (TAU * i as f64 / n as f64, TAU * j as f64 / n as f64);
            let symbol = 2.0 * (2.0 - 2.0 * u.cos()) + 2.0 * (2.0 - 2.0 * v.cos());
            let k = j * n + i;
            grid[k] = if symbol > 0.0 {
                grid[k] / symbol
            } else {
                Complex::new(0.0, 0.0)
            };
        }
    }
    transform(&mut grid, inv.as_ref());
    let scale = 1.0 / (n * n) as f64;
    for (hk, g) in h.iter_mut().zip(&grid) {
        *hk = g.re * scale;
    }
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
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
    let res = super::f32_resolution_nm(tile_nm[0].max(tile_nm[1]));
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
            p.push([i as f64 * 0.5 * w, j as f64 * tile_nm[1], z]);
        }
    }
    Ok(height_field_from_grid([nx, 1], p))
}

/// A flat plane at height `z` over the tile (two triangles, normal +z).
pub fn flat(tile_nm: [f64; 2], z: f64) -> Mesh {
    height_field([1, 1], tile_nm, |_, _| z)
}

/// A unit icosphere (Loop-free midpoint subdivision of an icosahedron), outward normals.
pub fn icosphere(subdivisions: u32) -> Mesh {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut p: Vec<[f64; 3]> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .to_vec();
    let norm = |v: [f64; 3]| {
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        [v[0] / l, v[1] / l, v[2] / l]
    };
    for v in &mut p {
        *v = norm(*v);
    }
    let mut tris: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut next = Vec::with_capacity(tris.len() * 4);
        let mut midpoint = |a: u32, b: u32, p: &mut Vec<[f64; 3]>| {
            let key = (a.min(b), a.max(b));
            *mid.entry(key).or_insert_with(|| {
                let (x, y) = (p[a as usize], p[b as usize]);
                p.push(norm([
                    (x[0] + y[0]) / 2.0,
                    (x[1] + y[1]) / 2.0,
                    (x[2] + y[2]) / 2.0,
                ]));
                (p.len() - 1) as u32
            })
        };
        for [a, b, c] in tris {
            let ab = midpoint(a, b, &mut p);
            let bc = midpoint(b, c, &mut p);
            let ca = midpoint(c, a, &mut p);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        tris = next;
    }
    Mesh {
        positions_nm: p,
        triangles: tris,
    }
}

/// Signed volume enclosed by a closed mesh (nm³), positive for outward normals
/// (divergence theorem: sum over triangles of `v0 . (v1 x v2) / 6`).
pub fn enclosed_volume(mesh: &Mesh) -> f64 {
    mesh.triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| mesh.positions_nm[i as usize]);
            let bc = cross(b, c);
            (a[0] * bc[0] + a[1] * bc[1] + a[2] * bc[2]) / 6.0
        })
        .sum()
}

/// Pigment spheres placed without overlap (random sequential addition) inside the layer
/// `z in [layer_nm[0], layer_nm[1]]`, fully inside the tile, to the requested volume fraction
/// of the layer. Each sphere is an icosphere scaled so its volume equals that of the ideal
/// sphere of `radius_nm`; the non-overlap test uses its circumscribed radius. Returns one
/// closed mesh per sphere, outward normals.
pub fn pigment_spheres(
    seed: u64,
    tile_nm: [f64; 2],
    radius_nm: f64,
    volume_fraction: f64,
    layer_nm: [f64; 2],
    subdivisions: u32,
) -> Result<Vec<Mesh>, String> {
    if !(radius_nm > 0.0 && radius_nm.is_finite()) {
        return Err(format!("radius must be positive, got {radius_nm}"));
    }
    if !(volume_fraction > 0.0 && volume_fraction < 0.5) {
        return Err(format!(
            "volume_fraction must be in (0, 0.5) (random sequential addition jams near 0.38), got {volume_fraction}"
        ));
    }
    let unit = icosphere(subdivisions);
    let scale = (4.0 / 3.0 * PI / enclosed_volume(&unit)).cbrt();
    let rc = radius_nm * scale; // circumscribed radius of the scaled icosphere
    let thickness = check_layer(layer_nm)?;
    if 2.0 * rc >= thickness || 2.0 * rc >= tile_nm[0] || 2.0 * rc >= tile_nm[1] {
        return Err(format!(
            "spheres of radius {radius_nm} nm do not fit in the layer ({thickness} nm) and tile"
        ));
    }
    // Placement tests the circumscribed radius within the room centres can take: beyond
    // the jamming limit of random sequential addition (about 0.38 for spheres, Feder 1980)
    // no placement can finish, so say so before trying.
    let room = (tile_nm[0] - 2.0 * rc) * (tile_nm[1] - 2.0 * rc) * (thickness - 2.0 * rc);
    let effective =
        volume_fraction * (rc / radius_nm).powi(3) * tile_nm[0] * tile_nm[1] * thickness / room;
    if effective > RSA_JAMMING_SPHERES {
        return Err(format!(
            "volume_fraction {volume_fraction} is {effective:.2} for placement (the icosphere's circumscribed radius and the layer's margins), above the {RSA_JAMMING_SPHERES} random sequential addition can reach: lower it, raise subdivisions, or widen the layer"
        ));
    }
    let v_sphere = 4.0 / 3.0 * PI * radius_nm.powi(3);
    let count = body_count(
        "sphere",
        volume_fraction * tile_nm[0] * tile_nm[1] * thickness / v_sphere,
        unit.triangles.len(),
    )?;
    let mut rng = Rng::new(seed, 0x5F4E);
    let mut centres: Vec<[f64; 3]> = Vec::with_capacity(count);
    let min_d2 = (2.0 * rc * 1.001).powi(2);
    // Only spheres in neighbouring cells can overlap a candidate: O(1) per attempt.
    let mut grid = NeighbourGrid::new(1.01 * min_d2.sqrt());
    let mut attempts = 0usize;
    while centres.len() < count {
        attempts += 1;
        if attempts > 2000 * count + 100_000 {
            return Err(format!(
                "could place only {} of {count} spheres without overlap; lower volume_fraction",
                centres.len()
            ));
        }
        let c = [
            rng.range(rc, tile_nm[0] - rc),
            rng.range(rc, tile_nm[1] - rc),
            rng.range(layer_nm[0] + rc, layer_nm[1] - rc),
        ];
        if grid.near(c).all(|k| {
            let o = centres[k];
            (o[0] - c[0]).powi(2) + (o[1] - c[1]).powi(2) + (o[2] - c[2]).powi(2) >= min_d2
        }) {
            grid.insert(c, centres.len());
            centres.push(c);
        }
    }
    Ok(centres
        .iter()
        .map(|c| Mesh {
            positions_nm: unit
                .positions_nm
                .iter()
                .map(|v| [c[0] + rc * v[0], c[1] + rc * v[1], c[2] + rc * v[2]])
                .collect(),
            triangles: unit.triangles.clone(),
        })
        .collect())
}

/// An oriented box: centre, three orthonormal axes and half extents.
#[derive(Clone, Copy, Debug)]
struct Obb {
    c: [f64; 3],
    axes: [[f64; 3]; 3],
    half: [f64; 3],
}

impl Obb {
    fn corners(&self) -> [[f64; 3]; 8] {
        let mut out = [[0.0; 3]; 8];
        for (i, o) in out.iter_mut().enumerate() {
            let s = [
                if i & 1 == 0 { -1.0 } else { 1.0 },
                if i & 2 == 0 { -1.0 } else { 1.0 },
                if i & 4 == 0 { -1.0 } else { 1.0 },
            ];
            *o = std::array::from_fn(|k| {
                self.c[k]
                    + s[0] * self.half[0] * self.axes[0][k]
                    + s[1] * self.half[1] * self.axes[1][k]
                    + s[2] * self.half[2] * self.axes[2][k]
            });
        }
        out
    }

    /// Closed box mesh with outward normals.
    fn mesh(&self) -> Mesh {
        let p = self.corners().to_vec();
        // Faces as quads of corner indices (bit 0 = x, 1 = y, 2 = z), outward.
        let quads = [
            [0, 2, 3, 1], // -z
            [4, 5, 7, 6], // +z
            [0, 1, 5, 4], // -y
            [2, 6, 7, 3], // +y
            [0, 4, 6, 2], // -x
            [1, 3, 7, 5], // +x
        ];
        let mut triangles = Vec::new();
        for q in quads {
            triangles.push([q[0], q[1], q[2]]);
            triangles.push([q[0], q[2], q[3]]);
        }
        let mut m = Mesh {
            positions_nm: p,
            triangles,
        };
        // A left-handed axis frame turns every face inside out: fix by the volume's sign.
        if enclosed_volume(&m) < 0.0 {
            for t in &mut m.triangles {
                t.swap(1, 2);
            }
        }
        m
    }

    /// Separating-axis test for two oriented boxes (Gottschalk, Lin & Manocha, "OBBTree",
    /// SIGGRAPH 1996): 15 candidate axes.
    fn overlaps(&self, o: &Obb) -> bool {
        let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let d = sub(o.c, self.c);
        let mut axes: Vec<[f64; 3]> = Vec::with_capacity(15);
        axes.extend(self.axes);
        axes.extend(o.axes);
        for a in self.axes {
            for b in o.axes {
                let c = cross(a, b);
                if dot(c, c) > 1e-18 {
                    axes.push(c);
                }
            }
        }
        for ax in axes {
            let ra: f64 = (0..3)
                .map(|i| self.half[i] * dot(self.axes[i], ax).abs())
                .sum();
            let rb: f64 = (0..3).map(|i| o.half[i] * dot(o.axes[i], ax).abs()).sum();
            if dot(d, ax).abs() > ra + rb {
                return false;
            }
        }
        true
    }
}

/// Square pearlescent flakes: platelets of side `size_nm` and thickness `thickness_nm`,
/// tilted from horizontal by an angle drawn from a normal distribution of standard
/// deviation `tilt_sd_deg` (about a random horizontal axis), with an optional coating shell
/// `coating_nm` thick, placed without overlap inside the layer and the tile to the
/// requested volume fraction of flake cores. Returns `(core, coating)` meshes per flake.
#[allow(clippy::too_many_arguments)]
pub fn flakes(
    seed: u64,
    tile_nm: [f64; 2],
    size_nm: f64,
    thickness_nm: f64,
    tilt_sd_deg: f64,
    coating_nm: f64,
    volume_fraction: f64,
    layer_nm: [f64; 2],
) -> Result<Vec<(Mesh, Option<Mesh>)>, String> {
    if !(size_nm > 0.0 && thickness_nm > 0.0 && thickness_nm < size_nm) {
        return Err(format!(
            "need 0 < thickness < size, got size {size_nm} nm, thickness {thickness_nm} nm"
        ));
    }
    if !(coating_nm >= 0.0 && tilt_sd_deg >= 0.0) {
        return Err("coating and tilt must be >= 0".into());
    }
    if !(volume_fraction > 0.0 && volume_fraction < 0.5) {
        return Err(format!(
            "volume_fraction must be in (0, 0.5), got {volume_fraction}"
        ));
    }
    let thickness = check_layer(layer_nm)?;
    let v_flake = size_nm * size_nm * thickness_nm;
    // 12 triangles per box, twice with a coating shell.
    let per_flake = if coating_nm > 0.0 { 24 } else { 12 };
    let count = body_count(
        "flake",
        volume_fraction * tile_nm[0] * tile_nm[1] * thickness / v_flake,
        per_flake,
    )?;
    let outer_half = [
        size_nm / 2.0 + coating_nm,
        size_nm / 2.0 + coating_nm,
        thickness_nm / 2.0 + coating_nm,
    ];
    let mut rng = Rng::new(seed, 0xF1A4E);
    let mut placed: Vec<Obb> = Vec::with_capacity(count);
    // Two boxes can overlap only if their centres are closer than twice the bounding
    // sphere radius of the (margin-enlarged) box.
    let bound = 1.001 * outer_half.iter().map(|h| h * h).sum::<f64>().sqrt();
    let mut grid = NeighbourGrid::new(1.01 * 2.0 * bound);
    let mut attempts = 0usize;
    while placed.len() < count {
        attempts += 1;
        if attempts > 5000 * count + 100_000 {
            return Err(format!(
                "could place only {} of {count} flakes without overlap; lower volume_fraction or the tilt",
                placed.len()
            ));
        }
        // Orientation: spin about z, then tilt about the rotated x axis.
        let spin = rng.range(0.0, TAU);
        let tilt = (tilt_sd_deg * rng.normal()).to_radians();
        let (cs, ss, ct, st) = (spin.cos(), spin.sin(), tilt.cos(), tilt.sin());
        let ax = [cs, ss, 0.0];
        let ay = [-ss * ct, cs * ct, st];
        let az = [ss * st, -cs * st, ct];
        let axes = [ax, ay, az];
        // Extent of the outer box along each world axis, to keep it inside tile and layer.
        let ext = |k: usize| {
            (0..3)
                .map(|i| outer_half[i] * axes[i][k].abs())
                .sum::<f64>()
        };
        let (ex, ey, ez) = (ext(0), ext(1), ext(2));
        if 2.0 * ex >= tile_nm[0] || 2.0 * ey >= tile_nm[1] || 2.0 * ez >= thickness {
            continue;
        }
        let c = [
            rng.range(ex, tile_nm[0] - ex),
            rng.range(ey, tile_nm[1] - ey),
            rng.range(layer_nm[0] + ez, layer_nm[1] - ez),
        ];
        // A 0.1 % margin keeps coatings of neighbours from touching.
        let cand = Obb {
            c,
            axes,
            half: outer_half.map(|h| h * 1.001),
        };
        if grid.near(c).all(|k| !placed[k].overlaps(&cand)) {
            grid.insert(c, placed.len());
            placed.push(cand);
        }
    }
    Ok(placed
        .iter()
        .map(|o| {
            let core = Obb {
                half: [size_nm / 2.0, size_nm / 2.0, thickness_nm / 2.0],
                ..*o
            };
            let shell = (coating_nm > 0.0).then(|| {
                Obb {
                    half: outer_half,
                    ..*o
                }
                .mesh()
            });
            (core.mesh(), shell)
        })
        .collect())
}

/// The most triangles one generator makes: 2^26 (67 million), about 10 GB once the
/// accelerators are built (`../shared/DESIGN.md` §2; the largest height field, resolution
/// 4096, makes 2 x 4096^2 = 33.5 million).
pub const MAX_GENERATED_TRIANGLES: u64 = 1 << 26;

/// The volume fraction beyond which random sequential addition of spheres cannot finish:
/// its jamming limit is 0.382 (Feder 1980, J. Theor. Biol. 87; Torquato, Uche & Stillinger
/// 2006, Phys. Rev. E 74), and the last percent takes unbounded attempts.
const RSA_JAMMING_SPHERES: f64 = 0.37;

/// The most bodies one generator places (each becomes an interface of its own).
pub const MAX_BODIES: u64 = 1_000_000;

/// Checks a body layer `[z0, z1]` (nm): finite, ordered, within the length limit; returns
/// its thickness.
fn check_layer(layer_nm: [f64; 2]) -> Result<f64, String> {
    let [z0, z1] = layer_nm;
    let lim = super::MAX_LENGTH_NM;
    if !(z0.is_finite() && z1.is_finite() && z0.abs() <= lim && z1.abs() <= lim) {
        return Err(format!(
            "layer = [{z0}, {z1}] nm must be finite and within +-{lim:e} nm"
        ));
    }
    if z1 <= z0 {
        return Err(format!(
            "layer = [z0, z1] needs z0 < z1, got [{z0}, {z1}] nm"
        ));
    }
    Ok(z1 - z0)
}

/// The number of bodies for an expected (real) count, checked before anything is
/// allocated: at least one, at most [`MAX_BODIES`] and [`MAX_GENERATED_TRIANGLES`].
fn body_count(what: &str, expected: f64, triangles_each: usize) -> Result<usize, String> {
    if !expected.is_finite() {
        return Err(format!("the {what} count is not finite: check the lengths"));
    }
    let count = expected.round();
    if count < 1.0 {
        return Err(format!(
            "the volume fraction gives no {what} in this tile; enlarge the tile or the fraction"
        ));
    }
    let triangles = count * triangles_each as f64;
    if count > MAX_BODIES as f64 || triangles > MAX_GENERATED_TRIANGLES as f64 {
        return Err(format!(
            "this tile and volume fraction need {count:.3e} {what}s ({triangles:.3e} triangles); the limits are {MAX_BODIES} bodies and {MAX_GENERATED_TRIANGLES} triangles: make the {what}s larger, the tile smaller or the fraction lower"
        ));
    }
    Ok(count as usize)
}

/// A uniform hash grid over points: a point's neighbours within one cell size lie in the
/// 27 cells around its own, which makes non-overlap placement O(1) per attempt instead of
/// O(n). The accept/reject decisions are those of testing every placed body.
struct NeighbourGrid {
    cell: f64,
    cells: HashMap<[i64; 3], Vec<usize>>,
}

impl NeighbourGrid {
    fn new(cell: f64) -> Self {
        NeighbourGrid {
            cell,
            cells: HashMap::new(),
        }
    }
    fn key(&self, p: [f64; 3]) -> [i64; 3] {
        p.map(|c| (c / self.cell).floor() as i64)
    }
    fn insert(&mut self, p: [f64; 3], id: usize) {
        self.cells.entry(self.key(p)).or_default().push(id);
    }
    /// Ids of the points in the 27 cells around `p`.
    fn near(&self, p: [f64; 3]) -> impl Iterator<Item = usize> + '_ {
        let k = self.key(p);
        (0..27).flat_map(move |n| {
            let d = [n % 3 - 1, n / 3 % 3 - 1, n / 9 - 1];
            let key = [k[0] + d[0], k[1] + d[1], k[2] + d[2]];
            self.cells.get(&key).into_iter().flatten().copied()
        })
    }
}

/// Which surface of a wavy film.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FilmSurface {
    Top,
    Bottom,
}

/// A generator as written in a sample (`generator = { kind = "...", ... }`) or on the
/// command line (`goniospec generate KIND --param key=value`). Lengths are in the sample's
/// unit; `resolution` counts grid cells per tile side.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum GeneratorSpec {
    /// A flat plane at height `z`.
    Flat {
        #[serde(default)]
        z: f64,
    },
    /// A periodic Gaussian random height field: RMS height `rms`, Gaussian correlation
    /// length `correlation_length`, mean height `z`.
    Gaussian {
        rms: f64,
        correlation_length: f64,
        resolution: usize,
        #[serde(default = "default_seed")]
        seed: u64,
        #[serde(default)]
        z: f64,
    },
    /// One surface of the seed's wavy film: both surfaces follow one Gaussian roughness
    /// (`roughness_rms`), and the thickness `thickness` varies by `thickness_rms`, both
    /// with correlation length `correlation_length`. The film's lower surface has mean
    /// height `z`. Use the same parameters and seed for `surface = "top"` and `"bottom"`.
    WavyFilm {
        surface: FilmSurface,
        thickness: f64,
        thickness_rms: f64,
        roughness_rms: f64,
        correlation_length: f64,
        resolution: usize,
        #[serde(default = "default_seed")]
        seed: u64,
        #[serde(default)]
        z: f64,
    },
    /// A microfacet surface whose facet normals follow GGX or Beckmann with roughness
    /// `alpha`; `resolution` facets per tile side.
    Microfacet {
        distribution: Distribution,
        alpha: f64,
        resolution: usize,
        /// Correlation length of the heights, in the sample's unit (default: tile / 8).
        correlation_length: Option<f64>,
        #[serde(default = "default_seed")]
        seed: u64,
        #[serde(default)]
        z: f64,
    },
    /// A gently curved sheet: `z + amplitude cos(2 pi x / Lx)`, one period across the tile
    /// along x, flat along y; `resolution` cells along x. The steepest slope is
    /// `atan(2 pi amplitude / Lx)`. Two sheets with the same amplitude and different `z`
    /// make a curved film of constant vertical thickness.
    Cosine {
        amplitude: f64,
        resolution: usize,
        #[serde(default)]
        z: f64,
    },
    /// A periodic wedge: `z + tan(slope_deg) |x - Lx/2|`, a roof of two planes of slope
    /// `slope_deg` across the tile (one kink at the centre, one at the edges). Over a flat
    /// sheet it makes a film whose thickness varies linearly, by `tan(slope) Lx / 2`.
    Wedge {
        slope_deg: f64,
        #[serde(default)]
        z: f64,
    },
    /// `count` symmetric V-grooves along y with opening angle `angle_deg`, ridges at `z`.
    VGrooves {
        angle_deg: f64,
        count: usize,
        #[serde(default)]
        z: f64,
    },
    /// Pigment spheres (bodies) in the layer `layer = [z0, z1]`.
    PigmentSpheres {
        radius: f64,
        volume_fraction: f64,
        #[serde(deserialize_with = "exactly_two")]
        layer: [f64; 2],
        #[serde(default = "default_subdivisions")]
        subdivisions: u32,
        #[serde(default = "default_seed")]
        seed: u64,
    },
    /// Square pearlescent flakes (bodies) in the layer `layer = [z0, z1]`, optionally
    /// coated (`coating` thickness; the body then needs a `coating` medium).
    Flakes {
        size: f64,
        thickness: f64,
        tilt_sd_deg: f64,
        #[serde(default)]
        coating: f64,
        volume_fraction: f64,
        #[serde(deserialize_with = "exactly_two")]
        layer: [f64; 2],
        #[serde(default = "default_seed")]
        seed: u64,
    },
}

/// A `[z0, z1]` pair: exactly two numbers (serde would otherwise ignore extra ones).
fn exactly_two<'de, D: serde::Deserializer<'de>>(d: D) -> Result<[f64; 2], D::Error> {
    let v = Vec::<f64>::deserialize(d)?;
    <[f64; 2]>::try_from(v.as_slice()).map_err(|_| {
        serde::de::Error::custom(format!(
            "expected [z0, z1] (two numbers), got {} values",
            v.len()
        ))
    })
}

fn default_seed() -> u64 {
    1
}
fn default_subdivisions() -> u32 {
    2
}

/// What a generator produced.
#[derive(Clone, Debug)]
pub enum Generated {
    /// A sheet spanning the tile.
    Sheet(Mesh),
    /// Closed bodies, each with an optional coating shell.
    Bodies(Vec<(Mesh, Option<Mesh>)>),
}

impl GeneratorSpec {
    /// The kind's name as written in TOML.
    pub fn kind(&self) -> &'static str {
        match self {
            GeneratorSpec::Flat { .. } => "flat",
            GeneratorSpec::Gaussian { .. } => "gaussian",
            GeneratorSpec::WavyFilm { .. } => "wavy-film",
            GeneratorSpec::Microfacet { .. } => "microfacet",
            GeneratorSpec::VGrooves { .. } => "v-grooves",
            GeneratorSpec::Cosine { .. } => "cosine",
            GeneratorSpec::Wedge { .. } => "wedge",
            GeneratorSpec::PigmentSpheres { .. } => "pigment-spheres",
            GeneratorSpec::Flakes { .. } => "flakes",
        }
    }

    /// Whether the generator makes closed bodies (else a sheet).
    pub fn makes_bodies(&self) -> bool {
        matches!(
            self,
            GeneratorSpec::PigmentSpheres { .. } | GeneratorSpec::Flakes { .. }
        )
    }

    /// Runs the generator; `u` is nanometres per sample unit. Sizes are checked before
    /// anything is allocated, and every coordinate of the result must be finite and within
    /// [`super::MAX_LENGTH_NM`] (a NaN `z` or a huge amplitude is refused, not written).
    pub fn generate(&self, tile_nm: [f64; 2], u: f64) -> Result<Generated, String> {
        let out = self.run(tile_nm, u)?;
        let meshes: Vec<&Mesh> = match &out {
            Generated::Sheet(m) => vec![m],
            Generated::Bodies(b) => b
                .iter()
                .flat_map(|(c, s)| std::iter::once(c).chain(s.as_ref()))
                .collect(),
        };
        let lim = super::MAX_LENGTH_NM;
        for m in meshes {
            if let Some(c) = m
                .positions_nm
                .iter()
                .flatten()
                .find(|c| !(c.is_finite() && c.abs() <= lim))
            {
                return Err(format!(
                    "a generated coordinate is {c:e} nm: lengths (z, amplitude, layer, ...) must be finite and keep the mesh within +-{lim:e} nm"
                ));
            }
        }
        Ok(out)
    }

    fn run(&self, tile_nm: [f64; 2], u: f64) -> Result<Generated, String> {
        Ok(match *self {
            GeneratorSpec::Flat { z } => Generated::Sheet(flat(tile_nm, z * u)),
            GeneratorSpec::Gaussian {
                rms,
                correlation_length,
                resolution,
                seed,
                z,
            } => {
                check_resolution(resolution)?;
                let h =
                    gaussian_heights(seed, tile_nm, resolution, rms * u, correlation_length * u)?;
                Generated::Sheet(grid_mesh(tile_nm, resolution, &h, z * u))
            }
            GeneratorSpec::WavyFilm {
                surface,
                thickness,
                thickness_rms,
                roughness_rms,
                correlation_length,
                resolution,
                seed,
                z,
            } => {
                check_resolution(resolution)?;
                let (t, l) = (thickness * u, correlation_length * u);
                if t.is_nan() || t <= 0.0 {
                    return Err(format!("thickness must be positive, got {thickness}"));
                }
                let rough = gaussian_heights(seed, tile_nm, resolution, roughness_rms * u, l)?;
                let var = gaussian_heights(
                    seed.wrapping_add(1),
                    tile_nm,
                    resolution,
                    thickness_rms * u,
                    l,
                )?;
                if let Some(min) = var.iter().map(|v| t + v).reduce(f64::min)
                    && min <= 0.0
                {
                    return Err(format!(
                        "the thickness variation makes the film vanish (minimum thickness {min:.1} nm); lower thickness_rms"
                    ));
                }
                let h: Vec<f64> = rough
                    .iter()
                    .zip(&var)
                    .map(|(r, v)| match surface {
                        FilmSurface::Top => t + r + v / 2.0,
                        FilmSurface::Bottom => r - v / 2.0,
                    })
                    .collect();
                Generated::Sheet(grid_mesh(tile_nm, resolution, &h, z * u))
            }
            GeneratorSpec::Microfacet {
                distribution,
                alpha,
                resolution,
                correlation_length,
                seed,
                z,
            } => {
                check_resolution(resolution)?;
                let corr = correlation_length.map_or(tile_nm[0] / 8.0, |l| l * u);
                Generated::Sheet(microfacet_surface(
                    seed,
                    tile_nm,
                    resolution,
                    distribution,
                    alpha,
                    corr,
                    z * u,
                )?)
            }
            GeneratorSpec::VGrooves {
                angle_deg,
                count,
                z,
            } => Generated::Sheet(v_grooves(tile_nm, count, angle_deg, z * u)?),
            GeneratorSpec::Cosine {
                amplitude,
                resolution,
                z,
            } => {
                check_resolution(resolution)?;
                if !amplitude.is_finite() {
                    return Err(format!("amplitude must be finite, got {amplitude}"));
                }
                let (a, z, lx) = (amplitude * u, z * u, tile_nm[0]);
                Generated::Sheet(height_field([resolution, 1], tile_nm, move |x, _| {
                    z + a * (std::f64::consts::TAU * x / lx).cos()
                }))
            }
            GeneratorSpec::Wedge { slope_deg, z } => {
                if slope_deg.is_nan() || slope_deg.abs() >= 45.0 {
                    return Err(format!(
                        "slope_deg must lie between -45 and 45 degrees, got {slope_deg}"
                    ));
                }
                let (s, z, lx) = (slope_deg.to_radians().tan(), z * u, tile_nm[0]);
                // Two cells along x put the kink exactly on a grid line.
                Generated::Sheet(height_field([2, 1], tile_nm, move |x, _| {
                    z + s * (x - lx / 2.0).abs()
                }))
            }
            GeneratorSpec::PigmentSpheres {
                radius,
                volume_fraction,
                layer,
                subdivisions,
                seed,
            } => {
                if subdivisions > 5 {
                    return Err(format!(
                        "subdivisions must be at most 5 (20 * 4^5 triangles per sphere), got {subdivisions}"
                    ));
                }
                Generated::Bodies(
                    pigment_spheres(
                        seed,
                        tile_nm,
                        radius * u,
                        volume_fraction,
                        layer.map(|v| v * u),
                        subdivisions,
                    )?
                    .into_iter()
                    .map(|m| (m, None))
                    .collect(),
                )
            }
            GeneratorSpec::Flakes {
                size,
                thickness,
                tilt_sd_deg,
                coating,
                volume_fraction,
                layer,
                seed,
            } => Generated::Bodies(flakes(
                seed,
                tile_nm,
                size * u,
                thickness * u,
                tilt_sd_deg,
                coating * u,
                volume_fraction,
                layer.map(|v| v * u),
            )?),
        })
    }
}

/// A height-field resolution: 1 to 4096 cells per side, and, since the mesh and the
/// spectral arrays behind it are built in memory, no more than this machine has
/// available (about 100 bytes per triangle while generating).
fn check_resolution(r: usize) -> Result<(), String> {
    if !(1..=4096).contains(&r) {
        return Err(format!(
            "resolution must be between 1 and 4096 cells per side, got {r}"
        ));
    }
    let bytes = 2.0 * (r as f64).powi(2) * GENERATE_BYTES_PER_TRIANGLE;
    if let Some(avail) = crate::io::available_memory_bytes()
        && bytes > avail as f64
    {
        return Err(format!(
            "resolution {r} needs about {:.1} GB to generate, more than the {:.1} GB available",
            bytes / 1e9,
            avail as f64 / 1e9
        ));
    }
    Ok(())
}

/// Bytes per height-field triangle while generating (mesh, heights, FFT buffers).
const GENERATE_BYTES_PER_TRIANGLE: f64 = 100.0;
