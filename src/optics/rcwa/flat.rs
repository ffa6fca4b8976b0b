//! Flat interfaces above a relief, one Floquet order at a time: a lacquer over an embossed
//! metal, a clear layer over a grating (docs/physics.md, "Reliefs under flat layers").
//!
//! A flat interface does not couple orders: harmonic `n` keeps its `α_n` through every
//! plane, and in each medium `F` (`E_y` in TE, `H_y` in TM) is `D e^{-iβz} + U e^{iβz}`,
//! `β = sqrt(ε − α_n²)` (`Im β ≥ 0`, lengths in units of `1 / k0`). Across a plane `F` and
//! `(1/η) ∂z F` are continuous (`η = 1` in TE, `ε` in TM: Born & Wolf §1.5.2, the tangential
//! `E_y` and `H_x` in TE, `H_y` and `E_x` in TM), so with `q = β / η` a plane between media
//! `i` (above) and `j` has, for amplitudes referred to the plane,
//!
//! ```text
//! r = (q_i − q_j) / (q_i + q_j),   t = 2 q_i / (q_i + q_j)       (lit from above)
//! r' = −r,                          t' = 2 q_j / (q_i + q_j)       (lit from below)
//! ```
//!
//! and a layer of thickness `h` moves both waves' reference by `e^{iβ h}`, which only decays.
//! The planes and layers are joined by Redheffer's star product (Li 1996, JOSA A 13, 1024),
//! scalar here: no growing exponential is ever formed, so evanescent orders and thick
//! layers are stable.

use super::C64;

/// One order's scattering through the flat stack, between the top plane (amplitudes
/// referred to it, in the half-space above) and the height `z = 0` in the relief's cover
/// (amplitudes referred to `z = 0`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Scalar {
    /// Reflection of a down-going wave from above.
    pub r: C64,
    /// Transmission down, from the top plane to `z = 0` in the cover.
    pub t: C64,
    /// Reflection of an up-going wave in the cover (referred to `z = 0`).
    pub r_back: C64,
    /// Transmission up, from `z = 0` in the cover to the top plane.
    pub t_back: C64,
}

impl Scalar {
    const IDENTITY: Scalar = Scalar {
        r: C64::new(0.0, 0.0),
        t: C64::new(1.0, 0.0),
        r_back: C64::new(0.0, 0.0),
        t_back: C64::new(1.0, 0.0),
    };

    /// `self` above `below`: Redheffer's star product.
    fn star(self, below: Scalar) -> Scalar {
        let loop_ = C64::new(1.0, 0.0) / (C64::new(1.0, 0.0) - self.r_back * below.r);
        Scalar {
            r: self.r + self.t_back * below.r * self.t * loop_,
            t: below.t * self.t * loop_,
            r_back: below.r_back + below.t * self.r_back * below.t_back * loop_,
            t_back: self.t_back * below.t_back * loop_,
        }
    }

    fn plane(qi: C64, qj: C64) -> Scalar {
        let s = qi + qj;
        let r = (qi - qj) / s;
        Scalar {
            r,
            t: 2.0 * qi / s,
            r_back: -r,
            t_back: 2.0 * qj / s,
        }
    }

    fn layer(beta: C64, h: f64) -> Scalar {
        let p = (C64::new(0.0, 1.0) * beta * h).exp();
        Scalar {
            r: C64::new(0.0, 0.0),
            t: p,
            r_back: C64::new(0.0, 0.0),
            t_back: p,
        }
    }
}

/// `kz / k0` of harmonic `alpha` in a medium of permittivity `eps`, on the branch that
/// propagates down or decays downward (`Im β ≥ 0`, `Re β ≥ 0` where real).
pub(super) fn beta(eps: C64, alpha: f64) -> C64 {
    let b = (eps - alpha * alpha).sqrt();
    if b.im < 0.0 || (b.im == 0.0 && b.re < 0.0) {
        -b
    } else {
        b
    }
}

/// The stack's scattering for harmonic `(alpha, gamma)` (`k_x`, `k_y` in units of `k0`) in
/// polarisation `tm` (s: E along `ŝ = ẑ × k_t`, amplitude E; p: H along it, amplitude H,
/// so that at `gamma = 0` they are TE's `E_y` and TM's `H_y`): the half-space above
/// (`eps_above`), then `planes` top first (`(z, ε below)`, heights in units of `1 / k0`),
/// the last plane's medium below it being the cover, down to `z = 0` in the cover. A flat
/// plane keeps s and p apart in any mount; `β = sqrt(ε − α² − γ²)`.
pub(super) fn stack(
    eps_above: C64,
    planes: &[(f64, C64)],
    alpha: f64,
    gamma: f64,
    tm: bool,
) -> Scalar {
    let g2 = gamma * gamma;
    let q = |eps: C64| {
        let b = beta(eps - g2, alpha);
        if tm { b / eps } else { b }
    };
    let mut s = Scalar::IDENTITY;
    let mut above = eps_above;
    for (k, &(z, eps)) in planes.iter().enumerate() {
        s = s.star(Scalar::plane(q(above), q(eps)));
        // Down to the next plane, or to z = 0 in the cover.
        let next = planes.get(k + 1).map_or(0.0, |p| p.0);
        s = s.star(Scalar::layer(beta(eps - g2, alpha), z - next));
        above = eps;
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One plane is Fresnel's (Born & Wolf §1.5.2) in both polarisations, and a lossless
    /// slab's R + T is 1 (its Airy sum); referred to `z = 0` a layer adds its phase.
    #[test]
    fn one_plane_is_fresnel_and_a_slab_conserves_energy() {
        let (n1, n2) = (1.0f64, 1.5f64);
        let s1 = 0.5f64; // sin of the incidence
        let (c1, c2) = ((1.0 - s1 * s1).sqrt(), (1.0 - (s1 / n2).powi(2)).sqrt());
        let rs = (n1 * c1 - n2 * c2) / (n1 * c1 + n2 * c2);
        let rp_h = (n2 * c1 - n1 * c2) / (n2 * c1 + n1 * c2); // H_y's reflection
        let eps2 = C64::new(n2 * n2, 0.0);
        let te = stack(C64::new(1.0, 0.0), &[(0.0, eps2)], s1, 0.0, false);
        let tm = stack(C64::new(1.0, 0.0), &[(0.0, eps2)], s1, 0.0, true);
        assert!((te.r - rs).norm() < 1e-14, "{} {rs}", te.r);
        assert!((tm.r - rp_h).norm() < 1e-14, "{} {rp_h}", tm.r);
        // A 2-unit glass slab on glass of index 2: R + T = 1 with T's flux factor.
        let eps3 = C64::new(4.0, 0.0);
        for tm in [false, true] {
            let one = stack(C64::new(1.0, 0.0), &[(3.0, eps2), (1.0, eps3)], s1, 0.0, tm);
            let (b1, b3) = (beta(C64::new(1.0, 0.0), s1), beta(eps3, s1));
            let flux = if tm {
                (b3 / eps3).re / b1.re
            } else {
                b3.re / b1.re
            };
            let rt = one.r.norm_sqr() + one.t.norm_sqr() * flux;
            assert!((rt - 1.0).abs() < 1e-13, "tm {tm}: R + T = {rt}");
        }
    }
}
