//! The study file: its TOML model, and its validation into a [`Study`].

use std::path::Path;

use serde::Deserialize;

use super::{ReferenceKind, Study, StudyError, Variant};
use crate::accel::Backend;
use crate::accumulate::{Coherence, PhasePrecision};
use crate::simulate::Wavelengths;
use crate::trace::TraceLimits;

/// Most repetitions of the sample per side in an area sweep (each tiling copies the
/// sample's meshes k_x k_y times).
const MAX_TILES_PER_SIDE: usize = 64;

#[derive(Deserialize, Debug, Clone)]
#[serde(deny_unknown_fields)]
pub(super) struct StudyFile {
    study: Header,
    sweep: Sweep,
    area: Option<AreaSweep>,
}

/// The seed's experiment: the sample tiled `k x k` with rays in proportion, per estimator.
#[derive(Deserialize, Debug, Clone)]
#[serde(deny_unknown_fields)]
pub struct AreaSweep {
    /// Tilings: `k` (k x k) or `[kx, ky]`.
    pub tiles: Vec<Tiling>,
    /// Rays per direction at one tile (scaled by k^2).
    pub rays: u64,
    #[serde(default = "all_estimators")]
    pub coherence: Vec<String>,
}

/// How often the sample repeats along x and y in the area experiment.
#[derive(Deserialize, Debug, Clone, Copy, PartialEq, Eq)]
#[serde(untagged)]
pub enum Tiling {
    Square(usize),
    Rect([usize; 2]),
}

impl Tiling {
    pub fn counts(self) -> [usize; 2] {
        match self {
            Tiling::Square(k) => [k, k],
            Tiling::Rect(k) => k,
        }
    }
}

fn all_estimators() -> Vec<String> {
    vec!["beamlet".into(), "bucket".into(), "global".into()]
}

#[derive(Deserialize, Debug, Clone)]
#[serde(deny_unknown_fields)]
struct Header {
    name: String,
    /// The sample, relative to the study file.
    sample: String,
    theta_i: Vec<f64>,
    /// Bin edges `A:B:STEP` (nm).
    wavelengths: String,
    #[serde(default = "default_reference_rays")]
    reference_rays: u64,
    #[serde(default = "default_seed")]
    seed: u64,
    /// "r2" (low-discrepancy entry points, the default) or "random" (plain Monte Carlo).
    #[serde(default = "default_sampling")]
    sampling: String,
    /// Independent repetitions (seeds) per point; the error is their RMS.
    #[serde(default = "default_repeats")]
    repeats: u64,
    /// "auto" (the analytic TMM for `[stack]` samples, else a high-budget run),
    /// "local-film" (the tangent-plane film reference of curved and wedged films) or
    /// "run" (a high-budget beamlet run) or "diffraction" (a high-budget run of the
    /// diffraction method, for studies that chart the angular distribution of both methods).
    #[serde(default = "default_reference")]
    reference: String,
    /// The largest error (absolute, in R) at which the report says a method holds
    /// (default 1e-3).
    #[serde(default = "default_tolerance")]
    tolerance: f64,
    /// What the study stresses, printed at the top of the report.
    #[serde(default)]
    notes: String,
}

fn default_tolerance() -> f64 {
    1e-3
}

fn default_reference() -> String {
    "auto".into()
}

fn default_repeats() -> u64 {
    1
}

fn default_sampling() -> String {
    "r2".into()
}

fn default_reference_rays() -> u64 {
    65_536
}
fn default_seed() -> u64 {
    1
}

#[derive(Deserialize, Debug, Clone)]
#[serde(deny_unknown_fields)]
struct Sweep {
    rays: Vec<u64>,
    #[serde(default = "default_theta_bins")]
    theta_o_bins: Vec<u32>,
    #[serde(default = "default_coherence")]
    coherence: Vec<String>,
    #[serde(default = "default_radius")]
    coherence_radius_nm: Vec<f64>,
    #[serde(default = "default_backend")]
    backend: Vec<String>,
    #[serde(default = "default_repr")]
    representation: Vec<String>,
    /// Power cutoff of the ray trees (fraction of launched power).
    #[serde(default = "default_cutoff")]
    cutoff: Vec<f64>,
    /// Depth limit of the ray trees (interactions).
    #[serde(default = "default_max_depth")]
    max_depth: Vec<u32>,
    /// Phase precision: "f64" or "f32".
    #[serde(default = "default_phase")]
    phase: Vec<String>,
    /// Where the sample sits in the world: offset (nm) along x and y of its frame.
    #[serde(default = "default_origin")]
    origin_nm: Vec<f64>,
}

fn default_cutoff() -> Vec<f64> {
    vec![TraceLimits::default().cutoff]
}
fn default_max_depth() -> Vec<u32> {
    vec![TraceLimits::default().max_depth]
}
fn default_phase() -> Vec<String> {
    vec!["f64".into()]
}
fn default_origin() -> Vec<f64> {
    vec![0.0]
}

fn default_theta_bins() -> Vec<u32> {
    vec![45]
}
fn default_coherence() -> Vec<String> {
    vec!["auto".into()]
}
fn default_radius() -> Vec<f64> {
    vec![crate::simulate::defaults::COHERENCE_RADIUS_NM]
}
fn default_backend() -> Vec<String> {
    vec![Backend::default_available().name().into()]
}
fn default_repr() -> Vec<String> {
    vec!["table".into()]
}

/// Parses and validates the text of a study file read from `path` (named in errors;
/// samples are resolved beside it): the TOML, then the sweep's axes, then the study's own
/// settings, then the area sweep.
pub fn parse(path: &Path, text: &str) -> Result<Study, StudyError> {
    let raw: StudyFile = toml::from_str(text).map_err(|e| {
        let line = e.span().map(|s| crate::sample::line_of(text, s.start));
        match line {
            Some(l) => format!(
                "{}:{l}: invalid study: {}",
                path.display(),
                e.message().trim()
            ),
            None => format!("{}: invalid study: {}", path.display(), e.message().trim()),
        }
    })?;
    // The stages' errors say what; the file is named here.
    let named = |e: StudyError| StudyError::from(format!("{}: {e}", path.display()));
    check_sweep(&raw.sweep, &raw.study.theta_i).map_err(named)?;
    let axes = Axes::parse(&raw.sweep).map_err(named)?;
    let settings = Settings::parse(&raw.study).map_err(named)?;
    let area = check_area(raw.area).map_err(named)?;
    let sw = &raw.sweep;
    Ok(Study {
        name: raw.study.name,
        sample_path: path
            .parent()
            .unwrap_or(Path::new(""))
            .join(&raw.study.sample),
        theta_i: raw.study.theta_i,
        edges: settings.edges,
        reference_rays: raw.study.reference_rays,
        seed: raw.study.seed,
        random_entry: settings.random_entry,
        repeats: raw.study.repeats.max(1),
        reference: settings.reference,
        tolerance: raw.study.tolerance,
        notes: raw.study.notes,
        rays: sw.rays.clone(),
        variants: axes.variants(sw),
        representation: axes.representation,
        area,
    })
}

/// The sweep's numeric axes: each non-empty and each value one a run can take.
fn check_sweep(sw: &Sweep, theta_i: &[f64]) -> Result<(), StudyError> {
    for (name, empty) in [
        ("rays", sw.rays.is_empty()),
        ("theta_o_bins", sw.theta_o_bins.is_empty()),
        ("coherence", sw.coherence.is_empty()),
        ("coherence_radius_nm", sw.coherence_radius_nm.is_empty()),
        ("backend", sw.backend.is_empty()),
        ("representation", sw.representation.is_empty()),
        ("cutoff", sw.cutoff.is_empty()),
        ("max_depth", sw.max_depth.is_empty()),
        ("phase", sw.phase.is_empty()),
        ("origin_nm", sw.origin_nm.is_empty()),
    ] {
        if empty {
            return Err(StudyError::from(format!(
                "[sweep] {name} is empty: give at least one value"
            )));
        }
    }
    if theta_i.is_empty() {
        return Err("[study] theta_i is empty".into());
    }
    if sw.rays.contains(&0) {
        return Err("[sweep] rays must be positive".into());
    }
    if let Some(c) = sw
        .cutoff
        .iter()
        .find(|c| !(c.is_finite() && **c >= 0.0 && **c < 1.0))
    {
        return Err(StudyError::from(format!(
            "[sweep] cutoff {c} must lie in [0, 1)"
        )));
    }
    if sw.max_depth.contains(&0) {
        return Err("[sweep] max_depth must be positive".into());
    }
    if let Some(r) = sw
        .coherence_radius_nm
        .iter()
        .find(|r| r.is_nan() || **r <= 0.0)
    {
        return Err(StudyError::from(format!(
            "[sweep] coherence_radius_nm {r} must be positive (or inf)"
        )));
    }
    if let Some(o) = sw.origin_nm.iter().find(|o| !o.is_finite()) {
        return Err(StudyError::from(format!(
            "[sweep] origin_nm {o} must be finite"
        )));
    }
    if sw.theta_o_bins.contains(&0) {
        return Err("[sweep] theta_o_bins must be positive".into());
    }
    Ok(())
}

/// The sweep's named axes, parsed.
struct Axes {
    precision: Vec<PhasePrecision>,
    coherence: Vec<Coherence>,
    backend: Vec<Backend>,
    representation: Vec<crate::brdf::Kind>,
}

impl Axes {
    fn parse(sw: &Sweep) -> Result<Axes, StudyError> {
        let precision = sw
            .phase
            .iter()
            .map(|p| {
                PhasePrecision::parse(p).ok_or_else(|| {
                    StudyError::from(format!("unknown phase precision '{p}' (f64 or f32)"))
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let coherence = sw
            .coherence
            .iter()
            .map(|c| {
                Coherence::parse(c).ok_or_else(|| {
                    StudyError::from(format!(
                        "unknown coherence '{c}' (auto, beamlet, diffraction, bucket or global)"
                    ))
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let backend = sw
            .backend
            .iter()
            .map(|b| {
                b.parse::<Backend>()
                    .map_err(|e| StudyError::from(e.to_string()))
            })
            .collect::<Result<Vec<_>, _>>()?;
        if let Some(b) = backend.iter().find(|b| !b.is_available()) {
            return Err(StudyError::from(format!(
                "backend {b} is not available in this build"
            )));
        }
        let representation = sw
            .representation
            .iter()
            .map(|r| crate::brdf::Kind::parse(r).map_err(|m| StudyError::from(m.to_string())))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Axes {
            precision,
            coherence,
            backend,
            representation,
        })
    }

    /// Every combination of the axes a run differs by (the coherence radius only where
    /// the estimator has one: the beamlet and the diffraction method).
    fn variants(&self, sw: &Sweep) -> Vec<Variant> {
        let mut variants = Vec::new();
        for &backend in &self.backend {
            for &coherence in &self.coherence {
                let radii = if matches!(
                    coherence,
                    Coherence::Auto | Coherence::Beamlet | Coherence::Diffraction
                ) {
                    &sw.coherence_radius_nm[..]
                } else {
                    &sw.coherence_radius_nm[..1]
                };
                for &radius in radii {
                    for &theta_o_bins in &sw.theta_o_bins {
                        for &cutoff in &sw.cutoff {
                            for &max_depth in &sw.max_depth {
                                for &precision in &self.precision {
                                    for &origin_nm in &sw.origin_nm {
                                        variants.push(Variant {
                                            backend,
                                            coherence,
                                            radius,
                                            theta_o_bins,
                                            cutoff,
                                            max_depth,
                                            precision,
                                            origin_nm,
                                        });
                                    }
                                }
                            }
                        }
                    }
                }
            }
        }
        variants
    }
}

/// The study's own settings, parsed.
struct Settings {
    reference: ReferenceKind,
    edges: Vec<f64>,
    random_entry: bool,
}

impl Settings {
    fn parse(h: &Header) -> Result<Settings, StudyError> {
        let reference = match h.reference.as_str() {
            "auto" => ReferenceKind::Auto,
            "local-film" => ReferenceKind::LocalFilm,
            "run" => ReferenceKind::Run,
            "diffraction" => ReferenceKind::Diffraction,
            other => {
                return Err(StudyError::from(format!(
                    "reference '{other}' must be \"auto\", \"local-film\", \"run\" or \"diffraction\""
                )));
            }
        };
        if !(h.tolerance >= 0.0 && h.tolerance.is_finite()) {
            return Err(StudyError::from(format!(
                "[study] tolerance {} must be a non-negative number",
                h.tolerance
            )));
        }
        if let Some(t) = h.theta_i.iter().find(|t| !(0.0..90.0).contains(*t)) {
            return Err(StudyError::from(format!(
                "[study] theta_i {t} must lie in [0, 90) degrees"
            )));
        }
        // The same A:B:STEP rules and limits as `--wavelengths` (finite, at most
        // MAX_WAVELENGTHS bins).
        let w = &h.wavelengths;
        if !w.contains(':') {
            return Err(StudyError::from(format!(
                "wavelengths '{w}' must be A:B:STEP"
            )));
        }
        let edges = match Wavelengths::parse(w, false) {
            Ok(Wavelengths::Bins(e)) => e,
            Ok(Wavelengths::Monochromatic(_)) => unreachable!("bins requested"),
            Err(e) => return Err(StudyError::from(format!("[study] wavelengths: {e}"))),
        };
        let random_entry = match h.sampling.as_str() {
            "r2" => false,
            "random" => true,
            other => {
                return Err(StudyError::from(format!(
                    "sampling '{other}' must be \"r2\" or \"random\""
                )));
            }
        };
        Ok(Settings {
            reference,
            edges,
            random_entry,
        })
    }
}

/// The area sweep, where there is one: tilings of 1 to [`MAX_TILES_PER_SIDE`] per side
/// and estimators by name.
fn check_area(area: Option<AreaSweep>) -> Result<Option<AreaSweep>, StudyError> {
    match area {
        Some(a)
            if a.tiles.is_empty()
                || a.tiles
                    .iter()
                    .any(|t| t.counts().iter().any(|&k| k == 0 || k > MAX_TILES_PER_SIDE)) =>
        {
            Err(StudyError::from(format!(
                "[area] tiles must be a non-empty list of counts from 1 to {MAX_TILES_PER_SIDE} per side"
            )))
        }
        Some(a) if a.coherence.iter().any(|c| Coherence::parse(c).is_none()) => {
            Err("[area] coherence must name beamlet, bucket or global".into())
        }
        other => Ok(other),
    }
}
