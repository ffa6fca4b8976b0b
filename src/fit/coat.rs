//! The clear coat of a fit (issue 46): the mirror bucket's power beyond the lobe around
//! it, a dielectric coat's index from its Fresnel reflection, and the base fitted under the
//! coat (docs/fitting.md, "Clear coats").

use glam::DVec3;

use super::{BaseKind, Data, Fit, cost, errors, fit_layer, golden, model_table, quality_warnings};
use crate::geom::from_spherical;
use crate::optics::C64;
use crate::render::colour;

/// Buckets whose centre lies within this angle of the mirror direction (radians), the
/// mirror's own excluded, give the lobe's density around it ([`mirror_excess`]).
pub(super) const MIRROR_NEIGHBOURHOOD: f64 = 0.105; // 6 degrees

/// The power in the mirror direction's bucket `b` of cell `c` beyond the lobe's: `P_b -
/// rho Omega_b`, with `rho` the power per unit projected solid angle of the buckets around
/// it (centres within [`MIRROR_NEIGHBOURHOOD`] of `mirror`, `b` excluded). A smooth coat
/// over a rough or scattering base puts its Fresnel reflection there alone; a rough
/// surface's lobe spreads over the neighbours too and leaves about nothing.
pub(super) fn mirror_excess(
    c: &crate::accumulate::Cell,
    mode: crate::accumulate::Coherence,
    buckets: &crate::accumulate::Buckets,
    b: usize,
    mirror: DVec3,
) -> f64 {
    let (mut p, mut omega) = (0.0, 0.0);
    for k in 0..buckets.len() {
        if k == b {
            continue;
        }
        let (th, ph) = buckets.centre(k);
        if from_spherical(th, ph).angle_between(mirror) < MIRROR_NEIGHBOURHOOD {
            p += c.fraction(2 * k, mode);
            omega += buckets.projected_solid_angle(k);
        }
    }
    let rho = if omega > 0.0 { p / omega } else { 0.0 };
    c.fraction(2 * b, mode) - rho * buckets.projected_solid_angle(b)
}

/// A smooth clear coat over the base (OpenPBR `coat_*`, glTF `KHR_materials_clearcoat`): a
/// dielectric interface of index `ior` whose Fresnel reflection `F_c(theta_i)` is a mirror
/// lobe, with the base seen through it weighted by `1 - F_c(theta_i)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coat {
    pub ior: f64,
    /// GGX alpha of the coat's lobe: 0 for the mirror the buckets cannot resolve further.
    pub alpha: f64,
}

/// Whether the fit tries a clear coat over the base.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CoatChoice {
    /// Where the simulation shows a mirror lobe beyond the lobe around it, a coat of fitted
    /// index, kept where it matches the simulation better than no coat.
    Auto,
    /// No coat.
    None,
    /// A coat of this index, always (the sample's clear coat, known to the user).
    Ior(f64),
}

/// The unpolarised Fresnel reflectance of a dielectric interface of index `n` from air at
/// `theta` (radians).
pub(super) fn fresnel(n: f64, theta: f64) -> f64 {
    crate::optics::fresnel::coefficients(C64::new(1.0, 0.0), C64::new(n, 0.0), theta.cos())
        .r_s
        .norm_sqr()
        * 0.5
        + crate::optics::fresnel::coefficients(C64::new(1.0, 0.0), C64::new(n, 0.0), theta.cos())
            .r_p
            .norm_sqr()
            * 0.5
}

/// A clear coat over a base (issue 46): where the smallest incident angle's mirror bucket holds
/// more than the lobe around it ([`Data::mirror`], above 0.01 of the power at the smallest
/// angle), the coat's index is fitted to that excess by the Fresnel reflectance (golden
/// section over 1.3-1.8, with a constant for the base's own light there; or the index the
/// user gives), and the base to what the coat passes: `R_base = (R - F_c) / (1 -
/// F_c)` with the mirror bucket's power replaced by its surroundings' in the lobe, by the
/// three stages of [`fit_layer`]. The model is `F_c(theta_i) + (1 - F_c(theta_i))
/// R_base(theta_i)`, OpenPBR's coat over its base without the coat's absorption. Returns the
/// fit, its cost on the whole material and whether a coat's Fresnel reflection explains
/// the excess (the index off the bounds, the base's constant below a quarter of the coat's
/// normal reflectance, the rest within a tenth), or `None` without such a mirror lobe.
pub(super) fn fit_coated(
    data: &Data,
    kind: BaseKind,
    try_film: bool,
    choice: CoatChoice,
) -> Option<(Fit, f64, bool)> {
    let mean_row = |r: &[f64]| r.iter().sum::<f64>() / r.len().max(1) as f64;
    let excess: Vec<f64> = data.mirror.iter().map(|r| mean_row(r)).collect();
    let first = data
        .theta_i_rad
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))
        .map(|(i, _)| i)?;
    if excess[first] < 0.01 && choice == CoatChoice::Auto {
        return None;
    }
    // The excess is the coat's Fresnel reflection plus what the base itself sends into the
    // mirror bucket beyond its surroundings (flakes near the surface's plane): F(n, theta)
    // plus a constant b >= 0, least squares in b for each n.
    let misfit = |n: f64| {
        let d: Vec<f64> = data
            .theta_i_rad
            .iter()
            .zip(&excess)
            .map(|(&th, &e)| e - fresnel(n, th))
            .collect();
        let b = (d.iter().sum::<f64>() / d.len() as f64).max(0.0);
        d.iter().map(|x| (x - b).powi(2)).sum::<f64>()
    };
    let ior = match choice {
        CoatChoice::Ior(n) => n,
        _ => golden(misfit, 1.3, 1.8, 60),
    };
    // A coat's Fresnel reflection explains the excess: the index off the search's bounds,
    // the base's constant under a quarter of the coat's normal reflectance, and what is
    // left within a tenth of the excess (RMS over the angles).
    let fresnel_like = {
        let d: Vec<f64> = data
            .theta_i_rad
            .iter()
            .zip(&excess)
            .map(|(&th, &e)| e - fresnel(ior, th))
            .collect();
        let b = (d.iter().sum::<f64>() / d.len() as f64).max(0.0);
        let rms = (d.iter().map(|x| (x - b).powi(2)).sum::<f64>() / d.len() as f64).sqrt();
        let mean_excess = excess.iter().sum::<f64>() / excess.len() as f64;
        ior > 1.31 && ior < 1.79 && b < 0.25 * fresnel(ior, 0.0) && rms < 0.1 * mean_excess
    };
    let fc: Vec<f64> = data
        .theta_i_rad
        .iter()
        .map(|&th| fresnel(ior, th))
        .collect();
    let mut base = Data {
        theta_i_rad: data.theta_i_rad.clone(),
        phi_i_rad: data.phi_i_rad,
        lambda_nm: data.lambda_nm.clone(),
        r: data
            .r
            .iter()
            .zip(&fc)
            .map(|(row, &f)| row.iter().map(|v| ((v - f) / (1.0 - f)).max(0.0)).collect())
            .collect(),
        lobe: data.lobe.clone(),
        buckets: data.buckets,
        t: data.t.clone(),
        mirror: vec![vec![0.0; data.lambda_nm.len()]; data.theta_i_rad.len()],
        mirror_bucket: data.mirror_bucket.clone(),
    };
    // The coat's mirror is no part of the base's lobe shape.
    for (i, l) in base.lobe.iter_mut().enumerate() {
        l[data.mirror_bucket[i]] = f64::NAN;
    }
    let (mut fit, _) = fit_layer(&base, kind, try_film);
    // The whole material: the coat plus the base it passes.
    let m: Vec<Vec<f64>> = model_table(&base, &fit)
        .iter()
        .zip(&fc)
        .map(|(row, &f)| row.iter().map(|v| f + (1.0 - f) * v).collect())
        .collect();
    let weights = colour::bin_weights(&data.lambda_nm);
    let white = colour::xyz(&vec![1.0; data.lambda_nm.len()], &weights);
    let c = cost(data, &m, &weights, white);
    fit.coat = Some(Coat { ior, alpha: 0.0 });
    (fit.rms_residual, fit.delta_e2000) = errors(data, &m);
    fit.warnings = quality_warnings(fit.rms_residual, &fit.delta_e2000, fit.alpha, &fit.film);
    Some((fit, c, fresnel_like))
}

/// Whether a fit represents the material: RMS reflectance error at most 0.02 and every
/// CIEDE2000 at most 2 (where [`quality_warnings`] stays silent about it).
pub(super) fn represents(f: &Fit) -> bool {
    f.rms_residual <= 0.02 && f.delta_e2000.iter().all(|&d| d <= 2.0)
}
