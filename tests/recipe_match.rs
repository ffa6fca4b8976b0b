//! `goniospec match` (issue 73): a search recovers a known recipe from goniospec's own
//! simulated target, a run interrupted and resumed writes the bytes an uninterrupted run
//! writes, and bad input is refused before any simulation.
//!
//! The target is a rough grey metal (GGX facets, alpha 0.3, n = 1.2 + 3.0i) simulated with
//! another seed, more trees and finer buckets than the candidates, and exported as an RGL
//! `.bsdf`: the form a measurement takes. The search starts far from it (alpha 0.15,
//! k 5).

mod common;

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use common::{goniospec, scratch};
use goniospec::compare::Material;
use goniospec::recipe::{Metric, Search, Template, Vary, fit_angles};

const METAL: &str = r#"# A rough grey metal: GGX facets, a constant index.
[sample]
name = "rough grey metal"
unit = "um"
tile = [20.0, 20.0]

[media.air]
n = 1.0

[media.metal]
n = 1.2
k = K

[[interface]]
generator = { kind = "microfacet", distribution = "ggx", alpha = ALPHA, resolution = 64 }
front = "air"
back = "metal"
"#;

const TRUTH: [f64; 2] = [0.3, 3.0];
const START: [f64; 2] = [0.15, 5.0];
const WAVELENGTHS: &str = "400:700:30";

fn metal(dir: &Path, name: &str, [alpha, k]: [f64; 2]) -> PathBuf {
    let p = dir.join(name);
    let text = METAL
        .replace("ALPHA", &format!("{alpha:?}"))
        .replace("K", &format!("{k:?}"));
    std::fs::write(&p, text).unwrap();
    p
}

/// A cheap match of the target from the start (two parameters, 1,024 trees, 5 bins)
/// writing into `out`, with `rest` added.
fn small_match(out: &Path, rest: &[&str]) -> Vec<String> {
    let (bsdf, start) = target();
    let mut v: Vec<String> = [
        "match",
        &start.to_string_lossy(),
        "--measured",
        &bsdf.to_string_lossy(),
        "--vary",
        "interface.0.generator.alpha=0.1:0.6",
        "--vary",
        "media.metal.k=1:6",
        "--rays",
        "1024",
        "--wavelengths",
        "400:700:60",
        "-o",
        &out.to_string_lossy(),
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    v.extend(rest.iter().map(|s| s.to_string()));
    v
}

/// The candidates a match's summary counts as repeated or read from records.
fn repeated(out: &str) -> usize {
    let at = out
        .find(" repeated or read from records")
        .expect("the search's summary");
    let head = &out[..at];
    head[head.rfind(' ').unwrap() + 1..].parse().unwrap()
}

fn refs(v: &[String]) -> Vec<&str> {
    v.iter().map(String::as_str).collect()
}

fn run(args: &[&str]) -> String {
    let (code, out, err) = goniospec(args);
    assert_eq!(code, 0, "goniospec {args:?} failed:\n{out}\n{err}");
    out
}

/// The target: the truth at 0 to 80 deg (seed 7, 32,768 trees, 30 x 24 buckets), built
/// into a table and exported as an RGL tensor file. Made once for the file's tests.
fn target() -> &'static (PathBuf, PathBuf) {
    static T: OnceLock<(PathBuf, PathBuf)> = OnceLock::new();
    T.get_or_init(|| {
        let d = scratch("match-target");
        let truth = metal(&d, "truth.toml", TRUTH);
        let s = |p: &str| d.join(p).to_string_lossy().into_owned();
        let truth_s = truth.to_string_lossy().into_owned();
        run(&[
            "simulate",
            &truth_s,
            "--theta-i",
            "0,10,20,30,40,50,60,70,80",
            "--rays",
            "32768",
            "--theta-o-bins",
            "30",
            "--phi-o-bins",
            "24",
            "--seed",
            "7",
            "--wavelengths",
            WAVELENGTHS,
            "-o",
            &s("target.gsa"),
        ]);
        run(&[
            "build",
            &s("target.gsa"),
            "--repr",
            "table",
            "-o",
            &s("target.gsb"),
        ]);
        run(&[
            "export",
            &s("target.gsb"),
            "--sample",
            &truth_s,
            "-o",
            &s("target.bsdf"),
        ]);
        let start = metal(&d, "start.toml", START);
        (d.join("target.bsdf"), start)
    })
}

fn search_over<'a>(
    template: &'a Template,
    vary: &'a [Vary],
    measured: &'a Material,
    fit: Vec<f64>,
    max_evaluations: usize,
) -> Search<'a> {
    let config = goniospec::simulate::SimSettings {
        theta_i_deg: fit.clone(),
        rays: 2048,
        seed: 1,
        wavelengths: WAVELENGTHS.into(),
        theta_o_bins: 18,
        phi_o_bins: 24,
        ..Default::default()
    }
    .resolve()
    .unwrap();
    Search {
        template,
        vary,
        measured,
        measured_key: 0,
        fit_deg: fit,
        config,
        metric: Metric::Colour,
        max_evaluations,
        starts: 0,
        tolerance: 0.02,
        records: None,
    }
}

/// Two parameters from a start far off: the search ends within 10 % of the truth in
/// each. The tolerance is one the objective resolves, checked here: a tenth off in either
/// parameter raises the error measurably above the truth's (by more than 5 times the
/// search's stopping tolerance), and the recipe found is not measurably worse than the
/// truth itself (the noise of both simulations is common to the two, as in the search).
#[test]
fn a_small_match_recovers_a_known_recipe() {
    let (bsdf, start) = target();
    let vary = [
        Vary::parse("interface.0.generator.alpha=0.1:0.6").unwrap(),
        Vary::parse("media.metal.k=1:6").unwrap(),
    ];
    let template = Template::read(start, &vary).unwrap();
    assert_eq!(template.values, START);
    let measured = Material::read(bsdf).unwrap();
    let Material::Tabulated(m) = &measured else {
        panic!("the target is a tensor file")
    };
    let angles: Vec<f64> = m.theta_i_rad.iter().map(|t| t.to_degrees()).collect();
    let (fit, held) = fit_angles(&[0.0, 30.0, 45.0], &angles).unwrap();
    assert_eq!(fit.len(), 3);
    assert!(held.len() >= 5, "{held:?}");
    let search = search_over(&template, &vary, &measured, fit, 60);
    let mut seen = 0;
    let outcome = search
        .run(&START, &mut |k, _, _| {
            seen = k;
        })
        .unwrap();
    assert_eq!(seen, outcome.trace.len());
    let best = &outcome.trace[outcome.best];
    for (k, (&got, &truth)) in best.values.iter().zip(&TRUTH).enumerate() {
        assert!(
            (got - truth).abs() <= 0.1 * truth,
            "{} = {got}, the truth {truth} (within 10 %); after {} candidates",
            vary[k].path,
            outcome.trace.len()
        );
    }
    let at = |v: [f64; 2]| search.evaluate(&v).unwrap().objective;
    let truth = at(TRUTH);
    assert!(
        best.objective <= truth + 0.05,
        "the recipe found ({}) is worse than the truth ({truth})",
        best.objective
    );
    eprintln!(
        "found {:?} ({} candidates): error {}; the truth's {truth}",
        best.values,
        outcome.trace.len(),
        best.objective
    );
    for off in [[TRUTH[0] * 1.1, TRUTH[1]], [TRUTH[0], TRUTH[1] * 0.9]] {
        let e = at(off);
        eprintln!("a tenth off {off:?}: {e}");
        assert!(
            e > truth + 5.0 * 0.02,
            "a tenth off ({off:?}: {e}) is not resolved from the truth ({truth})"
        );
    }
}

/// A match killed after a few candidates and run again resumes from the candidates'
/// records and writes the fitted sample, its simulation, the summary and the comparison
/// byte for byte as an uninterrupted run does; the trace holds the same candidates and
/// errors (only its record and time columns say what was resumed).
#[test]
fn an_interrupted_match_resumes_to_the_same_bytes() {
    let d = scratch("match-resume");
    let (whole, part) = (d.join("whole"), d.join("part"));
    let args = |out: &Path| small_match(out, &["--max-evaluations", "16"]);
    // Candidates the simplex visits twice are repeats in the whole run too.
    let repeats = repeated(&run(&refs(&args(&whole))));
    let part_args = args(&part);
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_goniospec"))
        .args(&part_args)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let records = part.join("candidates");
    let t0 = std::time::Instant::now();
    // Finished records only: a record being written is a temporary beside them.
    let count = |d: &Path| {
        std::fs::read_dir(d).map_or(0, |r| {
            r.filter(|e| {
                e.as_ref().is_ok_and(|e| {
                    let n = e.file_name().to_string_lossy().into_owned();
                    n.ends_with(".json") && !n.starts_with('.')
                })
            })
            .count()
        })
    };
    while count(&records) < 3 {
        assert!(t0.elapsed().as_secs() < 120, "no records appeared");
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(
        !part.join("fitted.toml").exists(),
        "the run finished before it was interrupted"
    );
    let kept = count(&records);
    let out = run(&refs(&part_args));
    assert_eq!(
        repeated(&out),
        kept + repeats,
        "the resumed run did not read the {kept} records:\n{out}"
    );
    for f in [
        "fitted.toml",
        "fitted.gsa",
        "match.json",
        "compare/compare.json",
        "compare/angles.csv",
    ] {
        let (a, b) = (
            std::fs::read(whole.join(f)).unwrap(),
            std::fs::read(part.join(f)).unwrap(),
        );
        assert!(a == b, "{f} differs between the whole and the resumed run");
    }
    let columns = |p: &Path| -> Vec<String> {
        std::fs::read_to_string(p.join("trace.csv"))
            .unwrap()
            .lines()
            .map(|l| l.split(',').take(5).collect::<Vec<_>>().join(","))
            .collect()
    };
    assert_eq!(columns(&whole), columns(&part));
    // The fitted sample loads from its own folder (its mesh-free recipe here, but its
    // relative file names are rewritten to reach the template's files) with the values
    // the summary gives.
    let fitted = goniospec::sample::load(&whole.join("fitted.toml"), Default::default());
    assert!(fitted.is_ok(), "{:?}", fitted.err());
    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(whole.join("match.json")).unwrap()).unwrap();
    let alpha = summary["parameters"][0]["fitted"].as_f64().unwrap();
    let text = std::fs::read_to_string(whole.join("fitted.toml")).unwrap();
    assert!(text.contains(&format!("alpha = {alpha}")), "{text}");
}

/// Each of these is refused with its reason, before any simulation and before the output
/// folder is made.
#[test]
fn bad_input_is_refused_before_any_simulation() {
    let (bsdf, start) = target();
    let d = scratch("match-bad");
    let out = d.join("out");
    let gsa = bsdf.with_file_name("target.gsa");
    let broken = d.join("broken.toml");
    std::fs::write(&broken, "[sample\n").unwrap();
    let (start, bsdf, gsa, broken, out_s) = (
        start.to_string_lossy().into_owned(),
        bsdf.to_string_lossy().into_owned(),
        gsa.to_string_lossy().into_owned(),
        broken.to_string_lossy().into_owned(),
        out.to_string_lossy().into_owned(),
    );
    // The template and the measurement, then what each case adds.
    let ok = |rest: &[&'static str]| -> Vec<String> {
        let mut v = vec![start.clone(), "--measured".into(), bsdf.clone()];
        v.extend(rest.iter().map(|s| s.to_string()));
        v
    };
    let k = ["--vary", "media.metal.k=1:6"];
    let with_k = |rest: &[&'static str]| -> Vec<String> { ok(&[&k[..], rest].concat()) };
    let cases: Vec<(Vec<String>, &str)> = vec![
        (
            ok(&["--vary", "media.metal.q=1:2"]),
            "has no 'q' in media.metal",
        ),
        (
            ok(&["--vary", "interface.0.generator.resolution=32:64"]),
            "integer 64",
        ),
        (ok(&["--vary", "sample.name=1:2"]), "not a number"),
        (ok(&["--vary", "media.metal.k=3:1"]), "is empty"),
        (ok(&["--vary", "media.metal.k=0:2:log"]), "LO > 0"),
        (
            ok(&["--vary", "interface.0.generator.alpha=-0.1:0.5"]),
            "alpha must be positive",
        ),
        (ok(&["--vary", "media.metal.n=0:2"]), "n must be positive"),
        (
            vec![
                start.clone(),
                "--measured".into(),
                gsa.clone(),
                k[0].into(),
                k[1].into(),
            ],
            "not a measured material",
        ),
        (
            vec![
                broken.clone(),
                "--measured".into(),
                bsdf.clone(),
                k[0].into(),
                k[1].into(),
            ],
            "not TOML",
        ),
        (with_k(&["--fit-angles", "0,2"]), "two asked angles"),
        (with_k(&["--max-evaluations", "3"]), "too few"),
        (
            with_k(&["--starts", "8", "--max-evaluations", "10"]),
            "8 starting points",
        ),
        (
            with_k(&["--metric", "gloss"]),
            "expected colour or lightness",
        ),
        (with_k(&["--vary", "media.metal.k=2:3"]), "twice"),
    ];
    for (args, why) in cases {
        let mut all = vec!["match"];
        all.extend(args.iter().map(String::as_str));
        all.extend(["-o", &out_s]);
        let (code, stdout, err) = goniospec(&all);
        assert_eq!(code, 1, "{all:?} was taken:\n{stdout}\n{err}");
        assert!(err.contains(why), "{all:?}: expected '{why}' in:\n{err}");
        assert!(!out.exists(), "{all:?} made the output folder");
    }
}

/// The starting points evaluated by two shards (separate processes, as GNU parallel or a
/// Slurm array runs them), then the search without a shard: the bytes of one process,
/// and the search reads every starting point from the shards' records.
#[test]
fn sharded_starting_points_give_one_process_bytes() {
    let d = scratch("match-shards");
    let args = |out: &Path, shard: Option<&str>| {
        let mut rest = vec!["--starts", "4", "--max-evaluations", "14"];
        if let Some(s) = shard {
            rest.extend(["--shard", s]);
        }
        small_match(out, &rest)
    };
    let (one, sharded) = (d.join("one"), d.join("sharded"));
    let repeats = repeated(&run(&refs(&args(&one, None))));
    // The start and 4 Halton points: shard 1 takes places 0, 2, 4; shard 2 places 1, 3.
    for (s, count) in [("1/2", 3), ("2/2", 2)] {
        let out = run(&refs(&args(&sharded, Some(s))));
        assert!(
            out.contains(&format!("shard {s}: {count} starting points recorded")),
            "{out}"
        );
        assert!(
            !sharded.join("fitted.toml").exists(),
            "a shard went on to search"
        );
    }
    let out = run(&refs(&args(&sharded, None)));
    assert_eq!(repeated(&out), 5 + repeats, "{out}");
    for f in [
        "fitted.toml",
        "fitted.gsa",
        "match.json",
        "compare/compare.json",
    ] {
        let (a, b) = (
            std::fs::read(one.join(f)).unwrap(),
            std::fs::read(sharded.join(f)).unwrap(),
        );
        assert!(a == b, "{f} differs between one process and the shards");
    }
}
