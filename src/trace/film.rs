//! Thin absorbing films handed to the transfer-matrix method (docs/physics.md, "Thin
//! absorbing films: the local film").
//!
//! Where a homogeneous wave enters an absorbing medium from a lossless one and the
//! medium's far face lies close behind the entry point, nearly parallel to it, the tracer
//! does not follow the film's internal series of partial waves: it takes the film's
//! coherent response, the transfer-matrix amplitudes of a flat film of the local thickness
//! (the tangent-plane or local-film model), and sends the transmitted wave on from the far
//! face. For parallel faces that is exact. For faces meeting at a small angle it is the
//! local-film model, which RCWA confirms on tilted gold films in TE (within 6.1e-3 up to 20
//! degrees) and in TM at 1 degree (within 3e-3 but for one transmittance, 5e-3 to 7e-3,
//! where the ray series were 2.2e-2 off); where a roof's period falls near or below the
//! wavelength its TM is 1e-2 to 6.5e-2 off, lateral structure that no local model
//! describes (and that the validity map warns about). The ray series of such a film are
//! inhomogeneous plane waves whose recombination no ray estimator gets right beyond a few
//! tenths of a degree (the roof of tests/tilted_absorbers.rs: 1.0e-2 off at 1 degree, like
//! bulk gold from a few degrees).
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
//!
//! The probe is cast only from faces that some face of the medium could face within
//! [`FILM_TILT_NONE`] ([`film_faces`]), and only as deep as the film is not yet opaque
//! ([`reach_nm`]): a metal substrate under gentle roughness is never probed.

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

/// The power a film must transmit for its far face to matter: 1e-12. Below it the film is
/// bulk (what its far face sends back is smaller still), and the light it would transmit
/// is far below the default power cutoff (`TraceLimits::CUTOFF`).
const FAR_FACE_POWER: f64 = 1e-12;

/// How deep the probe looks, nm, for a film of complex index `n` at vacuum wavelength
/// `lambda_nm`: one wavelength (where [`depth_weight`] reaches 0), or less where the film
/// is opaque sooner. Behind a facet at any angle the wave's normal attenuation is at least
/// the medium's `Im(n)` (`Im q = Re(n) Im(n) / Re(q)` grows as the tangential index grows),
/// so a film thicker than `ln(1 / FAR_FACE_POWER) lambda / (4 pi Im n)` transmits less than
/// `FAR_FACE_POWER` (gold: 490 nm at 550 nm, 450 at 650; aluminium 207 nm at 450). The
/// probe's cost is a ray cast per entry into an absorber; the shorter reach keeps it small
/// on bulk metals.
pub(super) fn reach_nm(n: C64, lambda_nm: f64) -> f64 {
    let opaque = (1.0 / FAR_FACE_POWER).ln() * lambda_nm / (4.0 * std::f64::consts::PI * n.im);
    lambda_nm.min(opaque)
}

/// Per face: whether a probe from it into the medium behind could find a far face, that
/// is, whether some face bounding that medium could face it within [`FILM_TILT_NONE`] (a
/// film, a flake, a fin). Bit 0 is for light entering the face's back medium (through its
/// front side), bit 1 for light entering its front medium. Where no face could (a metal
/// substrate under a height field's gentle facets, V-grooves whose walls meet at 60
/// degrees), the probe is never cast: it would find nothing, and it costs a ray cast per
/// entry into the absorber.
///
/// `faces` holds each face's unit normal, pointing into its front medium, and its front
/// and back media. Each face's outward normal (out of a medium) goes to a cell of a
/// 5-degree latitude-longitude grid; two faces face each other within `beta` when one's
/// outward normal is within `beta` of the other's reversed. Taken between the cells'
/// centres, with the cells' angular radius (at most 3.6 degrees) added twice, the test can
/// only err towards casting.
pub(super) fn film_faces(media: usize, faces: &[(DVec3, usize, usize)]) -> Vec<u8> {
    const BANDS: usize = 36;
    const SECTORS: usize = 72;
    const CELLS: usize = BANDS * SECTORS;
    let cell = |o: DVec3| -> usize {
        let theta = o.z.clamp(-1.0, 1.0).acos();
        let phi = o.y.atan2(o.x) + std::f64::consts::PI;
        let i = ((theta / std::f64::consts::PI * BANDS as f64) as usize).min(BANDS - 1);
        let j = ((phi / std::f64::consts::TAU * SECTORS as f64) as usize).min(SECTORS - 1);
        i * SECTORS + j
    };
    let centre = |c: usize| -> DVec3 {
        let (i, j) = (c / SECTORS, c % SECTORS);
        let theta = (i as f64 + 0.5) / BANDS as f64 * std::f64::consts::PI;
        let phi = (j as f64 + 0.5) / SECTORS as f64 * std::f64::consts::TAU - std::f64::consts::PI;
        DVec3::new(
            theta.sin() * phi.cos(),
            theta.sin() * phi.sin(),
            theta.cos(),
        )
    };
    // Per medium, the cells of its faces' outward normals.
    let mut occupied = vec![vec![false; CELLS]; media];
    for &(n, front, back) in faces {
        occupied[back][cell(n)] = true;
        occupied[front][cell(-n)] = true;
    }
    // Per medium and cell: whether a face of the medium could face one in that cell.
    let limit = (FILM_TILT_NONE + 2.0 * 3.6).to_radians().cos();
    let facing: Vec<Vec<bool>> = occupied
        .iter()
        .map(|cells| {
            let dirs: Vec<DVec3> = (0..CELLS).filter(|&c| cells[c]).map(centre).collect();
            (0..CELLS)
                .map(|c| cells[c] && dirs.iter().any(|&b| centre(c).dot(-b) >= limit))
                .collect()
        })
        .collect();
    faces
        .iter()
        .map(|&(n, front, back)| {
            u8::from(facing[back][cell(n)]) | u8::from(facing[front][cell(-n)]) << 1
        })
        .collect()
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

    /// Media 0 (air), 1 (gold), 2 (glass). A film's two faces face each other; the walls of
    /// 60-degree V-grooves (60 degrees from the vertical either way) and a height field's
    /// facets up to 60 degrees steep do not, and neither does a ridge whose faces are 50
    /// degrees from facing each other (beyond FILM_TILT_NONE and the grid's margin). Among
    /// a rough surface's facets, only steep ones that face each other are probed.
    #[test]
    fn only_faces_that_could_face_another_are_probed() {
        let tilted = |deg: f64, az: f64| {
            let (t, a) = (deg.to_radians(), az.to_radians());
            DVec3::new(t.sin() * a.cos(), t.sin() * a.sin(), t.cos())
        };
        // A gold film on glass, its back face tilted by 5 degrees: light entering the gold
        // through either face, and nothing else.
        let film = film_faces(3, &[(DVec3::Z, 0, 1), (tilted(5.0, 30.0), 1, 2)]);
        assert_eq!(film, [0b01, 0b10]);
        // Gold V-grooves and a rough gold height field: every face has gold behind it.
        let grooves = film_faces(3, &[(tilted(60.0, 0.0), 0, 1), (tilted(60.0, 180.0), 0, 1)]);
        assert_eq!(grooves, [0, 0]);
        let gentle: Vec<_> = (0..360)
            .step_by(7)
            .flat_map(|az| [0.0, 20.0, 40.0, 60.0].map(|t| (tilted(t, az as f64), 0, 1)))
            .collect();
        assert!(film_faces(3, &gentle).iter().all(|&f| f == 0));
        // A gold ridge whose faces' outward normals lean `t` from the vertical either way
        // face each other within `180 - 2 t` degrees: at 65 (50 from facing) it is not
        // probed, at 77.5 (25 from facing) it is, from either side (the air between two
        // such ridges absorbs nothing and is never probed).
        let ridge = |t: f64| film_faces(2, &[(tilted(t, 0.0), 0, 1), (tilted(t, 180.0), 0, 1)]);
        assert_eq!(ridge(65.0), [0, 0]);
        assert_eq!(ridge(77.5), [0b11, 0b11]);
        // Facets up to 40 degrees steep with two 80 degree ones facing each other added:
        // only the steep ones (a 60 degree facet would face an 80 degree one within 40
        // degrees, and be probed within the grid's margin).
        let mut rough: Vec<_> = gentle
            .iter()
            .copied()
            .filter(|&(n, _, _)| n.z > 0.7)
            .collect();
        let m = rough.len();
        rough.extend([(tilted(80.0, 0.0), 0, 1), (tilted(80.0, 180.0), 0, 1)]);
        let flags = film_faces(3, &rough);
        assert!(flags[..m].iter().all(|&f| f == 0));
        assert_eq!(flags[m..], [0b11, 0b11]);
    }
}
