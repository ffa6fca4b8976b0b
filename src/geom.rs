//! Directions and frames: spherical angles to unit vectors and back, and orthonormal bases;
//! and triangles as the accelerators take them ([`TriangleSoup`]).
//! Conventions (docs/design.md §1): z up, `theta` from +z, `phi` from +x towards +y, angles
//! in radians.

use glam::DVec3;

/// Triangles as the accelerators take them: f32 vertex positions (nanometres, sample
/// frame) and counter-clockwise index triples. The front side of a triangle is the side
/// `(v1 - v0) x (v2 - v0)` points to.
#[derive(Clone, Debug, Default)]
pub struct TriangleSoup {
    pub vertices: Vec<[f32; 3]>,
    pub triangles: Vec<[u32; 3]>,
}

impl TriangleSoup {
    /// The three corners of triangle `prim`.
    #[inline]
    pub fn corners(&self, prim: usize) -> [[f32; 3]; 3] {
        let [a, b, c] = self.triangles[prim];
        [
            self.vertices[a as usize],
            self.vertices[b as usize],
            self.vertices[c as usize],
        ]
    }

    /// Checks what every backend relies on: indices in range and finite coordinates.
    pub fn validate(&self) -> Result<(), SoupError> {
        if let Some(i) = self
            .vertices
            .iter()
            .position(|v| v.iter().any(|c| !c.is_finite()))
        {
            return Err(SoupError::NonFinite {
                vertex: i,
                coords: self.vertices[i],
            });
        }
        let n = self.vertices.len() as u64;
        if let Some(t) = self
            .triangles
            .iter()
            .position(|t| t.iter().any(|&i| u64::from(i) >= n))
        {
            return Err(SoupError::IndexOutOfRange {
                triangle: t,
                indices: self.triangles[t],
                vertices: n,
            });
        }
        Ok(())
    }
}

/// A triangle soup no accelerator can take.
#[derive(Debug, thiserror::Error)]
pub enum SoupError {
    #[error("vertex {vertex} has a non-finite coordinate {coords:?}")]
    NonFinite { vertex: usize, coords: [f32; 3] },
    #[error(
        "triangle {triangle} indexes vertex {indices:?} but there are only {vertices} vertices"
    )]
    IndexOutOfRange {
        triangle: usize,
        indices: [u32; 3],
        vertices: u64,
    },
}

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
