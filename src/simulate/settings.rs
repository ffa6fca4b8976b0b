//! The settings of a simulation: every user knob with its default and its validation, in
//! one place ([`SimSettings`]), and the run's configuration they resolve into
//! ([`SimConfig`]).
//!
//! Every front end builds a `SimSettings`: the CLI flattens it into its flags (clap), batch
//! plans and studies deserialise it (TOML keys of the flags' names, `theta_i` rather than
//! `--theta-i`), Python's keywords set its fields, and render's planner starts from its
//! default. [`SimSettings::resolve`] parses and validates it once.

use glam::DVec3;
use serde::{Deserialize, Serialize};

use super::SimError;
use super::values::{backend, backend_name, coherence, coherence_name, defaults, finite, radius};
use crate::accel::Backend;
use crate::accumulate::{Buckets, Coherence, PhasePrecision};
use crate::reference::rigorous::Effort;
use crate::spectrum::Wavelengths;
use crate::trace::TraceLimits;

/// Every user knob of one simulation, with its default (`Default`, from [`defaults`]) and
/// its validation ([`SimSettings::resolve`]). Its fields are the flags of `goniospec
/// simulate`; in TOML and Python their keys are the flags' names with `_` for `-`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, clap::Args)]
#[serde(default, deny_unknown_fields)]
pub struct SimSettings {
    /// Incident polar angles, degrees, comma-separated.
    #[arg(long = "theta-i", value_name = "DEG,...", value_parser = finite, value_delimiter = ',', default_values_t = defaults::THETA_I_DEG)]
    #[serde(rename = "theta_i")]
    pub theta_i_deg: Vec<f64>,
    /// Incident azimuths, degrees, comma-separated: the run is lit from every pair of
    /// polar angle and azimuth (all the polar angles at the first azimuth, then the next).
    /// Several azimuths give an anisotropic sample's (a grating's) whole BRDF.
    #[arg(long = "phi-i", value_name = "DEG,...", value_parser = finite, value_delimiter = ',', default_values_t = [0.0])]
    #[serde(rename = "phi_i", with = "super::directions::one_or_many")]
    pub phi_i_deg: Vec<f64>,
    /// Launched rays (trees) per incident direction; each covers every wavelength.
    #[arg(long, default_value_t = defaults::RAYS)]
    pub rays: u64,
    /// Wavelengths, nm: A:B:STEP gives bins of width STEP from A to B (or, with
    /// --monochromatic, the wavelengths A, A+STEP, ..., B); a comma list gives bin edges
    /// (or exact wavelengths with --monochromatic).
    #[arg(long, default_value = crate::spectrum::DEFAULT_WAVELENGTHS)]
    pub wavelengths: String,
    /// Use the exact wavelengths instead of jittered bins.
    #[arg(long)]
    pub monochromatic: bool,
    /// Accelerator: embree or obvhs (default: embree where available).
    #[arg(long, value_parser = backend)]
    #[serde(with = "backend_name", skip_serializing_if = "Option::is_none")]
    pub backend: Option<Backend>,
    /// Seed of entry points and wavelength jitter.
    #[arg(long, default_value_t = defaults::SEED)]
    pub seed: u64,
    /// How contributions interfere. auto (default): each (incident angle, wavelength)
    /// cell takes the method its scales call for, recorded in the .gsa (goniospec info
    /// lists them): the diffraction method where a coherent specular order or grating
    /// orders matter at the coherence radius and the tangent plane holds
    /// (k r_c cos^3 theta >= 35), the rigorous solver where structure is finer than three
    /// wavelengths or the tangent plane fails and it fits (300 modes per slice), rays
    /// (beamlet) elsewhere; the run says where a cell needed a method and could not have it. beamlet: each tree is
    /// coherent within itself (films, coatings) and incoherent with the others: the ray
    /// method. diffraction: every tree's exits add as fields over the periodic tile
    /// (physical optics on the ray field: grating orders, the coherent specular order of
    /// slightly rough surfaces); trees launch on a lattice, R and T stay the rays', and
    /// the power its transform kept is reported (docs/physics.md, "Diffraction"; where
    /// each holds: docs/validity.md). rigorous: no rays; the Fourier modal method (RCWA)
    /// solves Maxwell's equations on the periodic tile, sliced along z (a smooth 1-D
    /// relief, bare or under flat layers: the C-method, unsliced), for each cell,
    /// checked for convergence against a coarser solution (--orders, --slices,
    /// --rigorous-tolerance; docs/physics.md, "The rigorous solver"); for structure near
    /// or below the wavelength, where rays and the diffraction method do not hold. bucket
    /// and global: the failing comparison modes of the seed.
    #[arg(long, default_value = "auto", value_parser = coherence)]
    #[serde(deserialize_with = "coherence_name")]
    pub coherence: Coherence,
    /// The illumination's transverse coherence radius in nm (the beamlet radius), or inf
    /// for the plane-wave limit. It weights the interference of meshed layers' partial
    /// waves; coatings are exact transfer matrices, fully coherent whatever it is (the run
    /// says so where a meshed layer would differ by more than 1 %).
    #[arg(long, default_value_t = defaults::COHERENCE_RADIUS_NM, value_parser = radius)]
    pub coherence_radius_nm: f64,
    /// Polar bins of the outgoing hemispheres (equal in theta).
    #[arg(long, default_value_t = defaults::THETA_O_BINS)]
    pub theta_o_bins: u32,
    /// Azimuth bins of the outgoing hemispheres.
    #[arg(long, default_value_t = defaults::PHI_O_BINS)]
    pub phi_o_bins: u32,
    /// Children below this fraction of the launched power are dropped (and reported).
    #[arg(long, value_parser = finite, default_value_t = TraceLimits::CUTOFF)]
    pub cutoff: f64,
    /// Interface events along one path before it is dropped (and reported). Light guided
    /// in a film near its critical angle takes thousands: the seed's wavy film at 85 deg
    /// drops 2.4e-2 of its power at the default and 1.2e-4 at 4096
    #[arg(long, default_value_t = TraceLimits::MAX_DEPTH)]
    pub max_depth: u32,
    /// Segments of one tree before its remaining rays are dropped (samples with bodies or
    /// particle media play Russian roulette from 256 segments, so they rarely reach it).
    #[arg(long, default_value_t = TraceLimits::MAX_SEGMENTS)]
    pub max_segments: u32,
    /// Adaptive budget: trace each incident direction in batches until the relative
    /// standard error of the reflectance (total and every populated bucket) is at most
    /// this, e.g. 0.01; reports per direction whether it converged or ran out of budget.
    /// The first batch is the smaller of --rays and 1,024 trees, and each next one is
    /// sized by the error measured so far, 1.25 to 2.5 times the trees before it.
    #[arg(long, value_parser = finite, conflicts_with = "target_stderr")]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tolerance: Option<f64>,
    /// Adaptive budget by the BRDF's quality: trace each incident direction in batches
    /// until the median relative standard error of the buckets that hold 95 % of each
    /// wavelength's reflected power is at most this (e.g. 0.05: a BRDF whose bright
    /// buckets are good to 5 %; `goniospec bench converge` times it per sample); reports
    /// per direction what it reached. Batches as for --tolerance: from the smaller of
    /// --rays and 1,024 trees, grown by the measured error, so the target is met within
    /// about 1.25 times the trees it needs. The errors are those of 16 replicate groups
    /// of trees (README, "Simulation"); a direction's first 1024 trees fill them (before,
    /// the per-tree spread, which overstates the error, stands in).
    #[arg(long, value_parser = finite)]
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target_stderr: Option<f64>,
    /// Largest number of rays per incident direction with --tolerance or --target-stderr,
    /// and where the diffraction method raises its own: where its transform cannot hold
    /// the rays' power at --rays, the run is made again with four times the trees while
    /// that brings it nearer (a warning stored with the result says so). Past it, or where
    /// raising does not help, --coherence diffraction refuses the run and auto gives those
    /// cells to rays.
    #[arg(long, default_value_t = defaults::MAX_RAYS)]
    pub max_rays: u64,
    /// Trace every wavelength separately even when no medium is dispersive or absorbing
    /// and no interface is coated (where one tree would otherwise serve them all).
    #[arg(long)]
    pub no_path_sharing: bool,
    /// Trace each wavelength of a tree on its own instead of all at once. By default,
    /// without path sharing, a tree's wavelengths are traced together and each ray is
    /// shared until it refracts into a dispersive medium; both give the same bits, this
    /// only makes the run slower (for checking).
    #[arg(long)]
    pub no_wavelength_sharing: bool,
    /// Leave out next-event estimation in particle media: by default each scattering event
    /// in a particle layer under flat, clear layers sends the light it would pass straight
    /// out of the sample to the outgoing buckets at once (same expectation, less noise;
    /// README, "Simulation"). Off, only the walk's own escapes count (for checking).
    #[arg(long)]
    pub no_next_event: bool,
    /// Keep the full 4 x 4 Mueller matrix of every bucket as well as its unpolarised
    /// value (its m00, the same bits outside particle media): the polarimetric BRDF, from
    /// the fields the tracer carries for incident s and p light, in each direction's own
    /// s/p frame (docs/physics.md, "Polarisation"). Read it with `goniospec eval --mueller`, the
    /// npz or pbsdf export or Python. The rays and the diffraction method carry it; the
    /// comparison modes (bucket, global) do not. In particle media it costs: each
    /// scattering event then reaches one direction instead of every bucket, and the white
    /// paint's BRDF is about 12 times noisier at equal trees (140 times the trees for
    /// equal noise; README, "Polarisation").
    #[arg(long)]
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub mueller: bool,
    /// The rigorous solver's harmonics per patterned axis (orders -M..M); by default the
    /// orders that propagate in the densest medium plus 12 (1-D) or 3 (crossed gratings).
    /// The convergence check solves again with two thirds of them (strictly fewer); fewer
    /// than the orders that may propagate (2 n_max period / lambda) is refused.
    #[arg(long, value_name = "M")]
    #[serde(skip_serializing_if = "Option::is_none")]
    pub orders: Option<usize>,
    /// The rigorous solver's slices along z per structured region of the tile (flat layers
    /// are one exact slice each, and so is a band that does not change with height); the
    /// convergence check uses half as many, so at least 2 where the structure changes with
    /// height.
    #[arg(long, default_value_t = Effort::SLICES)]
    pub slices: usize,
    /// The largest difference in R, T or any order's efficiency between the rigorous
    /// solution and its coarser check that a cell may have; a cell above it is refused,
    /// naming what to raise.
    #[arg(long, value_parser = finite, default_value_t = Effort::TOLERANCE)]
    pub rigorous_tolerance: f64,
    /// The most wall time, s, the rigorous solver's cells may be estimated to take (from
    /// their harmonics and slices, before any is solved); a run estimated past it is
    /// refused with the estimate. Not a result: never in the output's header.
    #[arg(long, value_name = "SECONDS", value_parser = finite, default_value_t = Effort::BUDGET_S)]
    #[serde(skip, default = "rigorous_budget")]
    pub rigorous_budget: f64,
    /// Debugging only: write results that are physically impossible (R > 1, negative
    /// power, energy created) instead of refusing them with exit status 1. The run still
    /// prints what failed.
    #[arg(long)]
    pub allow_unphysical: bool,
}

impl Default for SimSettings {
    fn default() -> Self {
        SimSettings {
            theta_i_deg: defaults::THETA_I_DEG.to_vec(),
            phi_i_deg: vec![0.0],
            rays: defaults::RAYS,
            wavelengths: crate::spectrum::DEFAULT_WAVELENGTHS.into(),
            monochromatic: false,
            backend: None,
            seed: defaults::SEED,
            coherence: Coherence::Auto,
            coherence_radius_nm: defaults::COHERENCE_RADIUS_NM,
            theta_o_bins: defaults::THETA_O_BINS,
            phi_o_bins: defaults::PHI_O_BINS,
            cutoff: TraceLimits::CUTOFF,
            max_depth: TraceLimits::MAX_DEPTH,
            max_segments: TraceLimits::MAX_SEGMENTS,
            tolerance: None,
            target_stderr: None,
            max_rays: defaults::MAX_RAYS,
            no_path_sharing: false,
            no_wavelength_sharing: false,
            no_next_event: false,
            mueller: false,
            orders: None,
            slices: Effort::SLICES,
            rigorous_tolerance: Effort::TOLERANCE,
            rigorous_budget: Effort::BUDGET_S,
            allow_unphysical: false,
        }
    }
}

impl SimSettings {
    /// The run's configuration: the wavelengths parsed, the backend resolved (Embree where
    /// available) and checked to be in this build, and everything validated
    /// ([`validate`]). The one place settings become a run.
    pub fn resolve(&self) -> Result<SimConfig, SimError> {
        let wavelengths =
            Wavelengths::parse(&self.wavelengths, self.monochromatic).map_err(|e| {
                SimError::Setting {
                    key: "wavelengths",
                    message: e.to_string(),
                }
            })?;
        if let Some(b) = self.backend
            && !b.is_available()
        {
            return Err(SimError::Config(
                crate::accel::AccelError::EmbreeUnavailable.to_string(),
            ));
        }
        let cfg = self.config(wavelengths);
        validate(&cfg)?;
        Ok(cfg)
    }

    /// The run's configuration with `wavelengths` as parsed, unvalidated (see
    /// [`SimSettings::resolve`]; for callers whose settings were checked when they were
    /// read).
    pub fn config(&self, wavelengths: Wavelengths) -> SimConfig {
        SimConfig {
            backend: self.backend.unwrap_or_else(Backend::default_available),
            seed: self.seed,
            coherence: self.coherence,
            rho_nm: self.coherence_radius_nm,
            limits: TraceLimits {
                cutoff: self.cutoff,
                max_depth: self.max_depth,
                max_segments: self.max_segments,
                ..TraceLimits::default()
            },
            buckets: Buckets {
                theta_bins: self.theta_o_bins,
                phi_bins: self.phi_o_bins,
            },
            path_sharing: self.no_path_sharing.then_some(false),
            wavelength_sharing: !self.no_wavelength_sharing,
            next_event: !self.no_next_event,
            mueller: self.mueller,
            rigorous: Effort {
                orders: self.orders,
                slices: self.slices,
                tolerance: self.rigorous_tolerance,
            },
            rigorous_budget_s: self.rigorous_budget,
            allow_unphysical: self.allow_unphysical,
            tolerance: self.tolerance,
            target_stderr: self.target_stderr,
            max_rays: self.max_rays,
            ..SimConfig::new(Vec::new(), wavelengths, self.rays)
        }
        .with_directions(&self.theta_i_deg, &self.phi_i_deg)
    }

    /// Trees the run launches in all (for progress bars): `rays`, or `max_rays` when
    /// adaptive, per incident direction.
    pub fn budget(&self) -> u64 {
        let per = if self.tolerance.is_some() || self.target_stderr.is_some() {
            self.max_rays
        } else {
            self.rays
        };
        let directions = self.theta_i_deg.len() * self.phi_i_deg.len().max(1);
        per.saturating_mul(directions as u64)
    }
}

/// The smallest `--tolerance`: a relative standard error of 1e-6 already needs about 1e12
/// trees per direction for a reflectance near 1 with unit spread.
pub const MIN_TOLERANCE: f64 = 1e-6;

/// Settings of one simulation.
#[derive(Clone, Debug)]
pub struct SimConfig {
    /// Each direction's polar angle, degrees.
    pub theta_i_deg: Vec<f64>,
    /// The azimuth, degrees, of every direction where `phi_each_deg` is empty.
    pub phi_i_deg: f64,
    /// Each direction's azimuth, degrees, where a run has several (`directions`).
    pub phi_each_deg: Vec<f64>,
    /// Trees per incident direction (each covers every wavelength).
    pub rays: u64,
    pub wavelengths: Wavelengths,
    pub backend: Backend,
    pub seed: u64,
    pub coherence: Coherence,
    pub rho_nm: f64,
    pub limits: TraceLimits,
    pub buckets: Buckets,
    /// Share traced geometry across wavelengths; `None` = whenever no medium is dispersive.
    pub path_sharing: Option<bool>,
    /// Without path sharing, trace every wavelength of a tree at once, sharing each ray
    /// until it refracts into a dispersive medium (`Scene::trace_lanes`); `false` traces
    /// each wavelength on its own. Both give the same bits; this only changes the speed.
    pub wavelength_sharing: bool,
    /// Next-event estimation in particle media under flat, clear layers (`trace::escape`):
    /// the same expectation as the walk alone, with less noise.
    pub next_event: bool,
    /// Keep every bucket's Mueller matrix (`accumulate::Cell::mueller`).
    pub mueller: bool,
    /// What the rigorous solver spends, and the convergence it must reach.
    pub rigorous: Effort,
    /// The most wall time, s, the rigorous cells may be estimated to take.
    pub rigorous_budget_s: f64,
    /// Use the reference estimator (`accumulate::Estimator::reference`): the same physics,
    /// slower; for tests.
    pub reference_estimator: bool,
    /// Where the sample's frame sits in the world, nm: exit points and launch points are
    /// reported in world coordinates. The estimator must not depend on it (docs/design.md §3).
    pub origin_nm: DVec3,
    /// Adaptive budget: batches per incident direction, the first the smaller of `rays`
    /// and `growth::FIRST_BATCH`, each next one sized by the error measured so far
    /// (`growth::next_total`), until the relative standard error of the reflectance
    /// (total, and every populated bucket) is at most this, or `max_rays` is spent.
    /// `None`: exactly `rays` trees.
    pub tolerance: Option<f64>,
    /// Adaptive budget by the BRDF's quality: as `tolerance`, but until
    /// [`super::bright_bucket_error`] (the median relative standard error of the buckets
    /// holding [`super::BRIGHT_SHARE`] of each wavelength's reflected power) is at most
    /// this. At most one of the two.
    pub target_stderr: Option<f64>,
    /// The most trees per direction an adaptive budget spends, and the most the
    /// diffraction method raises its trees to, explicit or under auto (`simulate::raise`;
    /// 0: never raised).
    pub max_rays: u64,
    /// Whether the diffraction method may raise its trees within `max_rays` (default
    /// `true`). A batch unit may not: a material's units run one direction each and must
    /// merge into the plan's run at its trees, whereas a raise is the whole run's.
    pub raise_trees: bool,
    /// Entry points: the R2 low-discrepancy sequence (default), or independent uniform
    /// points (plain Monte Carlo, for convergence studies).
    pub random_entry: bool,
    /// Precision phases are formed in (`F32` only for the study's precision experiment).
    pub precision: PhasePrecision,
    /// Return results that fail [`check_physical`] instead of an error (debugging only).
    pub allow_unphysical: bool,
    /// The index of the first incident direction in a larger run this one is part of (a
    /// batch unit): direction `d` draws the random streams of direction
    /// `first_direction + d`, so the parts of a split run hold exactly the whole run's
    /// cells. 0 for a whole run.
    pub first_direction: u64,
    /// Set from another thread to stop the run at the next chunk of blocks; the run then
    /// returns [`SimError::Cancelled`] and nothing else (no partial result).
    pub cancel: Option<std::sync::Arc<std::sync::atomic::AtomicBool>>,
    /// Where the run keeps the trees it will trace, for a progress bar's total
    /// ([`super::ProgressPlan`]); `None` where nobody shows progress.
    pub progress_plan: Option<std::sync::Arc<super::ProgressPlan>>,
    /// Tests only: tracing this direction (an index into `theta_i_deg`) fails as a refused
    /// direction would, so that what a failed run keeps ([`super::SimError::Partial`]) can
    /// be checked against a run of the finished angles alone. `None` in every real run.
    #[doc(hidden)]
    pub fail_direction: Option<usize>,
}

impl SimConfig {
    /// Whether the budget is adaptive (`tolerance` or `target_stderr`).
    pub fn adaptive(&self) -> bool {
        self.tolerance.is_some() || self.target_stderr.is_some()
    }

    /// The adaptive budget's goal and what it is judged by.
    pub fn adaptive_goal(&self) -> Option<f64> {
        self.tolerance.or(self.target_stderr)
    }

    /// A simulation of `rays` trees per incident direction with the defaults of
    /// `goniospec simulate`: azimuth 0, the default backend, seed 1, the beamlet estimator
    /// with a 5 um radius, the default trace limits, 45 x 36 outgoing buckets, path
    /// sharing where no medium is dispersive, the sample at the world origin, a fixed
    /// budget, R2 entry points and f64 phases. Change fields with struct-update syntax.
    pub fn new(theta_i_deg: Vec<f64>, wavelengths: Wavelengths, rays: u64) -> SimConfig {
        SimConfig {
            theta_i_deg,
            phi_i_deg: 0.0,
            phi_each_deg: Vec::new(),
            rays,
            wavelengths,
            backend: Backend::default_available(),
            seed: defaults::SEED,
            coherence: Coherence::Beamlet,
            rho_nm: defaults::COHERENCE_RADIUS_NM,
            limits: TraceLimits::default(),
            buckets: Buckets {
                theta_bins: defaults::THETA_O_BINS,
                phi_bins: defaults::PHI_O_BINS,
            },
            path_sharing: None,
            wavelength_sharing: true,
            next_event: true,
            mueller: false,
            rigorous: Effort::default(),
            rigorous_budget_s: Effort::BUDGET_S,
            reference_estimator: false,
            origin_nm: DVec3::ZERO,
            tolerance: None,
            target_stderr: None,
            max_rays: 0,
            raise_trees: true,
            random_entry: false,
            precision: PhasePrecision::F64,
            allow_unphysical: false,
            first_direction: 0,
            cancel: None,
            progress_plan: None,
            fail_direction: None,
        }
    }
}

/// The validity warnings' view of a run (`sample::validity`): its wavelength range, most
/// oblique incidence, coherence radius, bucket width and method.
pub fn validity_context(cfg: &SimConfig) -> crate::sample::validity::Context {
    use crate::sample::validity::{Context, Method};
    Context {
        lambda_min_nm: cfg.wavelengths.min(),
        lambda_max_nm: cfg.wavelengths.max(),
        theta_i_deg: cfg.theta_i_deg.clone(),
        rho_nm: cfg.rho_nm,
        bucket_rad: std::f64::consts::FRAC_PI_2 / f64::from(cfg.buckets.theta_bins),
        method: match cfg.coherence {
            Coherence::Diffraction => Method::Diffraction,
            Coherence::Auto => Method::Auto,
            Coherence::Rigorous => Method::Rigorous,
            _ => Method::Rays,
        },
    }
}

/// The validity warnings `check` gives (no run to judge): one wavelength, normal incidence
/// up to `theta_max_deg`, coherence radius `rho_nm`, the default buckets, the method of
/// `coherence` (auto: the default run's).
pub fn check_validity_context(
    lambda_nm: f64,
    theta_max_deg: f64,
    rho_nm: f64,
    coherence: Coherence,
) -> crate::sample::validity::Context {
    let method = validity_context(&SimConfig {
        coherence,
        ..SimConfig::new(vec![0.0], Wavelengths::Monochromatic(vec![lambda_nm]), 1)
    })
    .method;
    crate::sample::validity::Context {
        lambda_min_nm: lambda_nm,
        lambda_max_nm: lambda_nm,
        // Every whole degree up to the most oblique: `check` judges the angles a run may ask.
        theta_i_deg: (0..)
            .map(f64::from)
            .take_while(|t| *t < theta_max_deg)
            .chain([theta_max_deg])
            .collect(),
        rho_nm,
        bucket_rad: std::f64::consts::FRAC_PI_2 / f64::from(defaults::THETA_O_BINS),
        method,
    }
}

/// Refuses a configuration no run can take (angles, counts, radii, limits), before any
/// work; [`simulate`] calls it first, and front ends that judge a run beforehand (the
/// validity warnings) call it before that.
pub fn validate(cfg: &SimConfig) -> Result<(), SimError> {
    let bad = |key: &'static str, m: String| Err(SimError::Setting { key, message: m });
    if cfg.theta_i_deg.is_empty() {
        return bad("theta_i", "no incident directions".into());
    }
    if let Some(t) = cfg.theta_i_deg.iter().find(|t| !(0.0..90.0).contains(*t)) {
        return bad(
            "theta_i",
            format!("incident angle {t} deg is outside [0, 90)"),
        );
    }
    super::directions::validate_azimuths(cfg)?;
    if !cfg.origin_nm.is_finite() {
        return bad(
            "origin_nm",
            format!("the sample's origin must be finite, got {}", cfg.origin_nm),
        );
    }
    if cfg.rays == 0 {
        return bad("rays", "must be at least 1".into());
    }
    if let Some(t) = cfg.tolerance
        && !(MIN_TOLERANCE..1.0).contains(&t)
    {
        return bad(
            "tolerance",
            format!(
                "must be a relative standard error in [{MIN_TOLERANCE:e}, 1), got {t:e} (below 1e-6 needs some 1e12 trees per direction)"
            ),
        );
    }
    if let Some(t) = cfg.target_stderr {
        if !(MIN_TOLERANCE..1.0).contains(&t) {
            return bad(
                "target_stderr",
                format!(
                    "must be a median relative standard error in [{MIN_TOLERANCE:e}, 1), got {t:e}"
                ),
            );
        }
        if cfg.tolerance.is_some() {
            return bad(
                "target_stderr",
                "give --tolerance (every bright bucket) or --target-stderr (their median), not both"
                    .into(),
            );
        }
        if matches!(cfg.coherence, Coherence::Bucket | Coherence::Global) {
            return bad(
                "target_stderr",
                format!(
                    "--coherence {} sums trees coherently, so its buckets have no per-tree error to judge: use --coherence auto or beamlet, or a fixed --rays",
                    cfg.coherence.name()
                ),
            );
        }
    }
    // A configuration built in code (not parsed) meets the parser's rules here.
    if let Err(e) =
        Wavelengths::from_parts(cfg.wavelengths.mode(), cfg.wavelengths.values_nm().to_vec())
    {
        return bad("wavelengths", e.to_string());
    }
    if cfg.rho_nm.is_nan() || cfg.rho_nm <= 0.0 {
        return bad(
            "coherence_radius_nm",
            format!("must be positive (or inf), got {}", cfg.rho_nm),
        );
    }
    // The diffraction method spreads each order by the illumination's transverse wave
    // vectors (standard deviation 1/(k rho) in direction sines) through a 5 x 5
    // Gauss-Hermite rule. Its outer nodes, 2.86 standard deviations out, leave the horizon
    // once 1/(k rho) > 0.35, i.e. rho < 0.455 lambda / n: then the centre node alone is left
    // and the spread vanishes (issue 48: 1 nm and 30 nm gave the BRDF of rho = inf, byte
    // for byte). Refused below half the run's longest vacuum wavelength.
    let lambda_max = cfg
        .wavelengths
        .values_nm()
        .iter()
        .copied()
        .fold(0.0, f64::max);
    if cfg.coherence == Coherence::Diffraction && cfg.rho_nm < 0.5 * lambda_max {
        return bad(
            "coherence_radius_nm",
            format!(
                "{} nm is below half the run's longest wavelength ({lambda_max} nm) for --coherence diffraction: so short a coherence radius spreads the illumination over more directions than propagate (1/(k rho) = {:.2} in direction sines), which the method's spread cannot hold; give at least {} nm, or inf",
                cfg.rho_nm,
                lambda_max / (2.0 * std::f64::consts::PI * cfg.rho_nm),
                0.5 * lambda_max
            ),
        );
    }
    validate_mueller(cfg)?;
    validate_budget(cfg)?;
    super::rigorous_fit::validate_effort(cfg)?;
    if !(cfg.limits.cutoff >= 0.0 && cfg.limits.cutoff < 1.0) {
        return bad(
            "cutoff",
            format!("must be in [0, 1), got {}", cfg.limits.cutoff),
        );
    }
    if cfg.buckets.theta_bins == 0 || cfg.buckets.phi_bins == 0 {
        return bad(
            "theta_o_bins",
            "bucket counts (theta_o_bins, phi_o_bins) must be at least 1".into(),
        );
    }
    // Sizes are estimated before anything is allocated (checked arithmetic throughout).
    let buckets = u64::from(cfg.buckets.theta_bins).checked_mul(u64::from(cfg.buckets.phi_bins));
    if buckets.is_none_or(|b| b > MAX_BUCKETS) {
        return bad(
            "theta_o_bins",
            format!(
                "{} x phi_o_bins {} is more than {MAX_BUCKETS} buckets per hemisphere",
                cfg.buckets.theta_bins, cfg.buckets.phi_bins
            ),
        );
    }
    // The accumulator: per (direction, wavelength) cell, two hemispheres of buckets with a
    // sum, a sum of squares and a count (24 bytes each).
    let bytes = buckets
        .and_then(|b| b.checked_mul(2 * 24))
        .and_then(|b| b.checked_mul(cfg.theta_i_deg.len() as u64))
        .and_then(|b| b.checked_mul(cfg.wavelengths.count() as u64));
    if bytes.is_none_or(|b| b > MAX_ACCUMULATOR_BYTES) {
        return bad(
            "theta_o_bins",
            format!(
                "the accumulator would need more than {} GiB ({} incident angles x {} wavelengths x {} buckets): use fewer theta_o_bins/phi_o_bins, wavelengths or angles",
                MAX_ACCUMULATOR_BYTES >> 30,
                cfg.theta_i_deg.len(),
                cfg.wavelengths.count(),
                buckets.unwrap_or(u64::MAX)
            ),
        );
    }
    if cfg.rays > MAX_RAYS || cfg.max_rays > MAX_RAYS {
        return bad(
            "max_rays",
            format!(
                "rays and max_rays above {MAX_RAYS:e} per direction would run for weeks; split the work into seeds and merge"
            ),
        );
    }
    Ok(())
}

/// An adaptive run starts at `rays` trees and grows to at most `max_rays`: a budget below
/// its start is a contradiction, not a cap (issue 74: `--max-rays 1 --rays 64
/// --target-stderr 0.05` ran 64 trees; `render` refused it already).
fn validate_budget(cfg: &SimConfig) -> Result<(), SimError> {
    if cfg.adaptive() && cfg.max_rays < cfg.rays {
        return Err(SimError::Setting {
            key: "max_rays",
            message: format!(
                "{} is below --rays {}: an adaptive run (--tolerance or --target-stderr) starts at --rays trees and grows to at most --max-rays",
                cfg.max_rays, cfg.rays
            ),
        });
    }
    Ok(())
}

/// `--mueller` with a comparison mode, which does not carry the Mueller matrix: refused.
fn validate_mueller(cfg: &SimConfig) -> Result<(), SimError> {
    if cfg.mueller && matches!(cfg.coherence, Coherence::Bucket | Coherence::Global) {
        return Err(SimError::Setting {
            key: "mueller",
            message: format!(
                "--coherence {} does not carry the Mueller matrix: the ray method (beamlet) and the diffraction method do (give --coherence auto, beamlet or diffraction)",
                cfg.coherence.name()
            ),
        });
    }
    Ok(())
}

/// Buckets per hemisphere (4096 x 1024 bins, far finer than any measurement).
const MAX_BUCKETS: u64 = 1 << 22;
/// The accumulator's cells must fit comfortably in memory (the machines this runs on have
/// tens of GiB).
const MAX_ACCUMULATOR_BYTES: u64 = 8 << 30;
/// The most trees per incident direction any run may ask for.
pub const MAX_RAYS: u64 = 1_000_000_000_000;

fn rigorous_budget() -> f64 {
    Effort::BUDGET_S
}
