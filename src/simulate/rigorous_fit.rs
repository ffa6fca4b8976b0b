//! Whether `--coherence auto` can give a cell the rigorous solver: the sample must be a
//! deterministic periodic tile it can slice, and the cell's eigenproblem within the budget
//! an auto run spends on one cell ([`AUTO_MAX_MODES`]); the sliced sample is built once, on
//! the first cell that asks.

use super::{SimConfig, SimError};
use crate::reference::rigorous::Effort;
use crate::reference::rigorous::Rigorous;
use crate::sample::Sample;

/// The most modes per slice (twice the harmonics) an auto run gives one cell: a 1-D
/// grating of 150 harmonics, whose cell of the default 24 slices and its check takes a few
/// seconds on one core (41 orders: 0.14 s, `bench rigorous`; the eigenproblem grows as the
/// cube). An explicit
/// `--coherence rigorous` may go to `reference::rigorous::Effort::MAX_MODES`.
pub const AUTO_MAX_MODES: usize = 300;

/// The most harmonics per axis `--orders` may ask for, and the most slices.
pub const MAX_ORDERS: usize = 300;
pub const MAX_SLICES: usize = 2000;

/// Why the rigorous solver cannot take `sample` under `cfg` at all (`None` where it can):
/// what `--coherence rigorous` refuses (`prepare`) and what keeps auto's cells from it.
pub fn rigorous_refused(sample: &Sample, cfg: &SimConfig) -> Option<&'static str> {
    if sample.guard_nm.is_some() {
        Some("its sides are open (a guard band), and the solver takes a periodic tile")
    } else if sample.media.iter().any(|m| m.scattering.is_some()) {
        Some("its particle media scatter with random phases")
    } else if cfg.adaptive() {
        Some(
            "--tolerance and --target-stderr stop on the trees' standard error, and the solver traces none (its accuracy is --rigorous-tolerance)",
        )
    } else {
        None
    }
}

/// Why the tile is not one period of the structure (`None` where it is): a sheet whose
/// boundary edges on the tile's sides have no partner on the opposite side, the defect
/// `goniospec check` reports as "does not tile" (`check::periodicity`, at its tolerance of
/// 1e-6 of the tile). The solver repeats the tile, and would solve a structure with a step
/// at every seam (issue 70: such a mesh was solved as a periodic sawtooth, exit 0).
pub fn untiled(sample: &Sample) -> Option<String> {
    let tol = 1e-6 * sample.tile_nm[0].max(sample.tile_nm[1]);
    sample
        .interfaces
        .iter()
        .enumerate()
        .filter(|(_, itf)| !itf.closed)
        .find_map(|(i, itf)| {
            let p = crate::check::periodicity(&itf.mesh, sample.tile_nm, tol);
            (p.unmatched > 0).then(|| {
                format!(
                    "interface {i} ({}) does not tile: {} boundary edges on the tile's sides have no partner on the opposite side (goniospec check lists it), and the solver repeats the tile",
                    itf.mesh_path.display(),
                    p.unmatched
                )
            })
        })
}

/// The rigorous solver as an auto run may use it: built on first use, its refusal kept.
pub struct RigorousFit<'a> {
    sample: &'a Sample,
    cfg: &'a SimConfig,
    solver: Option<Result<Rigorous, String>>,
}

impl<'a> RigorousFit<'a> {
    pub fn new(sample: &'a Sample, cfg: &'a SimConfig) -> Self {
        RigorousFit {
            sample,
            cfg,
            solver: None,
        }
    }

    /// Why the solver cannot take a cell at `lambda_nm` (`None` where it can).
    pub fn refusal(&mut self, lambda_nm: f64) -> Option<String> {
        let (sample, cfg) = (self.sample, self.cfg);
        if let Some(why) = rigorous_refused(sample, cfg) {
            return Some(why.into());
        }
        let solver = match self.solver.get_or_insert_with(|| match untiled(sample) {
            Some(why) => Err(why),
            None => Rigorous::new(sample, cfg.rigorous).map_err(|e| e.to_string()),
        }) {
            Ok(s) => s,
            Err(e) => return Some(e.clone()),
        };
        let modes = solver.modes_at(sample, lambda_nm);
        let max = crate::reference::rigorous::Effort::MAX_MODES;
        // Where an explicit run could take the cell, say so; beyond that, only the limit.
        let limit = if modes > max {
            format!("more than the solver takes ({max})")
        } else {
            format!(
                "more than the {AUTO_MAX_MODES} an auto run spends on a cell (--coherence rigorous takes up to {max})"
            )
        };
        (modes > AUTO_MAX_MODES).then(|| {
            format!(
                "it would need {modes} modes per slice over a period of {:.0} x {:.0} nm, {limit}",
                solver.fine.period_nm[0], solver.fine.period_nm[1],
            )
        })
    }

    /// The sliced sample, where it was built.
    pub fn into_solver(self) -> Option<Rigorous> {
        self.solver.and_then(Result::ok)
    }
}

/// Refuses effort no run can spend, and what the rigorous solver cannot take.
pub(super) fn validate_effort(cfg: &SimConfig) -> Result<(), SimError> {
    let e: Effort = cfg.rigorous;
    let bad = |key, message: String| Err(SimError::Setting { key, message });
    if e.orders.is_some_and(|m| m > MAX_ORDERS) {
        return bad(
            "orders",
            format!(
                "at most {MAX_ORDERS} harmonics per axis (got {:?})",
                e.orders
            ),
        );
    }
    if e.slices == 0 || e.slices > MAX_SLICES {
        return bad(
            "slices",
            format!("from 1 to {MAX_SLICES} slices (got {})", e.slices),
        );
    }
    if !(e.tolerance > 0.0 && e.tolerance < 1.0) {
        return bad(
            "rigorous_tolerance",
            format!("a difference in (0, 1) (got {})", e.tolerance),
        );
    }
    if !(cfg.rigorous_budget_s > 0.0 && cfg.rigorous_budget_s.is_finite()) {
        return bad(
            "rigorous_budget",
            format!(
                "a positive number of seconds (got {})",
                cfg.rigorous_budget_s
            ),
        );
    }
    Ok(())
}

/// The wall time, s, the rigorous cells `cells` (direction-major, as `Choice::rigorous`)
/// are estimated to take on the run's threads ([`Rigorous::cell_cost_s`]), and the most
/// one cell takes; refused past `--rigorous-budget` with the estimate, before any work.
pub fn check_budget(
    sample: &Sample,
    cfg: &SimConfig,
    solver: &Rigorous,
    cells: &[bool],
) -> Result<(f64, f64), SimError> {
    let nl = cfg.wavelengths.count();
    let centres = cfg.wavelengths.centres();
    let mut idx = Vec::new();
    let (mut total, mut most, mut count) = (0.0f64, 0.0f64, 0usize);
    for (j, &lambda) in centres.iter().enumerate() {
        sample.indices_into(lambda, &mut idx);
        for (di, &theta) in cfg.theta_i_deg.iter().enumerate() {
            if !cells[di * nl + j] {
                continue;
            }
            let wi = crate::geom::from_spherical(theta.to_radians(), cfg.phi_of(di).to_radians());
            let c = solver.cell_cost_s(&idx, lambda, -wi);
            total += c;
            most = most.max(c);
            count += 1;
        }
    }
    let threads = rayon::current_num_threads().max(1) as f64;
    let wall = total / threads.min(count.max(1) as f64);
    if wall > cfg.rigorous_budget_s {
        return Err(SimError::Config(format!(
            "the rigorous solver's {count} cells are estimated to take {wall:.0} s on {threads} threads (up to {most:.2} s a cell, from their harmonics and slices), past --rigorous-budget {} s: give fewer angles or wavelengths (or shard the run with batch), lower --orders or --slices where the check allows, or raise --rigorous-budget",
            cfg.rigorous_budget_s
        )));
    }
    Ok((wall, most))
}
