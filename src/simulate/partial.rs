//! What a run keeps when a direction fails after others finished (issue 48: the diffraction
//! method's refusal came after minutes and took every finished angle with it).
//!
//! Every direction draws its own random streams, numbered by its place in the run
//! (`SimConfig::first_direction` plus its index), and fills its own cells, so a contiguous
//! run of finished directions is exactly what a run of those angles alone would have given
//! (the batch units rest on the same property). That run is finished as a whole run is:
//! the same statistics, header and refusals of impossible results.

use std::time::Instant;

use super::lost::LostSums;
use super::run::Run;
use super::{DirectionStats, SimConfig, SimError, warnings};
use crate::accumulate::Cell;

/// The longest contiguous run of finished directions (`done[i]` set), as `a..b`; `None`
/// where none finished.
pub(super) fn finished_run(done: &[Option<DirectionStats>]) -> Option<std::ops::Range<usize>> {
    let mut best: Option<std::ops::Range<usize>> = None;
    let mut start = None;
    for i in 0..=done.len() {
        match (done.get(i).is_some_and(Option::is_some), start) {
            (true, None) => start = Some(i),
            (false, Some(a)) => {
                if best.as_ref().is_none_or(|b| i - a > b.len()) {
                    best = Some(a..i);
                }
                start = None;
            }
            _ => {}
        }
    }
    best
}

/// `cause` with the result of the longest contiguous run of finished directions
/// ([`SimError::Partial`]), or `cause` alone where none finished, the run was cancelled, or
/// the finished directions are themselves refused.
pub(super) fn keep_finished(
    run: Run<'_>,
    cfg: &SimConfig,
    cause: SimError,
    mut cells: Vec<Cell>,
    lost: LostSums,
    mut done: Vec<Option<DirectionStats>>,
    start_time: Instant,
) -> SimError {
    if matches!(cause, SimError::Cancelled) {
        return cause;
    }
    let Some(dirs) = finished_run(&done) else {
        return cause;
    };
    let nl = run.nl;
    let span = dirs.start * nl..dirs.end * nl;
    let part = SimConfig {
        theta_i_deg: cfg.theta_i_deg[dirs.clone()].to_vec(),
        phi_each_deg: cfg
            .phi_each_deg
            .get(dirs.clone())
            .map(<[f64]>::to_vec)
            .unwrap_or_default(),
        first_direction: cfg.first_direction + dirs.start as u64,
        fail_direction: None,
        ..cfg.clone()
    };
    // The run's configuration is now the part's (a shorter borrow of the same run).
    let mut run: Run<'_> = run;
    run.cfg = &part;
    let sample = run.sample;
    run.settings.theta_i_deg = part.theta_i_deg.clone();
    run.settings.phi_i_each_deg = part.phi_each_deg.clone();
    run.settings.first_direction = part.first_direction;
    run.cell_diffraction = run.cell_diffraction[span.clone()].to_vec();
    let notes = run.auto_direction_notes[dirs.clone()].to_vec();
    let sheets = std::mem::take(&mut run.sheets);
    let cells: Vec<Cell> = cells.drain(span.clone()).collect();
    let lost = lost.span(span);
    let directions: Vec<DirectionStats> = done[dirs]
        .iter_mut()
        .map(|d| d.take().expect("a finished direction"))
        .collect();
    match run.finish(cells, lost, directions, start_time) {
        Ok((mut acc, stats)) => {
            acc.header.warnings =
                warnings::stored_warnings(sample, &part, &acc, &stats, &notes, &sheets);
            SimError::Partial {
                cause: Box::new(cause),
                kept: Box::new((acc, stats)),
            }
        }
        Err(_) => cause,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn done(pattern: &str) -> Vec<Option<DirectionStats>> {
        pattern
            .chars()
            .map(|c| (c == 'x').then_some(DirectionStats::untraced(0.0)))
            .collect()
    }

    #[test]
    fn the_longest_contiguous_run_of_finished_directions_is_kept() {
        // In order: the directions before the failed one.
        assert_eq!(finished_run(&done("xx..")), Some(0..2));
        // The diffraction method, most oblique first: the directions after it.
        assert_eq!(finished_run(&done(".xxx")), Some(1..4));
        // Not contiguous: the longest run, the first of equal ones.
        assert_eq!(finished_run(&done("x.xx.")), Some(2..4));
        assert_eq!(finished_run(&done("x.x")), Some(0..1));
        assert_eq!(finished_run(&done("...")), None);
        assert_eq!(finished_run(&done("")), None);
    }
}
