//! The study command: error columns against an independent TMM, the Monte Carlo
//! convergence slope on a rough sample, outputs, and bad study files.

mod common;

use common::*;

#[test]
fn flat_film_errors_match_an_independent_tmm_within_their_error_bars() {
    let d = scratch("study-flat");
    std::fs::write(
        d.join("s.toml"),
        format!(
            "[study]\nname = \"flat\"\nsample = \"{}\"\ntheta_i = [0.0, 30.0]\nwavelengths = \"400:700:50\"\n[sweep]\nrays = [64, 256]\ncoherence_radius_nm = [inf]\n",
            root().join("studies/samples/flat-soap-film-meshed.toml").display()
        ),
    )
    .unwrap();
    let st = goniospec::study::load(&d.join("s.toml")).unwrap();
    let (points, reference) = goniospec::study::run(&st, |_| {}).unwrap();
    assert!(reference.contains("TMM"));
    assert_eq!(points.len(), 2);
    // The reference itself against the independent TMM of tests/common, band-averaged.
    let n = |_: f64| vec![c(1.0, 0.0), c(1.33, 0.0), c(1.0, 0.0)];
    for th in [0.0f64, 30.0] {
        for w in st.edges.windows(2) {
            let lib = goniospec::optics::tmm::solve_band(
                |l| {
                    goniospec::reference::stack_indices(
                        &goniospec::sample::load(&st.sample_path, Default::default()).unwrap(),
                        l,
                    )
                    .unwrap()
                },
                w[0],
                w[1],
                th.to_radians(),
            )
            .r();
            let (ind, _) = tmm_band(n, &[600.0], w[0], w[1], th.to_radians());
            assert!(
                (lib - ind).abs() < 1e-5,
                "reference {lib} vs independent {ind}"
            );
        }
    }
    goniospec::study::write(&st, &points, &reference, &d.join("out")).unwrap();
    let csv = std::fs::read_to_string(d.join("out/points.csv")).unwrap();
    let mut rows = csv.lines();
    let header: Vec<&str> = rows.next().unwrap().split(',').collect();
    let (ei, si) = (
        header.iter().position(|h| *h == "error").unwrap(),
        header.iter().position(|h| *h == "error_stderr").unwrap(),
    );
    for row in rows {
        let f: Vec<&str> = row.split(',').collect();
        let (e, s): (f64, f64) = (f[ei].parse().unwrap(), f[si].parse().unwrap());
        // A flat film's trees are identical, so its error bars vanish and the residual is
        // the jittered-bin sampling of the fringes: within 3 error bars plus 2e-3.
        assert!(e <= 3.0 * s + 2e-3, "{row}");
    }
    let report = std::fs::read_to_string(d.join("out/report.md")).unwrap();
    assert!(
        report.contains("| auto rho=inf") && report.contains("analytic TMM"),
        "{report}"
    );
}

#[test]
fn monte_carlo_error_falls_as_one_over_root_n_on_a_rough_sample() {
    let st = goniospec::study::load(&root().join("studies/rough-glass.toml")).unwrap();
    assert!(
        st.random_entry,
        "the shipped study samples with plain Monte Carlo"
    );
    let (points, reference) = goniospec::study::run(&st, |_| {}).unwrap();
    assert!(reference.contains("high-budget"));
    let table: Vec<_> = points
        .iter()
        .filter(|p| p.representation == goniospec::brdf::Kind::Table)
        .cloned()
        .collect();
    let slope = goniospec::study::convergence_slope(&table).unwrap();
    eprintln!("slope {slope}");
    assert!((-0.6..=-0.4).contains(&slope), "slope {slope}");
}

#[test]
fn bad_study_files_are_refused_with_clear_errors() {
    let d = scratch("study-bad");
    let base = format!(
        "[study]\nname = \"x\"\nsample = \"{}\"\ntheta_i = [0.0]\nwavelengths = \"400:700:100\"\n",
        root().join("meshes/flat-soap-film.toml").display()
    );
    let cases = [
        (
            format!("{base}colour = 1\n[sweep]\nrays = [10]\n"),
            "s.toml:6:",
            "unknown field `colour`",
        ),
        (
            format!("{base}[sweep]\nrays = []\n"),
            "s.toml",
            "[sweep] rays is empty",
        ),
        (
            format!("{base}[sweep]\nrays = [10]\ncoherence = []\n"),
            "s.toml",
            "[sweep] coherence is empty",
        ),
        (
            format!("{base}[sweep]\nrays = [10]\ncoherence = [\"psychic\"]\n"),
            "s.toml",
            "unknown coherence 'psychic'",
        ),
        (
            format!("{base}[sweep]\nrays = [10]\nrepresentation = [\"octree\"]\n"),
            "s.toml",
            "unknown representation 'octree'",
        ),
        (
            base.replace("400:700:100", "700:400:100") + "[sweep]\nrays = [10]\n",
            "s.toml",
            "A < B",
        ),
        // Found by fuzzing (fuzz/regressions/study): a bin count near 2^64 overflowed an
        // allocation; a tiling of 10^16 per side would copy the sample that often.
        (
            base.replace("400:700:100", "400:777777777777777700:50") + "[sweep]\nrays = [10]\n",
            "s.toml",
            "more than 10000 wavelengths",
        ),
        (
            format!(
                "{base}[sweep]\nrays = [10]\n[area]\ntiles = [1, [5555555555555555, 2]]\nrays = 100\n"
            ),
            "s.toml",
            "from 1 to 64 per side",
        ),
    ];
    for (text, loc, msg) in cases {
        std::fs::write(d.join("s.toml"), &text).unwrap();
        let e = goniospec::study::load(&d.join("s.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.contains(loc) && e.contains(msg), "{e}");
    }
}

#[test]
fn the_darkening_study_shows_global_falling_and_beamlet_staying() {
    let st = goniospec::study::load(&root().join("studies/darkening.toml")).unwrap();
    let rows = goniospec::study::run_area(&st, |_| {}).unwrap();
    let r = |name: &str, k: usize| {
        rows.iter()
            .find(|p| p.coherence.name() == name && p.tiles == [k, k])
            .unwrap()
            .r
    };
    assert!(
        (r("beamlet", 3) / r("beamlet", 1) - 1.0).abs() < 0.02,
        "beamlet {} -> {}",
        r("beamlet", 1),
        r("beamlet", 3)
    );
    assert!(
        r("global", 3) <= 0.5 * r("global", 1),
        "global {} -> {}",
        r("global", 1),
        r("global", 3)
    );
    let d = scratch("study-area");
    let written = goniospec::study::write_area(&rows, &d).unwrap();
    assert_eq!(written.len(), 2);
    assert!(
        std::fs::read_to_string(d.join("area.csv"))
            .unwrap()
            .lines()
            .count()
            == 10
    );
    for p in written {
        assert!(
            std::fs::metadata(&p).unwrap().len() > 5000,
            "{}",
            p.display()
        );
    }
}

/// The method as an axis (issue 26): the shipped grating study measures both methods against
/// a high-budget diffraction run. The two share R (the diffraction method keeps the rays'
/// R: within 1e-4 of each other here); rays stay far from the orders at every budget (the
/// angular distribution of a 5 um grating, against Kirchhoff and RCWA in tests/diffraction.rs:
/// L1 above 1), the diffraction method converges to them. The CSV and the chart carry it.
#[test]
fn the_grating_study_charts_the_angular_distribution_of_both_methods() {
    let st = goniospec::study::load(&root().join("studies/grating-methods.toml")).unwrap();
    let (points, reference) = goniospec::study::run(&st, |_| {}).unwrap();
    assert!(reference.contains("diffraction"), "{reference}");
    let of = |name: &str| -> Vec<&goniospec::study::Point> {
        points
            .iter()
            .filter(|p| p.variant.coherence.name() == name)
            .collect()
    };
    for p in &points {
        assert!(p.error < 1e-4, "R error {} at {} rays", p.error, p.rays);
    }
    for p in of("beamlet") {
        let l1 = p.distribution_l1.unwrap();
        assert!(l1 > 0.8, "rays at {} trees: L1 {l1}", p.rays);
    }
    let best = of("diffraction")
        .into_iter()
        .max_by_key(|p| p.rays)
        .unwrap();
    let l1 = best.distribution_l1.unwrap();
    assert!(l1 < 0.05, "diffraction at {} trees: L1 {l1}", best.rays);
    let d = scratch("study-methods");
    goniospec::study::write(&st, &points, &reference, &d).unwrap();
    let csv = std::fs::read_to_string(d.join("points.csv")).unwrap();
    assert!(csv.lines().next().unwrap().ends_with(",distribution_l1"));
    let written = goniospec::study::charts(&points, &d).unwrap();
    assert!(
        written
            .iter()
            .any(|p| p.ends_with("distribution-vs-time.svg")),
        "{written:?}"
    );
}

/// The study's folder (issue 47): `-o FILE` is refused before the study runs; a user's own
/// report.md or chart in the folder is never replaced (unless --force), other files of
/// theirs stay, and a second run into the study's own folder replaces what it wrote.
#[test]
fn a_study_replaces_only_what_it_wrote() {
    let d = scratch("study-outputs");
    std::fs::write(
        d.join("s.toml"),
        format!(
            "[study]\nname = \"flat\"\nsample = \"{}\"\ntheta_i = [0.0]\nwavelengths = \"400:700:100\"\n[sweep]\nrays = [16]\ncoherence_radius_nm = [inf]\n",
            root().join("studies/samples/flat-soap-film-meshed.toml").display()
        ),
    )
    .unwrap();
    let study = d.join("s.toml");
    let file = d.join("a-file");
    std::fs::write(&file, "mine").unwrap();
    let t0 = std::time::Instant::now();
    let (code, _, err) = goniospec(&[
        "study",
        study.to_str().unwrap(),
        "-o",
        file.to_str().unwrap(),
    ]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("is a file; give a folder"), "{err}");
    assert!(!err.contains("points"), "refused before the run: {err}");
    assert!(t0.elapsed().as_secs_f64() < 5.0);

    let out = d.join("out");
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join("report.md"), "my own report").unwrap();
    std::fs::write(out.join("error-vs-rays.png"), "my chart").unwrap();
    std::fs::write(out.join("notes.txt"), "notes").unwrap();
    let (code, _, err) = goniospec(&[
        "study",
        study.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("report.md, error-vs-rays.png would be replaced"),
        "{err}"
    );
    assert_eq!(
        std::fs::read_to_string(out.join("report.md")).unwrap(),
        "my own report"
    );
    assert!(!out.join("points.csv").exists());

    std::fs::remove_file(out.join("report.md")).unwrap();
    std::fs::remove_file(out.join("error-vs-rays.png")).unwrap();
    for _ in 0..2 {
        let (code, _, err) = goniospec(&[
            "study",
            study.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ]);
        assert_eq!(code, 0, "{err}");
    }
    assert!(
        std::fs::read_to_string(out.join("report.md"))
            .unwrap()
            .starts_with("# Study: flat")
    );
    assert_eq!(
        std::fs::read_to_string(out.join("notes.txt")).unwrap(),
        "notes"
    );
    let listed = std::fs::read_to_string(out.join(".goniospec-written")).unwrap();
    assert!(listed.lines().any(|l| l == "points.csv"), "{listed}");
    assert!(!listed.contains("notes.txt"), "{listed}");
}
