//! A metal relief under a flat lacquer (the holographic foil: an aluminised 1 um sinusoid
//! under 2 um of lacquer) by the C-method joined to its flat top order by order
//! (`optics::rcwa::solve_profile` with `planes`), against the Rayleigh-Fourier method
//! written here: plane waves in air, in the lacquer (both ways) and in the metal, every
//! boundary condition of both interfaces in one linear system solved by Gaussian
//! elimination (no curvilinear coordinates, no eigenproblem, no star product). Lord
//! Rayleigh, Proc. R. Soc. A 79 (1907) 399; Petit (ed.), "Electromagnetic Theory of
//! Gratings", Springer 1980, ch. 1. The Rayleigh expansion holds on a sinusoid for
//! `K A < 0.448` (Petit & Cadilhac 1966; Millar 1971); the foil's is 0.314. The reference
//! is checked for convergence in its own orders (40 against 60) and, on a lossless
//! version, for energy.

mod common;

use glam::DVec3;
use goniospec::accumulate::Coherence;
use goniospec::optics::C64;
use goniospec::optics::rcwa::{self, Plane, Profile, Solution};
use goniospec::simulate::{SimConfig, Wavelengths, simulate};

const I: C64 = C64::new(0.0, 1.0);
/// Aluminium near 550 nm (a constant index, as the test needs one medium, not a table).
const ALUMINIUM: C64 = C64::new(0.958, 6.69);
const PERIOD: f64 = 1000.0;
const AMP: f64 = 50.0;
const TOP: f64 = 2000.0;

fn deg(theta: f64) -> DVec3 {
    let t = theta.to_radians();
    DVec3::new(t.sin(), 0.0, -t.cos())
}

/// `z = AMP cos(2π x / Λ)` under a flat plane at `TOP` (`n_layer` below it, `n_above`
/// above), over a substrate `n_below`.
fn foil(n_above: f64, n_layer: f64, n_below: C64) -> Profile {
    Profile {
        period_nm: PERIOD,
        heights_nm: (0..1024)
            .map(|i| AMP * (2.0 * std::f64::consts::PI * i as f64 / 1024.0).cos())
            .collect(),
        eps_above: n_above * n_above,
        eps_below: n_below * n_below,
        planes: vec![Plane {
            z_nm: TOP,
            eps_below: C64::new(n_layer * n_layer, 0.0),
        }],
    }
}

/// The Rayleigh-Fourier reference: reflected efficiencies by order `(m, eta)` and total
/// R and T (T meaningful over a lossless substrate) for TE (`tm = false`) or TM, orders
/// `-n..=n`. Unknowns: reflected `r_m` (referred to the top plane), the lacquer's
/// down-going `d_m` (referred to the top plane) and up-going `u_m` (referred to the
/// relief's lowest point), the substrate's `t_m` (referred to its highest point), so that
/// every exponential in the system is at most 1.
fn rayleigh(
    n_above: f64,
    n_layer: f64,
    n_below: C64,
    lambda: f64,
    theta: f64,
    tm: bool,
    n: i64,
) -> (Vec<(i64, f64)>, f64, f64) {
    let k0 = 2.0 * std::f64::consts::PI / lambda;
    let (ea, el, eb) = (
        C64::new(n_above * n_above, 0.0),
        C64::new(n_layer * n_layer, 0.0),
        n_below * n_below,
    );
    let eta = |e: C64| if tm { e } else { C64::new(1.0, 0.0) };
    let orders: Vec<i64> = (-n..=n).collect();
    let no = orders.len();
    let a0 = n_above * theta.to_radians().sin();
    let alpha: Vec<f64> = orders
        .iter()
        .map(|&m| a0 + m as f64 * lambda / PERIOD)
        .collect();
    let (ba, bl, bb): (Vec<C64>, Vec<C64>, Vec<C64>) = (
        alpha.iter().map(|&a| common::kz(ea, a)).collect(),
        alpha.iter().map(|&a| common::kz(el, a)).collect(),
        alpha.iter().map(|&a| common::kz(eb, a)).collect(),
    );
    let s = 2048;
    let xs: Vec<f64> = (0..s).map(|j| PERIOD * j as f64 / s as f64).collect();
    let kg = 2.0 * std::f64::consts::PI / PERIOD;
    let h: Vec<f64> = xs.iter().map(|x| AMP * (kg * x).cos()).collect();
    let dh: Vec<f64> = xs.iter().map(|x| -AMP * kg * (kg * x).sin()).collect();
    // The projection on harmonic `q` of `f(x) e^{i (m - q) K x}`, from a table of the
    // `s` roots of unity.
    let roots: Vec<C64> = (0..s)
        .map(|j| C64::from_polar(1.0, 2.0 * std::f64::consts::PI * j as f64 / s as f64))
        .collect();
    let project = |f: &[C64], dm: i64| -> C64 {
        let step = dm.rem_euclid(s as i64) as usize;
        let (mut at, mut acc) = (0usize, C64::new(0.0, 0.0));
        for v in f {
            acc += v * roots[at];
            at = (at + step) % s;
        }
        acc / s as f64
    };
    let size = 4 * no;
    let mut a = vec![C64::new(0.0, 0.0); size * size];
    let mut b = vec![C64::new(0.0, 0.0); size];
    let col = |block: usize, m: usize| block * no + m;
    let centre = n as usize;
    // The top plane, order by order: F and (1/η) dF/dz.
    for q in 0..no {
        let lift = (I * bl[q] * k0 * (TOP + AMP)).exp(); // u from the lowest point to TOP
        let (r0, r1) = (q, no + q);
        a[r0 * size + col(0, q)] = C64::new(1.0, 0.0);
        a[r0 * size + col(1, q)] = -C64::new(1.0, 0.0);
        a[r0 * size + col(2, q)] = -lift;
        a[r1 * size + col(0, q)] = I * ba[q] / eta(ea);
        a[r1 * size + col(1, q)] = I * bl[q] / eta(el);
        a[r1 * size + col(2, q)] = -I * bl[q] * lift / eta(el);
        if q == centre {
            b[r0] = -C64::new(1.0, 0.0);
            b[r1] = I * ba[q] / eta(ea);
        }
    }
    // The relief, projected on each harmonic: F and (1/η) N·∇F with N = (−h', 1). Each
    // wave's F and N·∇F on the relief: lacquer down (−β, referred to TOP), lacquer up (+β,
    // to −AMP), substrate down (−γ, to +AMP).
    for m in 0..no {
        let terms = [
            (col(1, m), -bl[m], TOP, el, 1.0),
            (col(2, m), bl[m], -AMP, el, 1.0),
            (col(3, m), -bb[m], AMP, eb, -1.0),
        ];
        for (c, kzm, reference, e, sign) in terms {
            let f: Vec<C64> = h
                .iter()
                .map(|&hj| (I * kzm * k0 * (hj - reference)).exp())
                .collect();
            let g: Vec<C64> = f
                .iter()
                .zip(&dh)
                .map(|(&fj, &dj)| I * (kzm - alpha[m] * dj) * fj)
                .collect();
            for q in 0..no {
                let dm = m as i64 - q as i64;
                let (r0, r1) = (2 * no + q, 3 * no + q);
                a[r0 * size + c] = project(&f, dm) * sign;
                a[r1 * size + c] = project(&g, dm) * sign / eta(e);
            }
        }
    }
    let x = common::gauss(a, b);
    let b0 = ba[centre].re;
    let mut eff = Vec::new();
    let (mut r, mut t) = (0.0, 0.0);
    for m in 0..no {
        let e = x[col(0, m)].norm_sqr() * ba[m].re / b0;
        if ba[m].re > 0.0 {
            eff.push((orders[m], e));
        }
        r += e;
        // Flux through a horizontal plane: |t|² Re(γ / η) over β0 / η_above.
        t += x[col(3, m)].norm_sqr() * (bb[m] / eta(eb)).re / (b0 / eta(ea).re);
    }
    (eff, r, t)
}

fn order_r(s: &Solution, m: i64, pol: usize) -> f64 {
    s.orders
        .iter()
        .find(|o| o.up && o.m[0] == m)
        .map_or(0.0, |o| o.efficiency(pol))
}

/// The reference converges in its orders (40 against 60: 1e-6) and, lossless, conserves
/// energy (1e-9); the glass relief under a layer by the C-method conserves it too.
#[test]
fn the_reference_converges_and_a_lossless_version_conserves_energy() {
    for tm in [false, true] {
        let (_, r40, _) = rayleigh(1.0, 1.5, ALUMINIUM, 550.0, 30.0, tm, 40);
        let (_, r60, _) = rayleigh(1.0, 1.5, ALUMINIUM, 550.0, 30.0, tm, 60);
        assert!((r40 - r60).abs() < 1e-6, "tm {tm}: {r40} against {r60}");
        let (_, r, t) = rayleigh(1.0, 1.3, C64::new(1.72, 0.0), 550.0, 30.0, tm, 40);
        assert!((r + t - 1.0).abs() < 1e-9, "tm {tm}: R + T = {}", r + t);
    }
    let p = foil(1.0, 1.3, C64::new(1.72, 0.0));
    for theta in [0.0, 30.0, 60.0] {
        let s = rcwa::solve_profile(&p, 550.0, deg(theta), 16).unwrap();
        for pol in 0..2 {
            let sum = s.r[pol] + s.t[pol];
            assert!(
                (sum - 1.0).abs() < 1e-9,
                "{theta} deg pol {pol}: R + T = {sum}"
            );
        }
    }
}

/// The foil (air / 2 um lacquer n 1.5 / aluminium sinusoid, Λ 1 um, A 50 nm) at 450 to
/// 650 nm and 0 to 70 deg: every reflected order and R within 1e-4 of the Rayleigh-Fourier
/// method in TE and in TM (the issue asks 1e-3), at the harmonics a run takes (propagating
/// in the lacquer plus 12).
#[test]
fn a_lacquered_aluminium_sinusoid_matches_the_rayleigh_fourier_method() {
    let p = foil(1.0, 1.5, ALUMINIUM);
    let mut worst: f64 = 0.0;
    for lambda in [450.0, 550.0, 650.0] {
        let m = (2.0 * 1.5 * PERIOD / lambda).ceil() as usize + 12;
        for theta in [0.0, 20.0, 45.0, 70.0] {
            let s = rcwa::solve_profile(&p, lambda, deg(theta), m).unwrap();
            for (pol, tm) in [(0, false), (1, true)] {
                // At exactly 0 deg the frame's s is E along x: TM.
                let pol = if theta == 0.0 { 1 - pol } else { pol };
                let (orders, r, _) = rayleigh(1.0, 1.5, ALUMINIUM, lambda, theta, tm, 40);
                let d = (s.r[pol] - r).abs();
                assert!(
                    d < 1e-4,
                    "{lambda} nm {theta} deg tm {tm}: R {} against {r}",
                    s.r[pol]
                );
                worst = worst.max(d);
                for (om, e) in orders {
                    let d = (order_r(&s, om, pol) - e).abs();
                    assert!(
                        d < 1e-4,
                        "{lambda} nm {theta} deg tm {tm} order {om}: {} against {e}",
                        order_r(&s, om, pol)
                    );
                    worst = worst.max(d);
                }
            }
        }
    }
    println!("largest difference from the Rayleigh-Fourier method: {worst:.1e}");
}

/// The shipped foil (`meshes/holographic-foil.toml`: its relief of 256 facets a period, the
/// McPeak aluminium table) under the default `--coherence auto` at 0, 30 and 60 deg and
/// 550 nm: every cell takes the C-method joined to the lacquer (unsliced), and its R
/// (unpolarised) is within 1e-3 of the Rayleigh-Fourier method at the table's index there
/// (the bar; the facets' departure from the sinusoid is the difference; measured
/// 2.4e-5 at worst).
#[test]
fn the_shipped_foil_under_auto_is_the_reference() {
    let s = common::shipped("holographic-foil.toml");
    let cfg = SimConfig {
        coherence: Coherence::Auto,
        ..common::config(
            &[0.0, 30.0, 60.0],
            Wavelengths::parse("540:560:20", false).unwrap(),
            256,
        )
    };
    let (acc, stats) = simulate(&s, &cfg, &|_| {}).unwrap();
    let mut idx = Vec::new();
    s.indices_into(550.0, &mut idx);
    let al = idx[s.media.iter().position(|m| m.name == "aluminium").unwrap()];
    for (i, &theta) in cfg.theta_i_deg.iter().enumerate() {
        assert_eq!(acc.header.settings.cell_mode(i, 0), Coherence::Rigorous);
        assert!(
            stats.rigorous[i].is_some_and(|c| c.slices == 0),
            "{theta} deg"
        );
        let (r, _) = common::totals(&acc, i, 0);
        let te = rayleigh(1.0, 1.5, al, 550.0, theta, false, 40).1;
        let tm = rayleigh(1.0, 1.5, al, 550.0, theta, true, 40).1;
        let want = 0.5 * (te + tm);
        println!("{theta} deg: R {r:.6}, Rayleigh-Fourier {want:.6} (TE {te:.6}, TM {tm:.6})");
        assert!((r - want).abs() < 1e-3, "{theta} deg: R {r} against {want}");
    }
}
