//! The solver proper (module docs in [`super`]): each slice's modes, the interfaces'
//! scattering matrices, Redheffer's star product, and the propagating orders.

use faer::Mat;
use faer::linalg::solvers::{DenseSolveCore, Solve};
use glam::DVec3;

use super::fourier;
use super::{C64, Grid, Harmonics, Order, RcwaError, Slab, Solution, Structure};
use crate::optics::mueller::frame;

/// A slice's modes: `W` (`None`: the identity), `V` and the propagation constants `γ`.
struct Modes {
    w: Option<Mat<C64>>,
    v: Mat<C64>,
    gamma: Vec<C64>,
}

/// The branch of `sqrt(g2)` that decays or travels into the slice: `Im γ > 0`, or `γ > 0`
/// when real to rounding. A propagation constant of exactly zero (an order at grazing
/// exit, Rayleigh's anomaly) is moved off zero so the modes stay independent.
fn branch(g2: C64) -> C64 {
    let mut g = g2.sqrt();
    if g.im < -1e-12 * g.norm() {
        g = -g;
    }
    if g.norm() < 1e-10 {
        g = C64::new(1e-10, 1e-10);
    }
    g
}

/// The wave-vector matrices: `Kx`, `Ky` on the diagonal, in units of `k0`.
struct Wavevectors {
    kx: Vec<f64>,
    ky: Vec<f64>,
}

fn q_matrix(k: &Wavevectors, exx: &Mat<C64>, eyy: &Mat<C64>) -> Mat<C64> {
    let n = k.kx.len();
    Mat::from_fn(2 * n, 2 * n, |i, j| {
        let (bi, ii, bj, jj) = (i / n, i % n, j / n, j % n);
        let diag = if ii == jj { 1.0 } else { 0.0 };
        let (kx, ky) = (k.kx[ii], k.ky[ii]);
        match (bi, bj) {
            (0, 0) => C64::new(-kx * ky * diag, 0.0),
            (0, _) => C64::new(kx * kx * diag, 0.0) - eyy[(ii, jj)],
            (1, 0) => exx[(ii, jj)] - C64::new(ky * ky * diag, 0.0),
            _ => C64::new(ky * kx * diag, 0.0),
        }
    })
}

fn homogeneous(k: &Wavevectors, eps: C64) -> Modes {
    let n = k.kx.len();
    let gamma: Vec<C64> = (0..n)
        .map(|i| branch(eps - k.kx[i] * k.kx[i] - k.ky[i] * k.ky[i]))
        .collect();
    let e = Mat::from_fn(n, n, |i, j| if i == j { eps } else { C64::new(0.0, 0.0) });
    let q = q_matrix(k, &e, &e);
    let g2: Vec<C64> = gamma.iter().chain(&gamma).copied().collect();
    let v = Mat::from_fn(2 * n, 2 * n, |i, j| -q[(i, j)] / g2[j]);
    Modes {
        w: None,
        v,
        gamma: g2,
    }
}

fn patterned(k: &Wavevectors, grid: &Grid, h: Harmonics) -> Result<Modes, RcwaError> {
    let n = k.kx.len();
    let eps = fourier::laurent(grid, h, |e| e);
    let ez_inv = eps.partial_piv_lu().inverse();
    if !ez_inv.norm_l2().is_finite() {
        return Err(RcwaError::Singular("the permittivity's Toeplitz matrix"));
    }
    let exx = fourier::inverse_rule(grid, h, 0)?;
    let eyy = fourier::inverse_rule(grid, h, 1)?;
    let q = q_matrix(k, &exx, &eyy);
    // P from Kx εz⁻¹ and Ky εz⁻¹ (diagonal K scales rows and columns).
    let p = Mat::from_fn(2 * n, 2 * n, |i, j| {
        let (bi, ii, bj, jj) = (i / n, i % n, j / n, j % n);
        let e = ez_inv[(ii, jj)];
        let id = if ii == jj { 1.0 } else { 0.0 };
        match (bi, bj) {
            (0, 0) => e * (k.kx[ii] * k.ky[jj]),
            (0, _) => C64::new(id, 0.0) - e * (k.kx[ii] * k.kx[jj]),
            (1, 0) => e * (k.ky[ii] * k.ky[jj]) - C64::new(id, 0.0),
            _ => -e * (k.ky[ii] * k.kx[jj]),
        }
    });
    let omega2 = &p * &q;
    let evd = omega2.eigen().map_err(|_| RcwaError::Eigen(n))?;
    let w = evd.U().to_owned();
    let gamma: Vec<C64> = evd.S().column_vector().iter().map(|&l| branch(l)).collect();
    let qw = &q * &w;
    let v = Mat::from_fn(2 * n, 2 * n, |i, j| -qw[(i, j)] / gamma[j]);
    Ok(Modes {
        w: Some(w),
        v,
        gamma,
    })
}

/// In the classical mount (`ky = 0` for every harmonic) `P` and `Q` have no diagonal
/// blocks, so `PQ = diag(P_xy Q_yx, P_yx Q_xy)`: the modes with `E_x` (and `H_y`: TM for a
/// grating along x) and those with `E_y` (and `H_x`: TE) never mix, and every matrix after
/// them (interfaces, star products) is block diagonal too. Block `b` (0: `E_x`, 1: `E_y`)
/// of slab `slab` has `N x N` modes: the `2N x 2N` eigenproblem's cost (`O(N^3)`) split in
/// two quarters, and the same for the scattering matrices.
fn block_modes(k: &Wavevectors, slab: &Slab, h: Harmonics, b: usize) -> Result<Modes, RcwaError> {
    let n = k.kx.len();
    let kx = &k.kx;
    let grid = match slab {
        Slab::Grid(g) => g,
        &Slab::Uniform(eps) => {
            let gamma: Vec<C64> = kx.iter().map(|&x| branch(eps - x * x)).collect();
            // V = -Q W Γ⁻¹ with W = I: Q_yx = ε for E_x, Q_xy = kx² - ε for E_y.
            let v = Mat::from_fn(n, n, |i, j| {
                if i != j {
                    C64::new(0.0, 0.0)
                } else if b == 0 {
                    -eps / gamma[j]
                } else {
                    -(kx[j] * kx[j] - eps) / gamma[j]
                }
            });
            return Ok(Modes { w: None, v, gamma });
        }
    };
    // The block's Q (Q_yx = ε_xx, or Q_xy = Kx² - ε_yy) and P Q.
    let (q, omega2) = if b == 0 {
        let eps = fourier::laurent(grid, h, |e| e);
        let ez_inv = eps.partial_piv_lu().inverse();
        if !ez_inv.norm_l2().is_finite() {
            return Err(RcwaError::Singular("the permittivity's Toeplitz matrix"));
        }
        let exx = fourier::inverse_rule(grid, h, 0)?;
        // P_xy = I - Kx εz⁻¹ Kx.
        let p = Mat::from_fn(n, n, |i, j| {
            C64::new(if i == j { 1.0 } else { 0.0 }, 0.0) - ez_inv[(i, j)] * (kx[i] * kx[j])
        });
        let omega2 = &p * &exx;
        (exx, omega2)
    } else {
        let eyy = fourier::inverse_rule(grid, h, 1)?;
        // P_yx = -I, so P_yx Q_xy = ε_yy - Kx².
        let q = Mat::from_fn(n, n, |i, j| {
            C64::new(if i == j { kx[i] * kx[i] } else { 0.0 }, 0.0) - eyy[(i, j)]
        });
        let omega2 = Mat::from_fn(n, n, |i, j| -q[(i, j)]);
        (q, omega2)
    };
    let evd = omega2.eigen().map_err(|_| RcwaError::Eigen(n))?;
    let w = evd.U().to_owned();
    let gamma: Vec<C64> = evd.S().column_vector().iter().map(|&l| branch(l)).collect();
    let qw = &q * &w;
    let v = Mat::from_fn(n, n, |i, j| -qw[(i, j)] / gamma[j]);
    Ok(Modes {
        w: Some(w),
        v,
        gamma,
    })
}

/// A scattering matrix: `[c_a^-; c_b^+] = [[s11, s12], [s21, s22]] [c_a^+; c_b^-]`, `a` above
/// and `b` below, `+` down-going and `-` up-going.
struct Smatrix {
    s11: Mat<C64>,
    s12: Mat<C64>,
    s21: Mat<C64>,
    s22: Mat<C64>,
}

fn identity(n: usize) -> Mat<C64> {
    Mat::from_fn(n, n, |i, j| C64::new(if i == j { 1.0 } else { 0.0 }, 0.0))
}

fn left_solve(a: &Option<Mat<C64>>, b: &Option<Mat<C64>>, n: usize) -> Mat<C64> {
    match (a, b) {
        (None, None) => identity(n),
        (None, Some(b)) => b.clone(),
        (Some(a), None) => a.partial_piv_lu().inverse(),
        (Some(a), Some(b)) => a.partial_piv_lu().solve(b),
    }
}

/// The interface from slice `a` (above) into slice `b`: continuity of `e` and `h`,
/// `[[Wa, Wa], [Va, -Va]] c_a = [[Wb, Wb], [Vb, -Vb]] c_b`.
fn interface(a: &Modes, b: &Modes) -> Result<Smatrix, RcwaError> {
    let n = a.gamma.len();
    let ww = left_solve(&a.w, &b.w, n);
    let vv = a.v.partial_piv_lu().solve(&b.v);
    let t11 = Mat::from_fn(n, n, |i, j| 0.5 * (ww[(i, j)] + vv[(i, j)]));
    let t12 = Mat::from_fn(n, n, |i, j| 0.5 * (ww[(i, j)] - vv[(i, j)]));
    let lu = t11.partial_piv_lu();
    let t11_inv = lu.inverse();
    if !t11_inv.norm_l2().is_finite() {
        return Err(RcwaError::Singular("an interface's coupling matrix"));
    }
    let t12_t11inv = &t12 * &t11_inv;
    Ok(Smatrix {
        s12: &t11 - &t12_t11inv * &t12,
        s22: -(&t11_inv * &t12),
        s11: t12_t11inv,
        s21: t11_inv,
    })
}

/// Redheffer's star product: `A` above `B`.
fn star(a: &Smatrix, b: &Smatrix) -> Smatrix {
    let n = a.s11.nrows();
    let id = identity(n);
    let d1 = (&id - &b.s11 * &a.s22).partial_piv_lu(); // (I − B11 A22)
    let d2 = (&id - &a.s22 * &b.s11).partial_piv_lu(); // (I − A22 B11)
    let x1 = d1.solve(&b.s11 * &a.s21);
    let x2 = d1.solve(&b.s12);
    let y1 = d2.solve(&a.s21);
    let y2 = d2.solve(&a.s22 * &b.s12);
    Smatrix {
        s11: &a.s11 + &a.s12 * &x1,
        s12: &a.s12 * &x2,
        s21: &b.s21 * &y1,
        s22: &b.s22 + &b.s21 * &y2,
    }
}

/// Slice `m` of thickness `d` (in units of `1 / k0`) after the scattering matrix `s`.
fn propagate(s: Smatrix, m: &Modes, d: f64) -> Smatrix {
    let n = m.gamma.len();
    let x: Vec<C64> = m
        .gamma
        .iter()
        .map(|&g| (C64::new(0.0, 1.0) * g * d).exp())
        .collect();
    // The slice's own matrix is [[0, X], [X, 0]]; its star product written out.
    Smatrix {
        s11: s.s11,
        s12: Mat::from_fn(n, n, |i, j| s.s12[(i, j)] * x[j]),
        s21: Mat::from_fn(n, n, |i, j| x[i] * s.s21[(i, j)]),
        s22: Mat::from_fn(n, n, |i, j| x[i] * s.s22[(i, j)] * x[j]),
    }
}

/// [`super::solve`], with faer (the incidence checked there).
pub(super) fn solve(
    s: &Structure,
    lambda_nm: f64,
    d: DVec3,
    h: Harmonics,
) -> Result<Solution, RcwaError> {
    let n_above = s.eps_above.sqrt();
    let n = h.count();
    let k = Wavevectors {
        kx: (0..n)
            .map(|i| n_above * d.x + h.pq(i)[0] as f64 * lambda_nm / s.period_nm[0])
            .collect(),
        ky: (0..n)
            .map(|i| n_above * d.y + h.pq(i)[1] as f64 * lambda_nm / s.period_nm[1])
            .collect(),
    };
    let k0 = 2.0 * std::f64::consts::PI / lambda_nm;
    let above = homogeneous(&k, C64::new(s.eps_above, 0.0));
    let below = homogeneous(&k, s.eps_below);
    let total = if k.ky.iter().all(|&y| y == 0.0) {
        // The classical mount: two independent N x N problems (`block_modes`).
        let x = chain(s, k0, |slab| block_modes(&k, slab, h, 0))?;
        let y = chain(s, k0, |slab| block_modes(&k, slab, h, 1))?;
        let diag = |a: &Mat<C64>, b: &Mat<C64>| {
            Mat::from_fn(2 * n, 2 * n, |i, j| match (i / n, j / n) {
                (0, 0) => a[(i, j)],
                (1, 1) => b[(i - n, j - n)],
                _ => C64::new(0.0, 0.0),
            })
        };
        Smatrix {
            s11: diag(&x.s11, &y.s11),
            s12: diag(&x.s12, &y.s12),
            s21: diag(&x.s21, &y.s21),
            s22: diag(&x.s22, &y.s22),
        }
    } else {
        chain(s, k0, |slab| match slab {
            Slab::Uniform(e) => Ok(homogeneous(&k, *e)),
            Slab::Grid(g) => patterned(&k, g, h),
        })?
    };
    Ok(orders(&k, &total, h, d, s, &above, &below))
}

/// The stack's scattering matrix, each slab's modes (the half-spaces' too) from `modes`.
fn chain(
    s: &Structure,
    k0: f64,
    modes: impl Fn(&Slab) -> Result<Modes, RcwaError>,
) -> Result<Smatrix, RcwaError> {
    let above = modes(&Slab::Uniform(C64::new(s.eps_above, 0.0)))?;
    let below = modes(&Slab::Uniform(s.eps_below))?;
    let layers: Vec<Modes> = s
        .layers
        .iter()
        .map(|l| modes(&l.slab))
        .collect::<Result<_, _>>()?;
    let mut total: Option<Smatrix> = None;
    let mut prev = &above;
    for (l, m) in s.layers.iter().zip(&layers) {
        let i = interface(prev, m)?;
        let joined = match total {
            None => i,
            Some(t) => star(&t, &i),
        };
        total = Some(propagate(joined, m, l.thickness_nm * k0));
        prev = m;
    }
    let last = interface(prev, &below)?;
    Ok(match total {
        None => last,
        Some(t) => star(&t, &last),
    })
}

/// The propagating orders' Jones matrices from the stack's scattering matrix.
fn orders(
    k: &Wavevectors,
    sm: &Smatrix,
    h: Harmonics,
    d: DVec3,
    s: &Structure,
    above: &Modes,
    below: &Modes,
) -> Solution {
    let n = h.count();
    let zero = (0..n)
        .find(|&i| h.pq(i) == [0, 0])
        .expect("the zero harmonic is kept");
    let (p_in, s_in) = frame(d);
    let gamma_in = above.gamma[zero].re;
    // Columns: the incident s and p fields' (E_x, E_y) at the zero harmonic.
    let reflected: Vec<Mat<C64>> = [s_in, p_in]
        .iter()
        .map(|e| {
            let mut inc = Mat::<C64>::zeros(2 * n, 1);
            inc[(zero, 0)] = C64::new(e.x, 0.0);
            inc[(n + zero, 0)] = C64::new(e.y, 0.0);
            inc
        })
        .flat_map(|inc| [&sm.s11 * &inc, &sm.s21 * &inc])
        .collect();
    let mut sol = Solution::default();
    let lossless_below = s.eps_below.im == 0.0 && s.eps_below.re > 0.0;
    for (side, modes, eps) in [
        (0usize, above, C64::new(s.eps_above, 0.0)),
        (1, below, s.eps_below),
    ] {
        if side == 1 && !lossless_below {
            continue;
        }
        let n_med = eps.re.sqrt();
        for i in 0..n {
            let g = modes.gamma[i];
            if g.im.abs() > 1e-9 * g.norm() || g.re <= 0.0 {
                continue; // evanescent
            }
            let up = side == 0;
            let gz = if up { g.re } else { -g.re };
            let dir = DVec3::new(k.kx[i], k.ky[i], gz) / n_med;
            let dir = dir.normalize();
            let (p_out, s_out) = frame(dir);
            let scale = (g.re / gamma_in).sqrt();
            let mut jones = [C64::new(0.0, 0.0); 4];
            // Column 1: incident s (vectors 0, 1); column 0: incident p (vectors 2, 3).
            for (col, pol) in [(1usize, 0usize), (0, 1)] {
                let amp = &reflected[2 * pol + side];
                let (ex, ey) = (amp[(i, 0)], amp[(n + i, 0)]);
                let ez = -(ex * k.kx[i] + ey * k.ky[i]) / gz;
                let e = [ex, ey, ez];
                let dot = |v: DVec3| (e[0] * v.x + e[1] * v.y + e[2] * v.z) * scale;
                jones[col] = dot(p_out);
                jones[2 + col] = dot(s_out);
            }
            let o = Order {
                m: h.pq(i),
                up,
                dir,
                jones,
            };
            let tot = if up { &mut sol.r } else { &mut sol.t };
            tot[0] += o.efficiency(0);
            tot[1] += o.efficiency(1);
            sol.orders.push(o);
        }
    }
    sol
}
