//! The run driver: preparing the scene and estimator, tracing blocks of trees per
//! incident direction, reducing them in block order, and finishing the header and stats.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use rayon::prelude::*;

use super::groups::{GroupSums, error_groups};
use super::growth;
use super::lost::{Lost, LostSums};
use super::prepare::{ambient_lossless, media_in_range, method_refusals};
use super::{BLOCK, CHUNK_BLOCKS_PER_THREAD, MIN_CHUNK_BLOCKS, SimError};
use super::{
    BRIGHT_SHARE, CREATED_REFUSED, DIFFRACTION_RATIO_REFUSED, DiffractionCell, DirectionStats,
    SimConfig, SimStats, achieved_error, bright_bucket_error, check_physical, sample_hash,
};
use crate::accumulate::block::{BlockCell, Dense, add_block};
use crate::accumulate::file::{Accumulator, EntryPoints, Header, Settings};
use crate::accumulate::{Cell, Coherence, Estimator, Scratch, diffraction};
use crate::geom::from_spherical;
use crate::optics::C64;
use crate::rng::Rng;
use crate::sample::Sample;
use crate::trace::{Scene, TraceStack, Tree};

/// Counters every worker adds to.
#[derive(Default)]
pub(super) struct Counters {
    pub(super) done: AtomicU64,
    pub(super) segments: AtomicU64,
    pub(super) leaks: AtomicU64,
    pub(super) traces: AtomicU64,
    pub(super) energy_faults: AtomicU64,
    /// Trees whose exits and dropped power held more than they were launched with and
    /// their events were allowed to add (`Tree::overflow`), and the worst of them.
    pub(super) overflow_trees: AtomicU64,
    pub(super) worst_overflow: std::sync::Mutex<Option<super::lost::Overflow>>,
}

/// Overflow (`Tree::overflow`) beyond this fraction of the launched power is refused:
/// rounding of sums of order-1 terms (measured at most 1e-12 on every shipped sample and
/// both car-paint forms of issue 46, 0 to 85 degrees).
pub const OVERFLOW_ROUNDING: f64 = 1e-9;

/// One worker's reusable state: the ray stack, the trees (one per wavelength when they
/// are traced at once), the estimator's scratch and deposits, the dense block sums, and
/// the media indices and wavelength of each tree.
pub(super) struct Worker {
    pub(super) stack: TraceStack,
    pub(super) trees: Vec<Tree>,
    pub(super) scratch: Scratch,
    pub(super) deps: Vec<(u32, f64)>,
    pub(super) glob: Vec<(u32, [crate::optics::fresnel::Field; 2])>,
    pub(super) dense: Dense,
    pub(super) indices: Vec<Vec<C64>>,
    pub(super) lambdas: Vec<f64>,
}

/// How a tree's wavelengths are traced.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Tracing {
    /// One tree at the longest wavelength serves every wavelength (path sharing).
    Shared,
    /// Every wavelength at once, rays shared until a dispersive refraction.
    Lanes,
    /// Each wavelength on its own.
    PerWavelength,
}

/// Everything a run shares between its directions and workers.
pub(super) struct Run<'a> {
    pub(super) sample: &'a Sample,
    pub(super) cfg: &'a SimConfig,
    pub(super) scene: Scene<'a>,
    pub(super) est: Estimator,
    pub(super) settings: Settings,
    /// Geometry traced once for all wavelengths.
    pub(super) sharing: bool,
    pub(super) tracing: Tracing,
    pub(super) global: bool,
    /// Each cell's method (direction-major; `true`: the diffraction method, whose
    /// direction's trees launch on `lattice` and whose exits are kept for the far-field
    /// transform): all of them with `Coherence::Diffraction`, the choice of
    /// `auto::choose` with `Coherence::Auto`.
    pub(super) cell_diffraction: Vec<bool>,
    /// Each cell taken by the rigorous solver (`rigorous.rs`), and the sample sliced for it.
    pub(super) cell_rigorous: Vec<bool>,
    pub(super) rigorous: Option<crate::reference::rigorous::Rigorous>,
    pub(super) rigorous_cells: std::sync::Mutex<Vec<Option<super::RigorousCell>>>,
    /// What an auto run's rigorous cells could not do, with their direction.
    pub(super) rigorous_notes: std::sync::Mutex<Vec<(usize, String)>>,
    /// `Coherence::Auto`: a diffraction cell whose transform cannot hold the ray field
    /// takes rays (`diffract`) instead of refusing the run.
    pub(super) auto: bool,
    /// What `auto::choose` had to say, of the whole run and of each direction alone (kept
    /// in the `.gsa`: `warnings::stored_warnings`).
    pub(super) auto_notes: Vec<String>,
    pub(super) auto_direction_notes: Vec<Vec<String>>,
    /// The sample's sheets' scales (`validity::sheet_scales`).
    pub(super) sheets: Vec<Option<crate::sample::validity::Scales>>,
    pub(super) lattice: [u64; 2],
    /// `Coherence::Auto` with trees to raise to (`raise`): a cell whose transform cannot
    /// hold the ray field stops the run after its direction ([`Run::unheld`]), where it
    /// would otherwise take rays.
    pub(super) pilot: bool,
    /// Replicate groups per direction (`Header::error_groups`; 0 for none).
    pub(super) error_groups: u64,
    pub(super) nl: usize,
    pub(super) lambda_max: f64,
    /// Media indices at the longest wavelength (the shared geometry's).
    pub(super) fixed_indices: Vec<C64>,
    pub(super) counters: Counters,
    /// The diffraction method's contributions per wavelength, kept from direction to
    /// direction (cleared) so that their pages are faulted in once per run: grown afresh,
    /// their doublings and page faults were a third of a diffraction run's time, serial.
    pub(super) contribs: std::sync::Mutex<Vec<Vec<diffraction::Contribution>>>,
    /// `--rays` as asked (an explicit diffraction run's configuration holds its lattice's
    /// count: `traced_config`).
    pub(super) rays_asked: u64,
    /// Wall time of `prepare` (the scene's build, the sample's hash), s.
    pub(super) setup_seconds: f64,
}

impl<'a> Run<'a> {
    /// Stage 1: the scene, whether paths are shared, the media at every wavelength the
    /// run evaluates, the estimator and the header's settings.
    pub(super) fn prepare(sample: &'a Sample, cfg: &'a SimConfig) -> Result<Run<'a>, SimError> {
        let mut scene = Scene::new(sample, cfg.backend)?;
        let scattering = scene.scatters();
        let explicit = cfg.coherence == Coherence::Diffraction;
        method_refusals(sample, cfg, scattering)?;
        let dispersive = sample.media.iter().any(|m| m.model.is_dispersive()) || scattering;
        // A coating's coefficients depend on the wavelength even with constant indices.
        let coated = sample.interfaces.iter().any(|i| !i.coating.is_empty());
        // So do those of a thin absorbing film, which the tracer hands to the transfer
        // matrix (`trace::film`) wherever one lies behind a lossless medium.
        let lambdas: Vec<f64> = cfg.wavelengths.values_nm().to_vec();
        let absorbing = sample.media.iter().any(|m| {
            m.scattering.is_none()
                && lambdas
                    .iter()
                    .any(|&l| m.model.eval(l).is_ok_and(|(_, k)| k > 0.0))
        });
        let sharing = cfg
            .path_sharing
            .unwrap_or(!dispersive && !coated && !absorbing);
        super::prepare::sharing_refusal(sharing, dispersive, coated, absorbing)?;
        // Every wavelength the run evaluates must be inside every medium's range.
        media_in_range(sample, &lambdas)?;
        if scattering {
            super::prepare::tabulate_scattering(&mut scene, cfg, &lambdas)?;
        }
        // Spread over every bucket where the estimator sums each exit's power alone
        // (Mueller runs keep one direction per event: its exits carry Jones matrices).
        let spread = (matches!(cfg.coherence, Coherence::Beamlet | Coherence::Auto)
            && !cfg.mueller)
            .then_some(crate::trace::SpreadGrid {
                theta_bins: cfg.buckets.theta_bins,
                phi_bins: cfg.buckets.phi_bins,
            });
        let next_event = scattering && cfg.next_event && scene.enable_next_event(spread);
        let index_at = |l: f64| -> Vec<C64> {
            let mut v = Vec::new();
            sample.indices_into(l, &mut v);
            v
        };
        let nl = cfg.wavelengths.count();
        let lambda_max = cfg.wavelengths.max();
        let est = Estimator {
            // The diffraction method keeps the beamlet estimator's totals as the ray
            // method's, which its own are checked against.
            mode: if explicit || cfg.coherence == Coherence::Auto {
                Coherence::Beamlet
            } else {
                cfg.coherence
            },
            rho_nm: cfg.rho_nm,
            buckets: cfg.buckets,
            n_up: index_at(lambda_max)[scene.ambient].re,
            n_down: index_at(lambda_max)[scene.substrate].re,
            precision: cfg.precision,
            lambda_max_nm: lambda_max,
            reference: cfg.reference_estimator,
            mueller: cfg.mueller,
        };
        ambient_lossless(sample, &scene, &lambdas, dispersive)?;
        // The sheets' scales, measured once: the auto choice and the warnings kept with the
        // result (`warnings::stored_warnings`) judge them.
        let sheets = crate::sample::validity::sheet_scales(sample);
        let (choice, direction_notes) =
            super::prepare::method_choice(sample, cfg, &scene, &lambdas, est.n_up, &sheets)?;
        let settings = Settings {
            sample_name: sample.name.clone(),
            sample_hash: sample_hash(sample),
            theta_i_deg: cfg.theta_i_deg.clone(),
            phi_i_deg: cfg.phi_i_deg,
            phi_i_each_deg: cfg.phi_each_deg.clone(),
            wavelength_mode: cfg.wavelengths.mode(),
            wavelengths_nm: lambdas,
            coherence: cfg.coherence,
            coherence_radius_nm: cfg.rho_nm,
            cutoff: cfg.limits.cutoff,
            max_depth: cfg.limits.max_depth,
            theta_o_bins: cfg.buckets.theta_bins,
            phi_o_bins: cfg.buckets.phi_bins,
            phase_precision: cfg.precision,
            max_wraps: cfg.limits.max_wraps,
            max_segments: cfg.limits.max_segments,
            entry_points: if cfg.random_entry {
                EntryPoints::Uniform
            } else {
                EntryPoints::R2
            },
            path_sharing: sharing,
            tolerance: cfg.tolerance,
            target_stderr: cfg.target_stderr,
            max_rays: cfg.adaptive().then_some(cfg.max_rays),
            first_direction: cfg.first_direction,
            methods: Vec::new(),
            next_event,
            mueller: cfg.mueller,
            flat_top: crate::sample::flat_top(sample, scene.ambient),
            anisotropy: Some(crate::sample::symmetry::anisotropy(sample))
                .filter(|a| a.anisotropic()),
            rigorous: choice.rigorous.contains(&true).then_some(cfg.rigorous),
        };
        Ok(Run {
            sample,
            cfg,
            est,
            settings,
            sharing,
            error_groups: error_groups(cfg, scattering),
            tracing: if sharing {
                Tracing::Shared
            } else if cfg.wavelength_sharing && nl > 1 && !scattering {
                Tracing::Lanes
            } else {
                Tracing::PerWavelength
            },
            global: cfg.coherence == Coherence::Global,
            cell_diffraction: choice.diffraction,
            cell_rigorous: choice.rigorous,
            rigorous: choice.solver,
            rigorous_cells: std::sync::Mutex::new(vec![None; cfg.theta_i_deg.len() * nl]),
            rigorous_notes: Default::default(),
            auto: cfg.coherence == Coherence::Auto,
            auto_notes: choice.notes,
            auto_direction_notes: direction_notes,
            sheets,
            lattice: [cfg.rays, 1],
            pilot: false,
            nl,
            lambda_max,
            fixed_indices: index_at(lambda_max),
            counters: Counters::default(),
            contribs: Default::default(),
            rays_asked: cfg.rays,
            setup_seconds: 0.0,
            scene,
        })
    }

    /// Whether direction `di` has a cell of the diffraction method (its trees launch on
    /// the lattice).
    pub(super) fn diffracts(&self, di: usize) -> bool {
        self.cell_diffraction[di * self.nl..(di + 1) * self.nl]
            .iter()
            .any(|&d| d)
    }

    /// The trees of direction `di`: the lattice's `nx * ny` where an auto run's cells take
    /// the diffraction method (which an explicit run's configuration already holds:
    /// `traced_config`), `--rays` elsewhere. A direction's count depends on its own cells
    /// only, so a batch unit traces as the whole run's direction does.
    pub(super) fn rays_of(&self, di: usize) -> u64 {
        if self.auto && self.diffracts(di) {
            self.lattice[0] * self.lattice[1]
        } else {
            self.cfg.rays
        }
    }

    /// Replicate groups of direction `di` (`groups`): `ERROR_GROUPS` where its trees enter
    /// on the R2 sequence and have per-tree errors, else 1 (one sequence, as before groups).
    pub(super) fn groups_of(&self, di: usize) -> u64 {
        if self.error_groups > 1 && !self.diffracts(di) {
            self.error_groups
        } else {
            1
        }
    }

    /// Bucket keys per cell (both hemispheres).
    fn nkeys(&self) -> usize {
        2 * self.cfg.buckets.len()
    }

    /// Whether cell (`di`, `j`) takes the diffraction method.
    pub(super) fn cell_diffracts(&self, di: usize, j: usize) -> bool {
        self.cell_diffraction[di * self.nl + j]
    }

    fn worker(&self) -> Worker {
        Worker {
            stack: TraceStack::default(),
            trees: (0..self.nl).map(|_| Tree::default()).collect(),
            scratch: Scratch::default(),
            deps: Vec::new(),
            glob: Vec::new(),
            dense: Dense::new(
                self.nl,
                2 * self.cfg.buckets.len(),
                self.global,
                self.cfg.mueller,
            ),
            indices: vec![Vec::new(); self.nl],
            lambdas: vec![0.0; self.nl],
        }
    }

    /// The first cell of `range` whose diffraction transform held a share of the ray
    /// field's power outside `[DIFFRACTION_RATIO_REFUSED, 1 / DIFFRACTION_RATIO_REFUSED]`,
    /// in a run of the diffraction method (an auto run takes rays in such cells).
    pub(super) fn unheld(
        &self,
        diffraction: &[DiffractionCell],
        range: std::ops::Range<usize>,
    ) -> Option<super::raise::Unheld> {
        let k = if self.cfg.coherence == Coherence::Diffraction {
            range.clone().find(|&k| {
                let d = &diffraction[k];
                d.rays_r + d.rays_t > 0.0
                    && !(d.ratio() >= DIFFRACTION_RATIO_REFUSED
                        && d.ratio() <= 1.0 / DIFFRACTION_RATIO_REFUSED)
            })?
        } else if self.pilot {
            // An auto cell that took rays for it (and that the rigorous solver did not take).
            range.clone().find(|&k| diffraction[k].fell_back)?
        } else {
            return None;
        };
        Some(super::raise::Unheld {
            theta_deg: (self.cfg.theta_i_deg.get(k / self.nl).copied()).unwrap_or(f64::NAN),
            lambda_nm: self.settings.wavelength(k % self.nl),
            ratio: diffraction[k].ratio(),
        })
    }

    /// The refusal of the diffraction method's result where its transform held a share of
    /// the ray field's power outside `[DIFFRACTION_RATIO_REFUSED, 1 /
    /// DIFFRACTION_RATIO_REFUSED]` ([`Run::unheld`]). Checked after each direction (the most
    /// oblique first, where the rays sample the field most coarsely), so a run that will be
    /// refused stops at the first such direction, not after the others (issue 48: 2 min
    /// 40 s).
    pub(super) fn diffraction_refusal(&self, unheld: &super::raise::Unheld) -> SimError {
        let (theta, lambda) = (unheld.theta_deg, unheld.lambda_nm);
        // Where the tangent plane fails, more trees may sample the same wrong field: the
        // seed's film at 75 deg and 495 nm held 1.276, 1.252 and 1.270 at 4,096, 16,384 and
        // 65,536 trees (issue 48). Yet rough glass at 40 deg and 500 nm, below the same
        // margin, held 0.50 at 256 trees and 0.92 at 1,024: the run raises its trees while
        // that helps (`raise`), and says what it tried.
        let margin = super::auto::physical_optics_margin(self.sample, &self.sheets, theta, lambda);
        let advice = if margin < crate::sample::validity::PHYSICAL_OPTICS_MIN {
            format!(
                "the tangent plane the method rests on fails at this angle (k r_c cos^3 theta = {margin:.1}, below {}; Ogilvy 1991, §4.2), where more trees need not bring the transform back: --coherence auto takes rays in such cells, or leave this angle out",
                crate::sample::validity::PHYSICAL_OPTICS_MIN
            )
        } else {
            "the rays sample the field too coarsely for it (raise --rays, or --max-rays for the run to raise them itself), or the sample has structure near or below the wavelength, where neither rays nor physical optics hold (use --coherence rigorous, or --coherence auto, which takes it)".to_string()
        };
        SimError::Unphysical(format!(
            "sample '{}', theta_i {theta} deg, wavelength {lambda} nm: the diffraction transform holds {:.3} of the ray field's power in propagating orders (outside [{DIFFRACTION_RATIO_REFUSED}, {:.2}]): {advice}. (The method traces the most oblique incidence first, so this is found before the rest of the run.)",
            self.sample.name,
            unheld.ratio,
            1.0 / DIFFRACTION_RATIO_REFUSED
        ))
    }

    /// Stage 2: every tree of incident direction `di`, in batches (one for a fixed budget;
    /// until the tolerance is met for an adaptive one), each batch's blocks traced in
    /// parallel a chunk at a time and added to the cells in block order.
    pub(super) fn direction(
        &self,
        di: usize,
        theta_deg: f64,
        cells: &mut [Cell],
        lost: Lost,
        progress: &(dyn Fn(u64) + Sync),
    ) -> Result<DirectionStats, SimError> {
        let (cfg, nl) = (self.cfg, self.nl);
        let wi = from_spherical(theta_deg.to_radians(), cfg.phi_of(di).to_radians());
        // One random shift per replicate group (the first is a run without groups' one).
        let mut shift_rng = Rng::new(cfg.seed, 0x5817_0000 + cfg.first_direction + di as u64);
        let groups = self.groups_of(di);
        let shifts: Vec<[f64; 2]> = (0..groups)
            .map(|_| [shift_rng.uniform(), shift_rng.uniform()])
            .collect();
        let mut group_sums = (groups > 1).then(|| GroupSums::new(groups, nl, self.nkeys()));
        let adaptive = cfg.adaptive();
        // An adaptive direction grows from its first batch by the error it measured
        // (`growth`). Batches are whole blocks, so where a run stops never changes the sums
        // of the batches before it.
        let first = if adaptive {
            growth::first_batch(cfg.rays)
        } else {
            self.rays_of(di)
        };
        let target = if adaptive {
            cfg.max_rays.max(first)
        } else {
            self.rays_of(di)
        };
        let (mut start, mut next) = (0u64, first);
        let mut history: Vec<(u64, f64)> = Vec::new();
        // The diffraction method's contributions per wavelength, in block order.
        let mut contribs = std::mem::take(&mut *self.contribs.lock().expect("not poisoned"));
        contribs.resize_with(nl, Vec::new);
        contribs.iter_mut().for_each(Vec::clear);
        // Under path sharing, every exit once for all bins, in block order.
        let mut shared: Vec<diffraction::SharedExit> = Vec::new();
        let mut reserved = false;
        loop {
            let end = next.min(target);
            let nblocks = (end - start).div_ceil(BLOCK);
            // Blocks are reduced a chunk at a time, each chunk in block order, so memory
            // does not grow with the ray count and the sums are those of one pass over all
            // blocks in order, whatever the chunk size or the thread count.
            let mut chunk_lo = 0;
            while chunk_lo < nblocks {
                if cfg
                    .cancel
                    .as_ref()
                    .is_some_and(|c| c.load(Ordering::Relaxed))
                {
                    // The caller gets SimError::Cancelled: these sums are never used.
                    return Ok(DirectionStats {
                        rays: start,
                        ..DirectionStats::untraced(theta_deg)
                    });
                }
                let chunk = (CHUNK_BLOCKS_PER_THREAD * rayon::current_num_threads() as u64)
                    .max(MIN_CHUNK_BLOCKS);
                let chunk_hi = (chunk_lo + chunk).min(nblocks);
                let blocks: Vec<Vec<BlockCell>> = (chunk_lo..chunk_hi)
                    .into_par_iter()
                    .map_init(
                        || self.worker(),
                        |w, b| {
                            let lo = start + b * BLOCK;
                            let hi = (lo + BLOCK).min(end);
                            let out = self.block(w, di, wi, &shifts, adaptive, lo..hi);
                            let n = self.counters.done.fetch_add(hi - lo, Ordering::Relaxed)
                                + (hi - lo);
                            progress(n);
                            out
                        },
                    )
                    .collect();
                if chunk_lo > 0 && !reserved {
                    // Room for the whole batch at the first chunk's rate, where doubling
                    // would copy the lists a few times over.
                    for c in contribs.iter_mut() {
                        let room = c.len() / chunk_lo as usize * (nblocks as usize + 1) * 21 / 20;
                        c.reserve(room.saturating_sub(c.len()));
                    }
                    reserved = true;
                }
                // Combine blocks in block order: the sums do not depend on scheduling.
                for (b, block) in (start / BLOCK + chunk_lo..).zip(blocks) {
                    for (j, bc) in block.into_iter().enumerate() {
                        add_block(&mut cells[di * nl + j], &bc);
                        if let Some(gs) = group_sums.as_mut() {
                            gs.add(b, j, &bc);
                        }
                        contribs[j].extend(bc.diffraction);
                        shared.extend(bc.shared);
                        let k = di * nl + j;
                        lost.limit_dropped[k] += bc.dropped_limit;
                        lost.escaped[k] += bc.escaped;
                        lost.limit_bound[k] += bc.limit_bound;
                        lost.created[k] += bc.created;
                        lost.limited[k] += bc.limited;
                        lost.rebalanced[k] += bc.rebalanced;
                    }
                }
                chunk_lo = chunk_hi;
            }
            start = end;
            if let Some(gs) = &group_sums {
                gs.estimate(&mut cells[di * nl..(di + 1) * nl]);
            }
            let achieved = if cfg.target_stderr.is_some() {
                bright_bucket_error(&cells[di * nl..(di + 1) * nl], BRIGHT_SHARE)
            } else {
                achieved_error(cells, di, nl, cfg.coherence)
            };
            let converged =
                adaptive && achieved.is_some_and(|a| a <= cfg.adaptive_goal().unwrap_or(0.0));
            if !adaptive || converged || start >= target {
                if self.diffracts(di) {
                    self.diffract(
                        di,
                        wi,
                        &contribs,
                        &shared,
                        &mut cells[di * nl..(di + 1) * nl],
                        &mut lost.diffraction[di * nl..(di + 1) * nl],
                    )?;
                }
                if contribs.iter().any(|c| c.capacity() > 0) {
                    *self.contribs.lock().expect("not poisoned") = contribs;
                }
                return Ok(DirectionStats {
                    theta_i_deg: theta_deg,
                    rays: start,
                    achieved,
                    converged,
                    by_median: cfg.target_stderr.is_some(),
                    // Filled by `simulate`, which runs the directions one at a time.
                    segments: 0,
                    leaks: 0,
                    envelope_violations: 0,
                });
            }
            history.extend(achieved.map(|a| (start, a)));
            next = growth::next_total(start, &history, cfg.adaptive_goal().unwrap_or(0.0));
        }
    }

    /// Stage 3: the run's statistics and header; energy faults and impossible results are
    /// errors, never output.
    pub(super) fn finish(
        self,
        cells: Vec<Cell>,
        lost: LostSums,
        directions: Vec<DirectionStats>,
        start_time: Instant,
    ) -> Result<(Accumulator, SimStats), SimError> {
        let (cfg, c) = (self.cfg, &self.counters);
        let faults = c.energy_faults.load(Ordering::Relaxed);
        if faults > 0 {
            return Err(SimError::Unphysical(format!(
                "sample '{}': {faults} interface events from a lossless medium did not conserve energy (|r|^2 + T != 1); this is a bug, please report it",
                self.sample.name
            )));
        }
        let overflows = c.overflow_trees.load(Ordering::Relaxed);
        let worst = *c
            .worst_overflow
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        if let Some(o) = worst.filter(|_| overflows > 0 && !cfg.allow_unphysical) {
            return Err(SimError::Unphysical(format!(
                "sample '{}', theta_i {} deg, wavelength bin {} ({:.1} nm), tree {}: the tree carried out {:.3e} more of the launched power than it was launched with (and {overflows} trees in all did); each tree is checked on its own, so no spread of the others can hide it. Its events created power that no model accounts for: an evanescent wave or a facet event outside what the plane-wave model holds (docs/physics.md, \"Energy per tree\"); this is a bug, please report it with the sample. The result is impossible and was not written; pass --allow-unphysical to write it anyway for debugging",
                self.sample.name,
                cfg.theta_i_deg
                    .get(o.direction)
                    .copied()
                    .unwrap_or(f64::NAN),
                o.bin + 1,
                self.settings.wavelength(o.bin),
                o.tree,
                o.power,
            )));
        }
        let stats = SimStats {
            trees: c.done.load(Ordering::Relaxed),
            traces: c.traces.load(Ordering::Relaxed),
            segments: c.segments.load(Ordering::Relaxed),
            leaks: c.leaks.load(Ordering::Relaxed),
            seconds: start_time.elapsed().as_secs_f64(),
            setup_seconds: self.setup_seconds,
            path_sharing: self.sharing,
            wavelength_sharing: self.tracing == Tracing::Lanes,
            directions,
            limit_dropped: lost.limit_dropped,
            escaped: lost.escaped,
            limit_bound: lost.limit_bound,
            created: lost.created,
            limited: lost.limited,
            rebalanced: lost.rebalanced,
            diffraction: lost.diffraction,
            envelope_violations: self.scene.scatter_violations(),
            auto_notes: (self.auto_notes.iter())
                .cloned()
                .chain(
                    (self.rigorous_notes.lock().expect("not poisoned").iter()).map(|n| n.1.clone()),
                )
                .collect(),
            rigorous: std::mem::take(&mut *self.rigorous_cells.lock().expect("not poisoned")),
            densest_scatterer: {
                let s = &self.settings;
                let mid = s.wavelength(s.wavelength_count() / 2);
                self.scene
                    .densest_scatterer(mid)
                    .map(|(m, depth)| (self.sample.media[m].name.clone(), depth))
            },
        };
        let mut settings = self.settings;
        if self.auto {
            let solved: Vec<bool> = stats.rigorous.iter().map(Option::is_some).collect();
            settings.methods = super::auto::method_strings(
                &self.cell_diffraction,
                &solved,
                &stats.diffraction,
                self.nl,
            );
        }
        // Adaptive runs: the most trees any direction used; each direction's own count too.
        let rays = stats
            .directions
            .iter()
            .map(|d| d.rays)
            .max()
            .unwrap_or(cfg.rays);
        let header = Header {
            settings,
            seeds: vec![cfg.seed],
            rays,
            rays_per_direction: stats.directions.iter().map(|d| d.rays).collect(),
            backend: self.scene.backend().name().into(),
            leaks: stats.leaks,
            // An auto run whose every direction the rigorous solver took whole traced no
            // tree (one solution a cell): no replicate groups either.
            error_groups: if rays >= self.error_groups {
                self.error_groups
            } else {
                0
            },
            balanced: true,
            // Filled by `simulate` (`warnings::stored_warnings`).
            warnings: Vec::new(),
            rays_asked: matches!(cfg.coherence, Coherence::Auto | Coherence::Diffraction)
                .then_some(self.rays_asked),
        };
        let acc = Accumulator { header, cells };
        // (The diffraction method's refusal came after each direction: `diffraction_refusal`.)
        if !cfg.allow_unphysical {
            check_physical(&acc, &self.sample.name, Some(&stats))?;
            let (created, cell) = stats.worst_created(&acc);
            if created > CREATED_REFUSED {
                let nl = acc.header.settings.wavelength_count().max(1);
                return Err(SimError::Unphysical(format!(
                    "sample '{}', theta_i {} deg, wavelength bin {}: {created:.3} of the launched power per tree came from ray series that created energy (more than {CREATED_REFUSED}): light crossed absorbing features thinner than their decay length (ridge tips at grazing light, sub-skin-depth wedges), where no ray model holds (docs/physics.md, \"Where the ray model stops\"). The result is impossible and was not written; use a rigorous solver for this geometry, or pass --allow-unphysical to write it anyway",
                    self.sample.name,
                    cfg.theta_i_deg.get(cell / nl).copied().unwrap_or(f64::NAN),
                    cell % nl + 1
                )));
            }
        }
        Ok((acc, stats))
    }
}
