//! What a run will trace, for a front end's progress bar (issue 71: bars read "124928 of
//! 3072" where the diffraction method traced its lattice, "78444 of 73728" where the run
//! raised its trees, and an adaptive run's total was its budget however early it stopped).
//!
//! A front end puts a [`ProgressPlan`] in [`super::SimConfig::progress_plan`] and reads its
//! total whenever the run reports trees done. The run keeps the total true: set when a try
//! is prepared (every direction's trees: the lattice's where the diffraction method traces
//! one, an adaptive direction's whole budget, none where the rigorous solver takes every
//! cell), lowered by what an adaptive direction left when it stops, and raised by each try
//! a raised run makes (`raise`), whose count of trees goes on from the tries before it.

use std::sync::atomic::{AtomicU64, Ordering};

use super::run::Run;

/// The trees a run will trace, over every direction and every try; and those of the tries
/// before the current one, which the run's progress reports count on from. Also the cells
/// the rigorous solver takes, which trace no tree (issue 70: a crossed tile spent 6 min 49 s
/// at "trees: 0 of 16"): their count as the run knows it and those solved.
#[derive(Debug, Default)]
pub struct ProgressPlan {
    total: AtomicU64,
    before: AtomicU64,
    cells: AtomicU64,
    cells_done: AtomicU64,
}

impl ProgressPlan {
    /// The trees the run will trace as it now knows it; never below the count reported.
    pub fn total(&self) -> u64 {
        self.total.load(Ordering::Relaxed)
    }

    /// The rigorous solver's cells: `(solved, to solve)`, the total as the run now knows it
    /// (auto's rigorous cells from the start, the cells that fall back to it as they do).
    pub fn cells(&self) -> (u64, u64) {
        (
            self.cells_done.load(Ordering::Relaxed),
            self.cells.load(Ordering::Relaxed),
        )
    }

    /// `n` more cells for the rigorous solver.
    pub(super) fn more_cells(&self, n: u64) {
        self.cells.fetch_add(n, Ordering::Relaxed);
    }

    /// One of the rigorous solver's cells is done (solved or given up).
    pub(super) fn cell_done(&self) {
        self.cells_done.fetch_add(1, Ordering::Relaxed);
    }

    /// The trees of the tries before this one.
    pub(super) fn before(&self) -> u64 {
        self.before.load(Ordering::Relaxed)
    }

    /// A try that traced `trees` is over and another follows.
    pub(super) fn next_try(&self, trees: u64) {
        self.before.fetch_add(trees, Ordering::Relaxed);
    }
}

impl Run<'_> {
    /// The trees direction `di` will trace at most: its lattice's or the asked count, an
    /// adaptive direction's budget (whole batches, as `Run::direction` runs them), none
    /// where the rigorous solver takes every cell.
    fn planned_trees(&self, di: usize) -> u64 {
        if self.rigorous_only(di) {
            return 0;
        }
        if self.cfg.adaptive() {
            // Batches grow by the measured error (`growth`); the last stops at the budget.
            self.cfg
                .max_rays
                .max(super::growth::first_batch(self.cfg.rays))
        } else {
            self.rays_of(di)
        }
    }

    /// Sets the plan's total for this try: the tries before it and every direction's
    /// trees ([`Run::planned_trees`]).
    pub(super) fn announce_plan(&self) {
        if let Some(p) = &self.cfg.progress_plan {
            let all: u64 = (0..self.cfg.theta_i_deg.len())
                .map(|di| self.planned_trees(di))
                .sum();
            p.total.store(p.before() + all, Ordering::Relaxed);
            // Each try solves its cells again: those of the tries before, and this one's.
            let cells = self.cell_rigorous.iter().filter(|&&r| r).count() as u64;
            p.cells.store(
                p.cells_done.load(Ordering::Relaxed) + cells,
                Ordering::Relaxed,
            );
        }
    }

    /// Direction `di` is done having traced `trees`: what it did not trace of its plan (an
    /// adaptive direction that met its goal early) comes off the total.
    pub(super) fn direction_traced(&self, di: usize, trees: u64) {
        if let Some(p) = &self.cfg.progress_plan {
            let unspent = self.planned_trees(di).saturating_sub(trees);
            p.total.fetch_sub(unspent, Ordering::Relaxed);
        }
    }
}
