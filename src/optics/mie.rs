//! Mie theory: scattering of a plane wave by a homogeneous sphere in a lossless host.
//!
//! The algorithm is Bohren & Huffman's (Absorption and Scattering of Light by Small
//! Particles, 1983, appendix A, "BHMIE") with the stability measures Wiscombe recommends
//! (Improved Mie scattering algorithms, Appl. Opt. 19, 1505, 1980):
//! - the series is summed through `N = x + 4.05 x^(1/3) + 2` orders (Wiscombe eq. 4);
//! - the logarithmic derivative `D_n(mx) = psi_n'(mx) / psi_n(mx)` comes from the downward
//!   recurrence `D_(n-1) = n/(mx) - 1/(D_n + n/(mx))` (BH eq. 4.89), started well above
//!   both `N` and `|mx|`, which is stable for every complex `m` (large and strongly
//!   absorbing spheres included; the upward recurrence is not);
//! - the Riccati-Bessel function `psi_n(x) = x j_n(x)` comes from ratios run downward
//!   (Miller's method) and is anchored on the larger of `psi_0` and `psi_1`, because its
//!   upward recurrence loses accuracy as `n` approaches `x`; `chi_n(x) = -x y_n(x)` grows
//!   with `n` and is run upward, where it is stable.
//!
//! Conventions: the sphere's index relative to the host is `m = n + i k` with `k >= 0`
//! absorbing (the project's convention; BH's too, with time dependence `exp(-i w t)`); the
//! size parameter is `x = 2 pi r n_host / lambda`. Efficiencies `Q = C / (pi r^2)`; the
//! amplitude functions `S1` (perpendicular to the scattering plane) and `S2` (parallel) are
//! BH's (eq. 4.74): the scattered field is `E_s = exp(ikr) / (-ikr) S E_i` in the
//! scattering-plane basis, so `dC_sca/dOmega = |S_j|^2 / k^2` for light polarised along
//! basis vector `j`, with `k = 2 pi n_host / lambda`.

use super::C64;

/// Why the Mie series cannot be summed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MieError {
    #[error("the size parameter x = {0:e} must be finite and in [{MIN_X:e}, {MAX_X:e}]")]
    SizeParameter(f64),
    #[error("the relative index m = {0} must have a positive real part and k >= 0, finite")]
    Index(C64),
    #[error(
        "|m x| = {0} exceeds {MAX_X}: the sphere is too large against the wavelength for the series"
    )]
    TooLarge(f64),
}

/// The largest size parameter (and `|m x|`) summed: 1e5 orders of memory and time.
pub const MAX_X: f64 = 1e5;
/// The smallest size parameter: there the scattering efficiency, Rayleigh's
/// `8/3 x^4 |(m^2 - 1)/(m^2 + 2)|^2` (BH eq. 5.8), is below 3e-24 for a dielectric
/// sphere (`|(m^2 - 1)/(m^2 + 2)| < 1`), so it does not scatter measurably; far below, the
/// series' powers of `x` underflow (NaN at `x = 1e-300`, issue 47).
pub const MIN_X: f64 = 1e-6;

/// The Mie coefficients `a_n`, `b_n` (BH eq. 4.88) of one sphere, orders 1 to N.
#[derive(Clone, Debug)]
pub struct Mie {
    pub x: f64,
    pub m: C64,
    pub a: Vec<C64>,
    pub b: Vec<C64>,
    /// `(2n+1)/(n(n+1)) a_n` and `... b_n`, and `1/n`: the amplitude sums' factors, once.
    fa: Vec<C64>,
    fb: Vec<C64>,
    inv_n: Vec<f64>,
}

/// The number of orders summed (Wiscombe 1980, eq. 4).
pub fn orders(x: f64) -> usize {
    (x + 4.05 * x.cbrt() + 2.0) as usize
}

impl Mie {
    /// The coefficients of a sphere of relative index `m` and size parameter `x`.
    pub fn new(m: C64, x: f64) -> Result<Mie, MieError> {
        if !(x.is_finite() && (MIN_X..=MAX_X).contains(&x)) {
            return Err(MieError::SizeParameter(x));
        }
        if !(m.re.is_finite() && m.im.is_finite() && m.re > 0.0 && m.im >= 0.0) {
            return Err(MieError::Index(m));
        }
        let mx = m * x;
        if mx.norm() > MAX_X {
            return Err(MieError::TooLarge(mx.norm()));
        }
        let n_terms = orders(x).max(1);
        // D_n(mx), n = 0..=n_terms: started exactly at n_terms + 1 by Lentz's continued
        // fraction, then the downward recurrence. (BH start from D = 0 at max(N, |mx|) +
        // 15; for large, weakly absorbing spheres that start has not converged where the
        // series needs it: Q_ext of m = 1.05, x = 1000 came out 7e-4 low.)
        let top = n_terms + 1;
        let mut d = vec![C64::new(0.0, 0.0); top + 1];
        d[top] = log_derivative_lentz(mx, top);
        for n in (1..=top).rev() {
            let nz = C64::new(n as f64, 0.0) / mx;
            d[n - 1] = nz - 1.0 / (d[n] + nz);
        }
        let psi = psi_downward(x, n_terms);
        let (sin, cos) = x.sin_cos();
        // chi_(-1) = -sin x, chi_0 = cos x (BH appendix A); chi_n = (2n - 1)/x chi_(n-1) - chi_(n-2).
        let (mut chi_prev, mut chi) = (cos, cos / x + sin);
        let mut a = Vec::with_capacity(n_terms);
        let mut b = Vec::with_capacity(n_terms);
        for n in 1..=n_terms {
            let nx = n as f64 / x;
            // xi_n = psi_n - i chi_n (BH), so that xi_n = x h_n^(1)(x).
            let xi = C64::new(psi[n], -chi);
            let xi_prev = C64::new(psi[n - 1], -chi_prev);
            let ta = d[n] / m + nx;
            a.push((ta * psi[n] - psi[n - 1]) / (ta * xi - xi_prev));
            let tb = d[n] * m + nx;
            b.push((tb * psi[n] - psi[n - 1]) / (tb * xi - xi_prev));
            let next = (2 * n + 1) as f64 / x * chi - chi_prev;
            chi_prev = chi;
            chi = next;
        }
        let f = |i: usize| {
            let n = (i + 1) as f64;
            (2.0 * n + 1.0) / (n * (n + 1.0))
        };
        let fa = a.iter().enumerate().map(|(i, v)| v * f(i)).collect();
        let fb = b.iter().enumerate().map(|(i, v)| v * f(i)).collect();
        let inv_n = (0..a.len()).map(|i| 1.0 / (i + 1) as f64).collect();
        Ok(Mie {
            x,
            m,
            a,
            b,
            fa,
            fb,
            inv_n,
        })
    }

    /// Extinction efficiency (BH eq. 4.62): `2/x^2 sum (2n+1) Re(a_n + b_n)`.
    pub fn q_ext(&self) -> f64 {
        let s: f64 = (0..self.a.len())
            .map(|i| (2 * i + 3) as f64 * (self.a[i] + self.b[i]).re)
            .sum();
        2.0 * s / (self.x * self.x)
    }

    /// Scattering efficiency (BH eq. 4.61): `2/x^2 sum (2n+1) (|a_n|^2 + |b_n|^2)`.
    pub fn q_sca(&self) -> f64 {
        let s: f64 = (0..self.a.len())
            .map(|i| (2 * i + 3) as f64 * (self.a[i].norm_sqr() + self.b[i].norm_sqr()))
            .sum();
        2.0 * s / (self.x * self.x)
    }

    /// Asymmetry parameter `g = <cos theta>` (BH p. 120):
    /// `g Q_sca = 4/x^2 sum [n(n+2)/(n+1) Re(a_n a*_(n+1) + b_n b*_(n+1)) + (2n+1)/(n(n+1)) Re(a_n b*_n)]`.
    pub fn g(&self) -> f64 {
        let (a, b) = (&self.a, &self.b);
        let mut s = 0.0;
        for i in 0..a.len() {
            let n = (i + 1) as f64;
            if i + 1 < a.len() {
                s += n * (n + 2.0) / (n + 1.0)
                    * (a[i] * a[i + 1].conj() + b[i] * b[i + 1].conj()).re;
            }
            s += (2.0 * n + 1.0) / (n * (n + 1.0)) * (a[i] * b[i].conj()).re;
        }
        let q = self.q_sca();
        if q > 0.0 {
            4.0 * s / (self.x * self.x * q)
        } else {
            0.0
        }
    }

    /// The amplitude functions `(S1, S2)` at `mu = cos theta` (BH eq. 4.74), with the
    /// angular functions `pi_n`, `tau_n` from their upward recurrences (BH eq. 4.47):
    /// `pi_n = (2n-1)/(n-1) mu pi_(n-1) - n/(n-1) pi_(n-2)`, `tau_n = n mu pi_n - (n+1) pi_(n-1)`.
    pub fn s1_s2(&self, mu: f64) -> (C64, C64) {
        let (mut pi_prev, mut pi) = (0.0, 1.0);
        let (mut s1, mut s2) = (C64::new(0.0, 0.0), C64::new(0.0, 0.0));
        for i in 0..self.a.len() {
            let n = (i + 1) as f64;
            let tau = n * mu * pi - (n + 1.0) * pi_prev;
            let (fa, fb) = (self.fa[i], self.fb[i]);
            s1 += fa * pi + fb * tau;
            s2 += fa * tau + fb * pi;
            let next = ((2.0 * n + 1.0) * mu * pi - (n + 1.0) * pi_prev) * self.inv_n[i];
            pi_prev = pi;
            pi = next;
        }
        (s1, s2)
    }
}

/// `D_n(z) = psi_n'(z) / psi_n(z)` at one order, from `D_n(z) = -n/z + J_(n-1/2)(z) /
/// J_(n+1/2)(z)` (the Riccati-Bessel function is `sqrt(pi z / 2) J_(n+1/2)(z)`), the ratio
/// of Bessel functions being the continued fraction that their three-term recurrence
/// `J_(v-1) + J_(v+1) = (2v/z) J_v` gives: `J_(v-1)/J_v = b_0 - 1/(b_1 - 1/(b_2 - ...))`
/// with `b_k = 2(v + k)/z` (Lentz, Appl. Opt. 15, 668, 1976), evaluated by the modified
/// Lentz method (Thompson & Barnett 1986; Numerical Recipes, 3rd ed., §5.2).
fn log_derivative_lentz(z: C64, n: usize) -> C64 {
    let tiny = C64::new(1e-300, 0.0);
    let nu = n as f64 + 0.5;
    let b = |k: usize| 2.0 * (nu + k as f64) / z;
    let mut f = b(0);
    if f.norm() == 0.0 {
        f = tiny;
    }
    let (mut c, mut d) = (f, C64::new(0.0, 0.0));
    // Converges once the order passes |z|; the bound only guards against a NaN input.
    for k in 1..(10 * (z.norm() as usize + n) + 1000) {
        let bk = b(k);
        d = bk - d;
        if d.norm() == 0.0 {
            d = tiny;
        }
        c = bk - 1.0 / c;
        if c.norm() == 0.0 {
            c = tiny;
        }
        d = 1.0 / d;
        let delta = c * d;
        f *= delta;
        if (delta - 1.0).norm() < 1e-15 {
            break;
        }
    }
    -(n as f64) / z + f
}

/// `psi_n(x)`, n = 0..=n_terms, from ratios `psi_n / psi_(n-1)` run downward from far
/// above (Miller's method; the ratio obeys `r_n = 1 / ((2n+1)/x - r_(n+1))`), anchored on
/// whichever of `psi_0 = sin x` and `psi_1 = sin x / x - cos x` is larger in magnitude.
fn psi_downward(x: f64, n_terms: usize) -> Vec<f64> {
    let n_start = (n_terms as f64).max(x) as usize + 25 + (1.5 * x.sqrt()) as usize;
    let mut ratio = vec![0.0; n_terms + 2];
    let mut r = 0.0;
    for n in (1..=n_start).rev() {
        r = 1.0 / ((2 * n + 1) as f64 / x - r);
        if n <= n_terms + 1 {
            ratio[n] = r;
        }
    }
    let (sin, cos) = x.sin_cos();
    let psi0 = sin;
    let psi1 = sin / x - cos;
    let mut psi = vec![0.0; n_terms + 1];
    if psi0.abs() >= psi1.abs() {
        psi[0] = psi0;
        for n in 1..=n_terms {
            psi[n] = ratio[n] * psi[n - 1];
        }
    } else {
        psi[0] = psi1 / ratio[1];
        if n_terms >= 1 {
            psi[1] = psi1;
        }
        for n in 2..=n_terms {
            psi[n] = ratio[n] * psi[n - 1];
        }
    }
    psi
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rayleigh limit (BH eq. 5.8, 5.13): Q_sca = 8/3 x^4 |(m^2 - 1)/(m^2 + 2)|^2 and
    /// Q_ext = 4 x Im((m^2 - 1)/(m^2 + 2)) + Q_sca, to relative order x^2.
    #[test]
    fn small_spheres_scatter_as_rayleigh() {
        for m in [C64::new(1.5, 0.0), C64::new(1.33, 0.01), C64::new(2.0, 1.0)] {
            let x = 1e-3;
            let mie = Mie::new(m, x).unwrap();
            let p = (m * m - 1.0) / (m * m + 2.0);
            let q_sca = 8.0 / 3.0 * x.powi(4) * p.norm_sqr();
            let q_ext = 4.0 * x * p.im + q_sca;
            assert!((mie.q_sca() / q_sca - 1.0).abs() < 1e-5, "{m}");
            assert!((mie.q_ext() / q_ext - 1.0).abs() < 1e-5, "{m}");
            assert!(mie.g().abs() < 1e-5);
        }
    }

    /// A lossless sphere: extinction is scattering (optical theorem, BH eq. 4.76 with
    /// Q_ext = 4/x^2 Re S(0)), and the forward amplitude is S1(1) = S2(1).
    #[test]
    fn lossless_spheres_conserve_energy() {
        for x in [0.3, 3.0, 30.0, 300.0] {
            let mie = Mie::new(C64::new(1.5, 0.0), x).unwrap();
            let (qe, qs) = (mie.q_ext(), mie.q_sca());
            assert!((qe - qs).abs() < 1e-10 * qe, "x {x}: {qe} {qs}");
            let (s1, s2) = mie.s1_s2(1.0);
            assert!((s1 - s2).norm() < 1e-10 * s1.norm());
            assert!((4.0 / (x * x) * s1.re - qe).abs() < 1e-9 * qe);
        }
    }

    /// The phase function integrates to Q_sca: `pi x^2 Q_sca = integral (|S1|^2 +
    /// |S2|^2)/2 dOmega` (BH eq. 4.76, in units of 1/k^2), by Gauss-Legendre-free midpoint
    /// quadrature fine enough for x = 5.
    #[test]
    fn the_phase_function_integrates_to_q_sca() {
        let mie = Mie::new(C64::new(1.33, 0.05), 5.0).unwrap();
        let n = 20_000;
        let mut s = 0.0;
        for k in 0..n {
            let mu = -1.0 + (k as f64 + 0.5) * 2.0 / n as f64;
            let (s1, s2) = mie.s1_s2(mu);
            s += 0.5 * (s1.norm_sqr() + s2.norm_sqr()) * 2.0 / n as f64;
        }
        let q = 2.0 * std::f64::consts::PI * s / (std::f64::consts::PI * 25.0);
        assert!((q / mie.q_sca() - 1.0).abs() < 1e-6, "{q} {}", mie.q_sca());
    }

    #[test]
    fn bad_spheres_are_refused() {
        assert!(Mie::new(C64::new(1.5, 0.0), 0.0).is_err());
        assert!(Mie::new(C64::new(1.5, 0.0), f64::NAN).is_err());
        assert!(Mie::new(C64::new(1.5, -0.1), 1.0).is_err());
        assert!(Mie::new(C64::new(0.0, 1.0), 1.0).is_err());
        assert!(Mie::new(C64::new(2.0, 0.0), 9e4).is_err());
    }
}
