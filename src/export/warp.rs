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

    /// The forward map (`Marginal2D::sample`): sample to position. Each coordinate's CDF
    /// is the integral of a piecewise-linear density, so piecewise quadratic: the cell
    /// holding the target is found by binary search over the CDF at the nodes, and the
    /// quadratic solved there in closed form ([`cell_root`]), as Mitsuba's
    /// `sample_continuous` does. (A bisection of 64 steps per coordinate had been 60 % of
    /// an RGL export's time.)
    pub fn sample(&self, s: [f64; 2]) -> [f64; 2] {
        let (w, h) = (self.w, self.h);
        // The marginal in y: the first row cell whose upper node's CDF reaches the target.
        let ty = s[1].clamp(0.0, 1.0) * self.marg[h - 1];
        let oy = self.marg[1..].partition_point(|&m| m < ty).min(h - 2);
        let fy = cell_root(
            self.total(oy),
            self.total(oy + 1),
            (ty - self.marg[oy]) * (h - 1) as f64,
        );
        let uy = ((oy as f64 + fy) / (h - 1) as f64).clamp(0.0, 1.0);
        // The conditional in x, on the row through uy as `cdf_x` interpolates it.
        let py = uy * (h - 1) as f64;
        let oy = (py as usize).min(h - 2);
        let fy = py - oy as f64;
        let row = (1.0 - fy) * self.total(oy) + fy * self.total(oy + 1);
        if row <= 0.0 {
            // `cdf_x` is the identity on a row without density.
            return [s[0].clamp(0.0, 1.0), uy];
        }
        let tx = s[0].clamp(0.0, 1.0) * row;
        let before =
            |x: usize| (1.0 - fy) * self.cond[oy * w + x] + fy * self.cond[(oy + 1) * w + x];
        let (mut lo, mut hi) = (0usize, w - 2);
        while lo < hi {
            let mid = (lo + hi) / 2;
            if before(mid + 1) < tx {
                lo = mid + 1;
            } else {
                hi = mid;
            }
        }
        let d = |x: usize| (1.0 - fy) * self.data[oy * w + x] + fy * self.data[(oy + 1) * w + x];
        let fx = cell_root(d(lo), d(lo + 1), (tx - before(lo)) * (w - 1) as f64);
        [((lo as f64 + fx) / (w - 1) as f64).clamp(0.0, 1.0), uy]
    }
}

/// The fraction `f` in [0, 1] of a cell at which the integral of a density rising linearly
/// from `c0` to `c1` across it reaches `t` (in units of the cell's width times the density):
/// the root of `c0 f + (c1 - c0) f^2 / 2 = t` in its cancellation-free form
/// `f = 2 t / (c0 + sqrt(c0^2 + 2 (c1 - c0) t))` (Press et al., *Numerical Recipes*, 3rd
/// ed., eq. 5.6.4), which is `t / c0` for a flat density.
fn cell_root(c0: f64, c1: f64, t: f64) -> f64 {
    if t <= 0.0 {
        return 0.0;
    }
    let denom = c0 + (c0 * c0 + 2.0 * (c1 - c0) * t).max(0.0).sqrt();
    if denom > 0.0 {
        (2.0 * t / denom).min(1.0)
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The warp's two maps are inverses, and its CDFs are those of the bilinear density:
    /// checked against a brute-force integral of the interpolant.
    #[test]
    fn warp_maps_invert_each_other_and_match_the_density() {
        let (w, h) = (5, 4);
        let data: Vec<f64> = (0..w * h).map(|k| 0.2 + ((k * 7) % 5) as f64).collect();
        let warp = Warp::new(data.clone(), w, h).unwrap();
        for &s in &[[0.1, 0.2], [0.5, 0.5], [0.93, 0.07], [0.3, 0.99]] {
            let u = warp.sample(s);
            let back = warp.invert(u);
            assert!((back[0] - s[0]).abs() < 1e-12 && (back[1] - s[1]).abs() < 1e-12);
        }
        // With a row and cells without density, and a flat row: the closed-form `sample`
        // equals a 64-step bisection of the CDFs `invert` gives, on a 41 x 41 grid of
        // samples corners included.
        let mut holes = data.clone();
        for x in 0..w {
            holes[2 * w + x] = 0.0;
        }
        holes[1] = 0.0;
        holes[2] = 0.0;
        holes[w + 1] = 0.0;
        holes[w + 2] = 0.0;
        for x in 0..w {
            holes[3 * w + x] = 1.5;
        }
        let bisect = |f: &dyn Fn(f64) -> f64, target: f64| {
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
        for d in [data.clone(), holes] {
            let warp = Warp::new(d, w, h).unwrap();
            for a in 0..=40 {
                for b in 0..=40 {
                    let s = [a as f64 / 40.0, b as f64 / 40.0];
                    let u = warp.sample(s);
                    let uy = bisect(&|y| warp.invert([1.0, y])[1], s[1]);
                    let ux = bisect(&|x| warp.invert([x, uy])[0], s[0]);
                    assert!(
                        (u[0] - ux).abs() < 1e-9 && (u[1] - uy).abs() < 1e-9,
                        "{s:?}: closed form {u:?}, bisection {:?}",
                        [ux, uy]
                    );
                    let back = warp.invert(u);
                    assert!(
                        (back[0] - s[0]).abs() < 1e-12 && (back[1] - s[1]).abs() < 1e-12,
                        "{s:?} -> {u:?} -> {back:?}"
                    );
                }
            }
        }
        // Marginal CDF at uy = 0.6 by a fine midpoint rule over the bilinear density.
        let q = 2000;
        let (mut below, mut all) = (0.0, 0.0);
        for a in 0..q {
            for b in 0..q {
                let u = [(a as f64 + 0.5) / q as f64, (b as f64 + 0.5) / q as f64];
                let v = bilinear(&data, w, h, u);
                all += v;
                if u[1] < 0.6 {
                    below += v;
                }
            }
        }
        assert!((warp.invert([1.0, 0.6])[1] - below / all).abs() < 2e-3);
    }
}
