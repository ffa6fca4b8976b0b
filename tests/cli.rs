//! The `goniospec` binary as a user runs it: output formats, errors and exit codes.

mod common;

use std::process::Command;

use common::goniospec;

#[test]
fn backends_lists_versions() {
    let (code, out, _) = goniospec(&["backends"]);
    assert_eq!(code, 0);
    assert!(out.lines().any(|l| l.starts_with("obvhs 0.")), "{out}");
    if cfg!(embree) {
        let line = out.lines().find(|l| l.starts_with("embree ")).expect(&out);
        let version = line.split_whitespace().nth(1).unwrap();
        let parts: Vec<u32> = version.split('.').map(|p| p.parse().unwrap()).collect();
        assert_eq!(parts.len(), 3, "{line}");
        assert!(parts[0] == 3 || parts[0] == 4, "{line}");
        assert!(line.contains("(default)"), "{line}");
    } else {
        assert!(out.contains("unavailable: embree"), "{out}");
    }
}

#[test]
fn check_reports_a_shipped_sample() {
    let (code, out, err) = goniospec(&[
        "check",
        "meshes/thin-film-600nm.toml",
        "--leak-rays",
        "2000",
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("16384 triangles"), "{out}");
    assert!(out.contains("front / back: air / soap"), "{out}");
    assert!(
        out.contains(" 0 leaks") && out.contains("no defects found"),
        "{out}"
    );
}

#[test]
fn check_fails_with_the_file_named_and_status_1() {
    let (code, _, err) = goniospec(&["check", "meshes/does-not-exist.toml"]);
    assert_eq!(code, 1);
    assert!(
        err.starts_with("error: meshes/does-not-exist.toml: cannot read file"),
        "{err}"
    );
}

#[test]
fn check_exits_1_on_a_defective_sample() {
    let d = std::env::temp_dir().join(format!("goniospec-cli-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    // The lower sheet claims air above it, but the upper sheet put glass there.
    let sheet = |z: f64| {
        format!(
            "[[interface]]\ngenerator = {{ kind = \"flat\", z = {z:?} }}\nfront = \"air\"\nback = \"glass\"\n"
        )
    };
    std::fs::write(
        d.join("bad.toml"),
        format!(
            "[sample]\nname = \"bad\"\nunit = \"nm\"\ntile = [100.0, 100.0]\n[media.air]\nn = 1.0\n[media.glass]\nn = 1.5\n{}{}",
            sheet(50.0),
            sheet(0.0)
        ),
    )
    .unwrap();
    let p = d.join("bad.toml");
    let (code, out, _) = goniospec(&["check", p.to_str().unwrap(), "--leak-rays", "500"]);
    assert_eq!(code, 1, "{out}");
    assert!(out.contains("DEFECT:") && out.contains("leaks"), "{out}");
}

#[test]
fn generate_writes_an_obj_that_loads() {
    let d = std::env::temp_dir().join(format!("goniospec-gen-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let p = d.join("g.obj");
    let (code, out, err) = goniospec(&[
        "generate",
        "microfacet",
        "--tile",
        "2,2",
        "--unit",
        "um",
        "-p",
        "distribution=beckmann",
        "-p",
        "alpha=0.3",
        "-p",
        "resolution=32",
        "-o",
        p.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("wrote"), "{out}");
    let m = goniospec::sample::load_obj(&p, 1000.0, Default::default()).unwrap();
    assert!(m.triangles.len() >= 128);
    let (code, _, err) = goniospec(&[
        "generate",
        "gaussian",
        "-p",
        "rms=0.1",
        "-o",
        p.to_str().unwrap(),
    ]);
    assert_eq!(code, 1);
    assert!(err.contains("missing field `correlation_length`"), "{err}");
}

#[test]
fn bad_usage_exits_with_2() {
    let (code, _, err) = goniospec(&["bench", "trace", "--backend", "optix"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("unknown backend 'optix'"), "{err}");
    let (code, _, _) = goniospec(&["frobnicate"]);
    assert_eq!(code, 2);
}

#[test]
fn bench_trace_prints_its_figures() {
    let (code, out, err) = goniospec(&[
        "bench",
        "trace",
        "--triangles",
        "2000",
        "--rays",
        "5000",
        "--threads",
        "1",
    ]);
    assert_eq!(code, 0, "{err}");
    let backends: Vec<&str> = if cfg!(embree) {
        vec!["embree", "obvhs"]
    } else {
        vec!["obvhs"]
    };
    for b in &backends {
        for order in ["random", "sorted"] {
            let prefix = format!("{b} {order} 1T: ");
            let line = out
                .lines()
                .find(|l| l.starts_with(&prefix))
                .unwrap_or_else(|| panic!("no '{prefix}' in\n{out}"));
            let rate: f64 = line[prefix.len()..]
                .trim_end_matches(" Mrays/s")
                .parse()
                .expect(line);
            assert!(rate > 0.0 && rate.is_finite(), "{line}");
        }
        assert!(out.contains(&format!("{b} build: ")), "{out}");
    }
    if cfg!(embree) {
        assert!(out.contains("agreement: "), "{out}");
    }
}

#[test]
fn simulate_reflectance_merge_and_analytic_work_together() {
    let d = std::env::temp_dir().join(format!("goniospec-sim-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let a = d.join("a.gsa");
    let b = d.join("b.gsa");
    let m = d.join("m.gsa");
    let common = [
        "simulate",
        "meshes/flat-soap-film.toml",
        "--theta-i",
        "0,30",
        "--wavelengths",
        "400:700:100",
        "--rays",
        "64",
    ];
    let mut args: Vec<&str> = common.to_vec();
    args.extend(["-o", a.to_str().unwrap()]);
    let (code, out, err) = goniospec(&args);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("wrote"), "{out}");
    let mut args: Vec<&str> = common.to_vec();
    args.extend(["--seed", "2", "-o", b.to_str().unwrap()]);
    assert_eq!(goniospec(&args).0, 0);
    let (code, out, err) = goniospec(&[
        "merge",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "-o",
        m.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("2 runs, 128 rays"), "{out}");

    let (code, csv, err) = goniospec(&["reflectance", m.to_str().unwrap(), "--theta-i", "30"]);
    assert_eq!(code, 0, "{err}");
    let (code, tmm, err) = goniospec(&[
        "analytic",
        "meshes/flat-soap-film.toml",
        "--theta-i",
        "30",
        "--wavelengths",
        "400:700:100",
    ]);
    assert_eq!(code, 0, "{err}");
    let mut lines = csv.lines();
    assert_eq!(
        lines.next(),
        Some("lambda_nm,R,T,absorbed,dropped,R_stderr")
    );
    let mut tl = tmm.lines();
    assert_eq!(tl.next(), Some("lambda_nm,Rs,Rp,R,Ts,Tp,T,delta_deg"));
    let mut n = 0;
    for (row, trow) in lines.zip(tl) {
        let f: Vec<f64> = row.split(',').map(|v| v.parse().unwrap()).collect();
        let t: Vec<f64> = trow.split(',').map(|v| v.parse().unwrap()).collect();
        assert_eq!(f[0], t[0]);
        assert!((f[1] - t[3]).abs() < 2e-3, "R {} vs TMM {}", f[1], t[3]);
        assert!((f[1] + f[2] + f[3] + f[4] - 1.0).abs() < 1e-4, "{row}");
        n += 1;
    }
    assert_eq!(n, 3);

    // Errors: an angle that was not simulated, merging a run with itself, a damaged file.
    let (code, _, err) = goniospec(&["reflectance", m.to_str().unwrap(), "--theta-i", "45"]);
    assert_eq!(code, 1);
    assert!(err.contains("no incident angle 45 deg"), "{err}");
    let (code, _, err) = goniospec(&[
        "merge",
        a.to_str().unwrap(),
        a.to_str().unwrap(),
        "-o",
        m.to_str().unwrap(),
    ]);
    assert_eq!(code, 1);
    assert!(err.contains("seed 1"), "{err}");
    let mut bytes = std::fs::read(&a).unwrap();
    bytes.truncate(bytes.len() / 2);
    std::fs::write(d.join("cut.gsa"), bytes).unwrap();
    let (code, _, err) = goniospec(&[
        "reflectance",
        d.join("cut.gsa").to_str().unwrap(),
        "--theta-i",
        "0",
    ]);
    assert_eq!(code, 1);
    assert!(err.contains("truncated"), "{err}");
    let (code, _, err) = goniospec(&["analytic", "meshes/rough-gold.toml", "--theta-i", "0"]);
    assert_eq!(code, 1);
    assert!(err.contains("not written as a [stack]"), "{err}");
    let (code, _, err) = goniospec(&[
        "simulate",
        "meshes/rough-gold.toml",
        "--wavelengths",
        "100:200:50",
        "-o",
        m.to_str().unwrap(),
    ]);
    assert_eq!(code, 1);
    assert!(
        err.contains("medium 'gold'") && err.contains("outside the range"),
        "{err}"
    );
}

#[test]
fn simulate_output_does_not_depend_on_threads() {
    let d = std::env::temp_dir().join(format!("goniospec-thr-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let run = |t: &str, name: &str| {
        let p = d.join(name);
        let (code, _, err) = goniospec(&[
            "simulate",
            "meshes/thin-film-600nm.toml",
            "--theta-i",
            "20",
            "--wavelengths",
            "400:700:50",
            "--rays",
            "300",
            "--threads",
            t,
            "-o",
            p.to_str().unwrap(),
        ]);
        assert_eq!(code, 0, "{err}");
        std::fs::read(p).unwrap()
    };
    assert!(run("1", "one.gsa") == run("2", "two.gsa"));
}

/// `--report-json` writes the run's figures as numbers: trees as launched, the directions
/// asked for, a finite rate; it never overwrites a foreign file or the accumulator.
#[test]
fn simulate_writes_a_machine_readable_report() {
    let d = std::env::temp_dir().join(format!("goniospec-report-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let (gsa, json) = (d.join("r.gsa"), d.join("r.json"));
    let args = |report: &std::path::Path| {
        vec![
            "simulate".to_string(),
            "meshes/flat-soap-film.toml".into(),
            "--theta-i".into(),
            "0,40".into(),
            "--wavelengths".into(),
            "500:600:50".into(),
            "--rays".into(),
            "64".into(),
            "-o".into(),
            gsa.to_str().unwrap().into(),
            "--report-json".into(),
            report.to_str().unwrap().into(),
        ]
    };
    let run = |a: Vec<String>| goniospec(&a.iter().map(|s| s.as_str()).collect::<Vec<_>>());
    let (code, _, err) = run(args(&json));
    assert_eq!(code, 0, "{err}");
    let r: goniospec::simulate::RunReport =
        serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert_eq!(r.trees, 128);
    let angles: Vec<f64> = r.directions.iter().map(|x| x.theta_i_deg).collect();
    assert_eq!(angles, [0.0, 40.0]);
    assert!(r.directions.iter().all(|x| x.trees == 64));
    assert!(r.segments >= r.trees && r.trees_per_second.is_finite() && r.trees_per_second > 0.0);
    // A flat lossless film: nothing cut, created or limited.
    assert_eq!((r.worst_created, r.worst_limited), (0.0, 0.0));
    // Rerunning over its own report is fine; over a foreign file or the accumulator is not.
    assert_eq!(run(args(&json)).0, 0);
    let foreign = d.join("notes.json");
    std::fs::write(&foreign, "{\"mine\": 1}").unwrap();
    let (code, _, err) = run(args(&foreign));
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("refusing to overwrite"), "{err}");
    assert_eq!(std::fs::read_to_string(&foreign).unwrap(), "{\"mine\": 1}");
    let (code, _, err) = run(args(&gsa));
    assert_eq!(code, 1, "{err}");
}

#[test]
fn build_eval_and_info() {
    let d = std::env::temp_dir().join(format!("goniospec-brdf-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let gsa = d.join("r.gsa");
    let (code, _, err) = goniospec(&[
        "simulate",
        "meshes/rough-gold.toml",
        "--theta-i",
        "0,30,60",
        "--wavelengths",
        "500:700:100",
        "--rays",
        "2000",
        "--theta-o-bins",
        "18",
        "--phi-o-bins",
        "12",
        "-o",
        gsa.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let pairs = d.join("pairs.csv");
    std::fs::write(
        &pairs,
        "theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg\n30,0,30,180\n10,45,20,200\n",
    )
    .unwrap();
    for repr in ["kdtree", "subdivided", "table"] {
        let gsb = d.join(format!("{repr}.gsb"));
        let (code, out, err) = goniospec(&[
            "build",
            gsa.to_str().unwrap(),
            "--repr",
            repr,
            "-o",
            gsb.to_str().unwrap(),
        ]);
        assert_eq!(code, 0, "{err}");
        assert!(out.contains(&format!("{repr} representation")), "{out}");
        let (code, out, err) = goniospec(&[
            "eval",
            gsb.to_str().unwrap(),
            "--theta-i",
            "30",
            "--phi-i",
            "0",
            "--theta-o",
            "30",
            "--phi-o",
            "180",
        ]);
        assert_eq!(code, 0, "{err}");
        let rows: Vec<&str> = out.lines().collect();
        assert_eq!(rows[0], "lambda_nm,brdf");
        assert_eq!(rows.len(), 3, "{out}");
        let specular: f64 = rows[1].split(',').nth(1).unwrap().parse().unwrap();
        assert!(
            specular > 0.1,
            "{repr}: the specular direction of rough gold is bright: {specular}"
        );
        let (code, out, err) = goniospec(&[
            "eval",
            gsb.to_str().unwrap(),
            "--pairs",
            pairs.to_str().unwrap(),
        ]);
        assert_eq!(code, 0, "{err}");
        let rows: Vec<&str> = out.lines().collect();
        assert_eq!(rows[0], "pair,lambda_nm,brdf");
        assert_eq!(rows.len(), 1 + 2 * 2, "{out}");
        assert!(rows[1].starts_with("0,550,"), "{out}");
        let (code, out, _) = goniospec(&["info", gsb.to_str().unwrap()]);
        assert_eq!(code, 0);
        assert!(
            out.contains(&format!("representation {repr}")) && out.contains("rough gold"),
            "{out}"
        );
    }
    let (code, out, _) = goniospec(&["info", gsa.to_str().unwrap()]);
    assert_eq!(code, 0);
    assert!(
        out.contains("accumulator") && out.contains("rays per direction: [2000, 2000, 2000]"),
        "{out}"
    );
    // Errors.
    let (code, _, err) = goniospec(&["info", "meshes/rough-gold.toml"]);
    assert_eq!(code, 1);
    assert!(err.contains("not a .gsa, .gsb or .bsdf file"), "{err}");
    let (code, _, err) = goniospec(&[
        "eval",
        gsa.to_str().unwrap(),
        "--theta-i",
        "0",
        "--theta-o",
        "0",
    ]);
    assert_eq!(code, 1);
    // A .gsa is named as what it is, with the command that makes a BRDF of it.
    assert!(
        err.contains("an accumulator (.gsa)") && err.contains("goniospec build"),
        "{err}"
    );
    std::fs::write(&pairs, "theta_i,phi_i,theta_o,phi_o\n30,0,30\n").unwrap();
    let (code, _, err) = goniospec(&[
        "eval",
        d.join("table.gsb").to_str().unwrap(),
        "--pairs",
        pairs.to_str().unwrap(),
    ]);
    assert_eq!(code, 1);
    assert!(err.contains("pairs.csv:2: expected 4 columns"), "{err}");
    let (code, _, err) = goniospec(&[
        "build",
        gsa.to_str().unwrap(),
        "--repr",
        "octree",
        "-o",
        "x.gsb",
    ]);
    assert_eq!(code, 2);
    assert!(err.contains("unknown representation 'octree'"), "{err}");
}

#[test]
fn render_writes_exr_and_png_and_reports_clear_errors() {
    let d = std::env::temp_dir().join(format!("goniospec-render-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let gsa = d.join("f.gsa");
    let gsb = d.join("f.gsb");
    let exr = d.join("f.exr");
    assert_eq!(
        goniospec(&[
            "simulate",
            "meshes/flat-soap-film.toml",
            "--theta-i",
            "0,20,40,60,80",
            "--rays",
            "32",
            "-o",
            gsa.to_str().unwrap()
        ])
        .0,
        0
    );
    assert_eq!(
        goniospec(&[
            "build",
            gsa.to_str().unwrap(),
            "--repr",
            "table",
            "-o",
            gsb.to_str().unwrap()
        ])
        .0,
        0
    );
    let (code, out, err) = goniospec(&[
        "render",
        gsb.to_str().unwrap(),
        "-o",
        exr.to_str().unwrap(),
        "--width",
        "64",
        "--height",
        "48",
        "--spp",
        "2",
        "--light",
        "none",
        "--analytic",
        "meshes/flat-soap-film.toml",
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("mean CIE DE2000"), "{out}");
    let png = std::fs::read(d.join("f.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    let exr_bytes = std::fs::read(&exr).unwrap();
    assert_eq!(&exr_bytes[..4], &[0x76, 0x2f, 0x31, 0x01], "EXR magic");
    // A corrupted .gsb and a missing OBJ.
    let mut bad = std::fs::read(&gsb).unwrap();
    let n = bad.len();
    bad[n / 2] ^= 0xff;
    std::fs::write(d.join("bad.gsb"), bad).unwrap();
    let (code, _, err) = goniospec(&[
        "render",
        d.join("bad.gsb").to_str().unwrap(),
        "-o",
        exr.to_str().unwrap(),
    ]);
    assert_eq!(code, 1);
    assert!(err.contains("checksum mismatch"), "{err}");
    let (code, _, err) = goniospec(&[
        "render",
        gsb.to_str().unwrap(),
        "-o",
        exr.to_str().unwrap(),
        "--shape",
        "nowhere/teapot.obj",
    ]);
    assert_eq!(code, 1);
    assert!(
        err.contains("nowhere/teapot.obj") && err.contains("cannot read file"),
        "{err}"
    );
}

/// `render --simulate`: a flat panel lit from 40 degrees with no environment needs three
/// of the 18 grid angles; the run reports the saving, writes the .gsa/.gsb beside the
/// image, and its image agrees with the analytic TMM image of the same film.
#[test]
fn render_simulate_models_only_what_the_image_needs() {
    let d = std::env::temp_dir().join(format!("goniospec-render-sim-{}", std::process::id()));
    let exr = d.join("panel.exr");
    // A plane under a directional light, simulated from `sample` into `out` in `d`.
    let plane = |sample: &str, out: &str, rest: &[&str]| {
        let out = d.join(out);
        let mut args = vec![
            "render",
            "--simulate",
            sample,
            "-o",
            out.to_str().unwrap(),
            "--shape",
            "plane",
            "--light",
            "dir:40,-90",
            "--env",
            "none",
        ];
        args.extend_from_slice(rest);
        goniospec(&args)
    };
    let (code, out, err) = plane(
        "meshes/flat-soap-film.toml",
        "panel.exr",
        &["--width", "48", "--height", "48", "--spp", "2"],
    );
    assert_eq!(code, 0, "{err}");
    assert!(
        err.contains("needs 3 of the 18 incident angles") && err.contains("[35.0, 40.0, 45.0]"),
        "{err}"
    );
    let saved: f64 = err
        .split(" % saved")
        .next()
        .and_then(|s| s.rsplit(' ').next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no saving reported: {err}"));
    assert!(saved >= 83.0, "{err}");
    assert!(out.contains("rendered 48x48"), "{out}");
    for f in ["panel.gsa", "panel.gsb", "panel.png"] {
        assert!(d.join(f).exists(), "{f} missing");
    }
    // The simulated BRDF renders like the analytic film under a constant environment at
    // the viewing angles the panel shows (a second scene-driven run). The residual is the
    // table's linear interpolation between grid angles, not noise: mean DE2000 1.36 with
    // the 5-degree grid at tolerance 0.05 and at 0.01 alike, 0.92 with a 2.5-degree grid.
    let (code, out, err) = goniospec(&[
        "render",
        "--simulate",
        "meshes/flat-soap-film.toml",
        "-o",
        d.join("env.exr").to_str().unwrap(),
        "--shape",
        "plane",
        "--light",
        "none",
        "--theta-step",
        "2.5",
        "--width",
        "48",
        "--height",
        "48",
        "--analytic",
        "meshes/flat-soap-film.toml",
    ]);
    assert_eq!(code, 0, "{err}");
    let de: f64 = out
        .split("mean CIE DE2000 ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no DE2000: {out}"));
    // Below one just-noticeable difference (DE2000 = 1; Sharma, Wu & Dalal 2005): the
    // simulated film is indistinguishable from the analytic one on average.
    assert!(de < 1.0, "mean DE2000 {de}: {out}");
    // The flat film converges; a rough sample on a budget that cannot is said to fall
    // short before it is rendered (issue 49: 0 of 18 converged and it rendered anyway,
    // silently).
    assert!(!err.contains("did not reach --tolerance"), "{err}");
    // A 16 x 16 image on a small budget.
    let small = |sample: &str, out: &str, budget: &[&str]| {
        let mut rest = vec![
            "--width", "16", "--height", "16", "--spp", "1", "--rays", "128",
        ];
        rest.extend_from_slice(budget);
        plane(sample, out, &rest)
    };
    let (code, out, err) = small("meshes/rough-gold.toml", "gold.exr", &["--max-rays", "128"]);
    assert_eq!(code, 0, "{err}");
    assert!(
        err.contains(
            "warning: 3 of 3 directions did not reach --tolerance 0.05 within --max-rays 128"
        ),
        "{err}"
    );
    assert!(out.contains("rendered 16x16"), "{out}");
    // By the BRDF's own figure (--target-stderr, issue 49): a target the budget cannot
    // reach on rough gold is said before rendering in the same words; the flat film, all
    // of whose light is in its mirror bucket, converges.
    let target = |sample: &str| {
        small(
            sample,
            "target.exr",
            &["--max-rays", "256", "--target-stderr", "0.05"],
        )
    };
    let (code, _, err) = target("meshes/rough-gold.toml");
    assert_eq!(code, 0, "{err}");
    assert!(
        err.contains("did not reach --target-stderr 0.05 within --max-rays 256")
            && err.contains("loosen --target-stderr"),
        "{err}"
    );
    let (code, _, err) = target("meshes/flat-soap-film.toml");
    assert_eq!(code, 0, "{err}");
    assert!(
        err.contains("median relative standard error of the bright buckets")
            && err.contains("converged to --target-stderr 0.05")
            && !err.contains("did not reach"),
        "{err}"
    );
    // Either a .gsb or --simulate, and clear errors for bad settings.
    let (code, _, err) = goniospec(&["render", "-o", exr.to_str().unwrap()]);
    assert_eq!(code, 2, "{err}");
    let (code, _, err) = goniospec(&[
        "render",
        "--simulate",
        "meshes/flat-soap-film.toml",
        "-o",
        exr.to_str().unwrap(),
        "--tolerance",
        "0",
    ]);
    assert_eq!(code, 1);
    assert!(
        err.contains("--tolerance must be a positive number"),
        "{err}"
    );
}

/// Issue "nothing crashes": non-finite numbers, outputs over inputs, a full stdout and
/// grazing analytic angles. Each case: its exit status, a message naming the flag or file,
/// and no output written (inputs intact).
#[test]
fn bad_numbers_outputs_and_stdout_are_refused_cleanly() {
    let d = std::env::temp_dir().join(format!("goniospec-robust-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let sample = d.join("v.toml");
    std::fs::copy(root.join("meshes/flat-soap-film.toml"), &sample).unwrap();
    let original = std::fs::read(&sample).unwrap();
    let p = |x: &std::path::Path| x.to_str().unwrap().to_string();
    let out = d.join("o.gsa");
    let sim = |extra: &[&str], o: &str| {
        let mut args = vec![
            "simulate".to_string(),
            p(&sample),
            "--rays".into(),
            "4".into(),
        ];
        args.extend(extra.iter().map(|s| s.to_string()));
        args.extend(["-o".into(), o.to_string()]);
        let a: Vec<&str> = args.iter().map(|s| s.as_str()).collect();
        goniospec(&a)
    };
    // Non-finite numbers: usage errors (exit 2) naming the flag, nothing written.
    for (flag, value) in [
        ("--phi-i", "nan"),
        ("--theta-i", "inf"),
        ("--cutoff", "nan"),
    ] {
        let (code, _, err) = sim(&[flag, value], &p(&out));
        assert_eq!(code, 2, "{flag} {value}: {err}");
        assert!(err.contains(flag), "{flag}: {err}");
        assert!(!out.exists(), "{flag} {value}: an output appeared");
    }
    // Sizes that cannot fit or finish: refused before allocating, naming the flags.
    for (args, flag) in [
        (&["--wavelengths", "380:780:0.001"][..], "--wavelengths"),
        (
            &["--theta-o-bins", "65536", "--phi-o-bins", "65536"][..],
            "--theta-o-bins",
        ),
        (&["--max-rays", "18446744073709551615"][..], "--max-rays"),
        (&["--threads", "100000"][..], "--threads"),
    ] {
        let (code, _, err) = sim(args, &p(&out));
        assert_eq!(code, 1, "{args:?}: {err}");
        assert!(err.contains(flag), "{args:?}: {err}");
        assert!(!out.exists(), "{args:?}: an output appeared");
    }
    // Output over input: refused, the sample intact.
    let (code, _, err) = sim(&[], &p(&sample));
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("is the input"), "{err}");
    assert_eq!(std::fs::read(&sample).unwrap(), original);
    let (code, _, err) = goniospec(&["generate", "flat", "-o", &p(&sample)]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("--force"), "{err}");
    assert_eq!(std::fs::read(&sample).unwrap(), original);
    // A real run, then build onto itself and render options out of range.
    let (code, _, err) = sim(
        &["--theta-i", "30", "--wavelengths", "500", "--monochromatic"],
        &p(&out),
    );
    assert_eq!(code, 0, "{err}");
    let (code, _, err) = goniospec(&["build", &p(&out), "-o", &p(&out)]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("is the input"), "{err}");
    // A kd-tree the reader would refuse (k above 1024) and a negative split tolerance
    // are usage errors, and nothing is written.
    let k_out = d.join("k.gsb");
    for args in [["--k", "5000"], ["--tolerance=-1", "--repr=subdivided"]] {
        let (code, _, err) = goniospec(&["build", &p(&out), args[0], args[1], "-o", &p(&k_out)]);
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(
            err.contains(args[0].split('=').next().unwrap()),
            "{args:?}: {err}"
        );
        assert!(!k_out.exists(), "{args:?}: an output appeared");
    }
    let (code, _, err) = goniospec(&[
        "eval",
        &p(&out),
        "--theta-i",
        "30",
        "--theta-o",
        "30",
        "--phi-i",
        "nan",
    ]);
    assert_eq!(code, 2, "{err}");
    // Analytic at grazing incidence: the limit, not NaN.
    let (code, stdout, err) = goniospec(&[
        "analytic",
        "meshes/flat-soap-film.toml",
        "--theta-i",
        "89.9999999",
        "--wavelengths",
        "500",
        "--monochromatic",
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(!stdout.contains("NaN"), "{stdout}");
    // A reader that stops early (`| head -1`): 8001 rows (about 0.5 MB) overflow the pipe,
    // so the writer meets the closed pipe; it ends quietly with status 0, never a panic.
    {
        use std::io::BufRead;
        let mut child = Command::new(env!("CARGO_BIN_EXE_goniospec"))
            .args([
                "analytic",
                "meshes/flat-soap-film.toml",
                "--theta-i",
                "30",
                "--wavelengths",
                "380:780:0.05",
                "--monochromatic",
            ])
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let mut first = String::new();
        std::io::BufReader::new(child.stdout.take().unwrap())
            .read_line(&mut first)
            .unwrap();
        assert!(first.starts_with("lambda_nm"), "{first}");
        let o = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(0), "{err}");
        assert!(err.is_empty(), "{err}");
    }
    // A full standard output (Linux's /dev/full): an error with exit 1, not a panic.
    #[cfg(target_os = "linux")]
    {
        let full = std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/full")
            .unwrap();
        let gsb = d.join("o.gsb");
        let (code, _, err) = goniospec(&["build", &p(&out), "-o", &p(&gsb)]);
        assert_eq!(code, 0, "{err}");
        for args in [
            vec![
                "reflectance".to_string(),
                p(&out),
                "--theta-i".into(),
                "30".into(),
            ],
            vec!["check".to_string(), p(&sample)],
            vec![
                "eval".to_string(),
                p(&gsb),
                "--theta-i".into(),
                "30".into(),
                "--theta-o".into(),
                "30".into(),
            ],
            vec!["info".to_string(), p(&gsb)],
        ] {
            let o = Command::new(env!("CARGO_BIN_EXE_goniospec"))
                .args(&args)
                .stdout(full.try_clone().unwrap())
                .output()
                .unwrap();
            let err = String::from_utf8_lossy(&o.stderr);
            assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
            assert!(
                err.contains("writing to standard output") && !err.contains("panicked"),
                "{args:?}: {err}"
            );
        }
    }
}

/// Issue 12, items 2, 4 and 9: generator sizes, lengths after unit scaling and sample
/// syntax that used to panic, abort, hang or pass silently. Each is refused with exit 1,
/// a message naming the key (and line, where the sample file has one), and no output.
#[test]
fn sizes_lengths_and_shapes_are_refused_before_work() {
    let d = std::env::temp_dir().join(format!("goniospec-limits-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let out = d.join("o.obj");
    let o = out.to_str().unwrap();
    for (args, says) in [
        (
            &[
                "v-grooves",
                "-p",
                "angle_deg=90",
                "-p",
                "count=9223372036854775807",
            ][..],
            "count",
        ),
        (
            &[
                "pigment-spheres",
                "-p",
                "radius=1",
                "-p",
                "volume_fraction=0.1",
                "-p",
                "layer=[0,inf]",
            ][..],
            "layer",
        ),
        (
            &[
                "flakes",
                "-p",
                "size=1",
                "-p",
                "thickness=0.1",
                "-p",
                "tilt_sd_deg=5",
                "-p",
                "volume_fraction=0.1",
                "-p",
                "layer=[0,inf]",
            ][..],
            "layer",
        ),
        (
            &[
                "pigment-spheres",
                "-p",
                "radius=0.0001",
                "-p",
                "volume_fraction=0.1",
                "-p",
                "layer=[0,1]",
            ][..],
            "limits are 1000000 bodies",
        ),
        (
            &[
                "pigment-spheres",
                "-p",
                "radius=0.05",
                "-p",
                "volume_fraction=0.3",
                "-p",
                "layer=[0,1]",
                "-p",
                "subdivisions=0",
                "--tile",
                "10,10",
            ][..],
            "random sequential addition",
        ),
        (&["flat", "-p", "z=nan"][..], "NaN"),
        (
            &["cosine", "-p", "amplitude=1e308", "-p", "resolution=16"][..],
            "amplitude",
        ),
        (
            &[
                "flakes",
                "-p",
                "size=1",
                "-p",
                "thickness=0.1",
                "-p",
                "tilt_sd_deg=5",
                "-p",
                "volume_fraction=0.1",
                "-p",
                "layer=[0,1,2]",
            ][..],
            "[z0, z1]",
        ),
    ] {
        let mut a = vec!["generate"];
        a.extend_from_slice(args);
        a.extend_from_slice(&["-o", o]);
        let (code, _, err) = goniospec(&a);
        assert_eq!(code, 1, "{args:?}: {err}");
        assert!(
            err.contains(says) && !err.contains("panicked"),
            "{args:?}: {err}"
        );
        assert!(!out.exists(), "{args:?}: an output appeared");
    }

    // Sample files: a flat glass sheet, meshed, with one value changed.
    let sheet = "[sample]\nname = \"glass sheet\"\nunit = \"um\"\ntile = [20, 20]\n[media.air]\nn = 1.0\n[media.glass]\nn = 1.5\n[stack]\nmode = \"mesh\"\nambient = \"air\"\nlayers = [{ medium = \"glass\", thickness = 1.0 }]\nsubstrate = \"air\"\n";
    let s = d.join("s.toml");
    for (from, to, line, says) in [
        ("tile = [20, 20]", "tile = [1e306, 1e306]", 4, "tile side x"),
        (
            "tile = [20, 20]",
            "tile = [20, 20, 1]",
            4,
            "tile must be [Lx, Ly]",
        ),
        (
            "thickness = 1.0",
            "thickness = 1e306",
            12,
            "layer thickness",
        ),
        (
            "thickness = 1.0",
            "thickness = 1e17",
            12,
            "exceeds the 1e8 nm",
        ),
        (
            "thickness = 1.0",
            "thickness = 1e9",
            12,
            "exceeds the 1e8 nm",
        ),
        (
            "thickness = 1.0",
            "thickness = 1e-300",
            12,
            "thinner than f32 geometry",
        ),
    ] {
        std::fs::write(&s, sheet.replace(from, to)).unwrap();
        let (code, _, err) = goniospec(&["check", s.to_str().unwrap()]);
        assert_eq!(code, 1, "{to}: {err}");
        assert!(
            err.contains(&format!("s.toml:{line}:")) && err.contains(says),
            "{to}: {err}"
        );
    }
    // Devices are not read forever, work that cannot finish is refused, and an output
    // folder that cannot be written is found before any work.
    #[cfg(target_os = "linux")]
    for (args, code_want, says) in [
        (&["check", "/dev/urandom"][..], 1, "is a device"),
        (
            &["info", "/dev/zero"][..],
            1,
            "not a .gsa, .gsb or .bsdf file",
        ),
        (
            &[
                "simulate",
                "meshes/flat-soap-film.toml",
                "--tolerance",
                "1e-320",
                "-o",
                o,
            ][..],
            1,
            "--tolerance",
        ),
        (
            &["render", "x.gsb", "--width", "99999", "-o", "x.exr"][..],
            2,
            "--width",
        ),
        (
            &["render", "x.gsb", "--spp", "4294967296", "-o", "x.exr"][..],
            2,
            "--spp",
        ),
        (
            // /proc takes no new files, even from root.
            &[
                "simulate",
                "meshes/flat-soap-film.toml",
                "-o",
                "/proc/goniospec-x.gsa",
            ][..],
            1,
            "cannot write",
        ),
    ] {
        let (code, _, err) = goniospec(args);
        assert_eq!(code, code_want, "{args:?}: {err}");
        assert!(
            err.contains(says) && !err.contains("panicked"),
            "{args:?}: {err}"
        );
    }
    // The same 1e-300 nm layer as an exact coating is fine: no geometry to collapse. The
    // TMM of a vanishing layer between air and air reflects nothing.
    std::fs::write(
        &s,
        sheet
            .replace("thickness = 1.0", "thickness = 1e-300")
            .replace("mode = \"mesh\"\n", ""),
    )
    .unwrap();
    let (code, stdout, err) = goniospec(&[
        "analytic",
        s.to_str().unwrap(),
        "--theta-i",
        "0",
        "--wavelengths",
        "500",
        "--monochromatic",
    ]);
    assert_eq!(code, 0, "{err}");
    let row = stdout.lines().last().unwrap();
    let r: f64 = row.split(',').nth(3).unwrap().parse().unwrap(); // lambda,Rs,Rp,R,...
    assert!(r.abs() < 1e-12, "{stdout}");
}

/// Issue 30, one output policy: an output is never a file the run reads (a sample's own
/// height map or media table), never a file of another kind unless --force, and a prefix
/// must name a file. Each refusal leaves the file as it was; --force then writes it.
#[test]
fn outputs_never_replace_inputs_or_foreign_files() {
    let d = std::env::temp_dir().join(format!("goniospec-outputs-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    let p = |x: &std::path::Path| x.to_str().unwrap().to_string();
    // A sample with a media table and a mesh beside it.
    std::fs::write(d.join("n.csv"), "lambda_nm,n,k\n300,1.5,0\n900,1.5,0\n").unwrap();
    let (code, _, err) = goniospec(&[
        "generate",
        "flat",
        "--tile",
        "10,10",
        "-o",
        &p(&d.join("flat.obj")),
    ]);
    assert_eq!(code, 0, "{err}");
    std::fs::write(
        d.join("s.toml"),
        "[sample]\nname = \"glass\"\nunit = \"um\"\ntile = [10.0, 10.0]\n[media.air]\nn = 1.0\n[media.glass]\ntable = \"n.csv\"\n[[interface]]\nmesh = \"flat.obj\"\nfront = \"air\"\nback = \"glass\"\n",
    )
    .unwrap();
    let table = std::fs::read(d.join("n.csv")).unwrap();
    let sample_path = p(&d.join("s.toml"));
    let sim = |o: &str, extra: &[&str]| {
        let mut a = vec![
            "simulate",
            sample_path.as_str(),
            "--rays",
            "4",
            "--theta-i",
            "30",
            "--wavelengths",
            "500",
            "--monochromatic",
            "-o",
            o,
        ];
        a.extend(extra);
        goniospec(&a)
    };
    // simulate --force over the sample's own media table: still refused.
    let (code, _, err) = sim(&p(&d.join("n.csv")), &["--force"]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("is the input"), "{err}");
    assert_eq!(std::fs::read(d.join("n.csv")).unwrap(), table);
    let gsa = d.join("o.gsa");
    let (code, _, err) = sim(&p(&gsa), &[]);
    assert_eq!(code, 0, "{err}");
    let (code, _, err) = goniospec(&["build", &p(&gsa), "-o", &p(&d.join("o.gsb"))]);
    assert_eq!(code, 0, "{err}");
    // fit, plot and render over a foreign file: refused without --force, written with it.
    let notes = b"my notes\n".to_vec();
    for (tag, args, target) in [
        (
            "fit",
            vec!["fit", &p(&gsa), "-o", &p(&d.join("f"))],
            d.join("f.json"),
        ),
        (
            "plot",
            vec![
                "plot",
                &p(&d.join("o.gsb")),
                "--theta-i",
                "30",
                "-o",
                &p(&d.join("l.png")),
            ],
            d.join("l.png"),
        ),
        (
            "render",
            vec![
                "render",
                &p(&d.join("o.gsb")),
                "--width",
                "8",
                "--height",
                "8",
                "--spp",
                "1",
                "-o",
                &p(&d.join("r.exr")),
            ],
            d.join("r.png"),
        ),
    ] {
        std::fs::write(&target, &notes).unwrap();
        let (code, _, err) = goniospec(&args);
        assert_eq!(code, 1, "{tag}: {err}");
        assert!(err.contains("--force"), "{tag}: {err}");
        assert_eq!(std::fs::read(&target).unwrap(), notes, "{tag}: changed");
        let mut forced = args.clone();
        forced.push("--force");
        let (code, _, err) = goniospec(&forced);
        assert_eq!(code, 0, "{tag} --force: {err}");
        assert_ne!(std::fs::read(&target).unwrap(), notes, "{tag}: not written");
        // A second run replaces its own kind of file without --force.
        let (code, _, err) = goniospec(&args);
        assert_eq!(code, 0, "{tag} again: {err}");
    }
    // fit -o . (it wrote ..json with exit 0) and render --simulate over a foreign .gsa.
    for prefix in [".", ".."] {
        let (code, _, err) = goniospec(&["fit", &p(&gsa), "-o", prefix]);
        assert_eq!(code, 1, "{prefix}: {err}");
        assert!(err.contains("not a file prefix"), "{err}");
    }
    assert!(!std::path::Path::new("..json").exists());
    std::fs::write(d.join("scene.gsa"), &notes).unwrap();
    let (code, _, err) = goniospec(&[
        "render",
        "--simulate",
        &p(&d.join("s.toml")),
        "--width",
        "8",
        "--height",
        "8",
        "-o",
        &p(&d.join("scene.exr")),
    ]);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("scene.gsa") && err.contains("--force"),
        "{err}"
    );
    assert_eq!(std::fs::read(d.join("scene.gsa")).unwrap(), notes);
    let _ = std::fs::remove_dir_all(&d);
}

/// Issue 74's rules on the newest surfaces: a Stokes vector judged on its direction, not
/// its scale (the check overflowed at 1e200 and underflowed at 1e-170), a negative S0
/// reaching that check instead of "unexpected argument"; `mie` refusing the indices
/// samples refuse, and saying that an index-matched sphere's asymmetry is undefined; an
/// adaptive budget below its own start refused.
#[test]
fn stokes_vectors_mie_indices_and_budgets_are_judged_by_their_meaning() {
    let d = std::env::temp_dir().join(format!("goniospec-cli-74-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let gsa = d.join("gold.gsa");
    let (code, _, err) = goniospec(&[
        "simulate",
        "meshes/rough-gold.toml",
        "--theta-i",
        "0",
        "--rays",
        "16",
        "--wavelengths",
        "500:600:100",
        "-o",
        gsa.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    for st in [
        "1e200,1e200,1e200,0",
        "1e-170,1e-170,1e-170,1e-170",
        "-1,0,0,0",
    ] {
        let (code, _, err) = goniospec(&[
            "build",
            gsa.to_str().unwrap(),
            "--incident",
            st,
            "-o",
            d.join("st.gsb").to_str().unwrap(),
        ]);
        assert_eq!(code, 2, "{st}");
        assert!(err.contains("is not a polarisation state"), "{st}: {err}");
    }
    let (code, _, err) = goniospec(&["mie", "--n", "1e-100", "--x", "1"]);
    assert_eq!(code, 1);
    assert!(err.contains("--n must be between 1e-9 and 100"), "{err}");
    let (code, out, err) = goniospec(&["mie", "--n", "1.5", "--host", "1.5", "--x", "2"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("q_sca: 0.0000000000e0"), "{out}");
    assert!(out.contains("g: undefined"), "{out}");
    assert!(!out.to_lowercase().contains("nan"), "{out}");
    let (code, _, err) = goniospec(&[
        "simulate",
        "meshes/rough-gold.toml",
        "--theta-i",
        "0",
        "--rays",
        "64",
        "--max-rays",
        "1",
        "--target-stderr",
        "0.05",
        "-o",
        d.join("mr.gsa").to_str().unwrap(),
    ]);
    assert_eq!(code, 1);
    assert!(err.contains("--max-rays: 1 is below --rays 64"), "{err}");
    assert!(!d.join("mr.gsa").exists());
}

/// `analytic --theta-i` takes a list as `simulate` does (issue 71: `--theta-i 45,56.31` was
/// refused): each row starts with its angle, the rows of an angle are that angle's alone
/// (the same digits as asked on its own), and at normal incidence s and p are one wave
/// (Rs = Rp, Ts = Tp). An angle outside [0, 90) is refused before anything is printed.
#[test]
fn analytic_takes_a_list_of_angles() {
    let args = |angles: &str| {
        goniospec(&[
            "analytic",
            "meshes/flat-soap-film.toml",
            "--theta-i",
            angles,
            "--wavelengths",
            "400:700:100",
        ])
    };
    let (code, both, err) = args("0,56.31");
    assert_eq!(code, 0, "{err}");
    let mut lines = both.lines();
    assert_eq!(
        lines.next(),
        Some("theta_i_deg,lambda_nm,Rs,Rp,R,Ts,Tp,T,delta_deg")
    );
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 6, "{both}");
    for row in rows.iter().filter(|r| r[0] == "0") {
        assert_eq!(row[2], row[3], "Rs = Rp at normal incidence: {row:?}");
        assert_eq!(row[5], row[6], "Ts = Tp at normal incidence: {row:?}");
    }
    let (code, alone, err) = args("56.31");
    assert_eq!(code, 0, "{err}");
    let alone: Vec<&str> = alone.lines().skip(1).collect();
    let listed: Vec<String> = rows
        .iter()
        .filter(|r| r[0] == "56.31")
        .map(|r| r[1..].join(","))
        .collect();
    assert_eq!(listed, alone);
    let (code, out, err) = args("30,95");
    assert_eq!(code, 1);
    assert!(out.is_empty() && err.contains("got 95"), "{out} {err}");
}

/// `eval --help` states the Stokes sign convention and SCATMECH's (issue 71: its users
/// had to find that S1 = I_p - I_s flips against theirs).
#[test]
fn eval_help_states_the_stokes_convention() {
    let (code, out, err) = goniospec(&["eval", "--help"]);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains("S1 = I_p - I_s")
            && out.contains("SCATMECH")
            && out.contains("diag(1, -1, -1, 1)"),
        "{out}"
    );
}
