//! Dependent scattering of packed spheres: the static structure factor of hard spheres in
//! the Percus-Yevick approximation (Wertheim, Phys. Rev. Lett. 10, 321, 1963; Thiele, J.
//! Chem. Phys. 39, 474, 1963), as the quasi-crystalline approximation applies it to a
//! particle medium (Tsang & Kong, Scattering of Electromagnetic Waves: Advanced Topics,
//! 2001, ch. 8): the intensity a sphere scatters through angle `theta` is multiplied by
//! `S(q)` at the momentum transfer `q = 2 k sin(theta / 2)` (`k` the host's wavenumber),
//! because the waves of correlated neighbours interfere. `S(q) -> 1` for large `q`
//! (independent scattering) and `S(0) = (1 - f)^4 / (1 + 2 f)^2` at volume fraction `f`,
//! the compressibility limit: 0.456 at 10 %, 0.209 at 20 %. Absorption is left as the
//! independent spheres' (the approximation's first order).

/// The largest volume fraction the Percus-Yevick structure factor is trusted at: its
/// contact value and the equation of state it implies stay within a few per cent of
/// simulations of hard spheres up to about 0.4 (Hansen & McDonald, Theory of Simple
/// Liquids, 3rd ed., 2006, §4.4); above it a run warns.
pub const PY_TRUSTED_MAX: f64 = 0.4;
/// Random close packing of equal spheres (Scott & Kilgour, J. Phys. D 2, 863, 1969: 0.637):
/// no suspension of hard spheres is denser, so larger fractions are refused.
pub const RANDOM_CLOSE_PACKING: f64 = 0.64;
/// Below this volume fraction the correction is left out: `1 - S(0)` is under 2 % there
/// (`S(0) = 0.98` at 0.0034; a dilute suspension).
pub const PY_FROM: f64 = 0.005;

/// The Percus-Yevick structure factor of hard spheres of diameter `d` at volume fraction
/// `f`, at `x = q d`: `S = 1 / (1 - n c(q))` with the Fourier transform of the direct
/// correlation function `c(r) = -a - b (r/d) - g (r/d)^3` inside the sphere (`a = (1 + 2
/// f)^2 / (1 - f)^4`, `b = -6 f (1 + f/2)^2 / (1 - f)^4`, `g = f a / 2`; Hansen & McDonald
/// eq. 4.4.14), in closed form (e.g. Kinning & Thomas, Macromolecules 17, 1712, 1984, eq.
/// 7), and by its Taylor series at small `x`, where the closed form cancels.
pub fn percus_yevick(f: f64, x: f64) -> f64 {
    PercusYevick::new(f).at(x)
}

/// [`percus_yevick`] at one volume fraction, its coefficients computed once (a scattering
/// event evaluates it at every candidate angle).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PercusYevick {
    f: f64,
    a: f64,
    b: f64,
    g: f64,
}

impl PercusYevick {
    pub fn new(f: f64) -> PercusYevick {
        let one = (1.0 - f).powi(4);
        let a = (1.0 + 2.0 * f).powi(2) / one;
        PercusYevick {
            f,
            a,
            b: -6.0 * f * (1.0 + 0.5 * f).powi(2) / one,
            g: 0.5 * f * a,
        }
    }

    /// The volume fraction.
    pub fn f(&self) -> f64 {
        self.f
    }

    /// `S` at `x = q d`.
    #[inline]
    pub fn at(&self, x: f64) -> f64 {
        let PercusYevick { f, a, b, g } = *self;
        let nc = if x < 0.05 {
            // n c(q) = -24 f (a / 3 + b / 4 + g / 6) + 24 f x^2 (a / 30 + b / 36 + g / 48) + O(x^4)
            // (the moments of c(r) r^2 (1 - (q r)^2 / 6) over the sphere).
            -24.0 * f * (a / 3.0 + b / 4.0 + g / 6.0)
                + 24.0 * f * x * x * (a / 30.0 + b / 36.0 + g / 48.0)
        } else {
            let (s, c) = x.sin_cos();
            let x2 = x * x;
            -24.0 * f / (x2 * x2 * x2)
                * (a * x2 * x * (s - x * c)
                    + b * x2 * (2.0 * x * s - (x2 - 2.0) * c - 2.0)
                    + g * ((4.0 * x2 * x - 24.0 * x) * s - (x2 * x2 - 12.0 * x2 + 24.0) * c + 24.0))
        };
        1.0 / (1.0 - nc)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `n c(q)` by quadrature of the direct correlation function written here: `n 4 pi
    /// int_0^d c(r) r^2 sin(q r) / (q r) dr`, `n = 6 f / (pi d^3)`, Simpson on 20,000
    /// intervals.
    fn nc_quadrature(f: f64, x: f64) -> f64 {
        let one = (1.0 - f).powi(4);
        let a = (1.0 + 2.0 * f).powi(2) / one;
        let b = -6.0 * f * (1.0 + 0.5 * f).powi(2) / one;
        let g = 0.5 * f * a;
        let n = 20_000;
        let h = 1.0 / n as f64;
        let mut sum = 0.0;
        for i in 0..=n {
            let r = i as f64 * h;
            let c = -a - b * r - g * r * r * r;
            let sinc = if r * x == 0.0 {
                1.0
            } else {
                (x * r).sin() / (x * r)
            };
            let w = if i == 0 || i == n {
                1.0
            } else if i % 2 == 1 {
                4.0
            } else {
                2.0
            };
            sum += w * c * r * r * sinc;
        }
        // d = 1: n = 6 f / pi.
        6.0 * f / std::f64::consts::PI * 4.0 * std::f64::consts::PI * sum * h / 3.0
    }

    #[test]
    fn the_structure_factor_is_the_transform_of_the_direct_correlation_function() {
        for f in [0.01f64, 0.1, 0.2, 0.3, 0.5] {
            for x in [0.0, 0.01, 0.049, 0.051, 0.5, 2.0, 5.0, 7.0, 12.0, 30.0] {
                let want = 1.0 / (1.0 - nc_quadrature(f, x));
                let got = percus_yevick(f, x);
                assert!(
                    (got - want).abs() < 1e-6 * want.max(1.0),
                    "f {f}, x {x}: {got} against {want}"
                );
            }
        }
    }

    #[test]
    fn the_compressibility_limit_and_the_dilute_limit() {
        for f in [0.05f64, 0.1, 0.2, 0.3] {
            let s0 = (1.0 - f).powi(4) / (1.0 + 2.0 * f).powi(2);
            assert!((percus_yevick(f, 0.0) - s0).abs() < 1e-12, "f {f}");
        }
        // The figures: 0.456 at 10 %, 0.209 at 20 %.
        assert!((percus_yevick(0.1, 0.0) - 0.456).abs() < 5e-4);
        assert!((percus_yevick(0.2, 0.0) - 0.209).abs() < 5e-4);
        // Far from the first peak, neighbours no longer interfere.
        assert!((percus_yevick(0.3, 200.0) - 1.0).abs() < 2e-3);
        assert!((percus_yevick(1e-6, 3.0) - 1.0).abs() < 1e-4);
    }
}
