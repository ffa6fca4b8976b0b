//! BRDF representations: exact k-nearest search against brute force, flux conservation,
//! agreement between representations, the hemispherical integral against the simulated
//! reflectance, reciprocity, and damaged files.

mod common;

use std::f64::consts::{FRAC_PI_2, PI, TAU};
use std::path::Path;

use common::*;
use goniospec::accumulate::Buckets;
use goniospec::brdf::kdtree::{KdTree, KdTreeBrdf};
use goniospec::brdf::subdivided::SubdividedBrdf;
use goniospec::brdf::table::TableBrdf;
use goniospec::brdf::{Brdf, BucketData, Representation, file};
use goniospec::geom::from_spherical;
use goniospec::rng::Rng;
use goniospec::simulate::Wavelengths;
use rayon::prelude::*;

/// A random direction angle pair with poles, the azimuth seam and grazing angles over-
/// represented.
fn special_angles(r: &mut Rng) -> (f64, f64) {
    let t = match (r.uniform() * 10.0) as u32 {
        0 => 0.0,
        1 => FRAC_PI_2,
        2 => FRAC_PI_2 - 1e-6 * r.uniform(),
        _ => r.range(0.0, FRAC_PI_2),
    };
    let p = match (r.uniform() * 10.0) as u32 {
        0 => 0.0,
        1 => TAU - 1e-9 * r.uniform(),
        2 => 1e-9 * r.uniform(),
        3 => PI,
        _ => r.range(0.0, TAU),
    };
    (t, p)
}

#[test]
fn kdtree_nearest_neighbours_equal_brute_force() {
    let mut r = Rng::new(17, 0);
    let mut pts: Vec<[f64; 4]> = (0..100_000)
        .map(|_| {
            let (a, b) = special_angles(&mut r);
            let (c, d) = special_angles(&mut r);
            [a, b, c, d]
        })
        .collect();
    // Exact duplicates: ties broken by index in both searches.
    for i in 0..500 {
        pts[99_000 + i] = pts[i];
    }
    let tree = KdTree::build(&pts);
    tree.validate().unwrap();
    // 4,000 queries, 500 at each k: brute force costs 1e5 arcs a query.
    let queries: Vec<(glam::DVec3, glam::DVec3)> = (0..4_000)
        .map(|_| {
            let (a, b) = special_angles(&mut r);
            let (c, d) = special_angles(&mut r);
            (from_spherical(a, b), from_spherical(c, d))
        })
        .collect();
    let mismatches: Vec<String> = queries
        .par_iter()
        .enumerate()
        .filter_map(|(i, &(wi, wo))| {
            let k = 1 + i % 8;
            let mut got = Vec::new();
            tree.nearest(wi, wo, k, &mut got);
            let want = tree.nearest_brute(wi, wo, k);
            (got != want).then(|| {
                format!("query {i} {wi:?} {wo:?} k {k}:\n  tree  {got:?}\n  brute {want:?}")
            })
        })
        .collect();
    assert!(
        mismatches.is_empty(),
        "{} mismatches, first: {}",
        mismatches.len(),
        mismatches[0]
    );
}

/// Bucket centres on a grid, as `build` makes them for an isotropic sample (`phi_i = 0`),
/// are full of exact ties: queries at grid points, half-way between them and at random,
/// with k from 1 to 8, must still equal brute force (ties broken by index).
#[test]
fn kdtree_on_a_bucket_grid_equals_brute_force() {
    let mut pts = Vec::new();
    for i in 0..12 {
        let ti = (80.0 * f64::from(i) / 11.0).to_radians();
        for t in 0..30 {
            for p in 0..48 {
                let to = (f64::from(t) + 0.5) * 3f64.to_radians();
                pts.push([ti, 0.0, to, (f64::from(p) + 0.5) * TAU / 48.0]);
            }
        }
    }
    // The reciprocal entries, as `build --reciprocal` adds them.
    let n = pts.len();
    for j in 0..n {
        let [ti, _, to, po] = pts[j];
        pts.push([to, 0.0, ti, (-po).rem_euclid(TAU)]);
    }
    let tree = KdTree::build(&pts);
    tree.validate().unwrap();
    let mut r = Rng::new(23, 0);
    let queries: Vec<(glam::DVec3, glam::DVec3)> = (0..2_400)
        .map(|i| {
            let c = pts[(r.uniform() * pts.len() as f64) as usize];
            match i % 3 {
                0 => (from_spherical(c[0], c[1]), from_spherical(c[2], c[3])),
                1 => (
                    from_spherical(c[0] + 4f64.to_radians(), 0.0),
                    from_spherical(c[2] + 1.5f64.to_radians(), c[3] + PI / 48.0),
                ),
                _ => (
                    from_spherical(r.range(0.0, FRAC_PI_2), 0.0),
                    from_spherical(r.range(0.0, FRAC_PI_2), r.range(0.0, TAU)),
                ),
            }
        })
        .collect();
    let mismatches = queries
        .par_iter()
        .enumerate()
        .filter(|&(i, &(wi, wo))| {
            let k = 1 + i % 8;
            let mut got = Vec::new();
            tree.nearest(wi, wo, k, &mut got);
            got != tree.nearest_brute(wi, wo, k)
        })
        .count();
    assert_eq!(
        mismatches,
        0,
        "{mismatches} of {} queries differ",
        queries.len()
    );
}

/// A rough dielectric simulated at six incident angles (shared by the tests below).
fn rough_data(buckets: Buckets) -> (BucketData, goniospec::accumulate::file::Accumulator) {
    let s = goniospec::sample::load(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes/rough-glass.toml"),
        Default::default(),
    )
    .unwrap();
    let mut cfg = config(
        &[0.0, 15.0, 30.0, 45.0, 60.0, 75.0],
        Wavelengths::Bins(vec![450.0, 550.0, 650.0]),
        20_000,
    );
    cfg.buckets = buckets;
    let acc = run(&s, &cfg);
    (BucketData::from_accumulator(&acc), acc)
}

#[test]
fn subdivided_hemisphere_conserves_flux() {
    let (data, _) = rough_data(Buckets {
        theta_bins: 30,
        phi_bins: 24,
    });
    let sub = SubdividedBrdf::build(&data, 0.05);
    let nl = data.lambda_nm.len();
    for i in 0..data.theta_i_rad.len() {
        let leaves: Vec<usize> = sub.leaves(i).collect();
        assert!(
            leaves.len() > 4 && leaves.len() < 30 * 24,
            "{} leaves",
            leaves.len()
        );
        for j in 0..nl {
            let total: f64 = data.samples[i].iter().map(|s| s.flux[j]).sum();
            let in_leaves: f64 = leaves.iter().map(|&k| sub.flux[i][k * nl + j]).sum();
            assert!(
                (total - in_leaves).abs() <= 1e-12 * total.abs().max(1e-12),
                "{total} vs {in_leaves}"
            );
            let om: f64 = leaves.iter().map(|&k| sub.cells[i][k].omega).sum();
            assert!(
                (om - PI).abs() < 1e-9,
                "leaves cover the hemisphere's projected solid angle: {om}"
            );
        }
    }
}

/// `integral f_r cos(theta_o) dw_o` over the outgoing hemisphere, midpoint rule.
fn hemispherical(b: &dyn Brdf, wi: glam::DVec3, nl: usize) -> Vec<f64> {
    let (nt, np) = (180, 144);
    let mut acc = vec![0.0; nl];
    let mut v = vec![0.0; nl];
    for t in 0..nt {
        let th = (t as f64 + 0.5) * FRAC_PI_2 / nt as f64;
        let w = th.cos() * th.sin() * (FRAC_PI_2 / nt as f64) * (TAU / np as f64);
        for p in 0..np {
            let ph = (p as f64 + 0.5) * TAU / np as f64;
            b.eval(wi, from_spherical(th, ph), &mut v);
            for (a, x) in acc.iter_mut().zip(&v) {
                *a += w * x;
            }
        }
    }
    acc
}

#[test]
fn representations_agree_and_integrate_to_the_simulated_reflectance() {
    let (data, acc) = rough_data(Buckets {
        theta_bins: 45,
        phi_bins: 36,
    });
    let nl = data.lambda_nm.len();
    let reps: Vec<(&str, Box<dyn Brdf>)> = vec![
        ("kdtree", Box::new(KdTreeBrdf::build(&data, 4, true, false))),
        ("subdivided", Box::new(SubdividedBrdf::build(&data, 0.05))),
        ("table", Box::new(TableBrdf::build(&data))),
    ];
    // The hemispherical integral reproduces `goniospec reflectance` within 1 %.
    for (i, &th) in [0.0f64, 15.0, 30.0, 45.0, 60.0, 75.0].iter().enumerate() {
        let wi = from_spherical(th.to_radians(), 0.0);
        for (name, b) in &reps {
            let h = hemispherical(b.as_ref(), wi, nl);
            for (j, hj) in h.iter().enumerate() {
                let (r, _) = totals(&acc, i, j);
                assert!(
                    (hj / r - 1.0).abs() < 0.01,
                    "{name}, theta_i {th}, bin {j}: integral {hj} vs R {r}"
                );
            }
        }
    }
    // Pairwise agreement where the lobe carries the reflectance, at the simulated incident
    // angles up to 60 deg and outgoing angles up to 65 deg (grazing peaks are steeper than
    // any of the three resolves): within 3x the relative error of the buckets the table
    // interpolates between (the largest of its four) plus 10 % for interpolation, in 95 %
    // of the queries. The buckets' own errors, not the BRDF's median: the first polar band's
    // buckets are small (2 x 10 deg at the pole) and hold 0.55 relative error where the
    // median bucket holds 0.19, and a third of the queries at normal incidence land there.
    let (tb, pb) = (45usize, 36usize);
    let stated = |i: usize, to: f64, phi: f64| {
        let xt = (to / (FRAC_PI_2 / tb as f64) - 0.5).clamp(0.0, (tb - 1) as f64);
        let xp = (phi.rem_euclid(TAU) / (TAU / pb as f64) - 0.5).rem_euclid(pb as f64);
        let (t0, p0) = (xt.floor() as usize, xp.floor() as usize % pb);
        let worst = [t0, (t0 + 1).min(tb - 1)]
            .iter()
            .flat_map(|&t| [p0, (p0 + 1) % pb].map(|p| t * pb + p))
            .map(|k| {
                data.samples[i]
                    .get(k)
                    .and_then(|s| s.rel_stderr)
                    .unwrap_or(0.0)
            })
            .fold(0.0, f64::max);
        3.0 * worst + 0.10
    };
    let mut rng = Rng::new(5, 5);
    let mut v = vec![vec![0.0; nl]; 3];
    let (mut n, mut bad) = (0, 0);
    for q in 0..2000 {
        let ti = [0.0f64, 15.0, 30.0, 45.0, 60.0][q % 5].to_radians();
        let pi = rng.range(0.0, TAU);
        let wi = from_spherical(ti, pi);
        let spec = [-wi[0], -wi[1], wi[2]];
        // Outgoing directions near the specular lobe (the sample's slopes are ~8 deg).
        let to = (spec[2].acos() + rng.range(-0.15, 0.15)).clamp(0.0, 65f64.to_radians());
        let po = spec[1].atan2(spec[0]) + rng.range(-0.3, 0.3);
        let wo = from_spherical(to, po);
        for (k, (_, b)) in reps.iter().enumerate() {
            b.eval(wi, wo, &mut v[k]);
        }
        let m = v[2][0];
        if m <= 0.0 {
            continue;
        }
        n += 1;
        // The simulated directions are in the same order as the table's (ascending), and
        // the query's relative azimuth as the table takes it (the simulation's phi_i is 0).
        let (to_q, po_q) = goniospec::geom::angles(wo);
        let stated = stated(q % 5, to_q, po_q - pi);
        if (v[0][0] / m - 1.0).abs() > stated || (v[1][0] / m - 1.0).abs() > stated {
            bad += 1;
            if bad < 5 {
                eprintln!(
                    "wi {ti:.3} wo {to:.3} {po:.3}: kd {:.4e} sub {:.4e} table {:.4e}",
                    v[0][0], v[1][0], m
                );
            }
        }
    }
    eprintln!("{bad} of {n} lobe queries disagree by more than their buckets' errors allow");
    assert!(
        n > 1000 && bad * 20 <= n,
        "{bad} of {n} queries disagree beyond their buckets' errors"
    );
}

/// At theta_o = 0 every azimuth is one direction, so each representation gives one value
/// there whatever phi_o says (issue 71: the foil's table gave 32.9 or 60.7 1/sr by phi_o,
/// through the sign of a zero in the azimuth). The table's pole is the mean of its first
/// ring (the values at the ring's bucket centres, read through `eval`), and it is
/// continuous: a direction 1e-7 rad off the pole differs from it by at most the blend
/// weight `2 theta_o / dtheta` (6e-6) times the ring's spread.
#[test]
fn the_pole_is_one_direction_in_every_representation() {
    let (data, _) = rough_data(Buckets {
        theta_bins: 45,
        phi_bins: 36,
    });
    let nl = data.lambda_nm.len();
    let table = TableBrdf::build(&data);
    let reps: Vec<(&str, Box<dyn Brdf>)> = vec![
        ("kdtree", Box::new(KdTreeBrdf::build(&data, 4, true, false))),
        ("subdivided", Box::new(SubdividedBrdf::build(&data, 0.05))),
        ("table", Box::new(TableBrdf::build(&data))),
    ];
    let mut v = vec![0.0; nl];
    for th in [15.0f64, 30.0, 45.0] {
        let wi = from_spherical(th.to_radians(), 0.0);
        for (name, b) in &reps {
            let mut pole = vec![0.0; nl];
            b.eval(wi, from_spherical(0.0, 0.0), &mut pole);
            // (The k-d tree's nearest samples to the pole hold nothing at 15-45 deg.)
            assert!(*name == "kdtree" || pole[0] > 0.0, "{name}: {pole:?}");
            for deg in (0..360).step_by(15) {
                b.eval(wi, from_spherical(0.0, f64::from(deg).to_radians()), &mut v);
                assert_eq!(v, pole, "{name}, theta_i {th}: phi_o {deg} deg");
            }
        }
        // The table's pole against its first ring, and off the pole by 1e-7 rad.
        let mut pole = vec![0.0; nl];
        table.eval(wi, glam::DVec3::Z, &mut pole);
        let (dt, dp) = (FRAC_PI_2 / 45.0, TAU / 36.0);
        let mut ring = vec![0.0; nl];
        let mut spread = vec![(f64::INFINITY, 0.0f64); nl];
        for p in 0..36 {
            table.eval(wi, from_spherical(0.5 * dt, (p as f64 + 0.5) * dp), &mut v);
            for ((r, s), x) in ring.iter_mut().zip(spread.iter_mut()).zip(&v) {
                *r += x / 36.0;
                *s = (s.0.min(*x), s.1.max(*x));
            }
        }
        // Off the pole by 1e-7 rad the value is the pole's blended with the ring's by the
        // weight 2 theta_o / dt: it differs by at most that times the ring's spread.
        let blend = 2.0 * 1e-7 / dt;
        for deg in (0..360).step_by(30) {
            table.eval(
                wi,
                from_spherical(1e-7, f64::from(deg).to_radians()),
                &mut v,
            );
            for j in 0..nl {
                assert!(
                    (pole[j] - ring[j]).abs() <= 1e-12 * ring[j],
                    "theta_i {th}, bin {j}: pole {} against the ring's mean {}",
                    pole[j],
                    ring[j]
                );
                assert!(
                    (v[j] - pole[j]).abs() <= blend * (spread[j].1 - spread[j].0) + 1e-12,
                    "theta_i {th}, bin {j}, phi_o {deg}: {} beside the pole's {}",
                    v[j],
                    pole[j]
                );
            }
        }
    }
}

#[test]
fn reciprocal_kdtree_is_symmetric() {
    let (data, _) = rough_data(Buckets {
        theta_bins: 18,
        phi_bins: 12,
    });
    let b = KdTreeBrdf::build(&data, 6, true, true);
    let plain = KdTreeBrdf::build(&data, 6, true, false);
    // The simulated data are reciprocal within their noise: the reciprocal blend stays
    // close to the plain one in the lobe.
    let (mut p, mut q) = (vec![0.0; 2], vec![0.0; 2]);
    for th in [15.0f64, 30.0, 45.0] {
        let wi = from_spherical(th.to_radians(), 0.0);
        let wo = from_spherical((th + 5.0).to_radians(), PI);
        b.eval(wi, wo, &mut p);
        plain.eval(wi, wo, &mut q);
        assert!(
            (p[0] / q[0] - 1.0).abs() < 0.25,
            "theta {th}: reciprocal {p:?} vs plain {q:?}"
        );
    }
    let mut rng = Rng::new(9, 9);
    let (mut x, mut y) = (vec![0.0; 2], vec![0.0; 2]);
    for _ in 0..500 {
        let wi = from_spherical(rng.range(0.0, 1.3), rng.range(0.0, TAU));
        let wo = from_spherical(rng.range(0.0, 1.3), rng.range(0.0, TAU));
        b.eval(wi, wo, &mut x);
        b.eval(wo, wi, &mut y);
        for j in 0..2 {
            assert!(
                (x[j] - y[j]).abs() <= 1e-9 * x[j].abs().max(1e-12),
                "{x:?} vs {y:?}"
            );
        }
    }
}

#[test]
fn gsb_files_round_trip_and_refuse_damage() {
    let (data, _) = rough_data(Buckets {
        theta_bins: 18,
        phi_bins: 12,
    });
    let reps = vec![
        Representation::KdTree(KdTreeBrdf::build(&data, 4, true, false)),
        Representation::Subdivided(SubdividedBrdf::build(&data, 0.05)),
        Representation::Table(TableBrdf::build(&data)),
    ];
    let d = scratch("gsb");
    for r in &reps {
        let p = d.join(format!("{}.gsb", r.meta().repr));
        file::write(r, &p).unwrap();
        let back = file::read(&p).unwrap();
        assert_eq!(file::to_bytes(&back), file::to_bytes(r));
        let (wi, wo) = (from_spherical(0.5, 0.0), from_spherical(0.6, 3.0));
        let (mut a, mut b) = (vec![0.0; 2], vec![0.0; 2]);
        r.eval(wi, wo, &mut a);
        back.eval(wi, wo, &mut b);
        assert_eq!(a, b);
        let bytes = std::fs::read(&p).unwrap();
        let e = file::from_bytes(&bytes[..bytes.len() - 40], "x.gsb")
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("truncated"), "{e}");
        let mut bad = bytes.clone();
        bad[bytes.len() / 2] ^= 1;
        let e = file::from_bytes(&bad, "x.gsb").err().unwrap().to_string();
        assert!(e.contains("checksum mismatch"), "{e}");
        let mut magic = bytes.clone();
        magic[3] = b'?';
        let e = file::from_bytes(&magic, "x.gsb").err().unwrap().to_string();
        assert!(e.contains("wrong magic"), "{e}");
        let e = file::from_bytes(&bytes[..5], "x.gsb")
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("wrong magic") || e.contains("truncated"), "{e}");
    }
}

/// Issue 12, item 6: `.gsb` files whose checksum is valid but whose content is not (a NaN
/// angle, no angles, a child index out of range or pointing backwards, cell bounds of 1e9,
/// a declared array length near 2^64) are refused with a message, never a panic or hang.
#[test]
fn gsb_files_with_a_valid_checksum_but_senseless_content_are_refused() {
    let (data, _) = rough_data(Buckets {
        theta_bins: 18,
        phi_bins: 12,
    });
    let table = TableBrdf::build(&data);
    let sub = SubdividedBrdf::build(&data, 0.05);
    assert!(
        sub.cells[0].iter().any(|c| c.child != u32::MAX),
        "the test needs a split cell"
    );
    type Damage = Box<dyn Fn(&mut Representation)>;
    let table_case = |f: fn(&mut TableBrdf)| -> Damage {
        Box::new(move |r| match r {
            Representation::Table(t) => f(t),
            _ => unreachable!(),
        })
    };
    let sub_case = |f: fn(&mut SubdividedBrdf)| -> Damage {
        Box::new(move |r| match r {
            Representation::Subdivided(s) => f(s),
            _ => unreachable!(),
        })
    };
    let cases: Vec<(&str, Representation, Damage)> = vec![
        (
            "incident angles",
            Representation::Table(table.clone()),
            table_case(|t| t.theta_i_rad[0] = f64::NAN),
        ),
        (
            "table size",
            Representation::Table(table.clone()),
            table_case(|t| {
                t.theta_i_rad.clear();
                t.values.clear();
            }),
        ),
        (
            "table value",
            Representation::Table(table.clone()),
            table_case(|t| t.values[3] = f64::INFINITY),
        ),
        (
            "children outside",
            Representation::Subdivided(sub.clone()),
            sub_case(|s| {
                let k = s.cells[0].iter().position(|c| c.child != u32::MAX).unwrap();
                s.cells[0][k].child = 1_000_000;
            }),
        ),
        (
            "children outside",
            Representation::Subdivided(sub.clone()),
            sub_case(|s| {
                // A child pointing at its own parent: a descent would never end.
                let k = s.cells[0].iter().position(|c| c.child != u32::MAX).unwrap();
                s.cells[0][k].child = k as u32;
            }),
        ),
        (
            "outside the bucket grid",
            Representation::Subdivided(sub.clone()),
            sub_case(|s| {
                let last = s.cells[0].len() - 1;
                s.cells[0][last].t1 = 1_000_000_000;
            }),
        ),
        (
            "do not partition",
            Representation::Subdivided(sub.clone()),
            sub_case(|s| {
                let k = s.cells[0].iter().position(|c| c.child != u32::MAX).unwrap();
                let first = s.cells[0][k].child as usize;
                let c = s.cells[0][first];
                s.cells[0][first + 1] = c; // two children now overlap
            }),
        ),
    ];
    for (want, mut r, damage) in cases {
        damage(&mut r);
        let e = file::from_bytes(&file::to_bytes(&r), "x.gsb")
            .err()
            .unwrap_or_else(|| panic!("{want}: accepted"))
            .to_string();
        assert!(e.contains(want) && e.contains("x.gsb"), "{want}: {e}");
    }
    // A declared array length near 2^64, with the checksum made valid again.
    let mut bytes = file::to_bytes(&Representation::Table(table.clone()));
    // The payload starts after the 24-byte preamble and the header (container layout).
    let hlen = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    bytes[24 + hlen..24 + hlen + 8].copy_from_slice(&(u64::MAX - 3).to_le_bytes());
    goniospec::container::reseal(&mut bytes);
    let e = file::from_bytes(&bytes, "x.gsb").err().unwrap().to_string();
    assert!(e.contains("truncated"), "{e}");
    // The undamaged files still read.
    for r in [
        Representation::Table(table),
        Representation::Subdivided(sub),
    ] {
        assert!(file::from_bytes(&file::to_bytes(&r), "x.gsb").is_ok());
    }
}

/// Issue 11: files written before the shared container (`.gsa` version 2, `.gsb` version 1,
/// FNV-1a trailers) still read, with the same content as their re-encoding in the current
/// version (the fuzz seeds hold both; the current ones were re-framed by an independent
/// Python script with zlib's CRC-32).
#[test]
fn previous_container_versions_still_read() {
    let dir = root().join("fuzz/corpus");
    for name in ["small", "global"] {
        let old =
            goniospec::accumulate::file::Accumulator::read(&dir.join(format!("gsa/{name}-v2.gsa")))
                .unwrap();
        let new =
            goniospec::accumulate::file::Accumulator::read(&dir.join(format!("gsa/{name}.gsa")))
                .unwrap();
        assert_eq!(old, new);
        assert_eq!(
            old.to_bytes(),
            std::fs::read(dir.join(format!("gsa/{name}.gsa"))).unwrap()
        );
    }
    for name in ["table", "kdtree", "subdivided"] {
        // The current-version seeds were written before issue 45 renamed the bin centres
        // `meta.lambda_nm` (they hold `wavelengths_nm`, which is still read): both versions
        // decode to the same BRDF, and it round-trips through the current writer.
        let old = file::read(&dir.join(format!("gsb/{name}-v1.gsb"))).unwrap();
        let new = file::read(&dir.join(format!("gsb/{name}.gsb"))).unwrap();
        assert_eq!(file::to_bytes(&old), file::to_bytes(&new), "{name}");
        assert!(
            String::from_utf8_lossy(&std::fs::read(dir.join(format!("gsb/{name}.gsb"))).unwrap())
                .contains("wavelengths_nm = ["),
            "{name}: the seed holds the old name"
        );
        let again = file::to_bytes(&new);
        assert!(String::from_utf8_lossy(&again).contains("lambda_nm = ["));
        assert_eq!(
            file::to_bytes(&file::from_bytes(&again, "x.gsb").unwrap()),
            again,
            "{name}"
        );
    }
    // Any other version is refused by number.
    let mut bytes = std::fs::read(dir.join("gsb/table.gsb")).unwrap();
    bytes[8] = 9;
    let e = file::from_bytes(&bytes, "x.gsb").err().unwrap().to_string();
    assert!(
        e.contains("version 9") && e.contains("versions 1 and 2"),
        "{e}"
    );
}

/// Issue 28, item 2: a `.gsb` stores the run's whole wavelength sampling (bin edges, not
/// only centres), refuses a sampling that does not give its centres, and files written
/// before (centres only) still read, their bins rebuilt halfway between centres.
#[test]
fn gsb_files_carry_the_whole_wavelength_sampling() {
    let (data, _) = rough_data(Buckets {
        theta_bins: 9,
        phi_bins: 6,
    });
    let table = Representation::Table(TableBrdf::build(&data));
    let d = scratch("gsb-spectrum");
    let p = d.join("table.gsb");
    file::write(&table, &p).unwrap();
    let back = file::read(&p).unwrap();
    let edges = Wavelengths::Bins(vec![450.0, 550.0, 650.0]);
    assert_eq!(back.meta().spectrum.as_ref(), Some(&edges));
    assert_eq!(back.meta().sampling(), edges);

    // Edges that do not give the stored centres (500, 600) are refused.
    let mut wrong = TableBrdf::build(&data);
    wrong.meta.spectrum = Some(Wavelengths::Bins(vec![400.0, 550.0, 650.0]));
    let bytes = file::to_bytes(&Representation::Table(wrong));
    let e = file::from_bytes(&bytes, "x.gsb").err().unwrap().to_string();
    assert!(e.contains("do not give"), "{e}");

    // A file from before: no spectrum; bins rebuilt from the centres.
    let old = file::read(&root().join("fuzz/corpus/gsb/table.gsb")).unwrap();
    assert_eq!(old.meta().spectrum, None);
    let c = &old.meta().lambda_nm;
    let rebuilt = old.meta().sampling();
    assert_eq!(rebuilt.count(), c.len());
    for (j, &cj) in c.iter().enumerate() {
        let (lo, hi) = rebuilt.band(j);
        assert!(
            (0.5 * (lo + hi) - cj).abs() < 1e-9 && hi > lo,
            "{j}: {lo} {hi} {cj}"
        );
    }
}
