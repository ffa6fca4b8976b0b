//! `bench eval`: query times and accuracy of the BRDF representations on an analytic BRDF
//! and on rough samples.

use std::time::Instant;

use glam::DVec3;

use crate::rng::Rng;

/// A smooth analytic BRDF for `bench eval` (1/sr): a Lambertian base plus a broad
/// Blinn-Phong lobe (Blinn 1977, normalised as in Akenine-Moeller et al., Real-Time
/// Rendering, 4th ed., eq. 9.47 without Fresnel), with a mild wavelength tilt.
pub fn analytic_brdf(wi: DVec3, wo: DVec3, lambda_nm: f64) -> f64 {
    let h = (wi + wo).normalize();
    let n = 20.0;
    let spec = (n + 8.0) / (8.0 * std::f64::consts::PI) * h[2].max(0.0).powf(n);
    let tilt = 1.0 + 0.3 * (lambda_nm - 550.0) / 200.0;
    0.2 / std::f64::consts::PI * tilt + 0.05 * spec
}

/// Bucket data sampled exactly from [`analytic_brdf`] on a grid of `ni` incident angles
/// (0..80 deg) and `tb x pb` outgoing buckets.
pub fn analytic_buckets(ni: usize, tb: u32, pb: u32, lambdas: &[f64]) -> crate::brdf::BucketData {
    use crate::accumulate::Buckets;
    use crate::brdf::{BucketData, BucketSample, Meta};
    use crate::geom::from_spherical;
    let b = Buckets {
        theta_bins: tb,
        phi_bins: pb,
    };
    let theta_i: Vec<f64> = (0..ni)
        .map(|i| (80.0 * i as f64 / (ni.max(2) - 1) as f64).to_radians())
        .collect();
    let samples = theta_i
        .iter()
        .map(|&ti| {
            (0..b.len())
                .map(|k| {
                    let (t, p) = b.centre(k);
                    let omega = b.projected_solid_angle(k);
                    let f: Vec<f64> = lambdas
                        .iter()
                        .map(|&l| analytic_brdf(from_spherical(ti, 0.0), from_spherical(t, p), l))
                        .collect();
                    BucketSample {
                        theta_i_rad: ti,
                        phi_i_rad: 0.0,
                        theta_o_rad: t,
                        phi_o_rad: p,
                        flux: f.iter().map(|x| x * omega).collect(),
                        f,
                        omega,
                        rel_stderr: None,
                    }
                })
                .collect()
        })
        .collect();
    BucketData {
        theta_i_rad: theta_i,
        phi_i_rad: 0.0,
        buckets: b,
        lambda_nm: lambdas.to_vec(),
        samples,
        meta: Meta {
            repr: crate::brdf::Kind::Analytic,
            lambda_nm: lambdas.to_vec(),
            spectrum: Some(crate::spectrum::Wavelengths::Monochromatic(
                lambdas.to_vec(),
            )),
            sample_name: "analytic Lambert + Blinn-Phong".into(),
            sample_hash: "analytic".into(),
            simulation: String::new(),
            isotropic: false,
            reciprocal: false,
            median_rel_stderr: None,
            trees_per_direction: None,
            incident_stokes: None,
            rgb: false,
        },
    }
}

/// Median and 99th percentile of query times (ns) of `eval` over `queries`.
fn query_times(b: &dyn crate::brdf::Brdf, queries: &[(DVec3, DVec3)]) -> (f64, f64) {
    let mut out = vec![0.0; b.meta().lambda_nm.len()];
    let mut t: Vec<f64> = queries
        .iter()
        .map(|&(wi, wo)| {
            let t0 = Instant::now();
            b.eval(wi, wo, &mut out);
            std::hint::black_box(&out);
            t0.elapsed().as_nanos() as f64
        })
        .collect();
    t.sort_by(f64::total_cmp);
    (t[t.len() / 2], t[(t.len() * 99) / 100])
}

/// `bench eval`: query time, memory, build time and accuracy of each representation.
pub fn eval_bench(
    rough: Option<(&crate::brdf::BucketData, &crate::brdf::BucketData)>,
    mut log: impl FnMut(&str),
) {
    use crate::brdf::Brdf;
    use crate::brdf::kdtree::KdTreeBrdf;
    use crate::brdf::subdivided::SubdividedBrdf;
    use crate::brdf::table::TableBrdf;
    use crate::geom::from_spherical;
    let lambdas = [450.0, 550.0, 650.0];
    let mut rng = Rng::new(3, 3);
    let queries: Vec<(DVec3, DVec3)> = (0..20_000)
        .map(|_| {
            (
                from_spherical(
                    rng.range(0.0, 80f64.to_radians()),
                    rng.range(0.0, std::f64::consts::TAU),
                ),
                from_spherical(
                    rng.range(0.0, 85f64.to_radians()),
                    rng.range(0.0, std::f64::consts::TAU),
                ),
            )
        })
        .collect();
    log(
        "repr        buckets   build_s   memory_MB  median_ns  p99_ns   max_rel_err_vs_analytic  mean_rel_err",
    );
    for (ni, tb, pb) in [(10usize, 25u32, 40u32), (20, 50, 100), (40, 125, 200)] {
        let data = analytic_buckets(ni, tb, pb, &lambdas);
        let n = ni * (tb * pb) as usize;
        let nb = lambdas.len();
        let mut reps: Vec<(&str, Box<dyn Brdf>, f64, f64)> = Vec::new();
        let t0 = Instant::now();
        let kd = KdTreeBrdf::build(&data, 4, true, false);
        let bt = t0.elapsed().as_secs_f64();
        let mem = (kd.tree.heap_bytes() + kd.points.len() * 32 + kd.values.len() * 8) as f64 / 1e6;
        reps.push(("kdtree", Box::new(kd), bt, mem));
        let t0 = Instant::now();
        let sub = SubdividedBrdf::build(&data, 0.05);
        let bt = t0.elapsed().as_secs_f64();
        let cells: usize = sub.cells.iter().map(|c| c.len()).sum();
        let mem =
            (cells * (std::mem::size_of::<crate::brdf::subdivided::Cell>() + 8 * nb)) as f64 / 1e6;
        reps.push(("subdivided", Box::new(sub), bt, mem));
        let t0 = Instant::now();
        let table = TableBrdf::build(&data);
        let bt = t0.elapsed().as_secs_f64();
        let mem = (table.values.len() * 8) as f64 / 1e6;
        reps.push(("table", Box::new(table), bt, mem));
        let mut out = vec![0.0; nb];
        for (name, b, bt, mem) in &reps {
            let (med, p99) = query_times(b.as_ref(), &queries);
            let (mut maxe, mut sume) = (0.0f64, 0.0);
            let checked = 5000;
            for &(wi, wo) in &queries[..checked] {
                b.eval(wi, wo, &mut out);
                let want = analytic_brdf(wi, wo, lambdas[1]);
                let e = (out[1] / want - 1.0).abs();
                maxe = maxe.max(e);
                sume += e;
            }
            log(&format!(
                "{name:<11} {n:<9} {bt:<9.3} {mem:<10.1} {med:<10.0} {p99:<8.0} {maxe:<24.4} {:.4}",
                sume / checked as f64
            ));
            log(&format!("{name}_{n}_median_ns: {med:.0} ns"));
            log(&format!("{name}_{n}_p99_ns: {p99:.0} ns"));
        }
        // Brute-force nearest search over the same points, for the kd-tree's speed-up.
        let kd = KdTreeBrdf::build(&data, 4, true, false);
        // Queries in the tree's isotropic frame (phi_i = 0), as eval makes them.
        let rotated: Vec<(DVec3, DVec3)> = queries
            .iter()
            .map(|&(wi, wo)| {
                let (ti, pi) = crate::geom::angles(wi);
                let (to, po) = crate::geom::angles(wo);
                (from_spherical(ti, 0.0), from_spherical(to, po - pi))
            })
            .collect();
        let queries = &rotated;
        let m = 50.min(queries.len());
        let t0 = Instant::now();
        for &(wi, wo) in &queries[..m] {
            std::hint::black_box(kd.tree.nearest_brute(wi, wo, 4));
        }
        let queries = &queries[..];
        let brute = t0.elapsed().as_nanos() as f64 / m as f64;
        let mut near = Vec::new();
        let t0 = Instant::now();
        for &(wi, wo) in queries {
            kd.tree.nearest(wi, wo, 4, &mut near);
            std::hint::black_box(&near);
        }
        let tree = t0.elapsed().as_nanos() as f64 / queries.len() as f64;
        log(&format!(
            "  {n} buckets: kd-tree 4-nearest {tree:.0} ns/query against brute force {brute:.0} ns/query ({:.0}x)",
            brute / tree
        ));
    }
    if let Some((low, high)) = rough {
        let reference = TableBrdf::build(high);
        let reps: Vec<(&str, Box<dyn Brdf>)> = vec![
            ("kdtree", Box::new(KdTreeBrdf::build(low, 4, true, false))),
            ("subdivided", Box::new(SubdividedBrdf::build(low, 0.05))),
            ("table", Box::new(TableBrdf::build(low))),
        ];
        let nb = low.lambda_nm.len();
        let (mut a, mut r) = (vec![0.0; nb], vec![0.0; nb]);
        for (name, b) in &reps {
            let (mut num, mut den) = (0.0, 0.0);
            for &ti in &low.theta_i_rad {
                for t in 0..30 {
                    for p in 0..24 {
                        let wi = from_spherical(ti, 0.0);
                        let wo = from_spherical(
                            (t as f64 + 0.5) * 3f64.to_radians(),
                            (p as f64 + 0.5) * 15f64.to_radians(),
                        );
                        b.eval(wi, wo, &mut a);
                        reference.eval(wi, wo, &mut r);
                        let w = wo[2];
                        num += w * (a[0] - r[0]).abs();
                        den += w * r[0].abs();
                    }
                }
            }
            log(&format!(
                "rough sample: {name:<11} cosine-weighted relative L1 error against the high-sample table: {:.4}",
                num / den
            ));
        }
    }
}
