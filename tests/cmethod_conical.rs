//! The C-method in conical incidence (`optics::rcwa::solve_profile` with light off the
//! plane across the grooves, `d.y ≠ 0`) against references written here: Fresnel's
//! equations on a flat interface, energy on lossless reliefs (bare and under a layer), the
//! classical mount as the azimuth goes to 0, reciprocity, the Fourier modal method's
//! staircase on glass (conical, where it converges; itself checked against NIST SCATMECH
//! in `tests/rcwa_scatmech.rs`), and, on the aluminium foil under its lacquer, a vector
//! Rayleigh-Fourier method: plane waves of both polarisations in every medium, the
//! tangential `E` and `H` (along `(1, 0, a')` and `y`) matched on the relief and on the
//! flat top as vectors, one linear system by Gaussian elimination. It shares no formula with
//! the solver's coupled `E_y`, `H_y` formulation (Rayleigh 1907; Petit 1980, ch. 1; valid
//! for the sinusoid's `K A = 0.314 < 0.448`).

mod common;

use glam::DVec3;
use goniospec::optics::C64;
use goniospec::optics::rcwa::{self, Plane, Profile, Solution};

const I: C64 = C64::new(0.0, 1.0);
const ZERO: C64 = C64::new(0.0, 0.0);
const ALUMINIUM: C64 = C64::new(0.958, 6.69);
const GOLD: C64 = C64::new(0.43, 2.455);
const PERIOD: f64 = 1000.0;
const AMP: f64 = 50.0;
const TOP: f64 = 2000.0;

/// The unit direction at polar `theta` and azimuth `phi` (degrees), travelling down.
fn dir(theta: f64, phi: f64) -> DVec3 {
    let (t, p) = (theta.to_radians(), phi.to_radians());
    DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), -t.cos())
}

fn sinusoid(
    shape: fn(f64) -> f64,
    amp: f64,
    above: f64,
    below: C64,
    planes: Vec<Plane>,
) -> Profile {
    Profile {
        period_nm: PERIOD,
        heights_nm: (0..1024)
            .map(|i| amp * shape(2.0 * std::f64::consts::PI * i as f64 / 1024.0))
            .collect(),
        eps_above: above * above,
        eps_below: below * below,
        planes,
    }
}

fn lacquer(n: f64) -> Vec<Plane> {
    vec![Plane {
        z_nm: TOP,
        eps_below: C64::new(n * n, 0.0),
    }]
}

fn eff(s: &Solution, m: i64, up: bool, pol: usize) -> f64 {
    s.orders
        .iter()
        .find(|o| o.m == [m, 0] && o.up == up)
        .map_or(0.0, |o| o.efficiency(pol))
}

/// A flat interface lit at 40 deg from 45 deg of azimuth: Fresnel's R for s and p (Born &
/// Wolf §1.5.2), glass and gold, within 1e-12; lossless, R + T = 1.
#[test]
fn a_flat_interface_in_conical_incidence_is_fresnel() {
    for n in [C64::new(1.5, 0.0), GOLD] {
        let p = sinusoid(f64::cos, 0.0, 1.0, n, Vec::new());
        let t = 40f64.to_radians();
        let ci = C64::new(t.cos(), 0.0);
        let ct = (n * n - t.sin().powi(2)).sqrt() / n;
        let rs = (ci - n * ct) / (ci + n * ct);
        let rp = (n * ci - ct) / (n * ci + ct);
        let s = rcwa::solve_profile(&p, 550.0, dir(40.0, 45.0), 6).unwrap();
        assert!(
            (s.r[0] - rs.norm_sqr()).abs() < 1e-12,
            "{n}: R_s {}",
            s.r[0]
        );
        assert!(
            (s.r[1] - rp.norm_sqr()).abs() < 1e-12,
            "{n}: R_p {}",
            s.r[1]
        );
        if n.im == 0.0 {
            for pol in 0..2 {
                assert!((s.r[pol] + s.t[pol] - 1.0).abs() < 1e-12);
            }
        }
    }
}

/// Lossless reliefs lit off-plane conserve energy: a glass sinusoid bare and under a layer
/// (n 1.3 over n 1.72), at 30 and 60 deg of azimuth, both polarisations, R + T = 1 within
/// 1e-9; and as the azimuth goes to 0 the classical mount's answer returns (1e-7 deg: every
/// order's efficiency within 1e-9 of the classical solution's).
#[test]
fn conical_reliefs_conserve_energy_and_meet_the_classical_mount() {
    let bare = sinusoid(f64::cos, 50.0, 1.0, C64::new(1.5, 0.0), Vec::new());
    let layered = sinusoid(f64::cos, 50.0, 1.0, C64::new(1.72, 0.0), lacquer(1.3));
    for p in [&bare, &layered] {
        for (theta, phi) in [(30.0, 30.0), (50.0, 60.0), (20.0, 90.0)] {
            let s = rcwa::solve_profile(p, 550.0, dir(theta, phi), 16).unwrap();
            for pol in 0..2 {
                let sum = s.r[pol] + s.t[pol];
                assert!(
                    (sum - 1.0).abs() < 1e-9,
                    "{theta}/{phi} pol {pol}: R + T = {sum}"
                );
            }
        }
    }
    let gold = sinusoid(f64::cos, 50.0, 1.0, GOLD, lacquer(1.5));
    let classical = rcwa::solve_profile(&gold, 550.0, dir(30.0, 0.0), 16).unwrap();
    let near = rcwa::solve_profile(&gold, 550.0, dir(30.0, 1e-7), 16).unwrap();
    assert_eq!(classical.orders.len(), near.orders.len());
    for o in &classical.orders {
        for pol in 0..2 {
            let (a, b) = (o.efficiency(pol), eff(&near, o.m[0], o.up, pol));
            assert!(
                (a - b).abs() < 1e-9,
                "order {:?} pol {pol}: {a} against {b}",
                o.m
            );
        }
    }
}

/// Reciprocity (Petit 1980, §1.4): the unpolarised efficiency of order m from the
/// horizontal wave vector `k` equals that of order m from `−(k + m K)`, on a blazed gold
/// relief off-plane, within 1e-9.
#[test]
fn conical_order_efficiencies_are_reciprocal() {
    let blaze = |x: f64| x.sin() + 0.3 * (2.0 * x).sin();
    let p = sinusoid(blaze, 60.0, 1.0, GOLD, Vec::new());
    let lambda = 550.0;
    let d = dir(25.0, 40.0);
    let a = rcwa::solve_profile(&p, lambda, d, 14).unwrap();
    let mut checked = 0;
    for o in a.orders.iter().filter(|o| o.up && o.m[0] != 0) {
        let m = o.m[0] as f64;
        let (kx, ky) = (-(d.x + m * lambda / PERIOD), -d.y);
        let back = DVec3::new(kx, ky, -(1.0 - kx * kx - ky * ky).sqrt());
        let b = rcwa::solve_profile(&p, lambda, back, 14).unwrap();
        let (x, y) = (
            o.efficiency_unpolarised(),
            b.orders
                .iter()
                .find(|q| q.up && q.m == o.m)
                .unwrap()
                .efficiency_unpolarised(),
        );
        assert!((x - y).abs() < 1e-9, "order {m}: {x} against {y}");
        checked += 1;
    }
    assert!(checked >= 2, "{checked} orders");
}

/// `a × b` of complex 3-vectors.
fn cross(a: [C64; 3], b: [C64; 3]) -> [C64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The s wave (E along `ŝ = (−γ, α, 0) / |k_t|`) and the p wave (H along `ŝ`) of wave
/// vector `(α, γ, kz)` in `eps`, as `(E, H)` with `H = k × E`, `E = −k × H / ε` (units of
/// `k0` and `Z0`).
fn waves(alpha: f64, gamma: f64, kz: C64, eps: C64) -> [([C64; 3], [C64; 3]); 2] {
    let kt = alpha.hypot(gamma);
    let s = if kt == 0.0 {
        [ZERO, C64::new(1.0, 0.0), ZERO]
    } else {
        [C64::new(-gamma / kt, 0.0), C64::new(alpha / kt, 0.0), ZERO]
    };
    let k = [C64::new(alpha, 0.0), C64::new(gamma, 0.0), kz];
    let e_p = cross(k, s).map(|v| -v / eps);
    [(s, cross(k, s)), (e_p, s)]
}

/// The vector Rayleigh-Fourier reference for `z = AMP cos(2π x / Λ)` of `n_below` under
/// a flat plane at `TOP` (`n_layer` below it, air above), light along `d` in state `pol`
/// (0: E along `ŝ`, 1: p), orders `-n..=n`: each reflected order's efficiency. Unknowns per
/// order and polarisation: reflected (referred to TOP), the layer's down-going (to TOP) and
/// up-going (to −AMP) waves, the substrate's (to +AMP): every exponential at most 1.
fn vector_rayleigh(
    n_layer: f64,
    n_below: C64,
    lambda: f64,
    d: DVec3,
    pol: usize,
    n: i64,
) -> Vec<(i64, f64)> {
    let k0 = 2.0 * std::f64::consts::PI / lambda;
    let (ea, el, eb) = (
        C64::new(1.0, 0.0),
        C64::new(n_layer * n_layer, 0.0),
        n_below * n_below,
    );
    let no = (2 * n + 1) as usize;
    let gamma = d.y;
    let alpha: Vec<f64> = (-n..=n).map(|m| d.x + m as f64 * lambda / PERIOD).collect();
    let size = 8 * no;
    // Unknown (kind, polarisation, order): kind 0 reflected, 1 layer down, 2 layer up, 3 below.
    let col = |kind: usize, p: usize, m: usize| (kind * 2 + p) * no + m;
    let mut a = vec![ZERO; size * size];
    let mut b = vec![ZERO; size];
    let centre = n as usize;
    // The flat top, order by order: E_x, E_y, H_x, H_y.
    for q in 0..no {
        let (ba, bl) = (
            common::kz(ea, alpha[q].hypot(gamma)),
            common::kz(el, alpha[q].hypot(gamma)),
        );
        let lift = (I * bl * k0 * (TOP + AMP)).exp();
        let terms = [
            (0, waves(alpha[q], gamma, ba, ea), C64::new(1.0, 0.0)),
            (1, waves(alpha[q], gamma, -bl, el), C64::new(-1.0, 0.0)),
            (2, waves(alpha[q], gamma, bl, el), -lift),
        ];
        for (kind, w, f) in terms {
            for (p, (e, h)) in w.iter().enumerate() {
                for (row, v) in [e[0], e[1], h[0], h[1]].into_iter().enumerate() {
                    a[(4 * q + row) * size + col(kind, p, q)] = v * f;
                }
            }
        }
        if q == centre {
            let w = waves(alpha[q], gamma, -ba, ea)[pol];
            for (row, v) in [w.0[0], w.0[1], w.1[0], w.1[1]].into_iter().enumerate() {
                b[4 * q + row] = -v;
            }
        }
    }
    // The relief, projected on each harmonic: E·t, E_y, H·t, H_y with t = (1, 0, a').
    let s = 2048;
    let kg = 2.0 * std::f64::consts::PI / PERIOD;
    let xs: Vec<f64> = (0..s).map(|j| PERIOD * j as f64 / s as f64).collect();
    let h: Vec<f64> = xs.iter().map(|x| AMP * (kg * x).cos()).collect();
    let dh: Vec<f64> = xs.iter().map(|x| -AMP * kg * (kg * x).sin()).collect();
    let roots: Vec<C64> = (0..s)
        .map(|j| C64::from_polar(1.0, 2.0 * std::f64::consts::PI * j as f64 / s as f64))
        .collect();
    let project = |f: &[C64], dm: i64| {
        let step = dm.rem_euclid(s as i64) as usize;
        let (mut at, mut acc) = (0usize, ZERO);
        for v in f {
            acc += v * roots[at];
            at = (at + step) % s;
        }
        acc / s as f64
    };
    for m in 0..no {
        let (bl, bb) = (
            common::kz(el, alpha[m].hypot(gamma)),
            common::kz(eb, alpha[m].hypot(gamma)),
        );
        let terms = [
            (1, -bl, TOP, el, 1.0),
            (2, bl, -AMP, el, 1.0),
            (3, -bb, AMP, eb, -1.0),
        ];
        for (kind, kzm, reference, e, sign) in terms {
            let f: Vec<C64> = h
                .iter()
                .map(|&hj| (I * kzm * k0 * (hj - reference)).exp())
                .collect();
            let g: Vec<C64> = f.iter().zip(&dh).map(|(&fj, &dj)| fj * dj).collect();
            for q in 0..no {
                let dm = m as i64 - q as i64;
                let (pf, pg) = (project(&f, dm), project(&g, dm));
                for (p, (ev, hv)) in waves(alpha[m], gamma, kzm, e).iter().enumerate() {
                    let rows = [
                        ev[0] * pf + ev[2] * pg,
                        ev[1] * pf,
                        hv[0] * pf + hv[2] * pg,
                        hv[1] * pf,
                    ];
                    for (row, v) in rows.into_iter().enumerate() {
                        a[(4 * no + 4 * q + row) * size + col(kind, p, m)] = v * sign;
                    }
                }
            }
        }
    }
    let x = common::gauss(a, b);
    let b0 = -d.z;
    let norm2 = |v: [C64; 3]| v.iter().map(|c| c.norm_sqr()).sum::<f64>();
    (0..no)
        .filter_map(|m| {
            let ba = common::kz(ea, alpha[m].hypot(gamma));
            (ba.im == 0.0 && ba.re > 0.0).then(|| {
                let w = waves(alpha[m], gamma, ba, ea);
                let e = norm2(w[0].0) * x[col(0, 0, m)].norm_sqr()
                    + norm2(w[1].0) * x[col(0, 1, m)].norm_sqr();
                (m as i64 - n, e * ba.re / b0)
            })
        })
        .collect()
}

/// The foil (air, 2 um of lacquer n 1.5, an aluminium sinusoid of 1 um period and 50 nm
/// amplitude) lit from 30, 45 and 90 deg of azimuth at 20 and 50 deg, 450 and 650 nm: every
/// reflected order within 1e-4 of the vector Rayleigh-Fourier method for incident s and p
/// (the issue asks 1e-3), which is converged in its own orders (25 against 35: 1e-6).
#[test]
fn the_lacquered_foil_off_plane_matches_the_vector_rayleigh_fourier_method() {
    let d = dir(20.0, 45.0);
    for pol in 0..2 {
        let a = vector_rayleigh(1.5, ALUMINIUM, 550.0, d, pol, 25);
        let b = vector_rayleigh(1.5, ALUMINIUM, 550.0, d, pol, 35);
        for ((m, x), (_, y)) in a.iter().zip(&b) {
            assert!((x - y).abs() < 1e-6, "reference order {m}: {x} against {y}");
        }
    }
    let p = sinusoid(f64::cos, AMP, 1.0, ALUMINIUM, lacquer(1.5));
    let mut worst: f64 = 0.0;
    for lambda in [450.0, 650.0] {
        let m = (2.0 * 1.5 * PERIOD / lambda).ceil() as usize + 12;
        for (theta, phi) in [(20.0, 30.0), (50.0, 45.0), (20.0, 90.0)] {
            let s = rcwa::solve_profile(&p, lambda, dir(theta, phi), m).unwrap();
            for pol in 0..2 {
                for (om, e) in vector_rayleigh(1.5, ALUMINIUM, lambda, dir(theta, phi), pol, 25) {
                    let got = eff(&s, om, true, pol);
                    assert!(
                        (got - e).abs() < 1e-4,
                        "{lambda} nm {theta}/{phi} deg pol {pol} order {om}: {got} against {e}"
                    );
                    worst = worst.max((got - e).abs());
                }
            }
        }
    }
    println!("largest difference from the vector Rayleigh-Fourier method: {worst:.1e}");
}

/// The shipped foil (`meshes/holographic-foil.toml`, its 256 facets a period and the McPeak
/// aluminium table) under the default `--coherence auto`, lit from 45 deg of azimuth at 30
/// deg and 550 nm: the cell takes the C-method (unsliced), and its R (unpolarised) is within
/// 1e-3 of the vector Rayleigh-Fourier method at the table's index (the bar; the
/// facets' departure from the sinusoid is the difference).
#[test]
fn the_shipped_foil_off_plane_under_auto_is_the_reference() {
    use goniospec::accumulate::Coherence;
    use goniospec::simulate::{SimConfig, Wavelengths, simulate};
    let s = common::shipped("holographic-foil.toml");
    let cfg = SimConfig {
        coherence: Coherence::Auto,
        phi_i_deg: 45.0,
        ..common::config(
            &[30.0],
            Wavelengths::parse("540:560:20", false).unwrap(),
            256,
        )
    };
    let (acc, stats) = simulate(&s, &cfg, &|_| {}).unwrap();
    assert_eq!(acc.header.settings.cell_mode(0, 0), Coherence::Rigorous);
    assert!(stats.rigorous[0].is_some_and(|c| c.slices == 0));
    let mut idx = Vec::new();
    s.indices_into(550.0, &mut idx);
    let al = idx[s.media.iter().position(|m| m.name == "aluminium").unwrap()];
    let d = dir(30.0, 45.0);
    let total = |pol| -> f64 {
        vector_rayleigh(1.5, al, 550.0, d, pol, 25)
            .iter()
            .map(|o| o.1)
            .sum()
    };
    let want = 0.5 * (total(0) + total(1));
    let (r, _) = common::totals(&acc, 0, 0);
    println!("45 deg azimuth: R {r:.6}, vector Rayleigh-Fourier {want:.6}");
    assert!((r - want).abs() < 1e-3, "R {r} against {want}");
}
