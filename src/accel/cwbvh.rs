//! The obvhs backend: a compressed wide BVH (CWBVH; Ylitie, Karras & Laine, "Efficient
//! Incoherent Ray Traversal on GPUs Through Compressed Wide BVHs", HPG 2017) built with
//! PLOC (Meister & Bittner 2018), traversed on the CPU in pure Rust.

use std::time::Duration;

use glam::Vec3A;
use obvhs::{
    BvhBuildParams, cwbvh::CwBvh, cwbvh::builder::build_cwbvh_from_tris, ray::RayHit,
    triangle::Triangle,
};

use super::{Hit, Intersector, Ray, TriangleSoup};

/// Version of the obvhs crate this build links (kept in step with Cargo.toml).
pub const OBVHS_VERSION: &str = "0.4.0";

/// A triangle stored in BVH leaf order, prepared for Möller–Trumbore.
#[derive(Clone, Copy)]
struct PreparedTri {
    v0: Vec3A,
    e1: Vec3A,
    e2: Vec3A,
}

/// An obvhs CWBVH over a triangle soup.
pub struct ObvhsScene {
    bvh: CwBvh,
    /// Triangles in BVH primitive order, so leaves read memory sequentially.
    tris: Vec<PreparedTri>,
    /// BVH primitive slot → original triangle index.
    prim_ids: Vec<u32>,
    triangle_count: usize,
}

impl ObvhsScene {
    /// Builds the BVH (PLOC, medium quality) over `soup`, which the caller has validated.
    pub fn build(soup: &TriangleSoup) -> ObvhsScene {
        let tris: Vec<Triangle> = (0..soup.triangles.len())
            .map(|i| {
                let [a, b, c] = soup.corners(i).map(Vec3A::from_array);
                Triangle {
                    v0: a,
                    v1: b,
                    v2: c,
                }
            })
            .collect();
        let mut core_time = Duration::ZERO;
        let bvh = build_cwbvh_from_tris(&tris, BvhBuildParams::medium_build(), &mut core_time);
        let prim_ids: Vec<u32> = bvh.primitive_indices.clone();
        let prepared = prim_ids
            .iter()
            .map(|&i| {
                let t = &tris[i as usize];
                PreparedTri {
                    v0: t.v0,
                    e1: t.v1 - t.v0,
                    e2: t.v2 - t.v0,
                }
            })
            .collect();
        ObvhsScene {
            bvh,
            tris: prepared,
            prim_ids,
            triangle_count: soup.triangles.len(),
        }
    }
}

/// Möller–Trumbore in f32 with edges included (J. Graphics Tools 2(1), 1997).
/// Returns `(t, u, v)`, `t = +inf` for a miss.
#[inline(always)]
fn intersect(tri: &PreparedTri, o: Vec3A, d: Vec3A, tmin: f32, tmax: f32) -> (f32, f32, f32) {
    const MISS: (f32, f32, f32) = (f32::INFINITY, 0.0, 0.0);
    let p = d.cross(tri.e2);
    let det = tri.e1.dot(p);
    if det == 0.0 {
        return MISS;
    }
    let inv = 1.0 / det;
    let s = o - tri.v0;
    let u = s.dot(p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return MISS;
    }
    let q = s.cross(tri.e1);
    let v = d.dot(q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return MISS;
    }
    let t = tri.e2.dot(q) * inv;
    if t >= tmin && t <= tmax {
        (t, u, v)
    } else {
        MISS
    }
}

impl Intersector for ObvhsScene {
    #[inline]
    fn closest_hit(&self, ray: &Ray) -> Hit {
        let o = Vec3A::from_array(ray.origin);
        // obvhs derives traversal octants from sign bits: a -0.0 component (e.g. the y of
        // a direction built as -wi with phi = 0) makes it miss everything. Adding +0.0
        // turns -0.0 into +0.0 and changes nothing else.
        let d = Vec3A::from_array(ray.dir.map(|c| c + 0.0));
        let oray = obvhs::ray::Ray::new(o, d, ray.tmin, ray.tmax);
        let mut rh = RayHit::none();
        let (mut bu, mut bv) = (0.0f32, 0.0f32);
        let hit = self.bvh.ray_traverse(oray, &mut rh, |r, slot| {
            let (t, u, v) = intersect(&self.tris[slot], o, d, r.tmin, r.tmax);
            // obvhs records the hit exactly when t < current tmax; keep u, v in step.
            if t < r.tmax {
                bu = u;
                bv = v;
            }
            t
        });
        if !hit {
            return Hit::MISS;
        }
        let slot = rh.primitive_id as usize;
        let tri = &self.tris[slot];
        let n = tri.e1.cross(tri.e2).normalize_or_zero();
        Hit {
            t: rh.t,
            prim: self.prim_ids[slot],
            u: bu,
            v: bv,
            ng: n.to_array(),
        }
    }

    fn triangle_count(&self) -> usize {
        self.triangle_count
    }
}
