//! MERL BRDF export (Matusik, Pfister, Brand & McMillan, "A Data-Driven Reflectance
//! Model", SIGGRAPH 2003; the database's `BRDFRead.cpp` defines the layout): for fitting
//! tools that read the MERL format. It keeps only sRGB: **the spectrum is lost**.
//!
//! Layout (little endian): three i32 dimensions `90, 90, 180`, then three blocks (red,
//! green, blue) of `90 * 90 * 180` f64, indexed by `phi_d + 180 (theta_d + 90 theta_h)`
//! in Rusinkiewicz's half/difference angles (1998), `theta_h` on the square-root grid
//! `index = sqrt(theta_h / 90 deg) * 90`, `theta_d` and `phi_d` (reduced to [0, 180) deg by
//! reciprocity) on 1-degree grids. The reader multiplies the channels by `1/1500`,
//! `1.15/1500` and `1.66/1500`; the values stored here are divided by them. Each cell holds
//! the BRDF (1/sr) at its centre as linear sRGB: the spectrum weighted by the CIE 1931
//! 2-degree observer (normalised so that a flat spectrum of 1 has Y = 1), then the
//! IEC 61966-2-1 matrix (D65 white). Cells whose centre lies below the horizon hold 0.

use super::ExportError;
use glam::DVec3;
use rayon::prelude::*;

use crate::brdf::{Brdf, Representation};
use crate::render::colour;

pub const THETA_H: usize = 90;
pub const THETA_D: usize = 90;
pub const PHI_D: usize = 180;
/// The reader's scale factors (red, green, blue).
pub const SCALE: [f64; 3] = [1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0];

/// Rotation of `v` about the unit `axis` by `angle` (Rodrigues), as `BRDFRead.cpp`'s
/// `rotate_vector`.
fn rotate(v: DVec3, axis: DVec3, angle: f64) -> DVec3 {
    let (s, c) = angle.sin_cos();
    v * c + axis * (axis.dot(v) * (1.0 - c)) + axis.cross(v) * s
}

/// The incident and outgoing directions of the half/difference angles (radians), with
/// `phi_h = 0` (isotropic): the inverse of `std_coords_to_half_diff_coords`.
pub fn from_half_diff(theta_h: f64, theta_d: f64, phi_d: f64) -> (DVec3, DVec3) {
    let diff = DVec3::new(
        theta_d.sin() * phi_d.cos(),
        theta_d.sin() * phi_d.sin(),
        theta_d.cos(),
    );
    let wi = rotate(diff, DVec3::Y, theta_h);
    let h = DVec3::new(theta_h.sin(), 0.0, theta_h.cos());
    let wo = h * (2.0 * wi.dot(h)) - wi;
    (wi, wo)
}

/// The centre of cell `(i, j, k)`: `theta_h` on the square-root grid, radians.
pub fn cell_centre(i: usize, j: usize, k: usize) -> (f64, f64, f64) {
    let u = (i as f64 + 0.5) / THETA_H as f64;
    let theta_h = u * u * std::f64::consts::FRAC_PI_2;
    let theta_d = (j as f64 + 0.5) / THETA_D as f64 * std::f64::consts::FRAC_PI_2;
    let phi_d = (k as f64 + 0.5) / PHI_D as f64 * std::f64::consts::PI;
    (theta_h, theta_d, phi_d)
}

/// The bytes of a MERL file for `r`.
pub fn merl_bytes(r: &Representation) -> Result<Vec<u8>, ExportError> {
    if !r.meta().isotropic {
        return Err(ExportError::from(
            "the MERL format holds isotropic BRDFs only; build the BRDF without --anisotropic",
        ));
    }
    let weights = colour::bin_weights(&r.meta().lambda_nm);
    let nl = weights.len();
    let n = THETA_H * THETA_D * PHI_D;
    let cells: Vec<[f64; 3]> = (0..n)
        .into_par_iter()
        .map(|idx| {
            let (k, j, i) = (idx % PHI_D, idx / PHI_D % THETA_D, idx / (PHI_D * THETA_D));
            let (th, td, pd) = cell_centre(i, j, k);
            let (wi, wo) = from_half_diff(th, td, pd);
            if wi.z <= 0.0 || wo.z <= 0.0 {
                return [0.0; 3];
            }
            let mut f = vec![0.0; nl];
            r.eval(wi, wo, &mut f);
            colour::xyz_to_linear_srgb(colour::xyz(&f, &weights))
        })
        .collect();
    if let Some(c) = cells.iter().find(|c| c.iter().any(|v| !v.is_finite())) {
        return Err(ExportError::from(format!(
            "the BRDF's colour is not finite: {c:?}"
        )));
    }
    let mut out = Vec::with_capacity(12 + 3 * n * 8);
    for d in [THETA_H, THETA_D, PHI_D] {
        out.extend_from_slice(&(d as i32).to_le_bytes());
    }
    for (ch, scale) in SCALE.iter().enumerate() {
        for c in &cells {
            out.extend_from_slice(&(c[ch] / scale).to_le_bytes());
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The half vector of the reconstructed pair has the cell's theta_h, and its
    /// difference angle the cell's theta_d (Rusinkiewicz 1998, eqs. 1-2).
    #[test]
    fn half_diff_round_trip() {
        for (th, td, pd) in [(0.3, 0.5, 1.0), (0.01, 1.2, 2.9), (1.0, 0.2, 0.1)] {
            let (wi, wo) = from_half_diff(th, td, pd);
            let h = (wi + wo).normalize();
            assert!((h.z.acos() - th).abs() < 1e-12);
            assert!((wi.dot(h).acos() - td).abs() < 1e-12);
            assert!((wi.length() - 1.0).abs() < 1e-12 && (wo.length() - 1.0).abs() < 1e-12);
        }
    }
}
