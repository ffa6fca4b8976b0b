//! Coatings and the illumination's coherence radius: a coating is an exact transfer matrix
//! (`optics::tmm`), fully coherent whatever `--coherence-radius-nm` says, while a meshed
//! layer's partial waves interfere with the beamlet estimator's positional weight
//! `exp(-|dx_perp|^2 / (2 rho^2))` (docs/design.md §4). Where that weight would be
//! noticeably below 1, the run says the radius does not act on its coatings (issue 74: a
//! coated film at a 1 nm radius gave the fully coherent result byte for byte, unsaid).

use super::{Context, Finding, Method};
use crate::sample::Sample;

/// How far below 1 the first partial waves' positional weight may fall before the run
/// says that its coatings ignore the radius.
pub const WEIGHT_LOSS_SAID: f64 = 0.01;

/// The lateral offset across the beam, nm, between the wave a coating's top face reflects
/// and the one that crosses every layer and returns: `2 sum_k d_k tan(theta_k) cos(theta)`,
/// with `sin(theta_k) = n0 sin(theta) / n_k` (Snell's law, real parts of the indices) in
/// layer `k` of thickness `d_k` and `theta` in the medium `n0` the light comes from: the
/// offset along the face, seen across the direction of the reflected beam (as the
/// estimator's `dx_perp`). `None` where a layer is beyond total internal reflection (the
/// wave does not cross it) or a medium has no index at `lambda_nm`.
pub fn partial_wave_offset_nm(
    sample: &Sample,
    front: usize,
    layers: &[(usize, f64)],
    theta_rad: f64,
    lambda_nm: f64,
) -> Option<f64> {
    let n0 = sample.media[front].model.eval(lambda_nm).ok()?.0;
    let along: f64 = layers
        .iter()
        .map(|&(m, d)| {
            let n = sample.media[m].model.eval(lambda_nm).ok()?.0;
            let s = n0 * theta_rad.sin() / n;
            (s < 1.0).then(|| d * s / (1.0 - s * s).sqrt())
        })
        .sum::<Option<f64>>()?;
    Some(2.0 * along * theta_rad.cos())
}

/// The finding for the coating whose partial waves a meshed layer would weight least, at
/// the run's incidence on a face parallel to the tile and its middle wavelength; `None`
/// where every weight is within [`WEIGHT_LOSS_SAID`] of 1, the radius is infinite or the
/// method is the rigorous solver.
pub fn coatings_ignore_radius(sample: &Sample, ctx: &Context) -> Option<Finding> {
    let rho = ctx.rho_nm;
    if !rho.is_finite() || ctx.method == Method::Rigorous {
        return None;
    }
    let lambda = 0.5 * (ctx.lambda_min_nm + ctx.lambda_max_nm);
    // (weight, offset nm, theta deg, interface index).
    let mut worst: Option<(f64, f64, f64, usize)> = None;
    for (i, itf) in sample.interfaces.iter().enumerate() {
        if itf.coating.is_empty() {
            continue;
        }
        for &theta in &ctx.theta_i_deg {
            let Some(dx) =
                partial_wave_offset_nm(sample, itf.front, &itf.coating, theta.to_radians(), lambda)
            else {
                continue;
            };
            let w = (-dx * dx / (2.0 * rho * rho)).exp();
            if worst.is_none_or(|(v, ..)| w < v) {
                worst = Some((w, dx, theta, i));
            }
        }
    }
    let (w, dx, theta, i) = worst.filter(|(w, ..)| 1.0 - w > WEIGHT_LOSS_SAID)?;
    let itf = &sample.interfaces[i];
    let layers: Vec<String> = itf
        .coating
        .iter()
        .map(|&(m, d)| format!("'{}' {d} nm", sample.media[m].name))
        .collect();
    Some(Finding {
        message: format!(
            "the coating on {} ({}) is an exact transfer matrix and interferes fully whatever --coherence-radius-nm says: at a radius of {rho} nm and theta_i {theta} deg ({lambda} nm), its partial waves, {dx:.0} nm apart across the beam, would interfere in a meshed layer with weight exp(-dx^2 / (2 rho^2)) = {w:.3}. The radius acts on meshed layers only: to see it act, mesh the layers ([stack] mode = \"mesh\")",
            itf.mesh_path.display(),
            layers.join(", ")
        ),
    })
}
