//! Absorbing media against independent references: thin metal films (tunnelling), bulk
//! metal, an absorbing layer inside a stack at oblique incidence (the inhomogeneous wave),
//! energy on rough gold at every depth limit, and the refusal of impossible results.
//!
//! References are written here or in tests/common (the recursive Airy TMM), never taken from
//! the library. In the plane-wave limit (`rho = inf`) with a power cutoff of 1e-20 the
//! coherent sum of a convergent ray series differs from the exact field by amplitudes of
//! order sqrt(1e-20) = 1e-10, so the tolerances below (1e-6, 1e-5 as docs/design.md §7 and the
//! issue state them) are loose against that and tight against any physics error: the old
//! real-ray-length attenuation was off by 3e-4, the old geometric TIR at sin(theta) > Re(n)
//! by 0.72 (5 nm gold at 60 degrees).

mod common;

use common::*;
use goniospec::sample::{Sample, generate};
use goniospec::simulate::{SimConfig, SimError, Wavelengths, simulate};
use num_complex::Complex64 as C;

/// Plane-wave limit, exact wavelengths, a power cutoff far below the tolerances, and
/// limits that do not cut the series.
fn exact_config(theta: &[f64], lambdas: &[f64], cutoff: f64) -> SimConfig {
    let mut cfg = config(theta, Wavelengths::Monochromatic(lambdas.to_vec()), 1);
    cfg.rho_nm = f64::INFINITY;
    cfg.limits.cutoff = cutoff;
    cfg.limits.max_depth = 5000;
    cfg.limits.max_segments = 50_000_000;
    cfg
}

/// (R, T, absorbed, dropped) of cell (i, j).
fn rtad(acc: &goniospec::accumulate::file::Accumulator, i: usize, j: usize) -> [f64; 4] {
    let (r, t) = totals(acc, i, j);
    let c = acc.cell(i, j);
    let n = c.trees as f64;
    [r, t, c.absorbed / n, c.dropped / n]
}

fn metal(n: f64, k: f64) -> String {
    format!("[media.air]\nn = 1.0\n[media.metal]\nn = {n:?}\nk = {k:?}\n")
}

/// Gold (Johnson & Christy 1972, as in data/au-johnson.csv) at three wavelengths, as
/// constant indices so the reference can use the same numbers.
const GOLD: [(f64, f64, f64); 3] = [
    (450.0, 1.38, 1.92),
    (550.0, 0.43, 2.455),
    (650.0, 0.166, 3.15),
];

#[test]
fn thin_gold_films_tunnel_as_the_independent_tmm_says() {
    let thetas = [0.0, 30.0, 60.0];
    for &(lambda, n, k) in &GOLD {
        for d in [5.0, 20.0, 50.0] {
            let s = stack_sample("gold-film", &metal(n, k), "air", &[("metal", d)], "air");
            let acc = run(&s, &exact_config(&thetas, &[lambda], 1e-20));
            for (i, th) in thetas.iter().enumerate() {
                let [r, t, a, dropped] = rtad(&acc, i, 0);
                let (rr, tt) = tmm_ref(
                    &[c(1.0, 0.0), c(n, k), c(1.0, 0.0)],
                    &[d],
                    lambda,
                    th.to_radians(),
                );
                let aa = 1.0 - rr - tt;
                let msg = format!(
                    "{d} nm gold at {lambda} nm, {th} deg: R {r} T {t} A {a} (dropped {dropped:.1e}) vs TMM {rr} {tt} {aa}"
                );
                assert!((r - rr).abs() < 1e-6, "{msg}");
                assert!((t - tt).abs() < 1e-6, "{msg}");
                assert!((a - aa).abs() < 1e-6, "{msg}");
            }
        }
    }
}

/// Unpolarised Fresnel reflectance from vacuum onto complex `n2` (Born & Wolf §14.2),
/// written independently of the library.
fn fresnel_r(n2: C, theta: f64) -> f64 {
    let (rp, rs) = fresnel_amplitudes(C::new(1.0, 0.0), n2, theta);
    0.5 * (rs.norm_sqr() + rp.norm_sqr())
}

#[test]
fn bulk_gold_reflects_as_fresnel_and_transmits_nothing() {
    let thetas: Vec<f64> = (0..=8).map(|i| 10.0 * i as f64).collect();
    for &(lambda, n, k) in &GOLD {
        let s = stack_sample("bulk-gold", &metal(n, k), "air", &[], "metal");
        // The default settings: a user's run, not only the plane-wave limit.
        let acc = run(
            &s,
            &config(&thetas, Wavelengths::Monochromatic(vec![lambda]), 16),
        );
        for (i, th) in thetas.iter().enumerate() {
            let [r, t, a, _] = rtad(&acc, i, 0);
            let want = fresnel_r(C::new(n, k), th.to_radians());
            assert!(
                (r - want).abs() < 1e-9,
                "{lambda} nm, {th} deg: R {r} vs Fresnel {want}"
            );
            // A semi-infinite absorbing substrate: nothing reaches the tile's exit plane.
            assert_eq!(t, 0.0, "{lambda} nm, {th} deg: T through bulk gold");
            assert!(
                (a - (1.0 - want)).abs() < 1e-9,
                "{lambda} nm, {th} deg: A {a}"
            );
        }
    }
}

#[test]
fn an_absorbing_layer_inside_a_stack_matches_tmm_where_the_series_converges() {
    // air | SiO2 90 nm | absorber (2.0 + 0.3i) 40 nm | TiO2 60 nm | MgF2 100 nm | glass.
    let media = "[media.air]\nn = 1.0\n[media.sio2]\nn = 1.46\n[media.abs]\nn = 2.0\nk = 0.3\n[media.tio2]\nn = 2.4\n[media.mgf2]\nn = 1.38\n[media.glass]\nn = 1.52\n";
    let layers = [
        ("sio2", 90.0),
        ("abs", 40.0),
        ("tio2", 60.0),
        ("mgf2", 100.0),
    ];
    let s = stack_sample("abs-stack", media, "air", &layers, "glass");
    let n = [
        c(1.0, 0.0),
        c(1.46, 0.0),
        c(2.0, 0.3),
        c(2.4, 0.0),
        c(1.38, 0.0),
        c(1.52, 0.0),
    ];
    let d: Vec<f64> = layers.iter().map(|l| l.1).collect();
    // Up to 30 degrees the ray series of this high-contrast stack converges to 1e-6 with a
    // 1e-16 cutoff; further out it converges too slowly for 1e-5 (measured 1e-5 at 50,
    // 1e-4 at 70, 7e-4 at 80 degrees): flat multilayers at grazing incidence are what
    // coatings (the transfer matrix at the interface) are for. The old attenuation along
    // the real ray length missed by 3e-4 already at 30 degrees.
    let thetas = [0.0, 10.0, 20.0, 30.0];
    let lambdas = [450.0, 550.0, 650.0];
    let acc = run(&s, &exact_config(&thetas, &lambdas, 1e-16));
    for (i, th) in thetas.iter().enumerate() {
        for (j, &l) in lambdas.iter().enumerate() {
            let [r, t, a, dropped] = rtad(&acc, i, j);
            let (rr, tt) = tmm_ref(&n, &d, l, th.to_radians());
            let aa = 1.0 - rr - tt;
            let msg = format!(
                "{th} deg, {l} nm: R {r} T {t} A {a} (dropped {dropped:.1e}) vs TMM {rr} {tt} {aa}"
            );
            assert!((r - rr).abs() < 1e-5, "{msg}");
            assert!((t - tt).abs() < 1e-5, "{msg}");
            assert!((a - aa).abs() < 1e-5, "{msg}");
        }
    }
}

/// Runs a rough gold sample at several depth limits (same seed, so the same trees) and
/// checks that every run is accepted, R <= 1, A >= 0, nothing is transmitted, and that the
/// results converge with depth: a deeper run differs from a shallower one by at most what
/// the shallower one dropped can change coherently, `2 sqrt(D R) + D` (Cauchy-Schwarz), plus
/// rounding. The old tracer failed each: R 0.30 at depth 8, 11.7 at 16, 169,391 at 32.
fn gold_energy_at_depths(s: &Sample, rays: u64, depths: &[u32]) {
    let thetas = [0.0, 30.0, 60.0];
    let lambdas = [450.0, 550.0, 650.0];
    let mut runs = Vec::new();
    for &depth in depths {
        let mut cfg = config(&thetas, Wavelengths::Monochromatic(lambdas.to_vec()), rays);
        cfg.limits.max_depth = depth;
        let acc = simulate(s, &cfg, &|_| {})
            .unwrap_or_else(|e| panic!("depth {depth}: the run was refused: {e}"))
            .0;
        for i in 0..thetas.len() {
            for j in 0..lambdas.len() {
                let [r, t, a, dropped] = rtad(&acc, i, j);
                let at = format!("{}: depth {depth}, cell ({i}, {j})", s.name);
                assert!(r <= 1.0 && r > 0.0, "{at}: R {r}");
                assert!(a >= -1e-9, "{at}: absorbed {a}");
                assert!(t.abs() < 1e-5, "{at}: T {t} through bulk gold");
                assert!(dropped >= 0.0, "{at}: dropped {dropped}");
            }
        }
        runs.push(acc);
    }
    let deepest = runs.last().unwrap();
    for (acc, depth) in runs.iter().zip(depths) {
        for i in 0..thetas.len() {
            for j in 0..lambdas.len() {
                let [r, _, _, d] = rtad(acc, i, j);
                let [r_deep, _, _, d_deep] = rtad(deepest, i, j);
                let bound = 2.0 * (d * r).sqrt() + d + 2.0 * (d_deep * r_deep).sqrt() + d_deep;
                assert!(
                    (r - r_deep).abs() <= bound + 1e-9,
                    "{}: depth {depth} R {r} vs deepest {r_deep}: more than the dropped power {d:.2e} explains ({bound:.2e})",
                    s.name
                );
            }
        }
    }
}

#[test]
fn rough_gold_conserves_energy_at_every_depth_limit() {
    let s = goniospec::sample::load(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes/rough-gold.toml"),
        Default::default(),
    )
    .unwrap();
    gold_energy_at_depths(&s, 600, &[8, 32, 128]);
}

#[test]
fn steep_ggx_gold_conserves_energy_at_every_depth_limit() {
    // The worst case: GGX alpha 0.5 over gold, with thin gold wedges.
    let mesh = generate::microfacet_surface(
        7,
        [20_000.0, 20_000.0],
        100,
        generate::Distribution::Ggx,
        0.5,
        2500.0,
        0.0,
    )
    .unwrap();
    let d = scratch("ggx-gold");
    mesh.write_obj(&d.join("g.obj"), 1.0, "ggx").unwrap();
    let s = sample_in(
        &d,
        &format!(
            "[sample]\nname = \"ggx 0.5 gold\"\nunit = \"nm\"\ntile = [20000.0, 20000.0]\n[media.air]\nn = 1.0\n[media.gold]\ntable = \"{}\"\n[[interface]]\nmesh = \"g.obj\"\nfront = \"air\"\nback = \"gold\"\n",
            std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("data/au-johnson.csv")
                .display()
        ),
    );
    gold_energy_at_depths(&s, 400, &[8, 32, 128]);
}

/// A 0.5 nm film of index `n + i k` in air at normal incidence.
fn subnm_film(n: f64, k: f64) -> Sample {
    stack_sample("subnm", &metal(n, k), "air", &[("metal", 0.5)], "air")
}

/// A meshed 5-pair quarter-wave mirror: its ray series does not converge (the issue's
/// spectral radius 1.10); at the default limits 83 % of the power is cut.
fn meshed_mirror_toml() -> String {
    let (media, layers) = quarter_wave_mirror(5);
    stack_toml("meshed mirror", "mesh", media, &layers, "glass")
}

/// A 0.5 nm gold-like film (0.166 + 3.15i) at 650 nm: as a ray series its internal
/// reflections decay slowly (about 300 round trips; at the default depth 64 it lost 1e-3 of
/// the power to the limit). The tracer hands such a film to the transfer matrix at its
/// local thickness (`trace::film`), so it is exact with nothing cut, at any angle.
#[test]
fn a_sub_nm_meshed_metal_film_is_exact_through_the_local_film() {
    let s = subnm_film(0.166, 3.15);
    let thetas = [0.0, 45.0, 80.0];
    let acc = run(&s, &exact_config(&thetas, &[650.0], 1e-10));
    for (i, th) in thetas.iter().enumerate() {
        let (rr, tt) = tmm_ref(
            &[c(1.0, 0.0), c(0.166, 3.15), c(1.0, 0.0)],
            &[0.5],
            650.0,
            th.to_radians(),
        );
        let [r, t, _, d] = rtad(&acc, i, 0);
        assert!(
            (r - rr).abs() < 1e-6 && (t - tt).abs() < 1e-6 && d == 0.0,
            "{th} deg: R {r} T {t} (dropped {d}) against the TMM's {rr} {tt}"
        );
    }
    // The film's coefficients change with the wavelength: one traced tree cannot serve
    // several, and a run that asks for that is refused with the reason.
    let mut cfg = exact_config(&[0.0], &[550.0, 650.0], 1e-10);
    cfg.path_sharing = Some(true);
    match simulate(&s, &cfg, &|_| {}) {
        Err(SimError::Config(m)) => assert!(m.contains("absorbing medium"), "{m}"),
        other => panic!("path sharing was not refused: {:?}", other.map(|_| ())),
    }
}

/// A slowly converging series: a 0.5 nm lossless film of index 100 (a numerical stand-in:
/// its faces reflect 0.96 of the power, so the series needs hundreds of round trips; metal
/// films, which did the same, are now taken by the transfer matrix).
#[test]
fn a_slowly_converging_meshed_film_reports_its_cut_power_and_converges_with_depth() {
    let s = subnm_film(100.0, 0.0);
    let (rr, tt) = tmm_ref(
        &[c(1.0, 0.0), c(100.0, 0.0), c(1.0, 0.0)],
        &[0.5],
        650.0,
        0.0,
    );
    // At the default depth 64 the series is cut: the cut power is reported, and R and T
    // are off by less than its coherent bound.
    let mut cfg = exact_config(&[0.0], &[650.0], 1e-10);
    cfg.limits.max_depth = 64;
    let (acc, stats) = simulate(&s, &cfg, &|_| {}).unwrap();
    let cut = stats.worst_limit_dropped(&acc);
    let [r, t, _, d] = rtad(&acc, 0, 0);
    assert!(cut > 1e-3, "the depth limit should cut this series: {cut}");
    let bound = 2.0 * (d * (r + t)).sqrt() + d;
    assert!(
        (r - rr).abs() < bound && (t - tt).abs() < bound,
        "R {r} T {t} vs {rr} {tt}"
    );
    // The per-tree bound the warning prints (issue 25: the aggregate one was about 100
    // times the change) is never above the aggregate one and still bounds the change.
    let (per_tree, _) = stats.worst_limit_bound(&acc);
    assert!(per_tree <= bound * (1.0 + 1e-12), "{per_tree} > {bound}");
    assert!(
        (r - rr).abs() <= per_tree && (t - tt).abs() <= per_tree,
        "R {r} T {t} vs {rr} {tt}: beyond the per-tree bound {per_tree}"
    );
    // Deep enough, it converges to the TMM.
    cfg.limits.max_depth = 400;
    let acc = run(&s, &cfg);
    let [r, t, _, _] = rtad(&acc, 0, 0);
    assert!(
        (r - rr).abs() < 1e-4 && (t - tt).abs() < 1e-4,
        "R {r} T {t} vs {rr} {tt}"
    );
}

#[test]
fn a_ray_series_that_cannot_converge_is_refused_not_printed() {
    let d = scratch("mirror-refuse");
    let s = sample_in(&d, &meshed_mirror_toml());
    let mut cfg = config(&[0.0], Wavelengths::Monochromatic(vec![550.0]), 2);
    match simulate(&s, &cfg, &|_| {}) {
        Err(SimError::Unphysical(m)) => {
            for want in [
                "meshed mirror",
                "theta_i 0 deg",
                "lambda 550 nm",
                "did not converge",
                "coating",
                "--allow-unphysical",
            ] {
                assert!(m.contains(want), "message lacks '{want}': {m}");
            }
        }
        Err(e) => panic!("refused for the wrong reason: {e}"),
        Ok(_) => panic!("an unconverged result was accepted"),
    }
    // For debugging the result can still be had, explicitly.
    cfg.allow_unphysical = true;
    assert!(simulate(&s, &cfg, &|_| {}).is_ok());
}

#[test]
fn the_cli_refuses_an_impossible_result_with_exit_1_and_no_file() {
    let d = scratch("refuse-cli");
    std::fs::write(d.join("s.toml"), meshed_mirror_toml()).unwrap();
    let out = d.join("o.gsa");
    let run = |extra: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_goniospec"))
            .args([
                "simulate",
                "s.toml",
                "--theta-i",
                "0",
                "--wavelengths",
                "550",
            ])
            .args(["--monochromatic", "--rays", "2"])
            .args(["-o", "o.gsa"])
            .args(extra)
            .current_dir(&d)
            .output()
            .unwrap()
    };
    let o = run(&[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("did not converge") && err.contains("meshed mirror"),
        "{err}"
    );
    assert!(!out.exists(), "an impossible result was written");
    let o = run(&["--allow-unphysical"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.exists());
    assert!(String::from_utf8_lossy(&o.stderr).contains("warning (--allow-unphysical)"));
}

#[test]
fn an_absorbing_ambient_medium_is_refused() {
    let s = stack_sample("murky", &metal(1.3, 0.01), "metal", &[], "air");
    let Err(err) = simulate(
        &s,
        &config(&[0.0], Wavelengths::Monochromatic(vec![500.0]), 2),
        &|_| {},
    ) else {
        panic!("an absorbing ambient medium was accepted");
    };
    assert!(err.to_string().contains("lossless ambient"), "{err}");
}
