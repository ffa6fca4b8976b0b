//! The local-film reference for gently curved or wedged films: the reflectance of a film
//! of two sheet interfaces, computed as if every point of the top surface belonged to the
//! flat film tangent to it.
//!
//! For entry points spread uniformly over the tile (uniform in the plane perpendicular to
//! the incident beam, so each carries the same flux), the incident ray is intersected with
//! the top interface; the local film has that triangle's normal, the distance from the hit
//! point to the bottom interface along the inward normal as its thickness (nm), and the
//! local angle of incidence. Its reflectance is the transfer-matrix method's (Byrnes 2016,
//! [`super::tmm`]) averaged over the wavelength bin, and the reference is the mean over
//! entry points. This is the geometric-optics (tangent-plane) approximation: exact for a
//! flat film, accurate to first order in the slope for gentle curvature and small wedge
//! angles, and blind to shadowing, to inter-reflection between facets and to the lateral
//! walk-off of the partial waves. It shares no code with the tracer or the estimator.

use super::ReferenceError;
use crate::optics::C64;
use crate::optics::tmm::{self, StackIndices};
use crate::sample::Sample;
use glam::DVec3;

/// Reflectance of each wavelength bin (`edges`, nm) at incidence `theta_i_deg` (azimuth
/// 0) from `entries x entries` entry points. Errors when the sample is not a film of two
/// sheets (top: ambient over film; bottom: film over substrate) or a ray misses.
pub fn reflectance(
    sample: &Sample,
    theta_i_deg: f64,
    edges: &[f64],
    entries: usize,
) -> Result<Vec<f64>, ReferenceError> {
    let film = Film::of(sample)?;
    let theta = theta_i_deg.to_radians();
    let d = DVec3::new(theta.sin(), 0.0, -theta.cos());
    let [lx, ly] = sample.tile_nm;
    let index = |m: usize, l: f64| -> Result<C64, String> {
        let (n, k) = sample.media[m]
            .model
            .eval(l)
            .map_err(|e| format!("medium '{}': {e}", sample.media[m].name))?;
        Ok(C64::new(n, k))
    };
    for &l in [edges[0], edges[edges.len() - 1]].iter() {
        for m in [film.ambient, film.film, film.substrate] {
            index(m, l)?;
        }
    }
    let mut sum = vec![0.0; edges.len() - 1];
    for i in 0..entries {
        for j in 0..entries {
            let x = (i as f64 + 0.5) / entries as f64 * lx;
            let y = (j as f64 + 0.5) / entries as f64 * ly;
            // Entry points uniform on a plane above the film: uniform over the periodic
            // tile wherever the ray lands.
            let o = DVec3::new(x, y, film.z_max + 1.0);
            let (t, n) = nearest(&film.top, sample.tile_nm, o, d).ok_or_else(|| {
                format!("local-film reference: the ray entering at ({x:.0}, {y:.0}) nm misses the top surface")
            })?;
            let p = o + d * t;
            let inward = -n;
            let (thick, _) = nearest(&film.bottom, sample.tile_nm, p, inward).ok_or_else(|| {
                format!(
                    "local-film reference: no bottom surface below ({:.0}, {:.0}, {:.0}) nm",
                    p.x, p.y, p.z
                )
            })?;
            let cos_local = -d.dot(n);
            if cos_local <= 0.0 {
                // The top facet faces away from the beam: shadowed in this approximation;
                // it reflects nothing here (never for the gentle films this is meant for).
                continue;
            }
            let th = cos_local.min(1.0).acos();
            for (b, w) in edges.windows(2).enumerate() {
                let stack_at = |l: f64| StackIndices {
                    n: vec![
                        index(film.ambient, l).expect("range checked"),
                        index(film.film, l).expect("range checked"),
                        index(film.substrate, l).expect("range checked"),
                    ],
                    d_nm: vec![thick],
                };
                sum[b] += tmm::solve_band(stack_at, w[0], w[1], th).r();
            }
        }
    }
    let n = (entries * entries) as f64;
    Ok(sum.into_iter().map(|s| s / n).collect())
}

/// The two sheets of a film, as triangles (nm) with up-facing normals.
struct Film {
    top: Vec<[DVec3; 3]>,
    bottom: Vec<[DVec3; 3]>,
    ambient: usize,
    film: usize,
    substrate: usize,
    z_max: f64,
}

impl Film {
    fn of(sample: &Sample) -> Result<Film, ReferenceError> {
        let err = || {
            format!(
                "{}: the local-film reference needs a film of exactly two sheet interfaces (ambient over film over substrate)",
                sample.path.display()
            )
        };
        if sample.interfaces.len() != 2 || sample.interfaces.iter().any(|i| i.closed) {
            return Err(ReferenceError::from(err()));
        }
        let mean_z = |k: usize| {
            let m = &sample.interfaces[k].mesh;
            m.positions_nm.iter().map(|p| p.z).sum::<f64>() / m.positions_nm.len().max(1) as f64
        };
        let (t, b) = if mean_z(0) >= mean_z(1) {
            (0, 1)
        } else {
            (1, 0)
        };
        let (top, bottom) = (&sample.interfaces[t], &sample.interfaces[b]);
        // Normals up: front above. The film lies between top's back and bottom's front.
        if top.back != bottom.front {
            return Err(ReferenceError::from(err()));
        }
        let tris = |m: &crate::sample::mesh::Mesh| -> Vec<[DVec3; 3]> {
            m.triangles
                .iter()
                .map(|t| t.map(|k| m.positions_nm[k as usize]))
                .collect()
        };
        let z_max = sample
            .interfaces
            .iter()
            .flat_map(|i| i.mesh.positions_nm.iter().map(|p| p.z))
            .fold(f64::MIN, f64::max);
        Ok(Film {
            top: tris(&top.mesh),
            bottom: tris(&bottom.mesh),
            ambient: top.front,
            film: top.back,
            substrate: bottom.back,
            z_max,
        })
    }
}

/// Nearest hit of the ray `o + t d` (t > 1e-9 nm) with the triangles repeated over the
/// 3 x 3 neighbouring tiles: `(t, unit normal of the hit triangle, oriented up)`
/// (Möller–Trumbore, [`crate::accel::brute::intersect_triangle_f64_widened`]).
fn nearest(tris: &[[DVec3; 3]], tile: [f64; 2], o: DVec3, d: DVec3) -> Option<(f64, DVec3)> {
    let mut best: Option<(f64, DVec3)> = None;
    for ix in -1..=1 {
        for iy in -1..=1 {
            let shift = DVec3::new(f64::from(ix) * tile[0], f64::from(iy) * tile[1], 0.0);
            let o = o - shift;
            for tri in tris {
                let Some((t, _, _)) =
                    crate::accel::brute::intersect_triangle_f64_widened(o, d, *tri, 1e-12)
                else {
                    continue;
                };
                if t > 1e-9 && best.is_none_or(|b| t < b.0) {
                    let n = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
                    let s = if n.z < 0.0 { -1.0 } else { 1.0 };
                    best = Some((t, n * s / n.length()));
                }
            }
        }
    }
    best
}
