//! One (incident direction, wavelength) cell of an accumulator: plain sums, so runs and
//! batch units merge by addition, and the fractions and standard errors read from them.

use super::{Buckets, Coherence, add_fields};
use crate::optics::C64;
use crate::optics::fresnel::{Field, field_power};

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
        }
    }

    /// Adds another run's sums (same settings).
    pub fn merge(&mut self, o: &Cell) {
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
    /// once: returns `None`).
    pub fn fraction_stderr(&self, kk: usize, mode: Coherence) -> Option<f64> {
        (!matches!(mode, Coherence::Global | Coherence::Diffraction) && self.trees > 1)
            .then(|| stderr(self.sum[kk], self.sumsq[kk], self.trees))
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
            .then(|| stderr(self.r_sum, self.r_sumsq, self.trees))
    }
}

/// Standard error of a mean from a sum and a sum of squares of `n` samples.
pub fn stderr(sum: f64, sumsq: f64, n: u64) -> f64 {
    let n = n as f64;
    let mean = sum / n;
    let var = ((sumsq / n - mean * mean) * n / (n - 1.0)).max(0.0);
    (var / n).sqrt()
}
