//! Particle media: volume scattering by particles suspended in a lossless host, as the
//! tracer samples it (docs/physics.md, "Particle media").
//!
//! A scattering medium has an extinction coefficient `mu_ext` (1/nm) and a single-scattering
//! albedo `omega = mu_sca / mu_ext`. A ray inside it travels an exponentially distributed
//! free path (mean `1 / mu_ext`) before it meets a particle; there its power is multiplied
//! by `omega` (the absorbed part is counted as absorbed) and it leaves in a new direction
//! drawn from the phase function, its two polarisation fields transformed by the particle's
//! amplitude matrix. The scattered light is incoherent with every other path of its tree
//! (the particles sit at random, uncorrelated places: Bohren & Huffman 1983, §3.4), which
//! the tracer records by giving it a coherence group of its own.
//!
//! Two phase models:
//! - **Mie particles** (`optics::mie`): spheres of one radius or a log-normal distribution
//!   of radii (by number) at a volume fraction `f_v`, independent scattering (valid to
//!   about `f_v = 0.1`; denser suspensions scatter less than this predicts). With number
//!   density `N = f_v / <V>`, `mu_ext = N <C_ext>` and `mu_sca = N <C_sca>` (BH eq. 3.40,
//!   summed over sizes). A scattering event picks a radius with probability
//!   `w_r C_sca,r / sum w C_sca`, then a direction; the fields transform as
//!   `E' = [S2 (E . e_par) e_par' + S1 (E . e_perp) e_perp] / sqrt(k^2 C_sca,r q(Omega))`
//!   (BH eq. 3.12 in the scattering-plane basis) where `q` is the density the direction was
//!   drawn from: a tabulated approximation of the phase function, so the estimate is
//!   unbiased whatever the table's resolution (only its variance depends on it), because
//!   `integral |S E|^2 dOmega / k^2 = C_sca |E|^2` for a sphere and any polarisation.
//! - **Henyey-Greenstein** (Astrophys. J. 93, 70, 1941): a prescribed `g`, `mu_sca` and
//!   `mu_abs`, the same at every wavelength, sampled exactly by its inverse CDF; the fields
//!   are carried into the new direction's scattering-plane basis unchanged in power (a
//!   model of the angular distribution only, as radiative-transfer references assume).
//!
//! Particle properties are tabulated per whole nanometre of wavelength and used at the
//! nearest one (for the size parameters of pigments, `x < 30`, they change by less than
//! 1e-3 relative over half a nanometre).

use glam::DVec3;

use super::C64;
use super::fresnel::{Field, field_dot_real};
use super::mie::{Mie, MieError};
use crate::rng::Rng;

/// Intervals of the tabulated phase function over `theta` in `[0, pi]`.
pub const THETA_INTERVALS: usize = 256;
/// Radius nodes of a log-normal distribution: trapezoidal quadrature of the normal
/// density on `ln r` over +-3.5 standard deviations (the 5e-4 of the mass beyond is
/// renormalised away).
pub const LOG_NORMAL_NODES: usize = 17;

/// The spheres' radius.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Radius {
    Fixed {
        radius_nm: f64,
    },
    /// `ln r` normal with median `median_nm` and standard deviation `sigma`, by number.
    LogNormal {
        median_nm: f64,
        sigma: f64,
    },
}

impl Radius {
    /// `(radius_nm, weight)` nodes, weights summing to 1.
    pub fn nodes(&self) -> Vec<(f64, f64)> {
        match *self {
            Radius::Fixed { radius_nm } => vec![(radius_nm, 1.0)],
            Radius::LogNormal { median_nm, sigma } => {
                let k = LOG_NORMAL_NODES;
                let z = |i: usize| -3.5 + 7.0 * i as f64 / (k - 1) as f64;
                let w: Vec<f64> = (0..k)
                    .map(|i| {
                        let end = if i == 0 || i == k - 1 { 0.5 } else { 1.0 };
                        end * (-0.5 * z(i) * z(i)).exp()
                    })
                    .collect();
                let total: f64 = w.iter().sum();
                (0..k)
                    .map(|i| (median_nm * (sigma * z(i)).exp(), w[i] / total))
                    .collect()
            }
        }
    }
}

/// Why a particle medium cannot be tabulated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ParticleError {
    #[error("at {lambda_nm} nm: {source}")]
    Mie { lambda_nm: f64, source: MieError },
    #[error(
        "the host medium must be lossless (k = 0) to carry scattered light; it has k = {k} at {lambda_nm} nm"
    )]
    AbsorbingHost { lambda_nm: f64, k: f64 },
    #[error("{0}")]
    Invalid(String),
}

/// One radius at one wavelength.
#[derive(Clone, Debug)]
struct SizeEntry {
    mie: Mie,
    /// Scattering cross-section, nm^2.
    c_sca_nm2: f64,
    /// Cumulative mass of the tabulated phase function over the theta intervals
    /// (`THETA_INTERVALS + 1` values from 0 to 1).
    cdf: Vec<f64>,
}

/// A particle medium at one wavelength.
#[derive(Clone, Debug)]
pub struct LambdaEntry {
    mu_ext_per_nm: f64,
    albedo: f64,
    /// Wave number in the host, 1/nm.
    k_host: f64,
    sizes: Vec<SizeEntry>,
    /// Cumulative probability of each size at a scattering event.
    size_cdf: Vec<f64>,
}

/// A scattering medium ready for the tracer.
#[derive(Clone, Debug)]
pub enum ScatterModel {
    HenyeyGreenstein {
        g: f64,
        mu_sca_per_nm: f64,
        mu_abs_per_nm: f64,
    },
    Mie {
        /// Wavelength of `table[0]`, nm; one entry per whole nanometre.
        first_nm: i64,
        table: Vec<LambdaEntry>,
    },
}

impl ScatterModel {
    /// A Henyey-Greenstein medium (coefficients in 1/um, as the sample gives them).
    pub fn henyey_greenstein(
        g: f64,
        scattering_per_um: f64,
        absorption_per_um: f64,
    ) -> Result<ScatterModel, ParticleError> {
        if !(g.is_finite() && g > -1.0 && g < 1.0) {
            return Err(ParticleError::Invalid(format!(
                "g must lie strictly between -1 and 1, got {g}"
            )));
        }
        for (name, v) in [
            ("scattering_per_um", scattering_per_um),
            ("absorption_per_um", absorption_per_um),
        ] {
            if !(v.is_finite() && (0.0..=1e6).contains(&v)) {
                return Err(ParticleError::Invalid(format!(
                    "{name} must be between 0 and 1e6 per um, got {v}"
                )));
            }
        }
        if scattering_per_um + absorption_per_um <= 0.0 {
            return Err(ParticleError::Invalid(
                "a scattering medium needs scattering_per_um or absorption_per_um above 0".into(),
            ));
        }
        Ok(ScatterModel::HenyeyGreenstein {
            g,
            mu_sca_per_nm: scattering_per_um * 1e-3,
            mu_abs_per_nm: absorption_per_um * 1e-3,
        })
    }

    /// Mie particles of radius `radius` at volume fraction `volume_fraction`, tabulated for
    /// every whole nanometre covering `[lo_nm, hi_nm]`; `host(lambda)` and
    /// `particle(lambda)` are the complex indices of the host and the particles.
    pub fn mie(
        radius: Radius,
        volume_fraction: f64,
        lo_nm: f64,
        hi_nm: f64,
        host: &dyn Fn(f64) -> C64,
        particle: &dyn Fn(f64) -> C64,
    ) -> Result<ScatterModel, ParticleError> {
        if !(volume_fraction.is_finite() && volume_fraction > 0.0 && volume_fraction < 0.74) {
            return Err(ParticleError::Invalid(format!(
                "volume_fraction must lie in (0, 0.74) (0.74: spheres packed as densely as they can be), got {volume_fraction}"
            )));
        }
        let nodes = radius.nodes();
        if let Some(&(r, _)) = nodes.iter().find(|(r, _)| !(r.is_finite() && *r > 0.0)) {
            return Err(ParticleError::Invalid(format!(
                "particle radii must be positive and finite, got {r} nm"
            )));
        }
        // N = f_v / <V>, particles per nm^3.
        let mean_volume: f64 = nodes
            .iter()
            .map(|(r, w)| w * 4.0 / 3.0 * std::f64::consts::PI * r.powi(3))
            .sum();
        let density = volume_fraction / mean_volume;
        let first_nm = lo_nm.round() as i64;
        let last_nm = hi_nm.round() as i64;
        let mut table = Vec::new();
        for l in first_nm..=last_nm {
            let lambda = l as f64;
            let nh = host(lambda);
            if nh.im != 0.0 {
                return Err(ParticleError::AbsorbingHost {
                    lambda_nm: lambda,
                    k: nh.im,
                });
            }
            let k_host = 2.0 * std::f64::consts::PI * nh.re / lambda;
            let m = particle(lambda) / nh.re;
            let (mut c_ext, mut c_sca) = (0.0, 0.0);
            let mut sizes = Vec::new();
            let mut size_w = Vec::new();
            for &(r, w) in &nodes {
                let x = k_host * r;
                let mie = Mie::new(m, x).map_err(|source| ParticleError::Mie {
                    lambda_nm: lambda,
                    source,
                })?;
                let area = std::f64::consts::PI * r * r;
                let (ce, cs) = (mie.q_ext() * area, mie.q_sca() * area);
                c_ext += w * ce;
                c_sca += w * cs;
                size_w.push(w * cs);
                sizes.push(SizeEntry {
                    cdf: phase_cdf(&mie),
                    mie,
                    c_sca_nm2: cs,
                });
            }
            let total: f64 = size_w.iter().sum();
            let mut acc = 0.0;
            let size_cdf = size_w
                .iter()
                .map(|w| {
                    acc += w / total;
                    acc
                })
                .collect();
            table.push(LambdaEntry {
                mu_ext_per_nm: density * c_ext,
                albedo: (c_sca / c_ext).min(1.0),
                k_host,
                sizes,
                size_cdf,
            });
        }
        Ok(ScatterModel::Mie { first_nm, table })
    }

    fn entry(&self, lambda_nm: f64) -> Option<&LambdaEntry> {
        match self {
            ScatterModel::Mie { first_nm, table } => {
                let i = (lambda_nm.round() as i64 - first_nm).clamp(0, table.len() as i64 - 1);
                table.get(i as usize)
            }
            ScatterModel::HenyeyGreenstein { .. } => None,
        }
    }

    /// Extinction coefficient (1/nm) and single-scattering albedo at `lambda_nm`.
    pub fn coefficients(&self, lambda_nm: f64) -> (f64, f64) {
        match self {
            ScatterModel::HenyeyGreenstein {
                mu_sca_per_nm,
                mu_abs_per_nm,
                ..
            } => {
                let ext = mu_sca_per_nm + mu_abs_per_nm;
                (ext, mu_sca_per_nm / ext)
            }
            ScatterModel::Mie { .. } => {
                let e = self.entry(lambda_nm).expect("a tabulated wavelength");
                (e.mu_ext_per_nm, e.albedo)
            }
        }
    }

    /// Scatters a wave travelling along `d` (unit) with fields `e` (the two incident
    /// polarisations): returns the new direction and replaces the fields, their power
    /// multiplied by the albedo and by the event's importance weight.
    pub fn scatter(&self, lambda_nm: f64, d: DVec3, e: &mut [Field; 2], rng: &mut Rng) -> DVec3 {
        let (u, v) = frame(d);
        let phi = std::f64::consts::TAU * rng.uniform();
        let (sp, cp) = phi.sin_cos();
        match self {
            ScatterModel::HenyeyGreenstein { g, .. } => {
                let mu = sample_hg(*g, rng.uniform());
                let s = (1.0 - mu * mu).max(0.0).sqrt();
                let d2 = (d * mu + (u * cp + v * sp) * s).normalize();
                let (_, albedo) = self.coefficients(lambda_nm);
                let e_perp = v * cp - u * sp;
                let (par_in, par_out) = (e_perp.cross(d), e_perp.cross(d2));
                let a = albedo.sqrt();
                for f in e.iter_mut() {
                    let (ep, es) = (field_dot_real(f, par_in), field_dot_real(f, e_perp));
                    *f = combine(ep * a, par_out, es * a, e_perp);
                }
                d2
            }
            ScatterModel::Mie { .. } => {
                let t = self.entry(lambda_nm).expect("a tabulated wavelength");
                let r = rng.uniform();
                let k = t
                    .size_cdf
                    .partition_point(|&c| c < r)
                    .min(t.sizes.len() - 1);
                let size = &t.sizes[k];
                // theta: an interval by its mass, then uniform inside it.
                let r = rng.uniform();
                let i = size
                    .cdf
                    .partition_point(|&c| c <= r)
                    .clamp(1, THETA_INTERVALS)
                    - 1;
                let dtheta = std::f64::consts::PI / THETA_INTERVALS as f64;
                let theta = (i as f64 + rng.uniform()) * dtheta;
                let p_interval = size.cdf[i + 1] - size.cdf[i];
                let (st, mu) = theta.sin_cos();
                let d2 = (d * mu + (u * cp + v * sp) * st).normalize();
                // Density over solid angle: p / dtheta / (2 pi sin theta).
                let q = p_interval / (dtheta * std::f64::consts::TAU * st);
                let (s1, s2) = size.mie.s1_s2(mu);
                let norm = t.albedo.sqrt() / (t.k_host * t.k_host * size.c_sca_nm2 * q).sqrt();
                let e_perp = v * cp - u * sp;
                let (par_in, par_out) = (e_perp.cross(d), e_perp.cross(d2));
                for f in e.iter_mut() {
                    let (ep, es) = (field_dot_real(f, par_in), field_dot_real(f, e_perp));
                    let (a, b) = (s2 * ep * norm, s1 * es * norm);
                    *f = if st > 0.0 && q.is_finite() {
                        combine(a, par_out, b, e_perp)
                    } else {
                        [C64::new(0.0, 0.0); 3]
                    };
                }
                d2
            }
        }
    }
}

/// `a p + b q` for complex `a`, `b` and real vectors.
fn combine(a: C64, p: DVec3, b: C64, q: DVec3) -> Field {
    [a * p.x + b * q.x, a * p.y + b * q.y, a * p.z + b * q.z]
}

/// Two unit vectors completing `d` to a right-handed orthonormal frame `(u, v, d)`
/// (Duff et al., "Building an orthonormal basis, revisited", JCGT 6(1), 2017).
fn frame(d: DVec3) -> (DVec3, DVec3) {
    let sign = 1f64.copysign(d.z);
    let a = -1.0 / (sign + d.z);
    let b = d.x * d.y * a;
    (
        DVec3::new(1.0 + sign * d.x * d.x * a, sign * b, -sign * d.x),
        DVec3::new(b, sign + d.y * d.y * a, -d.y),
    )
}

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
/// [-1, 1]): `(1 - g^2) / (2 (1 + g^2 - 2 g mu)^(3/2))`.
pub fn hg_density(g: f64, mu: f64) -> f64 {
    (1.0 - g * g) / (2.0 * (1.0 + g * g - 2.0 * g * mu).powf(1.5))
}

/// The cumulative mass of the unpolarised phase function `(|S1|^2 + |S2|^2)/2 sin theta`
/// over `THETA_INTERVALS` equal intervals of theta (trapezoids), normalised to 1.
fn phase_cdf(mie: &Mie) -> Vec<f64> {
    let n = THETA_INTERVALS;
    let f: Vec<f64> = (0..=n)
        .map(|j| {
            let theta = std::f64::consts::PI * j as f64 / n as f64;
            let (s1, s2) = mie.s1_s2(theta.cos());
            0.5 * (s1.norm_sqr() + s2.norm_sqr()) * theta.sin()
        })
        .collect();
    let mut cdf = Vec::with_capacity(n + 1);
    cdf.push(0.0);
    let mut acc = 0.0;
    for j in 0..n {
        acc += 0.5 * (f[j] + f[j + 1]);
        cdf.push(acc);
    }
    // Every interval keeps some mass, so every direction can be drawn.
    let floor = 1e-12 * acc / n as f64;
    let mut acc2 = 0.0;
    for j in 0..n {
        let m = (cdf[j + 1] - cdf[j]).max(floor);
        acc2 += m;
        cdf[j + 1] = acc2;
    }
    for c in cdf.iter_mut() {
        *c /= acc2;
    }
    cdf
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optics::fresnel::field_power;

    fn unpolarised_pair(d: DVec3) -> [Field; 2] {
        let (u, v) = frame(d);
        let f = |w: DVec3| [C64::new(w.x, 0.0), C64::new(w.y, 0.0), C64::new(w.z, 0.0)];
        [f(u), f(v)]
    }

    #[test]
    fn frames_are_orthonormal() {
        for d in [
            DVec3::Z,
            -DVec3::Z,
            DVec3::new(0.3, -0.4, 0.866).normalize(),
            DVec3::X,
        ] {
            let (u, v) = frame(d);
            assert!((u.length() - 1.0).abs() < 1e-12 && (v.length() - 1.0).abs() < 1e-12);
            assert!(u.dot(v).abs() < 1e-12 && u.dot(d).abs() < 1e-12);
            assert!((u.cross(v) - d).length() < 1e-12);
        }
    }

    /// The weighted histogram of scattered directions against the phase function's mass
    /// in each bin of cos theta (chi-square with the per-bin variance of the weights).
    fn chi_square(model: &ScatterModel, lambda: f64, expected: &dyn Fn(f64, f64) -> f64) -> f64 {
        let bins = 40;
        let n = 200_000;
        let d = DVec3::new(0.2, 0.1, -0.97).normalize();
        let mut rng = Rng::new(7, 1);
        let (mut sw, mut sw2) = (vec![0.0; bins], vec![0.0; bins]);
        let (_, albedo) = model.coefficients(lambda);
        for _ in 0..n {
            let mut e = unpolarised_pair(d);
            let d2 = model.scatter(lambda, d, &mut e, &mut rng);
            let w = 0.5 * (field_power(&e[0]) + field_power(&e[1])) / albedo;
            let mu = d.dot(d2).clamp(-1.0, 1.0);
            let b = (((mu + 1.0) / 2.0 * bins as f64) as usize).min(bins - 1);
            sw[b] += w;
            sw2[b] += w * w;
        }
        let mut chi2 = 0.0;
        for b in 0..bins {
            let (lo, hi) = (
                -1.0 + 2.0 * b as f64 / bins as f64,
                -1.0 + 2.0 * (b + 1) as f64 / bins as f64,
            );
            let want = expected(lo, hi);
            let mean = sw[b] / n as f64;
            let var = (sw2[b] / n as f64 - mean * mean).max(1e-300) / n as f64;
            chi2 += (mean - want).powi(2) / var;
        }
        chi2
    }

    /// chi-square with 40 degrees of freedom exceeds 73.4 with probability 1e-3.
    const CHI2_40_P001: f64 = 73.4;

    #[test]
    fn henyey_greenstein_directions_follow_the_phase_function() {
        for g in [0.0, 0.5, -0.3, 0.9] {
            let m = ScatterModel::henyey_greenstein(g, 1.0, 0.1).unwrap();
            let chi2 = chi_square(&m, 550.0, &|lo, hi| {
                // Exact mass of the HG density over [lo, hi] by fine midpoint quadrature.
                let k = 2000;
                (0..k)
                    .map(|i| hg_density(g, lo + (i as f64 + 0.5) * (hi - lo) / k as f64))
                    .sum::<f64>()
                    * (hi - lo)
                    / k as f64
            });
            assert!(chi2 < CHI2_40_P001, "g {g}: chi2 {chi2}");
        }
    }

    #[test]
    fn mie_directions_and_weights_follow_the_phase_function() {
        for (r, lambda) in [(150.0, 550.0), (40.0, 450.0), (1500.0, 600.0)] {
            let m = ScatterModel::mie(
                Radius::Fixed { radius_nm: r },
                0.05,
                lambda,
                lambda,
                &|_| C64::new(1.5, 0.0),
                &|_| C64::new(2.6, 0.01),
            )
            .unwrap();
            let ScatterModel::Mie { table, .. } = &m else {
                unreachable!()
            };
            let e = &table[0];
            let size = &e.sizes[0];
            let k = e.k_host;
            let chi2 = chi_square(&m, lambda, &|lo, hi| {
                let n = 4000;
                let mass: f64 = (0..n)
                    .map(|i| {
                        let mu = lo + (i as f64 + 0.5) * (hi - lo) / n as f64;
                        let (s1, s2) = size.mie.s1_s2(mu);
                        0.5 * (s1.norm_sqr() + s2.norm_sqr())
                    })
                    .sum::<f64>()
                    * (hi - lo)
                    / n as f64;
                // dOmega = 2 pi dmu; dC/dOmega = |S|^2 / k^2.
                std::f64::consts::TAU * mass / (k * k * size.c_sca_nm2)
            });
            assert!(chi2 < CHI2_40_P001, "r {r}: chi2 {chi2}");
        }
    }

    #[test]
    fn log_normal_nodes_have_the_median_and_spread() {
        let n = Radius::LogNormal {
            median_nm: 100.0,
            sigma: 0.3,
        }
        .nodes();
        let w: f64 = n.iter().map(|x| x.1).sum();
        assert!((w - 1.0).abs() < 1e-12);
        let mean_ln: f64 = n.iter().map(|(r, w)| w * r.ln()).sum();
        let var_ln: f64 = n.iter().map(|(r, w)| w * (r.ln() - mean_ln).powi(2)).sum();
        assert!((mean_ln - 100f64.ln()).abs() < 1e-12);
        // Truncation at 3.5 sigma removes 0.6 % of the variance.
        assert!(
            (var_ln.sqrt() / 0.3 - 1.0).abs() < 5e-3,
            "{}",
            var_ln.sqrt()
        );
    }

    #[test]
    fn bad_media_are_refused() {
        assert!(ScatterModel::henyey_greenstein(1.0, 1.0, 0.0).is_err());
        assert!(ScatterModel::henyey_greenstein(0.5, -1.0, 0.0).is_err());
        assert!(ScatterModel::henyey_greenstein(0.5, 0.0, 0.0).is_err());
        let host = |_: f64| C64::new(1.5, 0.0);
        let p = |_: f64| C64::new(2.6, 0.0);
        let r = Radius::Fixed { radius_nm: 100.0 };
        assert!(ScatterModel::mie(r, 0.0, 500.0, 600.0, &host, &p).is_err());
        assert!(ScatterModel::mie(r, 0.8, 500.0, 600.0, &host, &p).is_err());
        assert!(ScatterModel::mie(r, 0.1, 500.0, 600.0, &|_| C64::new(1.5, 0.1), &p).is_err());
    }
}
