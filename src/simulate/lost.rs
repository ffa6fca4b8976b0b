//! What a run lost or could not trust, per cell (`SimStats`' per-cell sums), and the worst
//! tree that carried out more power than it may.

use super::DiffractionCell;

/// Per-cell sums of what the run lost or could not trust (see [`super::SimStats`]), filled
/// direction by direction.
pub(super) struct Lost<'a> {
    pub(super) diffraction: &'a mut [DiffractionCell],
    pub(super) limit_dropped: &'a mut [f64],
    pub(super) escaped: &'a mut [f64],
    pub(super) limit_bound: &'a mut [f64],
    pub(super) created: &'a mut [f64],
    pub(super) limited: &'a mut [f64],
    pub(super) rebalanced: &'a mut [f64],
}

/// The finished sums of [`Lost`].
pub(super) struct LostSums {
    pub(super) diffraction: Vec<DiffractionCell>,
    pub(super) limit_dropped: Vec<f64>,
    pub(super) escaped: Vec<f64>,
    pub(super) limit_bound: Vec<f64>,
    pub(super) created: Vec<f64>,
    pub(super) limited: Vec<f64>,
    pub(super) rebalanced: Vec<f64>,
}

impl LostSums {
    /// Zero sums for `n` cells.
    pub(super) fn new(n: usize) -> LostSums {
        LostSums {
            diffraction: vec![DiffractionCell::default(); n],
            limit_dropped: vec![0.0; n],
            escaped: vec![0.0; n],
            limit_bound: vec![0.0; n],
            created: vec![0.0; n],
            limited: vec![0.0; n],
            rebalanced: vec![0.0; n],
        }
    }

    /// The sums, for a direction to add to.
    pub(super) fn lost(&mut self) -> Lost<'_> {
        Lost {
            diffraction: &mut self.diffraction,
            limit_dropped: &mut self.limit_dropped,
            escaped: &mut self.escaped,
            limit_bound: &mut self.limit_bound,
            created: &mut self.created,
            limited: &mut self.limited,
            rebalanced: &mut self.rebalanced,
        }
    }

    /// Forgets cell `k`'s sums (a cell the rigorous solver took: what the rays lost there,
    /// and what the diffraction method had to say of it, is not the cell's).
    pub(super) fn clear(&mut self, k: usize) {
        self.diffraction[k] = DiffractionCell::default();
        for v in [
            &mut self.limit_dropped,
            &mut self.escaped,
            &mut self.limit_bound,
            &mut self.created,
            &mut self.limited,
            &mut self.rebalanced,
        ] {
            v[k] = 0.0;
        }
    }

    /// Cells `span` alone, as a run of those cells would have them.
    pub(super) fn span(&self, span: std::ops::Range<usize>) -> LostSums {
        LostSums {
            diffraction: self.diffraction[span.clone()].to_vec(),
            limit_dropped: self.limit_dropped[span.clone()].to_vec(),
            escaped: self.escaped[span.clone()].to_vec(),
            limit_bound: self.limit_bound[span.clone()].to_vec(),
            created: self.created[span.clone()].to_vec(),
            limited: self.limited[span.clone()].to_vec(),
            rebalanced: self.rebalanced[span].to_vec(),
        }
    }
}

/// A tree that carried out more power than it was launched with and its events were
/// allowed to add (`Tree::overflow`, fraction of launched power): where, and by how much.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Overflow {
    pub(super) power: f64,
    pub(super) direction: usize,
    pub(super) bin: usize,
    pub(super) tree: u64,
}

impl Overflow {
    /// Keeps the larger of `self` and `o`; ties go to the first direction, bin and tree, so
    /// the message does not depend on the thread count.
    pub(super) fn worse(self, o: Overflow) -> Overflow {
        let key = |x: &Overflow| (x.direction, x.bin, x.tree);
        match self.power.total_cmp(&o.power) {
            std::cmp::Ordering::Less => o,
            std::cmp::Ordering::Greater => self,
            std::cmp::Ordering::Equal if key(&o) < key(&self) => o,
            std::cmp::Ordering::Equal => self,
        }
    }
}
