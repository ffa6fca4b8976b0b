//! Directions and frames: spherical angles to unit vectors and back, and orthonormal bases.
//! Conventions (docs/design.md §1): z up, `theta` from +z, `phi` from +x towards +y, angles
//! in radians.

use glam::DVec3;

/// The unit vector of spherical angles `theta_rad` (from +z) and `phi_rad` (from +x).
#[inline]
pub fn from_spherical(theta_rad: f64, phi_rad: f64) -> DVec3 {
    let s = theta_rad.sin();
    DVec3::new(s * phi_rad.cos(), s * phi_rad.sin(), theta_rad.cos())
}

/// `(theta_rad, phi_rad)` of a unit vector, phi in [0, 2 pi).
#[inline]
pub fn angles(w: DVec3) -> (f64, f64) {
    (
        w[2].clamp(-1.0, 1.0).acos(),
        w[1].atan2(w[0]).rem_euclid(std::f64::consts::TAU),
    )
}

/// Two unit vectors completing `d` (unit) to a right-handed orthonormal frame `(u, v, d)`
/// (Duff et al., "Building an orthonormal basis, revisited", JCGT 6(1), 2017).
#[inline]
pub fn frame(d: DVec3) -> (DVec3, DVec3) {
    let sign = 1f64.copysign(d.z);
    let a = -1.0 / (sign + d.z);
    let b = d.x * d.y * a;
    (
        DVec3::new(1.0 + sign * d.x * d.x * a, sign * b, -sign * d.x),
        DVec3::new(b, sign + d.y * d.y * a, -d.y),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angles_invert_from_spherical() {
        for (t, p) in [(0.3, 1.2), (1.5, 5.9), (2.8, 0.1)] {
            let (t2, p2) = angles(from_spherical(t, p));
            assert!((t2 - t).abs() < 1e-12 && (p2 - p).abs() < 1e-12);
        }
    }

    #[test]
    fn frames_are_orthonormal_and_right_handed() {
        for d in [
            DVec3::Z,
            -DVec3::Z,
            DVec3::new(0.3, -0.4, 0.866).normalize(),
            DVec3::X,
        ] {
            let (u, v) = frame(d);
            assert!((u.length() - 1.0).abs() < 1e-12 && (v.length() - 1.0).abs() < 1e-12);
            assert!(u.dot(v).abs() < 1e-12 && u.dot(d).abs() < 1e-12);
            assert!((u.cross(v) - d).length() < 1e-12);
        }
    }
}
