//! Microfacet height fields: facet normals drawn from GGX or Beckmann, integrated
//! into a periodic height field by least squares (FFT).

use super::GenerateError;
use std::f64::consts::{PI, TAU};

use glam::DVec3;

use serde::Deserialize;

use super::super::mesh::Mesh;
use super::height::{gaussian_heights, grid_mesh};

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
    pub fn sample(self, alpha: f64, u1: f64, u2: f64) -> DVec3 {
        let tan2 = match self {
            Distribution::Beckmann => -alpha * alpha * (1.0 - u1).ln(),
            Distribution::Ggx => alpha * alpha * u1 / (1.0 - u1),
        };
        let cos_t = 1.0 / (1.0 + tan2).sqrt();
        let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
        let phi = TAU * u2;
        DVec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t)
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
) -> Result<Mesh, GenerateError> {
    if cells == 0 {
        return Err("resolution must be at least 1".into());
    }
    if !(alpha.is_finite() && alpha > 0.0) {
        return Err(GenerateError::from(format!(
            "alpha must be positive, got {alpha}"
        )));
    }
    let n = cells;
    let spacing = [tile_nm[0] / n as f64, tile_nm[1] / n as f64];
    let h_nm = spacing[0].max(spacing[1]);
    if !(corr_nm.is_finite() && corr_nm >= MIN_CELLS_PER_CORRELATION * h_nm) {
        return Err(GenerateError::from(format!(
            "correlation_length {corr_nm} nm spans fewer than {MIN_CELLS_PER_CORRELATION} grid cells of {h_nm:.1} nm: raise resolution to at least {} or the correlation length",
            (MIN_CELLS_PER_CORRELATION * tile_nm[0].max(tile_nm[1]) / corr_nm).ceil()
        )));
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
