//! The virtual goniospectrometer run: launches stratified ray trees over the tile for each
//! incident direction, traces them (sharing geometry across wavelengths where no medium is
//! dispersive), and accumulates them with the estimator into a `.gsa` accumulator.
//!
//! Determinism: trees are processed in fixed blocks whose sums are combined in block
//! order, and every random number comes from a stream keyed by (seed, direction, tree), so
//! the output bytes do not depend on the thread count.

use std::sync::atomic::Ordering;
use std::time::Instant;

use crate::accumulate::file::Accumulator;
use crate::accumulate::{Cell, Coherence};
use crate::sample::Sample;
use crate::trace::SceneError;

/// Trees per block: the unit of parallel work and of deterministic summation.
const BLOCK: u64 = 64;
/// Blocks in flight at once per worker thread (at least `MIN_CHUNK_BLOCKS` in all): their
/// sums are the only memory that grows with the work, so peak memory depends on the thread
/// count but not on the ray count. The chunking never changes the results.
const CHUNK_BLOCKS_PER_THREAD: u64 = 4;
const MIN_CHUNK_BLOCKS: u64 = 16;

pub use crate::spectrum::Wavelengths;

pub mod auto;
mod block;
mod diffract;
pub mod directions;
mod groups;
mod growth;
mod hash;
mod launch;
mod lost;
mod partial;
mod physical;
mod prepare;
mod progress;
mod raise;
mod rigorous;
mod rigorous_fit;
mod run;
mod settings;
mod stats;
mod values;
mod warnings;

pub use groups::ERROR_GROUPS;
pub use hash::sample_hash;
pub use launch::diffraction_lattice;
use lost::LostSums;
pub use physical::*;
pub use progress::ProgressPlan;
use run::Run;
pub use settings::*;
pub use stats::*;
pub use values::*;
pub use warnings::run_warnings;

/// What can stop a simulation.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[error("{0}")]
    Config(String),
    /// A setting ([`SimSettings`]) outside what a run can take: `key` is its name as in
    /// TOML and Python (`theta_o_bins`; the CLI's flag is `--theta-o-bins`).
    #[error("{key}: {message}")]
    Setting { key: &'static str, message: String },
    /// An impossible result (R > 1, negative power, energy created): never written.
    #[error("{0}")]
    Unphysical(String),
    /// Stopped through `SimConfig::cancel`.
    #[error("the simulation was cancelled")]
    Cancelled,
    /// A direction failed after others had finished: `kept` is the result of the
    /// finished directions (a contiguous run of the asked angles, checked as a whole run's),
    /// which a front end writes beside the output so that no finished work is lost.
    #[error("{cause}")]
    Partial {
        cause: Box<SimError>,
        kept: Box<(Accumulator, SimStats)>,
    },
}

/// Everything [`simulate`] refuses before it traces, without tracing: the settings, the
/// methods the sample cannot take, the media's ranges, the ambient medium, the diffraction
/// method's memory (what [`Run::prepare`] checks; it builds the sample's scene to do so).
/// `batch plan` runs it for every material, so a plan refuses what its units would.
pub fn preflight(sample: &Sample, cfg: &SimConfig) -> Result<(), SimError> {
    validate(cfg)?;
    Run::prepare(sample, &traced_config(sample, cfg)).map(|_| ())
}

/// The configuration a run traces: the diffraction method launches on a lattice
/// (`diffraction_lattice`), so it traces that lattice's `nx * ny` trees per direction (an
/// auto run does so in the directions that have a diffraction cell: `Run::rays_of`).
fn traced_config<'a>(sample: &Sample, cfg: &'a SimConfig) -> std::borrow::Cow<'a, SimConfig> {
    if cfg.coherence == Coherence::Diffraction {
        let [nx, ny] = diffraction_lattice(cfg.rays, sample.tile_nm);
        std::borrow::Cow::Owned(SimConfig {
            rays: nx * ny,
            ..cfg.clone()
        })
    } else {
        std::borrow::Cow::Borrowed(cfg)
    }
}

/// Runs the simulation. `progress` receives the number of trees finished so far (from 0
/// again where the diffraction method raises its trees).
///
/// Three stages: [`Run::prepare`] (scene, media, estimator, the header's settings),
/// [`Run::direction`] for every incident direction (blocks of trees traced in parallel and
/// reduced in block order), and [`Run::finish`] (statistics, header, and the refusal of
/// impossible results). Where the diffraction method's transform cannot hold the rays'
/// power at the trees asked, the run raises them within `max_rays` while that helps
/// ([`raise`]).
pub fn simulate(
    sample: &Sample,
    cfg: &SimConfig,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<(Accumulator, SimStats), SimError> {
    raise::simulate_raising(sample, cfg, progress)
}

/// One run at `cfg`'s trees ([`simulate`]); where the diffraction method's transform could
/// not hold the rays' power and that refused it, the cell is put in `unheld`. `pilot`: an
/// auto run stops likewise where a cell took rays for it, instead of going on (`raise`).
fn run_once(
    sample: &Sample,
    cfg: &SimConfig,
    progress: &(dyn Fn(u64) + Sync),
    unheld: &mut Option<raise::Unheld>,
    pilot: bool,
) -> Result<(Accumulator, SimStats), SimError> {
    validate(cfg)?;
    let asked = cfg.rays;
    let lattice = diffraction_lattice(cfg.rays, sample.tile_nm);
    let traced = traced_config(sample, cfg);
    let cfg = traced.as_ref();
    let start_time = Instant::now();
    let mut run = Run::prepare(sample, cfg)?;
    run.lattice = lattice;
    run.pilot = pilot && cfg.coherence == Coherence::Auto;
    run.rays_asked = asked;
    run.announce_plan();
    run.setup_seconds = start_time.elapsed().as_secs_f64();
    let mut cells: Vec<Cell> = (0..cfg.theta_i_deg.len() * run.nl)
        .map(|_| {
            let c = Cell::new(&cfg.buckets, run.global);
            if cfg.mueller { c.with_mueller() } else { c }
        })
        .collect();
    let mut sums = LostSums::new(cells.len());
    // Every direction draws its own random streams and fills its own cells, so the order
    // they are traced in changes no byte. The diffraction method traces the most oblique
    // first: it is where the rays sample the field most coarsely, and a direction its
    // transform cannot hold is refused as soon as it is done (`diffraction_refusal`); so
    // is an auto run that may raise its trees (`pilot`) where a cell took rays for it.
    let mut order: Vec<usize> = (0..cfg.theta_i_deg.len()).collect();
    if cfg.coherence == Coherence::Diffraction || run.pilot {
        order.sort_by(|&a, &b| cfg.theta_i_deg[b].total_cmp(&cfg.theta_i_deg[a]));
    }
    let mut done: Vec<Option<DirectionStats>> = (0..order.len()).map(|_| None).collect();
    for di in order {
        let c = &run.counters;
        let before = (
            c.segments.load(Ordering::Relaxed),
            c.leaks.load(Ordering::Relaxed),
            run.scene.scatter_violations(),
        );
        let mut whole = false;
        let mut presolved = None;
        let traced = if cfg.fail_direction == Some(di) {
            Err(SimError::Unphysical(format!(
                "direction {di} failed as the test asked (SimConfig::fail_direction)"
            )))
        } else if run.rigorous_only(di) {
            // Nothing to trace: the cells' one solution each (`rigorous`).
            run.solve_rigorous(di, cfg.theta_i_deg[di], &mut cells, &[], None, progress)
                .map(|_| DirectionStats::untraced(cfg.theta_i_deg[di]))
        } else if let Some(w) =
            match run.solved_whole(di, cfg.theta_i_deg[di], &mut cells, progress) {
                Ok(rigorous::Whole::Written) => Some(Ok(())),
                Ok(rigorous::Whole::NotTaken) => None,
                Ok(rigorous::Whole::Unconverged(solved)) => {
                    presolved = Some(solved);
                    None
                }
                Err(e) => Some(Err(e)),
            }
        {
            // Auto: every cell the solver's and converged, nothing traced.
            whole = w.is_ok();
            w.map(|()| DirectionStats::untraced(cfg.theta_i_deg[di]))
        } else {
            run.direction(di, cfg.theta_i_deg[di], &mut cells, sums.lost(), progress)
                .and_then(|d| {
                    // What the rays lost or could not trust in a rigorous cell, and what
                    // the diffraction method had to say of it, is not the cell's.
                    // Diffraction cells whose transform fell back to rays, or held a share
                    // it warns about: the rigorous solver's where it fits.
                    let warned = |c: &DiffractionCell| {
                        c.orders > 0
                            && !(DIFFRACTION_RATIO_WARN..=1.0 / DIFFRACTION_RATIO_WARN)
                                .contains(&c.ratio())
                    };
                    let fell: Vec<bool> = (sums.diffraction[di * run.nl..(di + 1) * run.nl].iter())
                        .map(|c| c.fell_back || warned(c))
                        .collect();
                    for k in run.solve_rigorous(
                        di,
                        cfg.theta_i_deg[di],
                        &mut cells,
                        &fell,
                        presolved,
                        progress,
                    )? {
                        sums.clear(k);
                    }
                    Ok(d)
                })
        };
        let failed = match traced {
            Ok(mut d) => {
                run.direction_traced(di, if whole { 0 } else { d.rays });
                d.segments = c.segments.load(Ordering::Relaxed) - before.0;
                d.leaks = c.leaks.load(Ordering::Relaxed) - before.1;
                d.envelope_violations = run.scene.scatter_violations() - before.2;
                done[di] = Some(d);
                *unheld = run.unheld(&sums.diffraction, di * run.nl..(di + 1) * run.nl);
                unheld.as_ref().map(|u| {
                    done[di] = None;
                    run.diffraction_refusal(u)
                })
            }
            Err(e) => Some(e),
        };
        if let Some(cause) = failed {
            return Err(partial::keep_finished(
                run, cfg, cause, cells, sums, done, start_time,
            ));
        }
    }
    let directions: Vec<DirectionStats> = done
        .into_iter()
        .map(|d| d.expect("every direction was traced"))
        .collect();
    if cfg
        .cancel
        .as_ref()
        .is_some_and(|c| c.load(Ordering::Relaxed))
    {
        return Err(SimError::Cancelled);
    }
    let lost = sums;
    for (di, n) in run.rigorous_notes.lock().expect("not poisoned").iter() {
        run.auto_direction_notes[*di].push(n.clone());
    }
    let notes = std::mem::take(&mut run.auto_direction_notes);
    let sheets = std::mem::take(&mut run.sheets);
    let (mut acc, stats) = run.finish(cells, lost, directions, start_time)?;
    acc.header.warnings = warnings::stored_warnings(sample, cfg, &acc, &stats, &notes, &sheets);
    Ok((acc, stats))
}
