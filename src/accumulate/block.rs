//! Per-thread accumulators of the simulation: dense per-key sums with touched lists (no
//! allocation or hashing per tree), drained into sparse per-block cells that are added
//! to the run's cells in block order, so sums do not depend on scheduling.

use super::{Cell, add_fields};
use crate::optics::C64;
use crate::optics::fresnel::Field;
use crate::optics::mueller::Mueller;

/// Sums of one block of trees for one cell, sparse and sorted by key.
#[derive(Default)]
pub(crate) struct BlockCell {
    pub(crate) trees: u64,
    /// `(key, sum, sum of squares, count)`.
    pub(crate) entries: Vec<(u32, f64, f64, u64)>,
    pub(crate) global: Vec<(u32, [Field; 2])>,
    /// With `--mueller`: `(key, sum, sum of squares)` of the trees' Mueller deposits.
    pub(crate) mueller: Vec<(u32, Mueller, Mueller)>,
    pub(crate) r: (f64, f64),
    pub(crate) t: (f64, f64),
    pub(crate) absorbed: f64,
    pub(crate) dropped: f64,
    pub(crate) dropped_limit: f64,
    /// Power that left an open sample through its sides (part of `dropped`).
    pub(crate) escaped: f64,
    /// Sum over trees of `2 sqrt(D_l (R + T)) + D_l`, `D_l` a tree's power cut by limits:
    /// the most that power can change the tree's coherent totals (Cauchy-Schwarz).
    pub(crate) limit_bound: f64,
    /// Sum over absorbing trees of `max(0, R + T + dropped - 1)`: power a tree's ray series
    /// created because its terms did not recombine (`SimStats::created`).
    pub(crate) created: f64,
    /// Sum over trees of `Tree::limited_power`.
    pub(crate) limited: f64,
    /// Sum over lossless trees of the power their groups' cross terms were corrected by
    /// (`Scratch::corrected`).
    pub(crate) rebalanced: f64,
    /// The diffraction method: every exit's contribution, tree by tree
    /// (`diffraction::contribution`).
    pub(crate) diffraction: Vec<super::diffraction::Contribution>,
    /// The diffraction method under path sharing: every exit once for all wavelengths, in
    /// the cell of the direction's first bin that diffracts (`diffraction::SharedExit`).
    pub(crate) shared: Vec<super::diffraction::SharedExit>,
}

/// Per-thread dense accumulators with touched lists: no allocation and no hashing per
/// tree.
pub(crate) struct Dense {
    nkeys: usize,
    /// One tree's deposits per key (combined before squaring), and whether touched.
    tree: Vec<(f64, bool)>,
    tree_touched: Vec<u32>,
    /// The block's sums per (wavelength, key).
    block: Vec<(f64, f64, u64)>,
    block_touched: Vec<u32>,
    glob: Vec<([Field; 2], bool)>,
    glob_touched: Vec<u32>,
    /// With `--mueller`: one tree's Mueller deposits per key with its touched list, and
    /// the block's sums and sums of squares, sparse (`(wavelength * nkeys + key, sum,
    /// sum of squares)`, found through `mslot`, `u32::MAX` where absent): a dense array
    /// of them per worker was 33 MB at 40 bins, zeroed for every worker rayon made.
    /// Empty otherwise.
    mtree: Vec<(Mueller, bool)>,
    mtree_touched: Vec<u32>,
    mslot: Vec<u32>,
    mblock: Vec<(u32, Mueller, Mueller)>,
}

impl Dense {
    pub(crate) fn new(nl: usize, nkeys: usize, global: bool, mueller: bool) -> Dense {
        let (mt, mb) = if mueller { (nkeys, nl * nkeys) } else { (0, 0) };
        Dense {
            nkeys,
            tree: vec![(0.0, false); nkeys],
            tree_touched: Vec::new(),
            block: vec![(0.0, 0.0, 0); nl * nkeys],
            block_touched: Vec::new(),
            glob: if global {
                vec![([[C64::new(0.0, 0.0); 3]; 2], false); nl * nkeys]
            } else {
                Vec::new()
            },
            glob_touched: Vec::new(),
            mtree: vec![([0.0; 16], false); mt],
            mtree_touched: Vec::new(),
            mslot: vec![u32::MAX; mb],
            mblock: Vec::new(),
        }
    }

    /// Adds one tree's deposits at wavelength `j` (and its Mueller deposits, empty
    /// without `--mueller`); returns its (R, T) totals.
    pub(crate) fn add_tree(
        &mut self,
        j: usize,
        deps: &[(u32, f64)],
        glob: &[(u32, [Field; 2])],
        mdeps: &[(u32, Mueller)],
    ) -> (f64, f64) {
        self.add_tree_mueller(j, mdeps);
        for &(k, v) in deps {
            let e = &mut self.tree[k as usize];
            if !e.1 {
                e.1 = true;
                self.tree_touched.push(k);
            }
            e.0 += v;
        }
        let (mut r, mut t) = (0.0, 0.0);
        // Each touched key holds one tree's value; the order of keys does not matter.
        for &k in &self.tree_touched {
            let v = std::mem::take(&mut self.tree[k as usize]).0;
            if k & 1 == 0 {
                r += v;
            } else {
                t += v;
            }
            let idx = j * self.nkeys + k as usize;
            let e = &mut self.block[idx];
            if e.2 == 0 {
                self.block_touched.push(idx as u32);
            }
            e.0 += v;
            e.1 += v * v;
            e.2 += 1;
        }
        self.tree_touched.clear();
        for (k, a) in glob {
            let idx = j * self.nkeys + *k as usize;
            let e = &mut self.glob[idx];
            if !e.1 {
                e.1 = true;
                self.glob_touched.push(idx as u32);
            }
            add_fields(&mut e.0, a);
        }
        (r, t)
    }

    /// One tree's Mueller deposits: combined per key, then added with their squares to
    /// the block's sums (as the scalar deposits are).
    fn add_tree_mueller(&mut self, j: usize, mdeps: &[(u32, Mueller)]) {
        for (k, m) in mdeps {
            let e = &mut self.mtree[*k as usize];
            if !e.1 {
                e.1 = true;
                self.mtree_touched.push(*k);
            }
            for (a, b) in e.0.iter_mut().zip(m) {
                *a += b;
            }
        }
        for &k in &self.mtree_touched {
            let v = std::mem::take(&mut self.mtree[k as usize]).0;
            let idx = j * self.nkeys + k as usize;
            if self.mslot[idx] == u32::MAX {
                self.mslot[idx] = self.mblock.len() as u32;
                self.mblock.push((idx as u32, [0.0; 16], [0.0; 16]));
            }
            let e = &mut self.mblock[self.mslot[idx] as usize];
            for (i, x) in v.iter().enumerate() {
                e.1[i] += x;
                e.2[i] += x * x;
            }
        }
        self.mtree_touched.clear();
    }

    /// Moves the block's sums into `out` (one `BlockCell` per wavelength), sorted by key,
    /// and clears the dense arrays.
    pub(crate) fn drain(&mut self, out: &mut [BlockCell]) {
        self.mblock.sort_unstable_by_key(|e| e.0);
        for (idx, sum, sq) in self.mblock.drain(..) {
            let (j, k) = (idx as usize / self.nkeys, idx as usize % self.nkeys);
            self.mslot[idx as usize] = u32::MAX;
            out[j].mueller.push((k as u32, sum, sq));
        }
        self.block_touched.sort_unstable();
        for &idx in &self.block_touched {
            let (j, k) = (idx as usize / self.nkeys, idx as usize % self.nkeys);
            let e = std::mem::take(&mut self.block[idx as usize]);
            out[j].entries.push((k as u32, e.0, e.1, e.2));
        }
        self.block_touched.clear();
        self.glob_touched.sort_unstable();
        for &idx in &self.glob_touched {
            let (j, k) = (idx as usize / self.nkeys, idx as usize % self.nkeys);
            let (a, _) = std::mem::replace(
                &mut self.glob[idx as usize],
                ([[C64::new(0.0, 0.0); 3]; 2], false),
            );
            out[j].global.push((k as u32, a));
        }
        self.glob_touched.clear();
    }
}

/// Adds one block's sums to a cell (blocks are added in block order).
pub(crate) fn add_block(cell: &mut Cell, b: &BlockCell) {
    for &(k, sum, sq, n) in &b.entries {
        cell.sum[k as usize] += sum;
        cell.sumsq[k as usize] += sq;
        cell.count[k as usize] += n;
    }
    for (k, a) in &b.global {
        add_fields(&mut cell.global[*k as usize], a);
    }
    for (k, sum, sq) in &b.mueller {
        let k = *k as usize;
        for (a, x) in cell.mueller[k].iter_mut().zip(sum) {
            *a += x;
        }
        for (a, x) in cell.mueller_sq[k].iter_mut().zip(sq) {
            *a += x;
        }
    }
    cell.trees += b.trees;
    cell.r_sum += b.r.0;
    cell.r_sumsq += b.r.1;
    cell.t_sum += b.t.0;
    cell.t_sumsq += b.t.1;
    cell.absorbed += b.absorbed;
    cell.dropped += b.dropped;
}
