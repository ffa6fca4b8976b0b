//! Thin absorbing films whose faces are not parallel, against the transfer-matrix method
//! averaged over the local thickness (written here, independent of the tracer).
//!
//! A 20 nm-class gold film on glass: flat top, back face a periodic roof tilted by
//! `alpha`, so the local thickness is `t(x) = T0 - tan(alpha) |x - L/2|`. The film is far
//! thinner than the wavelength, so its local reflectance is the flat film's at the local
//! thickness (the tangent-plane or local-film model): the ray series of one point recombines
//! within the beamlet, and the reflectance averaged over the tile is the average of
//! `R_TMM(t(x))` over x, for light entering at uniformly spread points (the tracer's entry
//! points are a low-discrepancy sequence over the tile). Before issue 25 the tracer
//! flux-normalised every event at a facet more than 1e-6 rad off the wave's entry facet:
//! R 0.80 against 0.405 at a tilt of 1e-4 degrees.

mod common;

use common::*;
use goniospec::simulate::Wavelengths;
use num_complex::Complex64 as C;

/// Gold (Johnson & Christy 1972, as in data/au-johnson.csv) at three wavelengths, as
/// constant indices so the reference can use the same numbers.
const GOLD: [(f64, f64, f64); 3] = [
    (450.0, 1.38, 1.92),
    (550.0, 0.43, 2.455),
    (650.0, 0.166, 3.15),
];
const GLASS: f64 = 1.5;
/// Thickness at the roof's ridge line, nm.
const T0: f64 = 25.0;

/// The tile side for a tilt: 20 um, or less so the thickness stays within [T0 - 10, T0].
fn tile_for(tilt_deg: f64) -> f64 {
    (20.0 / tilt_deg.to_radians().tan()).min(20_000.0)
}

/// Writes the film: `top.obj` (z = 0) and `back.obj` (the roof), and the sample.
fn film(tilt_deg: f64) -> goniospec::sample::Sample {
    let l = tile_for(tilt_deg);
    let d = scratch("tilted-film");
    let rise = tilt_deg.to_radians().tan() * l / 2.0;
    std::fs::write(
        d.join("top.obj"),
        format!("v 0 0 0\nv {l} 0 0\nv {l} {l} 0\nv 0 {l} 0\nf 1 2 3\nf 1 3 4\n"),
    )
    .unwrap();
    let (zl, zc) = (-T0 + rise, -T0);
    let h = l / 2.0;
    std::fs::write(
        d.join("back.obj"),
        format!(
            "v 0 0 {zl}\nv {h} 0 {zc}\nv {l} 0 {zl}\nv 0 {l} {zl}\nv {h} {l} {zc}\nv {l} {l} {zl}\nf 1 2 5\nf 1 5 4\nf 2 3 6\nf 2 6 5\n"
        ),
    )
    .unwrap();
    let table: String = GOLD
        .iter()
        .map(|(w, n, k)| format!("{w},{n},{k}\n"))
        .collect();
    std::fs::write(d.join("gold.csv"), format!("lambda_nm,n,k\n{table}")).unwrap();
    sample_in(
        &d,
        &format!(
            "[sample]\nname = \"gold roof {tilt_deg}\"\nunit = \"nm\"\ntile = [{l:?}, {l:?}]\n[media.air]\nn = 1.0\n[media.gold]\ntable = \"gold.csv\"\n[media.glass]\nn = {GLASS:?}\n[[interface]]\nmesh = \"top.obj\"\nfront = \"air\"\nback = \"gold\"\n[[interface]]\nmesh = \"back.obj\"\nfront = \"gold\"\nback = \"glass\"\n"
        ),
    )
}

/// The reference: unpolarised (R, T) of the flat film at each local thickness, averaged
/// over the tile (midpoint rule on 2,000 points; `R_TMM(t)` is smooth in t).
fn local_tmm(tilt_deg: f64, lambda: f64, n: f64, k: f64, theta_deg: f64) -> (f64, f64) {
    let l = tile_for(tilt_deg);
    let m = 2000;
    let (mut r, mut t) = (0.0, 0.0);
    for i in 0..m {
        let x = (i as f64 + 0.5) / m as f64 * l;
        let thick = T0 - tilt_deg.to_radians().tan() * (x - l / 2.0).abs();
        let (ri, ti) = tmm_ref(
            &[C::new(1.0, 0.0), C::new(n, k), C::new(GLASS, 0.0)],
            &[thick],
            lambda,
            theta_deg.to_radians(),
        );
        r += ri;
        t += ti;
    }
    (r / m as f64, t / m as f64)
}

/// (R, T) of the film at each tilt, incident angle and wavelength: `[tilt][theta][lambda]`.
fn simulate_films(tilts: &[f64], thetas: &[f64]) -> Vec<Vec<Vec<(f64, f64)>>> {
    let lambdas: Vec<f64> = GOLD.iter().map(|g| g.0).collect();
    tilts
        .iter()
        .map(|&tilt| {
            let s = film(tilt);
            let acc = run(
                &s,
                &config(thetas, Wavelengths::Monochromatic(lambdas.clone()), 256),
            );
            (0..thetas.len())
                .map(|i| (0..lambdas.len()).map(|j| totals(&acc, i, j)).collect())
                .collect()
        })
        .collect()
}

/// Where the beamlet estimator cannot yet follow the film (faces tilted by 0.05 degrees
/// and more at the default 5 um beamlet: its partial waves are inhomogeneous across the
/// beamlet, which the estimator's overlap treats as uniform), the run says so: the power
/// that met energy-limited events is reported above `CREATED_WARN`, which is what
/// `simulate` warns about. At 1e-2 degrees and below, where the film is exact, it stays
/// under it.
#[test]
fn the_run_reports_the_power_it_could_not_treat_exactly() {
    let lambdas: Vec<f64> = GOLD.iter().map(|g| g.0).collect();
    for (tilt, warned) in [(1e-4, false), (1e-2, false), (0.05, true), (1.0, true)] {
        let s = film(tilt);
        let cfg = config(
            &[0.0, 30.0],
            Wavelengths::Monochromatic(lambdas.clone()),
            256,
        );
        let (acc, stats) = goniospec::simulate::simulate(&s, &cfg, &|_| {}).unwrap();
        let (limited, _) = stats.worst_limited(&acc);
        assert_eq!(
            limited > goniospec::simulate::CREATED_WARN,
            warned,
            "tilt {tilt} deg: {limited:e} of the power met energy-limited events"
        );
    }
}

/// Tilts from 1e-6 to 1e-2 degree, 0/30/60 degrees, 450-650 nm: R and T within 2e-3 of
/// the local TMM, and no jump between neighbouring tilts beyond the reference's own change
/// (plus the same 2e-3). (Issue 25 asks this up to 1 degree; from 0.05 degree on the
/// estimator is not there yet, and the run warns: the next test.)
#[test]
fn a_gold_film_with_a_tilted_back_face_matches_the_local_tmm_up_to_a_hundredth_of_a_degree() {
    let tilts = [1e-6, 1e-4, 3e-3, 1e-2];
    let thetas = [0.0, 30.0, 60.0];
    let got = simulate_films(&tilts, &thetas);
    let mut refs = Vec::new();
    for (a, &tilt) in tilts.iter().enumerate() {
        let mut per_tilt = Vec::new();
        for (i, &th) in thetas.iter().enumerate() {
            let mut row = Vec::new();
            for (j, &(lambda, n, k)) in GOLD.iter().enumerate() {
                let (r_ref, t_ref) = local_tmm(tilt, lambda, n, k, th);
                let (r, t) = got[a][i][j];
                eprintln!(
                    "tilt {tilt:e} deg, theta {th}, {lambda} nm: R {r:.5} (local TMM {r_ref:.5}), T {t:.5} ({t_ref:.5})"
                );
                assert!(
                    (r - r_ref).abs() < 2e-3 && (t - t_ref).abs() < 2e-3,
                    "tilt {tilt} deg, theta {th}, {lambda} nm: R {r} T {t} against the local TMM {r_ref} {t_ref}"
                );
                row.push((r_ref, t_ref));
            }
            per_tilt.push(row);
        }
        refs.push(per_tilt);
    }
    for a in 1..tilts.len() {
        for i in 0..thetas.len() {
            for j in 0..GOLD.len() {
                let (dr, dt) = (
                    (got[a][i][j].0 - got[a - 1][i][j].0).abs(),
                    (got[a][i][j].1 - got[a - 1][i][j].1).abs(),
                );
                let (rr, rt) = (
                    (refs[a][i][j].0 - refs[a - 1][i][j].0).abs(),
                    (refs[a][i][j].1 - refs[a - 1][i][j].1).abs(),
                );
                assert!(
                    dr <= rr + 2e-3 && dt <= rt + 2e-3,
                    "a jump between tilts {} and {}: R by {dr}, T by {dt}, the local TMM by {rr}, {rt}",
                    tilts[a - 1],
                    tilts[a]
                );
            }
        }
    }
}
