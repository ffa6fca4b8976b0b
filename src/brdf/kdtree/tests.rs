use super::*;
use std::f64::consts::{FRAC_PI_2, PI};

#[test]
fn outward_rounding_brackets_the_value() {
    let mut x = 0.37f64;
    for k in 0..100_000 {
        x = (x * 7.13 + 0.31).fract() * TAU - if k % 3 == 0 { PI } else { 0.0 };
        for v in [x, -x, 0.0, 1e-300, -1e-300, PI, TAU] {
            let (lo, hi) = (f32_outward(v, true), f32_outward(v, false));
            assert!(f64::from(lo) <= v && v <= f64::from(hi), "{v}: {lo} {hi}");
            // At most one f32 step apart from the nearest.
            assert!(
                f64::from(hi) - f64::from(lo) <= 2.0 * f64::from(f32::EPSILON) * v.abs().max(1e-38)
            );
        }
    }
}

/// Random unit-vector pairs, from coincident and nearly so to antipodal.
fn pairs() -> impl Iterator<Item = (DVec3, DVec3)> {
    let mut r = crate::rng::Rng::new(5, 1);
    (0..200_000).map(move |i| {
        let a = from_spherical(r.range(0.0, PI), r.range(0.0, TAU));
        let sep = [0.0, 1e-9, 1e-6, 1e-3, 0.1, 1.0, 3.0, PI - 1e-6][i % 8] * r.uniform();
        let b = if i % 9 == 0 {
            a
        } else {
            let t = from_spherical(FRAC_PI_2, r.range(0.0, TAU));
            let t = (t - a * a.dot(t)).normalize();
            (a * sep.cos() + t * sep.sin()).normalize()
        };
        (a, b)
    })
}

#[test]
fn single_precision_chords_bracket_the_arc() {
    for (a, b) in pairs() {
        let exact = arc(a, b);
        let q = [a.x, a.y, a.z].map(|x| Vec4::splat(x as f32));
        let p = [b.x, b.y, b.z, b.x, b.y, b.z].map(|x| Vec4::splat(x as f32));
        let c = chords(&p, 0, &q).x;
        // Two chords summed, less the slack, stay below two arcs.
        assert!(
            f64::from(c + c) - F32_SLACK <= 2.0 * exact,
            "{a} {b}: {c} {exact}"
        );
        // The upper bound, with the slack the search adds, stays above.
        assert!(
            f64::from(arc_upper(c)) + F32_SLACK >= exact,
            "{a} {b}: {c} {exact}"
        );
    }
}

#[test]
fn box_bounds_never_exceed_the_distance_to_a_point_inside() {
    let pts: Vec<(DVec3, DVec3)> = pairs().take(4096).collect();
    let mut r = crate::rng::Rng::new(6, 1);
    for chunk in pts.chunks(16) {
        let box_of = |part: &[(DVec3, DVec3)]| -> Bounds {
            let v = |p: &(DVec3, DVec3)| [p.0.x, p.0.y, p.0.z, p.1.x, p.1.y, p.1.z];
            [
                std::array::from_fn(|d| {
                    f32_outward(
                        part.iter().map(|p| v(p)[d]).fold(f64::INFINITY, f64::min),
                        true,
                    )
                }),
                std::array::from_fn(|d| {
                    f32_outward(
                        part.iter()
                            .map(|p| v(p)[d])
                            .fold(f64::NEG_INFINITY, f64::max),
                        false,
                    )
                }),
            ]
        };
        let none = Child { at: 0, groups: 0 };
        let node = Node::new([box_of(&chunk[..8]), box_of(&chunk[8..])], [none; 2]);
        for _ in 0..16 {
            let (wi, wo) = (
                from_spherical(r.range(0.0, PI), r.range(0.0, TAU)),
                from_spherical(r.range(0.0, PI), r.range(0.0, TAU)),
            );
            let (fi, fo) = (wi.as_vec3(), wo.as_vec3());
            let q = [0, 1, 2].map(|c| Vec4::new(fi[c], fo[c], fi[c], fo[c]));
            let (b0, b1) = node.bounds_to(&q);
            for (j, p) in chunk.iter().enumerate() {
                let d = arc(wi, p.0) + arc(wo, p.1);
                assert!(if j < 8 { b0 } else { b1 } <= d, "{b0} {b1} {d}");
            }
        }
    }
}
