//! Every backend against a brute-force f64 loop over all triangles, and the backends
//! against each other. Ties on shared edges are recognised explicitly: a different
//! triangle is accepted only when the brute-force list of all hits shows it at the same
//! distance.

use goniospec::accel::{Accel, Backend, Hit, Intersector, Ray, TriangleSoup, brute};
use goniospec::rng::Rng;
use goniospec::sample::generate;

/// Random triangles scattered in a 10 x 10 x 10 box (no shared edges).
fn random_soup(seed: u64, n: usize) -> TriangleSoup {
    let mut r = Rng::new(seed, 0);
    let mut soup = TriangleSoup::default();
    for i in 0..n {
        let c = [r.range(0.0, 10.0), r.range(0.0, 10.0), r.range(0.0, 10.0)];
        for _ in 0..3 {
            soup.vertices.push([
                (c[0] + r.range(-1.5, 1.5)) as f32,
                (c[1] + r.range(-1.5, 1.5)) as f32,
                (c[2] + r.range(-1.5, 1.5)) as f32,
            ]);
        }
        let b = 3 * i as u32;
        soup.triangles.push([b, b + 1, b + 2]);
    }
    soup
}

/// A small periodic height field: many shared edges and vertices, where ties happen.
fn grid_soup(seed: u64, cells: usize) -> TriangleSoup {
    let tile = [1000.0, 1000.0];
    let h = generate::cosine_surface(seed, tile, 40.0, 8, 3);
    generate::height_field([cells, cells], tile, h).to_soup()
}

fn random_rays(seed: u64, n: usize, lo: [f32; 3], hi: [f32; 3]) -> Vec<Ray> {
    let mut r = Rng::new(seed, 1);
    (0..n)
        .map(|_| {
            let o = [0, 1, 2].map(|a| r.range(f64::from(lo[a]), f64::from(hi[a])) as f32);
            // Uniform direction on the sphere.
            let z = r.range(-1.0, 1.0);
            let phi = r.range(0.0, std::f64::consts::TAU);
            let s = (1.0 - z * z).sqrt();
            Ray::new(
                o,
                [(s * phi.cos()) as f32, (s * phi.sin()) as f32, z as f32],
            )
        })
        .collect()
}

/// Rays aimed from above exactly at mesh vertices and edge midpoints: each lands on a
/// shared edge or vertex, where several triangles tie.
fn edge_rays(soup: &TriangleSoup, n: usize, seed: u64) -> Vec<Ray> {
    let mut r = Rng::new(seed, 2);
    (0..n)
        .map(|_| {
            let t = soup.triangles[(r.uniform() * soup.triangles.len() as f64) as usize];
            let a = soup.vertices[t[0] as usize];
            let b = soup.vertices[t[1] as usize];
            let target = if r.uniform() < 0.5 {
                a
            } else {
                [0, 1, 2].map(|k| 0.5 * (a[k] + b[k]))
            };
            Ray::new([target[0], target[1], target[2] + 500.0], [0.0, 0.0, -1.0])
        })
        .collect()
}

/// Barycentric distance of the ray's crossing with `prim`'s plane from the triangle
/// (0 inside, > 0 outside), and the crossing's t, in f64.
fn crossing(soup: &TriangleSoup, ray: &Ray, prim: u32) -> (f64, f64) {
    let c = soup
        .corners(prim as usize)
        .map(|v| glam::DVec3::from(v.map(f64::from)));
    let o = glam::DVec3::from(ray.origin.map(f64::from));
    let d = glam::DVec3::from(ray.dir.map(f64::from));
    let (e1, e2) = (c[1] - c[0], c[2] - c[0]);
    let p = d.cross(e2);
    let det = e1.dot(p);
    let s = o - c[0];
    let u = s.dot(p) / det;
    let q = s.cross(e1);
    let v = d.dot(q) / det;
    let t = e2.dot(q) / det;
    let outside = (-u).max(-v).max(u + v - 1.0).max(0.0);
    (outside, t)
}

/// The smallest barycentric coordinate of the ray's crossing with `prim`'s plane.
fn min_barycentric(soup: &TriangleSoup, ray: &Ray, prim: u32) -> f64 {
    let c = soup
        .corners(prim as usize)
        .map(|v| glam::DVec3::from(v.map(f64::from)));
    let o = glam::DVec3::from(ray.origin.map(f64::from));
    let d = glam::DVec3::from(ray.dir.map(f64::from));
    match brute::intersect_triangle_f64(o, d, c) {
        Some((_, u, v)) => u.min(v).min(1.0 - u - v),
        None => f64::NEG_INFINITY,
    }
}

#[derive(Default, Debug)]
struct Tally {
    exact: usize,
    ties: usize,
    grazing: usize,
}

/// Compares one backend hit with brute force; panics with a dump on a real mismatch.
fn compare(soup: &TriangleSoup, ray: &Ray, got: &Hit, tally: &mut Tally, what: &str) {
    let want = brute::closest_hit(soup, ray);
    const EDGE_EPS: f64 = 1e-4; // f32 arithmetic near an edge: a sliver of barycentric slack
    if got.prim == want.prim {
        tally.exact += 1;
        if got.is_hit() {
            let scale = f64::from(want.t.abs().max(1.0));
            assert!(
                (f64::from(got.t) - f64::from(want.t)).abs() <= 1e-4 * scale,
                "{what}: t differs for {ray:?}: {got:?} vs brute {want:?}"
            );
            assert!(
                (got.u - want.u).abs() < 1e-3 && (got.v - want.v).abs() < 1e-3,
                "{what}: barycentrics differ for {ray:?}: {got:?} vs brute {want:?}"
            );
            let dn: f32 = (0..3)
                .map(|k| (got.ng[k] - want.ng[k]).powi(2))
                .sum::<f32>()
                .sqrt();
            assert!(
                dn < 1e-3,
                "{what}: normal differs for {ray:?}: {got:?} vs brute {want:?}"
            );
        }
        return;
    }
    // Different answers: accept only an explicit tie or a grazing edge case.
    let all = brute::all_hits(soup, ray);
    if got.is_hit() && want.is_hit() {
        let tie = all.iter().any(|&(p, t)| {
            p == got.prim
                && (t - f64::from(want.t)).abs() <= 1e-5 * f64::from(want.t.abs().max(1.0))
        });
        if tie {
            tally.ties += 1;
            return;
        }
    }
    // A hit brute force missed (or vice versa) must lie on a triangle edge within f32 slack.
    let edge_case = |h: &Hit| {
        let (out, _) = crossing(soup, ray, h.prim);
        out <= EDGE_EPS
    };
    let grazing = match (got.is_hit(), want.is_hit()) {
        (true, false) => edge_case(got),
        (false, true) => {
            // The backend missed a brute-force hit: allowed only within f32 slack of an
            // edge, measured from the inside as the smallest barycentric coordinate.
            let (out, _) = crossing(soup, ray, want.prim);
            out == 0.0 && min_barycentric(soup, ray, want.prim) <= EDGE_EPS
        }
        (true, true) => {
            // Different triangles at different t: both must be edge cases near each other.
            edge_case(got)
                && (f64::from(got.t) - f64::from(want.t)).abs()
                    <= 1e-3 * f64::from(want.t.abs().max(1.0))
        }
        (false, false) => unreachable!("both missed but prims differ"),
    };
    assert!(
        grazing,
        "{what}: real mismatch for {ray:?}\n  backend: {got:?}\n  brute:   {want:?}\n  all hits: {all:?}"
    );
    tally.grazing += 1;
}

fn check_backend_against_brute(backend: Backend) {
    let cases = [
        ("random soup", random_soup(7, 400), 3000usize),
        ("height field", grid_soup(3, 24), 3000usize),
    ];
    for (name, soup, n) in cases {
        let accel = Accel::build(backend, &soup).expect("build");
        assert_eq!(accel.backend(), backend);
        assert_eq!(accel.triangle_count(), soup.triangles.len());
        let (lo, hi) = if name == "random soup" {
            ([-2.0f32; 3], [12.0f32; 3])
        } else {
            ([0.0, 0.0, -200.0], [1000.0, 1000.0, 200.0])
        };
        let mut rays = random_rays(11, n, lo, hi);
        if name == "height field" {
            rays.extend(edge_rays(&soup, 1000, 5));
        }
        let mut tally = Tally::default();
        // Single queries.
        for ray in &rays {
            let got = accel.closest_hit(ray);
            compare(
                &soup,
                ray,
                &got,
                &mut tally,
                &format!("{backend} {name} single"),
            );
        }
        // The batch form must give exactly the single-query answers.
        let mut batch = vec![Hit::MISS; rays.len()];
        accel.closest_hits(&rays, &mut batch);
        for (ray, b) in rays.iter().zip(&batch) {
            assert_eq!(
                *b,
                accel.closest_hit(ray),
                "{backend} {name}: batch differs from single for {ray:?}"
            );
        }
        let hits = rays
            .iter()
            .filter(|r| brute::closest_hit(&soup, r).is_hit())
            .count();
        eprintln!(
            "{backend} {name}: {tally:?}, {hits} of {} rays hit",
            rays.len()
        );
        assert!(
            hits > rays.len() / 10,
            "{name}: too few rays hit anything for a meaningful test"
        );
        assert!(
            tally.grazing * 200 <= rays.len(),
            "{backend} {name}: {} grazing disagreements out of {} is more than f32 edge slack explains",
            tally.grazing,
            rays.len()
        );
        if name == "height field" {
            assert!(tally.ties + tally.exact > 0);
        }
    }
}

#[test]
fn obvhs_matches_brute_force() {
    check_backend_against_brute(Backend::Obvhs);
}

#[cfg(embree)]
#[test]
fn embree_matches_brute_force() {
    check_backend_against_brute(Backend::Embree);
}

#[cfg(embree)]
#[test]
fn embree_packets_match_single_rays() {
    let soup = grid_soup(9, 32);
    let Accel::Embree(scene) = Accel::build(Backend::Embree, &soup).unwrap() else {
        panic!("asked for embree");
    };
    let mut rays = random_rays(4, 1003, [0.0, 0.0, -200.0], [1000.0, 1000.0, 200.0]);
    rays[5].tmax = 10.0; // a short segment that stops before the surface
    let mut packet = vec![Hit::MISS; rays.len()];
    scene.closest_hits_packet8(&rays, &mut packet);
    let mut hit_count = 0;
    for (r, p) in rays.iter().zip(&packet) {
        let s = scene.closest_hit(r);
        assert_eq!(p.prim, s.prim, "packet and single disagree for {r:?}");
        if s.is_hit() {
            hit_count += 1;
            assert!((p.t - s.t).abs() <= 1e-5 * s.t.abs().max(1.0));
        }
    }
    assert!(hit_count > 100);
}

#[test]
fn empty_and_invalid_inputs_are_refused() {
    for backend in Backend::ALL.into_iter().filter(|b| b.is_available()) {
        let err = Accel::build(backend, &TriangleSoup::default())
            .err()
            .expect("empty refused");
        assert!(err.to_string().contains("no triangles"), "{err}");
        let bad = TriangleSoup {
            vertices: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            triangles: vec![[0, 1, 3]],
        };
        let err = Accel::build(backend, &bad)
            .err()
            .expect("out-of-range index refused");
        assert!(err.to_string().contains("indexes vertex"), "{err}");
        let nan = TriangleSoup {
            vertices: vec![[0.0; 3], [f32::NAN, 0.0, 0.0], [0.0, 1.0, 0.0]],
            triangles: vec![[0, 1, 2]],
        };
        let err = Accel::build(backend, &nan).err().expect("NaN refused");
        assert!(err.to_string().contains("non-finite"), "{err}");
    }
}

#[test]
fn rays_that_miss_everything_report_a_miss() {
    let soup = grid_soup(1, 8);
    for backend in Backend::ALL.into_iter().filter(|b| b.is_available()) {
        let accel = Accel::build(backend, &soup).unwrap();
        // Upward from above the surface, and parallel beside it.
        for ray in [
            Ray::new([500.0, 500.0, 1000.0], [0.0, 0.0, 1.0]),
            Ray::new([-100.0, 500.0, 0.0], [-1.0, 0.0, 0.0]),
        ] {
            assert!(!accel.closest_hit(&ray).is_hit(), "{backend}: {ray:?}");
            assert!(!brute::closest_hit(&soup, &ray).is_hit());
        }
        // Directions with negative-zero components (as -wi gives at phi = 0) still hit.
        let neg_zero = Ray::new([563.7, 488.1, 1000.0], [-0.34202, -0.0, -0.93969]);
        let h = accel.closest_hit(&neg_zero);
        assert!(h.is_hit(), "{backend}: -0.0 direction component");
        assert_eq!(
            h.prim,
            brute::closest_hit(&soup, &neg_zero).prim,
            "{backend}"
        );
        // Straight down hits, and a segment ending above the surface does not.
        let down = Ray::new([500.0, 500.0, 1000.0], [0.0, 0.0, -1.0]);
        let h = accel.closest_hit(&down);
        assert!(h.is_hit() && h.ng[2] > 0.9, "{backend}: {h:?}");
        let short = Ray {
            tmax: 100.0,
            ..down
        };
        assert!(!accel.closest_hit(&short).is_hit(), "{backend}");
    }
}

/// Embree and obvhs agree on at least 99.99 % of 100k rays over a 100k-triangle height
/// field.
#[cfg(embree)]
#[test]
fn embree_and_obvhs_agree_on_a_large_height_field() {
    use goniospec::accel::workload;
    let mesh = workload::default_surface(100_000, 42);
    let soup = mesh.to_soup();
    assert!(soup.triangles.len() >= 99_000);
    let rays = workload::random_rays(&mesh, 100_000, 43);
    let e = Accel::build(Backend::Embree, &soup).unwrap();
    let o = Accel::build(Backend::Obvhs, &soup).unwrap();
    let mut he = vec![Hit::MISS; rays.len()];
    let mut ho = vec![Hit::MISS; rays.len()];
    workload::trace_all(&e, &rays, &mut he);
    workload::trace_all(&o, &rays, &mut ho);
    let hits = he.iter().filter(|h| h.is_hit()).count();
    assert!(
        hits > 50_000,
        "only {hits} rays hit: the test would be vacuous"
    );
    let ag = workload::agreement(&he, &ho);
    let frac = ag.identical as f64 / ag.rays as f64;
    if frac < 0.9999 {
        for (i, (a, b)) in he
            .iter()
            .zip(&ho)
            .enumerate()
            .filter(|(_, (a, b))| a.prim != b.prim)
            .take(10)
        {
            eprintln!("ray {i} {:?}: embree {a:?} obvhs {b:?}", rays[i]);
        }
    }
    assert!(frac >= 0.9999, "agreement {frac} ({ag:?})");
}
