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
    runs_on(s, theta, (9, 8), 4096)
}

/// Both runs on a grid of `(theta, phi)` buckets with `trees` each.
fn runs_on(
    s: &goniospec::sample::Sample,
    theta: f64,
    (theta_bins, phi_bins): (u32, u32),
    trees: u64,
) -> (Accumulator, Accumulator) {
    let cfg = SimConfig {
        buckets: Buckets {
            theta_bins,
            phi_bins,
        },
        ..config(
            &[theta],
            Wavelengths::Bins(vec![450.0, 470.0, 600.0, 620.0]),
            trees,
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
/// walk's buckets of about 100 trees are heavy-tailed: where a bucket missed its rare large
/// deposits, its mean and its spread are both low, so its error is taken at the other
/// run's mean; without that, seed 1 of the spread estimate's slab reached 5.2 where seeds
/// 2-5 stayed below 3.6). Then R + T = 1 within 4 standard errors (lossless), and
/// next-event estimation has less noise in the bright buckets.
fn check(nee: &Accumulator, walk: &Accumulator) {
    let mode = Coherence::Beamlet;
    let (mut sum, mut n, mut worst) = (0.0, 0, 0.0f64);
    let nl = nee.header.settings.wavelength_count();
    for j in 0..nl {
        let (a, b) = (nee.cell(0, j), walk.cell(0, j));
        for k in 0..a.sum.len() {
            let (fa, fb) = (a.fraction(k, mode), b.fraction(k, mode));
            // The walk's bucket is a sum of few large deposits: its variance grows with
            // its mean (a compound Poisson sum), so where it fell short of the estimate
            // its own spread understates the error; it is taken at the other's mean.
            let walk_se = b.fraction_stderr(k, mode).unwrap() * (fa / fb).max(1.0).sqrt();
            let se = a.fraction_stderr(k, mode).unwrap().hypot(walk_se);
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

/// A strongly forward-peaked medium (Henyey-Greenstein g 0.9, optical depth 10, index 1
/// throughout: no faces reflect), where one cosine-drawn direction per event rarely met
/// the peak and then with a large weight (the bright buckets' error was 0.51 against the
/// walk's 0.45 at 20,000 trees on the default grid): spread over every bucket, each takes
/// its share of the peak, so the same checks hold, less noise included (0.090 against
/// 0.200 here; 0.082 against 0.45 on the default grid at 20,000 trees).
#[test]
fn next_event_estimation_gives_the_walks_brdf_in_a_forward_peaked_medium() {
    let s = sample_from(
        "nee-forward",
        "[sample]\nname = \"forward\"\nunit = \"um\"\ntile = [5.0, 5.0]\n\
         [media.air]\nn = 1.0\n\
         [media.slab]\nn = 1.0\n\
         henyey_greenstein = { g = 0.9, scattering_per_um = 1.0, absorption_per_um = 0.0 }\n\
         [media.below]\nn = 1.0\n\
         [stack]\nambient = \"air\"\nlayers = [{ medium = \"slab\", thickness = 10.0 }]\n\
         substrate = \"below\"\n",
    );
    let (nee, walk) = runs_on(&s, 30.0, (18, 16), 16384);
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
