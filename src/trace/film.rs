//! Thin absorbing films handed to the transfer-matrix method (docs/physics.md, "Thin
//! absorbing films: the local film").
//!
//! Where a homogeneous wave enters an absorbing medium from a lossless one and the medium's
//! far face
//! lies close behind the entry point, nearly parallel to it, the tracer does not follow
//! the film's internal series of partial waves: it takes the film's coherent response,
//! the transfer-matrix amplitudes of a flat film of the local thickness (the tangent-plane
//! or local-film model), and sends the transmitted wave on from the far face. For parallel
//! faces that is exact. For faces meeting at a small angle it is the local-film model, which
//! RCWA confirms on tilted gold films (within 3.5e-3 in TE up to 5 degrees; in TM within 3e-3
//! at 1 degree, where the ray series were 2e-2 off), while the ray series of such a film are
//! inhomogeneous plane waves whose recombination no ray estimator gets right beyond a few
//! tenths of a degree (the roof of tests/tilted_absorbers.rs: 1.0e-2 off at 1 degree, energy
//! created at 3).
//!
//! The hand-off has a weight `h` in [0, 1], continuous in the geometry: the film's result
//! is `h` times the local film's plus `1 - h` times the ray series' (amplitudes, so the
//! coherent sum is the same blend of fields). `h = tilt_weight(beta) * depth_weight(d /
//! lambda)`, with `beta` the angle between the faces and `d` the film's thickness along the
//! entry face's normal: 1 for films thin against the wavelength whose faces meet within
//! [`FILM_TILT_FULL`], falling smoothly to 0 at [`FILM_TILT_NONE`] and at a thickness of
//! one wavelength. Beyond those the ray model takes the light alone: thick layers carry
//! homogeneous-enough waves, or none at all once opaque (gold 500 nm thick transmits
//! 1e-12), and faces meeting at a large angle are ridges and wedges, which the event
//! weights and the run's warnings handle.

use super::{RayState, Scene};
use crate::optics::C64;
use glam::DVec3;

/// Faces meeting within this angle (degrees) are handed to the local film entirely.
pub const FILM_TILT_FULL: f64 = 20.0;
/// Faces meeting at this angle (degrees) or more are left to the ray series.
pub const FILM_TILT_NONE: f64 = 30.0;

/// The far face of a film found behind an entry point.
#[derive(Clone, Copy, Debug)]
pub(super) struct FilmBack {
    /// Where the probe along the entry face's inward normal meets the far face (tile
    /// coordinates, and the unwrapped offset of that tile copy), nm.
    pub pos: DVec3,
    pub off: [f64; 2],
    /// The film's local thickness: the probe's length, nm.
    pub depth_nm: f64,
    /// The far face's triangle, its unit normal facing back into the film, and the medium
    /// beyond it.
    pub prim: u32,
    pub normal: DVec3,
    pub beyond: usize,
    /// The hand-off's weight from the tilt between the faces alone ([`tilt_weight`]).
    pub tilt_weight: f64,
}

/// A raised-cosine step from 1 at `x <= a` to 0 at `x >= b` (C1-continuous).
fn step_down(x: f64, a: f64, b: f64) -> f64 {
    if x <= a {
        1.0
    } else if x >= b {
        0.0
    } else {
        0.5 * (1.0 + (std::f64::consts::PI * (x - a) / (b - a)).cos())
    }
}

/// The hand-off's weight for faces meeting at `beta_deg` degrees: 1 up to
/// [`FILM_TILT_FULL`], 0 from [`FILM_TILT_NONE`], a raised cosine between.
pub fn tilt_weight(beta_deg: f64) -> f64 {
    step_down(beta_deg, FILM_TILT_FULL, FILM_TILT_NONE)
}

/// The hand-off's weight for a film `depth_nm` thick at vacuum wavelength `lambda_nm`: 1 up
/// to half a wavelength, 0 from one wavelength, a raised cosine between.
pub fn depth_weight(depth_nm: f64, lambda_nm: f64) -> f64 {
    step_down(depth_nm / lambda_nm, 0.5, 1.0)
}

impl Scene<'_> {
    /// The far face of the medium `film` that the ray `r`, at its entry point on a facet of
    /// normal `nf` (facing the ray), enters: the first surface along `-nf` within `max_nm`,
    /// if it bounds `film` and meets the entry facet within [`FILM_TILT_NONE`]. The probe
    /// wraps around the tile's sides like a ray; it is geometry only (no lane, no field), so
    /// one probe serves every wavelength the ray carries.
    pub(super) fn film_back(
        &self,
        r: &RayState,
        nf: DVec3,
        film: usize,
        max_nm: f64,
    ) -> Option<FilmBack> {
        let dir = -nf;
        let mut probe = *r;
        probe.dir = dir;
        probe.n_re = DVec3::ZERO;
        probe.n_im = DVec3::ZERO;
        probe.opl = C64::new(0.0, 0.0);
        // Started just inside, so the entry facet itself is not found again.
        probe.pos += dir * self.eps;
        let mut travelled = self.eps;
        for _ in 0..4 {
            let left = max_nm - travelled;
            if left <= 0.0 {
                return None;
            }
            let (t_side, axis, t_plane) = self.bounds(&probe);
            let t_side_ext = t_side + self.eps / probe.dir[axis].abs().max(1e-12);
            let (prim, surface) = self.surface(&probe, t_side_ext.min(t_plane).min(left));
            if let Some((t, n)) = surface {
                let itf = &self.sample.interfaces[self.owner[prim as usize] as usize];
                let (from, beyond, normal) = if dir.dot(n) < 0.0 {
                    (itf.front, itf.back, n)
                } else {
                    (itf.back, itf.front, -n)
                };
                if from != film {
                    return None;
                }
                let beta = normal.dot(nf).clamp(-1.0, 1.0).acos().to_degrees();
                let w = tilt_weight(beta);
                return (w > 0.0).then_some(FilmBack {
                    pos: probe.pos + dir * t,
                    off: probe.off,
                    depth_nm: travelled + t,
                    prim,
                    normal,
                    beyond,
                    tilt_weight: w,
                });
            }
            if t_plane <= t_side || !t_side.is_finite() || t_side >= left {
                return None;
            }
            probe.pos += dir * t_side;
            travelled += t_side;
            self.wrap(&mut probe, axis);
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The weights are 1 and 0 where the docs say, monotone between, and continuous: no
    /// step between neighbouring arguments 1e-4 of the ramp apart is larger than the
    /// raised cosine's largest slope allows (pi / 2 per ramp width).
    #[test]
    fn the_hand_off_weights_fall_continuously_from_one_to_zero() {
        assert_eq!(tilt_weight(0.0), 1.0);
        assert_eq!(tilt_weight(FILM_TILT_FULL), 1.0);
        assert_eq!(tilt_weight(FILM_TILT_NONE), 0.0);
        assert_eq!(tilt_weight(90.0), 0.0);
        assert!((tilt_weight(0.5 * (FILM_TILT_FULL + FILM_TILT_NONE)) - 0.5).abs() < 1e-12);
        assert_eq!(depth_weight(0.0, 500.0), 1.0);
        assert_eq!(depth_weight(250.0, 500.0), 1.0);
        assert_eq!(depth_weight(500.0, 500.0), 0.0);
        assert!((depth_weight(375.0, 500.0) - 0.5).abs() < 1e-12);
        let n = 10_000;
        let check = |f: &dyn Fn(f64) -> f64, a: f64, b: f64| {
            let h = (b - a) / n as f64;
            let mut last = f(a - h);
            for i in 0..=n + 1 {
                let x = a + h * i as f64;
                let w = f(x);
                assert!(w <= last, "not monotone at {x}: {w} after {last}");
                let bound = std::f64::consts::FRAC_PI_2 / n as f64 * (1.0 + 1e-9);
                assert!(last - w <= bound, "a step of {} at {x}", last - w);
                last = w;
            }
        };
        check(&tilt_weight, FILM_TILT_FULL, FILM_TILT_NONE);
        check(&|x| depth_weight(x, 1.0), 0.5, 1.0);
    }
}
