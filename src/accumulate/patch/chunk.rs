//! Tubes' patches laid out a chunk at a time ([`Patches`]), so that their first cells'
//! exponentials and sines are evaluated in one batch, and the weakest tubes deposited on
//! four cells instead of a patch ([`Patches::push_point`]).

use super::{EXP_SAFE, Patch, Row, finish, floor_i, layout, row_starts, start_args, wrap};
use crate::optics::C64;

/// One tube's patch as the grid sees it: centred at `xw` (nm, in the tile), with inverse
/// covariance `[ixx, iyy, ixy]` (1/nm^2) and horizontal standard deviation `sx` (nm), cut
/// at `radius` standard deviations ([`radius`]), carrying the transverse wave vector `q`
/// (1/nm).
#[derive(Clone, Copy, Debug)]
pub(in crate::accumulate) struct Spec {
    pub inv: [f64; 3],
    pub sx: f64,
    pub radius: f64,
    pub q: [f64; 2],
    pub xw: [f64; 2],
}

/// Tubes whose field at their centre is below `exp(-8)` of the incident wave's (the level
/// to which the grid keeps folded copies off the orders) are deposited on four cells
/// ([`Patches::push_point`]) rather than a patch: a quarter of the film's tubes, the
/// light's deeper internal reflections.
pub(in crate::accumulate) const POINT_MASS: f64 = 3.354_626_279_025_119e-4;

/// Tubes whose patches are laid out together, so that the exponentials and sines of their
/// first cells (six and three a tube) are evaluated in one batch each
/// ([`crate::accumulate::phase::exp_batch`], [`crate::accumulate::phase::sin_cos_batch`]). Evaluated a tube at a
/// time, the batch functions' set-up for so few values was a seventh of a diffraction run.
pub(in crate::accumulate) const CHUNK: usize = 256;

/// A chunk of up to [`CHUNK`] tubes' patches on one grid: [`Patches::push`] lays out each
/// tube's rows, [`Patches::evaluate`] evaluates every first cell's exponentials and sines at
/// once, and [`Patches::patch`] gives each tube's weights, ready to splat. The values are the
/// same bits as a tube's own evaluation: the batch functions act value by value, and a tube
/// whose values leave their range is evaluated on its own, as it always was.
#[derive(Default)]
pub(in crate::accumulate) struct Patches {
    /// The grid's spacing `[dx, dy]` (nm) and cells `[mx, my]`.
    d: [f64; 2],
    m: [usize; 2],
    /// Per tube: its spec, the end of its rows in `rows` and `at`, its first cell's six
    /// exponents (signed), and whether they or its phases are evaluated on its own.
    specs: Vec<Spec>,
    ends: Vec<usize>,
    args: Vec<[f64; 6]>,
    alone: Vec<bool>,
    /// Per tube deposited on four cells ([`Patches::push_point`]): those cells and their
    /// shares; `None` for a patch.
    points: Vec<Option<([usize; 4], [f64; 4])>>,
    /// Every tube's rows ([`Row`]), and per row its grid row and first column, unwrapped.
    rows: Vec<Row>,
    at: Vec<(i64, i64)>,
    /// The batches: exponents (negated where positive) and their exponentials; phases and
    /// their sines and cosines.
    arg: Vec<f64>,
    gauss: Vec<f64>,
    phase: Vec<f64>,
    sin: Vec<f64>,
    cos: Vec<f64>,
    /// The tube being splatted.
    one: Patch,
}

impl Patches {
    /// Starts a chunk on the grid of `[mx, my]` cells of `[dx, dy]` nm.
    pub(in crate::accumulate) fn start(&mut self, d: [f64; 2], m: [usize; 2]) {
        self.d = d;
        self.m = m;
        for v in [&mut self.arg, &mut self.phase] {
            v.clear();
        }
        self.specs.clear();
        self.ends.clear();
        self.args.clear();
        self.alone.clear();
        self.points.clear();
        self.rows.clear();
        self.at.clear();
    }

    /// Tubes in the chunk.
    pub(in crate::accumulate) fn len(&self) -> usize {
        self.specs.len()
    }

    /// Adds a tube: its rows, and its first cell's exponents and phases to the batches.
    pub(in crate::accumulate) fn push(&mut self, s: Spec) {
        let first = layout(&mut self.rows, &mut self.at, &s, self.d, self.m);
        self.ends.push(self.rows.len());
        let (args, phases) = first.map_or(([0.0; 6], [0.0; 3]), |f| start_args(&s, self.d, f));
        // NaN is in neither range.
        let alone = !(args.iter().all(|x| x.abs() < EXP_SAFE)
            && phases
                .iter()
                .all(|x| x.abs() <= crate::accumulate::phase::MAX_PHASE));
        if alone {
            self.arg.extend([0.0; 6]);
            self.phase.extend([0.0; 3]);
        } else {
            // exp_batch takes arguments <= 0: a positive one is taken as the reciprocal of
            // its negative's exponential.
            self.arg.extend(args.iter().map(|x| -x.abs()));
            self.phase.extend(phases);
        }
        self.specs.push(s);
        self.args.push(args);
        self.alone.push(alone);
        self.points.push(None);
    }

    /// Adds a tube too weak for a patch ([`POINT_MASS`]): its field on the four cells
    /// around its centre, each by its bilinear share (cloud in cell: Hockney & Eastwood,
    /// Computer Simulation Using Particles, 1988, §5-2), times the tube's plane wave there.
    /// Its transform differs from its patch's by at most twice its peak at any order, the
    /// level the grid already lets its folded copy reach ([`crate::accumulate::diffraction`]'s
    /// `alias_margin` is 0 for it), and it keeps its own direction's amplitude exactly.
    pub(in crate::accumulate) fn push_point(&mut self, s: Spec) {
        let [dx, dy] = self.d;
        let [mx, my] = self.m;
        let (fx, fy) = (s.xw[0] / dx, s.xw[1] / dy);
        let (ix, iy) = (floor_i(fx), floor_i(fy));
        let (tx, ty) = (fx - ix as f64, fy - iy as f64);
        let (cx, cy) = (
            [wrap(ix, mx), wrap(ix + 1, mx)],
            [wrap(iy, my), wrap(iy + 1, my)],
        );
        let cells = [
            cy[0] * mx + cx[0],
            cy[0] * mx + cx[1],
            cy[1] * mx + cx[0],
            cy[1] * mx + cx[1],
        ];
        let share = [
            (1.0 - tx) * (1.0 - ty),
            tx * (1.0 - ty),
            (1.0 - tx) * ty,
            tx * ty,
        ];
        let phases = point_phases(&s, self.d);
        let alone = !phases
            .iter()
            .all(|x| x.abs() <= crate::accumulate::phase::MAX_PHASE);
        self.arg.extend([0.0; 6]);
        self.phase.extend(if alone { [0.0; 3] } else { phases });
        self.ends.push(self.rows.len());
        self.specs.push(s);
        self.args.push([0.0; 6]);
        self.alone.push(alone);
        self.points.push(Some((cells, share)));
    }

    /// Tube `i`'s four cells and their weights where it was added by
    /// [`Patches::push_point`] (after [`Patches::evaluate`]): each cell's share times the
    /// plane wave `exp(i q . (x_cell - x_w))`.
    pub(in crate::accumulate) fn point(&mut self, i: usize) -> Option<([usize; 4], [C64; 4])> {
        let (cells, share) = self.points[i]?;
        let sc: [[f64; 2]; 3] = if self.alone[i] {
            point_phases(&self.specs[i], self.d)
                .map(crate::accumulate::phase::sin_cos)
                .map(|(s, c)| [s, c])
        } else {
            std::array::from_fn(|k| [self.sin[3 * i + k], self.cos[3 * i + k]])
        };
        let [p0, tx, ty] = sc.map(|[s, c]| C64::new(c, s));
        let w = [p0, p0 * tx, p0 * ty, p0 * tx * ty];
        Some((cells, std::array::from_fn(|k| w[k] * share[k])))
    }

    /// Every tube's first-cell exponentials and sines, in one batch each.
    pub(in crate::accumulate) fn evaluate(&mut self) {
        crate::accumulate::phase::exp_batch(&self.arg, &mut self.gauss);
        crate::accumulate::phase::sin_cos_batch(&self.phase, &mut self.sin, &mut self.cos);
    }

    /// Tube `i`'s patch, its weights filled and their sum taken (after [`Patches::evaluate`]).
    pub(in crate::accumulate) fn patch(&mut self, i: usize) -> &Patch {
        let (lo, hi) = (if i == 0 { 0 } else { self.ends[i - 1] }, self.ends[i]);
        let (rows, at, p) = (&mut self.rows[lo..hi], &self.at[lo..hi], &mut self.one);
        p.runs.clear();
        p.start.clear();
        p.sum = 0.0;
        if at.is_empty() {
            return p;
        }
        let args = self.args[i];
        let mut g = [0.0; 6];
        let sc: [[f64; 2]; 3];
        if self.alone[i] {
            // As a tube alone: the batch functions on its own six and three values (which
            // send them to the C library where out of range), or the C library's `exp`.
            let (_, phases) = start_args(&self.specs[i], self.d, at[0]);
            if args.iter().all(|x| x.abs() < EXP_SAFE) {
                p.arg.clear();
                p.arg.extend(args.iter().map(|x| -x.abs()));
                crate::accumulate::phase::exp_batch(&p.arg, &mut p.gauss);
                g.copy_from_slice(&p.gauss);
                invert_positive(&mut g, &args);
            } else {
                g = args.map(f64::exp);
            }
            crate::accumulate::phase::sin_cos_batch(&phases, &mut p.sin, &mut p.cos);
            sc = std::array::from_fn(|k| [p.sin[k], p.cos[k]]);
        } else {
            g.copy_from_slice(&self.gauss[6 * i..6 * i + 6]);
            invert_positive(&mut g, &args);
            sc = std::array::from_fn(|k| [self.sin[3 * i + k], self.cos[3 * i + k]]);
        }
        let (alpha, tx) = row_starts(p, at, g, sc);
        finish(p, rows, self.m[0], alpha, tx);
        p
    }
}

/// A four-cell tube's phases (rad): the plane wave at its lower-left cell, `q . (x_cell -
/// x_w)`, and its turns per column and per row, on the grid of `[dx, dy]` nm.
fn point_phases(s: &Spec, [dx, dy]: [f64; 2]) -> [f64; 3] {
    let (u0, v0) = (
        floor_i(s.xw[0] / dx) as f64 * dx - s.xw[0],
        floor_i(s.xw[1] / dy) as f64 * dy - s.xw[1],
    );
    [s.q[0] * u0 + s.q[1] * v0, s.q[0] * dx, s.q[1] * dy]
}

/// `g[k] = exp(-|x_k|)` becomes `exp(x_k)`: its reciprocal where `x_k > 0`.
fn invert_positive(g: &mut [f64; 6], args: &[f64; 6]) {
    for (g, x) in g.iter_mut().zip(args) {
        if *x > 0.0 {
            *g = 1.0 / *g;
        }
    }
}
