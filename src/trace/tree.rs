//! What one traced tree produced: its exits, the power it dropped, and its counters.

use crate::optics::C64;
use crate::optics::fresnel::{Field, field_power};
use glam::DVec3;

/// A ray leaving the sample through the launch plane (up) or the bottom plane (down).
#[derive(Clone, Copy, Debug)]
pub struct Exit {
    /// Field of each incident polarisation, without the propagation phase; for an
    /// inhomogeneous wave, on the power basis (`fresnel::on_power_basis`: `|e|^2` is its
    /// flux, in TM too).
    pub e: [Field; 2],
    /// Complex optical path length from the launch plane, nm.
    pub opl: C64,
    /// Unit direction of travel.
    pub dir: DVec3,
    /// Imaginary part of the exit wave's complex index vector `N = N' + i N''`
    /// (dimensionless; the field varies as `exp(i k0 N . x)`): zero for a homogeneous
    /// wave; perpendicular to `dir` for the inhomogeneous wave that leaves an absorber
    /// through a face not parallel to its planes of constant amplitude; scaled by the
    /// recombination weights of the events on its path (zero after a ridge tip's fully
    /// energy-limited event, whose partial waves do not recombine).
    pub n_im: DVec3,
    /// Exit point on the exit plane, unwrapped (nm).
    pub x: DVec3,
    pub up: bool,
    /// Coherence group: 0 for light that has met no particle; each volume scattering
    /// event starts a group of its own, incoherent with every other (the estimator pairs
    /// exits of one group only).
    pub group: u32,
    /// Cross-section of the exit's ray tube relative to the launched tube's (the product
    /// of `cos(theta_t) / cos(theta_i)` over its refractions at plane facets; reflection
    /// keeps it). The diffraction method needs it for each tube's footprint on the exit
    /// plane; the power-normalised field `e` already accounts for it in power.
    pub tube: f64,
    /// A hash of the facets the ray met and whether it was reflected or transmitted at
    /// each: exits of neighbouring trees with the same path left the same flat facets
    /// alike, so their points give the tube's exact shape (the diffraction method).
    pub path: u64,
}

/// Power dropped by the cutoff or a limit, lost to a leak, or escaped through an open side:
/// `power[p] * exp(-4 pi im / lambda)`.
#[derive(Clone, Copy, Debug)]
pub struct Dropped {
    pub power: [f64; 2],
    pub im: f64,
    /// Dropped by a limit (depth, segments, wraps) or a leak rather than by the power
    /// cutoff: such power says the ray series was cut before it converged, and its
    /// coherent effect on the result is not bounded by the cutoff.
    pub limit: bool,
    /// Left an open sample through a side (`Sample::guard_nm`): escaped, not cut.
    pub escaped: bool,
}

/// A tree's dropped power at one wavelength (see [`Tree::dropped`]), as fractions of the
/// launched power.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DroppedPower {
    /// Everything dropped, escaped included.
    pub all: f64,
    /// The part dropped by limits and leaks ([`Dropped::limit`]).
    pub limit: f64,
    /// The part that left through the sides of an open sample ([`Dropped::escaped`]).
    pub escaped: f64,
}

/// Everything one tree produced.
#[derive(Clone, Debug, Default)]
pub struct Tree {
    pub exits: Vec<Exit>,
    pub dropped: Vec<Dropped>,
    /// Some power entered an absorbing medium (so the tree's absorbed power is the launched
    /// power less what left and what was dropped; zero otherwise).
    pub absorbing: bool,
    /// Interface events arriving from a lossless medium whose `|r|^2 + T` missed 1 by more
    /// than 1e-9 (an arithmetic or branch fault; always 0 in a correct build).
    pub energy_faults: u32,
    /// Events whose energy was limited because their partial waves recombine only in
    /// part (`fresnel::limit_excess`).
    pub limited: u32,
    /// The incident power (fraction of launched, attenuated along its path) of those
    /// events, each weighted by `1 - w`: how much light went through events that are
    /// energy-limited rather than exact (`SimStats::limited`).
    pub limited_power: f64,
    pub leaks: u32,
    pub segments: u32,
    /// Random events: volume scattering and Russian roulette, its survivals (each started
    /// a coherence group of its own) and its kills (whose power is gone, not dropped). A
    /// tree with any carries importance weights and balances only on average.
    pub random_events: u32,
    /// Power (fraction of launched, attenuated along the path) that events allowed to add
    /// it added beyond what entered them: events from inside absorbers (where `|r|^2 + T`
    /// exceeds 1 and the series' coherent sum takes it back), the weights of Russian
    /// roulette's survivors, and volume scattering's rounding. Events from lossless media
    /// conserve `|E|^2` or are limited to it (`fresnel::limit_field_excess`), so a tree's
    /// exits and dropped power never hold more than `1 + excess` incoherently
    /// ([`Tree::overflow`]).
    pub excess: f64,
    /// Next-event estimation spread over the reflected hemisphere's buckets (`spread`):
    /// power per bucket (fraction of launched), in `Buckets::index` order; empty where
    /// the run does not spread.
    pub nee: Vec<f64>,
    /// Scratch for `spread`.
    pub(super) spread_scratch: super::spread::SpreadScratch,
    /// Scratch for coated interfaces (indices and thicknesses of one event's stack).
    pub(super) n_buf: Vec<C64>,
    pub(super) d_buf: Vec<f64>,
}

impl Tree {
    pub fn clear(&mut self) {
        self.exits.clear();
        self.dropped.clear();
        self.absorbing = false;
        self.energy_faults = 0;
        self.limited = 0;
        self.limited_power = 0.0;
        self.leaks = 0;
        self.segments = 0;
        self.random_events = 0;
        self.excess = 0.0;
        self.nee.fill(0.0);
    }

    /// Records an event that took a field of power `p_in` (fraction of launched, both
    /// polarisations averaged, unattenuated) into children of `p_out` where the path so
    /// far attenuates by `att`: what it added goes to [`Tree::excess`].
    pub(super) fn note_event(&mut self, p_in: f64, p_out: f64, att: f64) {
        if p_out > p_in {
            self.excess += (p_out - p_in) * att;
        }
    }

    /// How far the tree's exits and dropped power at `lambda_nm` exceed what it was launched
    /// with and what its events were allowed to add, `exits + dropped - 1 - excess` (at most
    /// rounding for a tree whose every event conserved or limited its power; positive
    /// beyond that only where an event created power that nothing accounted for, which the
    /// run refuses: issue 46).
    pub fn overflow(&self, lambda_nm: f64) -> f64 {
        self.exit_power(lambda_nm) + self.dropped(lambda_nm).all - 1.0 - self.excess
    }

    /// Records the power of a field dropped at optical path `opl` (see [`Dropped`]).
    pub(super) fn drop_field(&mut self, e: &[Field; 2], opl: C64, limit: bool) {
        self.dropped.push(Dropped {
            power: [field_power(&e[0]), field_power(&e[1])],
            im: opl.im,
            limit,
            escaped: false,
        });
    }

    /// Records the power of a field that left an open sample through a side.
    pub(super) fn escape_field(&mut self, e: &[Field; 2], opl: C64) {
        self.dropped.push(Dropped {
            power: [field_power(&e[0]), field_power(&e[1])],
            im: opl.im,
            limit: false,
            escaped: true,
        });
    }

    /// Incoherent power of the exits at `lambda_nm` (the sum of `|a_j|^2`, both
    /// polarisations averaged).
    pub fn exit_power(&self, lambda_nm: f64) -> f64 {
        let a = -4.0 * std::f64::consts::PI / lambda_nm;
        self.exits
            .iter()
            .map(|x| 0.5 * (field_power(&x.e[0]) + field_power(&x.e[1])) * (a * x.opl.im).exp())
            .sum()
    }

    /// Dropped power at `lambda_nm`, averaged over the two polarisations: all of it, the
    /// part dropped by limits and leaks, and the part that escaped through the sides.
    pub fn dropped(&self, lambda_nm: f64) -> DroppedPower {
        let a = -4.0 * std::f64::consts::PI / lambda_nm;
        let mut out = DroppedPower::default();
        for d in &self.dropped {
            let p = 0.5 * (d.power[0] + d.power[1]) * (a * d.im).exp();
            out.all += p;
            if d.limit {
                out.limit += p;
            }
            if d.escaped {
                out.escaped += p;
            }
        }
        out
    }
}
