//! The C-method (Chandezon's curvilinear coordinates) for a 1-D relief `z = a(x)` between
//! two half-spaces in the classical mount (docs/physics.md, "The rigorous solver", "Smooth
//! bare reliefs: the C-method"); light off the plane across the grooves takes `conical.rs`,
//! and a relief with sharp corners is sampled in the stretched coordinate of `asr.rs`, which
//! changes `W`, `P`, `ε` and the plane waves' closed form below as that module says.
//!
//! A staircase of a smooth metal profile puts a right-angled metal corner at every step,
//! whose field singularities the Fourier modal method resolves only as `1 / M` in TM. In
//! the coordinates `(x, u = z - a(x))` the interface is the plane `u = 0` and nothing is
//! sliced: the Helmholtz equation for `F` (`E_y` in TE, `H_y` in TM), with lengths in units
//! of `1 / k0`, is the first-order system (Chandezon, Maystre & Raoult 1980, J. Opt. 11,
//! 235; in the form of Li, Chandezon, Granet & Plumey 1999, Appl. Opt. 38, 304)
//!
//! ```text
//! ∂u F = w (G + ȧ ∂x F),     ∂u G = −∂x (w ∂x F − w ȧ G) − ε F,     w = 1 / (1 + ȧ²)
//! ```
//!
//! where `G = (1 + ȧ²) ∂u F − ȧ ∂x F` is `|∇(z − a)|` times the normal derivative, so that
//! `F` and `G / η` (`η = 1` in TE, `ε` in TM) are continuous across `u = 0`. With Floquet
//! harmonics `α_n = n_1 sin θ + n λ / Λ` and the Toeplitz matrices `W = [[w]]`, `P =
//! [[w ȧ]]`, the modes `e^{iρu}` of a medium are the eigenvectors of
//!
//! ```text
//! M = [ i P α        W     ]       M [f; g] = iρ [f; g].
//!     [ α W α − ε    i α P ]
//! ```
//!
//! Plane waves are modes: `e^{i(α_n x ± β_n z)}` is `e^{±iβ_n u}` times `e^{i(α_n x ±
//! β_n a(x))}`, with `G = i(±β_n − α_n ȧ) F`. The propagating orders' modes are taken in
//! that closed form (their amplitudes are the orders' plane-wave amplitudes), the
//! evanescent ones from `M`: in the medium above those with `Re(iρ) < 0` (decaying upward),
//! below those with `Re(iρ) > 0`. Matching `F` and `G / η` harmonic by harmonic gives the
//! reflected and transmitted amplitudes.
//!
//! Flat planes above the relief (a lacquer's top) are joined order by order ([`super::flat`]):
//! the orders that reach the lowest plane are taken in closed form in the cover, evanescent
//! ones too, and the boundary is solved for a down-going wave of each (docs/physics.md,
//! "Reliefs under flat layers").

use faer::Mat;
use faer::linalg::solvers::Solve;
use glam::DVec3;

use super::{C64, Order, Profile, RcwaError, Solution};
use crate::optics::mueller::frame;

const I: C64 = C64::new(0.0, 1.0);

/// The profile's samples and their functions, and the Fourier coefficients the method
/// takes, `c[n + kmax]` for `n` in `-kmax..=kmax`. Where the relief has sharp corners the
/// samples are taken in the stretched coordinate `x₁` of [`super::asr`] (adaptive spatial
/// resolution); elsewhere `x₁ = x`, `φ = 1` and `shift = 0`.
pub(super) struct Sampled {
    /// `k0 a(f(x₁_i))` at `x₁_i = i Λ / S`.
    pub(super) a: Vec<f64>,
    /// `da/dx` at the same points: the spectral derivative of the samples, or the
    /// polyline's slope under the stretch.
    slope: Vec<f64>,
    /// The stretch's derivative `φ = dx / dx₁` (1 without one).
    phi: Vec<f64>,
    /// `k0 (f(x₁_i) − x₁_i)` (0 without a stretch).
    shift: Vec<f64>,
}

/// `Σ_i f_i e^{-2πi n i / S}` for each `n` of `orders` (`S` the length of `f`), from a
/// table of the `S` roots of unity (the exponent taken modulo `S`, so no sine is evaluated
/// per term).
fn dft(f: &[C64], orders: impl Iterator<Item = i64>) -> Vec<C64> {
    let s = f.len();
    let roots: Vec<C64> = (0..s)
        .map(|k| C64::from_polar(1.0, -2.0 * std::f64::consts::PI * k as f64 / s as f64))
        .collect();
    orders
        .map(|n| {
            let step = n.rem_euclid(s as i64) as usize;
            let (mut at, mut sum) = (0usize, C64::new(0.0, 0.0));
            for &v in f {
                sum += v * roots[at];
                at += step;
                if at >= s {
                    at -= s;
                }
            }
            sum
        })
        .collect()
}

/// `(1 / S) Σ f_i e^{-2πi n i / S}` for `n` in `-kmax..=kmax`.
fn coefficients(f: &[C64], kmax: usize) -> Vec<C64> {
    let k = kmax as i64;
    let s = f.len() as f64;
    dft(f, -k..=k).into_iter().map(|c| c / s).collect()
}

/// `Σ_k g_k e^{-2πi k i / S}` for every `i` in `0..S` (`S` the length of `g`), conjugated:
/// the inverse transform of `conj(g)`.
fn coefficients_at(g: &[C64]) -> Vec<C64> {
    dft(g, 0..g.len() as i64)
        .into_iter()
        .map(|c| c.conj())
        .collect()
}

#[cfg(test)]
thread_local! {
    /// A stretch the tests impose on a smooth relief, with its fixed points (nm): the same
    /// relief in other coordinates, which must give the same answer.
    pub(super) static STRETCH: std::cell::RefCell<Option<Vec<f64>>> =
        const { std::cell::RefCell::new(None) };
}

pub(super) fn sampled(p: &Profile, k0: f64) -> Sampled {
    let s = p.heights_nm.len();
    #[cfg(test)]
    if let Some(corners) = STRETCH.with(|c| c.borrow().clone()) {
        return tests::stretched_smooth(p, k0, &corners);
    }
    // A relief with sharp corners (a trapezoid's, a V-groove's): the stretched coordinate.
    let line = super::asr::polyline(&p.heights_nm, p.period_nm);
    let corners = line.corners();
    if !corners.is_empty() {
        let st = super::asr::stretch(&corners, p.period_nm, s);
        let (mut a, mut slope, mut phi, mut shift) = (
            Vec::with_capacity(s),
            Vec::with_capacity(s),
            Vec::with_capacity(s),
            Vec::with_capacity(s),
        );
        for (i, &(f, ph)) in st.iter().enumerate() {
            let (z, sl) = line.at(f);
            a.push(k0 * z);
            slope.push(sl);
            phi.push(ph);
            shift.push(k0 * (f - i as f64 * p.period_nm / s as f64));
        }
        return Sampled {
            a,
            slope,
            phi,
            shift,
        };
    }
    let h: Vec<C64> = p.heights_nm.iter().map(|&z| C64::new(z, 0.0)).collect();
    // The derivative of the samples' trigonometric interpolant (no Nyquist term).
    let kmax = (s - 1) / 2;
    let c = coefficients(&h, kmax);
    let two_pi_l = 2.0 * std::f64::consts::PI / p.period_nm;
    // ȧ(x_i) = Σ_n i n (2π / Λ) c_n e^{2πi n i / S}: the derivative's coefficients taken
    // back to the samples, conjugating the forward transform.
    let d: Vec<C64> = c
        .iter()
        .enumerate()
        .map(|(k, &ck)| (I * ((k as f64 - kmax as f64) * two_pi_l) * ck).conj())
        .collect();
    let mut full = vec![C64::new(0.0, 0.0); s];
    for (k, &dk) in d.iter().enumerate() {
        full[(k as i64 - kmax as i64).rem_euclid(s as i64) as usize] = dk;
    }
    // Σ_n d_n e^{2πi n i / S} = conj(Σ_n conj(d_n) e^{-2πi n i / S}) = S conj(c'_i).
    let back = coefficients_at(&full);
    let slope = back.iter().map(|b| b.re).collect();
    Sampled {
        a: p.heights_nm.iter().map(|z| k0 * z).collect(),
        slope,
        phi: vec![1.0; s],
        shift: vec![0.0; s],
    }
}

/// Toeplitz matrix `T_ij = c[i - j]` of `n` harmonics from coefficients `c[k + 2m]`.
fn toeplitz(c: &[C64], n: usize) -> Mat<C64> {
    let m = (n - 1) / 2;
    Mat::from_fn(n, n, |i, j| c[i + 2 * m - j])
}

/// A set of modes at `u = 0`: columns `[f; g]`.
pub(super) type Columns = Vec<(Vec<C64>, Vec<C64>)>;

/// The closed-form mode of the plane wave of harmonic `n` (index `idx` among the `N`)
/// travelling up (`up`) or down with `kz = beta` (propagating: real; or evanescent,
/// decaying away from the relief: `Im β > 0`): `f_m = c_{m-n}[e^{±iβa}]`, `g_m =
/// c_{m-n}[i(±β − α_n ȧ) e^{±iβa}]`.
pub(super) fn plane_wave(
    sm: &Sampled,
    alpha: f64,
    beta: C64,
    up: bool,
    idx: usize,
    n: usize,
) -> (Vec<C64>, Vec<C64>) {
    let sb = if up { beta } else { -beta };
    // Under a stretch, F = e^{iα(f − x₁)} e^{±iβa} and G = iφ(±β − α ȧ) F ([`super::asr`]).
    let e: Vec<C64> =
        sm.a.iter()
            .zip(&sm.shift)
            .map(|(&a, &sh)| (I * (sb * a + alpha * sh)).exp())
            .collect();
    let ge: Vec<C64> = e
        .iter()
        .zip(sm.slope.iter().zip(&sm.phi))
        .map(|(&e, (&d, &ph))| I * ph * (sb - alpha * d) * e)
        .collect();
    let kmax = n - 1;
    let (ce, cg) = (coefficients(&e, kmax), coefficients(&ge, kmax));
    // Row m (harmonic index) takes coefficient m - idx, at kmax + m - idx.
    let f = (0..n).map(|m| ce[kmax + m - idx]).collect();
    let g = (0..n).map(|m| cg[kmax + m - idx]).collect();
    (f, g)
}

/// The medium's evanescent modes that decay away from the interface (`up`: into `u > 0`),
/// from the eigenvectors of `M`, `count` of them.
pub(super) fn evanescent(
    sm: &Sampled,
    alpha: &[f64],
    eps: C64,
    up: bool,
    count: usize,
    kmax: usize,
) -> Result<Columns, RcwaError> {
    let n = alpha.len();
    if count == 0 {
        return Ok(Vec::new());
    }
    // Under a stretch w̃ = 1 / (φ (1 + ȧ²)) and ε φ ([`super::asr`]).
    let w: Vec<C64> = sm
        .slope
        .iter()
        .zip(&sm.phi)
        .map(|(d, ph)| C64::new(1.0 / (ph * (1.0 + d * d)), 0.0))
        .collect();
    let pw: Vec<C64> = sm
        .slope
        .iter()
        .zip(&sm.phi)
        .map(|(d, ph)| C64::new(d / (ph * (1.0 + d * d)), 0.0))
        .collect();
    let stretched = sm.phi.iter().any(|&ph| ph != 1.0);
    let tphi = stretched.then(|| {
        let phi: Vec<C64> = sm.phi.iter().map(|&ph| C64::new(ph, 0.0)).collect();
        toeplitz(&coefficients(&phi, kmax), n)
    });
    let (tw, tp) = (
        toeplitz(&coefficients(&w, kmax), n),
        toeplitz(&coefficients(&pw, kmax), n),
    );
    let m = Mat::from_fn(2 * n, 2 * n, |i, j| {
        let (bi, ii, bj, jj) = (i / n, i % n, j / n, j % n);
        match (bi, bj) {
            (0, 0) => I * tp[(ii, jj)] * alpha[jj],
            (0, _) => tw[(ii, jj)],
            (1, 0) => {
                let e = match &tphi {
                    Some(t) => eps * t[(ii, jj)],
                    None if ii == jj => eps,
                    None => C64::new(0.0, 0.0),
                };
                alpha[ii] * tw[(ii, jj)] * alpha[jj] - e
            }
            _ => I * alpha[ii] * tp[(ii, jj)],
        }
    });
    let evd = m.eigen().map_err(|_| RcwaError::Eigen(n))?;
    let (u, s) = (evd.U(), evd.S().column_vector());
    let mut idx: Vec<usize> = (0..2 * n).collect();
    // iρ's real part: negative for modes decaying upward, positive downward.
    idx.sort_by(|&a, &b| s[a].re.total_cmp(&s[b].re));
    let chosen: Vec<usize> = if up {
        idx[..count].to_vec()
    } else {
        idx[2 * n - count..].to_vec()
    };
    let scale = s.iter().map(|l| l.norm()).fold(1.0, f64::max);
    if chosen
        .iter()
        .any(|&k| if up { s[k].re } else { -s[k].re } > -1e-9 * scale)
    {
        return Err(RcwaError::Singular(
            "the C-method's evanescent modes do not separate from the propagating ones",
        ));
    }
    Ok(chosen
        .into_iter()
        .map(|k| {
            (
                (0..n).map(|i| u[(i, k)]).collect(),
                (0..n).map(|i| u[(n + i, k)]).collect(),
            )
        })
        .collect())
}

/// `kz / k0` of harmonic `alpha` in `eps` where it propagates.
pub(super) fn propagating(eps: C64, alpha: f64) -> Option<f64> {
    (eps.im == 0.0 && eps.re > alpha * alpha).then(|| (eps.re - alpha * alpha).sqrt())
}

/// The smallest amplitude, relative to its value at the relief's top, at which an
/// evanescent order of the cover reaching the lowest flat plane is still coupled to it:
/// orders decaying more over the gap are left to the numerical modes (their coupling
/// through the plane is below it).
const REACH: f64 = 1e-13;

/// The largest `κ (a_max − a_min)` (`κ = Im β`, in units of `k0`) of an evanescent order
/// taken in closed form: across the relief its Rayleigh mode's coefficients `c[e^{κa}]`
/// grow as `I_n(κ A)` and its expansion is valid there (the Rayleigh hypothesis for a
/// shallow relief: Petit & Cadilhac 1966); farther evanescent orders are the numerical
/// modes' (Li et al. 1999).
const CLOSED_FORM_KAPPA_DEPTH: f64 = 3.0;

/// The orders of a cover of (real) `k² = e1` taken in closed form: those propagating, and
/// where a flat plane lies `gap` above the relief's top (units of `1 / k0`) the evanescent
/// ones reaching it above [`REACH`] (refused past [`CLOSED_FORM_KAPPA_DEPTH`]), as
/// harmonic index and `β`.
pub(super) fn closed_form(
    sm: &Sampled,
    alpha: &[f64],
    e1: f64,
    gap: Option<f64>,
) -> Result<Vec<(usize, C64)>, RcwaError> {
    let (lo, hi) =
        sm.a.iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &a| {
                (l.min(a), h.max(a))
            });
    let mut cover = Vec::new();
    for (i, &a) in alpha.iter().enumerate() {
        if let Some(b) = propagating(C64::new(e1, 0.0), a) {
            cover.push((i, C64::new(b, 0.0)));
            continue;
        }
        let b = super::flat::beta(C64::new(e1, 0.0), a);
        let Some(g) = gap else { continue };
        if (-b.im * g).exp() <= REACH {
            continue;
        }
        if b.im * (hi - lo) > CLOSED_FORM_KAPPA_DEPTH {
            return Err(RcwaError::Unsupported(
                "a flat interface lies so close above the relief that evanescent orders deeper than the relief's Rayleigh expansion holds reach it: the C-method here cannot take it",
            ));
        }
        cover.push((i, b));
    }
    Ok(cover)
}

/// The relief's response in its cover, one matrix per polarisation (TE, TM): for unit
/// down-going amplitude (referred to `z = 0`) of each order in `cover`, the up-going
/// amplitudes of the same orders (`r`, rows and columns as `cover`) and the transmitted
/// amplitudes of `below`'s orders (`t`).
struct Response {
    /// The orders taken in closed form in the cover: harmonic index and `β`.
    cover: Vec<(usize, C64)>,
    /// The orders propagating in the half-space below: harmonic index and `β`.
    below: Vec<(usize, f64)>,
    r: [Mat<C64>; 2],
    t: [Mat<C64>; 2],
}

/// Solves the relief's boundary for every closed-form incident order at once. In the
/// cover, the propagating orders, and where a flat plane lies `gap` above the relief's top
/// (units of `1 / k0`) the evanescent orders that reach it above [`REACH`], are plane waves
/// in closed form; the rest of both media's modes come from `M`.
fn respond(
    sm: &Sampled,
    alpha: &[f64],
    e1: f64,
    e2: C64,
    gap: Option<f64>,
) -> Result<Response, RcwaError> {
    let n = alpha.len();
    let kmax = n - 1;
    let cover = closed_form(sm, alpha, e1, gap)?;
    let below: Vec<(usize, f64)> = (0..n)
        .filter_map(|i| propagating(e2, alpha[i]).map(|b| (i, b)))
        .collect();
    // Up-going modes above: the closed-form waves, then the evanescent modes.
    let mut above: Columns = cover
        .iter()
        .map(|&(i, b)| plane_wave(sm, alpha[i], b, true, i, n))
        .collect();
    above.extend(evanescent(
        sm,
        alpha,
        C64::new(e1, 0.0),
        true,
        n - cover.len(),
        kmax,
    )?);
    let mut down: Columns = below
        .iter()
        .map(|&(i, b)| plane_wave(sm, alpha[i], C64::new(b, 0.0), false, i, n))
        .collect();
    down.extend(evanescent(sm, alpha, e2, false, n - below.len(), kmax)?);
    let incident: Columns = cover
        .iter()
        .map(|&(i, b)| plane_wave(sm, alpha[i], b, false, i, n))
        .collect();
    let e1 = C64::new(e1, 0.0);
    let k = cover.len();
    let mut r = [Mat::zeros(k, k), Mat::zeros(k, k)];
    let mut t = [Mat::zeros(below.len(), k), Mat::zeros(below.len(), k)];
    for pol in 0..2 {
        // TE: F = E_y, η = 1; TM: F = H_y, η = ε.
        let eta = |e: C64| if pol == 1 { e } else { C64::new(1.0, 0.0) };
        let a = Mat::from_fn(2 * n, 2 * n, |row, c| {
            let (col, sign, e) = if c < n {
                (&above[c], 1.0, e1)
            } else {
                (&down[c - n], -1.0, e2)
            };
            if row < n {
                col.0[row] * sign
            } else {
                col.1[row - n] * sign / eta(e)
            }
        });
        let rhs = Mat::from_fn(2 * n, k, |row, j| {
            if row < n {
                -incident[j].0[row]
            } else {
                -incident[j].1[row - n] / eta(e1)
            }
        });
        let x = a.partial_piv_lu().solve(&rhs);
        if !x.norm_l2().is_finite() {
            return Err(RcwaError::Singular("the C-method's boundary system"));
        }
        r[pol] = Mat::from_fn(k, k, |row, j| x[(row, j)]);
        t[pol] = Mat::from_fn(below.len(), k, |row, j| x[(n + row, j)]);
    }
    Ok(Response { cover, below, r, t })
}

/// The flat planes, the cover's permittivity and the gap: [`cover`].
pub(super) type Cover = (Vec<(f64, C64)>, C64, Option<f64>);

/// The relief's flat planes in units of `1 / k0` (`(z, ε below)`, top first), the cover's
/// permittivity (which must be lossless) and the gap from the relief's top to the lowest
/// plane (units of `1 / k0`; `None` without planes).
pub(super) fn cover(p: &Profile, k0: f64, sm: &Sampled) -> Result<Cover, RcwaError> {
    let planes: Vec<(f64, C64)> = p
        .planes
        .iter()
        .map(|q| (k0 * q.z_nm, q.eps_below))
        .collect();
    let e_cover = planes.last().map_or(C64::new(p.eps_above, 0.0), |q| q.1);
    if e_cover.im != 0.0 || e_cover.re <= 0.0 {
        return Err(RcwaError::Unsupported(
            "the medium over the relief absorbs: the C-method here takes a lossless cover",
        ));
    }
    let top = sm.a.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let gap = planes.last().map(|q| q.0 - top);
    if gap.is_some_and(|g| g.is_nan() || g <= 0.0) {
        return Err(RcwaError::Unsupported(
            "a flat interface above the relief must lie above its highest point",
        ));
    }
    Ok((planes, e_cover, gap))
}

/// What both mounts start from: the sampled relief, the index above, the flat planes, the
/// cover and its gap ([`cover`]), and the harmonics' `k_x` (`α_n = n_1 d_x + n λ / Λ`).
pub(super) struct Setup {
    pub(super) sm: Sampled,
    pub(super) n1: f64,
    pub(super) e_top: C64,
    pub(super) planes: Vec<(f64, C64)>,
    pub(super) e_cover: C64,
    pub(super) gap: Option<f64>,
    pub(super) alpha: Vec<f64>,
}

impl Setup {
    pub(super) fn new(p: &Profile, lambda_nm: f64, d: DVec3, m: usize) -> Result<Setup, RcwaError> {
        if p.heights_nm.len() <= 4 * m + 1 {
            return Err(RcwaError::Unsupported(
                "the relief has fewer samples than the harmonics need (4 m + 2)",
            ));
        }
        let k0 = 2.0 * std::f64::consts::PI / lambda_nm;
        let sm = sampled(p, k0);
        let n1 = p.eps_above.sqrt();
        let (planes, e_cover, gap) = cover(p, k0, &sm)?;
        let alpha = (0..2 * m + 1)
            .map(|i| n1 * d.x + (i as f64 - m as f64) * lambda_nm / p.period_nm)
            .collect();
        Ok(Setup {
            sm,
            n1,
            e_top: C64::new(p.eps_above, 0.0),
            planes,
            e_cover,
            gap,
            alpha,
        })
    }
}

/// Solves the relief `p` (with its flat planes above) for light of `lambda_nm` along `d`
/// (unit, `d.y = 0`, `d.z < 0`) with harmonics `-m..=m` (the incidence checked by
/// [`super::solve_profile`]).
pub(super) fn solve(
    p: &Profile,
    lambda_nm: f64,
    d: DVec3,
    m: usize,
) -> Result<Solution, RcwaError> {
    if d.y != 0.0 {
        return Err(RcwaError::Unsupported(
            "the classical C-method takes light in the plane across the grooves (conical.rs takes the rest)",
        ));
    }
    let Setup {
        sm,
        n1,
        e_top,
        planes,
        e_cover,
        gap,
        alpha,
    } = Setup::new(p, lambda_nm, d, m)?;
    let n = alpha.len();
    let resp = respond(&sm, &alpha, e_cover.re, p.eps_below, gap)?;
    // The orders leaving into the half-space above.
    let up: Vec<(usize, f64)> = (0..n)
        .filter_map(|i| propagating(e_top, alpha[i]).map(|b| (i, b)))
        .collect();
    let k = resp.cover.len();
    let at = |i: usize| resp.cover.iter().position(|c| c.0 == i);
    let mut amps = [
        vec![C64::new(0.0, 0.0); up.len() + resp.below.len()],
        vec![C64::new(0.0, 0.0); up.len() + resp.below.len()],
    ];
    for (pol, out) in amps.iter_mut().enumerate() {
        let sc: Vec<_> = resp
            .cover
            .iter()
            .map(|&(i, _)| super::flat::stack(e_top, &planes, alpha[i], 0.0, pol == 1))
            .collect();
        let inc = super::flat::stack(e_top, &planes, alpha[m], 0.0, pol == 1);
        // In the cover, D = t e_m + r_back U and U = R D: (I − r_back R) D = t e_m.
        let rr = &resp.r[pol];
        let down = match at(m) {
            Some(mi) => {
                let a = Mat::from_fn(k, k, |i, j| {
                    let id = if i == j { 1.0 } else { 0.0 };
                    C64::new(id, 0.0) - sc[i].r_back * rr[(i, j)]
                });
                let b = Mat::from_fn(
                    k,
                    1,
                    |i, _| if i == mi { inc.t } else { C64::new(0.0, 0.0) },
                );
                a.partial_piv_lu().solve(&b)
            }
            None => Mat::zeros(k, 1),
        };
        let upc = rr * &down;
        let tr = &resp.t[pol] * &down;
        if !(upc.norm_l2().is_finite() && tr.norm_l2().is_finite()) {
            return Err(RcwaError::Singular("the C-method's flat layers"));
        }
        for (slot, &(i, _)) in up.iter().enumerate() {
            let direct = if i == m { inc.r } else { C64::new(0.0, 0.0) };
            out[slot] = direct + at(i).map_or(C64::new(0.0, 0.0), |j| sc[j].t_back * upc[(j, 0)]);
        }
        for slot in 0..resp.below.len() {
            out[up.len() + slot] = tr[(slot, 0)];
        }
    }
    let beta0 = -n1 * d.z;
    let orders: Vec<(usize, f64, bool, C64)> = up
        .iter()
        .map(|&(i, b)| (i, b, true, e_top))
        .chain(resp.below.iter().map(|&(i, b)| (i, b, false, p.eps_below)))
        .collect();
    Ok(assemble(&alpha, &orders, &amps, n1, beta0, d, m))
}

/// The solution from each leaving order's amplitudes per unit incident `F` (TE and TM):
/// its Jones matrix in the frames of `mueller::frame`, scaled so that `|J|²` is the
/// efficiency.
fn assemble(
    alpha: &[f64],
    orders: &[(usize, f64, bool, C64)],
    amps: &[Vec<C64>; 2],
    n1: f64,
    beta0: f64,
    d: DVec3,
    m: usize,
) -> Solution {
    let (p_in, s_in) = frame(d);
    let mut sol = Solution::default();
    for (slot, &(i, b, up, e)) in orders.iter().enumerate() {
        let nm = e.re.sqrt();
        let dir = DVec3::new(alpha[i], 0.0, if up { b } else { -b }) / nm;
        let (p_out, s_out) = frame(dir);
        // Unit incident E along `e_in`: TE part F = ŷ·E, TM part F = H_y = n1 ŷ·(d × E).
        // The order's E: TE F ŷ, TM (1 / n) H × k̂ with H = F ŷ; scaled so that |J|² is
        // the efficiency (power flux ∝ |E|² kz).
        let scale = (b / beta0).sqrt();
        let field = |e_in: DVec3| {
            let te = amps[0][slot] * DVec3::Y.dot(e_in);
            let tm = amps[1][slot] * (n1 * DVec3::Y.dot(d.cross(e_in))) / nm;
            let y_cross_k = DVec3::Y.cross(dir);
            let onto = |v: DVec3| (te * DVec3::Y.dot(v) + tm * y_cross_k.dot(v)) * scale;
            (onto(p_out), onto(s_out))
        };
        let (pp, sp) = field(p_in);
        let (ps, ss) = field(s_in);
        let o = Order {
            m: [i as i64 - m as i64, 0],
            up,
            dir,
            jones: [pp, ps, sp, ss],
        };
        let tot = if up { &mut sol.r } else { &mut sol.t };
        tot[0] += o.efficiency(0);
        tot[1] += o.efficiency(1);
        sol.orders.push(o);
    }
    sol
}

#[cfg(test)]
mod tests;
