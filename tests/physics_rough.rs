//! Rough and curved samples: convergence, the seed's darkening, invariance, curved films
//! against the local-film reference, white furnace, reciprocity, backends, determinism.

mod common;

use common::*;
#[cfg(embree)]
use goniospec::accel::Backend;
use goniospec::accumulate::file::Accumulator;
use goniospec::accumulate::{Buckets, Coherence};
use goniospec::sample::{Sample, generate};
use goniospec::simulate::Wavelengths;

/// The same sample tiled `k x k` times: a k^2 larger sampled area, statistically identical.
fn tiled(s: &Sample, k: usize) -> Sample {
    s.tiled([k, k])
}

fn mono550() -> Wavelengths {
    Wavelengths::Monochromatic(vec![550.0])
}

#[test]
fn rough_film_converges_between_n_and_10n_rays() {
    let s = shipped("thin-film-600nm.toml");
    let mut cfg = config(&[30.0], mono550(), 3000);
    cfg.buckets = Buckets {
        theta_bins: 18,
        phi_bins: 12,
    };
    let a = run(&s, &cfg);
    cfg.rays = 30_000;
    cfg.seed = 2;
    let b = run(&s, &cfg);
    let (ca, cb) = (a.cell(0, 0), b.cell(0, 0));
    let mut populated = 0;
    let mut within = 0;
    // Populated: at least 30 trees deposited there in the smaller run, so the per-tree
    // spread is a usable error estimate.
    let mut outliers = Vec::new();
    for kk in 0..2 * cfg.buckets.len() {
        if ca.count[kk] < 30 {
            continue;
        }
        populated += 1;
        let (fa, fb) = (
            ca.fraction(kk, Coherence::Beamlet),
            cb.fraction(kk, Coherence::Beamlet),
        );
        let (sa, sb) = (
            ca.fraction_stderr(kk, Coherence::Beamlet).unwrap(),
            cb.fraction_stderr(kk, Coherence::Beamlet).unwrap(),
        );
        if (fa - fb).abs() <= 3.0 * (sa * sa + sb * sb).sqrt() {
            within += 1;
        } else {
            outliers.push((kk, ca.count[kk], fa, sa, fb, sb));
        }
    }
    for o in &outliers {
        eprintln!(
            "outlier: key {} ({} trees): {} +- {} vs {} +- {}",
            o.0, o.1, o.2, o.3, o.4, o.5
        );
    }
    eprintln!("{within} of {populated} populated buckets agree within 3 sigma");
    assert!(
        populated >= 20,
        "too few populated buckets ({populated}) for a meaningful test"
    );
    assert!(
        within as f64 >= 0.99 * populated as f64,
        "{within} of {populated}"
    );
    let (ra, rb) = (totals(&a, 0, 0).0, totals(&b, 0, 0).0);
    let (sa, sb) = (
        ca.r_stderr(Coherence::Beamlet).unwrap(),
        cb.r_stderr(Coherence::Beamlet).unwrap(),
    );
    eprintln!("R: {ra} +- {sa} (N) vs {rb} +- {sb} (10 N)");
    assert!(
        (ra - rb).abs() <= 3.0 * (sa * sa + sb * sb).sqrt(),
        "total R drifts: {ra} vs {rb}"
    );
}

#[test]
fn a_larger_sampled_area_does_not_darken_the_beamlet_estimate_but_darkens_global() {
    let s = shipped("thin-film-600nm.toml");
    let big = tiled(&s, 2);
    let mut results = Vec::new();
    for mode in [Coherence::Beamlet, Coherence::Global] {
        let mut cfg = config(&[30.0], mono550(), 4000);
        cfg.coherence = mode;
        let small_r = totals(&run(&s, &cfg), 0, 0).0;
        cfg.rays = 16_000;
        let big_r = totals(&run(&big, &cfg), 0, 0).0;
        eprintln!("{mode:?}: R {small_r} (1x area) -> {big_r} (4x area)");
        results.push((small_r, big_r));
    }
    let (b1, b4) = results[0];
    assert!(
        (b4 / b1 - 1.0).abs() < 0.02,
        "beamlet R changed with the sampled area: {b1} -> {b4}"
    );
    let (g1, g4) = results[1];
    assert!(
        g4 <= 0.5 * g1,
        "global mode should darken by at least 2x: {g1} -> {g4}"
    );
}

#[test]
fn translation_and_bucket_grid_leave_total_r_unchanged_but_not_for_bucket_mode() {
    let s = shipped("thin-film-600nm.toml");
    let r_of = |mode: Coherence, origin: [f64; 3], theta_bins: u32| {
        let mut cfg = config(&[30.0], mono550(), 2000);
        cfg.coherence = mode;
        cfg.origin_nm = origin.into();
        cfg.buckets = Buckets {
            theta_bins,
            phi_bins: 36,
        };
        totals(&run(&s, &cfg), 0, 0).0
    };
    let mm = [1.0e6, 1.0e6, 1.0e6];
    let base = r_of(Coherence::Beamlet, [0.0; 3], 45);
    let moved = r_of(Coherence::Beamlet, mm, 45);
    assert!(
        ((moved - base) / base).abs() < 1e-6,
        "translation changed R: {base} -> {moved}"
    );
    let fine = r_of(Coherence::Beamlet, [0.0; 3], 180);
    assert!(
        ((fine - base) / base).abs() < 1e-6,
        "bucket grid changed R: {base} -> {fine}"
    );
    // Gondek's / the seed's bucket superposition fails at least one of these.
    let b45 = r_of(Coherence::Bucket, [0.0; 3], 45);
    let b180 = r_of(Coherence::Bucket, [0.0; 3], 180);
    let bmoved = r_of(Coherence::Bucket, mm, 45);
    eprintln!("beamlet {base}; bucket: 45 bins {b45}, 180 bins {b180}, moved {bmoved}");
    let grid = ((b180 - b45) / b45).abs();
    let shift = ((bmoved - b45) / b45).abs();
    assert!(
        grid > 1e-3 || shift > 1e-3,
        "bucket mode should depend on the grid or the origin: {grid} {shift}"
    );
}

/// R of the flat-film local reference: the TMM at the local incidence angle and local
/// (perpendicular) thickness where the ray meets the film, averaged over entry points.
#[test]
fn gently_curved_film_approaches_the_local_film_reference() {
    let lx = 20_000.0;
    let slope = 2f64.to_radians().tan();
    let amp = lx * slope / (2.0 * std::f64::consts::PI);
    let h = |x: f64| amp * (2.0 * std::f64::consts::PI * x / lx).sin();
    let tile = [lx, 2000.0];
    let d = scratch("curved");
    generate::height_field([400, 1], tile, |x, _| 600.0 + h(x))
        .write_obj(&d.join("top.obj"), 1.0, "top")
        .unwrap();
    generate::height_field([400, 1], tile, |x, _| h(x))
        .write_obj(&d.join("bottom.obj"), 1.0, "bottom")
        .unwrap();
    let s = sample_in(
        &d,
        "[sample]\nname = \"curved\"\nunit = \"nm\"\ntile = [20000.0, 2000.0]\n[media.air]\nn = 1.0\n[media.soap]\nn = 1.33\n[[interface]]\nmesh = \"top.obj\"\nfront = \"air\"\nback = \"soap\"\n[[interface]]\nmesh = \"bottom.obj\"\nfront = \"soap\"\nback = \"air\"\n",
    );
    let theta = 30f64.to_radians();
    let lambdas = [480.0, 550.0, 620.0];
    let cfg = config(&[30.0], Wavelengths::Monochromatic(lambdas.to_vec()), 4000);
    let acc = run(&s, &cfg);
    // Reference: march along x of the entry point; the ray meets the top surface where
    // z_top - t cos(theta) = 600 + h(x_e + t sin(theta)).
    let z_top = 600.0 + amp + 100.0;
    for (j, &l) in lambdas.iter().enumerate() {
        let n_e = 2000;
        let mut sum = 0.0;
        for i in 0..n_e {
            let xe = (i as f64 + 0.5) / n_e as f64 * lx;
            let (mut lo, mut hi) = (0.0, 2.0 * z_top / theta.cos());
            for _ in 0..80 {
                let t = 0.5 * (lo + hi);
                if z_top - t * theta.cos() > 600.0 + h(xe + t * theta.sin()) {
                    lo = t;
                } else {
                    hi = t;
                }
            }
            let xh = xe + lo * theta.sin();
            let alpha = (amp * 2.0 * std::f64::consts::PI / lx
                * (2.0 * std::f64::consts::PI * xh / lx).cos())
            .atan();
            // Incident direction of travel (sin, 0, -cos); local normal (-sin a, 0, cos a).
            let cos_local = theta.cos() * alpha.cos() + theta.sin() * alpha.sin();
            let (r, _) = tmm_ref(
                &[c(1.0, 0.0), c(1.33, 0.0), c(1.0, 0.0)],
                &[600.0 * alpha.cos()],
                l,
                cos_local.acos(),
            );
            sum += r;
        }
        let reference = sum / n_e as f64;
        let (r, _) = totals(&acc, 0, j);
        eprintln!("lambda {l}: R {r} vs local-film {reference}");
        assert!(
            (r - reference).abs() < 0.01,
            "lambda {l}: R {r} vs local-film reference {reference}"
        );
    }
}

/// The seed's film as `make demo` runs it (0-85 deg by 5 deg, 40 bins over 380-780 nm, the
/// default auto method) neither gains nor loses energy: it is lossless, so in every cell
/// R + T = 1 within 4 standard errors of R and T together and within 2e-3 absolute. Issue
/// 71: it reported R + T = 1.0130 at 70 deg and 1.0139 at 85 deg, where the beamlet
/// overlaps of its reflected and transmitted partial waves did not match on its curved
/// faces, and lost 2.5e-2 at 85 deg to the depth cut (light guided in the film near its
/// critical angle). The file holds the balance to rounding (`Header::balanced`).
#[test]
fn the_seed_film_conserves_energy_at_every_angle_of_the_demo() {
    let s = shipped("thin-film-600nm.toml");
    let angles: Vec<f64> = (0..18).map(|i| 5.0 * i as f64).collect();
    let edges: Vec<f64> = (0..=40).map(|i| 380.0 + 10.0 * i as f64).collect();
    let mut cfg = config(&angles, Wavelengths::Bins(edges), 2048);
    cfg.coherence = Coherence::Auto;
    // As the demo runs it: light guided in the film near its critical angle at 85 deg
    // needs thousands of events (at the default 64 it drops 2.4e-2, reported).
    cfg.limits.max_depth = 4096;
    let acc = run(&s, &cfg);
    assert!(acc.header.balanced);
    let mode = acc.header.settings.coherence_mode();
    let mut worst: (f64, f64, usize) = (0.0, 0.0, 0);
    for (i, theta) in angles.iter().enumerate() {
        for j in 0..40 {
            let (r, t) = totals(&acc, i, j);
            let c = acc.cell(i, j);
            let se = c.r_stderr(mode).unwrap().hypot(c.t_stderr(mode).unwrap());
            let gap = (r + t - 1.0).abs();
            assert!(
                gap <= 4.0 * se && gap <= 2e-3,
                "theta {theta} deg, bin {j}: R {r} + T {t} = {} (standard error {se:.1e})",
                r + t
            );
            if gap > worst.0 {
                worst = (gap, *theta, j);
            }
        }
    }
    eprintln!(
        "largest |R + T - 1|: {:.2e} at {} deg, bin {}",
        worst.0, worst.1, worst.2
    );
}

/// A file that says its lossless trees conserve power (`Header::balanced`) is held to
/// `R + T + dropped = 1` to rounding in every cell without absorption: the shipped rough
/// glass's cell with R raised by 1e-6 and resealed is refused, naming the cell and the
/// balance, though 1e-6 is far inside its noise; the same file from before the balance
/// (no flag) is judged by the noise and read.
#[test]
fn a_lossless_cell_that_does_not_balance_is_refused() {
    use goniospec::simulate::check_file;
    let glass = shipped("rough-glass.toml");
    let acc = run(
        &glass,
        &config(&[30.0], Wavelengths::Monochromatic(vec![550.0]), 1024),
    );
    assert!(acc.header.balanced);
    assert!(check_file(&acc, "honest").is_ok());
    let (r, t) = totals(&acc, 0, 0);
    let c = acc.cell(0, 0);
    assert_eq!(c.absorbed, 0.0);
    let d = c.dropped / c.trees as f64;
    assert!(
        (r + t + d - 1.0).abs() < 1e-9,
        "R + T + dropped = {}",
        r + t + d
    );
    let mut forged = acc.clone();
    forged.cells[0].r_sum += 1e-6 * forged.cells[0].trees as f64;
    let err = check_file(&forged, "forged.gsa").unwrap_err().to_string();
    assert!(
        err.contains("forged.gsa") && err.contains("without absorption") && err.contains("created"),
        "{err}"
    );
    forged.header.balanced = false;
    assert!(check_file(&forged, "older.gsa").is_ok());
}

#[test]
fn white_furnace_lossless_samples_keep_all_power() {
    // A near-perfect mirror (n -> 0, large k: |r| = 1 - 4n/(1 + k^2)) cut into V-grooves.
    let d = scratch("furnace");
    generate::v_grooves([20_000.0, 20_000.0], 10, 90.0, 0.0)
        .unwrap()
        .write_obj(&d.join("v.obj"), 1.0, "v")
        .unwrap();
    let mirror = sample_in(
        &d,
        "[sample]\nname = \"mirror grooves\"\nunit = \"nm\"\ntile = [20000.0, 20000.0]\n[media.air]\nn = 1.0\n[media.mirror]\nn = 1e-6\nk = 20.0\n[[interface]]\nmesh = \"v.obj\"\nfront = \"air\"\nback = \"mirror\"\n",
    );
    let cfg = config(
        &[0.0, 30.0, 60.0],
        Wavelengths::Bins(vec![400.0, 550.0, 700.0]),
        2000,
    );
    let acc = run(&mirror, &cfg);
    for i in 0..3 {
        for j in 0..2 {
            let (r, t) = totals(&acc, i, j);
            let cell = acc.cell(i, j);
            let dropped = cell.dropped / cell.trees as f64;
            assert!(t == 0.0);
            assert!(
                (r - (1.0 - dropped)).abs() < 1e-3,
                "theta {i} bin {j}: R {r}, dropped {dropped}"
            );
        }
    }
    // A lossless rough dielectric: reflected + transmitted + dropped = 1.
    let glass = shipped("rough-glass.toml");
    let acc = run(
        &glass,
        &config(&[0.0, 45.0], Wavelengths::Monochromatic(vec![500.0]), 2000),
    );
    for i in 0..2 {
        let (r, t) = totals(&acc, i, 0);
        let cell = acc.cell(i, 0);
        let dropped = cell.dropped / cell.trees as f64;
        eprintln!("rough glass {i}: R {r} T {t} dropped {dropped}");
        assert!(
            (r + t + dropped - 1.0).abs() < 1e-3,
            "R + T + dropped = {}",
            r + t + dropped
        );
    }
}

/// Reciprocity, `f_r(w_i, w_o) = f_r(w_o, w_i)`, on the shipped rough glass's own surface:
/// light from (25 deg, phi 15) read in the bucket around (35 deg, phi 195) against light
/// from (35 deg, phi 195) read around (25 deg, phi 15) (10 deg in theta, 30 in phi), the
/// exact swap for a fixed surface.
///
/// A bucket's average is not the BRDF at its centre: on a surface of flat facets (12,800
/// here, about 30 correlation cells across the tile) the two buckets gather the facets
/// whose normals lie in two different half-vector regions (the images of the buckets at
/// the two incidences), so their averages differ by the facets themselves, well beyond
/// the honest standard errors (7 % at 400,000 trees). That part is computed here from the
/// mesh by brute force, single scattering (each facet's power, `A (n . w_i) F / (L^2 cos
/// theta_i)`, to the bucket of its mirror direction; Fresnel for the glass's index at
/// 550 nm), and the simulated pair must differ as the facets do: within 3 combined
/// standard errors plus 2 % of the value for what single scattering leaves out (shadowing
/// and masking, and light that meets the surface twice, at slopes of 8 deg and 25-35 deg:
/// Smith's masking there is above 0.99).
#[test]
fn brdf_of_a_rough_dielectric_is_reciprocal_as_its_facets_are() {
    let s = shipped("rough-glass.toml");
    let b = Buckets {
        theta_bins: 9,
        phi_bins: 12,
    };
    let run_from = |theta_i: f64, phi_i: f64| {
        let mut cfg = config(&[theta_i], mono550(), 100_000);
        cfg.phi_i_deg = phi_i;
        cfg.buckets = b;
        run(&s, &cfg)
    };
    let dir = |t: f64, p: f64| goniospec::geom::from_spherical(t.to_radians(), p.to_radians());
    let f = |acc: &Accumulator, wo: glam::DVec3| {
        let (k, omega) = (2 * b.index(wo), b.projected_solid_angle(b.index(wo)));
        let cell = acc.cell(0, 0);
        (
            cell.fraction(k, Coherence::Beamlet) / omega,
            cell.fraction_stderr(k, Coherence::Beamlet).unwrap() / omega,
        )
    };
    // Single scattering by the facets, brute force.
    let itf = &s.interfaces[0];
    let glass = if s.media[itf.front].name == "glass" {
        itf.front
    } else {
        itf.back
    };
    let n = s.media[glass].model.eval(550.0).unwrap().0;
    let fresnel = |c: f64| {
        let st2 = (1.0 - c * c) / (n * n);
        let ct = (1.0 - st2).sqrt();
        let rs = (c - n * ct) / (c + n * ct);
        let rp = (n * c - ct) / (n * c + ct);
        0.5 * (rs * rs + rp * rp)
    };
    let facets = |wi: glam::DVec3, wo: glam::DVec3| {
        let bucket = b.index(wo);
        let mut power = 0.0;
        for t in 0..itf.mesh.triangles.len() {
            let a = itf.mesh.area_vector(t) * 0.5;
            let m = a.normalize() * if a.z < 0.0 { -1.0 } else { 1.0 };
            let c = m.dot(wi);
            let r = 2.0 * c * m - wi;
            if c > 0.0 && r.z > 0.0 && b.index(r) == bucket {
                power += a.length() * c * fresnel(c);
            }
        }
        power / (s.tile_nm[0] * s.tile_nm[1] * wi.z) / b.projected_solid_angle(bucket)
    };
    let (wa, wb) = (dir(25.0, 15.0), dir(35.0, 195.0));
    let (f1, s1) = f(&run_from(25.0, 15.0), wb);
    let (f2, s2) = f(&run_from(35.0, 195.0), wa);
    let (g1, g2) = (facets(wa, wb), facets(wb, wa));
    eprintln!(
        "f_r(25 -> 35) = {f1} +- {s1}, f_r(35 -> 25) = {f2} +- {s2}; facets alone {g1}, {g2}"
    );
    assert!(
        f1 > 10.0 * s1 && f2 > 10.0 * s2,
        "the lobe must be resolved"
    );
    assert!(
        ((f1 - f2) - (g1 - g2)).abs() <= 3.0 * (s1 * s1 + s2 * s2).sqrt() + 0.02 * f1.max(f2),
        "not reciprocal: {f1} vs {f2}, where the facets give {g1} vs {g2}"
    );
}

/// Built only where Embree was found (`cfg(embree)` from build.rs), so a machine without
/// it skips this test visibly instead of passing it silently.
#[cfg(embree)]
#[test]
fn embree_and_obvhs_give_the_same_accumulator() {
    assert!(Backend::Embree.is_available());
    let s = shipped("thin-film-600nm.toml");
    let mut cfg = config(
        &[20.0, 60.0],
        Wavelengths::Bins(vec![450.0, 550.0, 650.0]),
        1000,
    );
    cfg.backend = Backend::Embree;
    let e = run(&s, &cfg);
    cfg.backend = Backend::Obvhs;
    let o = run(&s, &cfg);
    let mut differing = 0;
    let mut total = 0;
    for (ce, co) in e.cells.iter().zip(&o.cells) {
        for (a, b) in ce.sum.iter().zip(&co.sum) {
            total += 1;
            if (a - b).abs() > 1e-9 * a.abs().max(b.abs()).max(1e-12) {
                differing += 1;
            }
        }
        let (re, ro) = (ce.r_sum / ce.trees as f64, co.r_sum / co.trees as f64);
        assert!(
            (re - ro).abs() < 1e-4 * re.max(1e-6),
            "total R differs: {re} vs {ro}"
        );
    }
    eprintln!("{differing} of {total} bucket sums differ (edge ties)");
    assert!(
        differing * 100 <= total,
        "{differing} of {total} buckets differ"
    );
}

#[test]
fn one_and_two_threads_write_identical_files() {
    let s = shipped("thin-film-600nm.toml");
    let cfg = config(
        &[0.0, 45.0],
        Wavelengths::Bins(vec![400.0, 500.0, 600.0, 700.0]),
        700,
    );
    let bytes = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| run(&s, &cfg)).to_bytes()
    };
    let (one, two) = (bytes(1), bytes(2));
    assert!(one == two, "1 and 2 threads differ");
    let d = scratch("det");
    let p = d.join("a.gsa");
    Accumulator::from_bytes(&one, "x")
        .unwrap()
        .write(&p)
        .unwrap();
    assert_eq!(std::fs::read(&p).unwrap(), one);
}

#[test]
fn merge_adds_runs_and_refuses_mismatches() {
    let s = shipped("thin-film-600nm.toml");
    let cfg = config(&[30.0], mono550(), 500);
    let a = run(&s, &cfg);
    let mut cfg2 = cfg.clone();
    cfg2.seed = 2;
    let b = run(&s, &cfg2);
    let mut m = a.clone();
    m.merge(&b).unwrap();
    let (ca, cb, cm) = (a.cell(0, 0), b.cell(0, 0), m.cell(0, 0));
    assert_eq!(cm.trees, ca.trees + cb.trees);
    for k in 0..cm.sum.len() {
        assert_eq!(cm.sum[k], ca.sum[k] + cb.sum[k]);
        assert_eq!(cm.sumsq[k], ca.sumsq[k] + cb.sumsq[k]);
    }
    let rm = totals(&m, 0, 0).0;
    assert!((rm - 0.5 * (totals(&a, 0, 0).0 + totals(&b, 0, 0).0)).abs() < 1e-12);
    assert_eq!(m.header.seeds, vec![1, 2]);
    assert_eq!(m.header.rays, 1000);
    // Same seed twice, different settings, different samples: refused.
    let e = m.clone().merge(&a).unwrap_err().to_string();
    assert!(e.contains("seed 1"), "{e}");
    let mut cfg3 = cfg2.clone();
    cfg3.seed = 3;
    cfg3.rho_nm = 1000.0;
    let e = a.clone().merge(&run(&s, &cfg3)).unwrap_err().to_string();
    assert!(
        e.contains("coherence_radius_nm: 5000.0 against 1000.0"),
        "{e}"
    );
    let other = shipped("rough-glass.toml");
    let e = a
        .clone()
        .merge(&run(&other, &cfg3))
        .unwrap_err()
        .to_string();
    assert!(e.contains("different samples"), "{e}");
}

/// Runs of different seeds are independent, so the replicate groups' variance estimates of
/// their sums add on merge (checked to the bit against the two runs' own); where one run
/// has too few trees for every group (512 < 1024) its per-tree spread, computed here from
/// its sums, stands in. A `.gsa` keeps the estimates through a write and a read, and a
/// header of one group or of more groups than trees is refused.
#[test]
fn merges_add_the_replicate_groups_variances_and_files_keep_them() {
    let s = shipped("rough-gold.toml");
    let cfg = config(&[30.0], mono550(), 1024);
    let a = run(&s, &cfg);
    let b = run(
        &s,
        &goniospec::simulate::SimConfig {
            seed: 2,
            ..cfg.clone()
        },
    );
    let small = run(
        &s,
        &goniospec::simulate::SimConfig {
            seed: 3,
            rays: 512,
            ..cfg.clone()
        },
    );
    assert_eq!(a.header.error_groups, goniospec::simulate::ERROR_GROUPS);
    let (ca, cb, cs) = (a.cell(0, 0), b.cell(0, 0), small.cell(0, 0));
    assert!(!ca.var.is_empty() && !cb.var.is_empty() && cs.var.is_empty());
    let mut m = a.clone();
    m.merge(&b).unwrap();
    let cm = m.cell(0, 0);
    for k in 0..cm.sum.len() {
        assert_eq!(cm.var[k], ca.var[k] + cb.var[k]);
    }
    assert_eq!(cm.r_var, ca.r_var + cb.r_var);
    let mut m2 = a.clone();
    m2.merge(&small).unwrap();
    let n = cs.trees as f64;
    for k in 0..cs.sum.len() {
        let per_tree = (cs.sumsq[k] - cs.sum[k] * cs.sum[k] / n) * n / (n - 1.0);
        let (got, want) = (m2.cell(0, 0).var[k], ca.var[k] + per_tree);
        assert!(
            (got - want).abs() <= 1e-12 * want,
            "key {k}: {got} against {want}"
        );
    }
    let back = Accumulator::from_bytes(&m.to_bytes(), "m.gsa").unwrap();
    assert_eq!(back, m);
    // A header of one group (no spread to estimate from) or of more groups than trees is
    // refused when read.
    for bad in [1, m.header.rays + 1] {
        let mut c = m.clone();
        c.header.error_groups = bad;
        let err = Accumulator::from_bytes(&c.to_bytes(), "bad.gsa")
            .err()
            .unwrap_or_else(|| panic!("error_groups {bad} was read"))
            .to_string();
        assert!(err.contains("error_groups"), "{bad}: {err}");
    }
}

#[test]
fn damaged_accumulator_files_are_refused() {
    let s = shipped("flat-soap-film.toml");
    let bytes = run(&s, &config(&[0.0], mono550(), 8)).to_bytes();
    let e = Accumulator::from_bytes(&bytes[..bytes.len() - 100], "f.gsa")
        .unwrap_err()
        .to_string();
    assert!(e.contains("truncated"), "{e}");
    let mut bad = bytes.clone();
    let n = bad.len();
    bad[n - 50] ^= 0x40;
    let e = Accumulator::from_bytes(&bad, "f.gsa")
        .unwrap_err()
        .to_string();
    assert!(e.contains("checksum mismatch"), "{e}");
    let mut magic = bytes.clone();
    magic[0] = b'X';
    let e = Accumulator::from_bytes(&magic, "f.gsa")
        .unwrap_err()
        .to_string();
    assert!(e.contains("wrong magic"), "{e}");
    let mut version = bytes.clone();
    version[8] = 99;
    let e = Accumulator::from_bytes(&version, "f.gsa")
        .unwrap_err()
        .to_string();
    assert!(e.contains("version 99"), "{e}");
    assert!(Accumulator::from_bytes(&bytes, "f.gsa").is_ok());
}

#[test]
fn accumulators_with_a_valid_checksum_but_senseless_content_are_refused() {
    // The checksum proves a file was not damaged, not that its writer made sense: a NaN
    // angle, an unknown estimator (read as beamlet before), no rays, a wrapped grid.
    let s = shipped("flat-soap-film.toml");
    let good = run(&s, &config(&[0.0], mono550(), 4));
    type Damage = Box<dyn Fn(&mut Accumulator)>;
    let cases: Vec<(&str, Damage)> = vec![
        (
            "theta_i_deg",
            Box::new(|a| a.header.settings.theta_i_deg = vec![f64::NAN]),
        ),
        ("no rays", Box::new(|a| a.header.rays = 0)),
        (
            "wavelengths",
            Box::new(|a| a.header.settings.wavelengths_nm = vec![-550.0]),
        ),
        ("non-finite", Box::new(|a| a.cells[0].r_sum = f64::NAN)),
    ];
    for (want, damage) in cases {
        let mut a = good.clone();
        damage(&mut a);
        let e = Accumulator::from_bytes(&a.to_bytes(), "x.gsa")
            .expect_err(want)
            .to_string();
        assert!(e.contains(want) && e.contains("x.gsa"), "{want}: {e}");
    }
    // Headers rewritten in the bytes, the checksum recomputed (the library's types cannot
    // hold these values, so its writer could not lay out such a file): a grid whose size
    // wraps, and an unknown estimator (read as beamlet before; now refused by name).
    let bytes = good.to_bytes();
    let fmt = goniospec::accumulate::file::FORMAT;
    let frame = goniospec::container::decode(&fmt, &bytes, "x.gsa").unwrap();
    let header = frame.header;
    for (from, to, want) in [
        ("theta_o_bins = 45", "theta_o_bins = 65536", "bucket grid"),
        ("coherence = \"beamlet\"", "coherence = \"bogus\"", "bogus"),
    ] {
        let text = header
            .replace(from, to)
            .replace("phi_o_bins = 36", "phi_o_bins = 65536");
        assert!(text.contains(to), "{from}");
        let crafted = goniospec::container::encode(&fmt, &text, frame.payload);
        let e = Accumulator::from_bytes(&crafted, "x.gsa")
            .unwrap_err()
            .to_string();
        assert!(e.contains(want) && e.contains("x.gsa"), "{from}: {e}");
    }
    // The undamaged file still reads.
    assert!(Accumulator::from_bytes(&good.to_bytes(), "x.gsa").is_ok());
}
