//! The diffraction method (`--coherence diffraction`, issue 26) against references written
//! here, independent of the tracer: the Kirchhoff (physical-optics) order efficiencies of a
//! sinusoidal grating (Bessel functions), the coherent specular fraction of a slightly rough
//! surface, flat films against the transfer-matrix method, and energy (Parseval).

mod common;

use common::*;
use goniospec::accumulate::{Buckets, Coherence};
use goniospec::simulate::{SimConfig, Wavelengths, simulate};
use std::f64::consts::PI;

/// Bessel function of the first kind by Bessel's integral, `J_n(x) = (1/pi) int_0^pi
/// cos(n t - x sin t) dt` (Abramowitz & Stegun 9.1.21), with the trapezoid rule, which
/// converges geometrically for this periodic integrand.
fn bessel_j(n: i32, x: f64) -> f64 {
    let m = 4000;
    let h = PI / m as f64;
    let f = |t: f64| (f64::from(n) * t - x * t.sin()).cos();
    let mut s = 0.5 * (f(0.0) + f(PI));
    for i in 1..m {
        s += f(i as f64 * h);
    }
    s * h / PI
}

/// A sinusoidal grating one period wide ([`sinusoid`]).
fn grating(
    tag: &str,
    period: f64,
    amp: f64,
    n: f64,
    k: f64,
    segments: usize,
) -> goniospec::sample::Sample {
    sinusoid(tag, period, amp, (n, k), segments, 1)
}

/// In-plane reflected power per 1-degree polar bin, signed by the azimuth (negative
/// angles: phi = 180 deg), from -89.5 to 89.5 degrees.
fn in_plane(
    acc: &goniospec::accumulate::file::Accumulator,
    i: usize,
    j: usize,
    b: &Buckets,
) -> Vec<(f64, f64)> {
    let c = acc.cell(i, j);
    let mode = acc.header.settings.coherence_mode();
    let mut out = Vec::new();
    for bucket in 0..b.len() {
        let f = c.fraction(2 * bucket, mode);
        if f == 0.0 {
            continue;
        }
        let (t, p) = b.centre(bucket);
        let sign = if p.cos() >= 0.0 { 1.0 } else { -1.0 };
        out.push((sign * t.to_degrees(), f));
    }
    out.sort_by(|a, b| a.0.total_cmp(&b.0));
    out
}

/// The specular direction for light from `theta_deg` at azimuth 0 (`+ 0.0` turns the
/// -0.0 of normal incidence into +0.0, whose azimuth is 0, not 180 degrees).
fn specular(theta_deg: f64) -> glam::DVec3 {
    let t = theta_deg.to_radians();
    glam::DVec3::new(-t.sin() + 0.0, 0.0, t.cos())
}

fn cfg(theta: f64, lambda: f64, rays: u64, buckets: Buckets) -> SimConfig {
    SimConfig {
        coherence: Coherence::Diffraction,
        rho_nm: f64::INFINITY,
        buckets,
        ..SimConfig::new(vec![theta], Wavelengths::Monochromatic(vec![lambda]), rays)
    }
}

/// Unpolarised Fresnel reflectance of a plane interface from air into index `n + i k` at
/// incidence `theta` (radians) (Born & Wolf §1.5.2, §14.2 for absorbing media).
fn fresnel_r(theta: f64, n: f64, k: f64) -> f64 {
    let n2 = num_complex::Complex64::new(n, k);
    let (s, c) = theta.sin_cos();
    let ct = (1.0 - s * s / (n2 * n2)).sqrt();
    let rs = (c - n2 * ct) / (c + n2 * ct);
    let rp = (n2 * c - ct) / (n2 * c + ct);
    0.5 * (rs.norm_sqr() + rp.norm_sqr())
}

/// The Kirchhoff (tangent-plane) efficiencies of the in-plane orders of `z = A sin(2 pi x
/// / period)` for light from `theta1` (radians) in the plane across the grooves: Beckmann
/// & Spizzichino, The Scattering of Electromagnetic Waves from Rough Surfaces (1963), ch.
/// 4: order m leaves at `sin theta2 = sin theta1 + m lambda / period` with amplitude
/// `F J_m(k A (cos theta1 + cos theta2))`, `F = (1 + cos(theta1 + theta2)) / (cos theta2
/// (cos theta1 + cos theta2))`, and carries `|amplitude|^2 cos theta2 / cos theta1` of the
/// incident power, times the Fresnel reflectance at the local angle of the specular point,
/// `(theta1 + theta2) / 2`.
fn kirchhoff(
    period: f64,
    amp: f64,
    lambda: f64,
    theta1: f64,
    n: f64,
    k_ext: f64,
) -> Vec<(i32, f64)> {
    let k = 2.0 * PI / lambda;
    let mmax = (2.0 * period / lambda).ceil() as i32;
    (-mmax..=mmax)
        .filter_map(|m| {
            let s2 = theta1.sin() + f64::from(m) * lambda / period;
            if s2.abs() >= 1.0 {
                return None;
            }
            let t2 = s2.asin();
            let (c1, c2) = (theta1.cos(), t2.cos());
            let f = (1.0 + (theta1 + t2).cos()) / (c2 * (c1 + c2));
            let j = bessel_j(m, k * amp * (c1 + c2));
            let rf = fresnel_r(0.5 * (theta1 + t2).abs(), n, k_ext);
            Some((m, rf * f * f * j * j * c2 / c1))
        })
        .collect()
}

/// The simulated grating's in-plane orders: power per order (bins summed by the order
/// nearest their centre), the diffracted total, and the ray method's total.
fn grating_orders(
    period: f64,
    amp: f64,
    lambda: f64,
    theta_deg: f64,
    n: f64,
    k_ext: f64,
    rays: u64,
) -> (std::collections::BTreeMap<i32, f64>, f64, f64) {
    let s = grating("diffr-grating", period, amp, n, k_ext, 512);
    let b = Buckets {
        theta_bins: 180,
        phi_bins: 4,
    };
    let (acc, stats) = simulate(&s, &cfg(theta_deg, lambda, rays, b), &|_| {}).unwrap();
    let mut orders = std::collections::BTreeMap::new();
    for (t, f) in in_plane(&acc, 0, 0, &b) {
        // The light comes from phi = 0, so the specular side is phi = 180 deg: Beckmann's
        // theta2 is positive there.
        let s2 = -t.to_radians().sin();
        let m = ((s2 - theta_deg.to_radians().sin()) * period / lambda).round() as i32;
        *orders.entry(m).or_insert(0.0) += f;
    }
    let d = stats.diffraction[0];
    (orders, d.r, d.rays_r)
}

/// The grating's simulated orders against the Kirchhoff efficiencies: the L1 distance of
/// the two in-plane distributions (each normalised to 1; 0 identical, 2 disjoint), the
/// largest absolute difference of one order's efficiency, and the transform's ratio.
fn against_kirchhoff(period: f64, amp: f64, theta: f64, n: f64, k: f64) -> (f64, f64, f64) {
    let (ours, r, r_rays) = grating_orders(period, amp, 550.0, theta, n, k, 40_000);
    let kir = kirchhoff(period, amp, 550.0, theta.to_radians(), n, k);
    let ks: f64 = kir.iter().map(|x| x.1).sum();
    let os: f64 = ours.values().sum();
    let (mut l1, mut worst) = (0.0, 0.0f64);
    for &(m, kv) in &kir {
        let o = ours.get(&m).copied().unwrap_or(0.0);
        l1 += (o / os - kv / ks).abs();
        worst = worst.max((o - kv).abs());
    }
    // Orders the reference does not have (none should carry power).
    l1 += ours
        .iter()
        .filter(|(m, _)| !kir.iter().any(|(km, _)| km == *m))
        .map(|(_, o)| o / os)
        .sum::<f64>();
    (l1, worst, r / r_rays)
}

/// Sinusoidal gratings of slope up to 17 degrees (A / period = 0.05), glass and gold, at
/// period / wavelength 9 and 18, 0 and 30 degrees: the orders against the Kirchhoff
/// efficiencies written above. The reference itself conserves energy to 1e-3 at these
/// angles (checked here), so it is the physical-optics answer the method must reproduce;
/// the tolerance, L1 <= 0.06 and 1.2e-2 of the incident power per order, covers the
/// Kirchhoff model's own neglect of the exit plane's near field (tubes of neighbouring
/// facets overlap or part over the 2A between the surface and the exit plane), measured
/// at 0.004-0.05 here.
#[test]
fn sinusoidal_gratings_match_kirchhoff() {
    for &(theta, period) in &[
        (0.0, 5000.0),
        (30.0, 5000.0),
        (0.0, 10_000.0),
        (30.0, 10_000.0),
    ] {
        let refl: f64 = kirchhoff(
            period,
            0.05 * period,
            550.0,
            f64::to_radians(theta),
            1.0e9,
            0.0,
        )
        .iter()
        .map(|x| x.1)
        .sum();
        assert!(
            (refl - 1.0).abs() < 2e-3,
            "Kirchhoff reference loses energy: {refl}"
        );
    }
    for &(period, theta, n, k) in &[
        (5000.0, 0.0, 1.5, 0.0),
        (5000.0, 30.0, 1.5, 0.0),
        (10_000.0, 30.0, 1.5, 0.0),
        (5000.0, 0.0, 0.43, 2.455),
        (10_000.0, 30.0, 0.43, 2.455),
    ] {
        let (l1, worst, ratio) = against_kirchhoff(period, 0.05 * period, theta, n, k);
        eprintln!(
            "period {period} nm, theta {theta} deg, n {n} + {k}i: L1 {l1:.4}, worst order {worst:.2e}, transform ratio {ratio:.4}"
        );
        assert!(l1 < 0.06, "L1 {l1} against Kirchhoff");
        assert!(worst < 1.2e-2, "an order is off by {worst}");
        assert!((0.95..1.05).contains(&ratio), "transform ratio {ratio}");
    }
}

/// The ray method at the same gratings gives one continuous lobe: far from the orders
/// (the issue's L1 of 1.2-1.9 at these periods); the diffraction method is the one that
/// changes the answer, so this is the contrast the method exists for.
#[test]
fn rays_alone_miss_the_orders() {
    let (period, amp) = (5000.0, 250.0);
    let s = grating("diffr-rays", period, amp, 1.5, 0.0, 512);
    let b = Buckets {
        theta_bins: 180,
        phi_bins: 4,
    };
    let rays = SimConfig {
        coherence: Coherence::Beamlet,
        ..cfg(0.0, 550.0, 40_000, b)
    };
    let acc = run(&s, &rays);
    let kir = kirchhoff(period, amp, 550.0, 0.0, 1.5, 0.0);
    let ks: f64 = kir.iter().map(|x| x.1).sum();
    let mut ours = std::collections::BTreeMap::new();
    for (t, f) in in_plane(&acc, 0, 0, &b) {
        let m = (-t.to_radians().sin() * period / 550.0).round() as i32;
        *ours.entry(m).or_insert(0.0) += f;
    }
    let os: f64 = ours.values().sum();
    let l1: f64 = kir
        .iter()
        .map(|&(m, kv)| (ours.get(&m).copied().unwrap_or(0.0) / os - kv / ks).abs())
        .sum();
    assert!(l1 > 0.3, "rays alone came within L1 {l1} of the orders");
}

/// What the patches' cut may add to a flat film's transform, as a share of its power. Each
/// tube's patch is cut where its Gaussian falls to `exp(-r^2 / 2)` of its peak (`r = 4`
/// standard deviations, `patch::PATCH_RADIUS`) and renormalised, so the lattice's summed
/// field departs from uniform by at most twice the Gaussian's share beyond the cut, `2
/// exp(-8)` of it; that departure has no mean (the renormalisation), so it adds power only
/// in spurious orders, at most its square: `4 exp(-16) = 4.5e-7` (docs/physics.md, "The
/// patches' cut"). The uncut lattice's own ripple, 4e-11, is below it.
const CUT_POWER: f64 = 4.0 * 1.125_351_747_192_591e-7;

/// A flat film is one order: the diffraction method gives the transfer-matrix R and T
/// (within [`CUT_POWER`] of their power) and, in the plane-wave limit, puts it all in the
/// specular bucket; a finite coherence radius spreads it over neighbouring buckets and
/// keeps the total.
#[test]
fn flat_films_are_unchanged() {
    let s = shipped("flat-soap-film.toml");
    let b = Buckets {
        theta_bins: 89,
        phi_bins: 37,
    };
    for theta in [0.0, 30.0, 60.0] {
        let (r_ref, t_ref) = tmm_ref(
            &[
                common::c(1.0, 0.0),
                common::c(1.33, 0.0),
                common::c(1.0, 0.0),
            ],
            &[600.0],
            550.0,
            f64::to_radians(theta),
        );
        for rho in [f64::INFINITY, 5000.0] {
            let c = SimConfig {
                rho_nm: rho,
                ..cfg(theta, 550.0, 1024, b)
            };
            let (acc, stats) = simulate(&s, &c, &|_| {}).unwrap();
            let d = stats.diffraction[0];
            // The spurious orders add to the transform's total, never take from it.
            let near = |x: f64, x_ref: f64| x >= x_ref - 1e-12 && x <= x_ref * (1.0 + CUT_POWER);
            assert!(near(d.r, r_ref), "R {} against {r_ref}", d.r);
            assert!(near(d.t, t_ref), "T {} against {t_ref}", d.t);
            let cell = acc.cell(0, 0);
            let (r, t) = cell.totals(Coherence::Diffraction, &b);
            assert!((r - r_ref).abs() < 1e-9 && (t - t_ref).abs() < 1e-9);
            let up: f64 = (0..b.len())
                .map(|k| cell.fraction(2 * k, Coherence::Diffraction))
                .sum();
            assert!((up - r_ref).abs() < 1e-9, "buckets sum to {up}, R {r_ref}");
            let f = cell.fraction(2 * b.index(specular(theta)), Coherence::Diffraction);
            if rho.is_infinite() {
                // The orders carry the rays' R: the spurious ones' share is the
                // specular bucket's deficit.
                assert!(
                    f <= r_ref + 1e-12 && f >= r_ref * (1.0 - CUT_POWER),
                    "specular bucket {f} against R {r_ref}"
                );
            } else {
                assert!(
                    f < r_ref * 0.9,
                    "a 5 um coherence radius spreads the order: {f}"
                );
            }
        }
    }
}

/// Slightly rough glass (RMS 20 nm, correlation length 2 um): the specular order carries
/// the coherent fraction `|<exp(-i q_z h)>|^2` of the reflected power, `q_z = 2 k cos
/// theta` (Beckmann & Spizzichino 1963, ch. 5), computed here from the mesh's own heights,
/// and near the Gaussian ensemble's `exp(-(4 pi sigma cos theta / lambda)^2)`.
#[test]
fn slight_roughness_keeps_the_coherent_specular_fraction() {
    let toml = "[sample]\nname = \"slightly rough glass\"\nunit = \"nm\"\ntile = [20000.0, 20000.0]\n[media.air]\nn = 1.0\n[media.glass]\nn = 1.5\n[[interface]]\ngenerator = { kind = \"gaussian\", rms = 20.0, correlation_length = 2000.0, resolution = 128 }\nfront = \"air\"\nback = \"glass\"\n";
    let s = sample_from("diffr-rough", toml);
    let lambda: f64 = 550.0;
    // Unique grid heights (the last row and column repeat the first).
    let pos = &s.interfaces[0].mesh.positions_nm;
    let n = (pos.len() as f64).sqrt().round() as usize;
    let heights: Vec<f64> = (0..n - 1)
        .flat_map(|j| (0..n - 1).map(move |i| (i, j)))
        .map(|(i, j)| pos[j * n + i].z)
        .collect();
    let mean = heights.iter().sum::<f64>() / heights.len() as f64;
    let rms =
        (heights.iter().map(|h| (h - mean).powi(2)).sum::<f64>() / heights.len() as f64).sqrt();
    for theta in [0.0, 30.0] {
        let qz = 2.0 * (2.0 * PI / lambda) * f64::to_radians(theta).cos();
        let (re, im) = heights.iter().fold((0.0, 0.0), |(a, b), h| {
            let p = -qz * (h - mean);
            (a + p.cos(), b + p.sin())
        });
        let coherent = (re * re + im * im) / (heights.len() as f64).powi(2);
        let ensemble = (-(qz * rms).powi(2)).exp();
        // Bin counts whose edges miss the specular directions (0 and 30 deg, phi 180).
        let b = Buckets {
            theta_bins: 355,
            phi_bins: 701,
        };
        let (acc, stats) = simulate(&s, &cfg(theta, lambda, 65_536, b), &|_| {}).unwrap();
        let spec = b.index(specular(theta));
        let cell = acc.cell(0, 0);
        let r = stats.diffraction[0].rays_r;
        let frac = cell.fraction(2 * spec, Coherence::Diffraction) / r;
        eprintln!(
            "theta {theta}: specular fraction {frac:.4}, mesh's coherent factor {coherent:.4}, ensemble {ensemble:.4}, rms {rms:.2} nm, ratio {:.4}",
            stats.diffraction[0].ratio()
        );
        assert!((frac - coherent).abs() < 0.02, "{frac} against {coherent}");
        assert!((coherent - ensemble).abs() < 0.05);
    }
}

/// The same inputs and seed give the same bytes whatever the thread count.
#[test]
fn diffraction_is_deterministic_across_threads() {
    let s = grating("diffr-det", 5000.0, 250.0, 1.5, 0.0, 128);
    let c = SimConfig {
        rho_nm: 5000.0,
        ..cfg(
            30.0,
            550.0,
            4096,
            Buckets {
                theta_bins: 45,
                phi_bins: 36,
            },
        )
    };
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let three = rayon::ThreadPoolBuilder::new()
        .num_threads(3)
        .build()
        .unwrap();
    let a = one.install(|| run(&s, &c));
    let b = three.install(|| run(&s, &c));
    assert_eq!(a.cells, b.cells);
}

/// What the method cannot take is refused before any tracing, with what to do.
#[test]
fn diffraction_refuses_what_it_cannot_take() {
    let b = Buckets {
        theta_bins: 45,
        phi_bins: 36,
    };
    let refusal = |s: &goniospec::sample::Sample, c: &SimConfig| {
        simulate(s, c, &|_| {}).unwrap_err().to_string()
    };
    let s = grating("diffr-refuse", 5000.0, 250.0, 1.5, 0.0, 64);
    let adaptive = SimConfig {
        tolerance: Some(0.01),
        max_rays: 10_000,
        ..cfg(0.0, 550.0, 1024, b)
    };
    let e = refusal(&s, &adaptive);
    assert!(e.contains("--tolerance"), "{e}");
    let e = refusal(&shipped("metallic-paint.toml"), &cfg(0.0, 550.0, 64, b));
    assert!(
        e.contains("Russian roulette") || e.contains("random phases"),
        "{e}"
    );
    let big = sample_from(
        "diffr-big",
        "[sample]\nname = \"big\"\nunit = \"nm\"\ntile = [2000000.0, 2000000.0]\n[media.air]\nn = 1.0\n[media.glass]\nn = 1.5\n[[interface]]\ngenerator = { kind = \"flat\" }\nfront = \"air\"\nback = \"glass\"\n",
    );
    let e = refusal(&big, &cfg(0.0, 550.0, 64, b));
    assert!(e.contains("smaller tile"), "{e}");
}

/// One cell of the validity map: the sinusoidal glass grating `s` (`period`, `amp` nm) at
/// `theta` deg and 550 nm traced with `asked` on 2-degree buckets: the method the cell took
/// (auto records it), R, the Kirchhoff R, the L1 distance of the in-plane distribution
/// against the Kirchhoff orders binned alike (each normalised to 1), and the transform's
/// power ratio.
fn map_cell(
    s: &goniospec::sample::Sample,
    period: f64,
    amp: f64,
    theta: f64,
    asked: Coherence,
    rays: u64,
) -> (Coherence, f64, f64, f64, f64) {
    let lambda = 550.0;
    let b = Buckets {
        theta_bins: 45,
        phi_bins: 2,
    };
    let kir = kirchhoff(period, amp, lambda, f64::to_radians(theta), 1.5, 0.0);
    let mut kb = vec![0.0; 2 * b.len()];
    for &(m, e) in &kir {
        let s2 = f64::to_radians(theta).sin() + f64::from(m) * lambda / period;
        let w = glam::DVec3::new(-s2 + 0.0, 0.0, (1.0 - s2 * s2).sqrt());
        kb[2 * b.index(w)] += e;
    }
    let kr: f64 = kb.iter().sum();
    let c = SimConfig {
        coherence: asked,
        allow_unphysical: true,
        ..cfg(theta, lambda, rays, b)
    };
    let (acc, stats) = simulate(s, &c, &|_| {}).unwrap();
    let mode = acc.header.settings.cell_mode(0, 0);
    let cell = acc.cell(0, 0);
    let (r, _) = cell.totals(mode, &b);
    let ours: Vec<f64> = (0..2 * b.len())
        .map(|k| {
            if k % 2 == 0 {
                cell.fraction(k, mode)
            } else {
                0.0
            }
        })
        .collect();
    let os: f64 = ours.iter().sum();
    let l1: f64 = ours
        .iter()
        .zip(&kb)
        .map(|(o, k)| (o / os - k / kr).abs())
        .sum();
    (mode, r, kr, l1, stats.diffraction[0].ratio())
}

/// The validity map of docs/validity.md: sinusoidal glass gratings (A / period = 0.05) at
/// 550 nm, period / wavelength 1.8-36, 0 and 30 degrees; for rays (the beamlet estimator),
/// the diffraction method and auto (with the method it took and its margin k r_c cos^3
/// theta), the total R against the Kirchhoff sum and the L1 distance of the in-plane
/// distribution in 2-degree bins against the Kirchhoff orders binned alike. Prints the
/// table (about 20 s): `cargo test --release --test diffraction validity_map -- --ignored
/// --nocapture`.
#[test]
#[ignore]
fn validity_map() {
    let lambda = 550.0;
    println!(
        "| period / wavelength | theta_i | Kirchhoff R | rays: R error, L1 | diffraction: R error, L1, power kept | auto: method (k r_c cos^3 theta), R error, L1 |"
    );
    println!("|---|---|---|---|---|---|");
    for ratio in [1.8f64, 3.6, 9.1, 18.0, 36.0] {
        let period: f64 = (ratio * lambda).round();
        let amp = 0.05 * period;
        let segments = ((period / 10.0) as usize).clamp(128, 2048);
        let s = grating("diffr-map", period, amp, 1.5, 0.0, segments);
        for theta in [0.0, 30.0] {
            let rays = 8 * 20_000u64.max((period / 5.0) as u64);
            let mut row = String::new();
            for asked in [Coherence::Beamlet, Coherence::Diffraction, Coherence::Auto] {
                let (mode, r, kr, l1, ratio_kept) = map_cell(&s, period, amp, theta, asked, rays);
                if row.is_empty() {
                    row = format!("| {ratio} | {theta} | {kr:.5} |");
                }
                if asked == Coherence::Auto {
                    let sheets = goniospec::sample::validity::sheet_scales(&s);
                    let margin = goniospec::simulate::auto::physical_optics_margin(
                        &s, &sheets, theta, lambda,
                    );
                    let m = match mode {
                        Coherence::Diffraction => "diffraction",
                        Coherence::Rigorous => "rigorous",
                        _ => "rays",
                    };
                    row += &format!(" {m} ({margin:.1}), {:.1e}, {l1:.3} |", (r - kr).abs());
                } else if mode == Coherence::Diffraction {
                    row += &format!(" {:.1e}, {l1:.3}, {ratio_kept:.3} |", (r - kr).abs());
                } else {
                    row += &format!(" {:.1e}, {l1:.3} |", (r - kr).abs());
                }
            }
            println!("{row}");
        }
    }
}

/// A grating 1.8 wavelengths wide (990 nm at 550 nm), 30 deg: below the 3 wavelengths in
/// the denser medium where the validity map ends, so auto takes the rigorous solver. The
/// diffraction method, asked for, still gets the Kirchhoff orders there (the tangent
/// plane's margin k r_c cos^3 theta is about 5.5, above the 5 gratings hold to; L1 <= 0.06,
/// the tolerance of `sinusoidal_gratings_match_kirchhoff`, R within 1e-2: the near-field
/// error the map measures there, 7.7e-3), where rays spread them into one lobe (L1 above
/// 1); the rigorous solver's orders are near both (L1 below 0.1 against Kirchhoff's, whose
/// R it corrects by the near field: within 1e-2).
#[test]
fn auto_takes_the_rigorous_solver_at_a_grating_two_wavelengths_wide() {
    let (period, amp) = (990.0, 49.5);
    let s = grating("diffr-auto", period, amp, 1.5, 0.0, 128);
    for (asked, rays, taken, l1_max) in [
        (Coherence::Auto, 4096, Coherence::Rigorous, 0.1),
        (Coherence::Diffraction, 40_000, Coherence::Diffraction, 0.06),
    ] {
        let (mode, r, kr, l1, _) = map_cell(&s, period, amp, 30.0, asked, rays);
        assert_eq!(mode, taken);
        assert!(l1 < l1_max, "{taken}: L1 {l1} against the Kirchhoff orders");
        assert!(
            (r - kr).abs() < 1e-2,
            "{taken}: R {r} against Kirchhoff {kr}"
        );
    }
    let (_, _, _, l1_rays, _) = map_cell(&s, period, amp, 30.0, Coherence::Beamlet, 40_000);
    assert!(l1_rays > 1.0, "rays came within L1 {l1_rays} of the orders");
}

/// The diffraction method on the grating `(period, amplitude)` nm, index `n + i k`, against
/// one case of a rigorous reference (`theta_deg`, total `r`, `orders` as order -> efficiency):
/// R within 1e-3, and the orders, each normalised by its total, within L1 0.05 order by order.
fn matches_rigorous_orders(
    case: &serde_json::Value,
    (period, amp): (f64, f64),
    lambda: f64,
    (n, k): (f64, f64),
    label: &str,
) {
    let theta = case["theta_deg"].as_f64().unwrap();
    let r_ref = case["r"].as_f64().unwrap();
    let reference: std::collections::BTreeMap<i32, f64> = case["orders"]
        .as_object()
        .unwrap()
        .iter()
        .map(|(m, e)| (m.parse().unwrap(), e.as_f64().unwrap()))
        .collect();
    let (ours, _, r) = grating_orders(period, amp, lambda, theta, n, k, 40_000);
    let os: f64 = ours.values().sum();
    let keys: std::collections::BTreeSet<i32> =
        ours.keys().chain(reference.keys()).copied().collect();
    let l1: f64 = keys
        .iter()
        .map(|m| {
            (ours.get(m).copied().unwrap_or(0.0) / os
                - reference.get(m).copied().unwrap_or(0.0) / r_ref)
                .abs()
        })
        .sum();
    println!(
        "{label} theta {theta}: R {r:.6} against {r_ref:.6} (|dR| {:.1e}); order L1 {l1:.4}",
        (r - r_ref).abs()
    );
    assert!((r - r_ref).abs() < 1e-3, "{label}: R {r} against {r_ref}");
    assert!(l1 < 0.05, "{label}: order L1 {l1}");
}

/// Against a rigorous solver: the RCWA order efficiencies of tests/interop/grating_meent.py
/// (meent, converged in slices and orders, energy checked there) for a glass sinusoid of
/// period 10 um (18 wavelengths), 0 and 30 degrees. The diffraction method's R within 1e-3
/// and its orders, order by order, within L1 0.05 (stricter than the issue's 2-degree
/// bins). Run by `make interop`, which sets GONIOSPEC_RCWA_JSON to the script's JSON
/// (kept in tests/reference/interop/, made again when the script changes).
#[test]
#[ignore]
fn against_rcwa() {
    let path = std::env::var("GONIOSPEC_RCWA_JSON").expect("GONIOSPEC_RCWA_JSON: run make interop");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    let (period, amp) = (
        v["period_nm"].as_f64().unwrap(),
        v["amplitude_nm"].as_f64().unwrap(),
    );
    let (lambda, n) = (v["lambda_nm"].as_f64().unwrap(), v["n"].as_f64().unwrap());
    for case in v["cases"].as_array().unwrap() {
        // The method's R is the ray field's (its orders are scaled to it).
        matches_rigorous_orders(case, (period, amp), lambda, (n, 0.0), "against RCWA");
    }
}

/// The metal references of tests/interop/grating_rayleigh.py: sinusoidal gold gratings by
/// the Rayleigh-Fourier method (converged in orders, checked for energy on a lossless
/// grating and against grcwa's RCWA for TE there). Run by `make interop`, which sets
/// GONIOSPEC_METAL_GRATING_JSON to the script's JSON (kept in tests/reference/interop/,
/// made again when the script changes).
fn metal_references() -> serde_json::Value {
    let path = std::env::var("GONIOSPEC_METAL_GRATING_JSON")
        .expect("GONIOSPEC_METAL_GRATING_JSON: run make interop");
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// Issue 26's metal grating: gold, period 5 um (9.1 wavelengths), A = 250 nm, at 0 and 30
/// degrees. The diffraction method's R within 1e-3 of the rigorous one and its orders,
/// order by order, within L1 0.05, as for the glass grating against RCWA above.
#[test]
#[ignore]
fn metal_grating_against_rigorous() {
    let v = metal_references();
    let (lambda, n, k) = (
        v["lambda_nm"].as_f64().unwrap(),
        v["n"].as_f64().unwrap(),
        v["k"].as_f64().unwrap(),
    );
    let (period, amp) = (5000.0, 250.0);
    let g = v["gratings"]
        .as_array()
        .unwrap()
        .iter()
        .find(|g| g["period_nm"] == period && g["amplitude_nm"] == amp)
        .expect("the 5 um, 250 nm grating");
    for case in g["cases"].as_array().unwrap() {
        let theta = case["theta_deg"].as_f64().unwrap();
        if ![0.0, 30.0].contains(&theta) {
            continue;
        }
        matches_rigorous_orders(case, (period, amp), lambda, (n, k), "metal grating");
    }
}

/// Issue 25's metal profiles at 0 to 85 degrees: the rays' total R against the rigorous one
/// on 24 gold gratings (the calibration of docs/validity.md, one run per grating), within
/// `validity::R_TOLERANCE` or with a warning on R (the surface plasmon, or structure smooth at
/// grazing light) for a run at that angle. The warnings must also stay quiet where the rays
/// hold: none at normal incidence, where every grating here is within the tolerance.
#[test]
#[ignore]
fn metal_gratings_match_rigorous_r_or_warn() {
    use goniospec::sample::validity::{self, R_TOLERANCE};
    let v = metal_references();
    let (lambda, n, k) = (
        v["lambda_nm"].as_f64().unwrap(),
        v["n"].as_f64().unwrap(),
        v["k"].as_f64().unwrap(),
    );
    let b = Buckets {
        theta_bins: 45,
        phi_bins: 4,
    };
    let (mut warned, mut quiet, mut needless) = (0, 0, 0);
    for g in v["gratings"].as_array().unwrap() {
        let (period, amp) = (
            g["period_nm"].as_f64().unwrap(),
            g["amplitude_nm"].as_f64().unwrap(),
        );
        let s = grating("metal-r", period, amp, n, k, 512);
        let cases = g["cases"].as_array().unwrap();
        let thetas: Vec<f64> = cases
            .iter()
            .map(|c| c["theta_deg"].as_f64().unwrap())
            .collect();
        let c = SimConfig {
            buckets: b,
            ..SimConfig::new(
                thetas.clone(),
                Wavelengths::Monochromatic(vec![lambda]),
                20_000,
            )
        };
        let (acc, _) = simulate(&s, &c, &|_| {}).unwrap();
        for (i, case) in cases.iter().enumerate() {
            let theta = thetas[i];
            let r_ref = case["r"].as_f64().unwrap();
            let (r, _) = totals(&acc, i, 0);
            let mut one = goniospec::simulate::validity_context(&c);
            one.theta_i_deg = vec![theta];
            let on_r: Vec<String> = validity::findings(&s, &one)
                .into_iter()
                .map(|f| f.message)
                .filter(|m| m.contains("plasmon") || m.contains("total R is uncertain"))
                .collect();
            let d = r - r_ref;
            println!(
                "period {period:.0} nm, A {amp:.0} nm, {theta:>2.0} deg: rays R {r:.5}, rigorous {r_ref:.5}, dR {d:+.4}; warned on R: {}",
                !on_r.is_empty()
            );
            if theta == 0.0 {
                assert!(on_r.is_empty(), "a warning at normal incidence: {on_r:?}");
            }
            assert!(
                d.abs() <= R_TOLERANCE || !on_r.is_empty(),
                "R {r} against the rigorous {r_ref}, without a warning"
            );
            if on_r.is_empty() {
                quiet += 1;
            } else {
                warned += 1;
                needless += usize::from(d.abs() <= R_TOLERANCE);
            }
        }
    }
    println!(
        "{warned} cases warned ({needless} of them within the tolerance), {quiet} quiet (all within it)"
    );
}

/// The partial coherence's spread at short radii (issue 48): below half the longest
/// wavelength the 5 x 5 Gauss-Hermite spread cannot hold the illumination's angular spread
/// (its outer nodes leave the horizon and the centre node alone is left: 1 nm and 30 nm
/// gave the BRDF of rho = inf byte for byte), so such radii are refused, naming the
/// smallest that holds. Above it, at normal incidence (every node within the horizon), the
/// flat film's one order is spread as the Gaussian of direction sines with standard
/// deviation `sigma = lambda / (2 pi n rho)` per axis (Mandel & Wolf §5.6.4): the mean of
/// `|s|^2 = sin^2 theta_o` over the reflected power is `2 sigma^2` (the 5-point rule is
/// exact for it), within the 0.25-degree buckets' resolution (8 %), and the hemisphere keeps
/// R exactly.
#[test]
fn short_coherence_radii_spread_or_are_refused() {
    let s = shipped("flat-soap-film.toml");
    let b = Buckets {
        theta_bins: 89,
        phi_bins: 37,
    };
    for rho in [1.0, 30.0, 274.0] {
        let c = SimConfig {
            rho_nm: rho,
            ..cfg(30.0, 550.0, 64, b)
        };
        match simulate(&s, &c, &|_| {}) {
            Err(goniospec::simulate::SimError::Setting { key, message }) => {
                assert_eq!(key, "coherence_radius_nm");
                assert!(message.contains("at least 275 nm"), "{message}");
            }
            other => panic!(
                "rho {rho} nm: expected a refusal, got {:?}",
                other.map(|_| ())
            ),
        }
    }
    let (r_ref, _) = tmm_ref(
        &[
            common::c(1.0, 0.0),
            common::c(1.33, 0.0),
            common::c(1.0, 0.0),
        ],
        &[600.0],
        550.0,
        0.0,
    );
    let fine = Buckets {
        theta_bins: 359,
        phi_bins: 72,
    };
    for rho in [1000.0, 400.0] {
        let c = SimConfig {
            rho_nm: rho,
            ..cfg(0.0, 550.0, 256, fine)
        };
        let (acc, _) = simulate(&s, &c, &|_| {}).unwrap();
        let cell = acc.cell(0, 0);
        let (mut up, mut s2) = (0.0, 0.0);
        for k in 0..fine.len() {
            let f = cell.fraction(2 * k, Coherence::Diffraction);
            up += f;
            s2 += f * fine.centre(k).0.sin().powi(2);
        }
        assert!(
            (up - r_ref).abs() < 1e-9,
            "rho {rho}: buckets sum to {up}, R {r_ref}"
        );
        let sigma = 550.0 / (2.0 * std::f64::consts::PI * rho);
        let mean = s2 / up;
        assert!(
            (mean / (2.0 * sigma * sigma) - 1.0).abs() < 0.08,
            "rho {rho} nm: mean sin^2 {mean} against 2 sigma^2 = {}",
            2.0 * sigma * sigma
        );
    }
}

/// The diffraction method traces the most oblique direction first, so a direction its
/// transform cannot hold is refused before the rest of the run (issue 48: the refusal at
/// 75 deg came after 2 min 40 s of the other angles). The order changes no byte: a
/// direction's cells are the same whichever directions are traced with it and before it
/// (30 deg as the second of [0, 30], traced last, and of [60, 30], traced after 60).
#[test]
fn the_order_of_directions_changes_no_byte() {
    let s = shipped("thin-film-600nm.toml");
    let b = Buckets {
        theta_bins: 30,
        phi_bins: 24,
    };
    let run = |thetas: Vec<f64>| {
        let c = SimConfig {
            coherence: Coherence::Diffraction,
            rho_nm: 5000.0,
            buckets: b,
            ..SimConfig::new(thetas, Wavelengths::Monochromatic(vec![550.0]), 256)
        };
        simulate(&s, &c, &|_| {}).unwrap().0
    };
    let (a, c) = (run(vec![0.0, 30.0]), run(vec![60.0, 30.0]));
    let (x, y) = (a.cell(1, 0), c.cell(1, 0));
    assert_eq!(x.trees, y.trees);
    assert!(
        x.sum == y.sum && x.sumsq == y.sumsq,
        "the 30 deg cells differ"
    );
    assert_eq!((x.r_sum, x.t_sum, x.dropped), (y.r_sum, y.t_sum, y.dropped));
}
