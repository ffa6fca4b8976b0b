//! What a run reports beside its accumulator: per-direction convergence, per-cell lost
//! and untrusted power, and the diffraction method's transform totals.

use crate::accumulate::file::Accumulator;
use crate::accumulate::{Cell, Coherence};

/// How one incident direction ended.
#[derive(Clone, Debug, PartialEq)]
pub struct DirectionStats {
    pub theta_i_deg: f64,
    pub rays: u64,
    /// Largest relative standard error over wavelength bins of the total reflectance and
    /// of every populated reflection bucket (holding at least a tenth of the brightest
    /// bucket's power); `None` where undefined (global mode).
    pub achieved: Option<f64>,
    /// The tolerance was reached (adaptive runs).
    pub converged: bool,
    /// `achieved` is [`bright_bucket_error`] (`--target-stderr`), not the largest error.
    pub by_median: bool,
    /// What the direction's trees met: segments traced, segments that met an interface
    /// from the wrong medium, and particle scattering draws beyond the tabulated envelope
    /// (the run's totals are in [`SimStats`]).
    pub segments: u64,
    pub leaks: u64,
    pub envelope_violations: u64,
}

impl DirectionStats {
    /// A direction whose every cell the rigorous solver took: one solution per cell,
    /// counted as one tree (`simulate::rigorous`); nothing traced, nothing met.
    pub fn untraced(theta_i_deg: f64) -> DirectionStats {
        DirectionStats {
            theta_i_deg,
            rays: 1,
            achieved: None,
            converged: false,
            by_median: false,
            segments: 0,
            leaks: 0,
            envelope_violations: 0,
        }
    }
}

impl std::fmt::Display for DirectionStats {
    /// `theta_i 30 deg: 4096 trees, relative standard error 0.0123 (converged)`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "theta_i {} deg: {} trees, {} {} ({})",
            self.theta_i_deg,
            self.rays,
            if self.by_median {
                "median relative standard error of the bright buckets"
            } else {
                "relative standard error"
            },
            self.achieved
                .map_or("undefined".into(), |v| format!("{v:.4}")),
            if self.converged {
                "converged"
            } else {
                "budget exhausted"
            }
        )
    }
}

/// The share of each wavelength's reflected power whose buckets judge a BRDF's quality
/// (`--target-stderr`, `bench converge`): the brightest buckets that hold 95 % of it.
pub const BRIGHT_SHARE: f64 = 0.95;

/// The reflected buckets of one direction's `cells` (one per wavelength) that hold
/// `share` of each wavelength's reflected power, brightest first: `(wavelength, key)`
/// pairs (ties by key, so the choice is deterministic).
pub fn bright_buckets(cells: &[Cell], share: f64) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    for (j, c) in cells.iter().enumerate() {
        // Reflected keys are even (`accumulate::key`).
        let mut up: Vec<(usize, f64)> = (0..c.sum.len())
            .step_by(2)
            .filter(|&k| c.sum[k] > 0.0)
            .map(|k| (k, c.sum[k]))
            .collect();
        up.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        let total: f64 = up.iter().map(|b| b.1).sum();
        let mut acc_power = 0.0;
        for (k, s) in up {
            if acc_power >= share * total {
                break;
            }
            acc_power += s;
            out.push((j, k));
        }
    }
    out
}

/// A BRDF's quality (issue 49): the median relative standard error of the buckets of one
/// direction's `cells` that hold `share` of each wavelength's reflected power, over every
/// wavelength (the upper median of an even count); `None` where no bucket has power or a
/// cell has fewer than 2 trees. The errors are the cells' own (`Cell::sum_var`): the
/// replicate groups' spread where the run has groups, else the per-tree spread.
pub fn bright_bucket_error(cells: &[Cell], share: f64) -> Option<f64> {
    if cells.iter().any(|c| c.trees < 2) {
        return None;
    }
    let mut rel: Vec<f64> = bright_buckets(cells, share)
        .into_iter()
        .map(|(j, k)| {
            let c = &cells[j];
            c.sum_var(k).sqrt() / c.sum[k]
        })
        .collect();
    rel.sort_by(f64::total_cmp);
    rel.get(rel.len() / 2).copied()
}

/// The achieved relative error of incident direction `di` (see [`DirectionStats`]).
pub fn achieved_error(cells: &[Cell], di: usize, nl: usize, mode: Coherence) -> Option<f64> {
    if mode == Coherence::Global {
        return None;
    }
    let mut worst: f64 = 0.0;
    for c in &cells[di * nl..(di + 1) * nl] {
        let n = c.trees as f64;
        if c.trees < 2 {
            return Some(f64::INFINITY);
        }
        let r = c.r_sum / n;
        if r > 0.0 {
            worst = worst.max(c.r_stderr(mode).unwrap_or(f64::INFINITY) / r);
        }
        let fmax = (0..c.sum.len())
            .step_by(2)
            .map(|k| c.sum[k] / n)
            .fold(0.0, f64::max);
        for k in (0..c.sum.len()).step_by(2) {
            let f = c.sum[k] / n;
            if f > 0.0 && f >= 0.1 * fmax {
                worst = worst.max(c.fraction_stderr(k, mode).unwrap_or(f64::INFINITY) / f);
            }
        }
    }
    Some(worst)
}

/// One cell of the diffraction method: what the rays gave and what the transform kept in
/// propagating orders before its orders were scaled to the rays' totals.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DiffractionCell {
    /// The beamlet estimator's R and T on the same trees (the cell's totals).
    pub rays_r: f64,
    pub rays_t: f64,
    /// The propagating orders' R and T as transformed (Parseval: equal to the rays' where
    /// the ray field is sampled finely enough and puts no power beyond the horizon).
    pub r: f64,
    pub t: f64,
    /// Propagating orders with power.
    pub orders: usize,
    /// Tubes shaped by their tracked cross-section (no neighbouring tree had the same
    /// exit), and tubes that passed a line focus.
    pub fallback_tubes: usize,
    pub flipped_tubes: usize,
    /// `--coherence auto`: the transform could not hold the ray field (its ratio outside
    /// `[DIFFRACTION_RATIO_REFUSED, 1 / DIFFRACTION_RATIO_REFUSED]`), so the cell kept the
    /// rays' buckets.
    pub fell_back: bool,
}

impl DiffractionCell {
    /// The transform's total against the rays', `(R + T)_orders / (R + T)_rays` (1 when
    /// Parseval holds; NaN for an empty cell).
    pub fn ratio(&self) -> f64 {
        (self.r + self.t) / (self.rays_r + self.rays_t)
    }
}

/// The diffraction method's orders hold this fraction of the ray field's power or more
/// (and at most its inverse) without comment. Sinusoidal gratings of slope 17 deg at
/// period / wavelength 9 keep 0.990 at 0 deg and 0.969 at 30 deg (tests/diffraction.rs):
/// the rest is the transform's tail beyond the horizon and the exit plane's near field.
/// Outside, `simulate` warns.
pub const DIFFRACTION_RATIO_WARN: f64 = 0.95;
/// The most memory the diffraction method's kept exits may take, bytes.
pub const DIFFRACTION_MAX_BYTES: f64 = 8e9;

/// Below this (or above its inverse) the ray field is too coarse or too far from a plane
/// wave per tube for the transform (sub-wavelength structure, rays too sparse), and the
/// run is refused.
pub const DIFFRACTION_RATIO_REFUSED: f64 = 0.8;

/// Run statistics.
#[derive(Clone, Debug, Default)]
pub struct SimStats {
    pub trees: u64,
    pub traces: u64,
    pub segments: u64,
    pub leaks: u64,
    /// Wall time of the whole run, s.
    pub seconds: f64,
    /// The part of `seconds` spent before tracing (building the scene's accelerator,
    /// hashing the sample), s; rates of trees and segments are over the rest.
    pub setup_seconds: f64,
    pub path_sharing: bool,
    /// Every wavelength of a tree was traced at once (`SimConfig::wavelength_sharing`).
    pub wavelength_sharing: bool,
    pub directions: Vec<DirectionStats>,
    /// Per cell (direction-major, like the accumulator's cells): the summed power per tree
    /// dropped by limits (depth, segments, wraps) and leaks rather than by the cutoff.
    pub limit_dropped: Vec<f64>,
    /// Per cell: the summed power per tree that left an open sample through its sides
    /// (`Sample::guard_nm`; zero for periodic sides). It is part of the dropped power.
    pub escaped: Vec<f64>,
    /// Per cell: the summed per-tree bound `2 sqrt(D_l (R + T)) + D_l` on how much the
    /// power cut by limits (`D_l`) can change a tree's coherent totals.
    pub limit_bound: Vec<f64>,
    /// Per cell: the summed power per tree created by ray series that did not recombine,
    /// `max(0, R + T + dropped - 1)` over trees that entered an absorbing medium. A
    /// physical field never exceeds its source; a tree does when light crossed an
    /// absorbing feature thinner than its decay length (a ridge tip at grazing light, a
    /// sub-skin-depth wedge) whose partial waves leave in directions that do not
    /// interfere, where no ray model holds (docs/physics.md, "Where the ray model stops").
    pub created: Vec<f64>,
    /// Per cell: the summed power per tree that met energy-limited events inside absorbers
    /// (`trace::Tree::limited_power`): facets that change the wave by a good part of its
    /// index (ridge tips, flake edges, the faces of absorbing wedges and of layers thicker
    /// than the wavelength; `trace::recombination_weight`), and the share of thin films
    /// whose faces meet at 20-30 degrees that their ray series take rather than the local
    /// film (`trace::film`). There R and T come from a model that conserves energy, not
    /// from exact amplitudes.
    pub limited: Vec<f64>,
    /// Per cell: the summed power per tree by which lossless trees' coherence groups were
    /// scaled to carry out what entered them (`accumulate::conserve`): how far the beamlet
    /// overlaps of their partial waves were from conserving energy.
    pub rebalanced: Vec<f64>,
    /// The diffraction method, per cell: the ray method's totals beside the diffracted
    /// ones (empty cells for other methods).
    pub diffraction: Vec<DiffractionCell>,
    /// Particle media: scattering angles drawn where the phase function exceeded its
    /// tabulated envelope (`optics::particles`; each such draw is slightly biased). 0 in a
    /// correct table.
    pub envelope_violations: u64,
    /// The medium that scatters most in volume and its optical depth over the sample's
    /// height at the run's middle wavelength (`Scene::densest_scatterer`): a refusal for
    /// series cut by the limits names it where light diffuses through many mean free paths.
    pub densest_scatterer: Option<(String, f64)>,
    /// `--coherence auto`: the cells that needed the diffraction method and took rays,
    /// and why (`auto::choose`).
    pub auto_notes: Vec<String>,
    /// The rigorous solver, per cell (`None` for cells it did not take).
    pub rigorous: Vec<Option<RigorousCell>>,
}

/// What the rigorous solver did in one cell: the harmonics per axis, the slices, its
/// difference from the coarser check (`reference::rigorous`), its wall time and its
/// estimate, s.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RigorousCell {
    pub harmonics: [usize; 2],
    /// Slices per structured region (0: the C-method on a relief, unsliced).
    pub slices: usize,
    pub difference: f64,
    pub seconds: f64,
    /// The time the cell was estimated to take before it was solved
    /// (`reference::rigorous::Rigorous::cell_cost_s`), s.
    pub estimate_s: f64,
    /// An order left exactly at grazing: the cell was solved at a wavelength
    /// `reference::rigorous::RAYLEIGH_SHIFT` longer.
    pub rayleigh: bool,
}

impl SimStats {
    /// The statistics of direction `di` alone (`nl` wavelength cells per direction), as a
    /// run of that one direction would have them.
    pub fn direction(&self, di: usize, nl: usize) -> SimStats {
        let cells = |v: &[f64]| v.get(di * nl..(di + 1) * nl).unwrap_or(&[]).to_vec();
        let d = self.directions.get(di).cloned();
        SimStats {
            trees: d.as_ref().map_or(0, |d| d.rays),
            segments: d.as_ref().map_or(0, |d| d.segments),
            leaks: d.as_ref().map_or(0, |d| d.leaks),
            envelope_violations: d.as_ref().map_or(0, |d| d.envelope_violations),
            directions: d.into_iter().collect(),
            limit_dropped: cells(&self.limit_dropped),
            escaped: cells(&self.escaped),
            limit_bound: cells(&self.limit_bound),
            created: cells(&self.created),
            limited: cells(&self.limited),
            rebalanced: cells(&self.rebalanced),
            diffraction: self
                .diffraction
                .get(di * nl..(di + 1) * nl)
                .unwrap_or(&[])
                .to_vec(),
            auto_notes: Vec::new(),
            rigorous: self
                .rigorous
                .get(di * nl..(di + 1) * nl)
                .unwrap_or(&[])
                .to_vec(),
            ..self.clone()
        }
    }

    /// The largest mean power per tree that met energy-limited events, with its cell.
    pub fn worst_limited(&self, acc: &Accumulator) -> (f64, usize) {
        worst_per_tree(&self.limited, acc)
    }

    /// The largest mean power per tree that lossless trees' groups were rebalanced by
    /// ([`SimStats::rebalanced`]), with that cell's index.
    pub fn worst_rebalanced(&self, acc: &Accumulator) -> (f64, usize) {
        worst_per_tree(&self.rebalanced, acc)
    }

    /// The largest mean power per tree that any cell's ray series created, with that
    /// cell's index.
    pub fn worst_created(&self, acc: &Accumulator) -> (f64, usize) {
        worst_per_tree(&self.created, acc)
    }

    /// The largest mean per-tree bound on how much the power cut by limits can change R
    /// and T, with that cell's index.
    pub fn worst_limit_bound(&self, acc: &Accumulator) -> (f64, usize) {
        worst_per_tree(&self.limit_bound, acc)
    }

    /// Wall time spent tracing and estimating (after the set-up), s.
    pub fn trace_seconds(&self) -> f64 {
        (self.seconds - self.setup_seconds).max(f64::MIN_POSITIVE)
    }

    /// The largest mean power per tree that any cell lost through the sides of an open
    /// sample, with that cell's index.
    pub fn worst_escaped(&self, acc: &Accumulator) -> (f64, usize) {
        worst_per_tree(&self.escaped, acc)
    }

    /// The largest mean power per tree that any cell lost to limits and leaks: when it is
    /// not small the ray series was cut before it converged.
    pub fn worst_limit_dropped(&self, acc: &Accumulator) -> f64 {
        worst_per_tree(&self.limit_dropped, acc).0
    }
}

/// The largest of the per-cell sums `per_cell` divided by the cell's trees, and its cell.
fn worst_per_tree(per_cell: &[f64], acc: &Accumulator) -> (f64, usize) {
    per_cell
        .iter()
        .zip(&acc.cells)
        .map(|(d, c)| d / c.trees.max(1) as f64)
        .enumerate()
        .fold((0.0, 0), |w, (i, v)| if v > w.0 { (v, i) } else { w })
}

/// A run's figures for scripts and benchmarks (`simulate --report-json FILE`): what the
/// summary line and warnings say, as numbers. Powers are per tree, fractions of the
/// launched power; times in s; memory in MB.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RunReport {
    pub trees: u64,
    pub traced_trees: u64,
    pub segments: u64,
    pub seconds: f64,
    pub setup_seconds: f64,
    pub trees_per_second: f64,
    pub segments_per_second: f64,
    pub path_sharing: bool,
    pub wavelength_sharing: bool,
    /// Peak resident memory of the process, MB (`None` where the platform does not say).
    pub peak_memory_mb: Option<f64>,
    pub directions: Vec<DirectionReport>,
    /// The largest mean power per tree cut by limits, created by ray series that did not
    /// recombine, met at energy-limited events, and lost through open sides.
    pub worst_limit_dropped: f64,
    pub worst_created: f64,
    pub worst_limited: f64,
    pub worst_escaped: f64,
    /// The diffraction method: the power its transform kept against the rays', furthest
    /// from 1 over the cells (`None` for other methods).
    pub diffraction_worst_ratio: Option<f64>,
    pub envelope_violations: u64,
}

/// One incident direction of a [`RunReport`] (see [`DirectionStats`]).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DirectionReport {
    pub theta_i_deg: f64,
    pub trees: u64,
    pub relative_standard_error: Option<f64>,
    pub converged: bool,
}

impl RunReport {
    /// The report of a finished run.
    pub fn new(stats: &SimStats, acc: &Accumulator) -> RunReport {
        let ts = stats.trace_seconds();
        let diffraction_worst_ratio = stats
            .diffraction
            .iter()
            .filter(|d| d.rays_r + d.rays_t > 0.0)
            .map(|d| d.ratio())
            .max_by(|a, b| (a - 1.0).abs().total_cmp(&(b - 1.0).abs()));
        RunReport {
            trees: stats.trees,
            traced_trees: stats.traces,
            segments: stats.segments,
            seconds: stats.seconds,
            setup_seconds: stats.setup_seconds,
            trees_per_second: stats.trees as f64 / ts,
            segments_per_second: stats.segments as f64 / ts,
            path_sharing: stats.path_sharing,
            wavelength_sharing: stats.wavelength_sharing,
            peak_memory_mb: crate::io::peak_rss_mb(),
            directions: stats
                .directions
                .iter()
                .map(|d| DirectionReport {
                    theta_i_deg: d.theta_i_deg,
                    trees: d.rays,
                    relative_standard_error: d.achieved,
                    converged: d.converged,
                })
                .collect(),
            worst_limit_dropped: stats.worst_limit_dropped(acc),
            worst_created: stats.worst_created(acc).0,
            worst_limited: stats.worst_limited(acc).0,
            worst_escaped: stats.worst_escaped(acc).0,
            diffraction_worst_ratio,
            envelope_violations: stats.envelope_violations,
        }
    }
}
