//! `goniospec fit`: it recovers the parameters of samples whose truth is known, and its
//! glTF passes the Khronos glTF validator.

mod common;

use std::path::Path;
use std::process::Command;

use common::*;

/// Simulates `sample` at 0-60 degrees and fits it through the CLI; returns the JSON.
fn simulate_and_fit(sample: &Path, rays: &str, dir: &Path) -> serde_json::Value {
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
    let out = gs(&["fit", "s.gsa", "-o", "fit"]);
    eprintln!("{out}");
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
}

/// Runs the Khronos glTF validator (npm `gltf-validator`, installed into the target folder
/// on first use) on a fitted material.
#[test]
fn the_fitted_gltf_passes_the_khronos_validator() {
    let d = scratch("fit-gltf");
    simulate_and_fit(&root().join("meshes/flat-soap-film.toml"), "16", &d);
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
    let o = Command::new("node")
        .arg(root().join("tests/interop/validate-gltf.js"))
        .arg(&modules)
        .arg(d.join("fit.gltf"))
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
