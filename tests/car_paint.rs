//! A clear-coated car paint, as a new user writes it (issue 46): a clear coat (n 1.52) over a
//! binder (n 1.49) holding aluminium flakes (McPeak et al. 2015), over a black primer (index
//! 1.5 + 1.0i). Two forms: the coat's top a Gaussian surface (RMS 0.15 um, correlation
//! length 4 um), and coat and binder as a flat `[stack]` (the shipped
//! `meshes/car-paint.toml`).
//!
//! The reference is energy: the primer is a semi-infinite absorber, so `T = 0` and `R +
//! dropped <= 1`, whatever the flakes do. Before issue 46 the rough form wrote R = 144,763 at
//! 60 degrees and 495 nm with exit status 0 (evanescent waves from the flakes' edges met the
//! coat at a pole of their Fresnel coefficients and grew at every bounce); the first case
//! below is that run. Every tree is now also checked on its own (`Tree::overflow`): a run
//! that finishes had none carry out more than it was launched with.

mod common;

use common::{goniospec, root, scratch};

use goniospec::simulate::Wavelengths;

/// The rough-coat form: the clear coat's top a Gaussian surface 45 um up, the coat/binder
/// plane at 15 um, the binder/primer plane at 0, the flakes in 0.5-14.5 um.
fn rough_coat() -> String {
    format!(
        r#"[sample]
name = "car paint, rough clear coat"
unit = "um"
tile = [40.0, 40.0]
[media.air]
n = 1.0
[media.coat]
n = 1.52
[media.binder]
n = 1.49
[media.aluminium]
table = "{al}"
[media.black]
n = 1.5
k = 1.0
[[interface]]
generator = {{ kind = "gaussian", rms = 0.15, correlation_length = 4.0, resolution = 64, z = 45.0 }}
front = "air"
back = "coat"
[[interface]]
generator = {{ kind = "flat", z = 15.0 }}
front = "coat"
back = "binder"
[[interface]]
generator = {{ kind = "flat", z = 0.0 }}
front = "binder"
back = "black"
[[body]]
generator = {{ kind = "flakes", size = 10.0, thickness = 0.3, tilt_sd_deg = 6.0, volume_fraction = 0.04, layer = [0.5, 14.5], seed = 3 }}
inside = "aluminium"
outside = "binder"
"#,
        al = common::root().join("data/al-mcpeak.csv").display()
    )
}

/// Runs `s` and asserts, in every cell, `T = 0` (the primer is semi-infinite) and `R + T +
/// dropped <= 1` within rounding and 5 standard errors of R (the Monte Carlo noise of the
/// beamlet estimator's cross terms between the coat's reflection and the flakes' light:
/// 1e-2 at 256 trees); returns the largest `R + T + dropped` seen, for the message.
fn assert_conserves(s: &goniospec::sample::Sample, theta: &[f64], seed: u64, rays: u64) -> f64 {
    let mut cfg = common::config(theta, Wavelengths::Bins(vec![]), rays);
    cfg.wavelengths = Wavelengths::parse("380:780:10", false).unwrap();
    cfg.seed = seed;
    let acc = common::run(s, &cfg);
    let st = &acc.header.settings;
    let mut worst: f64 = 0.0;
    for (i, t) in theta.iter().enumerate() {
        for j in 0..st.wavelength_count() {
            let c = acc.cell(i, j);
            let (r, tt) = common::totals(&acc, i, j);
            let dropped = c.dropped / c.trees as f64;
            let se = c.r_stderr(st.coherence_mode()).unwrap();
            let sum = r + tt + dropped;
            worst = worst.max(sum);
            assert_eq!(tt, 0.0, "{}: T at {t} deg", s.name);
            assert!(
                sum <= 1.0 + 1e-9 + 5.0 * se,
                "{}: seed {seed}, {t} deg, {} nm: R + T + dropped = {sum} (R {r} +- {se})",
                s.name,
                st.wavelength(j)
            );
            // Far from 1 in fact: the primer and the flakes absorb.
            assert!(
                sum < 0.8,
                "{}: {t} deg, {} nm: {sum}",
                s.name,
                st.wavelength(j)
            );
        }
    }
    worst
}

#[test]
fn the_rough_coated_paint_creates_no_energy() {
    let s = common::sample_from("car-paint-rough", &rough_coat());
    // The run that wrote R = 144,763 (seed 1, 512 trees, 0/30/60 degrees, 40 bins).
    let w = assert_conserves(&s, &[0.0, 30.0, 60.0], 1, 512);
    // Another seed and grazing light.
    let w2 = assert_conserves(&s, &[75.0], 2, 256);
    eprintln!("rough coat: largest R + T + dropped {w:.4}, {w2:.4}");
}

#[test]
fn the_smooth_coated_paint_creates_no_energy() {
    let s = common::shipped("car-paint.toml");
    for (seed, theta) in [(1, vec![0.0, 55.0, 75.0]), (3, vec![30.0, 60.0])] {
        let w = assert_conserves(&s, &theta, seed, 256);
        eprintln!("smooth coat, seed {seed}: largest R + T + dropped {w:.4}");
    }
}

/// Paint layers that make no sense are refused by name before any work (issue 74): the
/// shipped car paint's flakes moved into its coat (`layer = [20, 40]` um, the coat being
/// z = 15 to 45 um over a 15 um binder), and its binder typed 0.015 for 15 (a unit slip).
/// `check` and `simulate` each name the [[body]], the flakes' extent in z and the binder's,
/// read here from the stack's own arithmetic (binder from z = 0 to its thickness).
#[test]
fn flakes_outside_their_binder_are_refused_by_name() {
    let shipped = std::fs::read_to_string(root().join("meshes/car-paint.toml")).unwrap();
    let dir = scratch("flakes-outside");
    for (tag, from, to, binder) in [
        (
            "in-coat",
            "layer = [0.5, 14.5]",
            "layer = [20.0, 40.0]",
            "'binder' fills z = 0 to 15 um",
        ),
        (
            "unit-slip",
            "{ medium = \"binder\", thickness = 15.0 }",
            "{ medium = \"binder\", thickness = 0.015 }",
            "'binder' fills z = 0 to 0.015 um",
        ),
    ] {
        assert!(shipped.contains(from), "{tag}: the shipped paint changed");
        // Its data table named by its absolute path, from the scratch folder.
        let table = root().join("data/al-mcpeak.csv");
        let text = shipped
            .replace(from, to)
            .replace("../data/al-mcpeak.csv", table.to_str().unwrap());
        let path = dir.join(format!("{tag}.toml"));
        std::fs::write(&path, text).unwrap();
        let p = path.to_str().unwrap();
        let out = dir.join(format!("{tag}.gsa"));
        for args in [
            vec!["check", p],
            vec!["simulate", p, "--rays", "8", "-o", out.to_str().unwrap()],
        ] {
            let (code, _, err) = goniospec(&args);
            assert_ne!(code, 0, "{tag} {args:?}");
            assert!(
                err.contains("[[body]] 1 (generator flakes, outside = \"binder\")")
                    && err.contains(binder)
                    && err.contains("its bodies span z ="),
                "{tag} {args:?}: {err}"
            );
        }
        assert!(!out.exists());
    }
}
