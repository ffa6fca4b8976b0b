//! Taking a simulated material into other tools: the RGL tensor format (`.bsdf`) read by
//! Mitsuba 3 and pbrt-v4 ([`rgl`], [`tensor`]), NumPy arrays ([`npz`]), and the MERL format
//! of fitting tools ([`merl`], sRGB only).

pub mod merl;
pub mod npz;
pub mod rgl;
pub mod tensor;

use crate::brdf::{Brdf, Representation};

/// The incident elevations a representation was simulated at, radians, ascending: the
/// table's and the subdivided hemisphere's own, or the simulation settings' for a kd-tree.
pub fn simulated_incidence(r: &Representation) -> Result<Vec<f64>, String> {
    match r {
        Representation::Table(t) => Ok(t.theta_i.clone()),
        Representation::Subdivided(s) => Ok(s.theta_i.clone()),
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
                        .ok_or_else(|| "theta_i_deg holds a non-number".to_string())
                })
                .collect()
        }
    }
}
