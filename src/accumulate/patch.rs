//! One tube's Gaussian patch on the diffraction method's grid ([`super::diffraction`]):
//! its rows of cells, their weights by recurrence, and the splat of its field.

use crate::optics::C64;
use crate::optics::fresnel::Field;

/// Patches are cut where their exponent reaches `-PATCH_RADIUS^2 / 2`: `exp(-12.5) = 3.7e-6`
/// of a patch's weight is left out (and renormalised). (At 4 the cells cut off a coarse grid
/// differ from patch to patch enough that a flat film's patches no longer sum to a uniform
/// field to 1e-9 in power.)
pub(super) const PATCH_RADIUS: f64 = 5.0;

/// One tube's patch on the grid, row by row: each row's run of cells inside the ellipse
/// `quad <= PATCH_RADIUS^2`, with the Gaussian and the plane wave's phase at its first cell
/// (evaluated for all rows at once by `phase::exp_batch` and `phase::sin_cos_batch`) and
/// stepped along the row by recurrence, so a cell costs a few multiplications and no
/// transcendental function.
#[derive(Default)]
pub(super) struct Patch {
    /// `(first cell's index, first column, cells)` per row.
    rows: Vec<(usize, usize, usize)>,
    /// Per row: the Gaussian's exponent at the first two cells, then their exponentials.
    arg: Vec<f64>,
    gauss: Vec<f64>,
    /// Per row: the phase at the first cell, its sine and cosine.
    phase: Vec<f64>,
    sin: Vec<f64>,
    cos: Vec<f64>,
    /// Along a row the Gaussian's ratio between neighbouring cells shrinks by this factor
    /// per step (`exp(-ixx dx^2)`), and the phase turns by this one.
    shrink: f64,
    step_phase: C64,
    mx: usize,
}

/// Lays out the patch of a tube at `xw` (nm, in the tile) with inverse covariance `[ixx,
/// iyy, ixy]` (1/nm^2), horizontal standard deviation `sx` (nm) and transverse wave vector
/// `q` (1/nm) on the grid of `[mx, my]` cells of `[dx, dy]` nm.
pub(super) fn patch_rows(
    p: &mut Patch,
    [ixx, iyy, ixy]: [f64; 3],
    sx: f64,
    q: [f64; 2],
    xw: [f64; 2],
    [dx, dy]: [f64; 2],
    [mx, my]: [usize; 2],
) -> &mut Patch {
    p.rows.clear();
    p.arg.clear();
    p.phase.clear();
    let r2 = PATCH_RADIUS * PATCH_RADIUS;
    // The ellipse's extent in y: quad is at least (iyy - ixy^2 / ixx) v^2 = v^2 / cyy.
    let hy = PATCH_RADIUS * (ixx / (ixx * iyy - ixy * ixy)).sqrt();
    let hx = PATCH_RADIUS * sx;
    let (x0, x1) = (
        ((xw[0] - hx) / dx).ceil() as i64,
        ((xw[0] + hx) / dx).floor() as i64,
    );
    let (y0, y1) = (
        ((xw[1] - hy) / dy).ceil() as i64,
        ((xw[1] + hy) / dy).floor() as i64,
    );
    for iy in y0..=y1 {
        let v = iy as f64 * dy - xw[1];
        // The row's cells inside the ellipse: ixx u^2 + 2 ixy v u + iyy v^2 <= r2.
        let b = ixy * v;
        let disc = b * b - ixx * (iyy * v * v - r2);
        if disc < 0.0 {
            continue;
        }
        let root = disc.sqrt();
        let lo = (((xw[0] + (-b - root) / ixx) / dx).ceil() as i64).max(x0);
        let hi = (((xw[0] + (-b + root) / ixx) / dx).floor() as i64).min(x1);
        if lo > hi {
            continue;
        }
        let e = |u: f64| -0.5 * (ixx * u * u + 2.0 * ixy * u * v + iyy * v * v);
        let u = lo as f64 * dx - xw[0];
        p.arg.push(e(u));
        p.arg.push(e(u + dx));
        p.phase.push(q[0] * u + q[1] * v);
        p.rows.push((
            iy.rem_euclid(my as i64) as usize * mx,
            lo.rem_euclid(mx as i64) as usize,
            (hi - lo + 1) as usize,
        ));
    }
    // Quadratic forms are never positive, so the exponentials stay in exp_batch's range.
    super::phase::exp_batch(&p.arg, &mut p.gauss);
    super::phase::sin_cos_batch(&p.phase, &mut p.sin, &mut p.cos);
    p.shrink = (-ixx * dx * dx).exp();
    p.step_phase = C64::from_polar(1.0, q[0] * dx);
    p.mx = mx;
    p
}

impl Patch {
    /// The Gaussian at row `r`'s first cell and its ratio to the next cell's. Every row's
    /// first cell is inside the ellipse (`exp(-12.5)` or more), so the ratio is finite; a
    /// row of one cell never uses it.
    #[inline(always)]
    fn start(&self, r: usize) -> (f64, f64) {
        let g = self.gauss[2 * r];
        (g, self.gauss[2 * r + 1] / g)
    }

    /// The sum of the Gaussian over the patch's cells.
    pub(super) fn sum(&self) -> f64 {
        let mut sum = 0.0;
        for (r, &(_, _, n)) in self.rows.iter().enumerate() {
            let (mut g, mut ratio) = self.start(r);
            for _ in 0..n {
                sum += g;
                g *= ratio;
                ratio *= self.shrink;
            }
        }
        sum
    }

    /// Adds `a w` to the six components of every cell, `w` the Gaussian times the plane
    /// wave: the complex product written as `A Re(w) + B Im(w)` over the twelve reals of a
    /// cell (`A = (Re a, Im a)`, `B = (-Im a, Re a)` per component), the same bits as `a *
    /// w` in `num_complex`, in a form that runs four lanes wide where the CPU has AVX2
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
        crate::machine::with_avx2(
            #[inline(always)]
            move || {
                // By value, so they stay in registers: through the captured references the
                // loads were repeated per cell and the update stayed scalar (1.3x the run).
                let (re, im) = (re, im);
                for (r, &(base, first, n)) in self.rows.iter().enumerate() {
                    let (mut g, mut ratio) = self.start(r);
                    let mut ph = C64::new(self.cos[r], self.sin[r]);
                    let mut col = first;
                    for _ in 0..n {
                        let w = ph * g;
                        let cell = &mut cells[base + col];
                        for i in 0..12 {
                            cell[i] += re[i] * w.re + im[i] * w.im;
                        }
                        g *= ratio;
                        ratio *= self.shrink;
                        ph *= self.step_phase;
                        col += 1;
                        if col == self.mx {
                            col = 0;
                        }
                    }
                }
            },
        );
    }
}
