//! The diffraction method's last step for one incident direction: the kept exits of every
//! wavelength transformed into Floquet orders, which replace the cell's buckets.

use std::sync::Mutex;

use glam::DVec3;
use rayon::prelude::*;

use super::run::Run;
use super::{DIFFRACTION_RATIO_REFUSED, DiffractionCell, SimError};
use crate::accumulate::{Cell, diffraction};

impl Run<'_> {
    /// The diffraction method for incident direction `di` (towards the light `wi`): each
    /// of its diffraction cells' contributions transformed into Floquet orders
    /// (`diffraction::diffract`), which replace the cell's bucket sums and totals; the
    /// beamlet estimator's totals are kept in `out` for the energy check. Under
    /// `--coherence auto` a cell whose transform holds a share of the ray field's power
    /// outside `[DIFFRACTION_RATIO_REFUSED, 1 / DIFFRACTION_RATIO_REFUSED]` keeps the rays'
    /// buckets instead (`DiffractionCell::fell_back`), where an explicit run is refused.
    pub(super) fn diffract(
        &self,
        di: usize,
        wi: DVec3,
        contribs: &[Vec<diffraction::Contribution>],
        shared: &[diffraction::SharedExit],
        cells: &mut [Cell],
        out: &mut [DiffractionCell],
    ) -> Result<(), SimError> {
        let d = -wi;
        let hemisphere = |j: usize, down: bool, n_out: f64| self.hemisphere(j, d, down, n_out);
        // Under path sharing the tubes' shapes are the same in every bin: found once.
        let first = (0..contribs.len()).find(|&j| self.cell_diffracts(di, j));
        let shapes = match first {
            Some(j) if !shared.is_empty() => {
                let mut list = Vec::new();
                self.contributions(j, d, shared, &mut list, &mut Phases::default());
                let shapes = |down| {
                    let h = hemisphere(j, down, self.est.n_up);
                    diffraction::tube_shapes(&h.launches(), &list)
                };
                Some(rayon::join(|| shapes(false), || shapes(true)))
            }
            _ => None,
        };
        // Work is taken a wavelength at a time, shortest first (its grid and its patches
        // are the largest), as each thread comes free, and each wavelength's two
        // hemispheres are transformed side by side: the last wavelengths left are the
        // cheapest, so no thread waits long on another. Each wavelength's result is its
        // own, whoever computed it.
        let pool = Mutex::new(Vec::new());
        let mut results: Vec<(usize, Result<_, diffraction::DiffractionError>)> = (0..contribs
            .len())
            .filter(|&j| self.cell_diffracts(di, j))
            .par_bridge()
            .map_init(<(Vec<_>, Phases)>::default, |(formed, phases), j| {
                // Every tree of the bin took its centre (`block`).
                let list: &[diffraction::Contribution] = if shared.is_empty() {
                    &contribs[j]
                } else {
                    self.contributions(j, d, shared, formed, phases);
                    formed
                };
                (j, self.transform_bin(j, d, list, shapes.as_ref(), &pool))
            })
            .collect();
        results.sort_by_key(|r| r.0);
        for (j, res) in results {
            let (up, down) = res.map_err(|e| SimError::Config(e.to_string()))?;
            let cell = &mut cells[j];
            let n = cell.trees as f64;
            let (r_ray, t_ray) = (cell.r_sum / n, cell.t_sum / n);
            out[j] = DiffractionCell {
                rays_r: r_ray,
                rays_t: t_ray,
                r: up.total,
                t: down.total,
                orders: up.orders + down.orders,
                fallback_tubes: up.fallback_tubes + down.fallback_tubes,
                flipped_tubes: up.flipped_tubes + down.flipped_tubes,
                fell_back: false,
            };
            let ratio = out[j].ratio();
            if self.auto
                && r_ray + t_ray > 0.0
                && !(DIFFRACTION_RATIO_REFUSED..=1.0 / DIFFRACTION_RATIO_REFUSED).contains(&ratio)
            {
                out[j].fell_back = true;
                continue;
            }
            cell.sum.fill(0.0);
            cell.sumsq.fill(0.0);
            cell.count.fill(0);
            cell.var.clear();
            // Energy is the ray field's: each hemisphere's orders are scaled to the ray
            // method's total there. The transform's own total (what it kept in propagating
            // orders) is reported and judged in `finish` (DIFFRACTION_RATIO_*).
            let scale = |rays: f64, total: f64| if total > 0.0 { rays / total } else { 0.0 };
            let (su, sd) = (scale(r_ray, up.total), scale(t_ray, down.total));
            for (&(kk, p), s) in up
                .per_key
                .iter()
                .map(|e| (e, su))
                .chain(down.per_key.iter().map(|e| (e, sd)))
            {
                let p = p * s;
                cell.sum[kk as usize] = p * n;
                cell.sumsq[kk as usize] = p * p * n;
                cell.count[kk as usize] = cell.trees;
            }
            // The orders' Mueller matrices, scaled alike (their m00 the sums' very bits).
            if !cell.mueller.is_empty() {
                cell.mueller.fill([0.0; 16]);
                cell.mueller_sq.fill([0.0; 16]);
                let keys = up.per_key.iter().chain(&down.per_key).map(|e| e.0);
                let scales = std::iter::repeat_n(su, up.per_key.len())
                    .chain(std::iter::repeat_n(sd, down.per_key.len()));
                let matrices = up.per_key_mueller.iter().chain(&down.per_key_mueller);
                for ((kk, s), m) in keys.zip(scales).zip(matrices) {
                    let v = m.map(|x| x * s);
                    cell.mueller[kk as usize] = v.map(|x| x * n);
                    cell.mueller_sq[kk as usize] = v.map(|x| x * x * n);
                }
            }
        }
        Ok(())
    }

    /// The transform's settings for bin `j`'s hemisphere (`down`, into the real index
    /// `n_out`), for light travelling along `d`.
    fn hemisphere(&self, j: usize, d: DVec3, down: bool, n_out: f64) -> diffraction::Hemisphere {
        let lambda = self.settings.wavelength(j);
        let k = 2.0 * std::f64::consts::PI / lambda;
        diffraction::Hemisphere {
            tile_nm: self.sample.tile_nm,
            lambda_nm: lambda,
            n_out,
            k_in: [k * self.est.n_up * d.x, k * self.est.n_up * d.y],
            cos_i: -d.z,
            lattice: self.lattice,
            rho_nm: self.cfg.rho_nm,
            down,
            mueller: self.cfg.mueller,
        }
    }

    /// Bin `j`'s two hemispheres transformed from its contributions `list` (`shapes`, the
    /// tubes' up and down, where found once), side by side where their grids are small,
    /// each with a scratch from `pool`.
    fn transform_bin(
        &self,
        j: usize,
        d: DVec3,
        list: &[diffraction::Contribution],
        shapes: Option<&Shapes>,
        pool: &Mutex<Vec<diffraction::Scratch>>,
    ) -> Result<(diffraction::Pattern, diffraction::Pattern), diffraction::DiffractionError> {
        let lambda = self.settings.wavelength(j);
        let mut idx = Vec::new();
        self.sample.indices_into(lambda, &mut idx);
        let n_sub = idx[self.scene.substrate];
        let side = |down: bool, n_out: f64| {
            let h = self.hemisphere(j, d, down, n_out);
            let shape = shapes.map(|(u, dn)| if down { &dn[..] } else { &u[..] });
            let mut scratch = pool.lock().expect("not poisoned").pop().unwrap_or_default();
            let out = diffraction::diffract(&h, list, shape, &self.cfg.buckets, &mut scratch);
            pool.lock().expect("not poisoned").push(scratch);
            out
        };
        // An absorbing substrate transmits nothing (no exit leaves downwards).
        let transmits = n_sub.im == 0.0 && list.iter().any(|c| c.down);
        let down = || {
            if transmits {
                side(true, n_sub.re)
            } else {
                Ok(diffraction::Pattern::default())
            }
        };
        // Side by side only where two grids a thread are small: a grid may take up to 3 GiB
        // with its buffers (`diffraction::MAX_GRID_CELLS`).
        let cells = |n_out| {
            let [mx, my] =
                diffraction::grid_cells(self.sample.tile_nm, lambda, n_out, self.lattice);
            mx.saturating_mul(my)
        };
        let (up, down) = if cells(self.est.n_up).max(cells(n_sub.re)) <= SIDE_BY_SIDE_CELLS {
            rayon::join(|| side(false, self.est.n_up), down)
        } else {
            (side(false, self.est.n_up), down())
        };
        Ok((up?, down?))
    }

    /// Bin `j`'s contributions of the exits kept once for every bin (path sharing), into
    /// `out`, each the bits `tally` forms a bin's own with ([`Run::contribution_in_bin`]):
    /// their phases first, then every sine and cosine in one batch (`phase::sin_cos_each`;
    /// one C library call per exit was a tenth of a diffraction run).
    fn contributions(
        &self,
        j: usize,
        d: DVec3,
        shared: &[diffraction::SharedExit],
        out: &mut Vec<diffraction::Contribution>,
        phases: &mut Phases,
    ) {
        let k = 2.0 * std::f64::consts::PI / self.cfg.wavelengths.centre(j);
        let kn = k * self.est.n_up;
        let k_in = [kn * d.x, kn * d.y];
        phases.psi.clear();
        phases.psi.extend(shared.iter().map(|s| {
            let entry_phase = self.est.entry_phase(k, d, s.origin);
            diffraction::exit_phase(&s.exit, k, entry_phase, k_in)
        }));
        crate::accumulate::phase::sin_cos_each(&phases.psi, &mut phases.sin, &mut phases.cos);
        out.clear();
        out.extend(shared.iter().zip(phases.sin.iter().zip(&phases.cos)).map(
            |(s, (&sin, &cos))| {
                diffraction::contribution_at(&s.exit, s.tree, s.slot, k, (sin, cos))
            },
        ));
    }

    /// Exit `slot` of tree `tree` (launched at `origin`, world nm, along `d`) as bin `j`'s
    /// contribution: at the bin's centre (`jittered_lambda`), with the incident wave's
    /// phase at the launch point. The one place both paths form it, so they give the same
    /// bits.
    pub(super) fn contribution_in_bin(
        &self,
        j: usize,
        d: DVec3,
        origin: DVec3,
        exit: &crate::trace::Exit,
        tree: u32,
        slot: u32,
    ) -> diffraction::Contribution {
        let k = 2.0 * std::f64::consts::PI / self.cfg.wavelengths.centre(j);
        let entry_phase = self.est.entry_phase(k, d, origin);
        let kn = k * self.est.n_up;
        diffraction::contribution(exit, tree, slot, k, entry_phase, [kn * d.x, kn * d.y])
    }
}

/// The largest grid (cells) whose two hemispheres are transformed side by side: 200 MB
/// with its buffers.
const SIDE_BY_SIDE_CELLS: usize = 1 << 20;

/// The tubes' shapes of both hemispheres (up, down), found once under path sharing.
type Shapes = (Vec<diffraction::TubeShape>, Vec<diffraction::TubeShape>);

/// A thread's buffers for a bin's exit phases and their sines and cosines.
#[derive(Default)]
struct Phases {
    psi: Vec<f64>,
    sin: Vec<f64>,
    cos: Vec<f64>,
}
