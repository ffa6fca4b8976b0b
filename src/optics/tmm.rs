//! The transfer-matrix method (TMM) for a flat layered stack with complex indices: the
//! analytic reference every flat sample is checked against.
//!
//! Formulation of S. J. Byrnes, "Multilayer optical calculations", arXiv:1603.02720
//! (2016), §3 (eqs. 13–22); equivalent to Born & Wolf §1.6. Layer 0 is the ambient medium
//! (real index), the last layer the substrate; both semi-infinite.

use super::C64;
use super::fresnel::n_cos;

/// Reflectance and transmittance (fractions of incident power) of a stack.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rt {
    pub r_s: f64,
    pub r_p: f64,
    pub t_s: f64,
    pub t_p: f64,
    /// `r_p conj(r_s)` of the reflected amplitudes (the p coefficient of the transverse H
    /// field, as `amplitudes` gives it): the reflected Mueller matrix's `m22 + i m23` in
    /// the s/p frames of `optics::mueller` (docs/physics.md, "Polarisation").
    pub rp_rs: C64,
}

impl Rt {
    /// Unpolarised reflectance: the mean of s and p.
    pub fn r(&self) -> f64 {
        0.5 * (self.r_s + self.r_p)
    }
    /// Unpolarised transmittance.
    pub fn t(&self) -> f64 {
        0.5 * (self.t_s + self.t_p)
    }
    /// The ellipsometric phase difference `arg(r_p conj r_s)`, degrees (of the band
    /// average where [`solve_band`] made it).
    pub fn delta_deg(&self) -> f64 {
        self.rp_rs.im.atan2(self.rp_rs.re).to_degrees()
    }
    fn add_scaled(&mut self, o: &Rt, w: f64) {
        self.rp_rs += w * o.rp_rs;
        self.r_s += w * o.r_s;
        self.r_p += w * o.r_p;
        self.t_s += w * o.t_s;
        self.t_p += w * o.t_p;
    }
}

/// A stack for the TMM: indices from ambient to substrate, and thicknesses (nm) of the
/// inner layers.
#[derive(Clone, Debug)]
pub struct StackIndices {
    /// `n + i k` of ambient, layers (top first) and substrate.
    pub n: Vec<C64>,
    /// Thickness of each inner layer (len = n.len() - 2), nm.
    pub d_nm: Vec<f64>,
}

/// A layer whose phase thickness has an imaginary part above this (its amplitude falls by
/// `e^-30` across it) is factored out of the transfer matrix (`amplitudes`).
const OPAQUE: f64 = 30.0;
/// The transfer matrix is rescaled when an entry grows past this.
const RESCALE: f64 = 1e150;

/// Amplitude reflection and transmission coefficients `(r, t)` of a stack for s (`[0]`)
/// and p (`[1]`) light at wavelength `lambda_nm`, for a wave whose tangential index
/// `n sin(theta)` is `kx` (conserved through the stack). `n` runs from the incidence
/// medium (first) to the exit medium (last); `d_nm` are the inner layers' thicknesses. The
/// coefficients are ratios of E-field amplitudes in the convention of
/// `optics::fresnel` (Byrnes eqs. 13-17), so a stack without inner layers gives the bare
/// interface's Fresnel coefficients.
///
/// # Panics
/// When the number of thicknesses does not match the number of inner layers.
pub fn amplitudes(n: &[C64], d_nm: &[f64], kx: C64, lambda_nm: f64) -> [(C64, C64); 2] {
    assert_eq!(d_nm.len() + 2, n.len(), "one thickness per inner layer");
    // Normal indices and cosines are formed on the fly: a coated interface calls this once
    // per ray event, which must not allocate.
    let nc = |j: usize| n_cos(n[j], kx);
    if nc(0) == C64::new(0.0, 0.0) {
        // Grazing incidence (sin(theta) rounds to 1 in the incidence medium): the limit of
        // both Fresnel coefficients is -1 and nothing enters (Born & Wolf §1.5.2).
        return [(C64::new(-1.0, 0.0), C64::new(0.0, 0.0)); 2];
    }
    let last = n.len() - 1;
    let solve_pol = |p: bool| -> (C64, C64) {
        let interface = |j: usize, k: usize| -> (C64, C64) {
            let (nj, nk) = (n[j], n[k]);
            let (qj, qk) = (nc(j), nc(k));
            if p {
                let (cj, ck) = (qj / nj, qk / nk);
                let den = nk * cj + nj * ck;
                ((nk * cj - nj * ck) / den, 2.0 * nj * cj / den)
            } else {
                let den = qj + qk;
                ((qj - qk) / den, 2.0 * qj / den)
            }
        };
        // M = (1/t01) [[1, r01], [r01, 1]] * prod_j (1/t_j,j+1) P_j [[1, r], [r, 1]]
        let (r01, t01) = interface(0, 1);
        let mut m = [
            [C64::new(1.0, 0.0) / t01, r01 / t01],
            [r01 / t01, C64::new(1.0, 0.0) / t01],
        ];
        // Factors taken out of M to keep it finite: the sum of the opaque layers' phase
        // thicknesses (their e^{-i delta}) and the log of rescalings. r = M10 / M00 does
        // not see them; t = 1 / M00 is divided by them at the end (and rounds to 0 where a
        // stack is opaque, rather than overflowing to NaN: a 10 um metal layer or 4,000
        // layers did).
        let (mut opaque_delta, mut log_scale) = (C64::new(0.0, 0.0), 0.0);
        for j in 1..last {
            let delta = 2.0 * std::f64::consts::PI * nc(j) * d_nm[j - 1] / lambda_nm;
            let (r, t) = interface(j, j + 1);
            let l = if delta.im < OPAQUE {
                let (em, ep) = ((-C64::i() * delta).exp(), (C64::i() * delta).exp());
                [[em / t, em * r / t], [ep * r / t, ep / t]]
            } else {
                // An absorbing layer many decay lengths thick: e^{-i delta} (of modulus
                // e^{Im delta}) is taken out, leaving e^{2 i delta}, which rounds to 0.
                opaque_delta += delta;
                let e2 = (2.0 * C64::i() * delta).exp();
                [[1.0 / t, r / t], [e2 * r / t, e2 / t]]
            };
            m = [
                [
                    m[0][0] * l[0][0] + m[0][1] * l[1][0],
                    m[0][0] * l[0][1] + m[0][1] * l[1][1],
                ],
                [
                    m[1][0] * l[0][0] + m[1][1] * l[1][0],
                    m[1][0] * l[0][1] + m[1][1] * l[1][1],
                ],
            ];
            let big = m.iter().flatten().map(|x| x.norm()).fold(0.0, f64::max);
            if big > RESCALE {
                for x in m.iter_mut().flatten() {
                    *x /= big;
                }
                log_scale += big.ln();
            }
        }
        let mut t = C64::new(1.0, 0.0) / m[0][0];
        if opaque_delta != C64::new(0.0, 0.0) || log_scale != 0.0 {
            t *= (C64::i() * opaque_delta - log_scale).exp();
        }
        (m[1][0] / m[0][0], t)
    };
    [solve_pol(false), solve_pol(true)]
}

/// R and T of the stack at wavelength `lambda_nm` for incidence at `theta0_rad` in the
/// ambient medium.
///
/// # Panics
/// When the number of thicknesses does not match the number of inner layers.
pub fn solve(stack: &StackIndices, lambda_nm: f64, theta0_rad: f64) -> Rt {
    let n0 = stack.n[0];
    let kx = n0 * theta0_rad.sin(); // conserved n sin(theta)
    let [(rs, ts), (rp, tp)] = amplitudes(&stack.n, &stack.d_nm, kx, lambda_nm);
    let last = stack.n.len() - 1;
    let (nc0, ncl) = (n_cos(n0, kx), n_cos(stack.n[last], kx));
    let (cos0, cosl) = (nc0 / n0, ncl / stack.n[last]);
    // Byrnes eqs. 21-22 (no transmitted power at grazing incidence, where Re(nc0) = 0).
    let ratio = |num: f64, den: f64| if den > 0.0 { num / den } else { 0.0 };
    let ratio_s = ratio(ncl.re, nc0.re);
    let ratio_p = ratio((stack.n[last] * cosl.conj()).re, (n0 * cos0.conj()).re);
    Rt {
        r_s: rs.norm_sqr(),
        r_p: rp.norm_sqr(),
        t_s: (ts.norm_sqr() * ratio_s).max(0.0),
        t_p: (tp.norm_sqr() * ratio_p).max(0.0),
        rp_rs: rp * rs.conj(),
    }
}

/// R and T averaged over the wavelength band `[lo_nm, hi_nm]` (composite Simpson rule,
/// fine enough to resolve the stack's thin-film fringes): what a jittered wavelength bin
/// converges to. `stack_at` gives the indices at each wavelength (dispersive media).
pub fn solve_band(
    stack_at: impl Fn(f64) -> StackIndices,
    lo_nm: f64,
    hi_nm: f64,
    theta0_rad: f64,
) -> Rt {
    let s0 = stack_at(0.5 * (lo_nm + hi_nm));
    // Fringe period ~ lambda^2 / (2 sum n d): take at least 16 samples per period.
    let opt: f64 = s0
        .d_nm
        .iter()
        .zip(&s0.n[1..])
        .map(|(d, n)| d * n.re.abs())
        .sum();
    let period = (lo_nm * lo_nm / (2.0 * opt.max(1e-9))).max(1e-6);
    let mut steps = ((hi_nm - lo_nm) / period * 16.0).ceil().max(64.0) as usize;
    steps += steps % 2; // Simpson needs an even count
    steps = steps.min(200_000);
    let h = (hi_nm - lo_nm) / steps as f64;
    let mut acc = Rt {
        r_s: 0.0,
        r_p: 0.0,
        t_s: 0.0,
        t_p: 0.0,
        rp_rs: C64::new(0.0, 0.0),
    };
    for i in 0..=steps {
        let l = lo_nm + i as f64 * h;
        let w = if i == 0 || i == steps {
            1.0
        } else if i % 2 == 1 {
            4.0
        } else {
            2.0
        };
        acc.add_scaled(
            &solve(&stack_at(l), l, theta0_rad),
            w * h / 3.0 / (hi_nm - lo_nm),
        );
    }
    acc
}
