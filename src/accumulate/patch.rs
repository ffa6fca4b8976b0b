//! One tube's Gaussian patch on the diffraction method's grid ([`super::diffraction`]):
//! its rows of cells, each cell's weight (the Gaussian times the plane wave), and the splat
//! of its field.

use crate::optics::C64;
use crate::optics::fresnel::Field;

mod chunk;
pub(super) use chunk::{CHUNK, POINT_MASS, Patches, Spec};

/// Patches of a tube whose field is as strong as the incident wave's are cut where their
/// exponent reaches `-PATCH_RADIUS^2 / 2`: `exp(-8) = 3.4e-4` of the patch's peak, the level
/// every other approximation of the transform is held to (the aliases' margin,
/// `diffraction::ALIAS_MARGIN`, and the four-cell tubes, [`POINT_MASS`]). The weight left
/// out is renormalised, so the lattice's summed field departs from uniform by at most `2
/// exp(-8)` of it, without mean: a flat film's spurious orders carry at most `4 exp(-16) =
/// 4.5e-7` of its power (`tests/diffraction.rs`, `flat_films_are_unchanged`).
///
/// (Until 2026-12-06 the cut was at 5 standard deviations, `exp(-12.5)`: 1.56 times the
/// cells a patch takes now, for a BRDF that differs from this one by a hundredth of the
/// method's own error at 4,096 trees; docs/physics.md, "The patches' cut".) Weaker tubes are
/// cut where their field falls to the same absolute level ([`radius`]).
pub(super) const PATCH_RADIUS: f64 = 4.0;

/// The smallest radius a patch is cut at, in standard deviations: a tube too weak for any
/// of its field to reach the cut still carries its power, through its central cells.
const MIN_RADIUS: f64 = 1.5;

/// Where a tube's patch is cut, in standard deviations, for a tube whose field at its
/// centre is `m` times the incident wave's (both on the exit plane): where its Gaussian
/// falls to the level `exp(-PATCH_RADIUS^2 / 2)` of the incident wave, `m exp(-r^2 / 2) =
/// exp(-PATCH_RADIUS^2 / 2)`, so every tube's field is cut at the same absolute level
/// whatever its strength (the part left out of an order's amplitude is bounded by the
/// patch's tail, `m exp(-r^2 / 2)`), and at least [`MIN_RADIUS`].
pub(super) fn radius(m: f64) -> f64 {
    if m >= 1.0 || m.is_nan() {
        return PATCH_RADIUS;
    }
    let r2 = PATCH_RADIUS * PATCH_RADIUS + 2.0 * m.ln();
    r2.max(MIN_RADIUS * MIN_RADIUS).sqrt()
}

/// Rows whose weights are computed at once: four lanes, one row each, stepping along
/// their rows together (`machine::row_weights`), instead of one chain of dependent
/// multiplications.
const LANES: usize = 4;

/// One tube's patch on the grid, row by row: each row's run of cells inside the ellipse
/// `quad <= radius^2`, and every cell's weight, the Gaussian times the plane wave.
///
/// The weight `w(u, v) = exp(-quad(u, v) / 2) exp(i q . (u, v))` is the exponential of a
/// quadratic in `(u, v)`, so its ratio from one cell to the next along a row, `w(u + dx, v)
/// / w(u, v)`, is itself geometric: it shrinks by `alpha = exp(-ixx dx^2)` per column and
/// by `beta = exp(-ixy dx dy)` per row, and the ratio from one row to the next shrinks by
/// `gamma = exp(-iyy dy^2)` per row and by `beta` per column (the phase's ratios are the
/// constant turns `exp(i q_x dx)` and `exp(i q_y dy)`). A patch therefore costs a handful
/// of exponentials and sines at its first cell; every row's first weight follows from the
/// row before by a few multiplications, and every other cell from its neighbour by two.
#[derive(Default)]
pub(super) struct Patch {
    /// The rows' runs of cells that do not cross the tile's edge (`machine::Run`).
    runs: Vec<crate::machine::Run>,
    /// Per row: the Gaussian, its ratio to the next column and the plane wave at the row's
    /// first cell.
    start: Vec<[f64; 4]>,
    /// The exponents and phases at the patch's first cell, and their values.
    arg: Vec<f64>,
    gauss: Vec<f64>,
    sin: Vec<f64>,
    cos: Vec<f64>,
    /// Per cell of the longest row of each group of [`LANES`] rows, the group's rows side
    /// by side: the weights' real and imaginary parts.
    w_re: Vec<[f64; LANES]>,
    w_im: Vec<[f64; LANES]>,
    /// The Gaussian's sum over the patch's cells.
    sum: f64,
}

/// A row of a patch: `(first cell's index in the grid's row, first column, cells, its
/// group's first weight)`; row `r` of a patch has its weights in lane `r % LANES` of its
/// group's.
type Row = (usize, usize, usize, usize);

/// `1.5 2^52`: adding it to `|x| < 2^51` rounds `x` to the nearest integer in the low bits
/// of the sum's mantissa (the conversion `as i64` instead costs a saturation check).
const ROUND: f64 = 6_755_399_441_055_744.0;

/// The integer nearest `x`, for `|x| < 2^51`.
fn round_i(x: f64) -> i64 {
    (x + ROUND).to_bits() as i64 - ROUND.to_bits() as i64
}

/// `ceil x` for `|x| < 2^51` (the C library's `ceil` is a call on baseline x86-64).
fn ceil_i(x: f64) -> i64 {
    let t = round_i(x);
    t + i64::from((t as f64) < x)
}

/// `floor x` for `|x| < 2^51`.
fn floor_i(x: f64) -> i64 {
    let t = round_i(x);
    t - i64::from((t as f64) > x)
}

/// `i mod n` in `0..n`, without the division where `i` is already in range.
fn wrap(i: i64, n: usize) -> usize {
    if (0..n as i64).contains(&i) {
        i as usize
    } else {
        i.rem_euclid(n as i64) as usize
    }
}

/// Where the exponents of a patch's first cell would leave the range in which `exp` and
/// its reciprocal are both finite and normal, the patch takes the C library's `exp`. (It
/// cannot for a valid patch: the covariance's floor of a quarter cell squared bounds
/// `ixx dx^2`, `iyy dy^2` and `|ixy| dx dy` by 4, and the first cell lies in the ellipse,
/// where the Gaussian's gradient is at most `radius sqrt(ixx)`, so every exponent is within
/// 20 of 0.)
const EXP_SAFE: f64 = 700.0;

/// A tube's rows (see [`Patch`]) on the grid of `[mx, my]` cells of `[dx, dy]` nm, appended
/// to `rows` and `at`; returns its first cell (grid row and column, unwrapped), or `None`
/// where no cell's centre lies in its ellipse.
fn layout(
    rows: &mut Vec<Row>,
    at: &mut Vec<(i64, i64)>,
    s: &Spec,
    [dx, dy]: [f64; 2],
    [mx, my]: [usize; 2],
) -> Option<(i64, i64)> {
    let ([ixx, iyy, ixy], xw) = (s.inv, s.xw);
    let r2 = s.radius * s.radius;
    let (inv_ixx, inv_dx) = (1.0 / ixx, 1.0 / dx);
    // The ellipse's extent in y: quad is at least (iyy - ixy^2 / ixx) v^2 = v^2 / cyy.
    let hy = s.radius * (ixx / (ixx * iyy - ixy * ixy)).sqrt();
    let hx = s.radius * s.sx;
    let (x0, x1) = (
        ceil_i((xw[0] - hx) * inv_dx),
        floor_i((xw[0] + hx) * inv_dx),
    );
    let (y0, y1) = (ceil_i((xw[1] - hy) / dy), floor_i((xw[1] + hy) / dy));
    let before = at.len();
    for iy in y0..=y1 {
        let v = iy as f64 * dy - xw[1];
        // The row's cells inside the ellipse: ixx u^2 + 2 ixy v u + iyy v^2 <= r2.
        let b = ixy * v;
        let disc = b * b - ixx * (iyy * v * v - r2);
        if disc < 0.0 {
            continue;
        }
        let root = disc.sqrt();
        let lo = ceil_i((xw[0] + (-b - root) * inv_ixx) * inv_dx).max(x0);
        let hi = floor_i((xw[0] + (-b + root) * inv_ixx) * inv_dx).min(x1);
        if lo > hi {
            continue;
        }
        let n = (hi - lo + 1) as usize;
        at.push((iy, lo));
        rows.push((wrap(iy, my) * mx, wrap(lo, mx), n, 0));
    }
    at.get(before).copied()
}

/// Lays out the patch of tube `s` on the grid of `[mx, my]` cells of `[dx, dy]` nm, with
/// every cell's weight and the Gaussian's sum (see [`Patch`] for the recurrences): a chunk
/// of one tube.
#[cfg(test)]
fn patch_rows(ps: &mut Patches, s: Spec, d: [f64; 2], m: [usize; 2]) -> &Patch {
    ps.start(d, m);
    ps.push(s);
    ps.evaluate();
    ps.patch(0)
}

/// The patch's groups of [`LANES`] rows, its runs of cells, and its weights
/// (`Row`'s last field, `Patch::runs`, `w_re`, `w_im`, `sum`), from its rows' first cells.
fn finish(p: &mut Patch, rows: &mut [Row], mx: usize, alpha: f64, tx: C64) {
    // Each group of LANES rows gets its longest row's length of weights.
    let mut cells = 0;
    for group in rows.chunks_mut(LANES) {
        let len = group.iter().map(|r| r.2).max().unwrap_or(0);
        for r in group {
            r.3 = cells;
        }
        cells += len;
    }
    p.w_re.resize(cells, [0.0; LANES]);
    p.w_im.resize(cells, [0.0; LANES]);
    for (r, &(base, first, n, at)) in rows.iter().enumerate() {
        // The row's cells in runs that do not cross the tile's edge.
        let (mut col, mut done) = (first, 0);
        while done < n {
            let len = (n - done).min(mx - col);
            p.runs.push(crate::machine::Run {
                cell: base + col,
                weight: at + done,
                len,
                lane: r % LANES,
            });
            done += len;
            col = 0;
        }
    }
    fill_weights(p, rows, alpha, tx);
}

/// The exponents and phases at a patch's first cell, at grid row `iy0` and column `lo0`:
/// the Gaussian's exponent there and its steps one column right and one row up, the
/// constant shrinks per column, per row and across; the phase there and its turns per
/// column and per row.
fn start_args(s: &Spec, [dx, dy]: [f64; 2], (iy0, lo0): (i64, i64)) -> ([f64; 6], [f64; 3]) {
    let ([ixx, iyy, ixy], q, xw) = (s.inv, s.q, s.xw);
    let (u0, v0) = (lo0 as f64 * dx - xw[0], iy0 as f64 * dy - xw[1]);
    let e = |u: f64, v: f64| -0.5 * (ixx * u * u + 2.0 * ixy * u * v + iyy * v * v);
    let e00 = e(u0, v0);
    let ln_col = e(u0 + dx, v0) - e00;
    let ln_row = e(u0, v0 + dy) - e00;
    let ln_beta = -ixy * dx * dy;
    let (ln_alpha, ln_gamma) = (-ixx * dx * dx, -iyy * dy * dy);
    (
        [e00, ln_col, ln_row, ln_beta, ln_alpha, ln_gamma],
        [q[0] * u0 + q[1] * v0, q[0] * dx, q[1] * dy],
    )
}

/// Every row's first cell (`Patch::start`) from the patch's first: its Gaussian, ratios and
/// phase there (`g`, the exponentials of [`start_args`]'s exponents; `sc`, the sines and
/// cosines of its phases), carried from row to row by the recurrences of [`Patch`]. Returns
/// the shrink of the column ratio per column, `exp(-ixx dx^2)`, and the phase's turn per
/// column.
fn row_starts(p: &mut Patch, at: &[(i64, i64)], g: [f64; 6], sc: [[f64; 2]; 3]) -> (f64, C64) {
    let [g00, col0, row0, beta, alpha, gamma] = g;
    let (inv_alpha, inv_beta) = (1.0 / alpha, 1.0 / beta);
    let ph0 = C64::new(sc[0][1], sc[0][0]);
    let tx = C64::new(sc[1][1], sc[1][0]);
    let ty = C64::new(sc[2][1], sc[2][0]);
    // Every row's first cell from the last one's: rows up, then columns right or left.
    let (mut g, mut gc, mut gr, mut ph) = (g00, col0, row0, ph0);
    let (mut iy, mut col) = at[0];
    for &(row, lo) in at {
        while iy < row {
            g *= gr;
            gr *= gamma;
            gc *= beta;
            ph *= ty;
            iy += 1;
        }
        while col < lo {
            g *= gc;
            gc *= alpha;
            gr *= beta;
            ph *= tx;
            col += 1;
        }
        while col > lo {
            gc *= inv_alpha;
            gr *= inv_beta;
            g /= gc;
            ph *= tx.conj();
            col -= 1;
        }
        p.start.push([g, gc, ph.re, ph.im]);
    }
    (alpha, tx)
}

/// Every row's weights and the Gaussian's sum (`Patch::w_re`, `w_im`, `sum`), four rows at a
/// time from their first cells (`machine::row_weights`).
fn fill_weights(p: &mut Patch, rows: &[Row], alpha: f64, tx: C64) {
    let Patch {
        start,
        w_re,
        w_im,
        sum,
        ..
    } = p;
    let mut lane_sum = [0.0; LANES];
    for (group, st) in rows.chunks(LANES).zip(start.chunks(LANES)) {
        // A group short of LANES rows runs its missing lanes on nothing (no cells).
        let lane = |l: usize, k: usize| st.get(l).map_or(0.0, |s| s[k]);
        let n: [usize; LANES] = std::array::from_fn(|l| group.get(l).map_or(0, |r| r.2));
        let len = n.iter().copied().max().unwrap_or(0);
        let at = group[0].3;
        let s = crate::machine::row_weights(
            &mut w_re[at..at + len],
            &mut w_im[at..at + len],
            crate::machine::RowLanes {
                g: std::array::from_fn(|l| lane(l, 0)),
                r: std::array::from_fn(|l| lane(l, 1)),
                re: std::array::from_fn(|l| lane(l, 2)),
                im: std::array::from_fn(|l| lane(l, 3)),
                n: n.map(|n| n as f64),
            },
            alpha,
            [tx.re, tx.im],
        );
        for l in 0..LANES {
            lane_sum[l] += s[l];
        }
    }
    *sum = lane_sum.iter().sum();
}

impl Patch {
    /// The sum of the Gaussian over the patch's cells.
    pub(super) fn sum(&self) -> f64 {
        self.sum
    }

    /// Adds `a w` to the six components of every cell, `w` the cell's weight: the complex
    /// product written as `A Re(w) + B Im(w)` over the twelve reals of a cell (`A = (Re a,
    /// Im a)`, `B = (-Im a, Re a)` per component), the same bits as `a * w` in
    /// `num_complex`, in a form that runs four lanes wide where the CPU has AVX2
    /// (`machine::with_avx2`).
    pub(super) fn splat(&self, cells: &mut [[f64; 12]], a: [Field; 2]) {
        let mut re = [0.0; 12];
        let mut im = [0.0; 12];
        for (comp, v) in a.iter().flatten().enumerate() {
            re[2 * comp] = v.re;
            re[2 * comp + 1] = v.im;
            im[2 * comp] = -v.im;
            im[2 * comp + 1] = v.re;
        }
        crate::machine::splat_cells(cells, &self.runs, &self.w_re, &self.w_im, &re, &im);
    }
}

#[cfg(test)]
mod tests;
