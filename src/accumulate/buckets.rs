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
