//! Whether `--coherence auto` can give a cell the rigorous solver: the sample must be a
//! deterministic periodic tile it can slice, and the cell's eigenproblem within the budget
//! an auto run spends on one cell ([`AUTO_MAX_MODES`]); the sliced sample is built once, on
//! the first cell that asks.

use super::SimConfig;
use crate::reference::rigorous::Rigorous;
use crate::sample::Sample;

/// The most modes per slice (twice the harmonics) an auto run gives one cell: a 1-D
/// grating of 150 harmonics, whose cell of the default 24 slices and its check takes a few
/// seconds on one core (41 orders: 0.14 s, `bench rigorous`; the eigenproblem grows as the
/// cube). An explicit
/// `--coherence rigorous` may go to `reference::rigorous::Effort::MAX_MODES`.
pub const AUTO_MAX_MODES: usize = 300;

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
