//! Where methods break: phase precision far from the origin, the local-film reference of
//! wedged films, the study's stress sweeps and the scene-driven render plan.

mod common;

use common::*;
use goniospec::accumulate::PhasePrecision;
use goniospec::render::{Env, Light, RenderConfig, Shape};
use goniospec::simulate::Wavelengths;

/// f64 phases are exact wherever the sample sits; f32 phases are too once the sample is a
/// metre from the world origin (an f32 resolves 64 nm there). Reference: the independent
/// TMM of tests/common.
#[test]
fn f32_phases_fail_far_from_the_origin_and_f64_phases_do_not() {
    let s = stack_sample(
        "prec",
        "[media.air]\nn = 1.0\n[media.soap]\nn = 1.33\n",
        "air",
        &[("soap", 600.0)],
        "air",
    );
    let lambdas = [450.0, 550.0, 650.0];
    let theta = 30.0f64;
    let worst = |precision: PhasePrecision, origin: f64, coherence| {
        let mut cfg = config(&[theta], Wavelengths::Monochromatic(lambdas.to_vec()), 128);
        cfg.rho_nm = f64::INFINITY;
        cfg.coherence = coherence;
        cfg.precision = precision;
        cfg.origin_nm = glam::DVec3::new(origin, origin, 0.0);
        // f32 phases far from the origin are the failure this test shows: keep the result.
        cfg.allow_unphysical = true;
        let acc = run(&s, &cfg);
        lambdas
            .iter()
            .enumerate()
            .map(|(j, &l)| {
                let (r, _) = totals(&acc, 0, j);
                let (reference, _) = tmm_ref(
                    &[c(1.0, 0.0), c(1.33, 0.0), c(1.0, 0.0)],
                    &[600.0],
                    l,
                    theta.to_radians(),
                );
                (r - reference).abs()
            })
            .fold(0.0, f64::max)
    };
    use goniospec::accumulate::Coherence::{Beamlet, Bucket};
    for mode in [Beamlet, Bucket] {
        let f64_far = worst(PhasePrecision::F64, 1e9, mode);
        let f32_near = worst(PhasePrecision::F32, 0.0, mode);
        let f32_far = worst(PhasePrecision::F32, 1e9, mode);
        eprintln!(
            "{mode:?}: f64 at 1 m {f64_far:.2e}, f32 at 0 {f32_near:.2e}, f32 at 1 m {f32_far:.2e}"
        );
        assert!(f64_far < 1e-5, "{mode:?}: f64 at 1 m is off by {f64_far}");
        assert!(
            f32_near < 1e-4,
            "{mode:?}: f32 at the origin is off by {f32_near}"
        );
        assert!(
            f32_far > 10.0 * f32_near.max(1e-5),
            "{mode:?}: f32 at 1 m ({f32_far}) should be far worse than at the origin"
        );
    }
}

/// The local-film reference of a wedge against the same average written out here: the
/// entry point's hit on the tilted face, found by bisection, the local angle and the
/// thickness along the face normal, each through the independent TMM.
#[test]
fn local_film_reference_of_a_wedge_matches_an_independent_average() {
    let s = goniospec::sample::load(
        &root().join("studies/samples/wedge-film.toml"),
        Default::default(),
    )
    .unwrap();
    let (lx, slope, z0) = (40_000.0f64, 0.5f64.to_radians().tan(), 675.0f64);
    // Top: z0 - slope |x - Lx/2| (slope_deg = -0.5 in the file), bottom z = 0.
    let top = |x: f64| {
        let xm = x.rem_euclid(lx);
        z0 - slope * (xm - lx / 2.0).abs()
    };
    let edges = [500.0, 520.0, 600.0];
    for theta_deg in [0.0f64, 40.0] {
        let lib = goniospec::reference::local_film::reflectance(&s, theta_deg, &edges, 40).unwrap();
        let th = theta_deg.to_radians();
        let n = 400;
        let mut sum = [0.0; 2];
        for i in 0..n {
            let xe = (i as f64 + 0.5) / n as f64 * lx;
            let z_start = z0 + 1.0;
            let (mut lo, mut hi) = (0.0, 2.0 * z_start / th.cos());
            for _ in 0..100 {
                let t = 0.5 * (lo + hi);
                if z_start - t * th.cos() > top(xe + t * th.sin()) {
                    lo = t;
                } else {
                    hi = t;
                }
            }
            let xh = (xe + lo * th.sin()).rem_euclid(lx);
            let zh = top(xh);
            // Face normal (up): the face descends away from the centre.
            let sign = if xh > lx / 2.0 { 1.0 } else { -1.0 };
            let alpha = slope.atan();
            let nrm = [sign * alpha.sin(), 0.0, alpha.cos()];
            let cos_local = th.cos() * nrm[2] - th.sin() * nrm[0];
            let thick = zh / nrm[2];
            for (b, w) in edges.windows(2).enumerate() {
                let (r, _) = tmm_band(
                    |_| vec![c(1.0, 0.0), c(1.33, 0.0), c(1.0, 0.0)],
                    &[thick],
                    w[0],
                    w[1],
                    cos_local.acos(),
                );
                sum[b] += r;
            }
        }
        for b in 0..2 {
            let reference = sum[b] / n as f64;
            eprintln!(
                "theta {theta_deg}, bin {b}: library {} vs {reference}",
                lib[b]
            );
            assert!(
                (lib[b] - reference).abs() < 2e-4,
                "theta {theta_deg} bin {b}: {} vs {reference}",
                lib[b]
            );
        }
    }
}

/// The stress studies load, sweep what they say, and the report names what breaks: the
/// depth limit at 89 degrees (the internal angle a hair below critical) and a bucket edge
/// exactly on the 80-degree specular direction.
#[test]
fn grazing_study_reports_the_depth_limit_and_the_bucket_edge() {
    let st = goniospec::study::load(&root().join("studies/grazing.toml")).unwrap();
    let (points, reference) = goniospec::study::run(&st, |_| {}).unwrap();
    let find = |coh: &str, rho: f64, bins: u32, depth: u32| {
        points
            .iter()
            .filter(|p| {
                p.variant.coherence.name() == coh
                    && (p.variant.radius == rho || coh != "beamlet")
                    && p.variant.theta_o_bins == bins
                    && p.variant.max_depth == depth
            })
            .max_by_key(|p| p.rays)
            .unwrap()
            .error
    };
    let inf = f64::INFINITY;
    // The plane-wave beamlet estimator needs the deeper trees at 89 degrees.
    assert!(find("beamlet", inf, 45, 64) > 1e-4);
    assert!(find("beamlet", inf, 45, 1024) < 1e-4);
    // Bucket superposition splits the specular partial waves on a bucket edge.
    assert!(find("bucket", 5000.0, 45, 1024) > 0.05);
    assert!(find("bucket", 5000.0, 44, 1024) < 1e-3);
    let d = scratch("grazing-out");
    goniospec::study::write(&st, &points, &reference, &d).unwrap();
    let report = std::fs::read_to_string(d.join("report.md")).unwrap();
    assert!(
        report.contains("- breaks: `bucket rho=5000 bins=45"),
        "{report}"
    );
    assert!(
        report.contains("- holds: `bucket rho=5000 bins=44"),
        "{report}"
    );
}

#[test]
fn bad_stress_sweeps_are_refused_with_clear_errors() {
    let d = scratch("stress-bad");
    let base = format!(
        "[study]\nname = \"x\"\nsample = \"{}\"\ntheta_i = [0.0]\nwavelengths = \"400:700:100\"\n",
        root().join("meshes/flat-soap-film.toml").display()
    );
    for (body, want) in [
        (
            "[sweep]\nrays = [10]\nphase = [\"f16\"]\n",
            "unknown phase precision 'f16'",
        ),
        (
            "[sweep]\nrays = [10]\ncutoff = [1.5]\n",
            "cutoff 1.5 must lie in [0, 1)",
        ),
        (
            "[sweep]\nrays = [10]\nmax_depth = []\n",
            "[sweep] max_depth is empty",
        ),
        (
            "[sweep]\nrays = [10]\nmax_depth = [0]\n",
            "max_depth must be positive",
        ),
        (
            "[sweep]\nrays = [10]\ncoherence_radius_nm = [-5.0]\n",
            "must be positive",
        ),
        (
            "[sweep]\nrays = [10]\n[area]\ntiles = [[2, 0]]\nrays = 5\n",
            "[area] tiles",
        ),
    ] {
        std::fs::write(d.join("s.toml"), format!("{base}{body}")).unwrap();
        let e = goniospec::study::load(&d.join("s.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.contains(want), "{body}: {e}");
    }
    std::fs::write(
        d.join("s.toml"),
        format!("{}reference = \"oracle\"\n[sweep]\nrays = [10]\n", base),
    )
    .unwrap();
    let e = goniospec::study::load(&d.join("s.toml"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("reference 'oracle'"), "{e}");
    // A rectangular tiling is accepted.
    std::fs::write(
        d.join("s.toml"),
        format!("{base}[sweep]\nrays = [10]\n[area]\ntiles = [1, [5, 2]]\nrays = 5\n"),
    )
    .unwrap();
    let st = goniospec::study::load(&d.join("s.toml")).unwrap();
    let tiles: Vec<[usize; 2]> = st.area.unwrap().tiles.iter().map(|t| t.counts()).collect();
    assert_eq!(tiles, vec![[1, 1], [5, 2]]);
}

fn render_cfg(light: Light, env: Env) -> RenderConfig {
    RenderConfig {
        width: 48,
        height: 48,
        spp: 1,
        light,
        light_strength: 1.0,
        env,
        env_strength: 1.0,
        camera: glam::DVec3::new(0.0, -5.0, 3.0),
        fov_deg: 40.0,
        seed: 1,
    }
}

/// A flat panel under a directional light at 30 degrees needs only the grid angles around
/// 30; a constant environment adds the viewing angles, computed here from the camera
/// geometry; a sky needs everything.
#[test]
fn render_plan_asks_for_the_angles_the_image_queries() {
    use goniospec::render::plan::plan;
    let grid: Vec<f64> = (0..18).map(|k| 5.0 * k as f64).collect();
    let light = Light::Directional(goniospec::geom::from_spherical(30f64.to_radians(), 0.4));
    let p = plan(&Shape::Plane, &render_cfg(light, Env::None), &grid);
    assert!(p.object_pixels > 100);
    assert_eq!(p.needed(), vec![25.0, 30.0, 35.0]);
    // Viewing angles over the panel: from the camera at (0, -5, 3) to the corners and
    // edges of [-1, 1]^2, theta_o = acos(3 / distance).
    let cfg = render_cfg(Light::None, Env::Constant);
    let view = |x: f64, y: f64| {
        let d = ((x * x) + (y + 5.0).powi(2) + 9.0f64).sqrt();
        (3.0 / d).acos().to_degrees()
    };
    let (lo, hi) = (view(0.0, -1.0), view(1.0, 1.0));
    let needed = plan(&Shape::Plane, &cfg, &grid).needed();
    assert!(needed.len() < grid.len());
    assert!(*needed.first().unwrap() <= lo && *needed.last().unwrap() >= hi);
    assert!(*needed.first().unwrap() > lo - 10.0 && *needed.last().unwrap() < hi + 10.0);
    let sky = plan(&Shape::Sphere, &render_cfg(Light::None, Env::Sky), &grid);
    assert_eq!(sky.needed(), grid);
}

/// The library's scene-driven simulation: it simulates exactly the planned angles, the
/// saving it reports is the arithmetic of its budgets (a one-batch budget of one 64-tree
/// block: every needed direction spends 64 trees, so the bound is `64 x grid`), and bad
/// budgets or an
/// unlit image are refused before anything runs.
#[test]
fn scene_driven_simulation_runs_only_the_planned_angles() {
    use goniospec::render::plan::{SceneBudget, SceneError, simulate_scene};
    let light = Light::Directional(goniospec::geom::from_spherical(30f64.to_radians(), 0.4));
    let cfg = render_cfg(light, Env::None);
    let budget = SceneBudget {
        theta_step_deg: 5.0,
        rays: 64,
        max_rays: 64,
        tolerance: 0.05,
        target_stderr: None,
        seed: 3,
        wavelengths: Wavelengths::Monochromatic(vec![550.0]),
    };
    let plan = budget.plan(&Shape::Plane, &cfg).unwrap();
    assert_eq!(plan.needed(), vec![25.0, 30.0, 35.0]);
    let s = shipped("flat-soap-film.toml");
    let run = simulate_scene(&s, plan, &budget, &|_| {}).unwrap();
    assert_eq!(run.acc.header.settings.theta_i_deg, vec![25.0, 30.0, 35.0]);
    assert_eq!(run.spent(), 3 * 64);
    assert_eq!(run.full_hemisphere_bound(), 64 * 18);
    let (saved, skipped) = run.saving_percent();
    assert!((saved - 100.0 * 15.0 / 18.0).abs() < 1e-9, "{saved}");
    assert!((skipped - 100.0 * 15.0 / 18.0).abs() < 1e-9, "{skipped}");
    for bad in [
        SceneBudget {
            theta_step_deg: 90.0,
            ..budget.clone()
        },
        SceneBudget {
            rays: 0,
            ..budget.clone()
        },
        SceneBudget {
            max_rays: 32,
            ..budget.clone()
        },
        SceneBudget {
            tolerance: f64::NAN,
            ..budget.clone()
        },
        SceneBudget {
            target_stderr: Some(1.5),
            ..budget.clone()
        },
    ] {
        assert!(matches!(
            bad.plan(&Shape::Plane, &cfg),
            Err(SceneError::Budget(_))
        ));
    }
    let dark = render_cfg(Light::None, Env::None);
    assert!(matches!(
        budget.plan(&Shape::Plane, &dark),
        Err(SceneError::NothingNeeded)
    ));
}

/// `SimConfig::cancel`: a run whose flag is set stops and returns `Cancelled`, never a
/// partial accumulator.
#[test]
fn a_cancelled_run_returns_no_result() {
    use std::sync::Arc;
    use std::sync::atomic::AtomicBool;
    let s = shipped("rough-gold.toml");
    let mut cfg = config(
        &[0.0, 30.0],
        Wavelengths::Monochromatic(vec![550.0]),
        100_000,
    );
    cfg.cancel = Some(Arc::new(AtomicBool::new(true)));
    let t0 = std::time::Instant::now();
    assert!(matches!(
        goniospec::simulate::simulate(&s, &cfg, &|_| {}),
        Err(goniospec::simulate::SimError::Cancelled)
    ));
    assert!(t0.elapsed().as_secs() < 5);
}

/// The library refuses non-finite geometry settings before tracing (a NaN or infinite ray
/// would reach Embree, which aborts on it).
#[test]
fn non_finite_incidence_and_origin_are_refused() {
    let s = shipped("rough-gold.toml");
    let mut cfg = config(&[0.0], Wavelengths::Monochromatic(vec![550.0]), 16);
    cfg.phi_i_deg = f64::INFINITY;
    // Typed: the error names the setting, whatever front end words it.
    let e = goniospec::simulate::simulate(&s, &cfg, &|_| {}).unwrap_err();
    assert!(
        matches!(
            e,
            goniospec::simulate::SimError::Setting { key: "phi_i", .. }
        ),
        "{e}"
    );
    cfg.phi_i_deg = 0.0;
    cfg.origin_nm = glam::DVec3::new(f64::NAN, 0.0, 0.0);
    let e = goniospec::simulate::simulate(&s, &cfg, &|_| {}).unwrap_err();
    assert!(
        matches!(
            e,
            goniospec::simulate::SimError::Setting {
                key: "origin_nm",
                ..
            }
        ),
        "{e}"
    );
}
