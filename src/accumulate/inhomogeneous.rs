//! Pairs of exits of which at least one is an inhomogeneous wave (light that left an
//! absorber through a face tilted against its planes of constant amplitude): the terms of
//! carrying the pair to its midpoint, its Poynting flux factor, and the window its
//! directional overlap is taken over (docs/design.md §4, "Inhomogeneous exits";
//! docs/physics.md, "Energy at interfaces").

use glam::DVec3;

use crate::optics::C64;

/// What a pair of exits `a`, `b` of which at least one is an inhomogeneous wave (`N = N' +
/// i N''`, `N' . N'' = 0` and `|N'|^2 - |N''|^2 = n0^2` in the lossless exit medium, `N'`
/// along the exit's direction) needs beyond a homogeneous pair: the terms of carrying it
/// to its midpoint, `(phase_nm, grow_nm)`, and its interference flux factor `f`.
///
/// **Midpoint.**
///
/// A field `a exp(i k N . (x - x_a))` evaluated at the midpoint `x_c = (x_a + x_b) / 2`
/// has its amplitude multiplied by `exp(-k N''_a . (x_c - x_a))`, so the product of the
/// pair's amplitudes there gains `exp(k g)` with `g = -(N''_a - N''_b) . (x_b - x_a) / 2`
/// (`grow_nm`); and its phase difference is `k [OPL_a - OPL_b - (N'_a + N'_b) / 2 . (x_a -
/// x_b)]`, which differs from the homogeneous pairs' `n0 wbar . (x_a - x_b)`
/// ([`super::Estimator::path_difference`]) by `phase_nm`. Both vanish for homogeneous exits and
/// for exits at one point. Evaluated at any point common to the pair, the cross term
/// averages over launch points to the same value on a facet whose partial waves are plane
/// waves (a wedge); at the exit points, as before, the amplitudes of a film whose faces
/// are tilted were taken at different places: a gold film whose faces meet at 0.5 degree
/// was 4.3e-3 off the local transfer-matrix film, with 1.7e-3 of the power per tree
/// created at 60 degrees and 650 nm, and was 1.3e-3 off with none (1.7e-3 with the flux
/// factor too, 1.5e-3 with the exits on the power basis; tests/tilted_absorbers.rs).
/// (Carrying every exit of a tree to one common point instead makes the amplitudes of
/// partial waves that walked hundreds of nanometres grow without bound: 0.42 of the power
/// created at 0.5 degree.)
///
/// **Flux factor**, through the exit plane: `f = (q_a + conj(q_b)) / (Re q_a + Re q_b)`, with `q = N . z_out` the
/// complex normal index of each exit (`z_out` the exit plane's normal on the side the
/// light leaves by; `N' = |N'| d`, `|N'|^2 = n0^2 + |N''|^2` in the lossless exit medium).
///
/// The time-averaged normal Poynting flux of two plane waves `E_j`, `H_j = N_j x E_j` of one
/// polarisation through a plane is, up to a common factor,
///
/// ```text
/// |A_a|^2 Re q_a + |A_b|^2 Re q_b + Re[A_a conj(A_b) (q_a + conj(q_b))]
/// ```
///
/// (for s, `E = A y` and `H_x = -A q`; for p the same with the bilinear amplitude `A`,
/// `H_y = n A`: Born & Wolf §1.4.3, §14.2): the cross term's factor is `q_a + conj(q_b)`,
/// not `2 Re q`. The carried amplitudes hold `sqrt(Re q)` (optics::fresnel, "Carried
/// amplitudes"), so the pair's Hermitian product `h` is
/// multiplied by `f`, to second order in the difference of the exits' directions (the
/// homogeneous pairs' own approximation). For homogeneous exits `f = 1`; an inhomogeneous
/// pair's `f - 1 = i (q''_a - q''_b) / (q'_a + q'_b)` is first order in the tilt of a film's
/// faces. Measured on a gold film whose faces meet at 1 degree, against RCWA for TM (PyPI
/// nannos, Li's factorisation, 121 orders): R at 60 degrees and 650 nm 0.334 against
/// 0.325, was 0.358; at 550 nm 0.228 against 0.227, was 0.239 (docs/physics.md).
///
/// Returns `(phase_nm, grow_nm, f)`; a homogeneous pair `(0, 0, 1)`.
pub(super) fn pair_terms(
    a: &crate::trace::Exit,
    b: &crate::trace::Exit,
    n0: f64,
) -> (f64, f64, C64) {
    if a.n_im == DVec3::ZERO && b.n_im == DVec3::ZERO {
        return (0.0, 0.0, C64::ONE);
    }
    let n_re = |x: &crate::trace::Exit| x.dir * (n0 * n0 + x.n_im.length_squared()).sqrt();
    let (na, nb) = (n_re(a), n_re(b));
    let wbar = (a.dir + b.dir).normalize();
    let phase = -((na + nb) * 0.5 - wbar * n0).dot(a.x - b.x);
    let grow = -0.5 * (a.n_im - b.n_im).dot(b.x - a.x);
    let z = if a.up { DVec3::Z } else { -DVec3::Z };
    let (qa, qb) = (
        C64::new(na.dot(z), a.n_im.dot(z)),
        C64::new(nb.dot(z), b.n_im.dot(z)),
    );
    (phase, grow, (qa + qb.conj()) / (qa.re + qb.re))
}

/// [`super::Pair::m2`] for exits `a` and `b` about their mean direction `wbar`: `|(N''_a +
/// N''_b)_perp|^2`.
pub(super) fn inhomogeneity(a: &crate::trace::Exit, b: &crate::trace::Exit, wbar: DVec3) -> f64 {
    let m = a.n_im + b.n_im;
    let m = m - wbar * m.dot(wbar);
    m.dot(m)
}

/// A pair of inhomogeneous exits is evaluated over the window in which its amplitudes
/// change by at most this factor's logarithm (5 %): see [`directional_exponent`].
pub const AMPLITUDE_WINDOW: f64 = 0.05;

/// The exponent of a pair's directional overlap at wave number `k` (1/nm), for exits
/// `|w_j - w_l|^2 = dw2` apart in direction and with `m2` as in [`super::Pair::m2`], under a
/// beamlet of radius `rho_nm`:
///
/// - homogeneous exits (`m2 = 0`): the Gaussian beamlets' overlap `-|dw|^2 / (2
///   theta_w^2)`, `theta_w = lambda / (pi rho)` (docs/design.md §4), that is `-s^2 k^2
///   |dw|^2 / 2` over the window `s = rho / 2`;
/// - inhomogeneous exits (they left an absorber through a face not parallel to its planes
///   of constant amplitude, as each partial wave of a film whose faces are tilted does):
///   their fields `a exp(i k N . x)` change in amplitude by `exp(k |M| x)` across the
///   beamlet, `M = (N''_j + N''_l)_perp`, so their plane-wave extrapolation from the exit
///   points holds only within `s = AMPLITUDE_WINDOW / (k |M|)`. The overlap is taken over
///   that window where it is smaller than `rho / 2`: `-min(rho / 2, c / (k |M|))^2 k^2
///   |dw|^2 / 2`. The exact overlap of two inhomogeneous Gaussian beamlets over a window
///   `s` is `exp(-s^2 Q . Q / 2)` with `Q = k (dw + i M)` (docs/physics.md, "Energy at
///   interfaces"): within this window its other factors, `exp(s^2 k^2 |M|^2 / 2)` and a
///   phase `s^2 k^2 dw . M`, are within `c^2 / 2 = 1.25e-3` of 1 and are left out.
///
/// The window is continuous in `M` (it is the beamlet's until `k |M| rho / 2` reaches
/// `c`: a film tilted by about 1e-4 degree), so results are continuous in a facet's tilt.
#[inline(always)]
pub(super) fn directional_exponent(dw2: f64, m2: f64, k: f64, rho_nm: f64) -> f64 {
    let beamlet = 0.25 * k * k * rho_nm * rho_nm;
    let window = if m2 > 0.0 {
        beamlet.min(AMPLITUDE_WINDOW * AMPLITUDE_WINDOW / m2)
    } else {
        beamlet
    };
    -0.5 * dw2 * window
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use super::*;
    use crate::optics::fresnel::{field_power, hermitian};

    /// The overlap of two Gaussian-windowed plane waves `exp(i k (dw + i M) x)` along one
    /// line, by brute-force quadrature over the window `exp(-x^2 / (2 s^2))` (trapezoids
    /// over +-12 s), normalised by the window's own integral: the exact overlap the
    /// estimator's directional kernel stands for.
    fn window_overlap(dw: f64, m: f64, k: f64, s: f64) -> C64 {
        let n = 40_001;
        let (mut num, mut den) = (C64::new(0.0, 0.0), 0.0);
        for i in 0..n {
            let x = (i as f64 / (n - 1) as f64 - 0.5) * 24.0 * s;
            let g = (-x * x / (2.0 * s * s)).exp();
            num += g * (C64::new(-k * m * x, k * dw * x)).exp();
            den += g;
        }
        num / den
    }

    /// Two inhomogeneous plane waves leaving into air (`N' . N'' = 0`, `|N'|^2 - |N''|^2 =
    /// 1`, directions 30 and 30.5 degrees, `|N''|` 0.1 and 0.2, both in the x-z plane):
    /// their normal Poynting flux by brute force, `Re[(E x conj(H))_z] / 2` with `E = sum
    /// E_j` and `H = sum N_j x E_j` (Maxwell's curl equation for a plane wave, in units of
    /// the vacuum impedance), normalised by a single wave's, against the estimator's pair
    /// sum of the exits' carried fields with [`pair_terms`]. s-polarised, `E_j = A_j y`;
    /// p-polarised, `E_j = A_j (y x N_j)` (transverse: `E . N = 0`), whose complex vector's
    /// `|E|^2` is `|A|^2 (|N'|^2 + |N''|^2)` while it carries `|A|^2 Re(q)`: the tracer
    /// writes such exits on the power basis (`fresnel::on_power_basis`). Without the flux
    /// factor, or for p without the power basis, the sum is off by more than 1e-2.
    #[test]
    fn the_pair_flux_factor_gives_the_poynting_flux_of_inhomogeneous_waves() {
        use crate::optics::fresnel::{Field, on_power_basis};
        let wave = |theta_deg: f64, g: f64| {
            let t = theta_deg.to_radians();
            let d = DVec3::new(t.sin(), 0.0, t.cos());
            let along = DVec3::new(t.cos(), 0.0, -t.sin());
            (d, d * (1.0 + g * g).sqrt(), along * g)
        };
        let cross = |a: [C64; 3], b: [C64; 3]| -> [C64; 3] {
            [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ]
        };
        let waves = [wave(30.0, 0.1), wave(30.5, 0.2)];
        let amps = [C64::new(1.0, 0.0), C64::from_polar(0.8, 0.7)];
        let nvec = |(_, re, im): (DVec3, DVec3, DVec3)| -> [C64; 3] {
            std::array::from_fn(|i| C64::new(re[i], im[i]))
        };
        let y = [C64::ZERO, C64::ONE, C64::ZERO];
        for p_polarised in [false, true] {
            let field = |j: usize| -> [C64; 3] {
                let unit = if p_polarised {
                    cross(y, nvec(waves[j]))
                } else {
                    y
                };
                unit.map(|c| c * amps[j])
            };
            let flux = |which: &[usize]| {
                let (mut e, mut h) = ([C64::ZERO; 3], [C64::ZERO; 3]);
                for &j in which {
                    let ej = field(j);
                    let hj = cross(nvec(waves[j]), ej);
                    for i in 0..3 {
                        e[i] += ej[i];
                        h[i] += hj[i];
                    }
                }
                let hc = h.map(|x| x.conj());
                0.5 * cross(e, hc)[2].re
            };
            // Each exit as the tracer leaves it: the field times `sqrt(Re q)`, then on the
            // power basis (or not).
            let exit = |j: usize, basis: bool| {
                let (d, re, im) = waves[j];
                let raw: Field = field(j).map(|c| c * re.z.sqrt());
                let e = if basis {
                    on_power_basis(&raw, re, im, 1.0)
                } else {
                    raw
                };
                crate::trace::Exit {
                    e: [e, e],
                    opl: C64::ZERO,
                    dir: d,
                    n_im: im,
                    x: DVec3::ZERO,
                    up: true,
                    group: 0,
                    tube: 1.0,
                    path: 0,
                }
            };
            // A single wave's flux per unit `|A|^2 Re(q)` (the common factor, 1/2).
            let unit = flux(&[0]) / (amps[0].norm_sqr() * waves[0].1.z);
            let brute = flux(&[0, 1]) / unit;
            let estimate = |basis: bool, with_factor: bool| {
                let (a, b) = (exit(0, basis), exit(1, basis));
                let h = hermitian(&a.e[0], &b.e[0]);
                let f = if with_factor {
                    pair_terms(&a, &b, 1.0).2
                } else {
                    C64::ONE
                };
                field_power(&a.e[0]) + field_power(&b.e[0]) + 2.0 * (h * f).re
            };
            let with = estimate(true, true);
            assert!(
                (with - brute).abs() < 1e-4 * brute,
                "p {p_polarised}: {with} against {brute}"
            );
            let without = estimate(true, false);
            assert!(
                (without - brute).abs() > 1e-2 * brute,
                "p {p_polarised}, no factor: {without} against {brute}"
            );
            let complex_p = estimate(false, true);
            if p_polarised {
                assert!(
                    (complex_p - brute).abs() > 1e-2 * brute,
                    "p on the complex vector: {complex_p} against {brute}"
                );
            } else {
                assert!(
                    (complex_p - with).abs() < 1e-12 * brute,
                    "s: the power basis changes nothing: {complex_p} against {with}"
                );
            }
        }
        // Homogeneous exits: the factor is 1.
        let bare = |dir: DVec3| crate::trace::Exit {
            e: [[C64::ZERO; 3]; 2],
            opl: C64::ZERO,
            dir,
            n_im: DVec3::ZERO,
            x: DVec3::ZERO,
            up: true,
            group: 0,
            tube: 1.0,
            path: 0,
        };
        let (c, d) = (bare(waves[0].0), bare(waves[1].0));
        assert_eq!(pair_terms(&c, &d, 1.0).2, C64::ONE);
    }

    /// Homogeneous exits: the beamlet's Gaussian overlap `exp(-|dw|^2 / (2 theta_w^2))`,
    /// `theta_w = lambda / (pi rho)` (docs/design.md §4), and the quadrature over `s = rho /
    /// 2`. Inhomogeneous exits: over the window `s = min(rho / 2, c / (k |M|))` the exact
    /// overlap's magnitude and phase are within `c^2 / 2` of the kernel (the factors the
    /// kernel leaves out), for gold-film-like pairs (`|M|` 1-10 times `|dw|`) and a ridge
    /// tip's (`|M| = 3`, `|dw| = 1`).
    #[test]
    fn the_directional_kernel_is_the_window_overlap_to_its_stated_order() {
        let (lambda, rho) = (550.0, 5000.0);
        let k = 2.0 * PI / lambda;
        for dw in [1e-4, 1e-3, 3e-3] {
            let kernel = directional_exponent(dw * dw, 0.0, k, rho).exp();
            let theta_w = lambda / (PI * rho);
            let closed = (-dw * dw / (2.0 * theta_w * theta_w)).exp();
            assert!((kernel - closed).abs() < 1e-12, "{kernel} {closed}");
            let exact = window_overlap(dw, 0.0, k, rho / 2.0);
            assert!((exact.norm() - kernel).abs() < 1e-9, "{exact} {kernel}");
        }
        let c = AMPLITUDE_WINDOW;
        for (dw, m) in [
            (0.01, 0.03),
            (0.05, 0.12),
            (0.02, 0.2),
            (1.0, 3.0),
            (1e-6, 1e-5),
        ] {
            let kernel = directional_exponent(dw * dw, m * m, k, rho).exp();
            let s = (rho / 2.0).min(c / (k * m));
            let exact = window_overlap(dw, m, k, s);
            assert!(
                (exact.norm() / kernel - 1.0).abs() <= c * c / 2.0 * 1.01
                    && exact.arg().abs() <= c * c,
                "dw {dw}, M {m}: window {s} nm, exact {exact}, kernel {kernel}"
            );
        }
    }
}
