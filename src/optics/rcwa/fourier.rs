//! The permittivity's Fourier (Toeplitz) matrices of one patterned slice, with Li's
//! factorisation rules (docs/physics.md, "The rigorous solver").
//!
//! A slice's permittivity is a pixel grid over the tile: pixel `(ix, iy)` covers
//! `[ix, ix + 1) Λx / nx × [iy, iy + 1) Λy / ny`. Its Fourier coefficients are those of
//! that staircase exactly, `c_pq = Σ f (1 / nx ny) e^{-2πi (p (ix + ½) / nx + q (iy + ½) /
//! ny)} sinc(π p / nx) sinc(π q / ny)`, so the pixel count sets the geometry's resolution
//! and the harmonics the field's.
//!
//! The product of two functions that jump together at a boundary converges in Fourier space
//! only when the product is continuous there and is written with the inverse rule (Li 1996,
//! "Use of Fourier series in the analysis of discontinuous periodic structures", JOSA A 13,
//! 1870): `[[ε]] E` for a field component tangential to the boundary (Laurent's rule),
//! `[[1/ε]]^{-1} E` for the normal one. A pixel grid has boundaries along x and y only, so
//! Li's rule for crossed gratings holds exactly (Li 1997, "New formulation of the Fourier
//! modal method for crossed surface-relief gratings", JOSA A 14, 2758): `ε_xx` is the
//! inverse rule along x then Laurent's along y, `ε_yy` the reverse, and `1 / ε_zz` the
//! inverse of `[[ε]]`. For a grating patterned along one axis these reduce to the 1-D
//! rules, which is what makes TM converge on metals.

use faer::Mat;
use faer::linalg::solvers::DenseSolveCore;

use super::{C64, Grid, Harmonics, RcwaError};

fn sinc(u: f64) -> f64 {
    if u == 0.0 { 1.0 } else { u.sin() / u }
}

/// The staircase's Fourier coefficients along one axis of `n` pixels, `values[i]` at
/// pixel `i`, for orders `-k..=k` (index `p + k`).
fn coefficients_1d(values: impl Iterator<Item = C64> + Clone, n: usize, k: usize) -> Vec<C64> {
    (-(k as i64)..=k as i64)
        .map(|p| {
            let u = std::f64::consts::PI * p as f64 / n as f64;
            // e^{-2iu (i + ½)} by rotation from e^{-iu}: n complex products in place of n
            // sines and cosines (rounding grows as n ε, 1e-13 at the pixel counts used).
            let step = C64::new((2.0 * u).cos(), -(2.0 * u).sin());
            let mut w = C64::new(u.cos(), -u.sin());
            let mut sum = C64::new(0.0, 0.0);
            for v in values.clone() {
                sum += v * w;
                w *= step;
            }
            sum * (sinc(u) / n as f64)
        })
        .collect()
}

/// `[[f]]`: the Toeplitz matrix of a grid function `f` over the harmonics `h` (Laurent's
/// rule in both axes).
pub fn laurent(grid: &Grid, h: Harmonics, f: impl Fn(C64) -> C64) -> Mat<C64> {
    let [nx, ny] = grid.n;
    let [kx, ky] = [2 * h.m[0], 2 * h.m[1]];
    // Along x per row, then along y per x-order.
    let rows: Vec<Vec<C64>> = (0..ny)
        .map(|iy| {
            coefficients_1d(
                grid.eps[iy * nx..(iy + 1) * nx].iter().map(|&e| f(e)),
                nx,
                kx,
            )
        })
        .collect();
    let c: Vec<Vec<C64>> = (0..=2 * kx)
        .map(|p| coefficients_1d(rows.iter().map(|r| r[p]), ny, ky))
        .collect();
    Mat::from_fn(h.count(), h.count(), |i, j| {
        let ([p, q], [p2, q2]) = (h.pq(i), h.pq(j));
        c[(p - p2 + kx as i64) as usize][(q - q2 + ky as i64) as usize]
    })
}

/// Li's rule for the component normal to boundaries across `axis` (0: `ε_xx`, 1: `ε_yy`):
/// along `axis`, each line of pixels' `[[1/ε]]^{-1}`; along the other axis, Laurent's rule
/// over those matrices' entries.
pub fn inverse_rule(grid: &Grid, h: Harmonics, axis: usize) -> Result<Mat<C64>, RcwaError> {
    let nx = grid.n[0];
    let other = 1 - axis;
    let (n_along, n_across) = (grid.n[axis], grid.n[other]);
    let (m_along, m_across) = (h.m[axis], h.m[other]);
    let w = 2 * m_along + 1;
    let at = |along: usize, across: usize| {
        if axis == 0 {
            grid.eps[across * nx + along]
        } else {
            grid.eps[along * nx + across]
        }
    };
    // One inverted Toeplitz matrix per line of pixels along `axis`.
    let mut lines: Vec<Mat<C64>> = Vec::with_capacity(n_across);
    for a in 0..n_across {
        let c = coefficients_1d((0..n_along).map(|i| 1.0 / at(i, a)), n_along, 2 * m_along);
        let t = Mat::from_fn(w, w, |i, j| c[i + 2 * m_along - j]);
        let inv = t.partial_piv_lu().inverse();
        if !inv.norm_l2().is_finite() {
            return Err(RcwaError::Singular("the inverse rule's Toeplitz matrix"));
        }
        lines.push(inv);
    }
    // Laurent across: entry (i, j) of every line's matrix, transformed over the lines.
    let k = 2 * m_across;
    let mut across: Vec<Vec<C64>> = Vec::with_capacity(w * w);
    for i in 0..w {
        for j in 0..w {
            across.push(coefficients_1d(
                lines.iter().map(|l| l[(i, j)]),
                n_across,
                k,
            ));
        }
    }
    Ok(Mat::from_fn(h.count(), h.count(), |r, c| {
        let ([p, q], [p2, q2]) = (h.pq(r), h.pq(c));
        let (a, a2, b, b2) = if axis == 0 {
            (p, p2, q, q2)
        } else {
            (q, q2, p, p2)
        };
        let i = (a + m_along as i64) as usize;
        let j = (a2 + m_along as i64) as usize;
        across[i * w + j][(b - b2 + k as i64) as usize]
    }))
}
