//! `--coherence rigorous` end to end: the run's cells against an independent transfer
//! matrix (a flat film), energy balance and bucket sums of a lossless grating, bytes that do
//! not depend on the thread count, `--mueller` on top of the same bits, and the refusals.

mod common;

use common::*;
use goniospec::accumulate::Coherence;
use goniospec::sample::Sample;
use goniospec::simulate::{SimConfig, SimError, Wavelengths, simulate};

fn rigorous(theta: &[f64], wavelengths: &str) -> SimConfig {
    let mut cfg = config(theta, Wavelengths::parse(wavelengths, false).unwrap(), 64);
    cfg.coherence = Coherence::Rigorous;
    cfg
}

/// The reflected and transmitted fractions of a cell summed over its buckets.
fn bucket_sums(acc: &goniospec::accumulate::file::Accumulator, i: usize, j: usize) -> (f64, f64) {
    let s = &acc.header.settings;
    let (c, mode) = (acc.cell(i, j), s.coherence_mode());
    let b = s.buckets().len();
    (
        (0..b).map(|k| c.fraction(2 * k, mode)).sum(),
        (0..b).map(|k| c.fraction(2 * k + 1, mode)).sum(),
    )
}

/// The shipped 600 nm soap film by the rigorous solver: every cell's R and T are the
/// independent transfer-matrix recursion's (`common::tmm_ref`) at the bin's centre within
/// 1e-9, and under plane-wave illumination all of R lies in one bucket (a film reflects one
/// order; a finite coherence radius spreads it as it spreads the diffraction method's).
#[test]
fn a_rigorous_run_of_a_flat_film_is_the_tmm() {
    let s = shipped("flat-soap-film.toml");
    let mut cfg = rigorous(&[0.0, 45.0, 70.0], "400:700:100");
    cfg.rho_nm = f64::INFINITY;
    let acc = run(&s, &cfg);
    let n = [c(1.0, 0.0), c(1.33, 0.0), c(1.0, 0.0)];
    for (i, &theta) in cfg.theta_i_deg.iter().enumerate() {
        for j in 0..3 {
            let lambda = acc.header.settings.wavelength(j);
            let (r, t) = totals(&acc, i, j);
            let (rr, tr) = tmm_ref(&n, &[600.0], lambda, theta.to_radians());
            assert!(
                (r - rr).abs() < 1e-9 && (t - tr).abs() < 1e-9,
                "{theta} deg, {lambda} nm: R {r}, T {t} against the TMM's {rr}, {tr}"
            );
            let cell = acc.cell(i, j);
            let brightest = (0..cell.sum.len())
                .step_by(2)
                .map(|k| cell.fraction(k, Coherence::Rigorous))
                .fold(0.0, f64::max);
            assert!(
                (brightest - r).abs() < 1e-12,
                "one bucket holds R: {brightest} of {r}"
            );
        }
    }
}

/// A lossless glass sinusoid (period 1 um, amplitude 50 nm): R + T = 1 within 1e-9 in
/// every cell, the buckets sum to R and T, several orders are lit, and the bytes of a run on
/// one thread are those of a run on every core.
#[test]
fn a_rigorous_grating_run_balances_and_does_not_depend_on_threads() {
    let s = sinusoid("rig-glass", 1000.0, 50.0, (1.5, 0.0), 256, 1);
    let cfg = rigorous(&[0.0, 30.0], "500:600:50");
    let acc = run(&s, &cfg);
    for i in 0..2 {
        for j in 0..2 {
            let (r, t) = totals(&acc, i, j);
            assert!((r + t - 1.0).abs() < 1e-9, "R + T = {}", r + t);
            let (br, bt) = bucket_sums(&acc, i, j);
            assert!(
                (br - r).abs() < 1e-12 && (bt - t).abs() < 1e-12,
                "buckets {br}, {bt} against {r}, {t}"
            );
            let cell = acc.cell(i, j);
            let lit = (0..cell.sum.len())
                .step_by(2)
                .filter(|&k| cell.sum[k] > 1e-6)
                .count();
            assert!(lit >= 3, "reflected orders in {lit} buckets");
        }
    }
    let one = run_on_one_thread(&s, &cfg);
    assert!(
        one.to_bytes() == acc.to_bytes(),
        "the bytes depend on the thread count"
    );
}

/// `--mueller` with the rigorous solver on a gold sinusoid: each order is one Jones matrix,
/// so every bucket's matrix is realisable (the run is refused otherwise), and the matrices'
/// m00 are the unpolarised run's bits. (The test is of the bookkeeping, so the default
/// effort's TM convergence on gold, about 5e-2 here, is let through.)
#[test]
fn a_rigorous_mueller_run_keeps_the_unpolarised_bits() {
    let s = sinusoid("rig-gold", 1200.0, 80.0, (0.25, 3.0), 256, 1);
    let mut cfg = rigorous(&[20.0], "590:610:20");
    cfg.rigorous.tolerance = 0.2;
    let plain = run(&s, &cfg);
    let with = run(
        &s,
        &SimConfig {
            mueller: true,
            ..cfg
        },
    );
    let (a, b) = (plain.cell(0, 0), with.cell(0, 0));
    assert_eq!(a.sum, b.sum);
    let mut held = 0;
    for (k, m) in b.mueller.iter().enumerate() {
        assert_eq!(m[0].to_bits(), b.sum[k].to_bits(), "m00 of key {k}");
        held += usize::from(m[0] > 0.0);
    }
    assert!(held >= 2, "the gold grating lights several buckets");
    let real = with.realisability().expect("a --mueller run");
    assert_eq!(real.failed, 0);
    assert!(real.checked >= 2);
}

/// What the rigorous solver refuses, with the words a user acts on: a cell that does not
/// converge to the tolerance (naming --orders and --slices), particle media, and settings
/// out of range.
#[test]
fn rigorous_refusals_say_what_to_change() {
    let s = sinusoid("rig-refuse", 1000.0, 200.0, (0.25, 3.0), 256, 1);
    let mut cfg = rigorous(&[60.0], "600:610:10");
    cfg.rigorous.orders = Some(4);
    cfg.rigorous.slices = 2;
    let e = simulate(&s, &cfg, &|_| {}).unwrap_err().to_string();
    assert!(
        e.contains("did not converge") && e.contains("--orders"),
        "{e}"
    );
    let paint = shipped("paint-pigments.toml");
    let e = simulate(&paint, &rigorous(&[0.0], "500:600:100"), &|_| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("particle media"), "{e}");
    let mut cfg = rigorous(&[0.0], "500:600:100");
    cfg.rigorous.slices = 0;
    let e = simulate(&s, &cfg, &|_| {}).unwrap_err();
    assert!(matches!(e, SimError::Setting { key: "slices", .. }), "{e}");
    let mut cfg = rigorous(&[0.0], "500:600:100");
    cfg.rigorous_budget_s = -1.0;
    let e = simulate(&s, &cfg, &|_| {}).unwrap_err();
    assert!(
        matches!(
            e,
            SimError::Setting {
                key: "rigorous_budget",
                ..
            }
        ),
        "{e}"
    );
}

/// Issue 70, "cost known before work": a run whose rigorous cells are estimated past
/// `--rigorous-budget` is refused before any cell is solved, with the estimate and what to
/// change (a progress callback that would count a solved cell is never called); within the
/// budget every solved cell records its estimate, positive and finite, beside its time.
#[test]
fn a_run_estimated_past_its_budget_is_refused_before_work() {
    let s = sinusoid("rig-budget", 1000.0, 100.0, (1.5, 0.0), 256, 1);
    let mut cfg = rigorous(&[0.0, 30.0], "500:600:50");
    cfg.rigorous_budget_s = 1e-6;
    let called = std::sync::atomic::AtomicBool::new(false);
    let e = simulate(&s, &cfg, &|_| {
        called.store(true, std::sync::atomic::Ordering::Relaxed);
    })
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("4 cells are estimated to take")
            && e.contains("--rigorous-budget")
            && e.contains("a cell"),
        "{e}"
    );
    assert!(!called.load(std::sync::atomic::Ordering::Relaxed));
    cfg.rigorous_budget_s = 1800.0;
    let (_, stats) = simulate(&s, &cfg, &|_| {}).unwrap();
    assert!(
        stats
            .rigorous
            .iter()
            .all(|c| c.is_some_and(|c| c.estimate_s > 0.0 && c.estimate_s.is_finite()))
    );
}

/// The shipped samples of structure near the wavelength under the default `--coherence
/// auto`, at 30 deg and 550 nm. The transparent hologram (a ZnS-coated 1 um sinusoid in
/// lacquer, dielectric) takes the rigorous solver, whose R is that of a run at twice the
/// slices and 40 harmonics within the default tolerance, and R + T + A = 1. The aluminised
/// foil (a sinusoid under a flat lacquer) takes the C-method joined to its lacquer, unsliced
/// (its R against an independent reference: `tests/lacquered_relief.rs`). The optical
/// disc's aluminium trapezoid, whose slopes jump, takes the C-method in the stretched
/// coordinate of adaptive spatial resolution, unsliced, at 120 harmonics or more
/// (`tests/cmethod_corners.rs`). Held to 20 harmonics (`--orders 20`) it does not converge
/// (neither does the staircase's TM there: 3.1e-2 from its check): the cell keeps the
/// rays' result and the run stores a warning that says so.
#[test]
fn shipped_rigorous_samples_take_the_solver_or_say_why_not() {
    let auto = SimConfig {
        coherence: Coherence::Auto,
        ..config(
            &[30.0],
            Wavelengths::parse("540:560:20", false).unwrap(),
            256,
        )
    };
    let s = shipped("hri-hologram.toml");
    let acc = run(&s, &auto);
    assert_eq!(acc.header.settings.cell_mode(0, 0), Coherence::Rigorous);
    let (r, t) = totals(&acc, 0, 0);
    let a = acc.cell(0, 0).absorbed / acc.cell(0, 0).trees as f64;
    assert!((r + t + a - 1.0).abs() < 1e-9, "R + T + A = {}", r + t + a);
    let mut fine = rigorous(&[30.0], "540:560:20");
    fine.rigorous.orders = Some(40);
    fine.rigorous.slices = 48;
    let (rf, _) = totals(&run(&s, &fine), 0, 0);
    println!("hologram: R {r} (auto), {rf} (40 harmonics, 48 slices)");
    assert!(
        (r - rf).abs() < 5e-3,
        "R {r} against {rf} at the higher effort"
    );
    let (foil, stats) = simulate(&shipped("holographic-foil.toml"), &auto, &|_| {}).unwrap();
    assert_eq!(foil.header.settings.cell_mode(0, 0), Coherence::Rigorous);
    assert!(stats.rigorous[0].is_some_and(|c| c.slices == 0));
    let (disc, stats) = simulate(&shipped("optical-disc-track.toml"), &auto, &|_| {}).unwrap();
    assert_eq!(disc.header.settings.cell_mode(0, 0), Coherence::Rigorous);
    let cell = stats.rigorous[0].expect("the disc's cell is solved");
    assert!(cell.slices == 0 && cell.harmonics[0] >= 120, "{cell:?}");
    let mut held = auto.clone();
    held.rigorous.orders = Some(20);
    let disc = run(&shipped("optical-disc-track.toml"), &held);
    assert_eq!(disc.header.settings.cell_mode(0, 0), Coherence::Beamlet);
    assert!(
        disc.header
            .warnings
            .iter()
            .any(|w| w.contains("did not converge") && w.contains("kept the result")),
        "{:?}",
        disc.header.warnings
    );
}

/// A bare gold sinusoid (period 2 um, A = 100 nm, 256 facets) run by `--coherence rigorous`
/// takes the C-method (its cells unsliced), and its R is the C-method's on the exact
/// sinusoid (`optics::rcwa::solve_profile`, 1,024 samples) within 1e-4, the facets' own
/// departure from the curve (measured 2e-5); the buckets hold R and the cell balances.
#[test]
fn a_bare_metal_relief_takes_the_c_method() {
    let s = sinusoid("rig-cmethod", 2000.0, 100.0, (0.43, 2.455), 256, 1);
    let mut cfg = rigorous(&[30.0, 60.0], "550:560:10");
    cfg.wavelengths = Wavelengths::parse("550", true).unwrap();
    let (acc, stats) = simulate(&s, &cfg, &|_| {}).unwrap();
    assert!(
        stats
            .rigorous
            .iter()
            .all(|c| c.is_some_and(|c| c.slices == 0))
    );
    let n = goniospec::optics::C64::new(0.43, 2.455);
    let p = goniospec::optics::rcwa::Profile {
        period_nm: 2000.0,
        heights_nm: (0..1024)
            .map(|i| 100.0 * (2.0 * std::f64::consts::PI * i as f64 / 1024.0).sin())
            .collect(),
        eps_above: 1.0,
        eps_below: n * n,
        planes: Vec::new(),
    };
    for (i, &theta) in cfg.theta_i_deg.iter().enumerate() {
        let t = theta.to_radians();
        let d = glam::DVec3::new(t.sin(), 0.0, -t.cos());
        let exact = goniospec::optics::rcwa::solve_profile(&p, 550.0, d, 16).unwrap();
        let want = 0.5 * (exact.r[0] + exact.r[1]);
        let (r, t_) = totals(&acc, i, 0);
        let (rb, _) = bucket_sums(&acc, i, 0);
        assert!((r - want).abs() < 1e-4, "{theta} deg: R {r} against {want}");
        assert!(
            (rb - r).abs() < 1e-12 && t_ == 0.0,
            "{theta} deg: buckets {rb}, T {t_}"
        );
    }
}

/// Lamellae of `depth` nm (ridges of index `n` over the middle half of each `period`, air
/// between them, the same medium below): one sheet with vertical walls, a binary grating.
fn lamellae(tag: &str, period: f64, depth: f64, n: f64) -> Sample {
    let xz = [
        (0.0, 0.0),
        (0.25 * period, 0.0),
        (0.25 * period, depth),
        (0.75 * period, depth),
        (0.75 * period, 0.0),
        (period, 0.0),
    ];
    profile(tag, period, &xz, n)
}

/// One sheet through the points `xz` (nm) across a tile `period` wide, extruded along y,
/// air above and a medium of index `n` below.
fn profile(tag: &str, period: f64, xz: &[(f64, f64)], n: f64) -> Sample {
    let d = scratch(tag);
    let ly = period / 8.0;
    let mut obj = String::new();
    for &(x, z) in xz {
        obj.push_str(&format!("v {x:?} 0 {z:?}\nv {x:?} {ly:?} {z:?}\n"));
    }
    for i in 0..xz.len() - 1 {
        let (a, b, c, e) = (2 * i + 1, 2 * i + 3, 2 * i + 4, 2 * i + 2);
        obj.push_str(&format!("f {a} {b} {c}\nf {a} {c} {e}\n"));
    }
    std::fs::write(d.join("sheet.obj"), obj).unwrap();
    sample_in(
        &d,
        &format!(
            "[sample]\nname = \"profile\"\nunit = \"nm\"\ntile = [{period:?}, {ly:?}]\n[media.air]\nn = 1.0\n[media.m]\nn = {n:?}\n[[interface]]\nmesh = \"sheet.obj\"\nfront = \"air\"\nback = \"m\"\n"
        ),
    )
}

/// Issue 70: a structure that does not change with height is one slab per band, solved
/// once, whatever `--slices` says: the sliced tile has one patterned layer, R and T at 1, 2
/// and 24 slices agree to rounding, and R + T = 1 (lossless). It used to be cut into 24
/// identical slices, each solved. Under auto it takes the solver.
#[test]
fn lamellae_are_one_slab_whatever_the_slices() {
    use goniospec::reference::grating::{SliceSpec, slice};
    let s = lamellae("rig-lamellae", 600.0, 150.0, 2.0);
    for k in [1, 24] {
        let sliced = slice(
            &s,
            SliceSpec {
                pixels: [720, 1],
                slices: k,
            },
        )
        .unwrap();
        assert_eq!(
            sliced.layers.len(),
            1,
            "{k} slices: {:?}",
            sliced.layers.len()
        );
        assert!((sliced.layers[0].0 - 150.0).abs() < 1e-9);
    }
    let mut totals_at = Vec::new();
    for k in [1, 2, 24] {
        let mut cfg = rigorous(&[20.0], "540:560:20");
        cfg.rigorous.slices = k;
        let acc = run(&s, &cfg);
        let (r, t) = totals(&acc, 0, 0);
        assert!((r + t - 1.0).abs() < 1e-9, "{k} slices: R + T = {}", r + t);
        totals_at.push((r, t));
    }
    for (r, t) in &totals_at[1..] {
        assert!(
            (r - totals_at[0].0).abs() < 1e-12 && (t - totals_at[0].1).abs() < 1e-12,
            "{totals_at:?}"
        );
    }
    // Under auto the binary grating (period 600 nm, near the wavelength) takes the
    // rigorous solver: its vertical walls leave no slope, so it had been passed over as a
    // flat sheet and given rays, unwarned.
    let auto = SimConfig {
        coherence: Coherence::Auto,
        ..rigorous(&[20.0], "540:560:20")
    };
    let acc = run(&s, &auto);
    assert_eq!(acc.header.settings.cell_mode(0, 0), Coherence::Rigorous);
    let (r, _) = totals(&acc, 0, 0);
    assert!(
        (r - totals_at[2].0).abs() < 1e-12,
        "auto R {r}, {totals_at:?}"
    );
}

/// Issue 70: truncations the convergence check could not judge are refused, saying what to
/// give: fewer harmonics than the orders that may propagate (`--orders 0` and 1 passed the
/// check, with R 3 to 7 times too small), and one slice of a relief lit off its grooves'
/// plane, where the staircase serves (`--slices 1` passed, 37 % off).
#[test]
fn checks_that_could_be_fooled_are_refused() {
    let s = sinusoid("rig-fooled", 1000.0, 100.0, (1.5, 0.0), 256, 1);
    for m in [0, 1] {
        let mut cfg = rigorous(&[30.0], "540:560:20");
        cfg.rigorous.orders = Some(m);
        let e = simulate(&s, &cfg, &|_| {}).unwrap_err().to_string();
        assert!(
            e.contains(&format!(
                "--orders {m} keeps fewer harmonics than the 6 orders"
            )) && e.contains("give at least --orders 6"),
            "{e}"
        );
    }
    let mut cfg = rigorous(&[30.0], "540:560:20");
    cfg.phi_i_deg = 45.0;
    cfg.rigorous.slices = 1;
    let e = simulate(&s, &cfg, &|_| {}).unwrap_err().to_string();
    assert!(
        e.contains("--slices 1 cuts the structure") && e.contains("at least --slices 2"),
        "{e}"
    );
    // At 2 slices the check has 1 to compare with: a real comparison, which fails here.
    cfg.rigorous.slices = 2;
    let e = simulate(&s, &cfg, &|_| {}).unwrap_err().to_string();
    assert!(e.contains("did not converge"), "{e}");
}

/// Issue 70: at Rayleigh's anomaly, an order leaving exactly at grazing (a 1 um period at
/// 30 deg and 750 nm: order -2 has sin = 0.5 - 1.5 = -1; at 0 deg and 1,000 nm orders +-1),
/// the solver met a singular matrix and refused the cell. It is solved a hair longer
/// (`RAYLEIGH_SHIFT`, said in the run's figures) and continuous with its neighbours: the
/// efficiencies have a square-root edge there (Hessel & Oliner 1965), so 0.01 nm away R
/// moves by less than 1e-3 (6e-4 on the evanescent side at 0 deg, 1e-5 on the other),
/// and R + T = 1 (lossless).
#[test]
fn a_rayleigh_anomaly_is_solved_continuously() {
    let s = sinusoid("rig-rayleigh", 1000.0, 100.0, (1.5, 0.0), 256, 1);
    for (theta, lambda) in [(30.0, 750.0), (0.0, 1000.0)] {
        let at = |l: f64| {
            let cfg = rigorous(&[theta], "500:600:100");
            let cfg = SimConfig {
                wavelengths: Wavelengths::parse(&format!("{l}"), true).unwrap(),
                ..cfg
            };
            let (acc, stats) = simulate(&s, &cfg, &|_| {}).unwrap_or_else(|e| panic!("{e}"));
            let (r, t) = totals(&acc, 0, 0);
            assert!((r + t - 1.0).abs() < 1e-9, "{l} nm: R + T = {}", r + t);
            (r, stats.rigorous[0].expect("a rigorous cell").rayleigh)
        };
        let (r, anomaly) = at(lambda);
        assert!(
            anomaly,
            "{theta} deg, {lambda} nm is said to be at the anomaly"
        );
        for l in [lambda - 0.01, lambda + 0.01] {
            let (rl, near) = at(l);
            assert!(!near);
            assert!(
                (r - rl).abs() < 1e-3,
                "{theta} deg: R {r} at {lambda} nm, {rl} at {l} nm"
            );
        }
    }
}

/// Issue 70: a sheet whose sides do not meet across the tile (`goniospec check`: "does not
/// tile") is not one period of a structure, and the solver, which repeats the tile, would
/// solve it with a step at every seam: an explicit run is refused naming the interface, and
/// under auto the cell is not given the solver.
#[test]
fn a_mesh_that_does_not_tile_is_refused_by_the_solver() {
    // A ramp from 0 to 80 nm across the tile: a sawtooth once repeated.
    let s = profile(
        "rig-untiled",
        800.0,
        &[(0.0, 0.0), (400.0, 40.0), (800.0, 80.0)],
        1.5,
    );
    let e = simulate(&s, &rigorous(&[0.0], "540:560:20"), &|_| {})
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("interface 0") && e.contains("does not tile") && e.contains("opposite side"),
        "{e}"
    );
    let auto = SimConfig {
        coherence: Coherence::Auto,
        ..rigorous(&[0.0], "540:560:20")
    };
    let acc = run(&s, &auto);
    assert_ne!(acc.header.settings.cell_mode(0, 0), Coherence::Rigorous);
}

/// Issue 70: a run the rigorous solver takes whole traces no tree, so a bar of trees stood
/// at 0 for minutes. Progress counts its cells: the plan knows them before the first is
/// solved, and each one solved reports, up to all of them.
#[test]
fn progress_counts_the_rigorous_cells() {
    use std::sync::Arc;
    use std::sync::atomic::{AtomicU64, Ordering};
    let s = sinusoid("rig-progress", 1000.0, 100.0, (1.5, 0.0), 256, 1);
    let plan = Arc::new(goniospec::simulate::ProgressPlan::default());
    let mut cfg = rigorous(&[0.0, 30.0], "500:600:50");
    cfg.progress_plan = Some(plan.clone());
    let (calls, most) = (AtomicU64::new(0), AtomicU64::new(0));
    let seen = |_n: u64| {
        let (solved, cells) = plan.cells();
        assert_eq!(cells, 4, "the plan names every cell from the start");
        assert!(solved <= cells);
        calls.fetch_add(1, Ordering::Relaxed);
        most.fetch_max(solved, Ordering::Relaxed);
    };
    simulate(&s, &cfg, &seen).unwrap();
    assert_eq!(plan.cells(), (4, 4));
    assert_eq!(calls.load(Ordering::Relaxed), 4, "one report per cell");
    assert_eq!(most.load(Ordering::Relaxed), 4);
}

/// Under auto, a direction whose every cell the choice gives the rigorous solver is solved
/// before any tree and, every cell converging, traces none (the rays an auto run traces are
/// the fallback of a cell that does not converge): a glass sinusoid of period 400 nm (below
/// a wavelength) at 0 and 30 deg records one tree and no segment per direction, and its
/// cells hold the bytes of the explicit `--coherence rigorous` run's cells. At 4,096 trees,
/// where a traced run keeps 16 replicate groups, the run that traced nothing keeps none
/// and its file reads back (a header with more groups than trees is refused on reading).
#[test]
fn an_auto_direction_the_solver_takes_whole_traces_nothing() {
    let s = sinusoid("rig-whole", 400.0, 40.0, (1.5, 0.0), 256, 1);
    let auto = SimConfig {
        coherence: Coherence::Auto,
        ..config(
            &[0.0, 30.0],
            Wavelengths::parse("500:600:50", false).unwrap(),
            256,
        )
    };
    let (a, stats) = simulate(&s, &auto, &|_| {}).unwrap();
    for (di, d) in stats.directions.iter().enumerate() {
        assert_eq!((d.rays, d.segments), (1, 0), "direction {di}");
        for j in 0..2 {
            assert_eq!(a.header.settings.cell_mode(di, j), Coherence::Rigorous);
        }
    }
    let (r, _) = simulate(&s, &rigorous(&[0.0, 30.0], "500:600:50"), &|_| {}).unwrap();
    for k in 0..4 {
        let (x, y) = (a.cell(k / 2, k % 2), r.cell(k / 2, k % 2));
        assert!(
            x.sum == y.sum && x.r_sum == y.r_sum && x.t_sum == y.t_sum,
            "cell {k}: auto and rigorous differ"
        );
    }
    let many = SimConfig {
        rays: 4096,
        ..auto.clone()
    };
    let (a, _) = simulate(&s, &many, &|_| {}).unwrap();
    assert_eq!((a.header.rays, a.header.error_groups), (1, 0));
    let f = common::scratch("rig-whole-file").join("a.gsa");
    a.write(&f).unwrap();
    let back = goniospec::accumulate::file::Accumulator::read(&f).unwrap();
    assert_eq!(back.cells, a.cells);
}

/// Under auto the surface-plasmon warning on a metal grating's total R concerns the cells
/// the rays take, which the run chooses per cell: the optical disc at 30 deg and 410 nm
/// (its order 2 at tangential index 1.012, by the plasmon's 1.027) is solved by the
/// C-method and the run does not warn, where a ray run (`--coherence beamlet`) warns before
/// it starts.
#[test]
fn auto_warns_of_the_plasmon_only_where_rays_take_the_cell() {
    let run = |coherence: &str| {
        let out = common::scratch("rig-plasmon").join(format!("{coherence}.gsa"));
        let (code, _, err) = common::goniospec(&[
            "simulate",
            "meshes/optical-disc-track.toml",
            "--theta-i",
            "30",
            "--wavelengths",
            "400:420:20",
            "--theta-o-bins",
            "10",
            "--rays",
            "256",
            "--coherence",
            coherence,
            "-o",
            out.to_str().unwrap(),
        ]);
        assert_eq!(code, 0, "{err}");
        err
    };
    let auto = run("auto");
    assert!(auto.contains("nothing traced"), "{auto}");
    assert!(!auto.contains("surface plasmon"), "{auto}");
    let rays = run("beamlet");
    assert!(rays.contains("surface plasmon"), "{rays}");
}
