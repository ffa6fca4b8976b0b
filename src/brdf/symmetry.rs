//! Whether a BRDF is built isotropic (reduced to `phi_o - phi_i`) or keeps the incident
//! azimuth: what the run measured and what the sample is decide, and averaging over
//! azimuth a sample that is not rotation-symmetric happens only when asked.

use super::{BrdfError, BucketData, Kind};
use crate::accumulate::file::Settings;

/// Whether to build isotropic, from the user's choice `asked` (`Some(true)`:
/// `--isotropic`, `Some(false)`: `--anisotropic`, `None`: decide) and the run `s`:
/// anisotropic where it has several incident azimuths; refused where the sample is not
/// rotation-symmetric (`Settings::anisotropy`) and the run has one azimuth, which no
/// representation can turn into the others.
pub fn isotropic(s: &Settings, asked: Option<bool>) -> Result<bool, BrdfError> {
    if let Some(iso) = asked {
        return Ok(iso);
    }
    let azimuths = s.azimuths();
    if azimuths.len() > 1 {
        return Ok(false);
    }
    if let Some(a) = &s.anisotropy {
        return Err(BrdfError::from(format!(
            "sample '{}' is not rotation-symmetric (its facets lean along {} azimuths: harmonic {} of their tilt has strength {:.2}; docs/design.md §4, \"Incident directions\"), so its BRDF depends on the incident azimuth, and this run lit it from one (phi_i {} deg). Simulate it at the azimuths it will be seen from, e.g. `--phi-i 0,45,90,135,180,225,270,315`, and build that; or pass --isotropic to average it over azimuth as a rotation-symmetric sample (what build did before), or --anisotropic to keep the one azimuth's absolute directions",
            s.sample_name,
            a.harmonic,
            a.harmonic,
            a.strength,
            azimuths.first().copied().unwrap_or(s.phi_i_deg)
        )));
    }
    Ok(true)
}

/// Refuses a representation that holds one incident azimuth (the table and the
/// subdivided hemisphere store `phi_o - phi_i`) for data of several.
pub fn check_azimuths(kind: Kind, data: &BucketData) -> Result<(), BrdfError> {
    let n = azimuth_count(data);
    if n > 1 && matches!(kind, Kind::Table | Kind::Subdivided) {
        return Err(BrdfError::from(format!(
            "the {} representation holds one incident azimuth (it stores phi_o - phi_i), and these buckets have {n}: build --repr kdtree keeps them",
            kind.name()
        )));
    }
    Ok(())
}

/// The distinct incident azimuths of `data`'s directions.
pub fn azimuth_count(data: &BucketData) -> usize {
    let mut seen: Vec<f64> = Vec::new();
    for p in data
        .samples
        .iter()
        .filter_map(|d| d.first())
        .map(|b| b.phi_i_rad)
    {
        if !seen.iter().any(|q| (q - p).abs() < 1e-12) {
            seen.push(p);
        }
    }
    seen.len()
}
