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
//!   of radii (by number) at a volume fraction `f_v`. With number density `N = f_v /
//!   <V>`, `mu_ext = N <C_ext>` and `mu_sca = N <C_sca>` (BH eq. 3.40), the size integrals
//!   converged to a stated accuracy (`sizes`); packed spheres scatter dependently, the
//!   phase function multiplied by the hard spheres' structure factor (`structure`). A
//!   scattering event picks a radius with probability `w_r C_sca,r / sum w C_sca`, then a
//!   direction from the density
//!   `q(Omega) = sum_i |S E_i|^2 / (k^2 C_sca sum_i |E_i|^2)` of the two polarisation
//!   fields `E_i` the ray carries (BH eq. 3.12: `S E = S2 (E . e_par) e_par' + S1 (E .
//!   e_perp) e_perp` in the scattering-plane basis; `integral |S E|^2 dOmega = k^2 C_sca
//!   |E|^2` for a sphere and any polarisation). Its marginal in theta is the unpolarised
//!   phase function, drawn exactly by rejection under a tabulated envelope; given theta,
//!   the azimuth's density is `(1 + c cos(2 phi - phi0)) / (2 pi)`, drawn by rejection too.
//!   The fields become `E_i' = S E_i sqrt(omega sum_j |E_j|^2 / sum_j |S E_j|^2)`: the two
//!   fields' summed power is multiplied by exactly the albedo at every event (no random
//!   weights to pile up over hundreds of events), and every quantity the estimator forms
//!   (`sum_i |L E_i'|^2` for whatever linear optics `L` follows) is unbiased.
//! - **Henyey-Greenstein** (Astrophys. J. 93, 70, 1941): a prescribed `g`, `mu_sca` and
//!   `mu_abs`, the same at every wavelength, sampled exactly by its inverse CDF; the fields
//!   are carried into the new direction's scattering-plane basis unchanged in power (a
//!   model of the angular distribution only, as radiative-transfer references assume).
//!
//! Particle properties are tabulated per whole nanometre of wavelength and used at the
//! nearest one (for the size parameters of pigments, `x < 30`, they change by less than
//! 1e-3 relative over half a nanometre).

use super::C64;
use super::fresnel::{Field, field_dot_real, field_power};
use super::mie::{Mie, MieError};
use crate::geom::frame;
use crate::rng::Rng;
use glam::DVec3;

/// Intervals of the phase function's envelope over `theta` in `[0, pi]`, at least.
pub const THETA_INTERVALS: usize = 256;
pub use hg::{hg_density, sample_hg};
use sizes::size_integral;
pub use sizes::{MAX_RADIUS_NM, Radius, SIZE_TOLERANCE, TAIL_Z};
pub use towards::{COHERENCY_POINTS, Coherency};

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
    /// Stopped through the `cancelled` test given to [`ScatterModel::mie`].
    #[error("the particle medium's tabulation was cancelled")]
    Cancelled,
}

/// One radius at one wavelength.
#[derive(Clone, Debug)]
struct SizeEntry {
    mie: Mie,
    /// The envelope of the unpolarised phase function's density in theta,
    /// `f(theta) = (|S1|^2 + |S2|^2)/2 sin theta`: a constant bound per interval ...
    bound: Vec<f64>,
    /// ... and an alias table drawing an interval in proportion to its bound.
    alias: Alias,
    /// `[sin, cos]` of each interval's lower end (shared by the sizes of one interval
    /// count): a candidate angle's sine and cosine by the addition theorem.
    trig: std::sync::Arc<[[f64; 2]]>,
    /// With dependent scattering, the structure factor at the envelope's probes
    /// (`PROBE_STEPS` per interval, shared by the sizes of one interval count), between
    /// which a candidate angle's is interpolated linearly, where that is within
    /// `FACTOR_INTERPOLATION` of the closed form ([`interpolable`]); `None` where the
    /// closed form is evaluated at each candidate.
    factor: Option<std::sync::Arc<[f64]>>,
    /// `int_0^pi f S dtheta` (`S` the structure factor or 1; Simpson on the probes): the
    /// sampler's normalisation, for next-event estimation (`towards`).
    norm: f64,
}

/// Walker's alias method (Vose's construction, IEEE TSE 17(9), 972, 1991): draws index `i`
/// with probability `w_i / sum w` in constant time from one uniform number (one table
/// entry read, where a binary search over a large cumulative table missed the cache at
/// every step).
#[derive(Clone, Debug)]
struct Alias {
    prob: Vec<f64>,
    alias: Vec<u32>,
}

impl Alias {
    fn new(w: &[f64]) -> Alias {
        let n = w.len();
        let total: f64 = w.iter().sum();
        let mut scaled: Vec<f64> = w.iter().map(|x| x * n as f64 / total).collect();
        let (mut small, mut large): (Vec<usize>, Vec<usize>) =
            (0..n).partition(|&i| scaled[i] < 1.0);
        let mut prob = vec![1.0; n];
        let mut alias: Vec<u32> = (0..n as u32).collect();
        while let (Some(&s), Some(&l)) = (small.last(), large.last()) {
            small.pop();
            prob[s] = scaled[s];
            alias[s] = l as u32;
            scaled[l] -= 1.0 - scaled[s];
            if scaled[l] < 1.0 {
                large.pop();
                small.push(l);
            }
        }
        // What is left has probability 1 up to rounding.
        Alias { prob, alias }
    }

    /// An index for the uniform number `u` in [0, 1).
    #[inline]
    fn draw(&self, u: f64) -> usize {
        let x = u * self.prob.len() as f64;
        let i = (x as usize).min(self.prob.len() - 1);
        if x - i as f64 <= self.prob[i] {
            i
        } else {
            self.alias[i] as usize
        }
    }
}

/// A particle medium at one wavelength.
#[derive(Clone, Debug)]
pub struct LambdaEntry {
    mu_ext_per_nm: f64,
    albedo: f64,
    /// The size integral's asymmetry `<g C_sca> / <C_sca>`.
    g: f64,
    /// The size integral's last relative change (0 for one radius).
    size_change: f64,
    /// With dependent scattering: the structure factor and `k d` (host wavenumber times
    /// the spheres' diameter), for the sizes whose probes are too far apart to
    /// interpolate it (`SizeEntry::factor`).
    structure: Option<(structure::PercusYevick, f64)>,
    sizes: Vec<SizeEntry>,
    /// Cumulative probability of each size at a scattering event.
    size_cdf: Vec<f64>,
    /// The size-averaged scattered coherency over `sin(theta / 2)`, once asked (`towards`).
    coherency: std::sync::OnceLock<Box<[[f64; 4]]>>,
}

/// A scattering medium ready for the tracer.
#[derive(Debug)]
pub enum ScatterModel {
    HenyeyGreenstein {
        g: f64,
        mu_sca_per_nm: f64,
        mu_abs_per_nm: f64,
    },
    Mie {
        /// Wavelength of `table[0]`, nm; one entry per whole nanometre.
        first_nm: i64,
        table: Vec<std::sync::Arc<LambdaEntry>>,
        /// Draws where the phase function exceeded its envelope (the draw is then
        /// biased): 0 in a correct table; the run reports it.
        violations: std::sync::atomic::AtomicU64,
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

    /// Mie particles of radius `radius` at volume fraction `volume_fraction` (scattering
    /// dependently where `dependent`), tabulated for every whole nanometre covering
    /// `[lo_nm, hi_nm]`; `host(lambda)` and `particle(lambda)` are the complex indices of
    /// the host and the particles; `cancelled()` is asked between wavelengths and stops
    /// the tabulation with [`ParticleError::Cancelled`].
    #[allow(clippy::too_many_arguments)]
    pub fn mie(
        radius: Radius,
        volume_fraction: f64,
        dependent: bool,
        lo_nm: f64,
        hi_nm: f64,
        host: &(dyn Fn(f64) -> C64 + Sync),
        particle: &(dyn Fn(f64) -> C64 + Sync),
        cancelled: &(dyn Fn() -> bool + Sync),
    ) -> Result<ScatterModel, ParticleError> {
        let rcp = structure::RANDOM_CLOSE_PACKING;
        if !(volume_fraction.is_finite() && volume_fraction > 0.0 && volume_fraction < rcp) {
            return Err(ParticleError::Invalid(format!(
                "volume_fraction must lie in (0, {rcp}) ({rcp}: random close packing, the densest a suspension of spheres can be), got {volume_fraction}"
            )));
        }
        let [r_lo, r_hi] = radius.span_nm();
        if !(r_lo.is_finite() && r_lo > 0.0 && r_hi.is_finite()) {
            return Err(ParticleError::Invalid(format!(
                "particle radii must be positive and finite, got {r_lo} to {r_hi} nm"
            )));
        }
        // N = f_v / <V>, particles per nm^3.
        let density = volume_fraction / radius.mean_volume_nm3();
        // Dependent scattering: hard spheres of the volume-equivalent mean diameter.
        let packing = dependent.then(|| Packing {
            f: volume_fraction,
            d_nm: 2.0 * (radius.mean_volume_nm3() * 3.0 / (4.0 * std::f64::consts::PI)).cbrt(),
        });
        let first_nm = lo_nm.round() as i64;
        let last_nm = hi_nm.round() as i64;
        // Each whole nanometre on its own, in parallel (set-up grows as x^2 per size node);
        // collected in wavelength order, so the table is the same on any thread count.
        use rayon::prelude::*;
        let table = (first_nm..=last_nm)
            .into_par_iter()
            .map(|l| {
                // Asked between wavelengths (each a fraction of a second at most).
                if cancelled() {
                    return Err(ParticleError::Cancelled);
                }
                let key = memo::Key::new(
                    l as f64,
                    radius,
                    density,
                    packing,
                    host(l as f64),
                    particle(l as f64),
                );
                memo::entry(key, || {
                    lambda_entry(l as f64, radius, density, packing, host, particle)
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(ScatterModel::Mie {
            first_nm,
            table,
            violations: std::sync::atomic::AtomicU64::new(0),
        })
    }

    /// Draws that exceeded the envelope so far (see [`ScatterModel::Mie`]).
    pub fn violations(&self) -> u64 {
        match self {
            ScatterModel::Mie { violations, .. } => {
                violations.load(std::sync::atomic::Ordering::Relaxed)
            }
            ScatterModel::HenyeyGreenstein { .. } => 0,
        }
    }

    fn entry(&self, lambda_nm: f64) -> Option<&LambdaEntry> {
        match self {
            ScatterModel::Mie {
                first_nm, table, ..
            } => {
                let i = (lambda_nm.round() as i64 - first_nm).clamp(0, table.len() as i64 - 1);
                table.get(i as usize).map(|e| &**e)
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

    /// The asymmetry parameter `g = <cos theta>` at `lambda_nm`: the prescribed one, or
    /// the size integral's `<g C_sca> / <C_sca>`.
    pub fn asymmetry(&self, lambda_nm: f64) -> f64 {
        match self {
            ScatterModel::HenyeyGreenstein { g, .. } => *g,
            ScatterModel::Mie { .. } => self.entry(lambda_nm).expect("a tabulated wavelength").g,
        }
    }

    /// The asymmetry of the phase function a scattering event draws from at `lambda_nm`:
    /// the sampling radii's Mie asymmetries weighted by the scattering each stands for
    /// (the mixture of `sizes::SAMPLING_CELL_LN_R`).
    pub fn sampled_asymmetry(&self, lambda_nm: f64) -> f64 {
        match self {
            ScatterModel::HenyeyGreenstein { g, .. } => *g,
            ScatterModel::Mie { .. } => {
                let e = self.entry(lambda_nm).expect("a tabulated wavelength");
                let mut before = 0.0;
                e.sizes
                    .iter()
                    .zip(&e.size_cdf)
                    .map(|(s, &c)| {
                        let p = c - before;
                        before = c;
                        p * s.mie.g()
                    })
                    .sum()
            }
        }
    }

    /// The largest relative change of a size integral at its last refinement, over the
    /// tabulated wavelengths: below [`SIZE_TOLERANCE`] where it converged; above it where
    /// Mie resonances of lossless spheres narrower than the finest step remain (the
    /// integrals are then as good as that change says). 0 for one radius and for
    /// Henyey-Greenstein media.
    pub fn size_uncertainty(&self) -> f64 {
        match self {
            ScatterModel::HenyeyGreenstein { .. } => 0.0,
            ScatterModel::Mie { table, .. } => {
                table.iter().map(|e| e.size_change).fold(0.0, f64::max)
            }
        }
    }

    /// Scatters a wave travelling along `d` (unit) with fields `e` (the two incident
    /// polarisations): returns the new direction and replaces the fields, their power
    /// multiplied by the albedo and by the event's importance weight.
    pub fn scatter(&self, lambda_nm: f64, d: DVec3, e: &mut [Field; 2], rng: &mut Rng) -> DVec3 {
        let (u, v) = frame(d);
        match self {
            ScatterModel::HenyeyGreenstein { g, .. } => {
                let phi = std::f64::consts::TAU * rng.uniform();
                let (sp, cp) = phi.sin_cos();
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
            ScatterModel::Mie { violations, .. } => {
                let t = self.entry(lambda_nm).expect("a tabulated wavelength");
                let size = t.draw_size(rng.uniform());
                let n = size.bound.len();
                let dtheta = std::f64::consts::PI / n as f64;
                // theta from the unpolarised phase function, by rejection under the
                // envelope: an interval by the envelope's mass, a point in it, accepted
                // with probability f / bound.
                let (st, mu, s1, s2) = loop {
                    let i = size.alias.draw(rng.uniform());
                    // theta = theta_i + delta, 0 <= delta < pi / 256: sin and cos of
                    // delta by their Taylor series to delta^5 and delta^6 (the first terms
                    // left out are below 5e-17), then the addition theorem.
                    let frac = rng.uniform();
                    let delta = frac * dtheta;
                    let [s0, c0] = size.trig[i];
                    let d2 = delta * delta;
                    let sd = delta * (1.0 - d2 / 6.0 * (1.0 - d2 / 20.0));
                    let cd = 1.0 - d2 / 2.0 * (1.0 - d2 / 12.0 * (1.0 - d2 / 30.0));
                    let (st, ct) = (s0 * cd + c0 * sd, c0 * cd - s0 * sd);
                    let (s1, s2) = size.mie.s1_s2(ct);
                    let mut f = 0.5 * (s1.norm_sqr() + s2.norm_sqr()) * st;
                    if let Some(s) = &size.factor {
                        let x = (i as f64 + frac) * PROBE_STEPS as f64;
                        let j = (x as usize).min(s.len() - 2);
                        f *= s[j] + (x - j as f64) * (s[j + 1] - s[j]);
                    } else if let Some((py, kd)) = &t.structure {
                        // sin(theta / 2) = sqrt((1 - cos theta) / 2).
                        f *= py.at(2.0 * kd * (0.5 * (1.0 - ct)).max(0.0).sqrt());
                    }
                    if f > size.bound[i] {
                        violations.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    }
                    if rng.uniform() * size.bound[i] <= f {
                        break (st, ct, s1, s2);
                    }
                };
                // phi given theta: density (1 + rho (p cos 2phi + q sin 2phi)) / (2 pi) with
                // rho = (|S2|^2 - |S1|^2) / (|S2|^2 + |S1|^2), from the fields' components
                // a_i (along u) and b_i (along v): p = (alpha - beta) / (alpha + beta),
                // q = 2 Re sum a_i conj(b_i) / (alpha + beta). By rejection under 1 + |c|.
                let (mut alpha, mut beta, mut gamma) = (0.0, 0.0, 0.0);
                for f in e.iter() {
                    let (a, b) = (field_dot_real(f, u), field_dot_real(f, v));
                    alpha += a.norm_sqr();
                    beta += b.norm_sqr();
                    gamma += (a * b.conj()).re;
                }
                let (w1, w2) = (s1.norm_sqr(), s2.norm_sqr());
                let rho = if w1 + w2 > 0.0 {
                    (w2 - w1) / (w1 + w2)
                } else {
                    0.0
                };
                let total = (alpha + beta).max(f64::MIN_POSITIVE);
                let (pc, qc) = (rho * (alpha - beta) / total, rho * 2.0 * gamma / total);
                let amp = (pc * pc + qc * qc).sqrt();
                // A uniform azimuth without trigonometry: a point uniform in the unit disc
                // (by rejection from the square), whose angle is uniform.
                let (sp, cp) = loop {
                    let (x, y) = (2.0 * rng.uniform() - 1.0, 2.0 * rng.uniform() - 1.0);
                    let r2 = x * x + y * y;
                    if !(r2 > 1e-300 && r2 <= 1.0) {
                        continue;
                    }
                    let (c2, s2p) = ((x * x - y * y) / r2, 2.0 * x * y / r2);
                    if rng.uniform() * (1.0 + amp) <= 1.0 + pc * c2 + qc * s2p {
                        let r = r2.sqrt();
                        break (y / r, x / r);
                    }
                };
                let d2 = (d * mu + (u * cp + v * sp) * st).normalize();
                let e_perp = v * cp - u * sp;
                let (par_in, par_out) = (e_perp.cross(d), e_perp.cross(d2));
                let mut scattered = [[C64::new(0.0, 0.0); 3]; 2];
                let (mut p_in, mut p_out) = (0.0, 0.0);
                for (f, out) in e.iter().zip(scattered.iter_mut()) {
                    let (ep, es) = (field_dot_real(f, par_in), field_dot_real(f, e_perp));
                    *out = combine(s2 * ep, par_out, s1 * es, e_perp);
                    p_in += field_power(f);
                    p_out += field_power(out);
                }
                let norm = if p_out > 0.0 {
                    (t.albedo * p_in / p_out).sqrt()
                } else {
                    0.0
                };
                for (f, out) in e.iter_mut().zip(scattered) {
                    *f = out.map(|c| c * norm);
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

/// One wavelength's entry of [`ScatterModel::mie`]: the size-averaged extinction and
/// albedo, and each size node's coefficients and envelope.
#[allow(clippy::too_many_arguments)]
fn lambda_entry(
    lambda: f64,
    radius: Radius,
    density: f64,
    packing: Option<Packing>,
    host: &(dyn Fn(f64) -> C64 + Sync),
    particle: &(dyn Fn(f64) -> C64 + Sync),
) -> Result<LambdaEntry, ParticleError> {
    let nh = host(lambda);
    if nh.im != 0.0 {
        return Err(ParticleError::AbsorbingHost {
            lambda_nm: lambda,
            k: nh.im,
        });
    }
    let k_host = 2.0 * std::f64::consts::PI * nh.re / lambda;
    let m = particle(lambda) / nh.re;
    let integral = size_integral(radius, k_host, m, MAX_RADIUS_NM)
        .map_err(|e| ParticleError::Invalid(format!("at {lambda} nm: {e}")))?;
    let [c_ext, c_sca, c_g] = integral.sums;
    // The structure factor as a function of theta: S(q d), q = 2 k sin(theta / 2).
    let s_of = packing.map(|p| (structure::PercusYevick::new(p.f), k_host * p.d_nm));
    // S at the envelope's probes, once per interval count (most sizes share 256).
    let mut factors: Vec<(usize, std::sync::Arc<[f64]>)> = Vec::new();
    // The intervals' lower ends' sine and cosine, once per interval count.
    let mut trigs: Vec<(usize, std::sync::Arc<[[f64; 2]]>)> = Vec::new();
    let mut sizes = Vec::with_capacity(integral.sampling.len());
    let mut size_w = Vec::with_capacity(integral.sampling.len());
    // With packing: each sampling radius's scattering and g under S (the share of its
    // phase function S keeps, and the mean cosine of what it keeps).
    let (mut c_sca_dep, mut c_g_dep) = (0.0, 0.0);
    for (mie, w) in integral.sampling {
        let n = envelope_intervals(&mie);
        let table = match s_of {
            None => None,
            Some((py, kd)) => {
                if !factors.iter().any(|t| t.0 == n) {
                    let h = std::f64::consts::PI / n as f64;
                    let probes = (0..=n * PROBE_STEPS).map(|j| {
                        let theta = j as f64 / PROBE_STEPS as f64 * h;
                        py.at(2.0 * kd * (0.5 * theta).sin())
                    });
                    factors.push((n, probes.collect::<Vec<f64>>().into()));
                }
                factors.iter().find(|t| t.0 == n).map(|t| t.1.clone())
            }
        };
        let (bound, kept, mean_cos, norm) = envelope(&mie, table.as_deref());
        let w = w * kept;
        c_sca_dep += w;
        c_g_dep += w * mean_cos;
        size_w.push(w);
        let alias = Alias::new(&bound);
        if !trigs.iter().any(|t| t.0 == n) {
            let h = std::f64::consts::PI / n as f64;
            let t: Vec<[f64; 2]> = (0..n)
                .map(|i| {
                    let (s, c) = (i as f64 * h).sin_cos();
                    [s, c]
                })
                .collect();
            trigs.push((n, t.into()));
        }
        let trig = trigs
            .iter()
            .find(|t| t.0 == n)
            .expect("just added")
            .1
            .clone();
        sizes.push(SizeEntry {
            bound,
            alias,
            trig,
            factor: table.filter(|t| interpolable(t)),
            mie,
            norm,
        });
    }
    let (c_sca, g) = if packing.is_some() {
        (c_sca_dep, c_g_dep / c_sca_dep)
    } else {
        (c_sca, c_g / c_sca)
    };
    // Absorption is the independent spheres' (C_ext - C_sca of the integral).
    let c_ext = c_ext - integral.sums[1] + c_sca;
    let total: f64 = size_w.iter().sum();
    let mut acc = 0.0;
    let size_cdf = size_w
        .iter()
        .map(|w| {
            acc += w / total;
            acc
        })
        .collect();
    Ok(LambdaEntry {
        structure: s_of,
        mu_ext_per_nm: density * c_ext,
        albedo: (c_sca / c_ext).min(1.0),
        g,
        size_change: integral.change,
        sizes,
        size_cdf,
        coherency: std::sync::OnceLock::new(),
    })
}

/// The largest error allowed to the structure factor interpolated between the envelope's
/// probes: the phase function is then within 1e-5 of itself, below the standard error of
/// any run (a relative 1e-5 takes 1e10 trees to see), and far below the approximation's
/// own error (within 20 % of a T-matrix solution; docs/physics.md). Packed small spheres
/// qualify (k d below about 6 at 20 % by volume: the shipped white paint at every visible
/// wavelength); denser or larger ones evaluate the closed form at each candidate.
const FACTOR_INTERPOLATION: f64 = 1e-5;

/// Whether the structure factor tabulated at evenly spaced probes `s` is within
/// `FACTOR_INTERPOLATION` of itself between them by linear interpolation: its error there
/// is at most `h^2 / 8 max |S''|` (e.g. Atkinson, An Introduction to Numerical Analysis,
/// 1989, eq. 3.2.11), `h^2 S''` being the second difference to the next order, taken
/// here with a factor 2 margin.
fn interpolable(s: &[f64]) -> bool {
    let worst = s
        .windows(3)
        .map(|w| (w[0] - 2.0 * w[1] + w[2]).abs())
        .fold(0.0, f64::max);
    2.0 * worst / 8.0 <= FACTOR_INTERPOLATION
}

/// Hard spheres packed at volume fraction `f`, of diameter `d_nm` (the Percus-Yevick
/// structure factor's).
#[derive(Clone, Copy, Debug)]
struct Packing {
    f: f64,
    d_nm: f64,
}

/// The envelope's interval count for `mie`: `max(THETA_INTERVALS, 8 N)`.
fn envelope_intervals(mie: &Mie) -> usize {
    THETA_INTERVALS.max(8 * mie.a.len())
}

/// Steps between an envelope interval's probes: its `PROBE_STEPS + 1` evenly spaced
/// values of `f` (the ends shared with the neighbours).
const PROBE_STEPS: usize = 8;

/// The envelope of `f(theta) = (|S1|^2 + |S2|^2)/2 sin theta` for rejection sampling:
/// `max(THETA_INTERVALS, 8 N)` equal intervals of theta (N the series' orders, so an
/// interval is narrower than an eighth of the lobe's finest oscillation, of period P), in
/// each the largest of its `PROBE_STEPS + 1` evenly spaced values times 1.08, plus a floor
/// of 1e-9 of the peak. `f` is a trigonometric polynomial of degree about 2N, so a maximum
/// lies within half a probe step (P / 128) of a probe, where a lobe of period P has
/// fallen by at most `1 - cos(2 pi / 128)`, 0.12 %; the 8 % margin covers that many times
/// over. A draw above the bound is counted ([`ScatterModel::violations`]) and reported by
/// the run, never hidden; the tests draw millions across sizes and indices and find none.
/// With packing, `f` is multiplied by the structure factor at each probe (`factor`,
/// `PROBE_STEPS n + 1` of them; `S` varies over `1 / (k d)` in theta, slower than the
/// lobes). Returns the per-interval bounds, the share of the phase function the factor
/// keeps, the mean cosine of what it keeps and the integral of what it keeps over theta
/// (Simpson's rule on the probes).
fn envelope(mie: &Mie, factor: Option<&[f64]>) -> (Vec<f64>, f64, f64, f64) {
    let n = envelope_intervals(mie);
    let h = std::f64::consts::PI / (n * PROBE_STEPS) as f64;
    // Each probe once: f, its factor, and cos theta.
    let probes: Vec<(f64, f64, f64)> = (0..=n * PROBE_STEPS)
        .map(|j| {
            let (st, ct) = (j as f64 * h).sin_cos();
            let (s1, s2) = mie.s1_s2(ct);
            let p = 0.5 * (s1.norm_sqr() + s2.norm_sqr()) * st.max(0.0);
            (p, factor.map_or(1.0, |t| t[j]), ct)
        })
        .collect();
    // Simpson's rule on the probes (PROBE_STEPS subintervals per interval, an even count)
    // for the share of the phase function the factor keeps and its mean cosine.
    let (mut all, mut kept, mut cos) = (0.0, 0.0, 0.0);
    for (j, &(p, s, ct)) in probes.iter().enumerate() {
        let w = if j == 0 || j == n * PROBE_STEPS {
            1.0
        } else if j % 2 == 1 {
            4.0
        } else {
            2.0
        };
        all += w * p;
        kept += w * p * s;
        cos += w * p * s * ct;
    }
    let mut bound: Vec<f64> = probes
        .windows(PROBE_STEPS + 1)
        .step_by(PROBE_STEPS)
        .map(|w| 1.08 * w.iter().map(|&(p, s, _)| p * s).fold(0.0f64, f64::max))
        .collect();
    let peak = bound.iter().copied().fold(0.0, f64::max);
    for b in bound.iter_mut() {
        *b = b.max(1e-9 * peak);
    }
    let share = if all > 0.0 { kept / all } else { 1.0 };
    let mean_cos = if kept > 0.0 { cos / kept } else { 0.0 };
    (bound, share, mean_cos, kept * h / 3.0)
}

mod hg;
mod memo;
mod sizes;
pub mod structure;
mod towards;

#[cfg(test)]
mod tests;
