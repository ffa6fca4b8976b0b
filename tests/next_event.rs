//! Next-event estimation in particle media (issue 49; `trace::escape`): against the random
//! walk alone on the same sample, the same BRDF within the standard errors, the same R and
//! T, energy kept in a lossless slab, and less noise.

mod common;

use common::*;
use goniospec::accumulate::file::Accumulator;
use goniospec::accumulate::{Buckets, Coherence};
use goniospec::simulate::{SimConfig, Wavelengths, bright_bucket_error};

/// TiO2-like lossless spheres (radius 120 nm, n 2.6) at 10 % by volume in a 4 um binder
/// (n 1.49) over glass (n 1.5, lossless: light that crosses the slab leaves below), under
/// `coat` (a clear layer, or none).
fn paint(tag: &str, coat: Option<(f64, f64)>) -> goniospec::sample::Sample {
    let (coat_medium, coat_layer) = match coat {
        Some((n, um)) => (
            format!("[media.coat]\nn = {n}\n"),
            format!("{{ medium = \"coat\", thickness = {um} }}, "),
        ),
        None => (String::new(), String::new()),
    };
    sample_from(
        tag,
        &format!(
            "[sample]\nname = \"{tag}\"\nunit = \"um\"\ntile = [5.0, 5.0]\n\
             [media.air]\nn = 1.0\n[media.tio2]\nn = 2.6\n{coat_medium}\
             [media.paint]\nn = 1.49\n\
             particles = {{ medium = \"tio2\", radius_nm = 120.0, volume_fraction = 0.10 }}\n\
             [media.glass]\nn = 1.5\n\
             [stack]\nambient = \"air\"\n\
             layers = [{coat_layer}{{ medium = \"paint\", thickness = 4.0 }}]\n\
             substrate = \"glass\"\n"
        ),
    )
}

fn runs(s: &goniospec::sample::Sample, theta: f64) -> (Accumulator, Accumulator) {
    let cfg = SimConfig {
        buckets: Buckets {
            theta_bins: 9,
            phi_bins: 8,
        },
        ..config(
            &[theta],
            Wavelengths::Bins(vec![450.0, 470.0, 600.0, 620.0]),
            4096,
        )
    };
    let nee = run(s, &cfg);
    let walk = run(
        s,
        &SimConfig {
            next_event: false,
            ..cfg
        },
    );
    assert!(nee.header.settings.next_event && !walk.header.settings.next_event);
    (nee, walk)
}

/// The two estimates of every bucket (both hemispheres) and of R and T agree: z-scores
/// over their combined standard errors (per tree: a particle medium's trees are random
/// walks), whose mean square is 1 for honest errors, here within [0.6, 1.6] over the
/// buckets that both runs reached with more than 20 trees (a sum of ~400 squares scatters
/// by about 0.07, more where the walk's sparse buckets are skewed); none beyond 5 (the
/// walk's buckets of about 100 trees reach 4.7: its deposits are heavy-tailed there). Then R + T = 1 within 4 standard errors (lossless), and
/// next-event estimation has less noise in the bright buckets.
fn check(nee: &Accumulator, walk: &Accumulator) {
    let mode = Coherence::Beamlet;
    let (mut sum, mut n, mut worst) = (0.0, 0, 0.0f64);
    let nl = nee.header.settings.wavelength_count();
    for j in 0..nl {
        let (a, b) = (nee.cell(0, j), walk.cell(0, j));
        for k in 0..a.sum.len() {
            let (fa, fb) = (a.fraction(k, mode), b.fraction(k, mode));
            let se = a
                .fraction_stderr(k, mode)
                .unwrap()
                .hypot(b.fraction_stderr(k, mode).unwrap());
            // Buckets both runs reached with more than a few trees.
            if fa > 0.0 && fb > 0.0 && a.count[k] > 20 && b.count[k] > 20 && se > 0.0 {
                let z = (fa - fb) / se;
                sum += z * z;
                n += 1;
                worst = worst.max(z.abs());
            }
        }
        let (ra, ta) = totals(nee, 0, j);
        let (rb, tb) = totals(walk, 0, j);
        let (sr, st) = (
            a.r_stderr(mode).unwrap().hypot(b.r_stderr(mode).unwrap()),
            a.t_stderr(mode).unwrap().hypot(b.t_stderr(mode).unwrap()),
        );
        assert!(
            (ra - rb).abs() < 4.0 * sr,
            "bin {j}: R {ra} against {rb} +- {sr}"
        );
        assert!(
            (ta - tb).abs() < 4.0 * st,
            "bin {j}: T {ta} against {tb} +- {st}"
        );
        let se_rt = a.r_stderr(mode).unwrap() + a.t_stderr(mode).unwrap();
        let dropped = a.dropped / a.trees as f64;
        assert!(
            (ra + ta + dropped - 1.0).abs() < 4.0 * se_rt,
            "bin {j}: R + T + dropped = {} +- {se_rt}",
            ra + ta + dropped
        );
    }
    let mean_square = sum / n as f64;
    eprintln!("{n} buckets: mean z^2 {mean_square:.3}, largest |z| {worst:.2}");
    assert!(n > 100, "{n} buckets compared");
    assert!(
        (0.6..1.6).contains(&mean_square) && worst < 5.0,
        "mean z^2 {mean_square}, largest |z| {worst}"
    );
    let (ea, eb) = (
        bright_bucket_error(nee.direction_cells(0), 0.95).unwrap(),
        bright_bucket_error(walk.direction_cells(0), 0.95).unwrap(),
    );
    eprintln!("bright buckets' median relative error: {ea:.4} with, {eb:.4} without");
    assert!(
        ea < 0.8 * eb,
        "{ea} with next-event estimation, {eb} without"
    );
}

#[test]
fn next_event_estimation_gives_the_walks_brdf_in_a_particle_slab() {
    let s = paint("nee-slab", None);
    let (nee, walk) = runs(&s, 30.0);
    check(&nee, &walk);
}

#[test]
fn next_event_estimation_gives_the_walks_brdf_under_a_clear_coat() {
    let s = paint("nee-coat", Some((1.6, 3.0)));
    let (nee, walk) = runs(&s, 50.0);
    check(&nee, &walk);
}

/// Where it cannot apply (open sides: light may leave through them, so the way out is not
/// the layers' alone) the run does not record it and gives the walk's bits exactly.
#[test]
fn next_event_estimation_stays_off_where_the_way_out_is_not_the_layers() {
    let flat = paint("nee-open", None);
    let toml = std::fs::read_to_string(&flat.path)
        .unwrap()
        .replace("tile = [5.0, 5.0]\n", "tile = [5.0, 5.0]\nguard = 0.5\n");
    let s = sample_from("nee-open-guard", &toml);
    assert!(s.guard_nm.is_some());
    let cfg = config(&[30.0], Wavelengths::Bins(vec![500.0, 520.0]), 64);
    let on = run(&s, &cfg);
    let off = run(
        &s,
        &SimConfig {
            next_event: false,
            ..cfg
        },
    );
    assert!(!on.header.settings.next_event);
    assert!(on.to_bytes() == off.to_bytes());
}
