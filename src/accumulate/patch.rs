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

/// Cells a row is computed in at once: four lanes of independent recurrences, so the
/// weights run four wide (`machine::with_avx2`) instead of along one chain of dependent
/// multiplications.
const LANES: usize = 4;
// The row set-up in `patch_rows` writes the first four Gaussians out by hand.
const _: () = assert!(LANES == 4);

/// One tube's patch on the grid, row by row: each row's run of cells inside the ellipse
/// `quad <= radius^2`, and every cell's weight, the Gaussian times the plane wave. A row's
/// first [`LANES`] Gaussians and the phase at its first cell are evaluated for all rows at
/// once (`phase::exp_batch`, `phase::sin_cos_batch`); the rest of the row follows by
/// recurrence, each lane `LANES` cells on: the Gaussian's ratio over `LANES` cells shrinks
/// by `exp(-ixx (LANES dx)^2)` per step, and the phase turns by `q_x LANES dx`. A cell
/// costs a few multiplications and no transcendental function.
#[derive(Default)]
pub(super) struct Patch {
    /// `(first cell's index in the grid's row, first column, cells, first weight)` per row.
    rows: Vec<(usize, usize, usize, usize)>,
    /// Per row: the Gaussian's exponent at the first two cells, then their exponentials.
    arg: Vec<f64>,
    gauss: Vec<f64>,
    /// Per row: the plane wave's phase at its first cell, its sine and cosine.
    phase: Vec<f64>,
    sin: Vec<f64>,
    cos: Vec<f64>,
    /// Per cell of every row, padded to whole lanes: the weight's real and imaginary parts.
    w_re: Vec<f64>,
    w_im: Vec<f64>,
    /// The Gaussian's sum over the patch's cells.
    sum: f64,
    mx: usize,
}

/// `ceil x` for `|x| < 2^53` (the C library's `ceil` is a call on baseline x86-64).
fn ceil_i(x: f64) -> i64 {
    let t = x as i64;
    if (t as f64) < x { t + 1 } else { t }
}

/// `floor x` for `|x| < 2^53`.
fn floor_i(x: f64) -> i64 {
    let t = x as i64;
    if (t as f64) > x { t - 1 } else { t }
}

/// `i mod n` in `0..n`, without the division where `i` is already in range.
fn wrap(i: i64, n: usize) -> usize {
    if (0..n as i64).contains(&i) {
        i as usize
    } else {
        i.rem_euclid(n as i64) as usize
    }
}

/// Lays out the patch of a tube at `xw` (nm, in the tile) with inverse covariance `[ixx,
/// iyy, ixy]` (1/nm^2), horizontal standard deviation `sx` (nm), cut at `radius` standard
/// deviations ([`radius`]), and transverse wave vector `q` (1/nm) on the grid of `[mx,
/// my]` cells of `[dx, dy]` nm; with every cell's weight and the Gaussian's sum.
///
/// Only a row's first two Gaussians are exponentials (`phase::exp_batch`, for all rows at
/// once); the rest follow from their ratio `rho` and the per-cell shrink `s = exp(-ixx
/// dx^2)`: `g_l = g_0 rho^l s^(l (l - 1) / 2)`. A row's first phase is one sine and cosine
/// (`phase::sin_cos_batch`, for all rows at once), the rest the column step's powers.
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
    p.arg.clear();
    p.phase.clear();
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
    let mut cells = 0;
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
        let u = lo as f64 * dx - xw[0];
        let e = |u: f64| -0.5 * (ixx * u * u + 2.0 * ixy * u * v + iyy * v * v);
        p.arg.push(e(u));
        p.arg.push(e(u + dx));
        p.phase.push(q[0] * u + q[1] * v);
        let n = (hi - lo + 1) as usize;
        p.rows.push((wrap(iy, my) * mx, wrap(lo, mx), n, cells));
        cells += n.div_ceil(LANES) * LANES;
    }
    // The per-cell shrink's exponent and the column step's phase ride in the same batches,
    // last. Quadratic forms are never positive, so the exponentials stay in exp_batch's
    // range.
    p.arg.push(-ixx * dx * dx);
    p.phase.push(q[0] * dx);
    super::phase::exp_batch(&p.arg, &mut p.gauss);
    super::phase::sin_cos_batch(&p.phase, &mut p.sin, &mut p.cos);
    p.mx = mx;
    let s = p.gauss[p.gauss.len() - 1];
    // s^(LANES l) for l in 0..LANES, s^(LANES (LANES - 1) / 2), and s^(LANES^2): how much
    // a lane's ratio over LANES cells shrinks per LANES cells.
    let mut s_lanes = [1.0; LANES];
    let s4 = s * s * s * s;
    for l in 1..LANES {
        s_lanes[l] = s_lanes[l - 1] * s4;
    }
    let s6 = s * s * s * s * s * s;
    let shrink = s4 * s4 * s4 * s4;
    // The phase's turn over 0..=LANES cells.
    let col_step = C64::new(p.cos[p.cos.len() - 1], p.sin[p.sin.len() - 1]);
    let mut turn = [C64::new(1.0, 0.0); LANES + 1];
    for l in 1..=LANES {
        turn[l] = turn[l - 1] * col_step;
    }
    let t4 = turn[LANES];
    p.w_re.resize(cells, 0.0);
    p.w_im.resize(cells, 0.0);
    let Patch {
        rows,
        gauss,
        sin,
        cos,
        w_re,
        w_im,
        sum,
        ..
    } = p;
    *sum = crate::machine::with_avx2(
        #[inline(always)]
        move || {
            let mut lane_sum = [0.0; LANES];
            for (r, &(_, _, n, at)) in rows.iter().enumerate() {
                // g_l = g_0 rho^l s^(l (l - 1) / 2) and the ratio g_(l + LANES) / g_l =
                // rho^LANES s^(LANES (LANES - 1) / 2) s^(LANES l), for l in 0..LANES.
                let g0 = gauss[2 * r];
                let g1 = gauss[2 * r + 1];
                let rho = g1 / g0;
                let g2 = g1 * rho * s;
                let g3 = g2 * rho * s * s;
                let mut gl = [g0, g1, g2, g3];
                let rho2 = rho * rho;
                let r0 = rho2 * rho2 * s6;
                let mut ratio: [f64; LANES] = std::array::from_fn(|l| r0 * s_lanes[l]);
                let ph = C64::new(cos[r], sin[r]);
                let mut re: [f64; LANES] = std::array::from_fn(|l| (ph * turn[l]).re);
                let mut im: [f64; LANES] = std::array::from_fn(|l| (ph * turn[l]).im);
                let chunks = n.div_ceil(LANES);
                let (w_re, w_im) = (
                    &mut w_re[at..at + chunks * LANES],
                    &mut w_im[at..at + chunks * LANES],
                );
                for (c, (wr, wi)) in w_re
                    .chunks_exact_mut(LANES)
                    .zip(w_im.chunks_exact_mut(LANES))
                    .enumerate()
                {
                    // The row's last chunk holds cells beyond it, which count for nothing.
                    let live = n - c * LANES;
                    let mask: [f64; LANES] = std::array::from_fn(|l| f64::from(u8::from(l < live)));
                    for l in 0..LANES {
                        wr[l] = re[l] * gl[l];
                        wi[l] = im[l] * gl[l];
                        lane_sum[l] += gl[l] * mask[l];
                        gl[l] *= ratio[l];
                        ratio[l] *= shrink;
                        (re[l], im[l]) =
                            (re[l] * t4.re - im[l] * t4.im, re[l] * t4.im + im[l] * t4.re);
                    }
                }
            }
            lane_sum.iter().sum()
        },
    );
    p
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
        for &(base, first, n, at) in &self.rows {
            // The row's cells in runs that do not cross the tile's edge.
            let (mut col, mut done) = (first, 0);
            while done < n {
                let len = (n - done).min(self.mx - col);
                crate::machine::splat_cells(
                    &mut cells[base + col..base + col + len],
                    &self.w_re[at + done..at + done + len],
                    &self.w_im[at + done..at + done + len],
                    &re,
                    &im,
                );
                done += len;
                col = 0;
            }
        }
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
        let cases: [Case; 4] = [
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
