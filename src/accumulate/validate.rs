//! What a `.gsa` header must hold for a reader to rely on it ([`Header::validate`]).

use super::Coherence;
use super::file::{Header, InvalidHeader};
use crate::spectrum::Wavelengths;

impl Header {
    /// Checks every value a reader relies on (angles, wavelengths, modes, grid sizes, ray
    /// counts); the message names the field.
    pub fn validate(&self) -> Result<(), InvalidHeader> {
        let s = &self.settings;
        if s.theta_i_deg.is_empty() || s.theta_i_deg.iter().any(|t| !(0.0..90.0).contains(t)) {
            return Err(InvalidHeader::from(format!(
                "theta_i_deg must be angles in [0, 90), got {:?}",
                s.theta_i_deg
            )));
        }
        if !s.phi_i_deg.is_finite() || s.phi_i_each_deg.iter().any(|p| !p.is_finite()) {
            return Err(InvalidHeader::from(format!(
                "phi_i_deg must be finite, got {} {:?}",
                s.phi_i_deg, s.phi_i_each_deg
            )));
        }
        if !s.phi_i_each_deg.is_empty() && s.phi_i_each_deg.len() != s.theta_i_deg.len() {
            return Err(InvalidHeader::from(format!(
                "phi_i_each_deg has {} azimuths for {} directions",
                s.phi_i_each_deg.len(),
                s.theta_i_deg.len()
            )));
        }
        let w = &s.wavelengths_nm;
        if s.wavelength_count() == 0 || w.len() > 100_001 {
            return Err(InvalidHeader::from(format!(
                "{} wavelengths: none, or absurdly many",
                w.len()
            )));
        }
        Wavelengths::from_parts(s.wavelength_mode, w.clone())
            .map_err(|e| InvalidHeader::from(format!("wavelengths_nm: {e}")))?;
        if s.coherence_radius_nm.is_nan() || s.coherence_radius_nm <= 0.0 {
            return Err(InvalidHeader::from(format!(
                "coherence_radius_nm must be positive (or inf), got {}",
                s.coherence_radius_nm
            )));
        }
        if !(s.cutoff >= 0.0 && s.cutoff < 1.0) {
            return Err(InvalidHeader::from(format!(
                "cutoff must be in [0, 1), got {}",
                s.cutoff
            )));
        }
        let buckets = u64::from(s.theta_o_bins).checked_mul(u64::from(s.phi_o_bins));
        if s.theta_o_bins == 0 || s.phi_o_bins == 0 || buckets.is_none_or(|b| b > 1 << 22) {
            return Err(InvalidHeader::from(format!(
                "bucket grid {} x {} is empty or too large",
                s.theta_o_bins, s.phi_o_bins
            )));
        }
        if self.rays == 0 || self.seeds.is_empty() || self.rays_asked == Some(0) {
            return Err("no rays or no seeds recorded".into());
        }
        let nl = s.wavelength_count();
        let methods_ok = if s.coherence == Coherence::Auto {
            s.methods.len() == s.theta_i_deg.len()
                && s.methods
                    .iter()
                    .all(|m| m.len() == nl && m.bytes().all(|b| matches!(b, b'r' | b'd' | b'm')))
        } else {
            s.methods.is_empty()
        };
        if !methods_ok {
            return Err(InvalidHeader::from(format!(
                "methods must be, for coherence = \"auto\" only, one string per incident direction ({}) of one letter per wavelength cell ({nl}), r, d or m; got {} strings for coherence = \"{}\"",
                s.theta_i_deg.len(),
                s.methods.len(),
                s.coherence
            )));
        }
        if self.rays_per_direction.len() != s.theta_i_deg.len()
            || self.rays_per_direction.contains(&0)
            || self.rays_per_direction.iter().max() != Some(&self.rays)
        {
            return Err(InvalidHeader::from(format!(
                "rays_per_direction {:?} does not match {} directions and rays = {}",
                self.rays_per_direction,
                s.theta_i_deg.len(),
                self.rays
            )));
        }
        // One group has no spread to estimate a variance from (its N - 1 is 0); more groups
        // than trees could fill are not a run's.
        if self.error_groups == 1 || self.error_groups > self.rays {
            return Err(InvalidHeader::from(format!(
                "error_groups must be 0 (none) or from 2 to the rays ({}), got {}",
                self.rays, self.error_groups
            )));
        }
        let goal_ok = |g: Option<f64>| g.is_none_or(|t| t > 0.0 && t < 1.0);
        if !goal_ok(s.tolerance)
            || !goal_ok(s.target_stderr)
            || (s.tolerance.is_some() && s.target_stderr.is_some())
            || (s.tolerance.is_some() || s.target_stderr.is_some()) != s.max_rays.is_some()
        {
            return Err(InvalidHeader::from(format!(
                "an adaptive run needs one of tolerance or target_stderr in (0, 1), and max_rays with it, got {:?}, {:?} and {:?}",
                s.tolerance, s.target_stderr, s.max_rays
            )));
        }
        Ok(())
    }
}
