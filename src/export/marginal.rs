//! The reader's interpolants of the RGL `.bsdf` format: Mitsuba 3's `Marginal2D<Float, D,
//! true>` (`include/mitsuba/core/distr_2d.h`; the RGL loader's `powitacq::Marginal2D` is the
//! same warp), a 2-D table over the unit square that depends linearly on `D` parameters,
//! in its continuous form (Dupuy & Jakob 2018, §5). docs/measured.md gives the equations.
//!
//! A table holds one `h x w` slice per combination of parameter values, the last parameter
//! varying fastest. At a parameter point the reader blends the `2^D` slices around it
//! linearly (each parameter's bracketing values, weights clamped to `[0, 1]`, a parameter
//! of one value ignored), and then:
//! - [`Marginal2D::eval`] is the bilinear interpolant of the blended nodes;
//! - [`Marginal2D::invert`] maps a position to its warped sample: the conditional CDF along
//!   `x` on the position's row, then the marginal CDF along `y`, both of the bilinear
//!   density (each slice normalised to integrate to 1 when built with `normalize`);
//! - [`Marginal2D::sample`] is its inverse.
//!
//! The CDF tables are built per slice and blended, as the reader blends them, so a
//! blended warp is the reader's, not the warp of the blended density.

use super::ExportError;

/// A parameterised piecewise-bilinear table and, where built, its continuous warp.
#[derive(Clone, Debug)]
pub struct Marginal2D {
    w: usize,
    h: usize,
    /// Each parameter's values, ascending.
    params: Vec<Vec<f64>>,
    /// Each parameter's slice stride (0 for a parameter of one value).
    strides: Vec<usize>,
    /// Slice-major nodes, `data[slice * w * h + y * w + x]` (normalised per slice when
    /// `normalized`).
    data: Vec<f64>,
    /// Per slice and row, the row's integral from `x = 0` to each node after the first:
    /// `cond[slice * h * (w - 1) + y * (w - 1) + x]` (empty without the warp).
    cond: Vec<f64>,
    /// Per slice, the integral of the row totals up to each row after the first.
    marg: Vec<f64>,
    normalized: bool,
}

/// The blend of one parameter point: the first slice and, per corner of the parameter
/// box, its slice offset and weight.
struct Blend {
    corners: Vec<(usize, f64)>,
}

impl Marginal2D {
    /// A table of `h` rows of `w` nodes per slice over the parameter values `params`
    /// (each ascending and non-empty); `data` holds `product(params' lengths) * h * w`
    /// values. With `warp`, each slice is normalised to integrate to 1 over the unit
    /// square and its CDFs are built; the slices must then be non-negative and not all
    /// zero.
    pub fn new(
        data: &[f64],
        w: usize,
        h: usize,
        params: Vec<Vec<f64>>,
        warp: bool,
    ) -> Result<Marginal2D, ExportError> {
        if w < 2 || h < 2 {
            return Err(ExportError::from(format!(
                "a table needs at least 2 x 2 nodes, got {w} x {h}"
            )));
        }
        let mut strides = vec![0; params.len()];
        let mut slices = 1usize;
        for (i, p) in params.iter().enumerate().rev() {
            if p.is_empty() {
                return Err(ExportError::from("a table parameter has no value"));
            }
            if p.iter().any(|v| !v.is_finite()) || p.windows(2).any(|v| v[1] <= v[0]) {
                return Err(ExportError::from(
                    "a table parameter's values are not finite and ascending",
                ));
            }
            strides[i] = if p.len() > 1 { slices } else { 0 };
            slices = slices
                .checked_mul(p.len())
                .ok_or("the table's size overflows")?;
        }
        let n = w.checked_mul(h).ok_or("the table's size overflows")?;
        if slices.checked_mul(n) != Some(data.len()) {
            return Err(ExportError::from(format!(
                "a table of {slices} slices of {h} x {w} holds {} values, not {}",
                slices.saturating_mul(n),
                data.len()
            )));
        }
        let mut m = Marginal2D {
            w,
            h,
            params,
            strides,
            data: data.to_vec(),
            cond: Vec::new(),
            marg: Vec::new(),
            normalized: warp,
        };
        if warp {
            m.build_warp(slices)?;
        }
        Ok(m)
    }

    /// The CDFs of each slice of the bilinear density (trapezoidal in `x` on each row,
    /// then in `y` over the row totals: exact for a piecewise-bilinear function), each
    /// slice scaled to a total of 1.
    fn build_warp(&mut self, slices: usize) -> Result<(), ExportError> {
        let (w, h) = (self.w, self.h);
        let (sx, sy) = (0.5 / (w - 1) as f64, 0.5 / (h - 1) as f64);
        self.cond = vec![0.0; slices * h * (w - 1)];
        self.marg = vec![0.0; slices * (h - 1)];
        for s in 0..slices {
            let d = &mut self.data[s * w * h..(s + 1) * w * h];
            if d.iter().any(|v| !(v.is_finite() && *v >= 0.0)) {
                return Err(ExportError::from(
                    "a warp's density is negative or not finite",
                ));
            }
            let cond = &mut self.cond[s * h * (w - 1)..(s + 1) * h * (w - 1)];
            for y in 0..h {
                let mut acc = 0.0;
                for x in 0..w - 1 {
                    acc += sx * (d[y * w + x] + d[y * w + x + 1]);
                    cond[y * (w - 1) + x] = acc;
                }
            }
            let marg = &mut self.marg[s * (h - 1)..(s + 1) * (h - 1)];
            let mut acc = 0.0;
            for y in 0..h - 1 {
                acc += sy * (cond[y * (w - 1) + w - 2] + cond[(y + 1) * (w - 1) + w - 2]);
                marg[y] = acc;
            }
            if !(acc > 0.0 && acc.is_finite()) {
                return Err(ExportError::from(format!(
                    "a warp's density is zero everywhere in slice {s}"
                )));
            }
            let norm = 1.0 / acc;
            cond.iter_mut().for_each(|v| *v *= norm);
            marg.iter_mut().for_each(|v| *v *= norm);
            d.iter_mut().for_each(|v| *v *= norm);
        }
        Ok(())
    }

    /// Nodes per row and rows per slice.
    pub fn size(&self) -> (usize, usize) {
        (self.w, self.h)
    }

    /// The slices around `param` and their weights: per parameter, the interval its
    /// values bracket (the first or last where it lies outside), the weight of the upper
    /// value clamped to `[0, 1]`.
    fn blend(&self, param: &[f64]) -> Blend {
        let mut corners = vec![(0usize, 1.0f64)];
        for (dim, values) in self.params.iter().enumerate() {
            if values.len() == 1 {
                continue;
            }
            let p = param[dim];
            // The last value below p, kept within [0, len - 2] (Mitsuba's find_interval).
            let below = values.partition_point(|v| *v < p);
            let i = below.saturating_sub(1).min(values.len() - 2);
            let t = ((p - values[i]) / (values[i + 1] - values[i])).clamp(0.0, 1.0);
            let stride = self.strides[dim];
            corners = corners
                .into_iter()
                .flat_map(|(o, wgt)| {
                    [
                        (o + stride * i, wgt * (1.0 - t)),
                        (o + stride * (i + 1), wgt * t),
                    ]
                })
                .collect();
        }
        Blend { corners }
    }

    /// `table[slice * size + index]` blended over the corners.
    fn lookup(table: &[f64], size: usize, b: &Blend, index: usize) -> f64 {
        b.corners
            .iter()
            .filter(|c| c.1 != 0.0)
            .map(|&(slice, wgt)| wgt * table[slice * size + index])
            .sum()
    }

    /// The cell holding `u` (clamped to the square) and the position within it.
    fn cell(&self, u: [f64; 2]) -> ([usize; 2], [f64; 2]) {
        let px = u[0].clamp(0.0, 1.0) * (self.w - 1) as f64;
        let py = u[1].clamp(0.0, 1.0) * (self.h - 1) as f64;
        let (ox, oy) = ((px as usize).min(self.w - 2), (py as usize).min(self.h - 2));
        ([ox, oy], [px - ox as f64, py - oy as f64])
    }

    /// The blended nodes at the corners of cell `o`: `[v00, v10, v01, v11]`.
    fn corners(&self, b: &Blend, o: [usize; 2]) -> [f64; 4] {
        let n = self.w * self.h;
        let at = |x: usize, y: usize| Self::lookup(&self.data, n, b, y * self.w + x);
        [
            at(o[0], o[1]),
            at(o[0] + 1, o[1]),
            at(o[0], o[1] + 1),
            at(o[0] + 1, o[1] + 1),
        ]
    }

    /// The bilinear interpolant at `u = (x, y)` for the parameters `param` (Mitsuba's
    /// `Marginal2D::eval`): the table's values, or with the warp the normalised density.
    pub fn eval(&self, u: [f64; 2], param: &[f64]) -> f64 {
        let b = self.blend(param);
        let (o, f) = self.cell(u);
        let v = self.corners(&b, o);
        (1.0 - f[1]) * ((1.0 - f[0]) * v[0] + f[0] * v[1])
            + f[1] * ((1.0 - f[0]) * v[2] + f[0] * v[3])
    }

    /// The blended conditional CDF of row `y` at node `x + 1` (`x < w - 1`).
    fn cond_at(&self, b: &Blend, y: usize, x: usize) -> f64 {
        Self::lookup(&self.cond, self.h * (self.w - 1), b, y * (self.w - 1) + x)
    }

    /// The warp's inverse at position `u` (Mitsuba's `invert_continuous`): the sample in
    /// the unit square, and the density there. Needs the warp.
    pub fn invert(&self, u: [f64; 2], param: &[f64]) -> ([f64; 2], f64) {
        debug_assert!(!self.cond.is_empty(), "invert needs the warp");
        let b = self.blend(param);
        let (o, f) = self.cell(u);
        let v = self.corners(&b, o);
        let c0 = v[0] + (v[2] - v[0]) * f[1];
        let c1 = v[1] + (v[3] - v[1]) * f[1];
        let pdf = c0 + (c1 - c0) * f[0];
        let (wx, wy) = (1.0 / (self.w - 1) as f64, 1.0 / (self.h - 1) as f64);
        // The integral of the density along x within the cell, then the row before it.
        let mut x = f[0] * (c0 + (c1 - c0) * 0.5 * f[0]) * wx;
        let cond = |y: usize, i: usize| self.cond_at(&b, y, i);
        if o[0] > 0 {
            x += cond(o[1], o[0] - 1) + (cond(o[1] + 1, o[0] - 1) - cond(o[1], o[0] - 1)) * f[1];
        }
        let (r0, r1) = (cond(o[1], self.w - 2), cond(o[1] + 1, self.w - 2));
        x /= r0 + (r1 - r0) * f[1];
        let mut y = f[1] * (r0 + (r1 - r0) * 0.5 * f[1]) * wy;
        let marg_len = self.h - 1;
        if o[1] > 0 {
            y += Self::lookup(&self.marg, marg_len, &b, o[1] - 1);
        }
        if !self.normalized {
            y /= Self::lookup(&self.marg, marg_len, &b, marg_len - 1);
        }
        ([x, y], pdf)
    }

    /// The warp's forward map (Mitsuba's `sample_continuous`), the inverse of
    /// [`Marginal2D::invert`]: the position of sample `s` and the density there.
    pub fn sample(&self, s: [f64; 2], param: &[f64]) -> ([f64; 2], f64) {
        debug_assert!(!self.cond.is_empty(), "sample needs the warp");
        let b = self.blend(param);
        let (w, h) = (self.w, self.h);
        let eps = f64::from(f32::EPSILON) * 0.5;
        let mut sx = s[0].clamp(eps, 1.0 - eps);
        let mut sy = s[1].clamp(eps, 1.0 - eps);
        let marg = |i: usize| Self::lookup(&self.marg, h - 1, &b, i);
        if !self.normalized {
            sy *= marg(h - 2);
        }
        // The first row whose cumulative mass reaches the sample.
        let row = (0..h - 1).find(|&i| marg(i) >= sy).unwrap_or(h - 2);
        if row > 0 {
            sy -= marg(row - 1);
        }
        let cond = |y: usize, i: usize| self.cond_at(&b, y, i);
        let (r0, r1) = (cond(row, w - 2), cond(row + 1, w - 2));
        let fy = sample_segment(sy, (h - 1) as f64, r0, r1);
        sx *= r0 + (r1 - r0) * fy;
        let along = |i: usize| cond(row, i) + (cond(row + 1, i) - cond(row, i)) * fy;
        let col = (0..w - 1).find(|&i| along(i) >= sx).unwrap_or(w - 2);
        if col > 0 {
            sx -= along(col - 1);
        }
        let v = self.corners(&b, [col, row]);
        let c0 = v[0] + (v[2] - v[0]) * fy;
        let c1 = v[1] + (v[3] - v[1]) * fy;
        let fx = sample_segment(sx, (w - 1) as f64, c0, c1);
        (
            [
                (col as f64 + fx) / (w - 1) as f64,
                (row as f64 + fy) / (h - 1) as f64,
            ],
            c0 + (c1 - c0) * fx,
        )
    }
}

/// The position within a cell of width `1 / inv_width` whose linear density runs from
/// `v0` to `v1` at which the integral reaches `s` (the root of a quadratic; a constant
/// density where the ends differ by under 1e-4 of their sum, as the reader decides).
fn sample_segment(s: f64, inv_width: f64, v0: f64, v1: f64) -> f64 {
    let s = s * 2.0 * inv_width;
    if (v0 - v1).abs() > 1e-4 * (v0 + v1) {
        (v0 - (v0 * v0 + s * (v1 - v0)).max(0.0).sqrt()) / (v0 - v1)
    } else if v0 + v1 != 0.0 {
        s / (v0 + v1)
    } else {
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(w: usize, h: usize, seed: usize) -> Vec<f64> {
        (0..w * h)
            .map(|k| 0.2 + ((k * 7 + seed * 3) % 5) as f64)
            .collect()
    }

    /// One slice: the inverse agrees with the writer's warp (`warp::Warp`, built and
    /// inverted by its own unnormalised formulas), and `sample` undoes `invert` (to 1e-9
    /// inside; to 1e-6 at a corner, where the reader clamps samples to [2^-24, 1 - 2^-24]).
    #[test]
    fn one_slice_matches_the_writers_warp_and_sample_inverts_it() {
        let (w, h) = (5, 4);
        let data = table(w, h, 0);
        let m = Marginal2D::new(&data, w, h, vec![], true).unwrap();
        let writer = super::super::warp::Warp::new(data.clone(), w, h).unwrap();
        for u in [
            [0.1, 0.2],
            [0.5, 0.5],
            [0.93, 0.07],
            [0.3, 0.99],
            [0.0, 1.0],
        ] {
            let (s, _) = m.invert(u, &[]);
            let t = writer.invert(u);
            assert!(
                (s[0] - t[0]).abs() < 1e-12 && (s[1] - t[1]).abs() < 1e-12,
                "{u:?}"
            );
            let (back, _) = m.sample(s, &[]);
            let tol = if u.contains(&0.0) || u.contains(&1.0) {
                1e-6
            } else {
                1e-9
            };
            assert!(
                (back[0] - u[0]).abs() < tol && (back[1] - u[1]).abs() < tol,
                "{u:?} -> {s:?} -> {back:?}"
            );
        }
        // The density is normalised: the bilinear interpolant integrates to 1.
        let q = 400;
        let mut total = 0.0;
        for a in 0..q {
            for b in 0..q {
                let u = [(a as f64 + 0.5) / q as f64, (b as f64 + 0.5) / q as f64];
                total += m.eval(u, &[]);
            }
        }
        assert!((total / (q * q) as f64 - 1.0).abs() < 1e-6);
    }

    /// Two parameters: at a parameter value on the grid the table is that slice's; between
    /// values the interpolant is the linear blend of the neighbouring slices' interpolants;
    /// a parameter of one value is ignored; values outside the range clamp.
    #[test]
    fn parameters_blend_slices_linearly() {
        let (w, h) = (3, 3);
        let p0 = vec![0.0];
        let p1 = vec![0.0, 1.0, 3.0];
        let slices: Vec<Vec<f64>> = (0..3).map(|s| table(w, h, s + 1)).collect();
        let data: Vec<f64> = slices.iter().flatten().copied().collect();
        let m = Marginal2D::new(&data, w, h, vec![p0, p1.clone()], false).unwrap();
        let single = |s: usize| Marginal2D::new(&slices[s], w, h, vec![], false).unwrap();
        let u = [0.37, 0.81];
        for (s, &p) in p1.iter().enumerate() {
            assert_eq!(m.eval(u, &[5.0, p]), single(s).eval(u, &[]));
        }
        let mid = m.eval(u, &[0.0, 2.5]);
        let want = 0.25 * single(1).eval(u, &[]) + 0.75 * single(2).eval(u, &[]);
        assert!((mid - want).abs() < 1e-12);
        assert_eq!(m.eval(u, &[0.0, 9.0]), single(2).eval(u, &[]));
        assert_eq!(m.eval(u, &[0.0, -1.0]), single(0).eval(u, &[]));
        // The warp of a blend blends the slices' CDF tables: at a parameter on the grid
        // the inverse is that slice's own.
        let mw = Marginal2D::new(&data, w, h, vec![vec![0.0], p1], true).unwrap();
        let sw = Marginal2D::new(&slices[1], w, h, vec![], true).unwrap();
        let (a, _) = mw.invert(u, &[0.0, 1.0]);
        let (b, _) = sw.invert(u, &[]);
        assert!((a[0] - b[0]).abs() < 1e-12 && (a[1] - b[1]).abs() < 1e-12);
        let (s, _) = mw.invert(u, &[0.0, 2.0]);
        let (back, _) = mw.sample(s, &[0.0, 2.0]);
        assert!((back[0] - u[0]).abs() < 1e-9 && (back[1] - u[1]).abs() < 1e-9);
    }

    #[test]
    fn bad_tables_are_refused() {
        assert!(Marginal2D::new(&[1.0; 4], 1, 4, vec![], false).is_err());
        assert!(Marginal2D::new(&[1.0; 5], 2, 2, vec![], false).is_err());
        assert!(Marginal2D::new(&[0.0; 4], 2, 2, vec![], true).is_err());
        assert!(Marginal2D::new(&[1.0, -1.0, 1.0, 1.0], 2, 2, vec![], true).is_err());
        assert!(Marginal2D::new(&[1.0; 8], 2, 2, vec![vec![1.0, 1.0]], false).is_err());
    }
}
