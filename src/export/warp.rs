//! The continuous piecewise-bilinear warp of the RGL reader (Mitsuba 3's `Marginal2D<Float,
//! 0, true>`, `src/core/math` and `include/mitsuba/core/distr_2d.h`), mirrored so that the
//! writer puts its nodes where the reader will look (Dupuy & Jakob 2018, §5), and the
//! bilinear interpolation both use.

use super::ExportError;

/// Bilinear interpolation of a `h x w` grid over the unit square, nodes on its edges
/// (Mitsuba's `Marginal2D::eval` for data stored unnormalised). `u = (x, y)`.
pub(super) fn bilinear(data: &[f64], w: usize, h: usize, u: [f64; 2]) -> f64 {
    let px = u[0].clamp(0.0, 1.0) * (w - 1) as f64;
    let py = u[1].clamp(0.0, 1.0) * (h - 1) as f64;
    let (ox, oy) = ((px as usize).min(w - 2), (py as usize).min(h - 2));
    let (fx, fy) = (px - ox as f64, py - oy as f64);
    let at = |x: usize, y: usize| data[y * w + x];
    (1.0 - fy) * ((1.0 - fx) * at(ox, oy) + fx * at(ox + 1, oy))
        + fy * ((1.0 - fx) * at(ox, oy + 1) + fx * at(ox + 1, oy + 1))
}

/// The continuous piecewise-bilinear warp of Mitsuba's `Marginal2D<Float, 0, true>`: the
/// density is the bilinear interpolant of the data; `invert` maps a position `u` to its
/// marginal CDF in y and conditional CDF in x (closed form, as `invert_continuous`), and
/// `sample` is its inverse (by bisection, each coordinate monotone).
pub struct Warp {
    w: usize,
    h: usize,
    data: Vec<f64>,
    /// Per row, the integral of the row from x = 0 to each node (unit-square units).
    cond: Vec<f64>,
    /// Per row node, the integral up to it of the row totals.
    marg: Vec<f64>,
}

impl Warp {
    /// A warp over non-negative `data` (`h` rows of `w`), not all zero.
    pub fn new(data: Vec<f64>, w: usize, h: usize) -> Result<Warp, ExportError> {
        assert!(w >= 2 && h >= 2 && data.len() == w * h);
        if data.iter().any(|v| !(v.is_finite() && *v >= 0.0)) {
            return Err(ExportError::from(
                "a warp density is negative or not finite",
            ));
        }
        let mut cond = vec![0.0; w * h];
        for y in 0..h {
            let mut acc = 0.0;
            for x in 0..w - 1 {
                acc += 0.5 * (data[y * w + x] + data[y * w + x + 1]) / (w - 1) as f64;
                cond[y * w + x + 1] = acc;
            }
        }
        let mut marg = vec![0.0; h];
        for y in 0..h - 1 {
            marg[y + 1] =
                marg[y] + 0.5 * (cond[y * w + w - 1] + cond[(y + 1) * w + w - 1]) / (h - 1) as f64;
        }
        if marg[h - 1] <= 0.0 {
            return Err(ExportError::from("a warp density is zero everywhere"));
        }
        Ok(Warp {
            w,
            h,
            data,
            cond,
            marg,
        })
    }

    fn total(&self, y: usize) -> f64 {
        self.cond[y * self.w + self.w - 1]
    }

    /// The marginal CDF at `uy`.
    fn cdf_y(&self, uy: f64) -> f64 {
        let py = uy.clamp(0.0, 1.0) * (self.h - 1) as f64;
        let oy = (py as usize).min(self.h - 2);
        let fy = py - oy as f64;
        let (r0, r1) = (self.total(oy), self.total(oy + 1));
        (self.marg[oy] + fy * (r0 + 0.5 * fy * (r1 - r0)) / (self.h - 1) as f64)
            / self.marg[self.h - 1]
    }

    /// The conditional CDF at `ux` on the row through `uy`.
    fn cdf_x(&self, ux: f64, uy: f64) -> f64 {
        let (w, h) = (self.w, self.h);
        let px = ux.clamp(0.0, 1.0) * (w - 1) as f64;
        let py = uy.clamp(0.0, 1.0) * (h - 1) as f64;
        let (ox, oy) = ((px as usize).min(w - 2), (py as usize).min(h - 2));
        let (fx, fy) = (px - ox as f64, py - oy as f64);
        let d = |x: usize, y: usize| self.data[y * w + x];
        let c0 = (1.0 - fy) * d(ox, oy) + fy * d(ox, oy + 1);
        let c1 = (1.0 - fy) * d(ox + 1, oy) + fy * d(ox + 1, oy + 1);
        let partial = fx * (c0 + 0.5 * fx * (c1 - c0)) / (w - 1) as f64;
        let before = (1.0 - fy) * self.cond[oy * w + ox] + fy * self.cond[(oy + 1) * w + ox];
        let row = (1.0 - fy) * self.total(oy) + fy * self.total(oy + 1);
        if row > 0.0 {
            (before + partial) / row
        } else {
            ux
        }
    }

    /// The warp's inverse map (`Marginal2D::invert`): position to sample.
    pub fn invert(&self, u: [f64; 2]) -> [f64; 2] {
        [self.cdf_x(u[0], u[1]), self.cdf_y(u[1])]
    }

    /// The forward map (`Marginal2D::sample`): sample to position.
    pub fn sample(&self, s: [f64; 2]) -> [f64; 2] {
        let solve = |f: &dyn Fn(f64) -> f64, target: f64| {
            let (mut lo, mut hi) = (0.0f64, 1.0f64);
            for _ in 0..64 {
                let mid = 0.5 * (lo + hi);
                if f(mid) < target {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            0.5 * (lo + hi)
        };
        let uy = solve(&|y| self.cdf_y(y), s[1]);
        let ux = solve(&|x| self.cdf_x(x, uy), s[0]);
        [ux, uy]
    }
}
