//! How an adaptive direction (`--target-stderr`, `--tolerance`) grows its trees: from a
//! first batch that the replicate groups can judge, by the error it measured, so that the
//! goal is met within a small factor of the trees it needs (issue 71: `--target-stderr
//! 0.05` on the white paint ran the default 4,096 trees and reached 0.023 in 2 min 37 s,
//! where 1,024 reached 0.046 in 43 s).
//!
//! A standard error falls as `N^-alpha`: `alpha = 1/2` for independent trees and random
//! walks, up to about 3/4 under the R2 entry points on the shipped samples (docs/design.md
//! §4, "Standard errors"). After a batch that measured `e` at `N` trees, the total that
//! meets the goal `g` is predicted as `N (e / g)^(1 / alpha)`. With one measurement, `alpha`
//! is taken as 1 (the most optimistic: the prediction falls short rather than over, and the
//! next batch corrects it); with two, as measured between them, within [1/2, 1]. Each step
//! multiplies the total by [`MIN_GROWTH`] to [`MAX_GROWTH`] and asks [`MARGIN`] more than
//! predicted. The run stops at the first batch that meets the goal, so it spends at most
//! about `MIN_GROWTH` times what it needs where the prediction falls short, and the
//! prediction's own error where it overshoots.

use super::BLOCK;

/// The first batch of an adaptive direction: where the 16 replicate groups of 64-tree
/// blocks first all hold trees and the errors are theirs (docs/design.md §4).
pub const FIRST_BATCH: u64 = 16 * BLOCK;
/// Each batch at least this many times the trees before it (a prediction that falls just
/// short costs one more batch of at least a quarter more).
pub const MIN_GROWTH: f64 = 1.25;
/// Each batch at most this many times the trees before it, whatever the prediction (a
/// noisy error, or a first batch far from the goal).
pub const MAX_GROWTH: f64 = 2.5;
/// Asked beyond the prediction, for the noise of the measured error.
pub const MARGIN: f64 = 1.05;

/// The first batch of an adaptive direction asked for `rays` per batch: the smaller of
/// `rays` (in whole blocks) and [`FIRST_BATCH`].
pub fn first_batch(rays: u64) -> u64 {
    FIRST_BATCH.min(rays.div_ceil(BLOCK).max(1) * BLOCK)
}

/// The total trees of the next batch's end, after `done` trees whose measured errors so far
/// are `history` (`(trees, error)`, in order) against `goal`: a whole number of blocks.
pub fn next_total(done: u64, history: &[(u64, f64)], goal: f64) -> u64 {
    let predicted = match history {
        [.., (n1, e1), (n2, e2)] if *e1 > 0.0 && *e2 > 0.0 && n2 > n1 && *e2 > goal => {
            let alpha = ((e1 / e2).ln() / (*n2 as f64 / *n1 as f64).ln()).clamp(0.5, 1.0);
            Some((e2 / goal).powf(1.0 / alpha))
        }
        [.., (_, e)] if *e > goal => Some(e / goal),
        _ => None,
    };
    // No error to go by (global mode has none): double.
    let factor = predicted.map_or(2.0, |f| (f * MARGIN).clamp(MIN_GROWTH, MAX_GROWTH));
    let next = (done as f64 * factor).ceil() as u64;
    next.div_ceil(BLOCK).max(1) * BLOCK
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_batch_grows_by_the_measured_error_within_its_bounds() {
        // One measurement, alpha taken as 1: 2x the goal asks 2 x 1.05 as many.
        assert_eq!(next_total(1024, &[(1024, 0.1)], 0.05), 2176);
        // Just short: at least a quarter more.
        assert_eq!(next_total(1024, &[(1024, 0.0501)], 0.05), 1280);
        // Far off: at most 2.5 times.
        assert_eq!(next_total(1024, &[(1024, 1.0)], 0.05), 2560);
        // Two measurements that fell as N^-1/2 (Monte Carlo): (0.07 / 0.05)^2 x 1.05 =
        // 2.06 times 2048.
        let e2 = 0.1 / 2f64.sqrt();
        let n = next_total(2048, &[(1024, 0.1), (2048, e2)], 0.05);
        let want = 2048.0 * (e2 / 0.05).powi(2) * MARGIN;
        assert!(
            (n as f64 - want).abs() <= BLOCK as f64,
            "{n} against {want}"
        );
        // An error that rose (noise) is taken as falling as N^-1/2, the slowest.
        let n = next_total(2048, &[(1024, 0.06), (2048, 0.07)], 0.05);
        let want = 2048.0 * (0.07f64 / 0.05).powi(2) * MARGIN;
        assert!(
            (n as f64 - want).abs() <= BLOCK as f64,
            "{n} against {want}"
        );
        // No error at all: double; always whole blocks.
        assert_eq!(next_total(1000, &[], 0.05), 2048);
    }
}
