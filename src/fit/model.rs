//! The fit's reflectance model: a base, bare or under a thin film, by the transfer-matrix
//! method, scaled by the single-scattering lobe's albedo, plus the bare base's multiple
//! scattering.

use super::{Base, Data, Film, lobe_model};
use crate::optics::C64;
use crate::optics::tmm::{self, StackIndices};

/// Unpolarised reflectance at `theta` (radians, in air) of the base, or of the film on it,
/// at wavelength index `j`.
pub(super) fn reflectance(
    base: &Base,
    film: Option<(f64, f64)>,
    theta: f64,
    lambda: f64,
    j: usize,
) -> f64 {
    let nb = match base {
        Base::Dielectric { n } => C64::new(*n, 0.0),
        Base::Conductor { n } => n[j],
    };
    let (n, d_nm) = match film {
        Some((d, nf)) => (vec![C64::new(1.0, 0.0), C64::new(nf, 0.0), nb], vec![d]),
        None => (vec![C64::new(1.0, 0.0), nb], Vec::new()),
    };
    tmm::solve(&StackIndices { n, d_nm }, lambda, theta).r()
}

/// The model's reflectance table `R[i][j]` for given parameters, albedos `e[i]` and the
/// mean albedo `e_avg` ([`Albedo`]): single scattering `E F` plus the multiple-scattering
/// term of the bare base ([`multiple_scattering`]).
pub(super) fn model_r(data: &Data, e: &Albedo, base: &Base, film: Option<Film>) -> Vec<Vec<f64>> {
    model_on(data, e, base, &BaseTerms::new(data, e, base), film)
}

/// The terms of [`model_r`] that depend on the base alone (its bare reflectance at every
/// angle and wavelength, and its multiple scattering: 21 of every 26 transfer-matrix
/// solutions at 5 angles), computed once for the many films a search tries on one base.
pub(super) struct BaseTerms {
    bare: Vec<Vec<f64>>,
    ms: Vec<f64>,
}

impl BaseTerms {
    pub(super) fn new(data: &Data, e: &Albedo, base: &Base) -> BaseTerms {
        let ms = data
            .lambda_nm
            .iter()
            .enumerate()
            .map(|(j, &l)| multiple_scattering(base, l, j, e.avg))
            .collect();
        let bare = data
            .theta_i_rad
            .iter()
            .map(|&th| {
                data.lambda_nm
                    .iter()
                    .enumerate()
                    .map(|(j, &l)| reflectance(base, None, th, l, j))
                    .collect()
            })
            .collect();
        BaseTerms { bare, ms }
    }
}

/// [`model_r`] with the base's own terms given (`terms` from the same `base`).
pub(super) fn model_on(
    data: &Data,
    e: &Albedo,
    base: &Base,
    terms: &BaseTerms,
    film: Option<Film>,
) -> Vec<Vec<f64>> {
    data.theta_i_rad
        .iter()
        .enumerate()
        .map(|(i, &th)| {
            data.lambda_nm
                .iter()
                .enumerate()
                .map(|(j, &l)| {
                    let fb = terms.bare[i][j];
                    let f = match film {
                        Some(fm) => {
                            fm.weight * reflectance(base, Some((fm.thickness_nm, fm.n)), th, l, j)
                                + (1.0 - fm.weight) * fb
                        }
                        None => fb,
                    };
                    e.at[i] * f + (1.0 - e.at[i]) * terms.ms[j]
                })
                .collect()
        })
        .collect()
}

/// The single-scattering lobe's directional albedo with `F = 1` at each incident angle
/// (`at`) and its cosine-weighted mean over the hemisphere (`avg`, `2 int E(mu) mu dmu`).
pub(super) struct Albedo {
    pub(super) at: Vec<f64>,
    pub(super) avg: f64,
}

impl Albedo {
    pub(super) fn new(data: &Data, alpha: f64) -> Albedo {
        let e = |th: f64| lobe_model(data, alpha, th).iter().sum::<f64>().min(1.0);
        // Midpoint rule in mu on 16 points: E(mu) is smooth and bounded.
        const M: usize = 16;
        let avg = (0..M)
            .map(|k| {
                let mu = (k as f64 + 0.5) / M as f64;
                2.0 * mu * e(mu.acos()) / M as f64
            })
            .sum();
        Albedo {
            at: data.theta_i_rad.iter().map(|&th| e(th)).collect(),
            avg,
        }
    }
}

/// The directional albedo the single-scattering lobe leaves out, per unit `1 - E(theta_i)`:
/// light that a microfacet sends into another one before it escapes, Fresnel-weighted at
/// every bounce, `F_avg^2 E_avg / (1 - F_avg (1 - E_avg))` (Kulla & Conty, "Revisiting
/// Physically Based Shading at Imageworks", SIGGRAPH 2017 course, the Fresnel term of their
/// multiple-scattering lobe), with `F_avg = 2 int F(mu) mu dmu` of the bare base. The
/// simulation keeps that light; without the term the fit pushed a conductor's `k` to its
/// bound to make up for it.
pub(super) fn multiple_scattering(base: &Base, lambda: f64, j: usize, e_avg: f64) -> f64 {
    const M: usize = 16;
    let f_avg: f64 = (0..M)
        .map(|k| {
            let mu = (k as f64 + 0.5) / M as f64;
            2.0 * mu * reflectance(base, None, mu.acos(), lambda, j) / M as f64
        })
        .sum();
    f_avg * f_avg * e_avg / (1.0 - f_avg * (1.0 - e_avg))
}
