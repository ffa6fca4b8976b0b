//! `goniospec study`: sweeps rays, bucket resolution, estimator, beamlet radius, backend
//! and representation for one sample, and measures each point's wall time, rays, peak
//! memory, error against the best available reference (the analytic TMM for `[stack]`
//! samples, else a high-budget run) and BRDF query time. Writes a CSV and a `report.md`.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::accel::Backend;
use crate::accumulate::file::Accumulator;
use crate::accumulate::{Coherence, PhasePrecision};
use crate::brdf::{Brdf, BucketData, Representation};
use crate::optics::tmm;
use crate::sample::{self, MeshOptions, Sample};
use crate::simulate::{SimConfig, Wavelengths, simulate};
use crate::trace::TraceLimits;

mod charts;
mod file;
pub mod hiding;
mod report;
mod run;

pub use charts::charts;

/// Every file a study may write into its folder (`write`, `charts`, `write_area`), for the
/// output policy's check before the run (`output::guard_folder`).
pub fn output_names() -> Vec<String> {
    let mut v = vec!["points.csv".to_string(), "report.md".to_string()];
    for stem in charts::STEMS.iter().chain([&"reflectance-vs-area"]) {
        v.push(format!("{stem}.png"));
        v.push(format!("{stem}.svg"));
    }
    v
}
use charts::*;
pub use file::{AreaSweep, Tiling, parse};
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
    /// A high-budget run of the diffraction method (`--coherence diffraction`) with the
    /// default settings: its R is the rays', its angular distribution physical optics', so
    /// a study with the method as an axis charts both methods' distributions against it.
    Diffraction,
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
    /// Mean over incident angles and bins of the L1 distance between the point's reflected
    /// distribution over the buckets and the reference's (each normalised to 1; 0
    /// identical, 2 disjoint), from its last repetition; `None` where the reference has no
    /// distribution (TMM, local film) or the point's buckets differ from the reference's.
    pub distribution_l1: Option<f64>,
    /// Why a repetition's result was physically impossible (`simulate::check_physical`):
    /// such a point never holds, whatever its error.
    pub unphysical: Option<String>,
}

/// Reads and validates a study file; errors name the file and line.
pub fn load(path: &Path) -> Result<Study, StudyError> {
    let text = crate::io::read_text(path)
        .map_err(|e| format!("{}: cannot read file: {e}", path.display()))?;
    parse(path, &text)
}
