//! One block of trees: entry points, wavelengths, tracing and the estimator's tally per
//! wavelength. Tree `i` draws from its own random stream, so blocks are independent and
//! their sums do not depend on which worker ran them.

use std::sync::atomic::Ordering;

use glam::DVec3;

use super::groups::{group_of, group_size};
use super::launch::{entry_point, lattice_point};
use super::lost::Overflow;
use super::run::{Run, Tracing, Worker};
use crate::accumulate::block::BlockCell;
use crate::accumulate::{Scratch, diffraction};
use crate::optics::fresnel::Field;
use crate::rng::Rng;
use crate::spectrum::Wavelengths;
use crate::trace::{DroppedPower, Lane, Tree, launch_fields};

/// Where one tree enters and how it travels: its index, launch point in the sample's frame
/// and in the world (nm), direction of travel, launch fields, and its random-event stream.
struct Launch {
    i: u64,
    /// The direction's index in the run.
    di: usize,
    origin: DVec3,
    world_origin: DVec3,
    d: DVec3,
    e0: [Field; 2],
    stream: u64,
}

impl Run<'_> {
    /// The trees `trees` of direction `di` (towards the light `wi`): one `BlockCell` per
    /// wavelength.
    pub(super) fn block(
        &self,
        w: &mut Worker,
        di: usize,
        wi: DVec3,
        shifts: &[[f64; 2]],
        adaptive: bool,
        trees: std::ops::Range<u64>,
    ) -> Vec<BlockCell> {
        let cfg = self.cfg;
        let d = -wi;
        let e0 = launch_fields(d);
        let mut out: Vec<BlockCell> = (0..self.nl).map(|_| BlockCell::default()).collect();
        if self.tracing == Tracing::PerWavelength {
            self.block_by_wavelength(w, di, d, e0, shifts, adaptive, trees, &mut out);
            w.dense.drain(&mut out);
            return out;
        }
        for i in trees {
            // A cancelled run stops within a tree, not a chunk of blocks (Ctrl-C in Python
            // took 20 s on a steep height map); its sums are never used.
            if cfg
                .cancel
                .as_ref()
                .is_some_and(|c| c.load(Ordering::Relaxed))
            {
                break;
            }
            let mut rng = Rng::new(cfg.seed, (cfg.first_direction + di as u64) << 40 | i);
            let origin = self.entry(di, i, shifts, &mut rng);
            // The tree's jitter in bin j: the j-th draw of its stream (tracing draws
            // nothing from it).
            for j in 0..self.nl {
                w.lambdas[j] = self.jittered_lambda(di, i, j, adaptive, rng.uniform());
            }
            // Random events' own stream (Russian roulette; particle media re-seed it per
            // wavelength below), so results do not depend on scheduling.
            let stream = ((cfg.first_direction + di as u64) << 40) | i;
            w.stack.set_stream(
                cfg.seed ^ 0x5CA7_7E2E_D000_0000,
                stream.wrapping_mul(0x1_0000) | 0xFFFF,
            );
            let launch = Launch {
                i,
                di,
                origin,
                world_origin: origin + cfg.origin_nm,
                d,
                e0,
                stream,
            };
            self.trace_together(w, &launch);
            for (j, cell) in out.iter_mut().enumerate() {
                let t = self.tree_of(w, j, &launch);
                self.tally(w, t, j, cell, &launch);
            }
        }
        w.dense.drain(&mut out);
        out
    }

    /// The trees `trees` of direction `di` traced a wavelength at a time (`Tracing::
    /// PerWavelength`: particle media), wavelength-major: every tree of the block at bin 0,
    /// then at bin 1, and so on. A particle medium's tables of one wavelength (a few
    /// hundred kB: each sampled radius's envelope and alias table) then stay in the
    /// core's cache, where tree-major order walked all of them per tree and spent about
    /// half of the white paint's tracing time waiting for memory. Each tree and
    /// wavelength draws from its own stream and each bin's cell takes the trees in the
    /// same order, so the sums are the same bits in either order.
    #[allow(clippy::too_many_arguments)]
    fn block_by_wavelength(
        &self,
        w: &mut Worker,
        di: usize,
        d: DVec3,
        e0: [Field; 2],
        shifts: &[[f64; 2]],
        adaptive: bool,
        trees: std::ops::Range<u64>,
        out: &mut [BlockCell],
    ) {
        let (cfg, nl) = (self.cfg, self.nl);
        let cancelled = || {
            cfg.cancel
                .as_ref()
                .is_some_and(|c| c.load(Ordering::Relaxed))
        };
        let mut launches = Vec::with_capacity((trees.end - trees.start) as usize);
        let mut lambdas = Vec::with_capacity(launches.capacity() * nl);
        for i in trees {
            let mut rng = Rng::new(cfg.seed, (cfg.first_direction + di as u64) << 40 | i);
            let origin = self.entry(di, i, shifts, &mut rng);
            for j in 0..nl {
                lambdas.push(self.jittered_lambda(di, i, j, adaptive, rng.uniform()));
            }
            launches.push(Launch {
                i,
                di,
                origin,
                world_origin: origin + cfg.origin_nm,
                d,
                e0,
                stream: ((cfg.first_direction + di as u64) << 40) | i,
            });
        }
        for (j, cell) in out.iter_mut().enumerate() {
            for (n, launch) in launches.iter().enumerate() {
                // A cancelled run's sums are never used.
                if cancelled() {
                    return;
                }
                w.lambdas[j] = lambdas[n * nl + j];
                let t = self.tree_of(w, j, launch);
                self.tally(w, t, j, cell, launch);
            }
        }
    }

    /// Tree `i`'s entry point on the tile, nm (sample frame, at the top of the scene): a
    /// lattice point (diffraction), a uniform point (`random_entry`) or the R2 sequence.
    /// Open samples launch in the interior, the guard band from every side.
    fn entry(&self, di: usize, i: u64, shifts: &[[f64; 2]], rng: &mut Rng) -> DVec3 {
        let (cfg, sample) = (self.cfg, self.sample);
        let g = sample.guard_nm.unwrap_or(0.0);
        let xy = if self.diffracts(di) {
            lattice_point(i, self.lattice, shifts[0], sample.tile_nm)
        } else if cfg.random_entry {
            [
                rng.range(g, sample.tile_nm[0] - g),
                rng.range(g, sample.tile_nm[1] - g),
            ]
        } else {
            let (group, m) = group_of(i, self.groups_of(di));
            entry_point(m, shifts[group], sample.tile_nm, g)
        };
        DVec3::new(xy[0], xy[1], self.scene.z_top)
    }

    /// Tree `i`'s wavelength in bin `j` of direction `di`, nm, from the uniform draw `u`:
    /// stratified jitter (tree i, index m of its replicate group's n trees, takes stratum
    /// m of n in every bin: each group is stratified on its own, so the groups' estimates
    /// stay identically distributed).
    fn jittered_lambda(&self, di: usize, i: u64, j: usize, adaptive: bool, u: f64) -> f64 {
        match &self.cfg.wavelengths {
            Wavelengths::Bins(e) => {
                // Adaptive runs do not know N: a golden-ratio sequence (low-discrepancy
                // for every prefix) replaces the strata. The diffraction method sums trees
                // coherently, so they share one wavelength: the bin's centre. Where one
                // traced tree serves every wavelength (path sharing) its exits are the
                // same at any wavelength, so the transform takes them at the centre
                // (`tally`) while the rays' totals, which the orders are scaled to, keep
                // the jitter: at one wavelength the beamlet estimator's partial coherence
                // does not average out (the seed's film at 15 deg and 435 nm: R + T =
                // 1.009 at the centre, 1.0007 jittered).
                let frac = if self.cell_diffracts(di, j) && self.tracing != Tracing::Shared {
                    0.5
                } else if adaptive {
                    (i as f64 * 0.618_033_988_749_894_9 + u).fract()
                } else {
                    let k = self.groups_of(di);
                    let (group, m) = group_of(i, k);
                    (m as f64 + u) / group_size(group, self.rays_of(di), k) as f64
                };
                e[j] + (e[j + 1] - e[j]) * frac
            }
            Wavelengths::Monochromatic(v) => v[j],
        }
    }

    /// Counts one traced tree of `segments` segments.
    fn count(&self, segments: u64) {
        let c = &self.counters;
        c.segments.fetch_add(segments, Ordering::Relaxed);
        c.traces.fetch_add(1, Ordering::Relaxed);
    }

    /// A traced tree moved to the world (exits at `origin_nm`) and prepared for the
    /// estimator.
    fn traced(&self, tree: &mut Tree, scratch: &mut Scratch) {
        for x in &mut tree.exits {
            x.x += self.cfg.origin_nm;
        }
        self.est.prepare(tree, scratch);
        self.counters
            .leaks
            .fetch_add(u64::from(tree.leaks), Ordering::Relaxed);
    }

    /// Traces what is traced once for all wavelengths: the shared geometry (path sharing),
    /// or every wavelength at once (lanes). Per-wavelength tracing happens in `tree_of`.
    fn trace_together(&self, w: &mut Worker, l: &Launch) {
        let cfg = self.cfg;
        match self.tracing {
            Tracing::Shared => self.count(self.scene.trace(
                l.origin,
                l.d,
                l.e0,
                &self.fixed_indices,
                self.lambda_max,
                &cfg.limits,
                &mut w.stack,
                &mut w.trees[0],
            )),
            Tracing::Lanes => {
                for (j, v) in w.indices.iter_mut().enumerate() {
                    self.sample.indices_into(w.lambdas[j], v);
                }
                let lanes: Vec<Lane> = (w.indices.iter().zip(&w.lambdas))
                    .map(|(v, &l)| Lane {
                        indices: v,
                        lambda_nm: l,
                    })
                    .collect();
                self.count(self.scene.trace_lanes(
                    l.origin,
                    l.d,
                    l.e0,
                    &lanes,
                    &cfg.limits,
                    &mut w.stack,
                    &mut w.trees,
                ));
            }
            Tracing::PerWavelength => {}
        }
    }

    /// The index in `w.trees` of the tree of wavelength bin `j`, traced and prepared.
    fn tree_of(&self, w: &mut Worker, j: usize, l: &Launch) -> usize {
        match self.tracing {
            Tracing::Shared => {
                if j == 0 {
                    self.traced(&mut w.trees[0], &mut w.scratch);
                }
                0
            }
            Tracing::Lanes => {
                self.traced(&mut w.trees[j], &mut w.scratch);
                j
            }
            Tracing::PerWavelength => {
                let lambda = w.lambdas[j];
                self.sample.indices_into(lambda, &mut w.indices[0]);
                // Volume scattering's own stream for this tree and wavelength.
                w.stack.set_stream(
                    self.cfg.seed ^ 0x5CA7_7E2E_D000_0000,
                    l.stream.wrapping_mul(0x1_0000).wrapping_add(j as u64),
                );
                self.count(self.scene.trace(
                    l.origin,
                    l.d,
                    l.e0,
                    &w.indices[0],
                    lambda,
                    &self.cfg.limits,
                    &mut w.stack,
                    &mut w.trees[0],
                ));
                self.traced(&mut w.trees[0], &mut w.scratch);
                0
            }
        }
    }

    /// The estimator's tally of tree `w.trees[t]` at wavelength bin `j` into `cell`:
    /// buckets, R and T with their squares, absorbed, created, limited and dropped power,
    /// and the diffraction method's contributions.
    fn tally(&self, w: &mut Worker, t: usize, j: usize, cell: &mut BlockCell, l: &Launch) {
        let est = &self.est;
        let lambda = w.lambdas[j];
        let tree = &w.trees[t];
        w.deps.clear();
        w.glob.clear();
        let k = 2.0 * std::f64::consts::PI / lambda;
        let entry_phase = est.entry_phase(k, l.d, l.world_origin);
        est.deposit(
            tree,
            lambda,
            entry_phase,
            &mut w.scratch,
            &mut w.deps,
            &mut w.glob,
        );
        // Next-event estimation spread over the reflected buckets (`Tree::nee`).
        w.deps.extend(
            (tree.nee.iter().enumerate())
                .filter(|(_, v)| **v != 0.0)
                .map(|(b, v)| (crate::accumulate::key(b, false), *v)),
        );
        let (r, t) = w
            .dense
            .add_tree(j, &w.deps, &w.glob, w.scratch.mueller_deposits());
        // Each tree on its own: its exits and dropped power hold no more than it was
        // launched with and its events were allowed to add (issue 46).
        if !self.global {
            let over = tree.overflow(lambda);
            if over > super::run::OVERFLOW_ROUNDING {
                self.note_overflow(Overflow {
                    power: over,
                    direction: l.di,
                    bin: j,
                    tree: l.i,
                });
            }
        }
        if self.cell_diffracts(l.di, j) && self.tracing == Tracing::Shared {
            // One traced tree serves every bin: its exits once, with the first bin that
            // diffracts (`Run::diffract` forms each bin's contributions).
            if (0..j).all(|b| !self.cell_diffracts(l.di, b)) {
                cell.shared
                    .extend(tree.exits.iter().enumerate().map(|(slot, x)| {
                        diffraction::SharedExit {
                            tree: l.i as u32,
                            slot: slot as u32,
                            origin: l.world_origin,
                            exit: *x,
                        }
                    }));
            }
        } else if self.cell_diffracts(l.di, j) {
            for (slot, x) in tree.exits.iter().enumerate() {
                cell.diffraction.push(self.contribution_in_bin(
                    j,
                    l.d,
                    l.world_origin,
                    x,
                    l.i as u32,
                    slot as u32,
                ));
            }
        }
        let DroppedPower {
            all: dropped,
            limit: dropped_limit,
            escaped,
        } = tree.dropped(lambda);
        cell.trees += 1;
        cell.r.0 += r;
        cell.r.1 += r * r;
        cell.t.0 += t;
        cell.t.1 += t * t;
        let absorbed = absorbed_power(tree, lambda, r, t, dropped, self.global);
        cell.absorbed += absorbed;
        // A tree that met particles or Russian roulette carries importance weights: its
        // R + T may exceed 1 while the mean over trees conserves energy, which
        // check_physical judges. Only deterministic ray series count as created, and only
        // up to what their events inside absorbers added (`Tree::excess`): the rest of a
        // tree's excess is the beamlet estimator's partial coherence between paths that
        // left far apart (a clear coat's reflection and the light of a flake below it),
        // noise that averages out over trees, not power a series created.
        if tree.absorbing && !self.global && tree.random_events == 0 {
            cell.created += (-absorbed).max(0.0).min(tree.excess);
        }
        cell.limited += tree.limited_power;
        cell.rebalanced += w.scratch.corrected();
        cell.limit_bound += 2.0 * (dropped_limit * (r + t).max(0.0)).sqrt() + dropped_limit;
        cell.dropped += dropped;
        cell.dropped_limit += dropped_limit;
        cell.escaped += escaped;
        self.counters
            .energy_faults
            .fetch_add(u64::from(tree.energy_faults), Ordering::Relaxed);
    }

    /// Counts a tree that carried out more power than it may ([`Overflow`]), keeping the
    /// worst.
    fn note_overflow(&self, o: Overflow) {
        let c = &self.counters;
        c.overflow_trees.fetch_add(1, Ordering::Relaxed);
        let mut worst = c
            .worst_overflow
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        *worst = Some(worst.map_or(o, |w| w.worse(o)));
    }
}

/// Absorbed power of one tree at one wavelength: what entered absorbing media and did not
/// leave, `1 - R - T - dropped` with the tree's coherent totals (exact in the plane-wave
/// limit, where the coherent sum is the exact field; docs/design.md §3), or 0 when no power
/// entered an absorbing medium. Global mode has no per-tree coherent totals; there the
/// incoherent exit power stands in for `R + T`.
pub(super) fn absorbed_power(
    tree: &Tree,
    lambda: f64,
    r: f64,
    t: f64,
    dropped: f64,
    global: bool,
) -> f64 {
    // A tree with random events (roulette, particle scattering) balances only on average:
    // its residual is kept even without absorption, so the column sums to 1 and averages
    // to the true absorption (0 for a lossless sample).
    if !tree.absorbing && tree.random_events == 0 {
        return 0.0;
    }
    let out = if global {
        tree.exit_power(lambda)
    } else {
        r + t
    };
    1.0 - out - dropped
}
