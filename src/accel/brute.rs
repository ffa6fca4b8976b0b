//! Brute-force closest hit over every triangle, in f64: the reference every acceleration
//! structure is tested against. O(triangles) per ray; for tests and checks only.

use glam::DVec3;

use super::{Hit, INVALID_PRIM, Ray, TriangleSoup};

/// Ray–triangle intersection in f64 with edges included: the one routine the brute-force
/// intersector and the local-film reference share.
///
/// Möller & Trumbore, "Fast, Minimum Storage Ray/Triangle Intersection", J. Graphics Tools
/// 2(1), 1997. Returns `(t, u, v)` with the hit point `(1-u-v) v0 + u v1 + v v2`.
pub fn intersect_triangle_f64(
    origin: DVec3,
    dir: DVec3,
    corners: [DVec3; 3],
) -> Option<(f64, f64, f64)> {
    intersect_triangle_f64_widened(origin, dir, corners, 0.0)
}

/// [`intersect_triangle_f64`] with the triangle widened by `edge` in barycentric
/// coordinates, so a ray through a shared edge or vertex of a mesh hits one of its
/// triangles whatever the rounding.
pub fn intersect_triangle_f64_widened(
    origin: DVec3,
    dir: DVec3,
    corners: [DVec3; 3],
    edge: f64,
) -> Option<(f64, f64, f64)> {
    let [v0, v1, v2] = corners;
    let e1 = v1 - v0;
    let e2 = v2 - v0;
    let p = dir.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv = 1.0 / det;
    let s = origin - v0;
    let u = s.dot(p) * inv;
    if !(-edge..=1.0 + edge).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = dir.dot(q) * inv;
    if v < -edge || u + v > 1.0 + edge {
        return None;
    }
    Some((e2.dot(q) * inv, u, v))
}

/// Every triangle the ray segment crosses, as `(prim, t)`, sorted by `t` then `prim`.
pub fn all_hits(soup: &TriangleSoup, ray: &Ray) -> Vec<(u32, f64)> {
    let o = DVec3::from(ray.origin.map(f64::from));
    let d = DVec3::from(ray.dir.map(f64::from));
    let (tmin, tmax) = (f64::from(ray.tmin), f64::from(ray.tmax));
    let mut hits: Vec<(u32, f64)> = (0..soup.triangles.len())
        .filter_map(|i| {
            let c = soup.corners(i).map(|v| DVec3::from(v.map(f64::from)));
            intersect_triangle_f64(o, d, c)
                .filter(|&(t, _, _)| t >= tmin && t <= tmax)
                .map(|(t, _, _)| (i as u32, t))
        })
        .collect();
    hits.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
    hits
}

/// The closest hit by testing every triangle (lowest index wins an exact tie).
pub fn closest_hit(soup: &TriangleSoup, ray: &Ray) -> Hit {
    let o = DVec3::from(ray.origin.map(f64::from));
    let d = DVec3::from(ray.dir.map(f64::from));
    let (tmin, tmax) = (f64::from(ray.tmin), f64::from(ray.tmax));
    let mut best: Option<(u32, f64, f64, f64)> = None;
    for i in 0..soup.triangles.len() {
        let c = soup.corners(i).map(|v| DVec3::from(v.map(f64::from)));
        if let Some((t, u, v)) = intersect_triangle_f64(o, d, c)
            && t >= tmin
            && t <= tmax
            && best.is_none_or(|b| t < b.1)
        {
            best = Some((i as u32, t, u, v));
        }
    }
    match best {
        None => Hit::MISS,
        Some((prim, t, u, v)) => {
            let c = soup
                .corners(prim as usize)
                .map(|v| DVec3::from(v.map(f64::from)));
            let n = (c[1] - c[0]).cross(c[2] - c[0]);
            let l = n.length();
            let n = if l > 0.0 { n / l } else { n };
            Hit {
                t: t as f32,
                prim,
                u: u as f32,
                v: v as f32,
                ng: n.as_vec3().to_array(),
            }
        }
    }
}

/// Whether `hit` is a miss.
pub fn is_miss(hit: &Hit) -> bool {
    hit.prim == INVALID_PRIM
}
