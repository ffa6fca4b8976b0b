//! `bench converge`'s measures: the bright buckets' median relative error, and its check
//! against a second seed.

use goniospec::accumulate::file::Accumulator;
use goniospec::accumulate::{Cell, stderr};
use goniospec::bench::{bucket_noise, seed_check};
use goniospec::sample::{self, MeshOptions};
use goniospec::simulate::bright_buckets;
use goniospec::simulate::{SimConfig, Wavelengths, simulate};

fn run(seed: u64, random_entry: bool, rays: u64) -> Accumulator {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let s = sample::load(&root.join("meshes/rough-gold.toml"), MeshOptions::default()).unwrap();
    let mut cfg = SimConfig::new(
        vec![30.0],
        Wavelengths::Bins(vec![500.0, 540.0, 580.0, 620.0]),
        rays,
    );
    cfg.seed = seed;
    cfg.random_entry = random_entry;
    simulate(&s, &cfg, &|_| {}).unwrap().0
}

/// With independent uniform entry points every tree is an independent sample, so the
/// estimator's standard errors are honest: two seeds differ by a median of 0.674 of their
/// combined standard error (the median of |Z|), here within 0.1 (the median of a few
/// hundred buckets' |Z| scatters by about 0.05, and buckets hit by few trees are not quite
/// normal). The measured relative error agrees with the estimator's within 25 %.
#[test]
fn with_independent_trees_two_seeds_confirm_the_estimators_errors() {
    let (a, b) = (run(1, true, 2048), run(2, true, 2048));
    let (z, measured) = seed_check(&a, &b, 0, 0.95).unwrap();
    assert!((z - 0.674).abs() < 0.1, "median |a - b| / se = {z}");
    let estimated = bucket_noise(&a, 0, 0.95).unwrap();
    assert!(
        (measured / estimated - 1.0).abs() < 0.25,
        "measured {measured} against estimated {estimated}"
    );
}

/// With the default R2 entry points, quasi-Monte Carlo, trees are not independent and the
/// per-tree spread overstates the error (issue 49: 3-7x at the counts `bench converge`
/// reaches). The replicate groups' spread (independent shifts, `ERROR_GROUPS` of them) is
/// honest: over 24 seeds of the seed's film (16,384 trees, four 40 nm bins at 30 deg),
/// each bright bucket's standard deviation across the seeds against the root mean square
/// of the standard errors the runs report has a median of 1 within 0.15 (the median over
/// buckets of a 23-degree-of-freedom sample deviation is 0.99 of sigma; the buckets of one
/// run share its shifts, so their ratios move together and the margin is wider than the
/// median's own scatter). The per-tree spread of the same runs is checked to overstate it
/// (ratio below 0.8: 0.67-0.70 measured), so the test tells the two estimates apart.
/// One pair of seeds is no such check under QMC: the same correlation moves a pair's
/// median |z| between 0.53 and 1.01 over pairs of these runs.
#[test]
fn with_quasi_random_entry_points_the_replicate_groups_errors_are_honest() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let film = sample::load(
        &root.join("meshes/thin-film-600nm.toml"),
        MeshOptions::default(),
    )
    .unwrap();
    let runs: Vec<Accumulator> = (1..=24)
        .map(|seed| {
            let mut cfg = SimConfig::new(
                vec![30.0],
                Wavelengths::Bins(vec![420.0, 460.0, 500.0, 540.0, 580.0]),
                16_384,
            );
            cfg.seed = seed;
            simulate(&film, &cfg, &|_| {}).unwrap().0
        })
        .collect();
    assert!(
        runs.iter()
            .all(|a| a.cells.iter().all(|c| !c.var.is_empty()))
    );
    let m = runs.len() as f64;
    let mean_square = |se: &dyn Fn(&Cell, usize) -> f64, j: usize, k: usize| {
        runs.iter()
            .map(|a| se(a.cell(0, j), k).powi(2))
            .sum::<f64>()
            / m
    };
    let group = |c: &Cell, k: usize| c.sum_var(k).sqrt() / c.trees as f64;
    let per_tree = |c: &Cell, k: usize| stderr(c.sum[k], c.sumsq[k], c.trees);
    let (mut by_group, mut by_tree) = (Vec::new(), Vec::new());
    for (j, k) in bright_buckets(runs[0].direction_cells(0), 0.95) {
        let f: Vec<f64> = runs
            .iter()
            .map(|a| a.cell(0, j).sum[k] / a.cell(0, j).trees as f64)
            .collect();
        let mean = f.iter().sum::<f64>() / m;
        let sd = (f.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (m - 1.0)).sqrt();
        by_group.push(sd / mean_square(&group, j, k).sqrt());
        by_tree.push(sd / mean_square(&per_tree, j, k).sqrt());
    }
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let n = by_group.len();
    let (g, t) = (median(by_group), median(by_tree));
    assert!(n > 50, "{n} bright buckets");
    assert!((g - 1.0).abs() < 0.15, "measured / group error {g}");
    assert!(t < 0.8, "measured / per-tree error {t}");
}

/// `bench converge --material` measures each of 8 incident angles, 0 to 80 degrees in
/// equal steps, and prints their sum per sample: one line per angle and figure, the sum
/// equal to the angles' times as printed (to their rounding), every figure a number.
#[test]
fn the_material_benchmark_measures_eight_angles_and_sums_them() {
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_goniospec"))
        .args([
            "bench",
            "converge",
            "--material",
            "--samples",
            "thin-film-600nm",
            "--target",
            "0.5",
            "--threads",
            "2",
        ])
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{out}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let value = |key: &str| -> f64 {
        let line = out
            .lines()
            .find(|l| l.starts_with(&format!("{key}: ")))
            .unwrap_or_else(|| panic!("no {key} in {out}"));
        line.split_whitespace().nth(1).unwrap().parse().unwrap()
    };
    let mut sum = 0.0;
    for k in 0..8 {
        let theta = 80.0 * k as f64 / 7.0;
        let key = format!("thin_film_600nm_theta_{theta:.0}");
        assert_eq!(value(&format!("{key}_target_reached")), 1.0, "{out}");
        let t = value(&format!("{key}_seconds"));
        assert!(t > 0.0 && t.is_finite(), "{out}");
        assert!(value(&format!("{key}_median_rel_stderr")) <= 0.5, "{out}");
        sum += t;
    }
    let total = value("thin_film_600nm_material_seconds");
    assert!(
        (total - sum).abs() <= 0.005 * 8.0 + 1e-9,
        "{total} against {sum}: {out}"
    );
    assert_eq!(value("thin_film_600nm_material_target_reached"), 1.0);
}
