//! `goniospec fit`: it recovers the parameters of samples whose truth is known, and its
//! glTF passes the Khronos glTF validator.

mod common;

use std::path::Path;
use std::process::Command;

use common::*;

/// Simulates `sample` at 0-60 degrees and fits it through the CLI; returns the JSON.
fn simulate_and_fit(sample: &Path, rays: &str, dir: &Path) -> serde_json::Value {
    simulate_and_fit_with(sample, rays, dir, &[])
}

/// [`simulate_and_fit`] with extra `fit` flags.
fn simulate_and_fit_with(
    sample: &Path,
    rays: &str,
    dir: &Path,
    flags: &[&str],
) -> serde_json::Value {
    let gs = |args: &[&str]| {
        let o = Command::new(env!("CARGO_BIN_EXE_goniospec"))
            .args(args)
            .current_dir(dir)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stdout).to_string()
    };
    gs(&[
        "simulate",
        sample.to_str().unwrap(),
        "--theta-i",
        "0,15,30,45,60",
        "--wavelengths",
        "400:700:10",
        "--rays",
        rays,
        "-o",
        "s.gsa",
    ]);
    let mut args = vec!["fit", "s.gsa", "-o", "fit"];
    args.extend_from_slice(flags);
    let out = gs(&args);
    eprintln!("{out}");
    assert!(out.contains("fit_seconds: "), "{out}");
    serde_json::from_str(&std::fs::read_to_string(dir.join("fit.json")).unwrap()).unwrap()
}

#[test]
fn fit_recovers_the_flat_soap_films_thickness_and_index() {
    let d = scratch("fit-soap");
    let v = simulate_and_fit(&root().join("meshes/flat-soap-film.toml"), "16", &d);
    let film = &v["fit"]["film"];
    let (t, n) = (
        film["thickness_nm"].as_f64().unwrap(),
        film["ior"].as_f64().unwrap(),
    );
    assert!((t / 600.0 - 1.0).abs() < 0.01, "thickness {t} nm, not 600");
    assert!((n / 1.33 - 1.0).abs() < 0.01, "index {n}, not 1.33");
    // The same numbers in the renderers' parameter sets, in their units.
    assert!((v["openpbr"]["thin_film_thickness"].as_f64().unwrap() - t / 1000.0).abs() < 1e-12);
    assert!((v["standard_surface"]["thin_film_IOR"].as_f64().unwrap() - n).abs() < 1e-12);
    let gltf: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("fit.gltf")).unwrap()).unwrap();
    let ir = &gltf["materials"][0]["extensions"]["KHR_materials_iridescence"];
    assert!((ir["iridescenceThicknessMaximum"].as_f64().unwrap() - t).abs() < 1e-9);
}

#[test]
fn fit_recovers_the_roughness_of_a_ggx_gold_height_field() {
    let d = scratch("fit-gold");
    let v = simulate_and_fit(&root().join("meshes/rough-gold.toml"), "2000", &d);
    let alpha = v["fit"]["ggx_alpha"].as_f64().unwrap();
    assert!(
        (alpha / 0.2 - 1.0).abs() < 0.10,
        "alpha {alpha}, generator 0.2"
    );
    assert_eq!(v["fit"]["base"]["kind"], "conductor");
    assert!(
        v["fit"]["film"].is_null(),
        "a film was invented: {}",
        v["fit"]["film"]
    );
    // The conductor is gold (data/au-johnson.csv): its normal-incidence reflectance
    // |(n - 1) / (n + 1)|^2 at every wavelength within 0.02 of the table's, and k inside
    // its bound. The allowance covers the height field's departure from the GGX lobe (alpha
    // fits 3 % off) and the 2,000-tree noise (R standard error about 1.5e-3). Without the
    // multiple-scattering term the fit ran k to its bound of 20 and F0 to 0.999 in the red
    // (issue 25).
    let table: Vec<(f64, f64, f64)> = std::fs::read_to_string(root().join("data/au-johnson.csv"))
        .unwrap()
        .lines()
        .filter(|l| l.starts_with(|c: char| c.is_ascii_digit()))
        .map(|l| {
            let f: Vec<f64> = l.split(',').map(|x| x.trim().parse().unwrap()).collect();
            (f[0], f[1], f[2])
        })
        .collect();
    let at = |w: f64| {
        let i = table
            .windows(2)
            .position(|p| p[0].0 <= w && w <= p[1].0)
            .unwrap();
        let (a, b) = (table[i], table[i + 1]);
        let t = (w - a.0) / (b.0 - a.0);
        (a.1 + t * (b.1 - a.1), a.2 + t * (b.2 - a.2))
    };
    let f0 = |n: f64, k: f64| ((n - 1.0).powi(2) + k * k) / ((n + 1.0).powi(2) + k * k);
    let base = &v["fit"]["base"];
    let num = |key: &str| -> Vec<f64> {
        base[key]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    let (lambdas, ns, ks) = (num("lambda_nm"), num("n"), num("k"));
    assert!(!lambdas.is_empty());
    for ((&w, &n), &k) in lambdas.iter().zip(&ns).zip(&ks) {
        let (nt, kt) = at(w);
        assert!(k < 19.9, "{w} nm: k {k} at its bound");
        assert!(
            (f0(n, k) - f0(nt, kt)).abs() < 0.02,
            "{w} nm: fitted {n} + {k}i (F0 {}) against the table's {nt} + {kt}i (F0 {})",
            f0(n, k),
            f0(nt, kt)
        );
    }
}

/// A smooth clear coat (n 1.5, 2 um) over the shipped rough gold's GGX height field (alpha
/// 0.2): issue 46. The fit finds the coat by itself (`--coat auto`): its index within 0.03
/// of 1.5 from the Fresnel reflection in the mirror bucket beyond the gold's lobe around it
/// (the 2,000-tree noise of that excess, about 1e-3 against 0.04, moves the index by about
/// 0.01), and a conductor base under it; the OpenPBR block carries `coat_weight` 1 and the
/// index, the glTF `KHR_materials_clearcoat`.
#[test]
fn fit_finds_a_clear_coat_over_rough_gold() {
    let d = scratch("fit-coat");
    std::fs::write(
        d.join("coated.toml"),
        format!(
            "[sample]\nname = \"clear coat over rough gold\"\nunit = \"um\"\ntile = [20.0, 20.0]\n\
             [media.air]\nn = 1.0\n[media.coat]\nn = 1.5\n[media.gold]\ntable = \"{au}\"\n\
             [[interface]]\ngenerator = {{ kind = \"flat\", z = 2.0 }}\nfront = \"air\"\nback = \"coat\"\n\
             [[interface]]\nmesh = \"{mesh}\"\nfront = \"coat\"\nback = \"gold\"\n",
            au = root().join("data/au-johnson.csv").display(),
            mesh = root().join("meshes/rough-gold-ggx.obj").display()
        ),
    )
    .unwrap();
    let v = simulate_and_fit(&d.join("coated.toml"), "2000", &d);
    let coat = &v["fit"]["coat"];
    let n = coat["ior"]
        .as_f64()
        .unwrap_or_else(|| panic!("no coat: {}", v["fit"]));
    assert!((n - 1.5).abs() < 0.03, "coat index {n}, not 1.5");
    assert_eq!(v["fit"]["base"]["kind"], "conductor");
    assert_eq!(v["openpbr"]["coat_weight"], 1.0);
    assert!((v["openpbr"]["coat_ior"].as_f64().unwrap() - n).abs() < 1e-12);
    assert_eq!(v["standard_surface"]["coat"], 1.0);
    let gltf: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("fit.gltf")).unwrap()).unwrap();
    let cc = &gltf["materials"][0]["extensions"]["KHR_materials_clearcoat"];
    assert_eq!(cc["clearcoatFactor"], 1.0);
    assert!(
        gltf["extensionsUsed"]
            .as_array()
            .unwrap()
            .contains(&serde_json::json!("KHR_materials_clearcoat"))
    );
}

/// Rough fused silica transmits most of the light: the fit takes a dielectric base, whose
/// index is the glass's (1.46 at 550 nm, Malitson 1965) within 0.05, never a conductor
/// (issue 46: a conductor was fitted), and says why.
/// The shipped car paint keeps its clear coat (issue 71: `--coat auto` found none and
/// returned a coatless "conductor" of n 7-8 and k 0, which OpenPBR showed as a grey
/// near-mirror): the coat's index within 0.04 of the sample's 1.52 from its Fresnel
/// mirror, OpenPBR's `coat_weight` 1; the base under it, which the model cannot hold (aluminium
/// flakes in a binder over a black primer), is flagged where its n + ik sits at the search's
/// bounds or has no extinction, and the fit states its time.
#[test]
fn fit_keeps_the_car_paints_clear_coat() {
    let d = scratch("fit-car-paint");
    let v = simulate_and_fit(&root().join("meshes/car-paint.toml"), "512", &d);
    let n = v["fit"]["coat"]["ior"]
        .as_f64()
        .unwrap_or_else(|| panic!("no coat: {}", v["fit"]));
    assert!((n - 1.52).abs() < 0.04, "coat index {n}, not 1.52");
    assert_eq!(v["openpbr"]["coat_weight"], 1.0);
    let warnings = v["fit"]["warnings"].to_string();
    if v["fit"]["base"]["kind"] == "conductor" {
        assert!(
            warnings.contains("no extinction") || warnings.contains("bounds"),
            "{warnings}"
        );
    }
}

#[test]
fn fit_takes_a_dielectric_for_rough_glass() {
    let d = scratch("fit-glass");
    let v = simulate_and_fit(&root().join("meshes/rough-glass.toml"), "1000", &d);
    assert_eq!(v["fit"]["base"]["kind"], "dielectric", "{}", v["fit"]);
    let n = v["fit"]["base"]["ior"].as_f64().unwrap();
    assert!((n - 1.46).abs() < 0.05, "ior {n}");
    let warnings = v["fit"]["warnings"].to_string();
    assert!(warnings.contains("transmits"), "{warnings}");
}

/// The shipped metallic paint (aluminium flakes in a binder) is beyond one lobe with one
/// film: the fit keeps no film at the bounds of its model (it returned "a free-standing 41
/// nm film of ior 3.0 on ior 1.0", issue 46) and says so, naming flakes.
#[test]
fn fit_says_plainly_when_flakes_are_beyond_the_model() {
    let d = scratch("fit-flakes");
    let v = simulate_and_fit(&root().join("meshes/metallic-paint.toml"), "512", &d);
    if let Some(f) = v["fit"]["film"].as_object() {
        let (n, t) = (
            f["ior"].as_f64().unwrap(),
            f["thickness_nm"].as_f64().unwrap(),
        );
        assert!(
            n > 1.05 && n < 2.95 && t > 30.0 && t < 1990.0,
            "a film at the bounds was kept: {f:?}"
        );
    }
    let warnings = v["fit"]["warnings"].to_string();
    assert!(warnings.contains("flakes"), "{warnings}");
}

/// Runs the Khronos glTF validator (npm `gltf-validator`, installed into the target folder
/// on first use) on fitted materials: the soap film (iridescence) and a clear coat
/// (`KHR_materials_clearcoat`).
#[test]
fn the_fitted_gltf_passes_the_khronos_validator() {
    let d = scratch("fit-gltf");
    simulate_and_fit(&root().join("meshes/flat-soap-film.toml"), "16", &d);
    let coated = scratch("fit-gltf-coat");
    simulate_and_fit_with(
        &root().join("meshes/rough-gold.toml"),
        "64",
        &coated,
        &["--coat", "1.5"],
    );
    let modules = root().join("target").join("gltf-validator");
    if !modules.join("node_modules/gltf-validator").exists() {
        let o = Command::new("npm")
            .args(["install", "--silent", "--no-audit", "--no-fund", "--prefix"])
            .arg(&modules)
            .arg("gltf-validator@2.0.0-dev.3.10")
            .output()
            .expect("npm is needed for this test (Debian: apt-get install -y npm)");
        assert!(
            o.status.success(),
            "npm install gltf-validator failed: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    for dir in [&d, &coated] {
        let o = Command::new("node")
            .arg(root().join("tests/interop/validate-gltf.js"))
            .arg(&modules)
            .arg(dir.join("fit.gltf"))
            .output()
            .expect("node is needed for this test");
        let report = String::from_utf8_lossy(&o.stdout);
        eprintln!("{report}");
        assert!(
            o.status.success(),
            "the glTF has validation errors: {report} {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let issues: serde_json::Value = serde_json::from_str(report.trim()).unwrap();
        assert_eq!(issues["numErrors"], 0);
    }
}

#[test]
fn fit_says_plainly_when_it_cannot_represent_a_multilayer() {
    // A 5-pair quarter-wave mirror: no single film on a base reproduces its stop band.
    let d = scratch("fit-mirror");
    let (media, layers) = quarter_wave_mirror(5);
    std::fs::write(
        d.join("m.toml"),
        stack_toml("mirror", "coating", media, &layers, "glass"),
    )
    .unwrap();
    let gs = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_goniospec"))
            .args(args)
            .current_dir(&d)
            .output()
            .unwrap()
    };
    let o = gs(&[
        "simulate",
        "m.toml",
        "--theta-i",
        "0,15,30,45,60",
        "--wavelengths",
        "400:700:10",
        "--rays",
        "4",
        "-o",
        "m.gsa",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = gs(&["fit", "m.gsa", "-o", "fit"]);
    assert!(o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("cannot represent"), "no warning: {err}");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("fit.json")).unwrap()).unwrap();
    assert!(!v["fit"]["warnings"].as_array().unwrap().is_empty());
}
