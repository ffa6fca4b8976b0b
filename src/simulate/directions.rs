//! Incident directions: the polar angles and azimuths a run is lit from.
//!
//! `--theta-i` lists polar angles and `--phi-i` azimuths (degrees); a run's directions are
//! every pair, azimuth-major: all the polar angles at the first azimuth, then all at the
//! next. A run at one azimuth keeps the layout (and the bytes) it had before azimuth lists:
//! `SimConfig::phi_i_deg` holds the azimuth and `phi_each_deg` is empty. With several,
//! `theta_i_deg` repeats the polar angles once per azimuth and `phi_each_deg` gives each
//! direction's azimuth (the `.gsa` records both the same way: `accumulate::Settings`).
//!
//! Anisotropic samples (gratings, brushed metals, aligned flakes) reflect differently at
//! different azimuths; a run over several azimuths is what `build --anisotropic` and the
//! RGL export's `phi_i` grid need (docs/design.md §4, "Incident directions").

use serde::{Deserialize, Deserializer, Serialize, Serializer};

use super::{SimConfig, SimError};

impl SimConfig {
    /// Direction `di`'s azimuth, degrees.
    pub fn phi_of(&self, di: usize) -> f64 {
        self.phi_each_deg.get(di).copied().unwrap_or(self.phi_i_deg)
    }

    /// Lights the run from every pair of `theta_deg` and `phi_deg` (azimuth-major; one
    /// azimuth keeps the single-azimuth layout).
    pub fn with_directions(mut self, theta_deg: &[f64], phi_deg: &[f64]) -> SimConfig {
        let (theta, phi, each) = expand(theta_deg, phi_deg);
        self.theta_i_deg = theta;
        self.phi_i_deg = phi;
        self.phi_each_deg = each;
        self
    }
}

/// The directions of every pair of `theta_deg` and `phi_deg`, azimuth-major: the polar
/// angle of each, the first azimuth, and each direction's azimuth (empty for one azimuth).
pub fn expand(theta_deg: &[f64], phi_deg: &[f64]) -> (Vec<f64>, f64, Vec<f64>) {
    match phi_deg {
        [] => (theta_deg.to_vec(), 0.0, Vec::new()),
        [p] => (theta_deg.to_vec(), *p, Vec::new()),
        _ => {
            let theta = phi_deg
                .iter()
                .flat_map(|_| theta_deg.iter().copied())
                .collect();
            let each = phi_deg
                .iter()
                .flat_map(|&p| theta_deg.iter().map(move |_| p))
                .collect();
            (theta, phi_deg[0], each)
        }
    }
}

/// Refuses azimuths no run can take: not finite, repeated (the same direction twice), or
/// a per-direction list that does not match the polar angles.
pub(super) fn validate_azimuths(cfg: &SimConfig) -> Result<(), SimError> {
    let bad = |message: String| {
        Err(SimError::Setting {
            key: "phi_i",
            message,
        })
    };
    if let Some(p) = std::iter::once(&cfg.phi_i_deg)
        .chain(&cfg.phi_each_deg)
        .find(|p| !p.is_finite())
    {
        return bad(format!("must be finite, got {p}"));
    }
    if cfg.phi_each_deg.is_empty() {
        return Ok(());
    }
    if cfg.phi_each_deg.len() != cfg.theta_i_deg.len() {
        return bad(format!(
            "{} azimuths for {} incident directions (one each)",
            cfg.phi_each_deg.len(),
            cfg.theta_i_deg.len()
        ));
    }
    // Sorted, a repeated direction sits beside its twin: n log n for any list a user
    // types (a pairwise search took minutes on millions of directions).
    let mut pairs: Vec<(f64, f64, f64)> = cfg
        .theta_i_deg
        .iter()
        .zip(&cfg.phi_each_deg)
        .map(|(&t, &p)| (t, p.rem_euclid(360.0), p))
        .collect();
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    if let Some(w) = pairs
        .windows(2)
        .find(|w| w[0].0 == w[1].0 && w[0].1 == w[1].1)
    {
        return bad(format!(
            "the direction theta_i {} deg, phi_i {} deg is listed twice (azimuths are taken modulo 360 deg)",
            w[1].0, w[1].2
        ));
    }
    Ok(())
}

/// Serde for `phi_i`: one number (as every file before azimuth lists wrote it, and as one
/// azimuth is still written) or a list of numbers.
pub mod one_or_many {
    use super::*;

    #[derive(Deserialize)]
    #[serde(untagged)]
    enum OneOrMany {
        One(f64),
        Many(Vec<f64>),
    }

    pub fn serialize<S: Serializer>(v: &[f64], s: S) -> Result<S::Ok, S::Error> {
        match v {
            [one] => one.serialize(s),
            _ => v.serialize(s),
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<f64>, D::Error> {
        Ok(match OneOrMany::deserialize(d)? {
            OneOrMany::One(v) => vec![v],
            OneOrMany::Many(v) => v,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_azimuth_keeps_the_single_layout() {
        let (t, p, each) = expand(&[0.0, 30.0], &[45.0]);
        assert_eq!((t, p, each), (vec![0.0, 30.0], 45.0, vec![]));
    }

    #[test]
    fn several_azimuths_are_azimuth_major() {
        let (t, p, each) = expand(&[0.0, 30.0, 60.0], &[0.0, 90.0]);
        assert_eq!(t, [0.0, 30.0, 60.0, 0.0, 30.0, 60.0]);
        assert_eq!(p, 0.0);
        assert_eq!(each, [0.0, 0.0, 0.0, 90.0, 90.0, 90.0]);
    }

    #[test]
    fn phi_i_reads_a_number_or_a_list() {
        #[derive(Deserialize, Serialize)]
        struct T {
            #[serde(with = "one_or_many")]
            phi_i: Vec<f64>,
        }
        let one: T = toml::from_str("phi_i = 12.5").unwrap();
        assert_eq!(one.phi_i, [12.5]);
        assert_eq!(toml::to_string(&one).unwrap().trim(), "phi_i = 12.5");
        let many: T = toml::from_str("phi_i = [0.0, 45.0]").unwrap();
        assert_eq!(many.phi_i, [0.0, 45.0]);
        assert!(toml::from_str::<T>("phi_i = \"north\"").is_err());
    }

    #[test]
    fn repeated_directions_are_refused() {
        let cfg = crate::simulate::SimConfig::new(
            vec![],
            crate::spectrum::Wavelengths::Monochromatic(vec![500.0]),
            16,
        )
        .with_directions(&[10.0, 20.0], &[0.0, 360.0]);
        let e = validate_azimuths(&cfg).unwrap_err().to_string();
        assert!(e.contains("listed twice"), "{e}");
        let ok = crate::simulate::SimConfig::new(
            vec![],
            crate::spectrum::Wavelengths::Monochromatic(vec![500.0]),
            16,
        )
        .with_directions(&[10.0, 20.0], &[0.0, 90.0]);
        assert!(validate_azimuths(&ok).is_ok());
    }
}
