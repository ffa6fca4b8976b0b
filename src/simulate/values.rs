//! The values a setting takes from text (flags, TOML keys, Python keywords): each parser
//! refuses what no run can take with a message that says why ([`BadValue`]), and the
//! worker pool a run's thread count gives.

use serde::Deserialize;

use super::SimError;
use crate::accel::Backend;
use crate::accumulate::Coherence;

/// Every front end's defaults for a simulation, in one place (read by [`SimSettings`]'s
/// `Default` and its flags). The limits of a tree are `TraceLimits::default()`.
pub mod defaults {
    /// Incident polar angles, degrees.
    pub const THETA_I_DEG: [f64; 6] = [0.0, 15.0, 30.0, 45.0, 60.0, 75.0];
    /// Trees per incident direction.
    pub const RAYS: u64 = 4096;
    /// The most trees per direction of an adaptive run (`--tolerance`).
    pub const MAX_RAYS: u64 = 1_000_000;
    /// Beamlet radius: the illumination's transverse coherence length, nm.
    pub const COHERENCE_RADIUS_NM: f64 = crate::sample::validity::DEFAULT_COHERENCE_RADIUS_NM;
    /// Outgoing buckets per hemisphere, in theta and in phi.
    pub const THETA_O_BINS: u32 = 45;
    pub const PHI_O_BINS: u32 = 36;
    /// Random seed.
    pub const SEED: u64 = 1;
    /// The most worker threads a run may ask for (each holds its own scratch buffers).
    pub const MAX_THREADS: usize = 1024;
}

/// A value a setting cannot take (the setting's parser says why).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct BadValue(pub String);

/// A finite number: every floating-point setting goes through this, so NaN and infinity
/// are refused before any work starts (the CLI names the flag: clap's usage error, exit 2).
pub fn finite(s: &str) -> Result<f64, BadValue> {
    let v: f64 = s
        .trim()
        .parse()
        .map_err(|_| BadValue(format!("'{s}' is not a number")))?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(BadValue(format!("{s} is not a finite number")))
    }
}

/// A coherence radius, nm: positive, or `inf` for the plane-wave limit.
pub fn radius(s: &str) -> Result<f64, BadValue> {
    if s.trim().eq_ignore_ascii_case("inf") {
        return Ok(f64::INFINITY);
    }
    match s.trim().parse::<f64>() {
        Ok(v) if v > 0.0 && v.is_finite() => Ok(v),
        _ => Err(BadValue(format!(
            "'{s}' is not a positive radius in nm (or inf)"
        ))),
    }
}

/// A coherence mode by name.
pub fn coherence(s: &str) -> Result<Coherence, BadValue> {
    Coherence::parse(s).ok_or_else(|| {
        BadValue(format!(
            "unknown coherence '{s}' (auto, beamlet, diffraction, rigorous, bucket or global)"
        ))
    })
}

/// An accelerator by name.
pub fn backend(s: &str) -> Result<Backend, BadValue> {
    s.parse::<Backend>().map_err(|e| BadValue(e.to_string()))
}

/// A worker pool of `threads` threads (0: every core), at most [`defaults::MAX_THREADS`].
/// Results never depend on it.
pub fn thread_pool(threads: usize) -> Result<rayon::ThreadPool, SimError> {
    if threads > defaults::MAX_THREADS {
        return Err(SimError::Setting {
            key: "threads",
            message: format!(
                "{threads} is more than {}; 0 uses every core",
                defaults::MAX_THREADS
            ),
        });
    }
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| SimError::Config(format!("threads: {e}")))
}

/// A coherence mode by name, refused with [`coherence`]'s words.
pub(super) fn coherence_name<'de, D: serde::Deserializer<'de>>(
    d: D,
) -> Result<Coherence, D::Error> {
    coherence(&String::deserialize(d)?).map_err(serde::de::Error::custom)
}

/// Serde of an optional backend by name (`"embree"`, `"obvhs"`; absent: the default).
pub(super) mod backend_name {
    use crate::accel::Backend;
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(b: &Option<Backend>, s: S) -> Result<S::Ok, S::Error> {
        match b {
            Some(b) => s.serialize_str(b.name()),
            None => s.serialize_none(),
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Backend>, D::Error> {
        let name: Option<String> = Option::deserialize(d)?;
        name.map(|n| n.parse().map_err(serde::de::Error::custom))
            .transpose()
    }
}
