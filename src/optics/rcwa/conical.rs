//! The C-method in conical incidence: light whose plane of incidence is not across the
//! grooves (`k_y = γ k0 ≠ 0`, an azimuth other than 0), on a relief bare or under flat
//! layers (docs/physics.md, "Conical incidence: the C-method").
//!
//! With every field `∝ e^{iγy}`, `E_y` and `H_y` (`h = Z0 H`) each obey the 2-D Helmholtz
//! equation with `κ² = ε − γ²` in place of `ε`, so each medium's modes are those of
//! [`super::cmethod`] with `κ²`, shared by both fields. The transverse fields follow from
//! Maxwell's curl equations (units of `k0`, `∇×E = i h`, `∇×h = −iεE`):
//!
//! ```text
//! E_x = (i / κ²)(γ ∂x E_y − ∂z h_y),     E_z = (i / κ²)(∂x h_y + γ ∂z E_y)
//! h_x = (i / κ²)(γ ∂x h_y + ε ∂z E_y),   h_z = (i / κ²)(γ ∂z h_y − ε ∂x E_y)
//! ```
//!
//! so along the surface's tangent `(1, 0, ȧ)`, with `∂x|_u = ∂x + ȧ ∂z` (`iα` on harmonics
//! at `u = 0`) and `G = ∂z F − ȧ ∂x F`,
//!
//! ```text
//! E_t = (i / κ²)(iγα E_y − G_h),         h_t = (i / κ²)(iγα h_y + ε G_e)
//! ```
//!
//! and `E_y`, `h_y`, `E_t / i` and `h_t / i` are matched harmonic by harmonic: `4N`
//! equations for the `N` modes of each field in each medium. The two fields couple through
//! `γα / κ²`, which differs between the media (the coordinate transformation method in
//! conical incidence: Granet, "Coordinate Transformation Methods", ch. 8 of Popov (ed.),
//! "Gratings: Theory and Numeric Applications", Presses universitaires de Provence 2012; the
//! first-order form of Li, Chandezon, Granet & Plumey 1999, Appl. Opt. 38, 304); at `γ = 0`
//! the system splits into the classical TE (`E_y`, `G_e`) and TM (`h_y`, `G_h / ε`).
//!
//! Flat planes above the relief do not couple orders, but do couple `E_y` and `h_y`; they
//! keep each order's s and p waves (E, or h, along `ŝ = (−γ, α_n, 0) / |k_t|`) apart, so
//! the relief's response is taken to that basis order by order,
//!
//! ```text
//! [E_y; h_y] = [ α/k_t        γ k_z/(ε k_t) ] [S; P]
//!              [ −γ k_z/k_t   α/k_t         ]
//! ```
//!
//! (determinant `κ² / ε`), and joined to the planes' s (`q = β`) and p (`q = β / ε`)
//! scalars ([`super::flat`]).

use faer::Mat;
use faer::linalg::solvers::Solve;
use glam::DVec3;

use super::cmethod::{Columns, Sampled, Setup, closed_form, evanescent, plane_wave, propagating};
use super::flat;
use super::{C64, Order, Profile, RcwaError, Solution};
use crate::optics::mueller::frame;

const I: C64 = C64::new(0.0, 1.0);
const ZERO: C64 = C64::new(0.0, 0.0);
const ONE: C64 = C64::new(1.0, 0.0);

/// `ŝ`'s components `(α / k_t, γ / k_t)` of the harmonic `(α, γ)`; `(1, 0)` along the
/// normal, where `ŝ = ŷ`.
fn s_hat(alpha: f64, gamma: f64) -> (f64, f64) {
    let kt = alpha.hypot(gamma);
    if kt == 0.0 {
        (1.0, 0.0)
    } else {
        (alpha / kt, gamma / kt)
    }
}

/// The 2 x 2 map from an order's s and p amplitudes to its `E_y` and `h_y` amplitudes, in a
/// medium of permittivity `eps`, for a wave with `k_z = kz` (units of `k0`).
fn to_fields(alpha: f64, gamma: f64, kz: C64, eps: C64) -> [[C64; 2]; 2] {
    let (c, s) = s_hat(alpha, gamma);
    [
        [C64::new(c, 0.0), s * kz / eps],
        [-s * kz, C64::new(c, 0.0)],
    ]
}

fn inverse(t: [[C64; 2]; 2]) -> [[C64; 2]; 2] {
    let det = t[0][0] * t[1][1] - t[0][1] * t[1][0];
    [
        [t[1][1] / det, -t[0][1] / det],
        [-t[1][0] / det, t[0][0] / det],
    ]
}

/// The electric field of a plane wave of `k = (alpha, gamma, kz)` in `eps` with `E_y = ae`
/// and `h_y = ah`.
fn field(alpha: f64, gamma: f64, kz: C64, eps: C64, ae: C64, ah: C64) -> [C64; 3] {
    let k2 = eps - gamma * gamma;
    [
        -(gamma * alpha * ae - kz * ah) / k2,
        ae,
        -(alpha * ah + gamma * kz * ae) / k2,
    ]
}

/// The relief's response in its cover: for a unit down-going wave of each closed-form
/// order, E-type then H-type (`2k` columns), the up-going closed-form amplitudes (`r`,
/// `2k` rows: `E_y` of each order, then `h_y`) and the transmitted ones (`t`, `2 nb` rows).
struct Response {
    cover: Vec<(usize, C64)>,
    below: Vec<(usize, f64)>,
    r: Mat<C64>,
    t: Mat<C64>,
}

fn respond(
    sm: &Sampled,
    alpha: &[f64],
    gamma: f64,
    (e1, e2): (C64, C64),
    gap: Option<f64>,
) -> Result<Response, RcwaError> {
    let n = alpha.len();
    let kmax = n - 1;
    let (k1, k2) = (e1 - gamma * gamma, e2 - gamma * gamma);
    if k1.norm() < 1e-9 || k2.norm() < 1e-9 {
        return Err(RcwaError::Singular(
            "a medium's permittivity equals the light's k_y^2 (its fields along the grooves cannot carry the others)",
        ));
    }
    let cover = closed_form(sm, alpha, k1.re, gap)?;
    let below: Vec<(usize, f64)> = (0..n)
        .filter_map(|i| propagating(k2, alpha[i]).map(|b| (i, b)))
        .collect();
    let mut above: Columns = cover
        .iter()
        .map(|&(i, b)| plane_wave(sm, alpha[i], b, true, i, n))
        .collect();
    above.extend(evanescent(sm, alpha, k1, true, n - cover.len(), kmax)?);
    let mut down: Columns = below
        .iter()
        .map(|&(i, b)| plane_wave(sm, alpha[i], C64::new(b, 0.0), false, i, n))
        .collect();
    down.extend(evanescent(sm, alpha, k2, false, n - below.len(), kmax)?);
    let incident: Columns = cover
        .iter()
        .map(|&(i, b)| plane_wave(sm, alpha[i], b, false, i, n))
        .collect();
    // Row `r` of the four conditions for a mode `(f, g)` of type E (`h = false`) or H in a
    // medium of `(κ², ε)`.
    let entry = |col: &(Vec<C64>, Vec<C64>), h: bool, (kk, e): (C64, C64), row: usize| {
        let (block, i) = (row / n, row % n);
        let (f, g) = (col.0[i], col.1[i]);
        let iga = I * gamma * alpha[i];
        match (block, h) {
            (0, false) | (1, true) => f,
            (0, true) | (1, false) => ZERO,
            (2, false) => iga * f / kk,
            (2, true) => -g / kk,
            (3, false) => e * g / kk,
            _ => iga * f / kk,
        }
    };
    let a = Mat::from_fn(4 * n, 4 * n, |row, c| {
        let (side, h, j) = (c / (2 * n), (c / n) % 2 == 1, c % n);
        if side == 0 {
            entry(&above[j], h, (k1, e1), row)
        } else {
            -entry(&down[j], h, (k2, e2), row)
        }
    });
    let k = cover.len();
    let rhs = Mat::from_fn(4 * n, 2 * k, |row, c| {
        -entry(&incident[c % k], c >= k, (k1, e1), row)
    });
    let x = a.partial_piv_lu().solve(&rhs);
    if !x.norm_l2().is_finite() {
        return Err(RcwaError::Singular("the C-method's boundary system"));
    }
    let nb = below.len();
    let r = Mat::from_fn(2 * k, 2 * k, |row, c| x[((row / k) * n + row % k, c)]);
    let t = Mat::from_fn(2 * nb, 2 * k, |row, c| {
        x[(2 * n + (row / nb) * n + row % nb, c)]
    });
    Ok(Response { cover, below, r, t })
}

/// Solves the relief `p` (with its flat planes above) for light of `lambda_nm` along `d`
/// (unit, `d.z < 0`, any azimuth) with harmonics `-m..=m`.
pub(super) fn solve(
    p: &Profile,
    lambda_nm: f64,
    d: DVec3,
    m: usize,
) -> Result<Solution, RcwaError> {
    let Setup {
        sm,
        n1,
        e_top,
        planes,
        e_cover,
        gap,
        alpha,
    } = Setup::new(p, lambda_nm, d, m)?;
    let gamma = n1 * d.y;
    let resp = respond(&sm, &alpha, gamma, (e_cover, p.eps_below), gap)?;
    let k = resp.cover.len();
    let (r_sp, down_t) = in_s_and_p(&resp, &alpha, gamma, e_cover);
    // Each closed-form order's flat stack, s then p.
    let sc: Vec<[flat::Scalar; 2]> = resp
        .cover
        .iter()
        .map(|&(i, _)| [false, true].map(|tm| flat::stack(e_top, &planes, alpha[i], gamma, tm)))
        .collect();
    let inc_sc = [false, true].map(|tm| flat::stack(e_top, &planes, alpha[m], gamma, tm));
    let at = |i: usize| resp.cover.iter().position(|c| c.0 == i);
    let lu = Mat::from_fn(2 * k, 2 * k, |row, c| {
        let id = if row == c { ONE } else { ZERO };
        id - sc[row % k][row / k].r_back * r_sp[(row, c)]
    })
    .partial_piv_lu();
    // The incident wave's s and p amplitudes for incident p and s light (`frame`).
    let (p_in, s_in) = frame(d);
    let (c0, s0) = s_hat(alpha[m], gamma);
    let s_vec = DVec3::new(-s0, c0, 0.0);
    let kin = d * n1;
    let split = |e: DVec3| (e.dot(s_vec), kin.cross(e).dot(s_vec));
    let states = [split(p_in), split(s_in)];
    // Per incident state: (E of each reflected order, E of each transmitted order).
    let mut fields: Vec<Vec<[C64; 3]>> = Vec::with_capacity(2);
    for &(si, pi) in &states {
        let b = Mat::from_fn(2 * k, 1, |row, _| match at(m) {
            Some(mi) if row % k == mi => inc_sc[row / k].t * if row < k { si } else { pi },
            _ => ZERO,
        });
        let dn = lu.solve(&b);
        let up = &r_sp * &dn;
        // The transmitted waves from the cover's down-going E_y and h_y.
        let dn_eh = Mat::from_fn(2 * k, 1, |row, _| {
            let (o, j) = (row / k, row % k);
            down_t[j][o][0] * dn[(j, 0)] + down_t[j][o][1] * dn[(k + j, 0)]
        });
        let tr = &resp.t * &dn_eh;
        if !(up.norm_l2().is_finite() && tr.norm_l2().is_finite()) {
            return Err(RcwaError::Singular("the C-method's flat layers"));
        }
        let mut out = Vec::new();
        for (i, &a) in alpha.iter().enumerate() {
            let Some(bt) = propagating(e_top - gamma * gamma, a) else {
                continue;
            };
            let direct = |pol: usize, amp: f64| if i == m { inc_sc[pol].r * amp } else { ZERO };
            let (s_amp, p_amp) = match at(i) {
                Some(j) => (
                    direct(0, si) + sc[j][0].t_back * up[(j, 0)],
                    direct(1, pi) + sc[j][1].t_back * up[(k + j, 0)],
                ),
                None => (direct(0, si), direct(1, pi)),
            };
            out.push(s_and_p_field(a, gamma, bt, e_top, s_amp, p_amp));
        }
        let nb = resp.below.len();
        for (slot, &(i, b)) in resp.below.iter().enumerate() {
            let kz = C64::new(-b, 0.0);
            out.push(field(
                alpha[i],
                gamma,
                kz,
                p.eps_below,
                tr[(slot, 0)],
                tr[(nb + slot, 0)],
            ));
        }
        fields.push(out);
    }
    let ups = alpha
        .iter()
        .enumerate()
        .filter_map(|(i, &a)| propagating(e_top - gamma * gamma, a).map(|b| (i, b, true, e_top)));
    let downs = resp.below.iter().map(|&(i, b)| (i, b, false, p.eps_below));
    let leaving: Vec<_> = ups.chain(downs).collect();
    let sol = assemble(&alpha, gamma, &leaving, &fields, -n1 * d.z, m);
    Ok(sol)
}

/// The relief's response in each closed-form order's s and p waves, `R_sp = T_up⁻¹ R
/// T_down` block by order, and each order's `T_down` (its down-going waves' `E_y`, `h_y`).
fn in_s_and_p(
    resp: &Response,
    alpha: &[f64],
    gamma: f64,
    e_cover: C64,
) -> (Mat<C64>, Vec<[[C64; 2]; 2]>) {
    let k = resp.cover.len();
    let t_of = |j: usize, up: bool| {
        let (i, b) = resp.cover[j];
        to_fields(alpha[i], gamma, if up { b } else { -b }, e_cover)
    };
    let down_t: Vec<_> = (0..k).map(|j| t_of(j, false)).collect();
    let up_inv: Vec<_> = (0..k).map(|j| inverse(t_of(j, true))).collect();
    let r_sp = Mat::from_fn(2 * k, 2 * k, |row, c| {
        let (ro, rj, co, cj) = (row / k, row % k, c / k, c % k);
        let mut v = ZERO;
        for (a, inv) in up_inv[rj][ro].iter().enumerate() {
            for (b, t) in down_t[cj].iter().enumerate() {
                v += inv * resp.r[(a * k + rj, b * k + cj)] * t[co];
            }
        }
        v
    });
    (r_sp, down_t)
}

/// The electric field of the wave `(alpha, gamma, kz)` in `eps` with s amplitude `s_amp`
/// (`E = S ŝ`) and p amplitude `p_amp` (`h = P ŝ`, `E = −(k × h) / ε`).
fn s_and_p_field(alpha: f64, gamma: f64, kz: f64, eps: C64, s_amp: C64, p_amp: C64) -> [C64; 3] {
    let (c, s) = s_hat(alpha, gamma);
    let sv = [C64::new(-s, 0.0), C64::new(c, 0.0), ZERO];
    let kv = [alpha, gamma, kz];
    let h = sv.map(|x| x * p_amp);
    let kxh = [
        kv[1] * h[2] - kv[2] * h[1],
        kv[2] * h[0] - kv[0] * h[2],
        kv[0] * h[1] - kv[1] * h[0],
    ];
    [0, 1, 2].map(|q| sv[q] * s_amp - kxh[q] / eps)
}

/// The solution from each leaving order `(harmonic, kz, up, ε)` and its electric field for
/// incident p (`fields[0]`) and s light: Jones matrices in the frames of `mueller::frame`,
/// scaled so that `|J|²` is the efficiency (flux `∝ |E|² k_z`, over the incident `beta0`).
fn assemble(
    alpha: &[f64],
    gamma: f64,
    leaving: &[(usize, f64, bool, C64)],
    fields: &[Vec<[C64; 3]>],
    beta0: f64,
    m: usize,
) -> Solution {
    let mut sol = Solution::default();
    for (slot, &(i, b, up, e)) in leaving.iter().enumerate() {
        let nm = e.re.sqrt();
        let dir = DVec3::new(alpha[i], gamma, if up { b } else { -b }) / nm;
        let (p_out, s_out) = frame(dir);
        let scale = (b / beta0).sqrt();
        let onto = |f: &[C64; 3], v: DVec3| (f[0] * v.x + f[1] * v.y + f[2] * v.z) * scale;
        let (fp, fs) = (&fields[0][slot], &fields[1][slot]);
        let o = Order {
            m: [i as i64 - m as i64, 0],
            up,
            dir,
            jones: [
                onto(fp, p_out),
                onto(fs, p_out),
                onto(fp, s_out),
                onto(fs, s_out),
            ],
        };
        let tot = if up { &mut sol.r } else { &mut sol.t };
        tot[0] += o.efficiency(0);
        tot[1] += o.efficiency(1);
        sol.orders.push(o);
    }
    sol
}
