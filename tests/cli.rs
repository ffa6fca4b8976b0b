//! The `goniospec` binary as a user runs it: output formats, errors and exit codes.

use std::process::Command;

fn goniospec(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_goniospec"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("run goniospec");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

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
    let (code, out, err) = goniospec(&["check", "meshes/wavy-soap-film.toml"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("9216 triangles"), "{out}");
    assert!(out.contains("front air / back soap"), "{out}");
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
