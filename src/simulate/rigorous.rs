//! The rigorous solver's cells (`--coherence rigorous`, or the cells `--coherence auto`
//! gives it): no trees; each (incident direction, wavelength) cell solved by the Fourier
//! modal method on the sample's sliced tile (`reference::rigorous`), checked for
//! convergence, and its propagating orders written into the cell's buckets as the
//! diffraction method writes its orders (spread by the illumination's partial coherence,
//! `accumulate::diffraction::pattern_of_orders`).
//!
//! A rigorous cell holds its one solution as one tree: its sums are the efficiencies, its
//! sums of squares their squares (no spread: a standard error of 0, and `fraction_stderr`
//! says none is defined), R and T the solver's, and the absorbed power `1 - R - T`. A
//! direction whose every cell is rigorous traces nothing and records one tree.

use rayon::prelude::*;

use super::SimError;
use super::run::Run;
use crate::accumulate::Cell;
use crate::accumulate::diffraction::{self, Pattern};
use crate::geom::from_spherical;
use crate::reference::rigorous::{Converged, RigorousError};

impl Run<'_> {
    /// Whether cell (`di`, `j`) takes the rigorous solver.
    pub(super) fn cell_takes_rigorous(&self, di: usize, j: usize) -> bool {
        self.cell_rigorous[di * self.nl + j]
    }

    /// Whether direction `di` traces no tree: `--coherence rigorous`. (An auto run traces
    /// its rigorous cells' rays too, which a cell the solver cannot converge keeps, unless
    /// every cell of the direction is the solver's and converges: [`Self::solved_whole`].)
    pub(super) fn rigorous_only(&self, di: usize) -> bool {
        self.cfg.coherence == crate::accumulate::Coherence::Rigorous
            && (0..self.nl).all(|j| self.cell_takes_rigorous(di, j))
    }

    /// Solves direction `di`'s rigorous cells (in parallel over wavelengths; each cell on
    /// its own, so the bytes do not depend on the thread count) and writes them into
    /// `cells` (the run's, direction-major); returns the cells written. A cell the solver
    /// cannot answer refuses an explicit run; an auto run keeps that cell's rays and says
    /// why (`rigorous_notes`). An auto run also gives the solver, where it has one and the
    /// cell fits `AUTO_MAX_MODES`, the cells whose diffraction transform could not hold the
    /// ray field or held a share it warns about (`fell_back`, per cell of the direction),
    /// rather than leaving them rays or an uncertain transform.
    ///
    /// `solved`: the direction's cells already solved before its trace
    /// ([`Self::solved_whole`]), written as they are.
    pub(super) fn solve_rigorous(
        &self,
        di: usize,
        theta_deg: f64,
        cells: &mut [Cell],
        fell_back: &[bool],
        solved: Option<Vec<Result<Solved, RigorousError>>>,
        progress: &(dyn Fn(u64) + Sync),
    ) -> Result<Vec<usize>, SimError> {
        let Some(solver) = &self.rigorous else {
            return Ok(Vec::new());
        };
        let explicit = self.cfg.coherence == crate::accumulate::Coherence::Rigorous;
        let takes = |j: usize| {
            self.cell_takes_rigorous(di, j)
                || (fell_back.get(j).copied().unwrap_or(false)
                    && solver.modes_at(self.sample, self.settings.wavelength(j))
                        <= super::rigorous_fit::AUTO_MAX_MODES)
        };
        let nl = self.nl;
        if let Some(solved) = solved {
            // Every cell the solver's (`solved_whole`): none fell back from the diffraction
            // method, and each was solved once.
            return self.write_solved(di, cells, solved, explicit);
        }
        // Progress counts cells (no tree is traced): the cells that fell back to the
        // solver join the plan's count, and each cell done reports.
        if let Some(p) = self.cfg.progress_plan.as_deref() {
            p.more_cells(
                (0..nl)
                    .filter(|&j| takes(j) && !self.cell_takes_rigorous(di, j))
                    .count() as u64,
            );
        }
        let solved = self.solve_cells(solver, di, theta_deg, &takes, progress);
        self.write_solved(di, cells, solved, explicit)
    }

    /// Under auto, a direction whose every cell the choice gave the solver is solved before
    /// any tree is traced (the rays an auto run traces are the fallback of a cell that does
    /// not converge): where every cell converges it is written and nothing is traced
    /// ([`Whole::Written`]); where one does not, nothing is written, and the direction is
    /// traced and its solved cells are written after ([`Whole::Unconverged`], for
    /// [`Self::solve_rigorous`]: a cell's answer depends on its light alone, so it is the
    /// same bytes as one solved after the trace).
    pub(super) fn solved_whole(
        &self,
        di: usize,
        theta_deg: f64,
        cells: &mut [Cell],
        progress: &(dyn Fn(u64) + Sync),
    ) -> Result<Whole, SimError> {
        let Some(solver) = &self.rigorous else {
            return Ok(Whole::NotTaken);
        };
        if self.cfg.coherence != crate::accumulate::Coherence::Auto
            || !(0..self.nl).all(|j| self.cell_takes_rigorous(di, j))
        {
            return Ok(Whole::NotTaken);
        }
        let solved = self.solve_cells(solver, di, theta_deg, &|_| true, progress);
        if solved.iter().any(Result::is_err) {
            return Ok(Whole::Unconverged(solved));
        }
        self.write_solved(di, cells, solved, false)?;
        Ok(Whole::Written)
    }

    /// Solves the cells of direction `di` that `takes` names (in parallel over wavelengths;
    /// each cell on its own, so the bytes do not depend on the thread count), reporting
    /// each to the progress plan; writes nothing.
    fn solve_cells(
        &self,
        solver: &crate::reference::rigorous::Rigorous,
        di: usize,
        theta_deg: f64,
        takes: &(dyn Fn(usize) -> bool + Sync),
        progress: &(dyn Fn(u64) + Sync),
    ) -> Vec<Result<Solved, RigorousError>> {
        let wi = from_spherical(theta_deg.to_radians(), self.cfg.phi_of(di).to_radians());
        let d = -wi;
        let nl = self.nl;
        let plan = self.cfg.progress_plan.as_deref();
        let done = || {
            if let Some(p) = plan {
                p.cell_done();
                progress(
                    self.counters
                        .done
                        .load(std::sync::atomic::Ordering::Relaxed),
                );
            }
        };
        (0..nl)
            .into_par_iter()
            .map(|j| -> Result<Solved, RigorousError> {
                if !takes(j) {
                    return Ok(None);
                }
                let start = std::time::Instant::now();
                let lambda = self.settings.wavelength(j);
                let mut idx = Vec::new();
                self.sample.indices_into(lambda, &mut idx);
                let estimate = solver.cell_cost_s(&idx, lambda, d);
                let c = solver.solve(&idx, lambda, d, theta_deg);
                done();
                let c = c?;
                let n_up = idx[solver.fine.above].re;
                let n_down = idx[solver.fine.below];
                let spread = |up: bool, n: f64| {
                    let orders = c.solution.orders.iter().filter(|o| o.up == up);
                    diffraction::pattern_of_orders(
                        orders.map(|o| (o.dir, o.jones)),
                        &self.cfg.buckets,
                        2.0 * std::f64::consts::PI / lambda * n,
                        self.cfg.rho_nm,
                        !up,
                        self.cfg.mueller,
                    )
                };
                let up = spread(true, n_up);
                let down = if n_down.im == 0.0 {
                    spread(false, n_down.re)
                } else {
                    Pattern::default()
                };
                Ok(Some((c, up, down, start.elapsed().as_secs_f64(), estimate)))
            })
            .collect()
    }

    /// Writes the solved cells of direction `di` into `cells` and keeps their figures; a
    /// cell the solver could not answer refuses an explicit run, and an auto run keeps
    /// that cell's method and says why. Returns the cells written.
    fn write_solved(
        &self,
        di: usize,
        cells: &mut [Cell],
        solved: Vec<Result<Solved, RigorousError>>,
        explicit: bool,
    ) -> Result<Vec<usize>, SimError> {
        let nl = self.nl;
        let mut figures = self.rigorous_cells.lock().expect("not poisoned");
        let mut written = Vec::new();
        for (j, s) in solved.into_iter().enumerate() {
            let s = match s {
                Ok(s) => s,
                Err(e) if explicit => {
                    return Err(SimError::Config(format!(
                        "sample '{}': {e}",
                        self.sample.name
                    )));
                }
                Err(e) => {
                    let mut notes = self.rigorous_notes.lock().expect("not poisoned");
                    // Rays, or a diffraction cell's transform the solver was to replace.
                    notes.push((
                        di,
                        format!(
                            "{e}; that cell kept the result of the method it had (goniospec info lists it)"
                        ),
                    ));
                    continue;
                }
            };
            if let Some((c, up, down, seconds, estimate_s)) = s {
                written.push(di * nl + j);
                write_cell(&mut cells[di * nl + j], &c, &up, &down)?;
                figures[di * nl + j] = Some(super::RigorousCell {
                    harmonics: c.harmonics,
                    slices: c.slices,
                    difference: c.difference,
                    seconds,
                    estimate_s,
                    rayleigh: c.rayleigh_nm.is_some(),
                });
            }
        }
        Ok(written)
    }
}

/// One cell's solution, its spread orders up and down, its time and its estimate, s.
pub(super) type Solved = Option<(Converged, Pattern, Pattern, f64, f64)>;

/// What [`Run::solved_whole`] did with a direction.
pub(super) enum Whole {
    /// Not every cell is the solver's under auto: nothing done.
    NotTaken,
    /// Every cell converged and is written: nothing to trace.
    Written,
    /// A cell did not converge: the cells as solved, to write after the trace.
    Unconverged(Vec<Result<Solved, RigorousError>>),
}

/// How far above 1 a rigorous solution's `R + T` may be from rounding alone. The solver's
/// eigen-solution and S-matrix products lose digits in the evanescent orders: lossless
/// gratings lit off their plane of periodicity (conical mounts, where TE and TM couple and
/// the problem doubles) balance to 3.4e-9 (the ZnS hologram at 45 deg azimuth, 23
/// harmonics), classical mounts to 1e-12. A real error in the formulation is far larger.
const ENERGY_ROUNDING: f64 = 1e-7;

/// A cell's sums from one rigorous solution (see the module's documentation); refuses an
/// impossible one (R or T outside [0, 1], or R + T above 1 beyond [`ENERGY_ROUNDING`]).
fn write_cell(
    cell: &mut Cell,
    c: &Converged,
    up: &Pattern,
    down: &Pattern,
) -> Result<(), SimError> {
    let s = &c.solution;
    let r = 0.5 * (s.r[0] + s.r[1]);
    let t = 0.5 * (s.t[0] + s.t[1]);
    let a = 1.0 - r - t;
    if !(r.is_finite() && t.is_finite()) || r < 0.0 || t < 0.0 || a < -ENERGY_ROUNDING {
        return Err(SimError::Unphysical(format!(
            "the rigorous solver gave R = {r} and T = {t} (R + T = {}): impossible, so not written; this is a bug, please report it with the sample",
            r + t
        )));
    }
    cell.trees = 1;
    cell.sum.fill(0.0);
    cell.sumsq.fill(0.0);
    cell.count.fill(0);
    cell.var.clear();
    (cell.r_sum, cell.r_sumsq, cell.r_var) = (r, r * r, 0.0);
    (cell.t_sum, cell.t_sumsq, cell.t_var) = (t, t * t, 0.0);
    cell.absorbed = a.max(0.0);
    cell.dropped = 0.0;
    for &(kk, p) in up.per_key.iter().chain(&down.per_key) {
        cell.sum[kk as usize] = p;
        cell.sumsq[kk as usize] = p * p;
        cell.count[kk as usize] = 1;
    }
    if !cell.mueller.is_empty() {
        cell.mueller.fill([0.0; 16]);
        cell.mueller_sq.fill([0.0; 16]);
        let keys = up.per_key.iter().chain(&down.per_key).map(|e| e.0);
        for (kk, m) in keys.zip(up.per_key_mueller.iter().chain(&down.per_key_mueller)) {
            cell.mueller[kk as usize] = *m;
            cell.mueller_sq[kk as usize] = m.map(|x| x * x);
        }
    }
    Ok(())
}
