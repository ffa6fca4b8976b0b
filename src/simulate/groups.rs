//! Replicate groups: honest standard errors under quasi-Monte Carlo entry points.
//!
//! Trees enter the tile on the R2 low-discrepancy sequence (`launch::entry_point`), whose
//! error falls faster than independent points'; treating its trees as independent
//! overstated the error 3-7x (issue 49: `bench converge`'s `seed_check` 0.12-0.24 where
//! honest errors give 0.674). Randomised QMC's answer (Cranley & Patterson 1976; L'Ecuyer
//! & Lemieux 2002, "Recent advances in randomized quasi-Monte Carlo methods", §3): split
//! the trees into `K` groups, each its own R2 sequence under its own random shift, so the
//! groups' estimates are independent and identically distributed, and estimate the
//! variance of their mean from their spread (`K - 1` degrees of freedom). docs/design.md
//! §4, "Standard errors".
//!
//! Groups are whole blocks (block `b` is in group `b mod K`), so a block's sums go to one
//! group and the summation order, and so the bytes, stay independent of threads.

use super::{BLOCK, SimConfig};
use crate::accumulate::Cell;
use crate::accumulate::Coherence;
use crate::accumulate::block::BlockCell;

/// Replicate groups per incident direction. Sixteen: the error estimate's own relative
/// error is about `1 / sqrt(2 (K - 1))` = 18 %, while the groups' shorter sequences cost
/// QMC's convergence little (its error falls as about `N^-3/4` on these integrands
/// against the groups' `K^-1/2`: `K^1/4` = 2x at most; measured in `bench converge`).
pub const ERROR_GROUPS: u64 = 16;

/// Replicate groups of a run (`Header::error_groups`): `ERROR_GROUPS` where trees enter
/// on the R2 sequence and have per-tree errors, else none (0). A sample that scatters in
/// volume has none either: its trees are random walks, plain Monte Carlo whatever the
/// entry point, where the per-tree spread is exact with `N - 1` degrees of freedom and
/// the groups' 15 understate sparse buckets (a bucket 52 trees reached in a particle slab
/// was 5.6 of its group error from next-event estimation's 2079; tests/next_event.rs).
pub(super) fn error_groups(cfg: &SimConfig, scattering: bool) -> u64 {
    // A fixed budget too small to give every group trees keeps one sequence: its errors
    // would be the per-tree spread anyway, and sixteen short shifted sequences integrate
    // the tile worse than one (a tilted gold film at 256 trees: 2.1e-3 off the local
    // transfer matrix, where one sequence stays within 2e-3; tests/tilted_absorbers.rs).
    let too_few = !cfg.adaptive() && cfg.rays < ERROR_GROUPS * BLOCK;
    if scattering
        || too_few
        || cfg.random_entry
        || matches!(
            cfg.coherence,
            Coherence::Global | Coherence::Diffraction | Coherence::Rigorous
        )
    {
        0
    } else {
        ERROR_GROUPS
    }
}

/// Tree `i`'s group of `k` and its index in that group's sequence.
pub(super) fn group_of(i: u64, k: u64) -> (usize, u64) {
    let b = i / BLOCK;
    ((b % k) as usize, (b / k) * BLOCK + i % BLOCK)
}

/// How many of trees `0..n` are in group `g` of `k`.
pub(super) fn group_size(g: usize, n: u64, k: u64) -> u64 {
    let (full, rest) = (n / BLOCK, n % BLOCK);
    let g = g as u64;
    let blocks = if g < full { (full - 1 - g) / k + 1 } else { 0 };
    let last = if rest > 0 && full % k == g { rest } else { 0 };
    blocks * BLOCK + last
}

/// One direction's sums per group: trees, and per (wavelength, key) the deposits, and per
/// wavelength the totals R and T.
pub(super) struct GroupSums {
    k: usize,
    nkeys: usize,
    trees: Vec<u64>,
    sum: Vec<Vec<f64>>,
    r: Vec<Vec<f64>>,
    t: Vec<Vec<f64>>,
}

impl GroupSums {
    pub(super) fn new(k: u64, nl: usize, nkeys: usize) -> GroupSums {
        let k = k as usize;
        GroupSums {
            k,
            nkeys,
            trees: vec![0; k],
            sum: vec![vec![0.0; nl * nkeys]; k],
            r: vec![vec![0.0; nl]; k],
            t: vec![vec![0.0; nl]; k],
        }
    }

    /// Adds block `block`'s sums of wavelength `j`.
    pub(super) fn add(&mut self, block: u64, j: usize, bc: &BlockCell) {
        let g = (block % self.k as u64) as usize;
        if j == 0 {
            self.trees[g] += bc.trees;
        }
        let sum = &mut self.sum[g][j * self.nkeys..(j + 1) * self.nkeys];
        for &(key, s, _, _) in &bc.entries {
            sum[key as usize] += s;
        }
        self.r[g][j] += bc.r.0;
        self.t[g][j] += bc.t.0;
    }

    /// Writes the groups' variance estimates into the direction's `cells` (one per
    /// wavelength), or clears them while a group has no trees yet.
    ///
    /// With group means `m_g = S_g / n_g` and the pooled mean `m = S / N`, the variance of
    /// one group's mean is estimated by `s^2 = sum_g (m_g - m)^2 / (K - 1)`, and the
    /// pooled sum `S = sum_g n_g m_g` has variance `sum_g n_g^2 Var(m_g) = s^2 sum_g
    /// n_g^2` (groups differ by at most one block, so their variances are taken equal).
    pub(super) fn estimate(&self, cells: &mut [Cell]) {
        let k = self.k;
        if k < 2 || self.trees.contains(&0) {
            for c in cells.iter_mut() {
                c.var.clear();
                (c.r_var, c.t_var) = (0.0, 0.0);
            }
            return;
        }
        let n: Vec<f64> = self.trees.iter().map(|&t| t as f64).collect();
        let total: f64 = n.iter().sum();
        let n2: f64 = n.iter().map(|x| x * x).sum();
        let var = |s: &dyn Fn(usize) -> f64| -> f64 {
            let m = (0..k).map(s).sum::<f64>() / total;
            let ss: f64 = (0..k).map(|g| (s(g) / n[g] - m).powi(2)).sum();
            ss / (k - 1) as f64 * n2
        };
        for (j, c) in cells.iter_mut().enumerate() {
            let base = j * self.nkeys;
            c.var = (0..self.nkeys)
                .map(|key| var(&|g| self.sum[g][base + key]))
                .collect();
            c.r_var = var(&|g| self.r[g][j]);
            c.t_var = var(&|g| self.t[g][j]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every tree is in exactly one group, at an index below its group's size, and each
    /// group's indices are `0..size` without gaps: each group is a whole sequence.
    #[test]
    fn groups_partition_the_trees_into_whole_sequences() {
        for n in [1, 63, 64, 65, 1000, 1024, 1025, 4096, 5000] {
            for k in [1, 3, 16] {
                let mut seen: Vec<Vec<u64>> = vec![Vec::new(); k as usize];
                for i in 0..n {
                    let (g, m) = group_of(i, k);
                    seen[g].push(m);
                }
                for (g, mut ms) in seen.into_iter().enumerate() {
                    ms.sort_unstable();
                    let size = group_size(g, n, k);
                    assert_eq!(ms, (0..size).collect::<Vec<u64>>(), "n {n} k {k} g {g}");
                }
            }
        }
        assert_eq!(group_of(100, 1), (0, 100));
    }

    /// Independent groups of a known spread: the estimate of the pooled sum's variance
    /// against the closed form `K n^2 sigma^2` (each group's sum has variance
    /// `n^2 sigma^2`), averaged over many draws from a fixed generator.
    #[test]
    fn the_variance_estimate_is_unbiased_for_independent_groups() {
        let (k, nl, nkeys) = (ERROR_GROUPS, 1, 2);
        let mut rng = crate::rng::Rng::new(7, 1);
        let sigma = 0.3;
        let (mut mean_var, draws) = (0.0, 4000);
        for _ in 0..draws {
            let mut gs = GroupSums::new(k, nl, nkeys);
            for b in 0..k {
                // A group mean of 1 + sigma * (uniform with unit variance).
                let x = 1.0 + sigma * (rng.uniform() - 0.5) * 12f64.sqrt();
                let bc = BlockCell {
                    trees: BLOCK,
                    entries: vec![(0, x * BLOCK as f64, 0.0, BLOCK)],
                    ..BlockCell::default()
                };
                gs.add(b, 0, &bc);
            }
            let mut cells = vec![Cell::new(
                &crate::accumulate::Buckets {
                    theta_bins: 1,
                    phi_bins: 1,
                },
                false,
            )];
            gs.estimate(&mut cells);
            mean_var += cells[0].var[0] / draws as f64;
            assert_eq!(cells[0].var[1], 0.0);
        }
        let expected = k as f64 * (BLOCK as f64).powi(2) * sigma * sigma;
        // The mean of 4000 draws of a 15-dof variance estimate: relative error
        // sqrt(2 / 15 / 4000) = 0.6 %.
        assert!(
            (mean_var / expected - 1.0).abs() < 0.03,
            "{mean_var} against {expected}"
        );
    }
}
