//! One tube's Gaussian patch on the diffraction method's grid ([`super::diffraction`]):
//! its rows of cells, each cell's weight (the Gaussian times the plane wave), and the splat
//! of its field.

use crate::optics::C64;
use crate::optics::fresnel::Field;

/// Patches of a tube whose field is as strong as the incident wave's are cut where their
/// exponent reaches `-PATCH_RADIUS^2 / 2`: `exp(-12.5) = 3.7e-6` of the patch's peak is left
/// out (and renormalised). (At 4 the cells cut off a coarse grid differ from patch to patch
/// enough that a flat film's patches no longer sum to a uniform field to 1e-9 in power.)
/// Weaker tubes are cut where their field falls to the same absolute level ([`radius`]).
pub(super) const PATCH_RADIUS: f64 = 5.0;

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
    /// `(first cell's index in the grid's row, first column, cells, its group's first
    /// weight)` per row; row `r`'s weights are lane `r % LANES` of its group's.
    rows: Vec<(usize, usize, usize, usize)>,
    /// The rows' runs of cells that do not cross the tile's edge (`machine::Run`).
    runs: Vec<crate::machine::Run>,
    /// Per row: its grid row and first column, unwrapped.
    at: Vec<(i64, i64)>,
    /// Per row: the Gaussian, its ratio to the next column and the plane wave at the row's
    /// first cell.
    start: Vec<[f64; 4]>,
    /// The exponents and phases at the patch's first cell, and their values.
    arg: Vec<f64>,
    gauss: Vec<f64>,
    phase: Vec<f64>,
    sin: Vec<f64>,
    cos: Vec<f64>,
    /// Per cell of the longest row of each group of [`LANES`] rows, the group's rows side
    /// by side: the weights' real and imaginary parts.
    w_re: Vec<[f64; LANES]>,
    w_im: Vec<[f64; LANES]>,
    /// The Gaussian's sum over the patch's cells.
    sum: f64,
}

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

/// Lays out the patch of a tube at `xw` (nm, in the tile) with inverse covariance `[ixx,
/// iyy, ixy]` (1/nm^2), horizontal standard deviation `sx` (nm), cut at `radius` standard
/// deviations ([`radius`]), and transverse wave vector `q` (1/nm) on the grid of `[mx,
/// my]` cells of `[dx, dy]` nm; with every cell's weight and the Gaussian's sum (see
/// [`Patch`] for the recurrences).
#[allow(clippy::too_many_arguments)]
pub(super) fn patch_rows(
    p: &mut Patch,
    [ixx, iyy, ixy]: [f64; 3],
    sx: f64,
    radius: f64,
    q: [f64; 2],
    xw: [f64; 2],
    [dx, dy]: [f64; 2],
    [mx, my]: [usize; 2],
) -> &mut Patch {
    p.rows.clear();
    p.runs.clear();
    p.at.clear();
    p.start.clear();
    p.sum = 0.0;
    let r2 = radius * radius;
    let (inv_ixx, inv_dx) = (1.0 / ixx, 1.0 / dx);
    // The ellipse's extent in y: quad is at least (iyy - ixy^2 / ixx) v^2 = v^2 / cyy.
    let hy = radius * (ixx / (ixx * iyy - ixy * ixy)).sqrt();
    let hx = radius * sx;
    let (x0, x1) = (
        ceil_i((xw[0] - hx) * inv_dx),
        floor_i((xw[0] + hx) * inv_dx),
    );
    let (y0, y1) = (ceil_i((xw[1] - hy) / dy), floor_i((xw[1] + hy) / dy));
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
        p.at.push((iy, lo));
        p.rows.push((wrap(iy, my) * mx, wrap(lo, mx), n, 0));
    }
    let Some(&(iy0, lo0)) = p.at.first() else {
        return p;
    };
    let (alpha, tx) = row_starts(p, [ixx, iyy, ixy], q, xw, [dx, dy], (iy0, lo0));
    // Each group of LANES rows gets its longest row's length of weights.
    let mut cells = 0;
    for group in p.rows.chunks_mut(LANES) {
        let len = group.iter().map(|r| r.2).max().unwrap_or(0);
        for r in group {
            r.3 = cells;
        }
        cells += len;
    }
    p.w_re.resize(cells, [0.0; LANES]);
    p.w_im.resize(cells, [0.0; LANES]);
    for (r, &(base, first, n, at)) in p.rows.iter().enumerate() {
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
    fill_weights(p, alpha, tx);
    p
}

/// Every row's first cell (`Patch::start`) from the patch's first, at grid row `iy0` and
/// column `lo0`: its Gaussian, ratios and phase evaluated there, then carried from row to
/// row by the recurrences of [`Patch`]. Returns the shrink of the column ratio per column,
/// `exp(-ixx dx^2)`, and the phase's turn per column.
fn row_starts(
    p: &mut Patch,
    [ixx, iyy, ixy]: [f64; 3],
    q: [f64; 2],
    xw: [f64; 2],
    [dx, dy]: [f64; 2],
    (iy0, lo0): (i64, i64),
) -> (f64, C64) {
    // The patch's first cell: the Gaussian's exponent there and its steps one column right
    // and one row up; the constant shrinks; the phase there and its turns per column and row.
    let (u0, v0) = (lo0 as f64 * dx - xw[0], iy0 as f64 * dy - xw[1]);
    let e = |u: f64, v: f64| -0.5 * (ixx * u * u + 2.0 * ixy * u * v + iyy * v * v);
    let e00 = e(u0, v0);
    let ln_col = e(u0 + dx, v0) - e00;
    let ln_row = e(u0, v0 + dy) - e00;
    let ln_beta = -ixy * dx * dy;
    let (ln_alpha, ln_gamma) = (-ixx * dx * dx, -iyy * dy * dy);
    // exp_batch takes arguments <= 0: a positive one is taken as the reciprocal of its
    // negative's exponential.
    let args = [e00, ln_col, ln_row, ln_beta, ln_alpha, ln_gamma];
    p.arg.clear();
    p.arg.extend(args.iter().map(|x| -x.abs()));
    if args.iter().all(|x| x.abs() < EXP_SAFE) {
        super::phase::exp_batch(&p.arg, &mut p.gauss);
        for (g, x) in p.gauss.iter_mut().zip(args) {
            if x > 0.0 {
                *g = 1.0 / *g;
            }
        }
    } else {
        p.gauss.clear();
        p.gauss.extend(args.iter().map(|x| x.exp()));
    }
    let [g00, col0, row0, beta, alpha, gamma] = [0, 1, 2, 3, 4, 5].map(|i| p.gauss[i]);
    let (inv_alpha, inv_beta) = (1.0 / alpha, 1.0 / beta);
    p.phase.clear();
    p.phase
        .extend([q[0] * u0 + q[1] * v0, q[0] * dx, q[1] * dy]);
    super::phase::sin_cos_batch(&p.phase, &mut p.sin, &mut p.cos);
    let ph0 = C64::new(p.cos[0], p.sin[0]);
    let tx = C64::new(p.cos[1], p.sin[1]);
    let ty = C64::new(p.cos[2], p.sin[2]);
    // Every row's first cell from the last one's: rows up, then columns right or left.
    let (mut g, mut gc, mut gr, mut ph) = (g00, col0, row0, ph0);
    let (mut iy, mut col) = (iy0, lo0);
    for &(row, lo) in &p.at {
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
fn fill_weights(p: &mut Patch, alpha: f64, tx: C64) {
    let Patch {
        rows,
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
mod tests {
    use super::*;

    /// The patch's splat against the definition evaluated cell by cell: every cell of the
    /// grid whose unwrapped offset `(u, v)` from the tube's point lies inside the ellipse
    /// `quad(u, v) <= radius^2` gets `a exp(-quad / 2) exp(i q . (u, v))`, added at its
    /// place modulo the grid (periodic images), and the Gaussian's sum is their sum.
    fn reference(
        inv: [f64; 3],
        radius: f64,
        q: [f64; 2],
        xw: [f64; 2],
        d: [f64; 2],
        [mx, my]: [usize; 2],
        a: [Field; 2],
    ) -> (Vec<[f64; 12]>, f64) {
        let [ixx, iyy, ixy] = inv;
        let mut cells = vec![[0.0; 12]; mx * my];
        let mut sum = 0.0;
        let reach = 8 * mx.max(my) as i64;
        for iy in -reach..reach {
            for ix in -reach..reach {
                let (u, v) = (ix as f64 * d[0] - xw[0], iy as f64 * d[1] - xw[1]);
                let quad = ixx * u * u + 2.0 * ixy * u * v + iyy * v * v;
                if quad > radius * radius {
                    continue;
                }
                let g = (-0.5 * quad).exp();
                sum += g;
                let w = C64::from_polar(g, q[0] * u + q[1] * v);
                let cell = &mut cells[wrap(iy, my) * mx + wrap(ix, mx)];
                for (comp, f) in a.iter().flatten().enumerate() {
                    let z = f * w;
                    cell[2 * comp] += z.re;
                    cell[2 * comp + 1] += z.im;
                }
            }
        }
        (cells, sum)
    }

    /// The rows, their weights by recurrence four cells a lane, and the runs split at the
    /// tile's edge give what the definition gives, cell by cell: a round patch, a sheared
    /// one cut at the smallest radius, one wider than a lane crossing both edges of the
    /// grid, and one larger than the grid itself (its images overlap).
    #[test]
    fn the_splat_is_the_gaussian_times_the_plane_wave_in_every_cell() {
        let a: [Field; 2] = [
            [
                C64::new(0.3, -0.1),
                C64::new(0.05, 0.2),
                C64::new(-0.02, 0.01),
            ],
            [
                C64::new(-0.1, 0.4),
                C64::new(0.2, 0.0),
                C64::new(0.0, -0.03),
            ],
        ];
        // (inverse covariance from cxx, cyy, cxy in nm^2; radius; q in 1/nm; point in nm;
        // spacing in nm; cells).
        type Case = ([f64; 3], f64, [f64; 2], [f64; 2], [f64; 2], [usize; 2]);
        let cases: [Case; 5] = [
            (
                [15_000.0, 15_000.0, 0.0],
                5.0,
                [0.004, -0.002],
                [1013.7, 987.2],
                [103.0, 97.0],
                [20, 21],
            ),
            (
                [40_000.0, 9_000.0, 15_000.0],
                1.5,
                [-0.011, 0.007],
                [777.7, 1201.3],
                [101.0, 99.0],
                [24, 25],
            ),
            (
                [90_000.0, 30_000.0, -20_000.0],
                4.2,
                [0.013, 0.009],
                [30.5, 1911.1],
                [99.0, 103.0],
                [20, 20],
            ),
            (
                [250_000.0, 200_000.0, 50_000.0],
                5.0,
                [0.002, 0.001],
                [500.3, 400.9],
                [100.0, 100.0],
                [9, 8],
            ),
            // A tube squeezed to the covariance's floor across and stretched along a
            // diagonal (correlation 0.99): the recurrences' ratios at their extremes.
            (
                [2_600.0, 250_000.0, 0.99 * (2_600.0f64 * 250_000.0).sqrt()],
                5.0,
                [-0.015, 0.012],
                [1503.1, 1188.4],
                [100.0, 101.0],
                [30, 31],
            ),
        ];
        for (k, &([cxx, cyy, cxy], radius, q, xw, d, n)) in cases.iter().enumerate() {
            let det = cxx * cyy - cxy * cxy;
            let inv = [cyy / det, cxx / det, -cxy / det];
            let (want, want_sum) = reference(inv, radius, q, xw, d, n, a);
            let mut p = Patch::default();
            let rows = patch_rows(&mut p, inv, cxx.sqrt(), radius, q, xw, d, n);
            let sum = rows.sum();
            let mut got = vec![[0.0; 12]; n[0] * n[1]];
            rows.splat(&mut got, a);
            assert!(
                (sum - want_sum).abs() <= 1e-12 * want_sum,
                "case {k}: sum {sum} against {want_sum}"
            );
            let scale = want.iter().flatten().fold(0.0f64, |m, x| m.max(x.abs()));
            assert!(scale > 0.0);
            for (c, (g, w)) in got.iter().zip(&want).enumerate() {
                for i in 0..12 {
                    assert!(
                        (g[i] - w[i]).abs() <= 1e-12 * scale,
                        "case {k}, cell {c}, real {i}: {} against {}",
                        g[i],
                        w[i]
                    );
                }
            }
        }
    }

    /// `ceil_i` and `floor_i` against the library's, at integers, halves, either side of
    /// them and far out.
    #[test]
    fn ceil_and_floor_are_the_librarys() {
        for x in [
            0.0f64,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            2.5,
            -2.5,
            3.4999,
            -3.4999,
            1e-300,
            -1e-300,
            123456.75,
            -98765.25,
            1.0e15 + 0.5,
            -(1.0e15 + 0.5),
        ] {
            for y in [x, x.next_up(), x.next_down()] {
                assert_eq!(ceil_i(y), y.ceil() as i64, "ceil {y}");
                assert_eq!(floor_i(y), y.floor() as i64, "floor {y}");
            }
        }
    }

    /// Where a tube's patch is cut: at `PATCH_RADIUS` for a tube as strong as the incident
    /// wave or stronger, where `m exp(-r^2 / 2) = exp(-PATCH_RADIUS^2 / 2)` below it, and
    /// never under `MIN_RADIUS` (a vanishing tube, too).
    #[test]
    fn weaker_tubes_are_cut_at_the_same_absolute_level() {
        assert_eq!(radius(1.0), PATCH_RADIUS);
        assert_eq!(radius(3.0), PATCH_RADIUS);
        assert_eq!(radius(f64::NAN), PATCH_RADIUS);
        for m in [0.5, 1e-2, 1e-4] {
            let r = radius(m);
            let level = m * (-0.5 * r * r).exp();
            let want = (-0.5 * PATCH_RADIUS * PATCH_RADIUS).exp();
            assert!((level / want - 1.0).abs() < 1e-12, "m {m}: r {r}");
        }
        assert_eq!(radius(1e-9), MIN_RADIUS);
        assert_eq!(radius(0.0), MIN_RADIUS);
    }
}
