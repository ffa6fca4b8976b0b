//! The C-method on reliefs with sharp corners, in the stretched coordinate of adaptive
//! spatial resolution (`optics::rcwa::solve_profile`, `asr.rs`; Granet, Chandezon, Plumey &
//! Raniriharinosy 2001, JOSA A 18, 2102): the optical disc's trapezoid (1.6 um pitch, 200
//! nm deep, walls of slope 4) against references written here. The Fourier modal method's
//! staircase, a different discretisation of Maxwell's equations with vertical walls, is
//! converged on a dielectric trapezoid in both polarisations and on the metal in TE (50
//! slices against 400: 2e-5); there every order is compared. On the metal in TM the
//! staircase converges as `1 / M` (R 0.813 at 60 harmonics, 0.825 at 100), so there the
//! checks are reciprocity (Petit 1980, §1.4) on an asymmetric trapezoid and the C-method's
//! own convergence in its harmonics; the transformation itself is checked in
//! `cmethod.rs`'s unit tests (a stretched sinusoid is the plain one within 1e-8).

use glam::DVec3;
use goniospec::optics::C64;
use goniospec::optics::rcwa::{self, Grid, Harmonics, Layer, Profile, Slab, Solution, Structure};

/// Aluminium near 550 nm (McPeak et al. 2015; a constant index for the test).
const ALUMINIUM: C64 = C64::new(0.958, 6.69);
const PERIOD: f64 = 1600.0;
const DEPTH: f64 = 200.0;

fn deg(theta: f64) -> DVec3 {
    let t = theta.to_radians();
    DVec3::new(t.sin(), 0.0, -t.cos())
}

/// A groove of depth [`DEPTH`]: the top until `x[0]`, down to the bottom at `x[1]`, the
/// bottom until `x[2]`, up to the top at `x[3]` (nm).
fn groove(x: [f64; 4], at: f64) -> f64 {
    if at < x[0] || at >= x[3] {
        0.0
    } else if at < x[1] {
        -DEPTH * (at - x[0]) / (x[1] - x[0])
    } else if at < x[2] {
        -DEPTH
    } else {
        -DEPTH * (x[3] - at) / (x[3] - x[2])
    }
}

/// The disc's groove: 600 nm wide at the top, 500 at the bottom.
const DISC: [f64; 4] = [500.0, 550.0, 1050.0, 1100.0];

fn profile(x: [f64; 4], n: C64) -> Profile {
    Profile {
        period_nm: PERIOD,
        heights_nm: (0..1024)
            .map(|i| groove(x, i as f64 * PERIOD / 1024.0))
            .collect(),
        eps_above: 1.0,
        eps_below: n * n,
        planes: Vec::new(),
    }
}

/// The groove as a staircase of `slices` on `cells` pixels (a pixel is air where the
/// groove's surface lies below its centre).
fn staircase(x: [f64; 4], n: C64, slices: usize, cells: usize) -> Structure {
    let dz = DEPTH / slices as f64;
    let layers = (0..slices)
        .map(|j| {
            let z = -(j as f64 + 0.5) * dz;
            let eps = (0..cells)
                .map(|i| {
                    let at = (i as f64 + 0.5) * PERIOD / cells as f64;
                    if groove(x, at) < z {
                        C64::new(1.0, 0.0)
                    } else {
                        n * n
                    }
                })
                .collect();
            Layer {
                thickness_nm: dz,
                slab: Slab::Grid(Grid { n: [cells, 1], eps }),
            }
        })
        .collect();
    Structure {
        period_nm: [PERIOD, 1.0],
        eps_above: 1.0,
        layers,
        eps_below: n * n,
    }
}

fn efficiency(s: &Solution, m: i64, up: bool, pol: usize) -> f64 {
    s.orders
        .iter()
        .find(|o| o.m == [m, 0] && o.up == up)
        .map_or(0.0, |o| o.efficiency(pol))
}

/// The largest difference between two solutions' order efficiencies in polarisation `pol`
/// (0: s, TE; 1: p, TM), over the orders of either.
fn largest_difference(a: &Solution, b: &Solution, pol: usize) -> f64 {
    a.orders
        .iter()
        .chain(&b.orders)
        .map(|o| (efficiency(a, o.m[0], o.up, pol) - efficiency(b, o.m[0], o.up, pol)).abs())
        .fold(0.0, f64::max)
}

/// A glass trapezoid (the disc's groove in n = 1.5, 30 deg, 550 nm) by the C-method at 120
/// harmonics against the staircase (50 slices, 60 harmonics, 3,200 pixels; converged: 400
/// slices and 100 harmonics move it by 2e-5): every reflected and transmitted order within
/// 1e-3 in TE and TM (measured 3.3e-4 and 2.7e-4), and R + T within 1e-3 of 1 (measured
/// 2.9e-4 and 3.9e-4: the truncated stretch's own error, where the plain C-method on a
/// smooth relief balances to 1e-9).
#[test]
fn a_glass_trapezoid_is_the_staircase_limit() {
    let d = deg(30.0);
    let glass = C64::new(1.5, 0.0);
    let c = rcwa::solve_profile(&profile(DISC, glass), 550.0, d, 120).unwrap();
    let st = rcwa::solve(
        &staircase(DISC, glass, 50, 3200),
        550.0,
        d,
        Harmonics { m: [60, 0] },
    )
    .unwrap();
    for pol in 0..2 {
        let diff = largest_difference(&c, &st, pol);
        println!("glass trapezoid, pol {pol}: {diff:.2e} from the staircase");
        assert!(diff < 1e-3, "pol {pol}: {diff}");
        let sum = c.r[pol] + c.t[pol];
        assert!((sum - 1.0).abs() < 1e-3, "pol {pol}: R + T = {sum}");
    }
    assert!(c.orders.iter().filter(|o| o.up).count() >= 6);
}

/// The disc's aluminium trapezoid in TE (30 deg, 550 nm) against the staircase, which
/// converges there (60 against 100 harmonics: 1.1e-4 in every order): every order within
/// 2e-3 (measured 1.1e-3; the C-method moves by 2.9e-4 from 120 to 180 harmonics).
#[test]
fn an_aluminium_trapezoid_in_te_is_the_staircase_limit() {
    let d = deg(30.0);
    let c = rcwa::solve_profile(&profile(DISC, ALUMINIUM), 550.0, d, 120).unwrap();
    let st = rcwa::solve(
        &staircase(DISC, ALUMINIUM, 50, 3200),
        550.0,
        d,
        Harmonics { m: [60, 0] },
    )
    .unwrap();
    let diff = largest_difference(&c, &st, 0);
    println!("aluminium trapezoid, TE: {diff:.2e} from the staircase");
    assert!(diff < 2e-3, "{diff}");
}

/// Reciprocity (Petit 1980, "Electromagnetic Theory of Gratings", §1.4): the efficiency of
/// order m from `kx` equals that of order m from `-(kx + m λ / Λ)`, on an asymmetric
/// aluminium trapezoid (walls 50 and 200 nm wide), TE and TM, at 120 harmonics: within
/// 2e-3 (measured 9.3e-4; the truncated stretch keeps it only to its convergence, where
/// the plain C-method on a smooth relief keeps it to 1e-9).
#[test]
fn an_aluminium_trapezoid_is_reciprocal() {
    let p = profile([300.0, 350.0, 900.0, 1100.0], ALUMINIUM);
    let (lambda, kx) = (550.0, 20f64.to_radians().sin());
    let along = |kx: f64| DVec3::new(kx, 0.0, -(1.0 - kx * kx).sqrt());
    let a = rcwa::solve_profile(&p, lambda, along(kx), 120).unwrap();
    let mut checked = 0;
    for o in a.orders.iter().filter(|o| o.up && o.m[0] != 0) {
        let m = o.m[0];
        let b = rcwa::solve_profile(&p, lambda, along(-(kx + m as f64 * lambda / PERIOD)), 120)
            .unwrap();
        for pol in 0..2 {
            let (x, y) = (o.efficiency(pol), efficiency(&b, m, true, pol));
            assert!(
                (x - y).abs() < 2e-3,
                "order {m}, pol {pol}: {x} against {y}"
            );
        }
        checked += 1;
    }
    assert!(checked >= 3, "{checked} orders");
}

/// The disc's aluminium trapezoid converges in its harmonics (30 deg, 550 nm), where the
/// plain C-method and the staircase do not (TM R 0.8366 to 0.8444 from 40 to 200 harmonics
/// unstretched; the staircase 0.8128 at 60, 0.8249 at 100): 120 against 180 harmonics,
/// every order within 1e-3 in TE and TM (measured 2.9e-4 and 3.9e-5).
#[test]
fn the_disc_converges_in_its_harmonics() {
    let p = profile(DISC, ALUMINIUM);
    let d = deg(30.0);
    let a = rcwa::solve_profile(&p, 550.0, d, 120).unwrap();
    let b = rcwa::solve_profile(&p, 550.0, d, 180).unwrap();
    for pol in 0..2 {
        let diff = largest_difference(&a, &b, pol);
        println!("the disc, pol {pol}: 120 against 180 harmonics {diff:.2e}");
        assert!(diff < 1e-3, "pol {pol}: {diff}");
    }
}
