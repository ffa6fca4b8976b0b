use super::*;

fn unpolarised_pair(d: DVec3) -> [Field; 2] {
    let (u, v) = frame(d);
    let f = |w: DVec3| [C64::new(w.x, 0.0), C64::new(w.y, 0.0), C64::new(w.z, 0.0)];
    [f(u), f(v)]
}

/// The weighted histogram of scattered directions against the phase function's mass
/// in each bin of cos theta (chi-square with the per-bin variance of the weights).
fn chi_square(model: &ScatterModel, lambda: f64, expected: &dyn Fn(f64, f64) -> f64) -> f64 {
    let bins = 40;
    let n = 200_000;
    let d = DVec3::new(0.2, 0.1, -0.97).normalize();
    let mut rng = Rng::new(7, 1);
    let (mut sw, mut sw2) = (vec![0.0; bins], vec![0.0; bins]);
    let (_, albedo) = model.coefficients(lambda);
    for _ in 0..n {
        let mut e = unpolarised_pair(d);
        let d2 = model.scatter(lambda, d, &mut e, &mut rng);
        let w = 0.5 * (field_power(&e[0]) + field_power(&e[1])) / albedo;
        let mu = d.dot(d2).clamp(-1.0, 1.0);
        let b = (((mu + 1.0) / 2.0 * bins as f64) as usize).min(bins - 1);
        sw[b] += w;
        sw2[b] += w * w;
    }
    let mut chi2 = 0.0;
    for b in 0..bins {
        let (lo, hi) = (
            -1.0 + 2.0 * b as f64 / bins as f64,
            -1.0 + 2.0 * (b + 1) as f64 / bins as f64,
        );
        let want = expected(lo, hi);
        let mean = sw[b] / n as f64;
        let var = (sw2[b] / n as f64 - mean * mean).max(1e-300) / n as f64;
        chi2 += (mean - want).powi(2) / var;
    }
    chi2
}

/// chi-square with 40 degrees of freedom exceeds 73.4 with probability 1e-3.
const CHI2_40_P001: f64 = 73.4;

#[test]
fn henyey_greenstein_directions_follow_the_phase_function() {
    for g in [0.0, 0.5, -0.3, 0.9] {
        let m = ScatterModel::henyey_greenstein(g, 1.0, 0.1).unwrap();
        let chi2 = chi_square(&m, 550.0, &|lo, hi| {
            // Exact mass of the HG density over [lo, hi] by fine midpoint quadrature.
            let k = 2000;
            (0..k)
                .map(|i| hg_density(g, lo + (i as f64 + 0.5) * (hi - lo) / k as f64))
                .sum::<f64>()
                * (hi - lo)
                / k as f64
        });
        assert!(chi2 < CHI2_40_P001, "g {g}: chi2 {chi2}");
    }
}

fn white_particles(r: f64, lambda: f64) -> ScatterModel {
    ScatterModel::mie(
        Radius::Fixed { radius_nm: r },
        0.05,
        lambda,
        lambda,
        &|_| C64::new(1.5, 0.0),
        &|_| C64::new(2.6, 0.01),
    )
    .unwrap()
}

#[test]
fn mie_directions_follow_the_phase_function() {
    for (r, lambda) in [(150.0, 550.0), (40.0, 450.0), (1500.0, 600.0)] {
        let m = white_particles(r, lambda);
        let ScatterModel::Mie { table, .. } = &m else {
            unreachable!()
        };
        let mie = &table[0].sizes[0].mie;
        // k^2 C_sca = pi x^2 Q_sca.
        let k2c = std::f64::consts::PI * mie.x * mie.x * mie.q_sca();
        let chi2 = chi_square(&m, lambda, &|lo, hi| {
            let n = 4000;
            let mass: f64 = (0..n)
                .map(|i| {
                    let mu = lo + (i as f64 + 0.5) * (hi - lo) / n as f64;
                    let (s1, s2) = mie.s1_s2(mu);
                    0.5 * (s1.norm_sqr() + s2.norm_sqr())
                })
                .sum::<f64>()
                * (hi - lo)
                / n as f64;
            // dOmega = 2 pi dmu; dC/dOmega = |S|^2 / k^2.
            std::f64::consts::TAU * mass / k2c
        });
        assert!(chi2 < CHI2_40_P001, "r {r}: chi2 {chi2}");
        assert_eq!(m.violations(), 0, "r {r}: the envelope was exceeded");
    }
}

/// Light polarised along u: the azimuth follows (1 + rho cos 2 phi) / (2 pi) given
/// theta, so <cos 2 phi> = integral (|S2|^2 - |S1|^2)/4 sin theta dtheta / integral
/// (|S1|^2 + |S2|^2)/2 sin theta dtheta; and the fields' power is the albedo exactly.
#[test]
fn mie_azimuths_follow_the_polarisation_and_power_is_the_albedo() {
    let (r, lambda) = (150.0, 550.0);
    let m = white_particles(r, lambda);
    let ScatterModel::Mie { table, .. } = &m else {
        unreachable!()
    };
    let (mie, albedo) = (&table[0].sizes[0].mie, table[0].albedo);
    let (mut num, mut den) = (0.0, 0.0);
    let n = 20_000;
    for i in 0..n {
        let theta = (i as f64 + 0.5) * std::f64::consts::PI / n as f64;
        let (s1, s2) = mie.s1_s2(theta.cos());
        num += 0.25 * (s2.norm_sqr() - s1.norm_sqr()) * theta.sin();
        den += 0.5 * (s1.norm_sqr() + s2.norm_sqr()) * theta.sin();
    }
    let want = num / den;
    let d = DVec3::new(0.1, -0.2, -0.97).normalize();
    let (u, _) = frame(d);
    let mut rng = Rng::new(3, 9);
    let draws = 200_000;
    let (mut s, mut s2) = (0.0, 0.0);
    for _ in 0..draws {
        let f = [C64::new(u.x, 0.0), C64::new(u.y, 0.0), C64::new(u.z, 0.0)];
        let mut e = [f, f];
        let d2 = m.scatter(lambda, d, &mut e, &mut rng);
        let p = field_power(&e[0]) + field_power(&e[1]);
        assert!((p / 2.0 - albedo).abs() < 1e-12 * albedo, "{p}");
        // phi measured from u around d.
        let t = (d2 - d * d.dot(d2)).normalize();
        let (cu, cv) = (t.dot(u), t.dot(d.cross(u)));
        let c2 = cu * cu - cv * cv;
        s += c2;
        s2 += c2 * c2;
    }
    let mean = s / draws as f64;
    let se = ((s2 / draws as f64 - mean * mean) / draws as f64).sqrt();
    assert!(
        (mean - want).abs() < 4.0 * se,
        "<cos 2phi> {mean} +- {se}, want {want}"
    );
    assert!(
        want.abs() > 10.0 * se,
        "the check needs a polarised lobe: {want}"
    );
}

/// The envelope holds: no draw exceeds it across sizes from Rayleigh to x = 50,
/// lossless and absorbing.
#[test]
fn the_envelope_is_never_exceeded() {
    for (r, n_p) in [
        (20.0, C64::new(2.6, 0.0)),
        (120.0, C64::new(2.6, 0.01)),
        (400.0, C64::new(1.6, 0.0)),
        (900.0, C64::new(2.0, 0.5)),
        (3000.0, C64::new(1.33, 0.0)),
    ] {
        let m = ScatterModel::mie(
            Radius::LogNormal {
                median_nm: r,
                sigma: 0.2,
            },
            0.05,
            550.0,
            550.0,
            &|_| C64::new(1.5, 0.0),
            &|_| n_p,
        )
        .unwrap();
        let mut rng = Rng::new(11, r as u64);
        let d = DVec3::new(0.0, 0.6, -0.8);
        for _ in 0..200_000 {
            let mut e = unpolarised_pair(d);
            m.scatter(550.0, d, &mut e, &mut rng);
        }
        assert_eq!(m.violations(), 0, "r {r} nm, n {n_p}");
    }
}

#[test]
fn the_alias_table_draws_in_proportion() {
    let w = [0.5, 3.0, 0.0, 1.5, 5.0, 1e-9];
    let a = Alias::new(&w);
    let n = 100_000;
    let mut count = [0usize; 6];
    for k in 0..n {
        count[a.draw((k as f64 + 0.5) / n as f64)] += 1;
    }
    let total: f64 = w.iter().sum();
    for (c, wi) in count.iter().zip(&w) {
        // Evenly spaced u: each share is exact to a few draws.
        assert!(
            (*c as f64 - n as f64 * wi / total).abs() <= 3.0,
            "{count:?}"
        );
    }
}

#[test]
fn log_normal_nodes_have_the_median_and_spread() {
    let n = Radius::LogNormal {
        median_nm: 100.0,
        sigma: 0.3,
    }
    .nodes();
    let w: f64 = n.iter().map(|x| x.1).sum();
    assert!((w - 1.0).abs() < 1e-12);
    let mean_ln: f64 = n.iter().map(|(r, w)| w * r.ln()).sum();
    let var_ln: f64 = n.iter().map(|(r, w)| w * (r.ln() - mean_ln).powi(2)).sum();
    assert!((mean_ln - 100f64.ln()).abs() < 1e-12);
    // Truncation at 3.5 sigma removes 0.6 % of the variance.
    assert!(
        (var_ln.sqrt() / 0.3 - 1.0).abs() < 5e-3,
        "{}",
        var_ln.sqrt()
    );
}

#[test]
fn bad_media_are_refused() {
    assert!(ScatterModel::henyey_greenstein(1.0, 1.0, 0.0).is_err());
    assert!(ScatterModel::henyey_greenstein(0.5, -1.0, 0.0).is_err());
    assert!(ScatterModel::henyey_greenstein(0.5, 0.0, 0.0).is_err());
    let host = |_: f64| C64::new(1.5, 0.0);
    let p = |_: f64| C64::new(2.6, 0.0);
    let r = Radius::Fixed { radius_nm: 100.0 };
    assert!(ScatterModel::mie(r, 0.0, 500.0, 600.0, &host, &p).is_err());
    assert!(ScatterModel::mie(r, 0.8, 500.0, 600.0, &host, &p).is_err());
    assert!(ScatterModel::mie(r, 0.1, 500.0, 600.0, &|_| C64::new(1.5, 0.1), &p).is_err());
}
