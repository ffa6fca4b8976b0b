//! Taking a simulated material into other tools: the RGL tensor format (`.bsdf`) read by
//! Mitsuba 3 and pbrt-v4 ([`rgl`], [`tensor`]) with a scene for each that shows it as
//! `goniospec render` does ([`scene`]), NumPy arrays ([`npz`]), the MERL format of
//! fitting tools ([`merl`], sRGB only), and Mitsuba 3's polarised measured format
//! ([`pbsdf`], from a `--mueller` accumulator); and the other way in, measured materials
//! of the RGL database read as its loader reads them ([`measured`], over the reader's
//! interpolants, [`marginal`]).

pub mod marginal;
pub mod measured;
pub mod merl;
pub mod mirror;
pub mod npz;
pub mod pbsdf;
pub mod rgl;
pub mod scene;
pub mod tensor;
mod warp;

use crate::brdf::{Brdf, Representation};

/// What an export refuses: a representation it cannot tabulate, a resolution out of range, a tensor file that is not one.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ExportError {
    /// The message says what and where.
    #[error("{0}")]
    Invalid(String),
}

message_error!(ExportError, ExportError::Invalid);

/// The incident elevations a representation was simulated at, radians, ascending: the
/// table's and the subdivided hemisphere's own, or the simulation settings' for a kd-tree.
pub fn simulated_incidence(r: &Representation) -> Result<Vec<f64>, ExportError> {
    match r {
        Representation::Table(t) => Ok(t.theta_i_rad.clone()),
        Representation::Subdivided(s) => Ok(s.theta_i_rad.clone()),
        Representation::KdTree(_) => {
            let settings: toml::Table = toml::from_str(&r.meta().simulation)
                .map_err(|e| format!("the BRDF's simulation settings do not parse: {e}"))?;
            let list = settings
                .get("theta_i_deg")
                .and_then(|v| v.as_array())
                .ok_or("the BRDF's simulation settings hold no theta_i_deg")?;
            // Each angle once, ascending (a run over several azimuths repeats them).
            let mut out = list
                .iter()
                .map(|v| {
                    v.as_float()
                        .or_else(|| v.as_integer().map(|i| i as f64))
                        .map(f64::to_radians)
                        .ok_or_else(|| ExportError::from("theta_i_deg holds a non-number"))
                })
                .collect::<Result<Vec<f64>, ExportError>>()?;
            out.sort_by(f64::total_cmp);
            out.dedup();
            Ok(out)
        }
    }
}

/// The spacing of the incident angles an RGL file is tabulated at by default, degrees.
pub const RGL_THETA_I_STEP_DEG: f64 = 5.0;

/// The incident angles (radians, ascending) an RGL file holds by default: the simulated
/// ones, and between them every [`RGL_THETA_I_STEP_DEG`]. The reader interpolates its
/// stored quantity, `f cos(theta_o) 4 sigma(wi) / D(m)` at a position of the warped grid,
/// linearly in `theta_i` and divides by `sigma` at the incident angle asked (module
/// [`rgl`]); goniospec's table interpolates `f` itself at a fixed outgoing direction. Where
/// the nodes lie 40 degrees apart the two interpolants part: the shipped car paint simulated
/// at 0, 40 and 80 degrees rendered 14.6 % brighter in Mitsuba 3 than in `goniospec
/// render`, rough gold 7.8 % (issue 71). At nodes 5 degrees apart, each the table's own
/// value, the reader follows the table between them (5.2 % and 0.3 %; README, "A scene
/// that matches goniospec render").
pub fn rgl_incidence(simulated: &[f64]) -> Vec<f64> {
    let step = RGL_THETA_I_STEP_DEG.to_radians();
    let mut out: Vec<f64> = simulated.to_vec();
    for w in simulated.windows(2) {
        let gaps = ((w[1] - w[0]) / step - 1e-9).ceil().max(1.0) as usize;
        out.extend((1..gaps).map(|k| w[0] + (w[1] - w[0]) * k as f64 / gaps as f64));
    }
    out.sort_by(f64::total_cmp);
    out.dedup();
    out
}

/// The RGL `.bsdf` fields of `r`, simulated from `sample` (its facets give `D(m)`): at
/// `theta_i` (radians; default [`rgl_incidence`] of the simulated angles), on a `resolution`-node warped grid.
/// Refuses a sample other than the BRDF's.
pub fn rgl_for(
    r: &Representation,
    sample: &crate::sample::Sample,
    resolution: usize,
    theta_i: Option<Vec<f64>>,
) -> Result<(Vec<tensor::Field>, rgl::RglReport), ExportError> {
    if sample.name != r.meta().sample_name {
        return Err(ExportError::from(format!(
            "the sample is '{}', but the BRDF was simulated from '{}'",
            sample.name,
            r.meta().sample_name
        )));
    }
    // The name is the user's; the geometry and media are the sample's hash (a different
    // surface under the same name was accepted).
    let settings: crate::accumulate::file::Settings = toml::from_str(&r.meta().simulation)
        .map_err(|e| format!("the BRDF's simulation settings are unreadable: {e}"))?;
    let hash = crate::simulate::sample_hash(sample);
    if settings.sample_hash != hash {
        return Err(ExportError::from(format!(
            "the sample '{}' is not the one the BRDF was simulated from: its geometry or media differ (hash {hash}, the BRDF's {})",
            sample.name, settings.sample_hash
        )));
    }
    let theta_i = match theta_i {
        Some(t) => t,
        None => rgl_incidence(&simulated_incidence(r)?),
    };
    let scene = crate::trace::Scene::new(sample, crate::accel::Backend::default_available())
        .map_err(|e| e.to_string())?;
    let mut d =
        rgl::FacetDistribution::from_sample(sample, scene.ambient, resolution, r.meta().isotropic)?;
    let flat = d.flat_fraction > crate::sample::FLAT_TOP_FRACTION;
    // A flat surface facing the light: a table's mirror is written as a sharp lobe (module
    // [`mirror`]); another representation's, or one the table does not show, at the
    // bucket aperture.
    let sharp = match r {
        Representation::Table(t) if flat => Some(mirror::SharpMirror::from_table(
            t,
            mirror::SharpMirror::width_for(resolution),
        )),
        _ => None,
    };
    match &sharp {
        Some(Ok(m)) => {
            d.add_brdf_lobe(m.background(), r.meta().isotropic);
            d.add_peak(m);
        }
        _ if flat => d.add_brdf_lobe(r, r.meta().isotropic),
        _ => {}
    }
    let opts = rgl::RglOptions {
        resolution,
        prefilter: if d.flat_fraction > crate::sample::FLAT_TOP_FRACTION {
            7
        } else {
            1
        },
        theta_i,
        description: format!(
            "goniospec {} export of '{}' ({} representation, {} wavelengths)",
            env!("CARGO_PKG_VERSION"),
            r.meta().sample_name,
            r.meta().repr,
            r.meta().lambda_nm.len()
        ),
    };
    let (fields, mut report) = match &sharp {
        Some(Ok(m)) => rgl::rgl_fields(m, &d, &opts)?,
        _ => rgl::rgl_fields(r, &d, &opts)?,
    };
    match sharp {
        Some(Ok(m)) => {
            report.mirror_aperture_deg = None;
            report.sharp_mirror_deg = Some(m.width_deg());
            report.mirror_power = m.powers();
        }
        Some(Err(why)) => report.no_sharp_mirror = Some(why.0),
        None if flat => {
            report.no_sharp_mirror = Some(format!(
                "the {} representation does not keep its buckets (build --repr table does)",
                r.meta().repr
            ))
        }
        None => {}
    }
    Ok((fields, report))
}

#[cfg(test)]
mod tests {
    use super::rgl_incidence;

    fn degrees(list: &[f64]) -> Vec<f64> {
        let rad: Vec<f64> = list.iter().map(|d| d.to_radians()).collect();
        rgl_incidence(&rad)
            .iter()
            .map(|r| (r.to_degrees() * 1e9).round() / 1e9)
            .collect()
    }

    #[test]
    fn rgl_angles_are_the_simulated_ones_and_every_5_deg_between() {
        let every5: Vec<f64> = (0..=16).map(|k| 5.0 * k as f64).collect();
        assert_eq!(degrees(&[0.0, 40.0, 80.0]), every5);
        assert_eq!(degrees(&[0.0, 10.0, 80.0]), every5);
        // A gap that 5 deg does not divide is cut into equal parts no wider than 5 deg.
        assert_eq!(degrees(&[30.0, 42.0]), vec![30.0, 34.0, 38.0, 42.0]);
        assert_eq!(degrees(&[0.0, 3.0]), vec![0.0, 3.0]);
        assert_eq!(degrees(&[45.0]), vec![45.0]);
    }
}
