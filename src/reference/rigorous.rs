//! The rigorous solver on a sample (docs/physics.md, "The rigorous solver"): its tile sliced
//! twice ([`grating::slice`]: the run's slices, and half as many for the check), the
//! harmonics chosen per wavelength, and every answer checked for convergence against a
//! coarser one (two thirds of the harmonics per patterned axis and strictly fewer, half the
//! slices and strictly fewer, unless the structure does not change with height, when the
//! slicing is exact and one slab per band is solved). Truncations that drop an order that
//! may propagate, and one slice of a structure that changes with height, are refused: no
//! coarser check could show what they miss (issue 70: `--orders 0` and 1 and `--slices 1`
//! passed the check, R 3 to 7 times too small and 37 % off). The
//! difference, the largest over R, T and every order's efficiency in either polarisation,
//! estimates the answer's error: where the error falls as `1/M^p` with the harmonics `M`,
//! the answer's is the difference over `1.5^p - 1` (0.8 times it for `p = 2`, dielectric
//! staircases; twice it for `p = 1`, TM on metals, whose corners' field singularities
//! slow the Fourier series: Popov, Nevière, Gralak & Tayeb 2002, JOSA A 19, 33). A cell
//! whose difference is above the tolerance is refused, naming what to raise.

use glam::DVec3;

use super::grating::{self, SliceError, SliceSpec, Sliced};
use crate::optics::C64;
use crate::optics::rcwa::{self, Harmonics, RcwaError, Solution};
use crate::sample::Sample;

/// What the solver spends: harmonics per patterned axis (`None`: chosen per wavelength,
/// [`Rigorous::harmonics`]), slices per structured region, pixels per patterned axis, and
/// the largest difference from the coarser check that a cell may have.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Effort {
    pub orders: Option<usize>,
    pub slices: usize,
    pub tolerance: f64,
}

impl Effort {
    pub const SLICES: usize = 24;
    /// The default largest difference from the check: the difference estimates the answer's
    /// error (about 0.8 times it where the error falls as 1/M^2, dielectrics; about twice
    /// where it falls as 1/M, TM on metals), and 5e-3 is ten times below the diffraction
    /// method's R error near 3 wavelengths (docs/validity.md).
    pub const TOLERANCE: f64 = 5e-3;
    /// The default budget, s of wall time, for a run's rigorous cells as estimated before
    /// any is solved ([`Rigorous::cell_cost_s`]): half an hour.
    pub const BUDGET_S: f64 = 1800.0;
    /// Pixels along a patterned axis of a 1-D and of a 2-D structure (divisible by 1 to
    /// 6, 8, 9, 10, 12, 15 and 16, so that a tile of that many periods reduces to one).
    pub const PIXELS_1D: usize = 720;
    pub const PIXELS_2D: usize = 120;
    /// Harmonics beyond the propagating ones per patterned axis, by default.
    pub const MARGIN_1D: usize = 12;
    pub const MARGIN_2D: usize = 3;
    /// The most modes (`2 N`, N the harmonics) one slice may have: its eigenproblem's size.
    pub const MAX_MODES: usize = 1200;
    /// Heights per period of a relief the C-method takes (more than `4 m + 2` for `m`
    /// harmonics; else the staircase serves).
    pub const RELIEF_SAMPLES: usize = 1024;
    /// The harmonics the C-method starts from on a relief with sharp corners (adaptive
    /// spatial resolution: `optics::rcwa::has_corners`), where the run does not fix them:
    /// an aluminised trapezoid of 1.6 um pitch (the optical disc) reaches the check's 5e-3
    /// between 80 and 120 harmonics over 400-700 nm and 0-60 deg.
    pub const CORNER_HARMONICS: usize = 120;
    /// The most harmonics the C-method rises to on such a relief (by half again each time
    /// a cell's check fails, the last answer becoming the check).
    pub const CORNER_MAX_HARMONICS: usize = 180;
}

impl Default for Effort {
    fn default() -> Self {
        Effort {
            orders: None,
            slices: Effort::SLICES,
            tolerance: Effort::TOLERANCE,
        }
    }
}

/// Why the rigorous solver cannot answer a cell.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RigorousError {
    #[error(transparent)]
    Slice(#[from] SliceError),
    #[error(transparent)]
    Solver(#[from] RcwaError),
    #[error(
        "the medium above the structure ('{0}') absorbs: the rigorous solver takes the light from a lossless half-space"
    )]
    AboveAbsorbs(String),
    #[error(
        "the rigorous solver needs {modes} modes per slice at {lambda_nm} nm ({harmonics:?} harmonics per axis over a period of {period_nm:?} nm), more than {max}: the tile is too large against the wavelength for it (rays or the diffraction method hold at that scale)"
    )]
    TooLarge {
        modes: usize,
        harmonics: [usize; 2],
        period_nm: [f64; 2],
        lambda_nm: f64,
        max: usize,
    },
    #[error(
        "--orders {harmonics} keeps fewer harmonics than the {propagating} orders that may propagate at {lambda_nm} nm over a period of {period_nm} nm (in the densest medium, n {n_max:.3}): the answer would miss light that leaves, and no coarser check could show it; give at least --orders {propagating} (by default the solver takes {propagating} plus a margin)"
    )]
    TooFewOrders {
        harmonics: usize,
        propagating: usize,
        lambda_nm: f64,
        period_nm: f64,
        n_max: f64,
    },
    #[error(
        "--slices {0} cuts the structure into one slab per band, which the convergence check cannot refine (half of one slice is the same slice), and the structure changes with height: give at least --slices 2 (the default is {default}); lamellae and pillars, which do not change with height, are solved as one slab whatever the count",
        default = Effort::SLICES
    )]
    TooFewSlices(usize),
    #[error(
        "the rigorous solver did not converge at theta_i {theta_deg} deg and {lambda_nm} nm: {harmonics:?} harmonics and {slices} slices differ from {coarse:?} and {coarse_slices} by {difference:.2e} in R, T or an order's efficiency (tolerance {tolerance:.1e}){curvilinear}; raise --orders or --slices"
    )]
    NotConverged {
        /// Where the C-method took the relief first and did not converge: what it gave
        /// (a clause of the message; empty otherwise).
        curvilinear: String,
        theta_deg: f64,
        lambda_nm: f64,
        harmonics: [usize; 2],
        slices: usize,
        coarse: [usize; 2],
        coarse_slices: usize,
        difference: f64,
        tolerance: f64,
    },
}

/// A sample ready for the solver: its tile sliced at the run's effort and at the check's.
#[derive(Clone, Debug, PartialEq)]
pub struct Rigorous {
    pub effort: Effort,
    /// The medium above the structure, by name (for messages).
    pub above: String,
    pub fine: Sliced,
    pub coarse: Sliced,
    /// The slicing is exact in height (every structured band is the same at every height:
    /// lamellae, pillars): the slices' count does not matter, and the check compares the
    /// harmonics alone.
    pub exact_in_height: bool,
    /// The tile's one uncoated interface as a relief over one period along x, under its
    /// flat planes ([`grating::relief`], [`Effort::RELIEF_SAMPLES`] heights), where it is
    /// one: solved by the C-method joined to the planes instead of the staircase.
    pub relief: Option<grating::Relief>,
    /// The relief has sharp corners: the C-method takes [`Effort::CORNER_HARMONICS`] and
    /// more ([`Rigorous::curvilinear_harmonics`]).
    pub corners: bool,
}

/// One cell's answer: the solution, the harmonics and slices it took, and its difference
/// from the coarser check.
#[derive(Clone, Debug)]
pub struct Converged {
    pub solution: Solution,
    pub harmonics: [usize; 2],
    pub slices: usize,
    pub difference: f64,
    /// Solved by the C-method on the relief (no slices), not the staircase.
    pub curvilinear: bool,
    /// Where an order left exactly at grazing (Rayleigh's anomaly): the wavelength the cell
    /// was solved at instead, nm ([`RAYLEIGH_SHIFT`] longer).
    pub rayleigh_nm: Option<f64>,
}

/// The C-method's last check on a relief where it did not converge: its harmonics, the
/// check's, and their difference.
type Tried = (usize, usize, f64);

/// Seconds per unit of an eigenproblem's size cubed, one thread, for
/// [`Rigorous::cell_cost_s`]: from `goniospec bench rigorous` (AMD EPYC, 2026-12-07). The
/// C-method's solve of `N` harmonics takes `a N³ + b N` (`b N`: the transforms of the
/// relief's samples, one per closed-form order, which dominate at few harmonics): the foil's
/// cell at 41 harmonics 0.0335 s (41 and its check's 29), the disc's solves at 41 to 401
/// harmonics 0.015 to 1.98 s (2026-12-08: 401³ a = 1.98 s fits `a`). The 1-D staircase's
/// at 41 harmonics and 24 + 12 slices 0.132 s (41³ per slab, and 29³ for the check's), the
/// crossed one at 11 x 11 harmonics and 24 + 12 slices 2.80 s (242³ modes per slab, 162³
/// for the check's).
pub struct CellCost {
    pub c_method_cubic: f64,
    pub c_method_linear: f64,
    pub staircase_1d: f64,
    pub staircase_2n: f64,
}

pub const CELL_COST: CellCost = CellCost {
    c_method_cubic: 3.1e-8,
    c_method_linear: 4.4e-4,
    staircase_1d: 6.8e-8,
    staircase_2n: 7.2e-9,
};

/// The relative lengthening of the wavelength at which a cell is solved where one of its
/// orders leaves exactly at grazing (Rayleigh's anomaly: its propagation constant is zero
/// and the half-space's modes are dependent). The efficiencies are continuous there with
/// a square-root edge (Rayleigh 1907; Hessel & Oliner 1965), so the cell's answer moves by
/// about the square root of the shift, 1e-4, below the check's tolerance.
pub const RAYLEIGH_SHIFT: f64 = 1e-8;

/// Whether an order of the harmonics `m` of light along `d` at `lambda_nm` leaves a
/// lossless half-space of index `n` within rounding of grazing: `|n^2 - kx^2 - ky^2| <
/// 1e-9` in units of `k0^2`, `kx = n_above d.x + p lambda / period` as the solver builds
/// them.
fn grazing(
    n_above: f64,
    half_spaces: &[f64],
    d: DVec3,
    lambda_nm: f64,
    m: [usize; 2],
    period_nm: [f64; 2],
) -> bool {
    let k = |a: usize, p: i64| {
        let along = if a == 0 { d.x } else { d.y };
        n_above * along + p as f64 * lambda_nm / period_nm[a]
    };
    let (mx, my) = (m[0] as i64, m[1] as i64);
    (-mx..=mx).any(|p| {
        (-my..=my).any(|q| {
            let t = k(0, p).powi(2) + k(1, q).powi(2);
            half_spaces.iter().any(|n| (n * n - t).abs() < 1e-9)
        })
    })
}

impl Rigorous {
    /// Slices `sample` (probing first which axes it is patterned along, at 64 x 64 pixels).
    pub fn new(sample: &Sample, effort: Effort) -> Result<Rigorous, RigorousError> {
        let probe = grating::slice(
            sample,
            SliceSpec {
                pixels: [64, 64],
                slices: 4,
            },
        )?;
        let per = if probe.patterned == [true, true] {
            Effort::PIXELS_2D
        } else {
            Effort::PIXELS_1D
        };
        let pixels = probe.patterned.map(|p| if p { per } else { 1 });
        let at = |slices: usize| {
            grating::slice(
                sample,
                SliceSpec {
                    pixels,
                    slices: slices.max(1),
                },
            )
        };
        let fine = at(effort.slices)?;
        let relief = (fine.patterned == [true, false])
            .then(|| grating::relief(sample, fine.period_nm[0], Effort::RELIEF_SAMPLES))
            .flatten();
        let corners = relief
            .as_ref()
            .is_some_and(|r| rcwa::has_corners(&r.heights, fine.period_nm[0]));
        // Twice the slices giving the same slabs: the structure does not change with height
        // and any count is exact. Otherwise the check needs strictly fewer slices.
        let exact_in_height = grating::same_slabs(&fine, &at(2 * effort.slices)?);
        let coarse = if exact_in_height {
            fine.clone()
        } else {
            at(effort.slices.div_ceil(2))?
        };
        Ok(Rigorous {
            effort,
            above: sample.media[probe.above].name.clone(),
            fine,
            coarse,
            exact_in_height,
            relief,
            corners,
        })
    }

    /// The harmonics per axis at `lambda_nm` for light along `d` with the largest real index
    /// `n_max` among the media: the orders that propagate in the densest medium, plus the
    /// margin (or `--orders` where given); 0 along an axis the structure does not change
    /// along.
    pub fn harmonics(&self, lambda_nm: f64, n_max: f64) -> [usize; 2] {
        let s = &self.fine;
        let two_d = s.patterned == [true, true];
        let margin = if two_d {
            Effort::MARGIN_2D
        } else {
            Effort::MARGIN_1D
        };
        [0, 1].map(|a| {
            if !s.patterned[a] {
                0
            } else if let Some(m) = self.effort.orders {
                m
            } else {
                (2.0 * n_max * s.period_nm[a] / lambda_nm).ceil() as usize + margin
            }
        })
    }

    /// The harmonics the C-method starts from where the staircase would take `m`: on a
    /// relief with sharp corners at least [`Effort::CORNER_HARMONICS`] unless the run fixes
    /// them (`--orders`).
    pub fn curvilinear_harmonics(&self, m: usize) -> usize {
        if self.corners && self.effort.orders.is_none() {
            m.max(Effort::CORNER_HARMONICS)
        } else {
            m
        }
    }

    /// The estimated wall time of one cell on one thread, s: light of `lambda_nm` along `d`,
    /// the media indices `idx` there. The eigenproblems dominate and grow as the cube of
    /// their size, once per structured slab (flat ones are exact and nearly free), for the
    /// run's harmonics and slices and again for the check's; the constants are one thread
    /// of `goniospec bench rigorous` on the development machine ([`CELL_COST`]). A relief
    /// the C-method takes is counted as the C-method (it falls back to the staircase where
    /// it does not converge, which costs more).
    pub fn cell_cost_s(&self, idx: &[C64], lambda_nm: f64, d: DVec3) -> f64 {
        let n_max = idx.iter().map(|n| n.re.abs()).fold(1.0, f64::max);
        let m = self.harmonics(lambda_nm, n_max);
        let coarse = m.map(|k| (2 * k).div_ceil(3).min(k.saturating_sub(1)));
        let count = |m: [usize; 2]| ((2 * m[0] + 1) * (2 * m[1] + 1)) as f64;
        let (n, nc) = (count(m), count(coarse));
        if self.relief.is_some() && self.fine.patterned == [true, false] {
            let k = self.curvilinear_harmonics(m[0]);
            let kc = (2 * k).div_ceil(3).min(k.saturating_sub(1));
            let one = |k: usize| {
                let n = (2 * k + 1) as f64;
                CELL_COST.c_method_cubic * n.powi(3) + CELL_COST.c_method_linear * n
            };
            return one(k) + one(kc);
        }
        let structured = |s: &Sliced| {
            s.layers
                .iter()
                .filter(|l| matches!(l.1, grating::SlabIds::Grid { .. }))
                .count() as f64
        };
        let (sf, sc) = (structured(&self.fine), structured(&self.coarse));
        if self.fine.patterned == [true, false] && d.y == 0.0 {
            // The classical mount: two N x N problems a slab (TE and TM apart).
            CELL_COST.staircase_1d * (sf * n.powi(3) + sc * nc.powi(3))
        } else {
            CELL_COST.staircase_2n * (sf * (2.0 * n).powi(3) + sc * (2.0 * nc).powi(3))
        }
    }

    /// The modes per slice (twice the harmonics) a cell at `lambda_nm` takes: its cost.
    pub fn modes_at(&self, sample: &Sample, lambda_nm: f64) -> usize {
        let mut idx = Vec::new();
        sample.indices_into(lambda_nm, &mut idx);
        let n_max = idx.iter().map(|n| n.re.abs()).fold(1.0, f64::max);
        let m = self.harmonics(lambda_nm, n_max);
        2 * (2 * m[0] + 1) * (2 * m[1] + 1)
    }

    /// The C-method on the tile's relief, where it has one and it converges: the solution,
    /// its check and the harmonics taken (from `m`, or [`Self::curvilinear_harmonics`]);
    /// and where it does not converge, its last check (harmonics, the check's, difference).
    /// A relief, bare or under flat planes, from any azimuth: no staircase (TM on metals
    /// converges fast there: docs/physics.md).
    fn curvilinear(
        &self,
        idx: &[C64],
        above: C64,
        lambda_nm: f64,
        d: DVec3,
        m: usize,
    ) -> (Option<(Solution, Solution, usize)>, Option<Tried>) {
        let mut tried: Option<Tried> = None;
        let solved = self
            .relief
            .as_ref()
            .filter(|h| h.heights.len() > 4 * self.curvilinear_harmonics(m) + 2)
            .and_then(|h| {
                let p = rcwa::Profile {
                    period_nm: self.fine.period_nm[0],
                    heights_nm: h.heights.clone(),
                    eps_above: (above * above).re,
                    eps_below: idx[self.fine.below] * idx[self.fine.below],
                    planes: h
                        .planes
                        .iter()
                        .map(|&(z_nm, m)| rcwa::Plane {
                            z_nm,
                            eps_below: idx[m] * idx[m],
                        })
                        .collect(),
                };
                // Unsliced, the check has only the harmonics to differ in: fewer, always. On
                // a relief with corners, where the check fails the harmonics rise by half
                // again, the last answer becoming the check (an answer that fails to solve
                // counts as a failed check).
                let converged = |f: &Solution, c: &Solution| {
                    let balanced = (0..2).all(|k| (f.r[k] + f.t[k] - 1.0).abs() <= 1e-9);
                    difference(f, c) <= self.effort.tolerance && (p.eps_below.im != 0.0 || balanced)
                };
                let mut k = self.curvilinear_harmonics(m);
                let mut fewer = (2 * k).div_ceil(3).min(k.saturating_sub(1));
                let mut coarse = rcwa::solve_profile(&p, lambda_nm, d, fewer).ok();
                loop {
                    let fine = rcwa::solve_profile(&p, lambda_nm, d, k).ok();
                    if let (Some(f), Some(c)) = (&fine, &coarse) {
                        if converged(f, c) {
                            return Some((fine?, coarse?, k));
                        }
                        tried = Some((k, fewer, difference(f, c)));
                    }
                    let next = (3 * k).div_ceil(2);
                    if !self.corners
                        || self.effort.orders.is_some()
                        || next > Effort::CORNER_MAX_HARMONICS
                        || h.heights.len() <= 4 * next + 1
                    {
                        return None;
                    }
                    (coarse, fewer, k) = (fine, k, next);
                }
            });
        (solved, tried)
    }

    /// Solves one cell: light of `lambda_nm` along `d` (`theta_deg` for messages), the media
    /// indices `idx` there.
    pub fn solve(
        &self,
        idx: &[C64],
        lambda_nm: f64,
        d: DVec3,
        theta_deg: f64,
    ) -> Result<Converged, RigorousError> {
        let above = idx[self.fine.above];
        if above.im != 0.0 {
            return Err(RigorousError::AboveAbsorbs(self.above.clone()));
        }
        let n_max = idx.iter().map(|n| n.re.abs()).fold(1.0, f64::max);
        let m = self.harmonics(lambda_nm, n_max);
        let h = Harmonics { m };
        let modes = 2 * h.count();
        if modes > Effort::MAX_MODES {
            return Err(RigorousError::TooLarge {
                modes,
                harmonics: m,
                period_nm: self.fine.period_nm,
                lambda_nm,
                max: Effort::MAX_MODES,
            });
        }
        // Every order that may propagate must be kept (the densest medium's, at any angle:
        // |m| lambda / period <= 2 n_max), and the check keeps strictly fewer harmonics.
        for ((&k, &patterned), &period_nm) in
            m.iter().zip(&self.fine.patterned).zip(&self.fine.period_nm)
        {
            let propagating = (2.0 * n_max * period_nm / lambda_nm).ceil() as usize;
            if patterned && k < propagating {
                return Err(RigorousError::TooFewOrders {
                    harmonics: k,
                    propagating,
                    lambda_nm,
                    period_nm,
                    n_max,
                });
            }
        }
        let coarse_m = m.map(|k| (2 * k).div_ceil(3).min(k.saturating_sub(1)));
        // Rayleigh's anomaly: solved a hair longer (the fine and the check alike). An order
        // grazing in any lossless medium (a half-space, a flat layer, a relief's cover)
        // makes its up- and down-going waves one.
        let lossless: Vec<f64> = idx.iter().filter(|n| n.im == 0.0).map(|n| n.re).collect();
        let rayleigh_nm = [m, coarse_m]
            .iter()
            .any(|&h| grazing(above.re, &lossless, d, lambda_nm, h, self.fine.period_nm))
            .then_some(lambda_nm * (1.0 + RAYLEIGH_SHIFT));
        let lambda_nm = rayleigh_nm.unwrap_or(lambda_nm);
        // A relief, bare or under flat planes, from any azimuth: the C-method, which needs
        // no staircase (TM on metals converges fast there: docs/physics.md).
        // Where it does not converge (a relief with jumps or sharp corners, whose slope's
        // Fourier series converges slowly), the staircase serves; over a lossless medium
        // also where the truncated C-method leaves R + T off 1 by more than the run accepts
        // (1e-9; a meshed glass sinusoid of 128 facets: 4.6e-8), where the staircase, exact
        // in energy there, converges in both polarisations.
        let (curvilinear, tried) = self.curvilinear(idx, above, lambda_nm, d, m[0]);
        let profile = curvilinear.is_some();
        let (fine, coarse, slices, m) = if let Some((fine, coarse, k)) = curvilinear {
            (fine, coarse, 0, [k, 0])
        } else if !self.exact_in_height && self.effort.slices < 2 {
            return Err(RigorousError::TooFewSlices(self.effort.slices));
        } else {
            (
                rcwa::solve(&self.fine.structure(idx), lambda_nm, d, h)?,
                rcwa::solve(
                    &self.coarse.structure(idx),
                    lambda_nm,
                    d,
                    Harmonics { m: coarse_m },
                )?,
                self.effort.slices,
                m,
            )
        };
        let difference = difference(&fine, &coarse);
        if difference > self.effort.tolerance {
            return Err(RigorousError::NotConverged {
                curvilinear: tried.map_or(String::new(), |(k, kc, diff)| {
                    format!(
                        "; the C-method on the relief, tried first, did not either: {k} harmonics differ from {kc} by {diff:.2e}"
                    )
                }),
                theta_deg,
                lambda_nm,
                harmonics: m,
                slices,
                coarse: coarse_m,
                coarse_slices: if self.exact_in_height {
                    slices
                } else {
                    slices.div_ceil(2)
                },
                difference,
                tolerance: self.effort.tolerance,
            });
        }
        Ok(Converged {
            solution: fine,
            harmonics: m,
            slices,
            difference,
            curvilinear: profile,
            rayleigh_nm,
        })
    }
}

/// The largest difference between two solutions of one cell: R and T per polarisation, and
/// every order's efficiency per polarisation (an order missing from one counts as 0).
pub fn difference(a: &Solution, b: &Solution) -> f64 {
    let mut d: f64 = 0.0;
    for pol in 0..2 {
        d = d.max((a.r[pol] - b.r[pol]).abs());
        d = d.max((a.t[pol] - b.t[pol]).abs());
    }
    let find = |s: &Solution, o: &rcwa::Order| {
        s.orders
            .iter()
            .find(|x| x.m == o.m && x.up == o.up)
            .copied()
    };
    for (x, y) in [(a, b), (b, a)] {
        for o in &x.orders {
            let other = find(y, o);
            for pol in 0..2 {
                let e = other.map_or(0.0, |p| p.efficiency(pol));
                d = d.max((o.efficiency(pol) - e).abs());
            }
        }
    }
    d
}
