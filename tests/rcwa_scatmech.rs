//! The rigorous solver (`optics::rcwa`) against NIST SCATMECH's RCW_Model and
//! CrossRCW_Model, an independent implementation of the same method (Moharam et al. 1995
//! with Li's factorisation rules, 1996 and 1997). tests/interop/rcw_scatmech.py ran
//! SCATMECH (PyPI pyscatmech 0.1.10) and wrote tests/reference/rcw-scatmech.json: each
//! case's staircase as SCATMECH sliced it, the truncation, and every propagating order's
//! efficiency for s and p light. Here each staircase is rebuilt on a pixel grid whose edges
//! hold every transition exactly and solved at the same truncation, so the two solve one
//! discrete problem and must agree to rounding, whatever their distance from the converged
//! answer (which the stored spread at 1.5 times the harmonics gives).

mod common;

use glam::DVec3;
use goniospec::optics::C64;
use goniospec::optics::rcwa::{self, Grid, Harmonics, Layer, Slab, Solution, Structure};
use serde_json::Value;

fn cplx(v: &Value) -> C64 {
    C64::new(v[0].as_f64().unwrap(), v[1].as_f64().unwrap())
}

/// The fewest pixels per period (up to 100 000) whose edges hold every fraction in
/// `fractions` (of the period, in [0, 1]) to 1e-9.
fn pixels_holding(fractions: &[f64]) -> usize {
    (1..=100_000)
        .find(|&n| {
            fractions
                .iter()
                .all(|f| (f * n as f64 - (f * n as f64).round()).abs() < 1e-9 * n as f64)
        })
        .expect("the transitions fall on a grid of at most 100 000 pixels")
}

/// A 1-D case's staircase: each level's transitions (um, from -period/2 to period/2) with
/// the permittivity of the segment ending at each, top level first.
fn staircase_1d(case: &Value) -> Structure {
    let period = case["period_um"].as_f64().unwrap();
    let levels = case["levels"].as_array().unwrap();
    let frac = |x: &Value| x.as_f64().unwrap() / period + 0.5;
    let fractions: Vec<f64> = levels
        .iter()
        .flat_map(|l| l["positions_um"].as_array().unwrap().iter().map(frac))
        .collect();
    let n = pixels_holding(&fractions);
    let layers = levels
        .iter()
        .map(|l| {
            let pos: Vec<f64> = l["positions_um"]
                .as_array()
                .unwrap()
                .iter()
                .map(frac)
                .collect();
            let eps: Vec<C64> = l["eps"].as_array().unwrap().iter().map(cplx).collect();
            let grid = (0..n)
                .map(|i| {
                    let x = (i as f64 + 0.5) / n as f64;
                    // Segment k runs from pos[k - 1] to pos[k].
                    let k = (1..pos.len()).find(|&k| x < pos[k]).unwrap();
                    eps[k]
                })
                .collect();
            Layer {
                thickness_nm: l["thickness_um"].as_f64().unwrap() * 1e3,
                slab: Slab::Grid(Grid {
                    n: [n, 1],
                    eps: grid,
                }),
            }
        })
        .collect();
    Structure {
        period_nm: [period * 1e3, 1.0],
        eps_above: cplx(&case["eps_above"]).re,
        layers,
        eps_below: cplx(&case["eps_below"]),
    }
}

/// The crossed case: a block of `block_um` centred in the square cell, on 8 x 8 pixels
/// (75 nm: the block's edges at pixels 2, 6 along x and 3, 5 along y).
fn blocks(case: &Value) -> Structure {
    let period = case["period_um"].as_f64().unwrap();
    let b = [
        case["block_um"][0].as_f64().unwrap(),
        case["block_um"][1].as_f64().unwrap(),
    ];
    let n = 8;
    let inside = |i: usize, len: f64| {
        let x = ((i as f64 + 0.5) / n as f64 - 0.5) * period;
        x.abs() < 0.5 * len
    };
    for (len, edge) in [(b[0], 2.0), (b[1], 3.0)] {
        assert!(((0.5 - len / period / 2.0) * n as f64 - edge).abs() < 1e-9);
    }
    let eps = (0..n * n)
        .map(|k| {
            if inside(k % n, b[0]) && inside(k / n, b[1]) {
                cplx(&case["eps_block"])
            } else {
                cplx(&case["eps_above"])
            }
        })
        .collect();
    Structure {
        period_nm: [period * 1e3; 2],
        eps_above: cplx(&case["eps_above"]).re,
        layers: vec![Layer {
            thickness_nm: case["height_um"].as_f64().unwrap() * 1e3,
            slab: Slab::Grid(Grid { n: [n, n], eps }),
        }],
        eps_below: cplx(&case["eps_below"]),
    }
}

/// One side's orders grouped by the length of their transverse wave vector (to 1e-9): an
/// order is found by its exit angle, which needs no agreement on the signs of the order
/// indices or on the frames of the two codes. Within a group (only orders a symmetry
/// makes equivalent share an exit angle here) the efficiencies are compared sorted.
fn groups(orders: impl Iterator<Item = (f64, [f64; 2])>) -> Vec<(f64, Vec<[f64; 2]>)> {
    let mut out: Vec<(f64, Vec<[f64; 2]>)> = Vec::new();
    for (kt, e) in orders {
        match out.iter_mut().find(|(k, _)| (k - kt).abs() < 1e-9) {
            Some((_, v)) => v.push(e),
            None => out.push((kt, vec![e])),
        }
    }
    for (_, v) in &mut out {
        v.sort_by(|a, b| (a[0] + a[1]).total_cmp(&(b[0] + b[1])));
    }
    out.sort_by(|a, b| a.0.total_cmp(&b.0));
    out
}

/// The largest difference of any order's efficiency, s or p, on either side.
fn largest_difference(case: &Value, ours: &Solution) -> f64 {
    let mut worst: f64 = 0.0;
    for (side, up) in [("r", true), ("t", false)] {
        let theirs = case["orders"][side].as_array().unwrap();
        if theirs.is_empty() {
            continue;
        }
        let t = groups(theirs.iter().map(|o| {
            let d = &o["dir"];
            let kt = d[0].as_f64().unwrap().hypot(d[1].as_f64().unwrap());
            let (s, p) = (o["s"].as_f64().unwrap(), o["p"].as_f64().unwrap());
            (kt, [s, p])
        }));
        let o = groups(
            ours.orders
                .iter()
                .filter(|o| o.up == up)
                .map(|o| (o.dir.x.hypot(o.dir.y), [o.efficiency(0), o.efficiency(1)])),
        );
        let name = case["name"].as_str().unwrap();
        assert_eq!(
            t.iter().map(|g| g.1.len()).collect::<Vec<_>>(),
            o.iter().map(|g| g.1.len()).collect::<Vec<_>>(),
            "{name} ({side}): the propagating orders differ"
        );
        for ((kt, a), (ko, b)) in t.iter().zip(&o) {
            assert!(
                (kt - ko).abs() < 1e-9,
                "{name} ({side}): exit angles differ"
            );
            for (x, y) in a.iter().zip(b) {
                worst = worst.max((x[0] - y[0]).abs()).max((x[1] - y[1]).abs());
            }
        }
    }
    worst
}

/// Every case at SCATMECH's own staircase and truncation: every order's efficiency, s and
/// p, reflected and (lossless substrates) transmitted, within 1e-6. The 1-D cases are one
/// discrete problem in both codes (measured: within 6e-14); the crossed grating's Fourier
/// coefficients differ by SCATMECH's DFT of samples, a relative 1 - sinc(pi p / 4096) <=
/// 1e-6 at the highest harmonic (measured: 1.3e-8). One case is held to the issue's 1e-4
/// instead: on the 5 um sinusoid SCATMECH's reflected p orders differ from ours by up to
/// 5.4e-5 while its transmitted ones agree to 1e-9, and its R + T misses 1 by 5.2e-5 (stored
/// as `energy_defect`; 1e-14 on every other case), where ours holds R + T = 1 to 1e-9
/// (asserted here for every lossless case), so the difference is SCATMECH's. Glass sinusoids of 1, 2 and 5 um (and the 1 um one in conical incidence), a
/// lamellar gold grating, 60-degree gold V-grooves at 0, 60 and 85 deg in TE and TM (the
/// grooves of issue 25, where no PyPI solver converged in TM), and a crossed grating at the
/// same square truncation, 11 x 11 harmonics.
#[test]
fn orders_match_scatmech_on_its_own_staircases() {
    let path = common::root().join("tests/reference/rcw-scatmech.json");
    let v: Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    let cases = v["cases"].as_array().unwrap();
    assert_eq!(cases.len(), 9);
    for case in cases {
        let name = case["name"].as_str().unwrap();
        let (theta, rot) = (
            case["theta_deg"].as_f64().unwrap(),
            case["rotation_deg"].as_f64().unwrap(),
        );
        let m = case["order"].as_u64().unwrap() as usize;
        let (s, h) = match case["kind"].as_str().unwrap() {
            "1d" => (staircase_1d(case), Harmonics { m: [m, 0] }),
            _ => (blocks(case), Harmonics { m: [m, m] }),
        };
        let (t, p) = (theta.to_radians(), rot.to_radians());
        let mut d = DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), -t.cos());
        if theta == 0.0 {
            // SCATMECH takes normal incidence as sin(theta) = 1e-7 in the plane x-z (its
            // zero order's direction says so): the same incidence here, so that s is E along
            // y in both (exactly at normal incidence `mueller::frame` makes s E along x).
            let zero = &case["orders"]["r"]
                .as_array()
                .unwrap()
                .iter()
                .find(|o| o["i"] == 0);
            let dir = &zero.unwrap()["dir"];
            let sx = dir[0].as_f64().unwrap();
            assert!(sx > 0.0 && sx < 1e-6 && dir[1].as_f64().unwrap() == 0.0);
            d = DVec3::new(sx, 0.0, -(1.0 - sx * sx).sqrt());
        }
        let lambda = case["lambda_um"].as_f64().unwrap() * 1e3;
        let ours = rcwa::solve(&s, lambda, d, h).unwrap();
        let worst = largest_difference(case, &ours);
        let defect = case["energy_defect"].as_f64().unwrap();
        let lossless = !case["orders"]["t"].as_array().unwrap().is_empty();
        if lossless {
            for pol in 0..2 {
                let e = (ours.r[pol] + ours.t[pol] - 1.0).abs();
                assert!(e < 1e-9, "{name}: R + T - 1 = {e:.1e}");
            }
        }
        let tol = if defect < 1e-12 { 1e-6 } else { 1e-4 };
        println!(
            "{name}: R s {:.6} p {:.6}; largest order difference {worst:.1e} (SCATMECH's own spread at 1.5 times the harmonics: {:.1e})",
            ours.r[0],
            ours.r[1],
            case["spread"].as_f64().unwrap()
        );
        assert!(worst < tol, "{name}: an order differs by {worst:.2e}");
    }
}
