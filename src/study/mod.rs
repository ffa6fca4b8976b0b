//! `goniospec study`: sweeps rays, bucket resolution, estimator, beamlet radius, backend
//! and representation for one sample, and measures each point's wall time, rays, peak
//! memory, error against the best available reference (the analytic TMM for `[stack]`
//! samples, else a high-budget run) and BRDF query time. Writes a CSV and a `report.md`.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Deserialize;

use crate::accel::Backend;
use crate::accumulate::file::Accumulator;
use crate::accumulate::{Coherence, PhasePrecision};
use crate::brdf::{Brdf, BucketData, Representation};
use crate::optics::tmm;
use crate::sample::{self, MeshOptions, Sample};
use crate::simulate::{SimConfig, Wavelengths, simulate};
use crate::trace::TraceLimits;

mod charts;
mod report;
mod run;

pub use charts::charts;
use charts::*;
use report::*;

/// What stops a study: a study file that does not parse or validate (named with its line), a sample or reference that cannot be computed, charts or CSV that cannot be written.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StudyError {
    /// The message says what and where.
    #[error("{0}")]
    Invalid(String),
}

message_error!(StudyError, StudyError::Invalid);

impl From<crate::plot::PlotError> for StudyError {
    fn from(e: crate::plot::PlotError) -> Self {
        StudyError::Invalid(e.to_string())
    }
}

impl From<crate::reference::ReferenceError> for StudyError {
    fn from(e: crate::reference::ReferenceError) -> Self {
        StudyError::Invalid(e.to_string())
    }
}

pub use report::{write, write_area};
pub use run::{AreaPoint, convergence_slope, holds, run, run_area};

#[derive(Deserialize, Debug, Clone)]
#[serde(deny_unknown_fields)]
struct StudyFile {
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
    /// "run" (a high-budget beamlet run).
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
    vec!["beamlet".into()]
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

/// A parsed, validated study.
#[derive(Debug, Clone)]
pub struct Study {
    pub name: String,
    pub sample_path: PathBuf,
    pub theta_i: Vec<f64>,
    pub edges: Vec<f64>,
    pub reference_rays: u64,
    pub seed: u64,
    pub random_entry: bool,
    pub repeats: u64,
    pub reference: ReferenceKind,
    pub tolerance: f64,
    pub notes: String,
    pub rays: Vec<u64>,
    /// Every combination of the swept settings other than rays and representation.
    pub variants: Vec<Variant>,
    pub representation: Vec<crate::brdf::Kind>,
    pub area: Option<AreaSweep>,
}

/// What the errors are measured against.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReferenceKind {
    /// The analytic TMM for `[stack]` samples, else a high-budget run.
    Auto,
    /// [`crate::reference::local_film`].
    LocalFilm,
    /// A high-budget beamlet run with the default settings.
    Run,
}

/// One setting of everything a study sweeps except rays and representation (a line in
/// the charts).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Variant {
    pub backend: Backend,
    pub coherence: Coherence,
    /// Beamlet radius, nm.
    pub radius: f64,
    pub theta_o_bins: u32,
    pub cutoff: f64,
    pub max_depth: u32,
    pub precision: PhasePrecision,
    /// Offset of the sample's frame along x and y, nm.
    pub origin_nm: f64,
}

/// One measured point.
#[derive(Clone, Debug)]
pub struct Point {
    pub variant: Variant,
    pub rays: u64,
    pub representation: crate::brdf::Kind,
    pub wall_s: f64,
    pub traced_rays: u64,
    pub peak_mem_mb: f64,
    /// RMS over incident angles and bins of `R - R_reference`.
    pub error: f64,
    /// RMS of the point's own standard errors of R (its error bars; NaN-free: 0 when
    /// undefined).
    pub stderr: f64,
    /// Mean power dropped by the cutoff and limits per tree (fraction of launched power).
    pub dropped: f64,
    pub query_ns: f64,
    /// RMS over incident angles and bins of the representation's hemispherical integral
    /// `integral f cos(theta_o) dw_o` against the reference reflectance.
    pub repr_error: f64,
    /// Why a repetition's result was physically impossible (`simulate::check_physical`):
    /// such a point never holds, whatever its error.
    pub unphysical: Option<String>,
}

/// Most repetitions of the sample per side in an area sweep (each tiling copies the
/// sample's meshes k_x k_y times).
const MAX_TILES_PER_SIDE: usize = 64;

/// Reads and validates a study file; errors name the file and line.
pub fn load(path: &Path) -> Result<Study, StudyError> {
    let text = crate::io::read_text(path)
        .map_err(|e| format!("{}: cannot read file: {e}", path.display()))?;
    parse(path, &text)
}

/// Parses and validates the text of a study file read from `path` (named in errors;
/// samples are resolved beside it).
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
    let bad = |m: String| Err(StudyError::from(format!("{}: {m}", path.display())));
    let sw = &raw.sweep;
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
            return bad(format!("[sweep] {name} is empty: give at least one value"));
        }
    }
    if raw.study.theta_i.is_empty() {
        return bad("[study] theta_i is empty".into());
    }
    if sw.rays.contains(&0) {
        return bad("[sweep] rays must be positive".into());
    }
    if let Some(c) = sw
        .cutoff
        .iter()
        .find(|c| !(c.is_finite() && **c >= 0.0 && **c < 1.0))
    {
        return bad(format!("[sweep] cutoff {c} must lie in [0, 1)"));
    }
    if sw.max_depth.contains(&0) {
        return bad("[sweep] max_depth must be positive".into());
    }
    if let Some(r) = sw
        .coherence_radius_nm
        .iter()
        .find(|r| r.is_nan() || **r <= 0.0)
    {
        return bad(format!(
            "[sweep] coherence_radius_nm {r} must be positive (or inf)"
        ));
    }
    if let Some(o) = sw.origin_nm.iter().find(|o| !o.is_finite()) {
        return bad(format!("[sweep] origin_nm {o} must be finite"));
    }
    if sw.theta_o_bins.contains(&0) {
        return bad("[sweep] theta_o_bins must be positive".into());
    }
    let precision = sw
        .phase
        .iter()
        .map(|p| {
            PhasePrecision::parse(p).ok_or_else(|| {
                format!(
                    "{}: unknown phase precision '{p}' (f64 or f32)",
                    path.display()
                )
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    let reference = match raw.study.reference.as_str() {
        "auto" => ReferenceKind::Auto,
        "local-film" => ReferenceKind::LocalFilm,
        "run" => ReferenceKind::Run,
        other => {
            return bad(format!(
                "reference '{other}' must be \"auto\", \"local-film\" or \"run\""
            ));
        }
    };
    if !(raw.study.tolerance >= 0.0 && raw.study.tolerance.is_finite()) {
        return bad(format!(
            "[study] tolerance {} must be a non-negative number",
            raw.study.tolerance
        ));
    }
    if let Some(t) = raw.study.theta_i.iter().find(|t| !(0.0..90.0).contains(*t)) {
        return bad(format!("[study] theta_i {t} must lie in [0, 90) degrees"));
    }
    let coherence = sw
        .coherence
        .iter()
        .map(|c| {
            Coherence::parse(c).ok_or_else(|| {
                format!(
                    "{}: unknown coherence '{c}' (beamlet, bucket or global)",
                    path.display()
                )
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    let backend = sw
        .backend
        .iter()
        .map(|b| {
            b.parse::<Backend>()
                .map_err(|e| format!("{}: {e}", path.display()))
        })
        .collect::<Result<Vec<_>, _>>()?;
    if let Some(b) = backend.iter().find(|b| !b.is_available()) {
        return bad(format!("backend {b} is not available in this build"));
    }
    let representation = sw
        .representation
        .iter()
        .map(|r| crate::brdf::Kind::parse(r))
        .collect::<Result<Vec<_>, _>>();
    let representation = match representation {
        Ok(r) => r,
        Err(m) => return bad(m.to_string()),
    };
    // The same A:B:STEP rules and limits as `--wavelengths` (finite, at most
    // MAX_WAVELENGTHS bins).
    let w = &raw.study.wavelengths;
    if !w.contains(':') {
        return bad(format!("wavelengths '{w}' must be A:B:STEP"));
    }
    let edges = match Wavelengths::parse(w, false) {
        Ok(Wavelengths::Bins(e)) => e,
        Ok(Wavelengths::Monochromatic(_)) => unreachable!("bins requested"),
        Err(e) => {
            return bad(format!("[study] wavelengths: {e}"));
        }
    };
    let random_entry = match raw.study.sampling.as_str() {
        "r2" => false,
        "random" => true,
        other => return bad(format!("sampling '{other}' must be \"r2\" or \"random\"")),
    };
    let mut variants = Vec::new();
    for &backend in &backend {
        for &coherence in &coherence {
            // The coherence radius enters the beamlet estimator and the diffraction method.
            let radii = if matches!(coherence, Coherence::Beamlet | Coherence::Diffraction) {
                &sw.coherence_radius_nm[..]
            } else {
                &sw.coherence_radius_nm[..1]
            };
            for &radius in radii {
                for &theta_o_bins in &sw.theta_o_bins {
                    for &cutoff in &sw.cutoff {
                        for &max_depth in &sw.max_depth {
                            for &precision in &precision {
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
    Ok(Study {
        name: raw.study.name,
        sample_path: path
            .parent()
            .unwrap_or(Path::new(""))
            .join(&raw.study.sample),
        theta_i: raw.study.theta_i,
        edges,
        reference_rays: raw.study.reference_rays,
        seed: raw.study.seed,
        random_entry,
        repeats: raw.study.repeats.max(1),
        reference,
        tolerance: raw.study.tolerance,
        notes: raw.study.notes,
        rays: sw.rays.clone(),
        variants,
        representation,
        area: match raw.area {
            Some(a)
                if a.tiles.is_empty()
                    || a.tiles
                        .iter()
                        .any(|t| t.counts().iter().any(|&k| k == 0 || k > MAX_TILES_PER_SIDE)) =>
            {
                return bad(format!(
                    "[area] tiles must be a non-empty list of counts from 1 to {MAX_TILES_PER_SIDE} per side"
                ));
            }
            Some(a) if a.coherence.iter().any(|c| Coherence::parse(c).is_none()) => {
                return bad("[area] coherence must name beamlet, bucket or global".into());
            }
            other => other,
        },
    })
}
