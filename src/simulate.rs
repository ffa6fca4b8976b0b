//! The virtual goniospectrometer run: launches stratified ray trees over the tile for each
//! incident direction, traces them (sharing geometry across wavelengths where no medium is
//! dispersive), and accumulates them with the estimator into a `.gsa` accumulator.
//!
//! Determinism: trees are processed in fixed blocks whose sums are combined in block
//! order, and every random number comes from a stream keyed by (seed, direction, tree), so
//! the output bytes do not depend on the thread count.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use rayon::prelude::*;

use crate::accel::Backend;
use crate::accumulate::block::{BlockCell, Dense, add_block};
use crate::accumulate::file::{Accumulator, EntryPoints, Header, Settings, WavelengthMode};
use crate::accumulate::{
    Buckets, Cell, Coherence, Estimator, PhasePrecision, Scratch, diffraction,
};
use crate::geom::from_spherical;
use crate::io::fnv1a;
use crate::optics::C64;
use crate::rng::Rng;
use crate::sample::Sample;
use crate::trace::{
    DroppedPower, Lane, Scene, SceneError, TraceLimits, TraceStack, Tree, launch_fields,
};
use glam::DVec3;

/// Trees per block: the unit of parallel work and of deterministic summation.
const BLOCK: u64 = 64;
/// Blocks in flight at once per worker thread (at least `MIN_CHUNK_BLOCKS` in all): their
/// sums are the only memory that grows with the work, so peak memory depends on the thread
/// count but not on the ray count. The chunking never changes the results.
const CHUNK_BLOCKS_PER_THREAD: u64 = 4;
const MIN_CHUNK_BLOCKS: u64 = 16;

pub use crate::spectrum::Wavelengths;

/// Every front end's defaults for a simulation (CLI flags, Python keywords, studies), in
/// one place. The limits of a tree are `TraceLimits::default()`.
pub mod defaults {
    /// Trees per incident direction.
    pub const RAYS: u64 = 4096;
    /// The most trees per direction of an adaptive run (`--tolerance`).
    pub const MAX_RAYS: u64 = 1_000_000;
    /// Beamlet radius: the illumination's transverse coherence length, nm.
    pub const COHERENCE_RADIUS_NM: f64 = 5000.0;
    /// Outgoing buckets per hemisphere, in theta and in phi.
    pub const THETA_O_BINS: u32 = 45;
    pub const PHI_O_BINS: u32 = 36;
    /// Random seed.
    pub const SEED: u64 = 1;
}

/// The smallest `--tolerance`: a relative standard error of 1e-6 already needs about 1e12
/// trees per direction for a reflectance near 1 with unit spread.
pub const MIN_TOLERANCE: f64 = 1e-6;

/// Settings of one simulation.
#[derive(Clone, Debug)]
pub struct SimConfig {
    pub theta_i_deg: Vec<f64>,
    pub phi_i_deg: f64,
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
    /// Use the reference estimator (`accumulate::Estimator::reference`): the same physics,
    /// slower; for tests.
    pub reference_estimator: bool,
    /// Where the sample's frame sits in the world, nm: exit points and launch points are
    /// reported in world coordinates. The estimator must not depend on it (docs/design.md §3).
    pub origin_nm: DVec3,
    /// Adaptive budget: launch batches of `rays` trees per incident direction until the
    /// relative standard error of the reflectance (total, and every populated bucket) is
    /// at most this, or `max_rays` is spent. `None`: exactly `rays` trees.
    pub tolerance: Option<f64>,
    pub max_rays: u64,
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
}

impl SimConfig {
    /// A simulation of `rays` trees per incident direction with the defaults of
    /// `goniospec simulate`: azimuth 0, the default backend, seed 1, the beamlet estimator
    /// with a 5 um radius, the default trace limits, 45 x 36 outgoing buckets, path
    /// sharing where no medium is dispersive, the sample at the world origin, a fixed
    /// budget, R2 entry points and f64 phases. Change fields with struct-update syntax.
    pub fn new(theta_i_deg: Vec<f64>, wavelengths: Wavelengths, rays: u64) -> SimConfig {
        SimConfig {
            theta_i_deg,
            phi_i_deg: 0.0,
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
            reference_estimator: false,
            origin_nm: DVec3::ZERO,
            tolerance: None,
            max_rays: 0,
            random_entry: false,
            precision: PhasePrecision::F64,
            allow_unphysical: false,
            first_direction: 0,
            cancel: None,
        }
    }
}

/// How one incident direction ended.
#[derive(Clone, Debug, PartialEq)]
pub struct DirectionStats {
    pub theta_i_deg: f64,
    pub rays: u64,
    /// Largest relative standard error over wavelength bins of the total reflectance and
    /// of every populated reflection bucket (holding at least a tenth of the brightest
    /// bucket's power); `None` where undefined (global mode).
    pub achieved: Option<f64>,
    /// The tolerance was reached (adaptive runs).
    pub converged: bool,
}

impl std::fmt::Display for DirectionStats {
    /// `theta_i 30 deg: 4096 trees, relative standard error 0.0123 (converged)`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "theta_i {} deg: {} trees, relative standard error {} ({})",
            self.theta_i_deg,
            self.rays,
            self.achieved
                .map_or("undefined".into(), |v| format!("{v:.4}")),
            if self.converged {
                "converged"
            } else {
                "budget exhausted"
            }
        )
    }
}

/// The achieved relative error of incident direction `di` (see [`DirectionStats`]).
pub fn achieved_error(cells: &[Cell], di: usize, nl: usize, mode: Coherence) -> Option<f64> {
    if mode == Coherence::Global {
        return None;
    }
    let mut worst: f64 = 0.0;
    for c in &cells[di * nl..(di + 1) * nl] {
        let n = c.trees as f64;
        if c.trees < 2 {
            return Some(f64::INFINITY);
        }
        let r = c.r_sum / n;
        if r > 0.0 {
            worst = worst.max(c.r_stderr(mode).unwrap_or(f64::INFINITY) / r);
        }
        let fmax = (0..c.sum.len())
            .step_by(2)
            .map(|k| c.sum[k] / n)
            .fold(0.0, f64::max);
        for k in (0..c.sum.len()).step_by(2) {
            let f = c.sum[k] / n;
            if f > 0.0 && f >= 0.1 * fmax {
                worst = worst.max(c.fraction_stderr(k, mode).unwrap_or(f64::INFINITY) / f);
            }
        }
    }
    Some(worst)
}

/// The validity warnings' view of a run (`sample::validity`): its wavelength range, most
/// oblique incidence, coherence radius, bucket width and method.
pub fn validity_context(cfg: &SimConfig) -> crate::sample::validity::Context {
    use crate::sample::validity::{Context, Method};
    Context {
        lambda_min_nm: cfg.wavelengths.min(),
        lambda_max_nm: cfg.wavelengths.max(),
        theta_max_deg: cfg.theta_i_deg.iter().copied().fold(0.0, f64::max),
        rho_nm: cfg.rho_nm,
        bucket_rad: std::f64::consts::FRAC_PI_2 / f64::from(cfg.buckets.theta_bins),
        method: if cfg.coherence == Coherence::Diffraction {
            Method::Diffraction
        } else {
            Method::Rays
        },
    }
}

/// The validity warnings `check` gives (no run to judge): one wavelength, normal incidence
/// up to `theta_max_deg`, coherence radius `rho_nm`, the default buckets, rays.
pub fn check_validity_context(
    lambda_nm: f64,
    theta_max_deg: f64,
    rho_nm: f64,
) -> crate::sample::validity::Context {
    crate::sample::validity::Context {
        lambda_min_nm: lambda_nm,
        lambda_max_nm: lambda_nm,
        theta_max_deg,
        rho_nm,
        bucket_rad: std::f64::consts::FRAC_PI_2 / f64::from(defaults::THETA_O_BINS),
        method: crate::sample::validity::Method::Rays,
    }
}

/// One cell of the diffraction method: what the rays gave and what the transform kept in
/// propagating orders before its orders were scaled to the rays' totals.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DiffractionCell {
    /// The beamlet estimator's R and T on the same trees (the cell's totals).
    pub rays_r: f64,
    pub rays_t: f64,
    /// The propagating orders' R and T as transformed (Parseval: equal to the rays' where
    /// the ray field is sampled finely enough and puts no power beyond the horizon).
    pub r: f64,
    pub t: f64,
    /// Propagating orders with power.
    pub orders: usize,
    /// Tubes shaped by their tracked cross-section (no neighbouring tree had the same
    /// exit), and tubes that passed a line focus.
    pub fallback_tubes: usize,
    pub flipped_tubes: usize,
}

impl DiffractionCell {
    /// The transform's total against the rays', `(R + T)_orders / (R + T)_rays` (1 when
    /// Parseval holds; NaN for an empty cell).
    pub fn ratio(&self) -> f64 {
        (self.r + self.t) / (self.rays_r + self.rays_t)
    }
}

/// The diffraction method's orders hold this fraction of the ray field's power or more
/// (and at most its inverse) without comment. Sinusoidal gratings of slope 17 deg at
/// period / wavelength 9 keep 0.990 at 0 deg and 0.969 at 30 deg (tests/diffraction.rs):
/// the rest is the transform's tail beyond the horizon and the exit plane's near field.
/// Outside, `simulate` warns.
pub const DIFFRACTION_RATIO_WARN: f64 = 0.95;
/// The most memory the diffraction method's kept exits may take, bytes.
pub const DIFFRACTION_MAX_BYTES: f64 = 8e9;

/// Below this (or above its inverse) the ray field is too coarse or too far from a plane
/// wave per tube for the transform (sub-wavelength structure, rays too sparse), and the
/// run is refused.
pub const DIFFRACTION_RATIO_REFUSED: f64 = 0.8;

/// Run statistics.
#[derive(Clone, Debug, Default)]
pub struct SimStats {
    pub trees: u64,
    pub traces: u64,
    pub segments: u64,
    pub leaks: u64,
    /// Wall time of the whole run, s.
    pub seconds: f64,
    /// The part of `seconds` spent before tracing (building the scene's accelerator,
    /// hashing the sample), s; rates of trees and segments are over the rest.
    pub setup_seconds: f64,
    pub path_sharing: bool,
    /// Every wavelength of a tree was traced at once (`SimConfig::wavelength_sharing`).
    pub wavelength_sharing: bool,
    pub directions: Vec<DirectionStats>,
    /// Per cell (direction-major, like the accumulator's cells): the summed power per tree
    /// dropped by limits (depth, segments, wraps) and leaks rather than by the cutoff.
    pub limit_dropped: Vec<f64>,
    /// Per cell: the summed power per tree that left an open sample through its sides
    /// (`Sample::guard_nm`; zero for periodic sides). It is part of the dropped power.
    pub escaped: Vec<f64>,
    /// Per cell: the summed per-tree bound `2 sqrt(D_l (R + T)) + D_l` on how much the
    /// power cut by limits (`D_l`) can change a tree's coherent totals.
    pub limit_bound: Vec<f64>,
    /// Per cell: the summed power per tree created by ray series that did not recombine,
    /// `max(0, R + T + dropped - 1)` over trees that entered an absorbing medium. A
    /// physical field never exceeds its source; a tree does when light crossed an
    /// absorbing feature thinner than its decay length (a ridge tip at grazing light, a
    /// sub-skin-depth wedge) whose partial waves leave in directions that do not
    /// interfere, where no ray model holds (docs/physics.md, "Where the ray model stops").
    pub created: Vec<f64>,
    /// Per cell: the summed power per tree that met energy-limited events inside absorbers
    /// (`trace::Tree::limited_power`): facets tilted against the wave's entry facet by more
    /// than its partial waves can recombine over the coherence length (film faces tilted by
    /// more than about 0.02 degrees at a 5 um beamlet, ridge tips). There R and T come from
    /// a model that conserves energy, not from exact amplitudes.
    pub limited: Vec<f64>,
    /// The diffraction method, per cell: the ray method's totals beside the diffracted
    /// ones (empty cells for other methods).
    pub diffraction: Vec<DiffractionCell>,
    /// Particle media: scattering angles drawn where the phase function exceeded its
    /// tabulated envelope (`optics::particles`; each such draw is slightly biased). 0 in a
    /// correct table.
    pub envelope_violations: u64,
}

impl SimStats {
    /// The largest mean power per tree that met energy-limited events, with its cell.
    pub fn worst_limited(&self, acc: &Accumulator) -> (f64, usize) {
        worst_per_tree(&self.limited, acc)
    }

    /// The largest mean power per tree that any cell's ray series created, with that
    /// cell's index.
    pub fn worst_created(&self, acc: &Accumulator) -> (f64, usize) {
        worst_per_tree(&self.created, acc)
    }

    /// The largest mean per-tree bound on how much the power cut by limits can change R
    /// and T, with that cell's index.
    pub fn worst_limit_bound(&self, acc: &Accumulator) -> (f64, usize) {
        worst_per_tree(&self.limit_bound, acc)
    }

    /// Wall time spent tracing and estimating (after the set-up), s.
    pub fn trace_seconds(&self) -> f64 {
        (self.seconds - self.setup_seconds).max(f64::MIN_POSITIVE)
    }

    /// The largest mean power per tree that any cell lost through the sides of an open
    /// sample, with that cell's index.
    pub fn worst_escaped(&self, acc: &Accumulator) -> (f64, usize) {
        worst_per_tree(&self.escaped, acc)
    }

    /// The largest mean power per tree that any cell lost to limits and leaks: when it is
    /// not small the ray series was cut before it converged.
    pub fn worst_limit_dropped(&self, acc: &Accumulator) -> f64 {
        worst_per_tree(&self.limit_dropped, acc).0
    }
}

/// The largest of the per-cell sums `per_cell` divided by the cell's trees, and its cell.
fn worst_per_tree(per_cell: &[f64], acc: &Accumulator) -> (f64, usize) {
    per_cell
        .iter()
        .zip(&acc.cells)
        .map(|(d, c)| d / c.trees.max(1) as f64)
        .enumerate()
        .fold((0.0, 0), |w, (i, v)| if v > w.0 { (v, i) } else { w })
}

/// What can stop a simulation.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[error("{0}")]
    Config(String),
    /// An impossible result (R > 1, negative power, energy created): never written.
    #[error("{0}")]
    Unphysical(String),
    /// Stopped through `SimConfig::cancel`.
    #[error("the simulation was cancelled")]
    Cancelled,
}

/// Hash of everything in a sample that changes results: FNV-1a 64 of a canonical encoding of the sample's physics inputs: tile, media (names
/// and index models, [`crate::sample::IndexModel::canonical_bytes`]), interfaces (media,
/// coatings, vertices and triangles). Runs merge only when it agrees.
pub fn sample_hash(sample: &Sample) -> String {
    let mut bytes: Vec<u8> = Vec::new();
    for v in sample.tile_nm {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    for m in &sample.media {
        bytes.extend_from_slice(m.name.as_bytes());
        m.model.canonical_bytes(&mut bytes);
        // Scattering media only, so every other sample keeps its hash.
        if let Some(sc) = &m.scattering {
            sc.canonical_bytes(&mut bytes);
        }
    }
    // Open samples only, so periodic samples keep their hash.
    if let Some(g) = sample.guard_nm {
        bytes.extend_from_slice(b"guard");
        bytes.extend_from_slice(&g.to_le_bytes());
    }
    for i in &sample.interfaces {
        bytes.extend_from_slice(&(i.front as u64).to_le_bytes());
        bytes.extend_from_slice(&(i.back as u64).to_le_bytes());
        // Coated interfaces only, so uncoated samples keep their hash.
        for (m, d) in &i.coating {
            bytes.extend_from_slice(b"coat");
            bytes.extend_from_slice(&(*m as u64).to_le_bytes());
            bytes.extend_from_slice(&d.to_le_bytes());
        }
        for p in &i.mesh.positions_nm {
            for c in p.to_array() {
                bytes.extend_from_slice(&c.to_le_bytes());
            }
        }
        for t in &i.mesh.triangles {
            for c in t {
                bytes.extend_from_slice(&c.to_le_bytes());
            }
        }
    }
    format!("{:016x}", fnv1a(&bytes))
}

/// Entry point `i` of `n` on the tile: the R2 low-discrepancy sequence (Roberts 2018,
/// "The unreasonable effectiveness of quasirandom sequences") with a random shift.
/// `guard` (nm) keeps the points that far from every side (open samples; 0 otherwise).
fn entry_point(i: u64, shift: [f64; 2], tile: [f64; 2], guard: f64) -> [f64; 2] {
    const G: f64 = 1.324_717_957_244_746; // plastic number
    let a = [1.0 / G, 1.0 / (G * G)];
    let f = |k: usize| (shift[k] + (i as f64) * a[k]).rem_euclid(1.0);
    // With no guard this is `f * tile` exactly (`0 + x` and `L - 0` round to themselves).
    [0, 1].map(|k| guard + f(k) * (tile[k] - 2.0 * guard))
}

/// The diffraction method's entry points: an `nx x ny` lattice over the tile with about
/// `rays` points and cells as square as the tile allows (`nx / ny` near `Lx / Ly`). Its
/// tubes' footprints tile the exit plane with a near-constant overlap, so the Gaussian
/// patches of `accumulate::diffraction` sum to a uniform field (on a lattice of spacing d,
/// patches of 0.6 d ripple by `2 exp(-2 pi^2 0.36) = 1.6e-3`; an R2 set ripples by
/// percents and scatters that much power into spurious orders).
pub fn diffraction_lattice(rays: u64, tile_nm: [f64; 2]) -> [u64; 2] {
    let nx = ((rays as f64 * tile_nm[0] / tile_nm[1]).sqrt().round() as u64).max(1);
    let ny = ((rays as f64 / nx as f64).round() as u64).max(1);
    [nx, ny]
}

/// Point `i` of the lattice `n` (see [`diffraction_lattice`]), shifted by `shift` cells.
fn lattice_point(i: u64, n: [u64; 2], shift: [f64; 2], tile: [f64; 2]) -> [f64; 2] {
    let (ix, iy) = (i % n[0], i / n[0]);
    [
        (ix as f64 + shift[0]) / n[0] as f64 * tile[0],
        (iy as f64 + shift[1]) / n[1] as f64 * tile[1],
    ]
}

/// Runs the simulation. `progress` receives the number of trees finished so far.
///
/// Three stages: [`Run::prepare`] (scene, media, estimator, the header's settings),
/// [`Run::direction`] for every incident direction (blocks of trees traced in parallel and
/// reduced in block order), and [`Run::finish`] (statistics, header, and the refusal of
/// impossible results).
pub fn simulate(
    sample: &Sample,
    cfg: &SimConfig,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<(Accumulator, SimStats), SimError> {
    validate(cfg)?;
    // The diffraction method launches on a lattice (`diffraction_lattice`): the run traces
    // its `nx * ny` trees per direction.
    let lattice_cfg;
    let lattice = diffraction_lattice(cfg.rays, sample.tile_nm);
    let cfg = if cfg.coherence == Coherence::Diffraction {
        let [nx, ny] = lattice;
        lattice_cfg = SimConfig {
            rays: nx * ny,
            ..cfg.clone()
        };
        &lattice_cfg
    } else {
        cfg
    };
    let start_time = Instant::now();
    let mut run = Run::prepare(sample, cfg)?;
    run.lattice = lattice;
    run.setup_seconds = start_time.elapsed().as_secs_f64();
    let mut cells: Vec<Cell> = (0..cfg.theta_i_deg.len() * run.nl)
        .map(|_| Cell::new(&cfg.buckets, run.global))
        .collect();
    let mut limit_dropped = vec![0.0; cells.len()];
    let mut escaped = vec![0.0; cells.len()];
    let mut limit_bound = vec![0.0; cells.len()];
    let mut created = vec![0.0; cells.len()];
    let mut limited = vec![0.0; cells.len()];
    let mut diffraction = vec![DiffractionCell::default(); cells.len()];
    let directions = cfg
        .theta_i_deg
        .iter()
        .enumerate()
        .map(|(di, &theta_deg)| {
            let lost = Lost {
                diffraction: &mut diffraction,
                limit_dropped: &mut limit_dropped,
                escaped: &mut escaped,
                limit_bound: &mut limit_bound,
                created: &mut created,
                limited: &mut limited,
            };
            run.direction(di, theta_deg, &mut cells, lost, progress)
        })
        .collect::<Result<Vec<_>, SimError>>()?;
    if cfg
        .cancel
        .as_ref()
        .is_some_and(|c| c.load(Ordering::Relaxed))
    {
        return Err(SimError::Cancelled);
    }
    let lost = LostSums {
        diffraction,
        limit_dropped,
        escaped,
        limit_bound,
        created,
        limited,
    };
    run.finish(cells, lost, directions, start_time)
}

/// Per-cell sums of what the run lost or could not trust (see [`SimStats`]), filled
/// direction by direction.
struct Lost<'a> {
    diffraction: &'a mut [DiffractionCell],
    limit_dropped: &'a mut [f64],
    escaped: &'a mut [f64],
    limit_bound: &'a mut [f64],
    created: &'a mut [f64],
    limited: &'a mut [f64],
}

/// The finished sums of [`Lost`].
struct LostSums {
    diffraction: Vec<DiffractionCell>,
    limit_dropped: Vec<f64>,
    escaped: Vec<f64>,
    limit_bound: Vec<f64>,
    created: Vec<f64>,
    limited: Vec<f64>,
}

/// Counters every worker adds to.
#[derive(Default)]
struct Counters {
    done: AtomicU64,
    segments: AtomicU64,
    leaks: AtomicU64,
    traces: AtomicU64,
    energy_faults: AtomicU64,
}

/// One worker's reusable state: the ray stack, the trees (one per wavelength when they
/// are traced at once), the estimator's scratch and deposits, the dense block sums, and
/// the media indices and wavelength of each tree.
struct Worker {
    stack: TraceStack,
    trees: Vec<Tree>,
    scratch: Scratch,
    deps: Vec<(u32, f64)>,
    glob: Vec<(u32, [crate::optics::fresnel::Field; 2])>,
    dense: Dense,
    indices: Vec<Vec<C64>>,
    lambdas: Vec<f64>,
}

/// How a tree's wavelengths are traced.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Tracing {
    /// One tree at the longest wavelength serves every wavelength (path sharing).
    Shared,
    /// Every wavelength at once, rays shared until a dispersive refraction.
    Lanes,
    /// Each wavelength on its own.
    PerWavelength,
}

/// Everything a run shares between its directions and workers.
struct Run<'a> {
    sample: &'a Sample,
    cfg: &'a SimConfig,
    scene: Scene<'a>,
    est: Estimator,
    settings: Settings,
    /// Geometry traced once for all wavelengths.
    sharing: bool,
    tracing: Tracing,
    global: bool,
    /// `Coherence::Diffraction`: exits are kept for the far-field transform, and trees
    /// launch on this lattice (`diffraction_lattice`).
    diffraction: bool,
    lattice: [u64; 2],
    nl: usize,
    lambda_max: f64,
    /// Media indices at the longest wavelength (the shared geometry's).
    fixed_indices: Vec<C64>,
    counters: Counters,
    /// Wall time of `prepare` (the scene's build, the sample's hash), s.
    setup_seconds: f64,
}

impl<'a> Run<'a> {
    /// Stage 1: the scene, whether paths are shared, the media at every wavelength the
    /// run evaluates, the estimator and the header's settings.
    fn prepare(sample: &'a Sample, cfg: &'a SimConfig) -> Result<Run<'a>, SimError> {
        let mut scene = Scene::new(sample, cfg.backend)?;
        scene.set_coherence_length(cfg.rho_nm);
        // Particle media: properties change with the wavelength and free paths are random,
        // so every wavelength is traced on its own; scattered light has random phases, so
        // only the beamlet estimator (which pairs exits of one coherence group) applies.
        let scattering = scene.scatters();
        if scattering {
            if cfg.coherence != Coherence::Beamlet {
                return Err(SimError::Config(format!(
                    "--coherence {} sums the fields of every path in a bucket, but light scattered by this sample's particle media has random phases; use --coherence beamlet (the default)",
                    cfg.coherence
                )));
            }
            if cfg.path_sharing == Some(true) {
                return Err(SimError::Config(
                    "path sharing needs wavelength-independent paths: this sample has scattering media, whose free paths and directions are drawn per wavelength".into(),
                ));
            }
        }
        let diffraction = cfg.coherence == Coherence::Diffraction;
        if diffraction {
            if sample.guard_nm.is_some() {
                return Err(SimError::Config(
                    "--coherence diffraction takes the far field of a periodic tile, but this sample's sides are open (a guard band): give the height map periodic edges, or use --coherence beamlet".into(),
                ));
            }
            if sample.interfaces.iter().any(|i| i.closed) {
                return Err(SimError::Config(
                    "--coherence diffraction sums deterministic ray fields, but this sample has closed bodies (pigments, flakes) whose long trees end by Russian roulette with random weights; use --coherence beamlet, and a particle medium for sub-wavelength particles".into(),
                ));
            }
            if cfg.tolerance.is_some() {
                return Err(SimError::Config(
                    "--coherence diffraction sums all trees of a direction at once, so it has no per-tree error to stop on: give a fixed --rays instead of --tolerance".into(),
                ));
            }
        }
        let dispersive = sample.media.iter().any(|m| m.model.is_dispersive()) || scattering;
        // A coating's coefficients depend on the wavelength even with constant indices.
        let coated = sample.interfaces.iter().any(|i| !i.coating.is_empty());
        let sharing = cfg.path_sharing.unwrap_or(!dispersive && !coated);
        if sharing && dispersive {
            return Err(SimError::Config(
                "path sharing needs non-dispersive media: this sample's indices change with wavelength"
                    .into(),
            ));
        }
        if sharing && coated {
            return Err(SimError::Config(
                "path sharing needs wavelength-independent interfaces: this sample has coatings, whose coefficients change with wavelength"
                    .into(),
            ));
        }
        // Every wavelength the run evaluates must be inside every medium's range.
        let lambdas: Vec<f64> = match &cfg.wavelengths {
            Wavelengths::Bins(e) => e.clone(),
            Wavelengths::Monochromatic(v) => v.clone(),
        };
        for m in &sample.media {
            for &l in &lambdas {
                let (_, k) = m
                    .model
                    .eval(l)
                    .map_err(|e| SimError::Config(format!("medium '{}': {e}", m.name)))?;
                if m.scattering.is_some() && k != 0.0 {
                    return Err(SimError::Config(format!(
                        "medium '{}' scatters but its host index absorbs (k = {k} at {l} nm): a scattering medium's own index must be lossless; put the absorption in its particles or in absorption_per_um",
                        m.name
                    )));
                }
            }
        }
        // Particle media tabulated over the run's wavelengths (each whole nm between the
        // extremes; a Mie table refuses an absorbing host at any of them too).
        if scattering {
            let lo = lambdas.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = lambdas.iter().copied().fold(0.0, f64::max);
            scene.prepare_scattering(lo, hi)?;
        }
        let index_at = |l: f64| -> Vec<C64> {
            let mut v = Vec::new();
            indices_into(sample, l, &mut v);
            v
        };
        let nl = cfg.wavelengths.count();
        let lambda_max = cfg.wavelengths.max();
        let est = Estimator {
            // The diffraction method keeps the beamlet estimator's totals as the ray
            // method's, which its own are checked against.
            mode: if diffraction {
                Coherence::Beamlet
            } else {
                cfg.coherence
            },
            rho_nm: cfg.rho_nm,
            buckets: cfg.buckets,
            n_up: index_at(lambda_max)[scene.ambient].re,
            n_down: index_at(lambda_max)[scene.substrate].re,
            precision: cfg.precision,
            lambda_max_nm: lambda_max,
            reference: cfg.reference_estimator,
        };
        if let Some(&l) = lambdas
            .iter()
            .find(|&&l| index_at(l)[scene.ambient].im != 0.0)
        {
            return Err(SimError::Config(format!(
                "the medium above the sample ('{}') absorbs at {l} nm: reflectance is defined in a lossless ambient medium",
                sample.media[scene.ambient].name
            )));
        }
        if dispersive
            && (index_at(lambdas[0])[scene.ambient] != index_at(lambda_max)[scene.ambient])
        {
            return Err(SimError::Config(
                "the medium above the sample is dispersive; use a constant index for the ambient medium".into(),
            ));
        }
        if diffraction {
            // Every exit of a direction is kept (about 160 bytes each, two per tree as a
            // guide) and each wavelength's grid must fit.
            let bytes = 2.0 * 160.0 * cfg.rays as f64 * nl as f64;
            if bytes > DIFFRACTION_MAX_BYTES || cfg.rays > u64::from(u32::MAX) {
                return Err(SimError::Config(format!(
                    "--coherence diffraction keeps every exit of an incident direction in memory: {} trees x {nl} wavelengths needs about {:.1} GB (at most {:.0} GB): use fewer rays or fewer wavelengths per run (batch plans split a spectrum into units)",
                    cfg.rays,
                    bytes / 1e9,
                    DIFFRACTION_MAX_BYTES / 1e9
                )));
            }
            for &l in &lambdas {
                let n_sub = index_at(l)[scene.substrate];
                for n_out in [Some(est.n_up), (n_sub.im == 0.0).then_some(n_sub.re)]
                    .into_iter()
                    .flatten()
                {
                    let [mx, my] = diffraction::grid_cells(sample.tile_nm, l, n_out, est.n_up);
                    if mx.saturating_mul(my) > diffraction::MAX_GRID_CELLS {
                        return Err(SimError::Config(format!(
                            "--coherence diffraction needs a {mx} x {my} grid over the {:.0} x {:.0} nm tile at {l} nm (at most {} cells): use a smaller tile (a period, or a few correlation lengths); features this large against the wavelength are where rays alone hold",
                            sample.tile_nm[0],
                            sample.tile_nm[1],
                            diffraction::MAX_GRID_CELLS
                        )));
                    }
                }
            }
        }
        let settings = Settings {
            sample_name: sample.name.clone(),
            sample_hash: sample_hash(sample),
            theta_i_deg: cfg.theta_i_deg.clone(),
            phi_i_deg: cfg.phi_i_deg,
            wavelength_mode: match cfg.wavelengths {
                Wavelengths::Bins(_) => WavelengthMode::Bins,
                Wavelengths::Monochromatic(_) => WavelengthMode::Monochromatic,
            },
            wavelengths_nm: lambdas,
            coherence: cfg.coherence,
            coherence_radius_nm: cfg.rho_nm,
            cutoff: cfg.limits.cutoff,
            max_depth: cfg.limits.max_depth,
            theta_o_bins: cfg.buckets.theta_bins,
            phi_o_bins: cfg.buckets.phi_bins,
            phase_precision: cfg.precision,
            max_wraps: cfg.limits.max_wraps,
            max_segments: cfg.limits.max_segments,
            entry_points: if cfg.random_entry {
                EntryPoints::Uniform
            } else {
                EntryPoints::R2
            },
            path_sharing: sharing,
            tolerance: cfg.tolerance,
            max_rays: cfg.tolerance.map(|_| cfg.max_rays),
            first_direction: cfg.first_direction,
        };
        Ok(Run {
            sample,
            cfg,
            est,
            settings,
            sharing,
            tracing: if sharing {
                Tracing::Shared
            } else if cfg.wavelength_sharing && nl > 1 && !scattering {
                Tracing::Lanes
            } else {
                Tracing::PerWavelength
            },
            global: cfg.coherence == Coherence::Global,
            diffraction,
            lattice: [cfg.rays, 1],
            nl,
            lambda_max,
            fixed_indices: index_at(lambda_max),
            counters: Counters::default(),
            setup_seconds: 0.0,
            scene,
        })
    }

    fn worker(&self) -> Worker {
        Worker {
            stack: TraceStack::default(),
            trees: (0..self.nl).map(|_| Tree::default()).collect(),
            scratch: Scratch::default(),
            deps: Vec::new(),
            glob: Vec::new(),
            dense: Dense::new(self.nl, 2 * self.cfg.buckets.len(), self.global),
            indices: vec![Vec::new(); self.nl],
            lambdas: vec![0.0; self.nl],
        }
    }

    /// Stage 2: every tree of incident direction `di`, in batches (one for a fixed budget;
    /// until the tolerance is met for an adaptive one), each batch's blocks traced in
    /// parallel a chunk at a time and added to the cells in block order.
    fn direction(
        &self,
        di: usize,
        theta_deg: f64,
        cells: &mut [Cell],
        lost: Lost,
        progress: &(dyn Fn(u64) + Sync),
    ) -> Result<DirectionStats, SimError> {
        let (cfg, nl) = (self.cfg, self.nl);
        let wi = from_spherical(theta_deg.to_radians(), cfg.phi_i_deg.to_radians());
        let mut shift_rng = Rng::new(cfg.seed, 0x5817_0000 + cfg.first_direction + di as u64);
        let shift = [shift_rng.uniform(), shift_rng.uniform()];
        let adaptive = cfg.tolerance.is_some();
        // Batches are whole blocks, so where a run stops never changes the sums of the
        // batches before it.
        let batch = if adaptive {
            cfg.rays.div_ceil(BLOCK) * BLOCK
        } else {
            cfg.rays
        };
        let target = if adaptive {
            cfg.max_rays.max(batch)
        } else {
            cfg.rays
        };
        let mut start = 0u64;
        // The diffraction method's contributions per wavelength, in block order.
        let mut contribs: Vec<Vec<diffraction::Contribution>> = vec![Vec::new(); nl];
        loop {
            let end = (start + batch).min(target);
            let nblocks = (end - start).div_ceil(BLOCK);
            // Blocks are reduced a chunk at a time, each chunk in block order, so memory
            // does not grow with the ray count and the sums are those of one pass over all
            // blocks in order, whatever the chunk size or the thread count.
            let mut chunk_lo = 0;
            while chunk_lo < nblocks {
                if cfg
                    .cancel
                    .as_ref()
                    .is_some_and(|c| c.load(Ordering::Relaxed))
                {
                    // The caller gets SimError::Cancelled: these sums are never used.
                    return Ok(DirectionStats {
                        theta_i_deg: theta_deg,
                        rays: start,
                        achieved: None,
                        converged: false,
                    });
                }
                let chunk = (CHUNK_BLOCKS_PER_THREAD * rayon::current_num_threads() as u64)
                    .max(MIN_CHUNK_BLOCKS);
                let chunk_hi = (chunk_lo + chunk).min(nblocks);
                let blocks: Vec<Vec<BlockCell>> = (chunk_lo..chunk_hi)
                    .into_par_iter()
                    .map_init(
                        || self.worker(),
                        |w, b| {
                            let lo = start + b * BLOCK;
                            let hi = (lo + BLOCK).min(end);
                            let out = self.block(w, di, wi, shift, adaptive, lo..hi);
                            let n = self.counters.done.fetch_add(hi - lo, Ordering::Relaxed)
                                + (hi - lo);
                            progress(n);
                            out
                        },
                    )
                    .collect();
                // Combine blocks in block order: the sums do not depend on scheduling.
                for block in blocks {
                    for (j, bc) in block.into_iter().enumerate() {
                        add_block(&mut cells[di * nl + j], &bc);
                        contribs[j].extend(bc.diffraction);
                        let k = di * nl + j;
                        lost.limit_dropped[k] += bc.dropped_limit;
                        lost.escaped[k] += bc.escaped;
                        lost.limit_bound[k] += bc.limit_bound;
                        lost.created[k] += bc.created;
                        lost.limited[k] += bc.limited;
                    }
                }
                chunk_lo = chunk_hi;
            }
            start = end;
            let achieved = achieved_error(cells, di, nl, cfg.coherence);
            let converged = adaptive && achieved.is_some_and(|a| a <= cfg.tolerance.unwrap_or(0.0));
            if !adaptive || converged || start >= target {
                if self.diffraction {
                    self.diffract(
                        wi,
                        contribs,
                        &mut cells[di * nl..(di + 1) * nl],
                        &mut lost.diffraction[di * nl..(di + 1) * nl],
                    )?;
                }
                return Ok(DirectionStats {
                    theta_i_deg: theta_deg,
                    rays: start,
                    achieved,
                    converged,
                });
            }
        }
    }

    /// The diffraction method for one incident direction (towards the light `wi`): each
    /// wavelength's contributions transformed into Floquet orders (`diffraction::diffract`),
    /// which replace the cell's bucket sums and totals; the beamlet estimator's totals are
    /// kept in `out` for the energy check.
    fn diffract(
        &self,
        wi: DVec3,
        contribs: Vec<Vec<diffraction::Contribution>>,
        cells: &mut [Cell],
        out: &mut [DiffractionCell],
    ) -> Result<(), SimError> {
        let d = -wi;
        let results: Vec<Result<_, String>> = contribs
            .into_par_iter()
            .enumerate()
            .map(|(j, list)| {
                // Every tree of the bin took its centre (`block`).
                let lambda = self.settings.wavelength(j);
                let k = 2.0 * std::f64::consts::PI / lambda;
                let mut idx = Vec::new();
                indices_into(self.sample, lambda, &mut idx);
                let n_sub = idx[self.scene.substrate];
                let h = diffraction::Hemisphere {
                    tile_nm: self.sample.tile_nm,
                    lambda_nm: lambda,
                    n_out: self.est.n_up,
                    n_in: self.est.n_up,
                    k_in: [k * self.est.n_up * d.x, k * self.est.n_up * d.y],
                    cos_i: -d.z,
                    lattice: self.lattice,
                    rho_nm: self.cfg.rho_nm,
                    down: false,
                };
                let up = diffraction::diffract(&h, &list, &self.cfg.buckets)?;
                // An absorbing substrate transmits nothing (no exit leaves downwards).
                let down = if n_sub.im == 0.0 && list.iter().any(|c| c.down) {
                    let h = diffraction::Hemisphere {
                        n_out: n_sub.re,
                        down: true,
                        ..h
                    };
                    diffraction::diffract(&h, &list, &self.cfg.buckets)?
                } else {
                    diffraction::Pattern::default()
                };
                Ok((up, down))
            })
            .collect();
        for (j, res) in results.into_iter().enumerate() {
            let (up, down) = res.map_err(SimError::Config)?;
            let cell = &mut cells[j];
            let n = cell.trees as f64;
            let (r_ray, t_ray) = (cell.r_sum / n, cell.t_sum / n);
            cell.sum.fill(0.0);
            cell.sumsq.fill(0.0);
            cell.count.fill(0);
            // Energy is the ray field's: each hemisphere's orders are scaled to the ray
            // method's total there. The transform's own total (what it kept in propagating
            // orders) is reported and judged in `finish` (DIFFRACTION_RATIO_*).
            let scale = |rays: f64, total: f64| if total > 0.0 { rays / total } else { 0.0 };
            let (su, sd) = (scale(r_ray, up.total), scale(t_ray, down.total));
            for (&(kk, p), s) in up
                .per_key
                .iter()
                .map(|e| (e, su))
                .chain(down.per_key.iter().map(|e| (e, sd)))
            {
                let p = p * s;
                cell.sum[kk as usize] = p * n;
                cell.sumsq[kk as usize] = p * p * n;
                cell.count[kk as usize] = cell.trees;
            }
            out[j] = DiffractionCell {
                rays_r: r_ray,
                rays_t: t_ray,
                r: up.total,
                t: down.total,
                orders: up.orders + down.orders,
                fallback_tubes: up.fallback_tubes + down.fallback_tubes,
                flipped_tubes: up.flipped_tubes + down.flipped_tubes,
            };
        }
        Ok(())
    }

    /// The trees `trees` of direction `di` (towards the light `wi`): one `BlockCell` per
    /// wavelength. Tree `i` draws from its own random stream, so blocks are independent.
    fn block(
        &self,
        w: &mut Worker,
        di: usize,
        wi: DVec3,
        shift: [f64; 2],
        adaptive: bool,
        trees: std::ops::Range<u64>,
    ) -> Vec<BlockCell> {
        let (cfg, sample, est, c) = (self.cfg, self.sample, &self.est, &self.counters);
        let d = -wi;
        let e0 = launch_fields(d);
        let mut out: Vec<BlockCell> = (0..self.nl).map(|_| BlockCell::default()).collect();
        for i in trees {
            // A cancelled run stops within a tree, not a chunk of blocks (Ctrl-C in Python
            // took 20 s on a steep height map); its sums are never used.
            if cfg
                .cancel
                .as_ref()
                .is_some_and(|c| c.load(Ordering::Relaxed))
            {
                break;
            }
            let mut rng = Rng::new(cfg.seed, (cfg.first_direction + di as u64) << 40 | i);
            // Open samples launch in the interior, the guard band from every side.
            let g = sample.guard_nm.unwrap_or(0.0);
            let xy = if self.diffraction {
                lattice_point(i, self.lattice, shift, sample.tile_nm)
            } else if cfg.random_entry {
                [
                    rng.range(g, sample.tile_nm[0] - g),
                    rng.range(g, sample.tile_nm[1] - g),
                ]
            } else {
                entry_point(i, shift, sample.tile_nm, g)
            };
            let origin = DVec3::new(xy[0], xy[1], self.scene.z_top);
            // Stratified jitter: tree i takes stratum i of N in every bin.
            let lambda_of = |j: usize, u: f64| match &cfg.wavelengths {
                Wavelengths::Bins(e) => {
                    // Adaptive runs do not know N: a golden-ratio sequence
                    // (low-discrepancy for every prefix) replaces the strata.
                    // The diffraction method sums trees coherently, so they share one
                    // wavelength: the bin's centre.
                    let frac = if self.diffraction {
                        0.5
                    } else if adaptive {
                        (i as f64 * 0.618_033_988_749_894_9 + u).fract()
                    } else {
                        (i as f64 + u) / cfg.rays as f64
                    };
                    e[j] + (e[j + 1] - e[j]) * frac
                }
                Wavelengths::Monochromatic(v) => v[j],
            };
            let world_origin = origin + cfg.origin_nm;
            // The tree's jitter in bin j: the j-th draw of its stream (tracing draws
            // nothing from it).
            for j in 0..self.nl {
                w.lambdas[j] = lambda_of(j, rng.uniform());
            }
            let traced = |tree: &mut Tree, scratch: &mut Scratch| {
                for x in &mut tree.exits {
                    x.x += cfg.origin_nm;
                }
                est.prepare(tree, scratch);
                c.leaks.fetch_add(u64::from(tree.leaks), Ordering::Relaxed);
            };
            let count = |segments: u64| {
                c.segments.fetch_add(segments, Ordering::Relaxed);
                c.traces.fetch_add(1, Ordering::Relaxed);
            };
            // Random events' own stream (Russian roulette; particle media re-seed it per
            // wavelength below), so results do not depend on scheduling.
            let tree_stream = ((cfg.first_direction + di as u64) << 40) | i;
            w.stack.set_stream(
                cfg.seed ^ 0x5CA7_7E2E_D000_0000,
                tree_stream.wrapping_mul(0x1_0000) | 0xFFFF,
            );
            match self.tracing {
                Tracing::Shared => count(self.scene.trace(
                    origin,
                    d,
                    e0,
                    &self.fixed_indices,
                    self.lambda_max,
                    &cfg.limits,
                    &mut w.stack,
                    &mut w.trees[0],
                )),
                Tracing::Lanes => {
                    for (j, v) in w.indices.iter_mut().enumerate() {
                        indices_into(sample, w.lambdas[j], v);
                    }
                    let lanes: Vec<Lane> = (w.indices.iter().zip(&w.lambdas))
                        .map(|(v, &l)| Lane {
                            indices: v,
                            lambda_nm: l,
                        })
                        .collect();
                    count(self.scene.trace_lanes(
                        origin,
                        d,
                        e0,
                        &lanes,
                        &cfg.limits,
                        &mut w.stack,
                        &mut w.trees,
                    ));
                }
                Tracing::PerWavelength => {}
            }
            for (j, cell) in out.iter_mut().enumerate() {
                let lambda = w.lambdas[j];
                let tree = match self.tracing {
                    Tracing::Shared => {
                        if j == 0 {
                            traced(&mut w.trees[0], &mut w.scratch);
                        }
                        &w.trees[0]
                    }
                    Tracing::Lanes => {
                        traced(&mut w.trees[j], &mut w.scratch);
                        &w.trees[j]
                    }
                    Tracing::PerWavelength => {
                        indices_into(sample, lambda, &mut w.indices[0]);
                        // Volume scattering's own stream for this tree and wavelength.
                        w.stack.set_stream(
                            cfg.seed ^ 0x5CA7_7E2E_D000_0000,
                            tree_stream.wrapping_mul(0x1_0000).wrapping_add(j as u64),
                        );
                        count(self.scene.trace(
                            origin,
                            d,
                            e0,
                            &w.indices[0],
                            lambda,
                            &cfg.limits,
                            &mut w.stack,
                            &mut w.trees[0],
                        ));
                        traced(&mut w.trees[0], &mut w.scratch);
                        &w.trees[0]
                    }
                };
                w.deps.clear();
                w.glob.clear();
                let k = 2.0 * std::f64::consts::PI / lambda;
                let entry_phase = est.entry_phase(k, d, world_origin);
                est.deposit(
                    tree,
                    lambda,
                    entry_phase,
                    &mut w.scratch,
                    &mut w.deps,
                    &mut w.glob,
                );
                let (r, t) = w.dense.add_tree(j, &w.deps, &w.glob);
                if self.diffraction {
                    let k_in = k * est.n_up;
                    let k_in = [k_in * d.x, k_in * d.y];
                    for (slot, x) in tree.exits.iter().enumerate() {
                        cell.diffraction.push(diffraction::contribution(
                            x,
                            i as u32,
                            slot as u32,
                            k,
                            entry_phase,
                            k_in,
                        ));
                    }
                }
                let DroppedPower {
                    all: dropped,
                    limit: dropped_limit,
                    escaped,
                } = tree.dropped(lambda);
                cell.trees += 1;
                cell.r.0 += r;
                cell.r.1 += r * r;
                cell.t.0 += t;
                cell.t.1 += t * t;
                let absorbed = absorbed_power(tree, lambda, r, t, dropped, self.global);
                cell.absorbed += absorbed;
                // A tree that met particles or Russian roulette carries importance weights:
                // its R + T may exceed 1 while the mean over trees conserves energy, which
                // check_physical judges. Only deterministic ray series count as created.
                if tree.absorbing && !self.global && tree.random_events == 0 {
                    cell.created += (-absorbed).max(0.0);
                }
                cell.limited += tree.limited_power;
                cell.limit_bound += 2.0 * (dropped_limit * (r + t).max(0.0)).sqrt() + dropped_limit;
                cell.dropped += dropped;
                cell.dropped_limit += dropped_limit;
                cell.escaped += escaped;
                c.energy_faults
                    .fetch_add(u64::from(tree.energy_faults), Ordering::Relaxed);
            }
        }
        w.dense.drain(&mut out);
        out
    }

    /// Stage 3: the run's statistics and header; energy faults and impossible results are
    /// errors, never output.
    fn finish(
        self,
        cells: Vec<Cell>,
        lost: LostSums,
        directions: Vec<DirectionStats>,
        start_time: Instant,
    ) -> Result<(Accumulator, SimStats), SimError> {
        let (cfg, c) = (self.cfg, &self.counters);
        let faults = c.energy_faults.load(Ordering::Relaxed);
        if faults > 0 {
            return Err(SimError::Unphysical(format!(
                "sample '{}': {faults} interface events from a lossless medium did not conserve energy (|r|^2 + T != 1); this is a bug, please report it",
                self.sample.name
            )));
        }
        let stats = SimStats {
            trees: c.done.load(Ordering::Relaxed),
            traces: c.traces.load(Ordering::Relaxed),
            segments: c.segments.load(Ordering::Relaxed),
            leaks: c.leaks.load(Ordering::Relaxed),
            seconds: start_time.elapsed().as_secs_f64(),
            setup_seconds: self.setup_seconds,
            path_sharing: self.sharing,
            wavelength_sharing: self.tracing == Tracing::Lanes,
            directions,
            limit_dropped: lost.limit_dropped,
            escaped: lost.escaped,
            limit_bound: lost.limit_bound,
            created: lost.created,
            limited: lost.limited,
            diffraction: lost.diffraction,
            envelope_violations: self.scene.scatter_violations(),
        };
        let header = Header {
            settings: self.settings,
            seeds: vec![cfg.seed],
            // Adaptive runs: the most trees any direction used; each direction's own
            // count too.
            rays: stats
                .directions
                .iter()
                .map(|d| d.rays)
                .max()
                .unwrap_or(cfg.rays),
            rays_per_direction: stats.directions.iter().map(|d| d.rays).collect(),
            backend: self.scene.backend().name().into(),
            leaks: stats.leaks,
        };
        let acc = Accumulator { header, cells };
        if self.diffraction
            && let Some((k, d)) = stats
                .diffraction
                .iter()
                .enumerate()
                .filter(|(_, d)| d.rays_r + d.rays_t > 0.0)
                .find(|(_, d)| {
                    !(d.ratio() >= DIFFRACTION_RATIO_REFUSED
                        && d.ratio() <= 1.0 / DIFFRACTION_RATIO_REFUSED)
                })
        {
            let nl = self.nl;
            return Err(SimError::Unphysical(format!(
                "sample '{}', theta_i {} deg, wavelength {} nm: the diffraction transform holds {:.3} of the ray field's power in propagating orders (outside [{DIFFRACTION_RATIO_REFUSED}, {:.2}]): the rays sample the field too coarsely for it (raise --rays), or the sample has structure near or below the wavelength, where neither rays nor physical optics hold (use a rigorous solver: RCWA, FDTD)",
                self.sample.name,
                cfg.theta_i_deg.get(k / nl).copied().unwrap_or(f64::NAN),
                acc.header.settings.wavelength(k % nl),
                d.ratio(),
                1.0 / DIFFRACTION_RATIO_REFUSED
            )));
        }
        if !cfg.allow_unphysical {
            check_physical(&acc, &self.sample.name, Some(&stats.limit_dropped))?;
            let (created, cell) = stats.worst_created(&acc);
            if created > CREATED_REFUSED {
                let nl = acc.header.settings.wavelength_count().max(1);
                return Err(SimError::Unphysical(format!(
                    "sample '{}', theta_i {} deg, wavelength bin {}: {created:.3} of the launched power per tree came from ray series that created energy (more than {CREATED_REFUSED}): light crossed absorbing features thinner than their decay length (ridge tips at grazing light, sub-skin-depth wedges), where no ray model holds (docs/physics.md, \"Where the ray model stops\"). The result is impossible and was not written; use a rigorous solver for this geometry, or pass --allow-unphysical to write it anyway",
                    self.sample.name,
                    cfg.theta_i_deg.get(cell / nl).copied().unwrap_or(f64::NAN),
                    cell % nl + 1
                )));
            }
        }
        Ok((acc, stats))
    }
}

/// Every medium's complex index at `lambda_nm`, into `out` (reused: no allocation per
/// tree).
fn indices_into(sample: &Sample, lambda_nm: f64, out: &mut Vec<C64>) {
    out.clear();
    out.extend(sample.media.iter().map(|m| {
        let (n, k) = m
            .model
            .eval(lambda_nm)
            .expect("range checked in Run::prepare");
        C64::new(n, k)
    }));
}

/// Absorbed power of one tree at one wavelength: what entered absorbing media and did not
/// leave, `1 - R - T - dropped` with the tree's coherent totals (exact in the plane-wave
/// limit, where the coherent sum is the exact field; docs/design.md §3), or 0 when no power
/// entered an absorbing medium. Global mode has no per-tree coherent totals; there the
/// incoherent exit power stands in for `R + T`.
fn absorbed_power(tree: &Tree, lambda: f64, r: f64, t: f64, dropped: f64, global: bool) -> f64 {
    // A tree with random events (roulette, particle scattering) balances only on average:
    // its residual is kept even without absorption, so the column sums to 1 and averages
    // to the true absorption (0 for a lossless sample).
    if !tree.absorbing && tree.random_events == 0 {
        return 0.0;
    }
    let out = if global {
        tree.exit_power(lambda)
    } else {
        r + t
    };
    1.0 - out - dropped
}

/// Standard errors allowed before a result counts as impossible rather than noise.
const NOISE_SIGMAS: f64 = 5.0;
/// Rounding allowance on totals that are sums of many terms of order 1.
const ROUNDING: f64 = 1e-9;
/// Energy allowance of the finite-radius beamlet estimator (docs/design.md §4): its Gaussian
/// overlap weights interference partially, by design, so its reflected and transmitted
/// cross terms need not cancel exactly. Measured on the shipped samples (2,000 trees, 0-60
/// deg, 400-700 nm): at most 1.9e-3 (the seed's wavy film), 4.5e-5 on flat films, 0
/// elsewhere. The plane-wave limit (`rho = inf`) and the other estimators get none.
pub const BEAMLET_ENERGY_SLACK: f64 = 5e-3;
/// Mean power per tree cut by limits above which a result is refused as not converged (R
/// and T then uncertain by up to `2 sqrt(0.1) = 0.6`). Below it the cut power is reported
/// and allowed for: light guided sideways in a wavy film at 85 degrees loses 2.7e-2 to the
/// depth limit, multiply scattering paints 3e-3 to 5e-3; a meshed 5-pair mirror, whose
/// series diverges, 0.83.
pub const NOT_CONVERGED: f64 = 0.1;
/// Mean power per tree created by ray series that do not recombine
/// ([`SimStats::created`]) above which `simulate` warns: R and T are then uncertain by
/// about that much. On a flat or gently tilted absorbing film the series recombine and the
/// figure is zero to rounding; the shipped rough gold reaches 1.1e-3 only at 85 degrees and
/// 650 nm (ridge tips at grazing light).
pub const CREATED_WARN: f64 = 1e-3;
/// Mean power per tree created by ray series that do not recombine above which the result
/// is refused: a tenth of the light came out of a model that does not hold.
pub const CREATED_REFUSED: f64 = 0.1;

/// Refuses impossible and unconverged results (docs/design.md §4, "never clamp silently"):
/// non-finite totals, a cell that lost more than [`NOT_CONVERGED`] of its power to limits,
/// and in every cell
/// (incident direction, wavelength), a reflectance or transmittance above 1 or below 0, a
/// negative absorbed power or `R + T + dropped > 1` (energy created). (A single bucket
/// may end negative where a pair of one tree's exits straddles a bucket edge and their
/// cross term is split between the two: docs/design.md §4 has such buckets counted and reported,
/// which `goniospec reflectance` does, not refused.) Each allows rounding plus `NOISE_SIGMAS` standard errors of the
/// per-tree spread (Monte Carlo noise of the cross terms is legitimate; a systematic
/// excess is not), plus the largest coherent effect of the dropped amplitudes, `2 sqrt(D
/// (R + T)) + D` for the dropped power `D` (`|a + b|^2 - |a|^2 <= 2 |a| |b| + |b|^2`, and
/// Cauchy-Schwarz over trees; `limit_dropped`, per cell as in [`SimStats::limit_dropped`],
/// is the part cut by limits, for the convergence test), and for energy balances with a finite beamlet radius [`BEAMLET_ENERGY_SLACK`].
pub fn check_physical(
    acc: &Accumulator,
    sample_name: &str,
    limit_dropped: Option<&[f64]>,
) -> Result<(), SimError> {
    let s = &acc.header.settings;
    let mode = s.coherence_mode();
    let buckets = s.buckets();
    let nl = s.wavelength_count();
    // The diffraction method's totals are the beamlet estimator's on the same trees.
    let slack = if matches!(mode, Coherence::Beamlet | Coherence::Diffraction)
        && s.coherence_radius_nm.is_finite()
    {
        BEAMLET_ENERGY_SLACK
    } else {
        0.0
    };
    let partial = |slack: f64| {
        if slack > 0.0 {
            " (with a finite beamlet radius this can also be the estimator's partial coherence on steeply curved films, beyond its allowance: a smaller --coherence-radius-nm pairs fewer partial waves)"
        } else {
            ""
        }
    };
    for (i, theta) in s.theta_i_deg.iter().enumerate() {
        for j in 0..nl {
            let c = acc.cell(i, j);
            if c.trees == 0 {
                continue;
            }
            let n = c.trees as f64;
            let (r, t) = c.totals(mode, &buckets);
            let (a, d) = (c.absorbed / n, c.dropped / n);
            let se_r = c.r_stderr(mode).unwrap_or(0.0);
            let se_t = if mode == Coherence::Global || c.trees < 2 {
                0.0
            } else {
                crate::accumulate::stderr(c.t_sum, c.t_sumsq, c.trees)
            };
            // Every dropped amplitude, by the cutoff or a limit, can change the coherent
            // totals by up to the Cauchy-Schwarz bound; a cell that lost more than
            // NOT_CONVERGED to limits is refused outright below.
            let d_limit = limit_dropped.map_or(0.0, |l| l[i * nl + j] / n);
            let truncation = 2.0 * (d * (r + t).abs()).sqrt() + d;
            let tol = ROUNDING + NOISE_SIGMAS * (se_r + se_t) + truncation;
            let tol_energy = tol + slack;
            let hint = if d_limit > 1e-6 {
                format!(
                    " The ray series did not converge: {d_limit:.1e} of the power per tree was cut by --max-depth / --max-segments."
                )
            } else {
                String::new()
            };
            let what = if !(r.is_finite() && t.is_finite() && a.is_finite() && d.is_finite()) {
                Some(format!(
                    "a non-finite result (R {r}, T {t}, absorbed {a}, dropped {d}): a medium's index or the geometry is outside what the optics can represent"
                ))
            } else if d_limit > NOT_CONVERGED {
                Some(format!(
                    "the ray series did not converge: {d_limit:.1e} of the launched power per tree was cut by --max-depth / --max-segments, so R and T are uncertain by up to 2 sqrt({d_limit:.1e}) = {:.2}",
                    2.0 * d_limit.sqrt()
                ))
            } else if r > 1.0 + tol {
                Some(format!("R = {r:.9} > 1"))
            } else if r < -tol {
                Some(format!("R = {r:.3e} < 0"))
            } else if t < -tol {
                Some(format!("T = {t:.3e} < 0"))
            } else if t > 1.0 + tol {
                Some(format!("T = {t:.9} > 1"))
            } else if a < -tol_energy {
                Some(format!(
                    "absorbed power {a:.3e} < 0: R + T + dropped = {:.9} > 1, energy created{}",
                    r + t + d,
                    partial(slack)
                ))
            } else if r + t + d > 1.0 + tol_energy {
                Some(format!(
                    "R + T + dropped = {:.9} > 1, energy created{}",
                    r + t + d,
                    partial(slack)
                ))
            } else {
                None
            };
            if let Some(what) = what {
                return Err(SimError::Unphysical(format!(
                    "sample '{sample_name}', theta_i {theta} deg, phi_i {} deg, lambda {} nm: {what} \
                     (tolerance {tol:.1e}: rounding, {NOISE_SIGMAS} standard errors and the dropped \
                     power's coherent bound; energy balances also {slack:.0e} for partial coherence). The result is \
                     impossible and was not written.{hint} Likely causes: meshed thin layers whose ray \
                     series does not converge (high-contrast multilayers, absorbing layers thinner \
                     than their decay length): model them as a coating, a [stack] in its default \
                     mode or coating = [...] on the interface (docs/physics.md); or a bug. Pass \
                     --allow-unphysical to write it anyway for debugging.",
                    s.phi_i_deg,
                    s.wavelength(j),
                )));
            }
        }
    }
    Ok(())
}

/// Refuses a configuration no run can take (angles, counts, radii, limits), before any
/// work; [`simulate`] calls it first, and front ends that judge a run beforehand (the
/// validity warnings) call it before that.
pub fn validate(cfg: &SimConfig) -> Result<(), SimError> {
    let bad = |m: String| Err(SimError::Config(m));
    if cfg.theta_i_deg.is_empty() {
        return bad("no incident directions (--theta-i)".into());
    }
    if let Some(t) = cfg.theta_i_deg.iter().find(|t| !(0.0..90.0).contains(*t)) {
        return bad(format!("incident angle {t} deg is outside [0, 90)"));
    }
    if !cfg.phi_i_deg.is_finite() {
        return bad(format!("--phi-i must be finite, got {}", cfg.phi_i_deg));
    }
    if !cfg.origin_nm.is_finite() {
        return bad(format!(
            "the sample's origin must be finite, got {}",
            cfg.origin_nm
        ));
    }
    if cfg.rays == 0 {
        return bad("--rays must be at least 1".into());
    }
    if let Some(t) = cfg.tolerance
        && !(MIN_TOLERANCE..1.0).contains(&t)
    {
        return bad(format!(
            "--tolerance must be a relative standard error in [{MIN_TOLERANCE:e}, 1), got {t:e} (below 1e-6 needs some 1e12 trees per direction)"
        ));
    }
    if cfg.wavelengths.count() == 0 {
        return bad("no wavelengths".into());
    }
    let ls = match &cfg.wavelengths {
        Wavelengths::Bins(e) => e,
        Wavelengths::Monochromatic(v) => v,
    };
    if ls.iter().any(|l| !(l.is_finite() && *l > 0.0)) {
        return bad("wavelengths must be positive and finite".into());
    }
    if let Wavelengths::Bins(e) = &cfg.wavelengths
        && e.windows(2).any(|w| w[1] <= w[0])
    {
        return bad("wavelength bin edges must increase".into());
    }
    if cfg.rho_nm.is_nan() || cfg.rho_nm <= 0.0 {
        return bad(format!(
            "the coherence radius must be positive (or inf), got {}",
            cfg.rho_nm
        ));
    }
    if !(cfg.limits.cutoff >= 0.0 && cfg.limits.cutoff < 1.0) {
        return bad(format!(
            "the power cutoff must be in [0, 1), got {}",
            cfg.limits.cutoff
        ));
    }
    if cfg.buckets.theta_bins == 0 || cfg.buckets.phi_bins == 0 {
        return bad("bucket counts must be at least 1".into());
    }
    // Sizes are estimated before anything is allocated (checked arithmetic throughout).
    let buckets = u64::from(cfg.buckets.theta_bins).checked_mul(u64::from(cfg.buckets.phi_bins));
    if buckets.is_none_or(|b| b > MAX_BUCKETS) {
        return bad(format!(
            "--theta-o-bins {} x --phi-o-bins {} is more than {MAX_BUCKETS} buckets per hemisphere",
            cfg.buckets.theta_bins, cfg.buckets.phi_bins
        ));
    }
    // The accumulator: per (direction, wavelength) cell, two hemispheres of buckets with a
    // sum, a sum of squares and a count (24 bytes each).
    let bytes = buckets
        .and_then(|b| b.checked_mul(2 * 24))
        .and_then(|b| b.checked_mul(cfg.theta_i_deg.len() as u64))
        .and_then(|b| b.checked_mul(cfg.wavelengths.count() as u64));
    if bytes.is_none_or(|b| b > MAX_ACCUMULATOR_BYTES) {
        return bad(format!(
            "the accumulator would need more than {} GiB ({} incident angles x {} wavelengths x {} buckets): use fewer --theta-o-bins/--phi-o-bins, wavelengths or angles",
            MAX_ACCUMULATOR_BYTES >> 30,
            cfg.theta_i_deg.len(),
            cfg.wavelengths.count(),
            buckets.unwrap_or(u64::MAX)
        ));
    }
    if cfg.rays > MAX_RAYS || cfg.max_rays > MAX_RAYS {
        return bad(format!(
            "--rays / --max-rays above {MAX_RAYS:e} per direction would run for weeks; split the work into seeds and merge"
        ));
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
