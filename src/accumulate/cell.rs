//! One (incident direction, wavelength) cell of an accumulator: plain sums, so runs and
//! batch units merge by addition, and the fractions and standard errors read from them.

use super::{Buckets, Coherence, add_fields};
use crate::optics::C64;
use crate::optics::fresnel::{Field, field_power};
use crate::optics::mueller::Mueller;

/// Sums for one (incident direction, wavelength) cell; plain sums so runs merge by
/// addition (docs/design.md §5).
#[derive(Clone, Debug, PartialEq)]
pub struct Cell {
    pub trees: u64,
    /// Per bucket key (`key()`): sum over trees of the tree's deposit, and of its square.
    pub sum: Vec<f64>,
    pub sumsq: Vec<f64>,
    /// Per bucket key: how many trees deposited anything there.
    pub count: Vec<u64>,
    /// Per tree totals: reflected, transmitted (sum and sum of squares), absorbed, dropped.
    pub r_sum: f64,
    pub r_sumsq: f64,
    pub t_sum: f64,
    pub t_sumsq: f64,
    pub absorbed: f64,
    pub dropped: f64,
    /// Global mode: per bucket key, the summed complex amplitudes (2 pol x 3 comps).
    pub global: Vec<[Field; 2]>,
    /// Per bucket key: the variance of `sum` estimated from independent replicate groups
    /// of trees (randomised quasi-Monte Carlo, docs/design.md §4, "Standard errors"); empty where the cell
    /// has no such estimate, and the per-tree spread stands in.
    pub var: Vec<f64>,
    /// The same estimate for `r_sum` and `t_sum` (0 where `var` is empty).
    pub r_var: f64,
    pub t_var: f64,
    /// With `--mueller`, per bucket key: the sum over trees of the tree's Mueller deposit
    /// (`optics::mueller`, row-major; its `m00` is `sum`'s very value), and of its
    /// elements' squares. Empty otherwise.
    pub mueller: Vec<Mueller>,
    pub mueller_sq: Vec<Mueller>,
}

impl Cell {
    pub fn new(buckets: &Buckets, global: bool) -> Cell {
        let n = 2 * buckets.len();
        Cell {
            trees: 0,
            sum: vec![0.0; n],
            sumsq: vec![0.0; n],
            count: vec![0; n],
            r_sum: 0.0,
            r_sumsq: 0.0,
            t_sum: 0.0,
            t_sumsq: 0.0,
            absorbed: 0.0,
            dropped: 0.0,
            global: if global {
                vec![[[C64::new(0.0, 0.0); 3]; 2]; n]
            } else {
                Vec::new()
            },
            var: Vec::new(),
            r_var: 0.0,
            t_var: 0.0,
            mueller: Vec::new(),
            mueller_sq: Vec::new(),
        }
    }

    /// The cell with room for the Mueller matrices (`--mueller`).
    pub fn with_mueller(mut self) -> Cell {
        self.mueller = vec![[0.0; 16]; self.sum.len()];
        self.mueller_sq = vec![[0.0; 16]; self.sum.len()];
        self
    }

    /// The Mueller matrix of bucket key `kk` as a fraction of the launched power (`m00`
    /// is [`Cell::fraction`]); `None` where the run kept none.
    pub fn mueller(&self, kk: usize) -> Option<Mueller> {
        let m = self.mueller.get(kk)?;
        let n = self.trees.max(1) as f64;
        Some(m.map(|x| x / n))
    }

    /// The standard error of each element of [`Cell::mueller`], from the per-tree spread
    /// (`None` without Mueller matrices or with fewer than two trees).
    pub fn mueller_stderr(&self, kk: usize) -> Option<Mueller> {
        let (m, q) = (self.mueller.get(kk)?, self.mueller_sq.get(kk)?);
        (self.trees > 1).then(|| std::array::from_fn(|e| stderr(m[e], q[e], self.trees)))
    }

    /// Adds another run's sums (same settings). Runs of different seeds are independent, so
    /// the variances of their sums add; where only one run has a replicate estimate, the
    /// other's per-tree spread stands in for its part (none is kept where that run has a
    /// single tree, whose spread is unknown).
    pub fn merge(&mut self, o: &Cell) {
        if !self.var.is_empty() || !o.var.is_empty() {
            let known = |c: &Cell| !c.var.is_empty() || c.trees != 1;
            if known(self) && known(o) {
                let var: Vec<f64> = (0..self.sum.len())
                    .map(|k| self.sum_var(k) + o.sum_var(k))
                    .collect();
                self.r_var = self.r_sum_var() + o.r_sum_var();
                self.t_var = self.t_sum_var() + o.t_sum_var();
                self.var = var;
            } else {
                self.var.clear();
                (self.r_var, self.t_var) = (0.0, 0.0);
            }
        }
        self.trees += o.trees;
        for (a, b) in self.sum.iter_mut().zip(&o.sum) {
            *a += b;
        }
        for (a, b) in self.sumsq.iter_mut().zip(&o.sumsq) {
            *a += b;
        }
        for (a, b) in self.count.iter_mut().zip(&o.count) {
            *a += b;
        }
        for (a, b) in self.global.iter_mut().zip(&o.global) {
            add_fields(a, b);
        }
        for (a, b) in self.mueller.iter_mut().zip(&o.mueller) {
            a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
        }
        for (a, b) in self.mueller_sq.iter_mut().zip(&o.mueller_sq) {
            a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
        }
        self.r_sum += o.r_sum;
        self.r_sumsq += o.r_sumsq;
        self.t_sum += o.t_sum;
        self.t_sumsq += o.t_sumsq;
        self.absorbed += o.absorbed;
        self.dropped += o.dropped;
    }

    /// Fraction of launched power in bucket key `kk`.
    pub fn fraction(&self, kk: usize, mode: Coherence) -> f64 {
        if self.trees == 0 {
            return 0.0;
        }
        let n = self.trees as f64;
        match mode {
            Coherence::Global => {
                let a = &self.global[kk];
                0.5 * (field_power(&a[0].map(|c| c / n)) + field_power(&a[1].map(|c| c / n)))
            }
            _ => self.sum[kk] / n,
        }
    }

    /// Standard error of the fraction in bucket key `kk` from the per-tree spread
    /// (not defined for global or diffraction mode, whose buckets sum over all trees at
    /// once, nor for the rigorous solver, which has no trees: returns `None`).
    pub fn fraction_stderr(&self, kk: usize, mode: Coherence) -> Option<f64> {
        (!matches!(
            mode,
            Coherence::Global | Coherence::Diffraction | Coherence::Rigorous
        ) && self.trees > 1)
            .then(|| self.sum_var(kk).sqrt() / self.trees as f64)
    }

    /// The variance of bucket key `kk`'s sum: the replicate groups' estimate where the
    /// cell has one, else `n` times the per-tree sample variance (trees independent).
    pub fn sum_var(&self, kk: usize) -> f64 {
        match self.var.get(kk) {
            Some(&v) => v,
            None => per_tree_var(self.sum[kk], self.sumsq[kk], self.trees),
        }
    }

    fn r_sum_var(&self) -> f64 {
        if self.var.is_empty() {
            per_tree_var(self.r_sum, self.r_sumsq, self.trees)
        } else {
            self.r_var
        }
    }

    fn t_sum_var(&self) -> f64 {
        if self.var.is_empty() {
            per_tree_var(self.t_sum, self.t_sumsq, self.trees)
        } else {
            self.t_var
        }
    }

    /// Directional-hemispherical reflectance and transmittance.
    pub fn totals(&self, mode: Coherence, buckets: &Buckets) -> (f64, f64) {
        if self.trees == 0 {
            return (0.0, 0.0);
        }
        match mode {
            Coherence::Global => {
                let (mut r, mut t) = (0.0, 0.0);
                for b in 0..buckets.len() {
                    r += self.fraction(2 * b, mode);
                    t += self.fraction(2 * b + 1, mode);
                }
                (r, t)
            }
            _ => (
                self.r_sum / self.trees as f64,
                self.t_sum / self.trees as f64,
            ),
        }
    }

    /// Standard error of the total reflectance (per-tree spread).
    pub fn r_stderr(&self, mode: Coherence) -> Option<f64> {
        (mode != Coherence::Global && self.trees > 1)
            .then(|| self.r_sum_var().sqrt() / self.trees as f64)
    }

    /// Standard error of the total transmittance (as [`Cell::r_stderr`]).
    pub fn t_stderr(&self, mode: Coherence) -> Option<f64> {
        (mode != Coherence::Global && self.trees > 1)
            .then(|| self.t_sum_var().sqrt() / self.trees as f64)
    }
}

impl Cell {
    /// The replicate groups' part of the cell in a `.gsa` (`accumulate::file`): a flag (1
    /// or 0: whether the cell has the estimate), `var` per key, `r_var`, `t_var` (zeros
    /// where the flag is 0).
    pub(crate) fn group_values(&self) -> Vec<f64> {
        let has = !self.var.is_empty();
        let mut v = vec![if has { 1.0 } else { 0.0 }];
        v.extend((0..self.sum.len()).map(|k| self.var.get(k).copied().unwrap_or(0.0)));
        v.extend([self.r_var, self.t_var]);
        v
    }

    /// Reads [`Cell::group_values`] back (`sum.len() + 3` values), refusing senseless ones.
    pub(crate) fn set_group_values(&mut self, v: &[f64]) -> Result<(), &'static str> {
        let (has, rest) = v
            .split_first()
            .ok_or("a cell lacks its variance estimates")?;
        let sane = rest.iter().all(|x| x.is_finite() && *x >= 0.0);
        if !(*has == 0.0 || *has == 1.0) || !sane || rest.len() != self.sum.len() + 2 {
            return Err(
                "a cell holds a senseless variance estimate (a flag other than 0 or 1, or a negative or non-finite variance)",
            );
        }
        let (var, totals) = rest.split_at(self.sum.len());
        (self.r_var, self.t_var) = (totals[0], totals[1]);
        self.var = if *has == 1.0 {
            var.to_vec()
        } else {
            Vec::new()
        };
        Ok(())
    }
}

/// The variance of a sum of `n` independent samples estimated from the sum and the sum of
/// squares: `n` times the unbiased sample variance (0 for fewer than 2 samples).
fn per_tree_var(sum: f64, sumsq: f64, n: u64) -> f64 {
    if n < 2 {
        return 0.0;
    }
    let s = stderr(sum, sumsq, n) * n as f64;
    s * s
}

/// Standard error of a mean from a sum and a sum of squares of `n` samples.
pub fn stderr(sum: f64, sumsq: f64, n: u64) -> f64 {
    let n = n as f64;
    let mean = sum / n;
    let var = ((sumsq / n - mean * mean) * n / (n - 1.0)).max(0.0);
    (var / n).sqrt()
}

/// A `--mueller` cell's matrices in a `.gsa` payload (`accumulate::file`), sparse: the
/// number of keys with any non-zero sum, then for each, ascending, the key, its 16 sums and
/// its 16 sums of squares (a lobed sample fills few of its buckets).
pub(super) fn write_mueller(c: &Cell, put: &mut impl FnMut(f64)) {
    let held: Vec<usize> = (0..c.mueller.len())
        .filter(|&k| {
            c.mueller[k]
                .iter()
                .chain(&c.mueller_sq[k])
                .any(|&v| v != 0.0)
        })
        .collect();
    put(f64::from_bits(held.len() as u64));
    for k in held {
        put(f64::from_bits(k as u64));
        c.mueller[k]
            .iter()
            .chain(&c.mueller_sq[k])
            .for_each(|&v| put(v));
    }
}

/// A `--mueller` cell's sparse matrices at `pos` of `payload` into `c` (see
/// [`write_mueller`]): the count, then each key with its 16 sums and 16 sums of
/// squares, keys strictly ascending and in range. The position after them, or `None` where
/// the payload ends first or a key is senseless.
pub(super) fn read_mueller(payload: &[u8], mut pos: usize, c: &mut Cell) -> Option<usize> {
    let mut next = || {
        let b = payload.get(pos..pos + 8)?;
        pos += 8;
        Some(f64::from_le_bytes(b.try_into().ok()?))
    };
    let n = next()?.to_bits();
    if n > c.mueller.len() as u64 {
        return None;
    }
    let mut last = None;
    for _ in 0..n {
        let k = next()?.to_bits();
        if k >= c.mueller.len() as u64 || last.is_some_and(|l| k <= l) {
            return None;
        }
        last = Some(k);
        let k = k as usize;
        for v in c.mueller[k].iter_mut().chain(c.mueller_sq[k].iter_mut()) {
            *v = next()?;
        }
    }
    Some(pos)
}
