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
            list.iter()
                .map(|v| {
                    v.as_float()
                        .or_else(|| v.as_integer().map(|i| i as f64))
                        .map(f64::to_radians)
                        .ok_or_else(|| ExportError::from("theta_i_deg holds a non-number"))
                })
                .collect()
        }
    }
}

/// The RGL `.bsdf` fields of `r`, simulated from `sample` (its facets give `D(m)`): at
/// `theta_i` (radians; default the simulated angles), on a `resolution`-node warped grid.
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
        None => simulated_incidence(r)?,
    };
    let scene = crate::trace::Scene::new(sample, crate::accel::Backend::default_available())
        .map_err(|e| e.to_string())?;
    let mut d =
        rgl::FacetDistribution::from_sample(sample, scene.ambient, resolution, r.meta().isotropic)?;
    if d.flat_fraction > 0.99 {
        d.add_brdf_lobe(r, r.meta().isotropic);
    }
    let opts = rgl::RglOptions {
        resolution,
        prefilter: if d.flat_fraction > 0.99 { 3 } else { 1 },
        theta_i,
        description: format!(
            "goniospec {} export of '{}' ({} representation, {} wavelengths)",
            env!("CARGO_PKG_VERSION"),
            r.meta().sample_name,
            r.meta().repr,
            r.meta().lambda_nm.len()
        ),
    };
    rgl::rgl_fields(r, &d, &opts)
}
