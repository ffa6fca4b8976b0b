//! Outgoing-direction buckets: a regular (theta, phi) partition of each hemisphere with
//! exactly known projected solid angles.

use glam::DVec3;

/// `theta_bins` equal polar bands over [0, 90°] times `phi_bins` equal azimuth sectors,
/// for each hemisphere (up: reflection, down: transmission; theta measured from +z or -z).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Buckets {
    pub theta_bins: u32,
    pub phi_bins: u32,
}

impl Buckets {
    pub fn len(&self) -> usize {
        // In usize: the product of two u32 counts can wrap a u32.
        self.theta_bins as usize * self.phi_bins as usize
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The bucket of unit direction `w` within its hemisphere.
    #[inline]
    pub fn index(&self, w: DVec3) -> usize {
        let cos = w[2].abs().min(1.0);
        let theta = cos.acos();
        let ti = ((theta / std::f64::consts::FRAC_PI_2) * f64::from(self.theta_bins)) as u32;
        let phi = w[1].atan2(w[0]).rem_euclid(std::f64::consts::TAU);
        let pi = ((phi / std::f64::consts::TAU) * f64::from(self.phi_bins)) as u32;
        (ti.min(self.theta_bins - 1) * self.phi_bins + pi.min(self.phi_bins - 1)) as usize
    }

    /// `(theta0, theta1, phi0, phi1)` of bucket `b`, radians.
    pub fn bounds(&self, b: usize) -> (f64, f64, f64, f64) {
        let (ti, pi) = (b as u32 / self.phi_bins, b as u32 % self.phi_bins);
        let dt = std::f64::consts::FRAC_PI_2 / f64::from(self.theta_bins);
        let dp = std::f64::consts::TAU / f64::from(self.phi_bins);
        (
            f64::from(ti) * dt,
            f64::from(ti + 1) * dt,
            f64::from(pi) * dp,
            f64::from(pi + 1) * dp,
        )
    }

    /// Centre direction angles `(theta, phi)` of bucket `b`, radians.
    pub fn centre(&self, b: usize) -> (f64, f64) {
        let (t0, t1, p0, p1) = self.bounds(b);
        (0.5 * (t0 + t1), 0.5 * (p0 + p1))
    }

    /// Projected solid angle `integral cos(theta) dw` of bucket `b` (sr), exactly:
    /// `(phi1 - phi0) (sin^2 theta1 - sin^2 theta0) / 2`.
    pub fn projected_solid_angle(&self, b: usize) -> f64 {
        let (t0, t1, p0, p1) = self.bounds(b);
        0.5 * (p1 - p0) * (t1.sin().powi(2) - t0.sin().powi(2))
    }
}

/// The bucket of a direction found from its transverse part alone (its direction sines
/// `s`, `|s| = sin theta`), with [`Buckets::index`]'s bands and sectors but without its
/// arc cosine and arc tangent: a transform's far field looks up 25 directions an order
/// (`diffraction::spread`), and those two calls had been a tenth of a diffraction run.
///
/// The band is the last whose lower edge `theta_k = k pi / (2 T)` has `sin^2 theta_k <=
/// |s|^2` (a table over `|s|^2` gives the first candidate). The sector is the last whose
/// lower edge, as the unit vector `e_k = (cos phi_k, sin phi_k)`, has `e_k x s >= 0` while
/// the next edge has `e_(k+1) x s < 0`; a rough arc tangent (Rajan, Wang, Inkol & Joyal,
/// "Efficient approximations for the arctangent function", IEEE Signal Processing Magazine
/// 23(3), 2006, 108: `atan r ~ pi r / 4 + 0.273 r (1 - r)` on `[0, 1]`, within 0.0038 rad)
/// guesses it and the edges settle it. Either agrees with [`Buckets::index`] except for a
/// direction within rounding of an edge.
#[derive(Clone, Debug)]
pub struct SineIndex {
    buckets: Buckets,
    /// `sin^2` of each band's lower edge, and 1 past the last.
    sin2: Vec<f64>,
    /// Per cell of [`SINE_CELLS`] equal cells over `|s|^2` in `[0, 1]`: the band of the
    /// cell's lower end.
    start: Vec<u32>,
    /// Each sector's lower edge as a unit vector.
    edge: Vec<[f64; 2]>,
}

/// Cells of [`SineIndex`]'s table of first bands.
const SINE_CELLS: usize = 512;

impl SineIndex {
    pub fn new(buckets: &Buckets) -> Self {
        let t = buckets.theta_bins;
        let dt = std::f64::consts::FRAC_PI_2 / f64::from(t);
        let sin2: Vec<f64> = (0..=t)
            .map(|k| {
                if k == t {
                    1.0
                } else {
                    (f64::from(k) * dt).sin().powi(2)
                }
            })
            .collect();
        let start = (0..SINE_CELLS)
            .map(|j| {
                let x = j as f64 / SINE_CELLS as f64;
                (0..t).rev().find(|&k| sin2[k as usize] <= x).unwrap_or(0)
            })
            .collect();
        let dp = std::f64::consts::TAU / f64::from(buckets.phi_bins);
        let edge = (0..buckets.phi_bins)
            .map(|k| {
                let a = f64::from(k) * dp;
                [a.cos(), a.sin()]
            })
            .collect();
        SineIndex {
            buckets: *buckets,
            sin2,
            start,
            edge,
        }
    }

    /// The bucket of the direction whose transverse part is `s` (within its hemisphere).
    #[inline]
    pub fn index(&self, s: [f64; 2]) -> usize {
        let mut at = [
            self.first_band(s[0] * s[0] + s[1] * s[1]),
            self.sector_guess(s),
        ];
        self.index_near(s, &mut at)
    }

    /// [`Self::index`], walked from the bucket `at` (`[band, sector]`, updated) of a
    /// direction near `s`: where successive lookups move little, as an order's spread
    /// nodes do from one order to the next along a row of orders, a lookup is a few
    /// products and comparisons. Each bucket's conditions are exclusive, so the bucket found
    /// does not depend on where the walk started.
    #[inline]
    pub fn index_near(&self, s: [f64; 2], at: &mut [u32; 2]) -> usize {
        let p = self.buckets.phi_bins;
        at[0] = self.walk_band(s[0] * s[0] + s[1] * s[1], at[0]);
        at[1] = if p < 3 || (s[0] == 0.0 && s[1] == 0.0) {
            // A sector of half the circle or more is not the wedge between two edges; and
            // the normal, as `atan2(0, 0) = 0`.
            let phi = s[1].atan2(s[0]).rem_euclid(std::f64::consts::TAU);
            (((phi / std::f64::consts::TAU) * f64::from(p)) as u32).min(p - 1)
        } else {
            self.walk_sector(s, at[1].min(p - 1))
        };
        (at[0] * p + at[1]) as usize
    }

    /// A band at or below that of `sin^2 theta = t2`, from the table.
    fn first_band(&self, t2: f64) -> u32 {
        let cell = (t2.clamp(0.0, 1.0) * SINE_CELLS as f64) as usize;
        self.start[cell.min(SINE_CELLS - 1)]
    }

    /// The polar band of a direction with `sin^2 theta = t2`, walked from band `k` (NaN:
    /// the first, as [`Buckets::index`] gives it).
    fn walk_band(&self, t2: f64, mut k: u32) -> u32 {
        if t2.is_nan() {
            return 0;
        }
        let t = self.buckets.theta_bins;
        k = k.min(t - 1);
        while k + 1 < t && t2 >= self.sin2[k as usize + 1] {
            k += 1;
        }
        while k > 0 && t2 < self.sin2[k as usize] {
            k -= 1;
        }
        k
    }

    /// A sector near that of `s` (`s != 0`, at least three sectors): the rough arc
    /// tangent's.
    fn sector_guess(&self, s: [f64; 2]) -> u32 {
        let (ax, ay) = (s[0].abs(), s[1].abs());
        let r = ax.min(ay) / ax.max(ay);
        let mut a = std::f64::consts::FRAC_PI_4 * r + 0.273 * r * (1.0 - r);
        if ay > ax {
            a = std::f64::consts::FRAC_PI_2 - a;
        }
        if s[0] < 0.0 {
            a = std::f64::consts::PI - a;
        }
        if s[1] < 0.0 {
            a = std::f64::consts::TAU - a;
        }
        let p = self.buckets.phi_bins;
        ((a / std::f64::consts::TAU * f64::from(p)) as u32).min(p.saturating_sub(1))
    }

    /// The azimuth sector of `s` (`s != 0`, at least three sectors), walked from sector `i`.
    fn walk_sector(&self, s: [f64; 2], mut i: u32) -> u32 {
        let p = self.buckets.phi_bins;
        let cross = |k: u32| {
            let e = self.edge[k as usize];
            e[0] * s[1] - e[1] * s[0]
        };
        // The edges' signs change from + to - once around the circle, at s: walk to it
        // (NaN stops at once).
        for _ in 0..p {
            let next = if i + 1 == p { 0 } else { i + 1 };
            if cross(i) < 0.0 {
                i = if i == 0 { p - 1 } else { i - 1 };
            } else if cross(next) >= 0.0 {
                i = next;
            } else {
                break;
            }
        }
        i
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against [`Buckets::index`] (the arc cosine and arc tangent): random directions away
    /// from every edge by more than rounding, the axes (edges of sectors at every `P`
    /// divisible by 4) and the normal, for one to many bands and sectors.
    #[test]
    fn the_sines_find_the_bucket_the_angles_do() {
        use std::f64::consts::{FRAC_PI_2, TAU};
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut uniform = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        for (t, p) in [
            (1, 1),
            (1, 2),
            (45, 3),
            (45, 4),
            (45, 36),
            (90, 360),
            (7, 5),
        ] {
            let b = Buckets {
                theta_bins: t,
                phi_bins: p,
            };
            let f = SineIndex::new(&b);
            let mut checked = 0;
            for _ in 0..20_000 {
                let (theta, phi) = (FRAC_PI_2 * uniform(), TAU * uniform());
                let near = |x: f64, w: f64| {
                    let u = x / w;
                    (u - u.round()).abs() < 1e-9
                };
                if near(theta, FRAC_PI_2 / f64::from(t)) || near(phi, TAU / f64::from(p)) {
                    continue;
                }
                let w = DVec3::new(
                    theta.sin() * phi.cos(),
                    theta.sin() * phi.sin(),
                    theta.cos(),
                );
                assert_eq!(
                    f.index([w.x, w.y]),
                    b.index(w),
                    "T {t} P {p}: {theta} {phi}"
                );
                checked += 1;
            }
            assert!(
                checked > 19_000,
                "T {t} P {p}: {checked} directions checked"
            );
            // Walked from the last direction's bucket, along a row of nearby directions
            // and across the hemisphere: the same buckets.
            let mut at = [0, 0];
            for i in 0..4_000 {
                let (theta, phi) = if i % 2 == 0 {
                    (FRAC_PI_2 * uniform(), TAU * uniform())
                } else {
                    (0.3 + 1e-4 * f64::from(i), 0.1 + 1e-3 * f64::from(i))
                };
                let w = DVec3::new(
                    theta.sin() * phi.cos(),
                    theta.sin() * phi.sin(),
                    theta.cos(),
                );
                assert_eq!(f.index_near([w.x, w.y], &mut at), f.index([w.x, w.y]));
            }
            for (x, y) in [(0.5, 0.0), (0.0, 0.5), (-0.5, 0.0), (0.0, -0.5), (0.0, 0.0)] {
                let w = DVec3::new(x, y, (1.0f64 - x * x - y * y).sqrt());
                assert_eq!(f.index([x, y]), b.index(w), "T {t} P {p}: ({x}, {y})");
            }
        }
    }
}
