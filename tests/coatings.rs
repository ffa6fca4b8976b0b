//! Coatings: thin layers carried by an interface and applied through their transfer-matrix
//! coefficients (docs/physics.md), against the independent recursive TMM of tests/common.
//! A flat coated interface gives one reflected and one transmitted exit per tree, so the
//! result is exact whatever the beamlet radius; the tolerance 1e-6 is rounding headroom
//! (both sides are closed forms of the same physics computed along different routes).

mod common;

use common::*;
use goniospec::sample::Sample;
use goniospec::simulate::{SimError, Wavelengths, simulate};

/// A `[stack]` sample in its default mode (one coated interface).
fn coated_stack(tag: &str, media: &str, layers: &[(&str, f64)], substrate: &str) -> Sample {
    sample_from(tag, &stack_toml(tag, "coating", media, layers, substrate))
}

/// Runs `s` at `thetas` x `lambdas` (exact wavelengths) with beamlet radius `rho` and
/// checks R, T and A against the independent TMM for indices `n` and thicknesses `d`.
fn check_against_tmm(s: &Sample, n: &[C], d: &[f64], thetas: &[f64], lambdas: &[f64], rho: f64) {
    let mut cfg = config(thetas, Wavelengths::Monochromatic(lambdas.to_vec()), 4);
    cfg.rho_nm = rho;
    let acc = run(s, &cfg);
    for (i, th) in thetas.iter().enumerate() {
        for (j, &l) in lambdas.iter().enumerate() {
            let (r, t) = totals(&acc, i, j);
            let cell = acc.cell(i, j);
            let a = cell.absorbed / cell.trees as f64;
            let (rr, tt) = tmm_ref(n, d, l, th.to_radians());
            let msg = format!(
                "{}: rho {rho}, {th} deg, {l} nm: R {r} T {t} A {a} vs TMM {rr} {tt} {}",
                s.name,
                1.0 - rr - tt
            );
            assert!((r - rr).abs() < 1e-6, "{msg}");
            assert!((t - tt).abs() < 1e-6, "{msg}");
            assert!((a - (1.0 - rr - tt)).abs() < 1e-6, "{msg}");
        }
    }
}

type C = num_complex::Complex64;

#[test]
fn quarter_wave_mirrors_match_the_tmm_at_any_angle_and_radius() {
    // (HL)^N, n = 2.4 / 1.46, on glass 1.52, centred at 550 nm: the multilayer whose meshed
    // ray series cannot converge (spectral radius > 1 for N >= 5).
    for pairs in [5usize, 10] {
        let (media, layers) = quarter_wave_mirror(pairs);
        let mut n = vec![c(1.0, 0.0)];
        n.extend(
            layers
                .iter()
                .map(|(m, _)| c(if *m == "h" { 2.4 } else { 1.46 }, 0.0)),
        );
        n.push(c(1.52, 0.0));
        let d: Vec<f64> = layers.iter().map(|l| l.1).collect();
        let s = coated_stack(&format!("mirror{pairs}"), media, &layers, "glass");
        let lambdas: Vec<f64> = (0..=12).map(|i| 400.0 + 25.0 * i as f64).collect();
        for rho in [1000.0, 5000.0, f64::INFINITY] {
            check_against_tmm(&s, &n, &d, &[0.0, 30.0, 60.0], &lambdas, rho);
        }
    }
}

#[test]
fn thin_gold_coatings_tunnel_and_absorb_as_the_tmm_says() {
    for (lambda, nr, k) in [
        (450.0, 1.38, 1.92),
        (550.0, 0.43, 2.455),
        (650.0, 0.166, 3.15),
    ] {
        for thickness in [5.0, 20.0, 50.0] {
            let s = coated_stack(
                "gold-coating",
                &format!("[media.air]\nn = 1.0\n[media.gold]\nn = {nr:?}\nk = {k:?}\n"),
                &[("gold", thickness)],
                "air",
            );
            check_against_tmm(
                &s,
                &[c(1.0, 0.0), c(nr, k), c(1.0, 0.0)],
                &[thickness],
                &[0.0, 30.0, 60.0],
                &[lambda],
                5000.0,
            );
        }
    }
}

#[test]
fn a_coated_interface_from_below_uses_the_reversed_stack() {
    // Light from the glass side of an asymmetric coating (glass | TiO2 | MgF2 | air seen
    // from below) must see the layers in reverse order: compare with a stack written the
    // other way up, ambient glass, which the TMM handles as usual.
    let up = sample_from(
        "coat-up",
        "[sample]\nname = \"coat-up\"\nunit = \"nm\"\ntile = [20000.0, 20000.0]\n[media.air]\nn = 1.0\n[media.tio2]\nn = 2.4\n[media.mgf2]\nn = 1.38\n[media.glass]\nn = 1.52\n[[interface]]\ngenerator = { kind = \"flat\" }\nfront = \"glass\"\nback = \"air\"\ncoating = [ { medium = \"tio2\", thickness = 60.0 }, { medium = \"mgf2\", thickness = 100.0 } ]\n",
    );
    // The interface's front side (glass) faces up: glass is the ambient, air the
    // substrate, and the layers lie on the glass side, TiO2 outermost.
    check_against_tmm(
        &up,
        &[c(1.52, 0.0), c(2.4, 0.0), c(1.38, 0.0), c(1.0, 0.0)],
        &[60.0, 100.0],
        &[0.0, 20.0, 40.0],
        &[450.0, 550.0, 650.0],
        5000.0,
    );
}

#[test]
fn coatings_refuse_path_sharing_and_bad_modes() {
    let s = coated_stack(
        "share",
        "[media.air]\nn = 1.0\n[media.f]\nn = 1.38\n[media.glass]\nn = 1.52\n",
        &[("f", 100.0)],
        "glass",
    );
    let mut cfg = config(&[0.0], Wavelengths::Monochromatic(vec![500.0]), 2);
    cfg.path_sharing = Some(true);
    match simulate(&s, &cfg, &|_| {}) {
        Err(SimError::Config(m)) => assert!(m.contains("coatings"), "{m}"),
        other => panic!("expected a configuration error, got {:?}", other.err()),
    }
    let d = scratch("badmode");
    std::fs::write(
        d.join("s.toml"),
        "[sample]\nname = \"x\"\nunit = \"nm\"\ntile = [10.0, 10.0]\n[media.air]\nn = 1.0\n[stack]\nmode = \"meshy\"\nambient = \"air\"\nsubstrate = \"air\"\n",
    )
    .unwrap();
    let e = goniospec::sample::load(&d.join("s.toml"), Default::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("meshy") && e.contains(":8"), "{e}");
}

#[test]
fn a_pure_stack_is_coated_and_a_binder_stack_is_meshed_by_default() {
    let s = coated_stack(
        "pure",
        "[media.air]\nn = 1.0\n[media.f]\nn = 1.38\n[media.glass]\nn = 1.52\n",
        &[("f", 100.0)],
        "glass",
    );
    assert_eq!(s.interfaces.len(), 1);
    assert_eq!(s.interfaces[0].coating.len(), 1);
    let paint = goniospec::sample::load(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes/paint-pigments.toml"),
        Default::default(),
    )
    .unwrap();
    assert!(paint.interfaces.iter().all(|i| i.coating.is_empty()));
}

#[test]
fn an_absorbing_four_layer_stack_matches_the_tmm_at_every_angle() {
    // The stack of tests/physics_absorbing.rs (an absorber n = 2.0 + 0.3i between
    // dielectrics), whose meshed ray series reaches 1e-5 only up to 30-40 degrees: as a
    // coating it is exact from 0 to 80 degrees.
    let s = coated_stack(
        "abs-coating",
        "[media.air]\nn = 1.0\n[media.sio2]\nn = 1.46\n[media.abs]\nn = 2.0\nk = 0.3\n[media.tio2]\nn = 2.4\n[media.mgf2]\nn = 1.38\n[media.glass]\nn = 1.52\n",
        &[
            ("sio2", 90.0),
            ("abs", 40.0),
            ("tio2", 60.0),
            ("mgf2", 100.0),
        ],
        "glass",
    );
    let thetas: Vec<f64> = (0..=8).map(|i| 10.0 * i as f64).collect();
    check_against_tmm(
        &s,
        &[
            c(1.0, 0.0),
            c(1.46, 0.0),
            c(2.0, 0.3),
            c(2.4, 0.0),
            c(1.38, 0.0),
            c(1.52, 0.0),
        ],
        &[90.0, 40.0, 60.0, 100.0],
        &thetas,
        &[450.0, 550.0, 650.0],
        f64::INFINITY,
    );
}

#[test]
fn a_coated_film_on_the_seeds_wavy_surface_equals_the_meshed_film_at_normal_incidence() {
    // The seed's wavy top surface carrying a thin soap film as a coating, against the same
    // film meshed (the bottom face is the top shifted down by d). At normal incidence the
    // light inside the film walks no sideways distance, so the two differ only by the
    // meshed film's vertical offset: its thickness along each facet normal is d cos(theta_m),
    // and for d much thinner than a quarter wave R grows as d^2, so the coated R exceeds
    // the meshed one by about 2 R <1 - cos(theta_m)> (area-weighted over the facets).
    // (At oblique incidence the meshed film's internal rays cross facet edges, whose normals
    // jump by ~0.5 degrees on this 64^2 mesh, and the near-perfect cancellation of a thin
    // film's reflections makes that partial decoherence visible: the coating is the smooth
    // surface's answer there; docs/physics.md.)
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let top = goniospec::sample::load_obj(
        &root.join("meshes/thin-film-600nm-top.obj"),
        1000.0,
        Default::default(),
    )
    .unwrap();
    let mut one_minus_cos = (0.0, 0.0);
    for i in 0..top.triangles.len() {
        let a = top.area_vector(i);
        let len = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
        one_minus_cos.0 += a[2] * (1.0 - a[2] / len);
        one_minus_cos.1 += a[2];
    }
    let bias = one_minus_cos.0 / one_minus_cos.1;
    for d_nm in [10.0, 20.0] {
        let dir = scratch("wavy-coat");
        top.write_obj(&dir.join("top.obj"), 1.0, "top").unwrap();
        let mut bottom = top.clone();
        for p in &mut bottom.positions_nm {
            p[2] -= d_nm;
        }
        bottom
            .write_obj(&dir.join("bottom.obj"), 1.0, "bottom")
            .unwrap();
        let head = |name: &str| {
            format!(
                "[sample]\nname = \"{name}\"\nunit = \"nm\"\ntile = [20000.0, 20000.0]\n[media.air]\nn = 1.0\n[media.soap]\nn = 1.33\n"
            )
        };
        std::fs::write(
            dir.join("coated.toml"),
            head("coated")
                + &format!("[[interface]]\nmesh = \"top.obj\"\nfront = \"air\"\nback = \"air\"\ncoating = [ {{ medium = \"soap\", thickness = {d_nm:?} }} ]\n"),
        )
        .unwrap();
        std::fs::write(
            dir.join("meshed.toml"),
            head("meshed")
                + "[[interface]]\nmesh = \"top.obj\"\nfront = \"air\"\nback = \"soap\"\n[[interface]]\nmesh = \"bottom.obj\"\nfront = \"soap\"\nback = \"air\"\n",
        )
        .unwrap();
        let load = |f: &str| goniospec::sample::load(&dir.join(f), Default::default()).unwrap();
        let lambdas = [400.0, 550.0, 700.0];
        let cfg = config(&[0.0], Wavelengths::Monochromatic(lambdas.to_vec()), 4000);
        let (coated, meshed) = (
            run(&load("coated.toml"), &cfg),
            run(&load("meshed.toml"), &cfg),
        );
        let mode = coated.header.settings.coherence_mode();
        for (j, l) in lambdas.iter().enumerate() {
            let ((rc, _), (rm, _)) = (totals(&coated, 0, j), totals(&meshed, 0, j));
            let se = coated.cell(0, j).r_stderr(mode).unwrap()
                + meshed.cell(0, j).r_stderr(mode).unwrap();
            let expected_bias = 2.0 * rc * bias;
            eprintln!(
                "{d_nm} nm, {l} nm: coated {rc:.7} meshed {rm:.7} (diff {:.1e}, error bars {se:.1e}, thickness bias {expected_bias:.1e})",
                rc - rm
            );
            assert!(
                (rc - rm - expected_bias).abs() <= 5.0 * se + 0.5 * expected_bias,
                "{d_nm} nm film, {l} nm: coated {rc} vs meshed {rm}"
            );
        }
    }
}

#[test]
fn each_polarisation_of_a_coated_interface_matches_the_tmm() {
    // One traced tree of a coated flat interface: the s and p exit powers separately
    // against the independent TMM (the unpolarised averages above could hide a swap).
    use goniospec::optics::fresnel::field_power;
    use goniospec::trace::{Scene, TraceLimits, TraceStack, Tree, launch_fields};
    let s = coated_stack(
        "pol",
        "[media.air]\nn = 1.0\n[media.tio2]\nn = 2.4\n[media.mgf2]\nn = 1.38\n[media.glass]\nn = 1.52\n",
        &[("tio2", 60.0), ("mgf2", 100.0)],
        "glass",
    );
    let scene = Scene::new(&s, goniospec::accel::Backend::default_available()).unwrap();
    let idx = |name: &str| s.medium_id(name).unwrap();
    let mut indices = vec![num_complex::Complex64::new(0.0, 0.0); s.media.len()];
    for (name, n) in [("air", 1.0), ("tio2", 2.4), ("mgf2", 1.38), ("glass", 1.52)] {
        indices[idx(name)] = num_complex::Complex64::new(n, 0.0);
    }
    for theta in [0.0f64, 30.0, 60.0, 75.0] {
        for lambda in [450.0, 600.0] {
            let t = theta.to_radians();
            let d = glam::DVec3::new(-t.sin(), 0.0, -t.cos());
            let mut tree = Tree::default();
            scene.trace(
                glam::DVec3::new(5000.0, 5000.0, scene.z_top),
                d,
                launch_fields(d),
                &indices,
                lambda,
                &TraceLimits::default(),
                &mut TraceStack::default(),
                &mut tree,
            );
            let up: Vec<_> = tree.exits.iter().filter(|x| x.up).collect();
            assert_eq!(up.len(), 1, "one reflected exit");
            let (rs, rp) = (field_power(&up[0].e[0]), field_power(&up[0].e[1]));
            let n = [c(1.0, 0.0), c(2.4, 0.0), c(1.38, 0.0), c(1.52, 0.0)];
            let (want_s, want_p) = tmm_ref_pol(&n, &[60.0, 100.0], lambda, t);
            assert!(
                (rs - want_s).abs() < 1e-9 && (rp - want_p).abs() < 1e-9,
                "{theta} deg, {lambda} nm: R_s {rs} R_p {rp} vs TMM {want_s} {want_p}"
            );
        }
    }
}

#[test]
fn a_body_can_carry_thin_layers_and_keeps_its_meshed_shell_form() {
    // `coating = [ ... ]` on a [[body]]: thin layers on its outside, applied by the TMM;
    // `coating = "MEDIUM"` keeps meaning a meshed shell (the flakes generator's coat).
    let d = scratch("body-coat");
    std::fs::write(
        d.join("s.toml"),
        "[sample]\nname = \"coated spheres\"\nunit = \"nm\"\ntile = [2000.0, 2000.0]\n[media.air]\nn = 1.0\n[media.tio2]\nn = 2.4\n[media.oxide]\nn = 1.6\n[[interface]]\ngenerator = { kind = \"flat\", z = 900.0 }\nfront = \"air\"\nback = \"air\"\n[[body]]\ngenerator = { kind = \"pigment-spheres\", radius = 150.0, volume_fraction = 0.02, layer = [100.0, 800.0], subdivisions = 1 }\ninside = \"tio2\"\noutside = \"air\"\ncoating = [ { medium = \"oxide\", thickness = 20.0 } ]\n",
    )
    .unwrap();
    let s = goniospec::sample::load(&d.join("s.toml"), Default::default()).unwrap();
    let bodies: Vec<_> = s.interfaces.iter().filter(|i| i.closed).collect();
    assert!(!bodies.is_empty());
    let oxide = s.medium_id("oxide").unwrap();
    for b in &bodies {
        assert_eq!(b.coating, vec![(oxide, 20.0)]);
    }
    // It simulates (coated, so per wavelength) and conserves energy.
    let acc = run(
        &s,
        &config(&[0.0], Wavelengths::Monochromatic(vec![500.0]), 64),
    );
    let (r, t) = totals(&acc, 0, 0);
    assert!(r > 0.0 && t > 0.0 && r + t <= 1.0 + 5e-3, "R {r} T {t}");
    // The shell form: the flakes generator's coated flakes (`coating = 0.1`) carry a
    // meshed coat around each core; `coating = "tio2"` names its medium. Before issue 30
    // this was always refused ("did not match any variant of untagged enum RawCoating").
    std::fs::write(
        d.join("f.toml"),
        "[sample]\nname = \"coated flakes\"\nunit = \"um\"\ntile = [20.0, 20.0]\n[media.air]\nn = 1.0\n[media.mica]\nn = 1.58\n[media.tio2]\nn = 2.4\n[[body]]\ngenerator = { kind = \"flakes\", size = 6.0, thickness = 0.5, tilt_sd_deg = 5.0, volume_fraction = 0.02, layer = [1.0, 5.0], coating = 0.1, seed = 3 }\ninside = \"mica\"\noutside = \"air\"\ncoating = \"tio2\"\n",
    )
    .unwrap();
    let s = goniospec::sample::load(&d.join("f.toml"), Default::default())
        .unwrap_or_else(|e| panic!("the shell form is refused: {e}"));
    let (tio2, mica) = (s.medium_id("tio2").unwrap(), s.medium_id("mica").unwrap());
    let shells = s
        .interfaces
        .iter()
        .filter(|i| i.closed && i.back == tio2)
        .count();
    let cores = s
        .interfaces
        .iter()
        .filter(|i| i.closed && i.back == mica && i.front == tio2)
        .count();
    assert!(
        shells > 0 && shells == cores,
        "{shells} shells, {cores} cores"
    );
    // A misspelt medium names itself.
    std::fs::write(
        d.join("g.toml"),
        std::fs::read_to_string(d.join("f.toml"))
            .unwrap()
            .replace("coating = \"tio2\"", "coating = \"tiO2\""),
    )
    .unwrap();
    let e = goniospec::sample::load(&d.join("g.toml"), Default::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("tiO2"), "{e}");
}

/// `check` lists every coating layer with its thickness in nm, and warns where a layer is
/// too thick for the coating model: `thickness = 300` in a sample of unit "um" (meant as
/// 300 nm) is a 300 um layer, 60 beamlet radii thick (issue 47). The quarter-wave layer
/// (100 nm, walking 2 d tan(theta_t) = 152 nm at 60 degrees in n 1.38, under half the
/// 5000 nm beamlet) is not warned of.
#[test]
fn check_lists_coatings_in_nm_and_warns_of_a_unit_slip() {
    let media = "[media.air]\nn = 1.0\n[media.f]\nn = 1.38\n[media.glass]\nn = 1.52\n";
    let opts = goniospec::check::CheckOptions {
        leak_rays: 200,
        ..Default::default()
    };
    let thin = coated_stack("thin-coat", media, &[("f", 100.0)], "glass");
    let r = goniospec::check::check(&thin, &opts).unwrap();
    assert!(
        r.facts
            .iter()
            .any(|f| f.contains("coating of 1 layers") && f.contains("f 100 nm")),
        "{:#?}",
        r.facts
    );
    assert!(
        !r.warnings.iter().any(|w| w.contains("coating layer")),
        "{:#?}",
        r.warnings
    );

    let toml = stack_toml("slip", "coating", media, &[("f", 300.0)], "glass").replace(
        "unit = \"nm\"\ntile = [20000.0, 20000.0]",
        "unit = \"um\"\ntile = [20.0, 20.0]",
    );
    let slip = sample_from("slip", &toml);
    let r = goniospec::check::check(&slip, &opts).unwrap();
    assert!(
        r.facts.iter().any(|f| f.contains("f 300000 nm")),
        "{:#?}",
        r.facts
    );
    assert!(
        r.warnings
            .iter()
            .any(|w| w.contains("300000 nm thick") && w.contains("unit = \"um\"")),
        "{:#?}",
        r.warnings
    );
}

/// Issue 74: a coating is an exact transfer matrix, so a finite coherence radius does not
/// act on it; a run where a meshed layer's partial waves would interfere with a weight
/// noticeably below 1 says so, with that weight. A 100 nm layer of n = 1.38 on n = 1.5 at
/// 45 deg: the returning wave leaves `2 d tan(theta_l) cos(45 deg)` across the beam,
/// `sin(theta_l) = sin(45 deg) / 1.38` (Snell), computed here; at a 1 nm radius its weight
/// `exp(-dx^2 / 2)` is 0, and the run's result is still the coherent TMM's (the radius
/// does not act). At the default 5 um radius the weight is within 1e-3 of 1: nothing said.
#[test]
fn a_coating_says_the_coherence_radius_does_not_act_on_it() {
    let s = coated_stack(
        "coating-radius",
        "[media.air]\nn = 1.0\n[media.f]\nn = 1.38\n[media.glass]\nn = 1.5\n",
        &[("f", 100.0)],
        "glass",
    );
    let sin_l = 45f64.to_radians().sin() / 1.38;
    let dx = 2.0 * 100.0 * sin_l / (1.0 - sin_l * sin_l).sqrt() * 45f64.to_radians().cos();
    let lambda = 550.0;
    let mut cfg = config(&[0.0, 45.0], Wavelengths::Monochromatic(vec![lambda]), 4);
    cfg.rho_nm = 1.0;
    let (acc, _) = simulate(&s, &cfg, &|_| {}).unwrap();
    let said: Vec<&String> = acc
        .header
        .warnings
        .iter()
        .filter(|w| w.contains("interferes fully whatever --coherence-radius-nm"))
        .collect();
    assert_eq!(said.len(), 1, "{:?}", acc.header.warnings);
    assert!(
        said[0].contains(&format!("{dx:.0} nm apart")) && said[0].contains("= 0.000"),
        "{} (offset {dx})",
        said[0]
    );
    // The radius does not act: the coherent TMM's R at 45 deg.
    let (r, _) = totals(&acc, 1, 0);
    let (rr, _) = tmm_ref(
        &[C::new(1.0, 0.0), C::new(1.38, 0.0), C::new(1.5, 0.0)],
        &[100.0],
        lambda,
        45f64.to_radians(),
    );
    assert!((r - rr).abs() < 1e-6, "R {r} vs the coherent TMM {rr}");
    cfg.rho_nm = goniospec::sample::validity::DEFAULT_COHERENCE_RADIUS_NM;
    let w = (-dx * dx / (2.0 * cfg.rho_nm * cfg.rho_nm)).exp();
    assert!(1.0 - w < 1e-3);
    let (acc, _) = simulate(&s, &cfg, &|_| {}).unwrap();
    assert!(
        !acc.header
            .warnings
            .iter()
            .any(|w| w.contains("--coherence-radius-nm")),
        "{:?}",
        acc.header.warnings
    );
}
