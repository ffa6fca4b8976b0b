//! The Henyey-Greenstein phase function: its density and its inverse-CDF draw.

/// `cos theta` drawn from the Henyey-Greenstein phase function by its inverse CDF
/// (e.g. Jacques & Wang, "Monte Carlo modeling of light transport in tissues", 1995, eq.
/// 5.43): `mu = (1 + g^2 - ((1 - g^2) / (1 - g + 2 g xi))^2) / (2 g)`, uniform for g = 0.
pub fn sample_hg(g: f64, xi: f64) -> f64 {
    if g.abs() < 1e-6 {
        return 2.0 * xi - 1.0;
    }
    let s = (1.0 - g * g) / (1.0 - g + 2.0 * g * xi);
    ((1.0 + g * g - s * s) / (2.0 * g)).clamp(-1.0, 1.0)
}

/// The Henyey-Greenstein phase function per unit `cos theta` (integrates to 1 over
/// [-1, 1]): `(1 - g^2) / (2 (1 + g^2 - 2 g mu)^(3/2))`. The power 3/2 is taken as
/// `x sqrt(x)`: next-event estimation evaluates this once per bucket per scattering event,
/// and libm's `pow` was 35 % of a thick slab's run (issue 75).
#[inline]
pub fn hg_density(g: f64, mu: f64) -> f64 {
    let x = 1.0 + g * g - 2.0 * g * mu;
    (1.0 - g * g) / (2.0 * x * x.sqrt())
}
