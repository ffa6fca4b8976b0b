//! Polarimetric BRDFs (`--mueller`, issue 51): flat interfaces and a thin film against the
//! Mueller matrices of their closed-form Jones matrices (Fresnel, the Airy sum), written here
//! from the Stokes definitions; the unpolarised BRDF as the matrices' m00 bit for bit;
//! the fast estimator against the reference; realisability (Cloude's coherency
//! eigenvalues) on rough, absorbing and scattering samples; thread count, file and merge;
//! and what is refused.

mod common;

use common::*;
use goniospec::accumulate::Coherence;
use goniospec::accumulate::file::Accumulator;
use goniospec::simulate::{SimConfig, Wavelengths, simulate};
use num_complex::Complex64 as C;

/// The Mueller matrix (row-major) of the diagonal Jones matrix `diag(a, b)` acting on
/// the (p, s) amplitudes, from the Stokes definitions `S0 = |E_p|^2 + |E_s|^2`, `S1 =
/// |E_p|^2 - |E_s|^2`, `S2 = 2 Re(E_p conj E_s)`, `S3 = 2 Im(conj E_p E_s)`: with
/// `E_p' = a E_p` and `E_s' = b E_s`, `S2' = Re(a conj b) S2 + Im(a conj b) S3` and `S3' =
/// Re(a conj b) S3 - Im(a conj b) S2` (Azzam & Bashara 1977, §2.8, a diattenuating
/// retarder).
fn diagonal_mueller(a: C, b: C) -> [f64; 16] {
    let (pa, pb) = (a.norm_sqr(), b.norm_sqr());
    let x = a * b.conj();
    [
        0.5 * (pa + pb),
        0.5 * (pa - pb),
        0.0,
        0.0,
        0.5 * (pa - pb),
        0.5 * (pa + pb),
        0.0,
        0.0,
        0.0,
        0.0,
        x.re,
        x.im,
        0.0,
        0.0,
        -x.im,
        x.re,
    ]
}

/// The 600 nm soap film (n = 1.33) between air of the film tests.
fn soap_film(tag: &str) -> goniospec::sample::Sample {
    stack_sample(
        tag,
        "[media.air]\nn = 1.0\n[media.soap]\nn = 1.33\n",
        "air",
        &[("soap", 600.0)],
        "air",
    )
}

/// That film's reflected Mueller matrix at `theta_deg` and `lambda_nm`: the Airy sum
/// `r = (r01 + r12 e^{2i beta}) / (1 + r01 r12 e^{2i beta})`, `beta = 2 pi n d cos theta_1 /
/// lambda`, for each polarisation (Born & Wolf §7.6.1).
fn soap_film_mueller(theta_deg: f64, lambda_nm: f64) -> [f64; 16] {
    let (air, film) = (C::new(1.0, 0.0), C::new(1.33, 0.0));
    let th = theta_deg.to_radians();
    let (rp01, rs01) = fresnel_amplitudes(air, film, th);
    let th1 = (th.sin() / 1.33).asin();
    let (rp12, rs12) = fresnel_amplitudes(film, air, th1);
    let e = C::from_polar(
        1.0,
        4.0 * std::f64::consts::PI * 1.33 * 600.0 * th1.cos() / lambda_nm,
    );
    let airy = |a: C, b: C| (a + b * e) / (1.0 + a * b * e);
    diagonal_mueller(airy(rp01, rp12), airy(rs01, rs12))
}

/// The reflected Mueller matrix of direction `i`, wavelength `j`, summed over the
/// reflection buckets (a flat sample fills the specular one only), as fractions.
fn reflected(acc: &Accumulator, i: usize, j: usize) -> [f64; 16] {
    let c = acc.cell(i, j);
    let mut m = [0.0; 16];
    for kk in (0..c.sum.len()).step_by(2) {
        let x = c.mueller(kk).expect("a --mueller run keeps its matrices");
        for (a, b) in m.iter_mut().zip(x) {
            *a += b;
        }
    }
    m
}

fn mueller_config(theta: &[f64], wavelengths: Wavelengths, rays: u64) -> SimConfig {
    SimConfig {
        mueller: true,
        ..config(theta, wavelengths, rays)
    }
}

fn assert_matrix(got: &[f64; 16], want: &[f64; 16], tol: f64, what: &str) {
    for e in 0..16 {
        assert!(
            (got[e] - want[e]).abs() <= tol,
            "{what}: m{}{} = {} against {} (tolerance {tol:e})\n got {got:?}\nwant {want:?}",
            e / 4,
            e % 4,
            got[e],
            want[e]
        );
    }
}

/// The reflected matrix of every cell of `acc` (a run of the soap film at `thetas` x
/// `lambdas`, exact wavelengths) against the Airy sum ([`soap_film_mueller`]), within
/// rounding and what the power cutoff dropped, which may change the sum by `2 sqrt(D R) +
/// D`.
fn assert_airy(acc: &Accumulator, thetas: &[f64], lambdas: &[f64], what: &str) {
    for (i, &t) in thetas.iter().enumerate() {
        for (j, &l) in lambdas.iter().enumerate() {
            let want = soap_film_mueller(t, l);
            let cell = acc.cell(i, j);
            let d = cell.dropped / cell.trees as f64;
            let tol = 1e-9 + 2.0 * (d * want[0]).sqrt() + d;
            assert_matrix(
                &reflected(acc, i, j),
                &want,
                tol,
                &format!("{what} at {t} deg, {l} nm"),
            );
        }
    }
}

#[test]
fn single_interfaces_match_the_fresnel_mueller_matrices() {
    let glass = flat_substrate("mueller-glass", 1.5, 0.0);
    let gold = flat_substrate("mueller-gold", 0.43, 2.455);
    let thetas: Vec<f64> = (0..=17).map(|i| 5.0 * i as f64).collect();
    for (s, n2) in [(&glass, C::new(1.5, 0.0)), (&gold, C::new(0.43, 2.455))] {
        let cfg = mueller_config(&thetas, Wavelengths::Monochromatic(vec![548.6]), 16);
        let acc = run(s, &cfg);
        for (i, &t) in thetas.iter().enumerate() {
            let (rp, rs) = fresnel_amplitudes(C::new(1.0, 0.0), n2, t.to_radians());
            // One reflection per tree, nothing to interfere with: exact to rounding.
            assert_matrix(
                &reflected(&acc, i, 0),
                &diagonal_mueller(rp, rs),
                1e-12,
                &format!("{} at {t} deg", s.name),
            );
        }
    }
    // Past Brewster's angle (56.3 deg) glass's m22 = Re(r_p conj r_s) changes sign: the
    // check above is not blind to the p field's sign.
    let (rp, rs) = fresnel_amplitudes(C::new(1.0, 0.0), C::new(1.5, 0.0), 70f64.to_radians());
    assert!((rp * rs.conj()).re > 0.0);
    let (rp, rs) = fresnel_amplitudes(C::new(1.0, 0.0), C::new(1.5, 0.0), 30f64.to_radians());
    assert!((rp * rs.conj()).re < 0.0);
}

/// A 600 nm soap film on air in the plane-wave limit: the tree's reflected partial waves
/// summed coherently (the estimator's groups) against the Airy sum `r = (r01 + r12 e^{2i
/// beta}) / (1 + r01 r12 e^{2i beta})`, `beta = 2 pi n d cos theta_1 / lambda`, for each
/// polarisation (Born & Wolf §7.6.1).
#[test]
fn a_thin_film_matches_the_airy_sum_in_both_polarisations() {
    let soap = soap_film("mueller-soap");
    let thetas = [0.0, 30.0, 60.0, 75.0];
    let lambdas = vec![450.0, 550.0, 650.0];
    let mut cfg = mueller_config(&thetas, Wavelengths::Monochromatic(lambdas.clone()), 8);
    cfg.rho_nm = f64::INFINITY;
    assert_airy(&run(&soap, &cfg), &thetas, &lambdas, "soap");
}

/// Issue 74: a meshed flat film's exits all leave in one direction, and at 70 deg that
/// direction lies on a bucket edge of the default grid (2-degree buckets), where rounding
/// put them on both sides and their cross terms, split between the buckets, made matrices
/// no sample can have (refused at every ray count tried, 64 to 3,000). Now: at the default
/// angles and 70 deg every bucket is realisable at the default radius, and in the
/// plane-wave limit the reflected matrix is the Airy sum's, as the coated film's is.
#[test]
fn a_meshed_flat_film_gives_realisable_matrices_on_bucket_edges() {
    let soap = sample_from(
        "mueller-meshed-film",
        &stack_toml(
            "mueller-meshed-film",
            "mesh",
            "[media.air]\nn = 1.0\n[media.soap]\nn = 1.33\n",
            &[("soap", 600.0)],
            "air",
        ),
    );
    let lambdas = vec![450.0, 550.0, 650.0];
    let thetas = [0.0, 15.0, 30.0, 45.0, 60.0, 70.0, 75.0];
    for rays in [64, 256] {
        let cfg = mueller_config(&thetas, Wavelengths::Monochromatic(lambdas.clone()), rays);
        // `run` passes the run through every check a run makes before writing.
        let acc = run(&soap, &cfg);
        let r = acc.realisability().expect("kept");
        assert_eq!(r.failed, 0, "{rays} trees: {r:?}");
    }
    let thetas = [30.0, 60.0, 70.0];
    let mut cfg = mueller_config(&thetas, Wavelengths::Monochromatic(lambdas.clone()), 16);
    cfg.rho_nm = f64::INFINITY;
    assert_airy(&run(&soap, &cfg), &thetas, &lambdas, "meshed soap");
}

/// The unpolarised sums of a `--mueller` run are the run without it, bit for bit, and
/// every bucket's m00 is its unpolarised sum; the fast estimator's matrices agree with the
/// reference estimator's (every pair's phase by the C library) to rounding.
#[test]
fn m00_is_the_unpolarised_brdf_bit_for_bit_and_the_fast_path_is_the_reference() {
    let wl = Wavelengths::parse("400:700:75", false).unwrap();
    for name in ["thin-film-600nm", "rough-gold"] {
        let s = shipped(&format!("{name}.toml"));
        let plain = SimConfig {
            coherence: Coherence::Beamlet,
            ..config(&[30.0], wl.clone(), 96)
        };
        let polar = SimConfig {
            mueller: true,
            ..plain.clone()
        };
        let (a, b) = (run(&s, &plain), run(&s, &polar));
        for (x, y) in a.cells.iter().zip(&b.cells) {
            assert_eq!(x.sum, y.sum, "{name}: the unpolarised sums changed");
            assert_eq!(x.sumsq, y.sumsq);
            for (kk, m) in y.mueller.iter().enumerate() {
                assert_eq!(m[0].to_bits(), y.sum[kk].to_bits(), "{name}: key {kk}");
            }
        }
        let reference = run(
            &s,
            &SimConfig {
                reference_estimator: true,
                ..polar.clone()
            },
        );
        let mut pairs_seen = 0.0f64;
        for (x, y) in b.cells.iter().zip(&reference.cells) {
            let scale = x.sum.iter().map(|v| v.abs()).fold(0.0, f64::max);
            for (m, r) in x.mueller.iter().zip(&y.mueller) {
                for e in 1..16 {
                    assert!(
                        (m[e] - r[e]).abs() <= 1e-10 * scale,
                        "{name}: element {e}: {} against the reference's {}",
                        m[e],
                        r[e]
                    );
                    pairs_seen = pairs_seen.max(m[e].abs());
                }
            }
        }
        assert!(pairs_seen > 0.0, "{name}: no polarisation to compare");
    }
}

/// The Mueller matrices of rough, absorbing, layered and scattering samples are
/// realisable: every bucket's coherency matrix non-negative within its standard errors.
#[test]
fn every_shipped_kind_of_sample_gives_realisable_matrices() {
    let wl = Wavelengths::parse("400:700:100", false).unwrap();
    for (name, rays) in [
        ("rough-gold", 512),
        ("rough-glass", 512),
        ("thin-film-600nm", 256),
        ("paint-pigments", 64),
    ] {
        let s = shipped(&format!("{name}.toml"));
        let cfg = SimConfig {
            coherence: Coherence::Beamlet,
            ..mueller_config(&[0.0, 45.0], wl.clone(), rays)
        };
        let acc = run(&s, &cfg);
        let r = acc.realisability().expect("kept");
        assert!(r.checked > 0, "{name}: nothing checked");
        assert_eq!(
            r.failed, 0,
            "{name}: {} of {} buckets not realisable (worst {:.3e} of m00, {:.1} sigma)",
            r.failed, r.checked, r.worst_relative, r.worst_sigmas
        );
    }
}

#[test]
fn matrices_do_not_depend_on_threads_and_survive_the_file_and_merge() {
    let s = shipped("rough-glass.toml");
    let cfg = mueller_config(
        &[20.0],
        Wavelengths::parse("450:650:100", false).unwrap(),
        128,
    );
    let a = run(&s, &cfg);
    let one = run_on_one_thread(&s, &cfg);
    assert_eq!(a.cells, one.cells);
    let bytes = a.to_bytes();
    let back = Accumulator::from_bytes(&bytes, "mem").unwrap();
    assert_eq!(back, a);
    let b = run(
        &s,
        &SimConfig {
            seed: 2,
            ..cfg.clone()
        },
    );
    let mut merged = a.clone();
    merged.merge(&b).unwrap();
    let (x, y, m) = (a.cell(0, 0), b.cell(0, 0), merged.cell(0, 0));
    for kk in 0..x.mueller.len() {
        for e in 0..16 {
            assert_eq!(m.mueller[kk][e], x.mueller[kk][e] + y.mueller[kk][e]);
        }
    }
    // A run without matrices does not merge with one that has them.
    let plain = run(
        &s,
        &SimConfig {
            seed: 3,
            mueller: false,
            ..cfg
        },
    );
    let err = merged.merge(&plain).unwrap_err().to_string();
    assert!(err.contains("mueller"), "{err}");
}

/// An impossible matrix (a flat glass's specular matrix with m11 = 3 m00: two coherency
/// eigenvalues of `(m00 - m11 -/+ (m22 - m33)) / 4 < 0`) stops the check every run
/// passes through; flat glass's buckets have no spread to hide it in.
#[test]
fn an_unrealisable_matrix_is_refused() {
    let s = flat_substrate("mueller-refused", 1.5, 0.0);
    let cfg = mueller_config(&[20.0], Wavelengths::Monochromatic(vec![550.0]), 16);
    let mut acc = run(&s, &cfg);
    assert!(goniospec::simulate::check_physical(&acc, "flat glass", None).is_ok());
    let c = &mut acc.cells[0];
    let kk = (0..c.sum.len())
        .step_by(2)
        .max_by(|&a, &b| c.sum[a].total_cmp(&c.sum[b]))
        .unwrap();
    c.mueller[kk][5] = 3.0 * c.mueller[kk][0];
    let err = goniospec::simulate::check_physical(&acc, "flat glass", None)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("not physically realisable") && err.contains("1 of"),
        "{err}"
    );
}

/// The matrices are stored sparsely (a flat sample fills one bucket of 3,240 keys), and a
/// payload whose matrices are cut short, name a key out of range or out of order, or carry
/// bytes past the last cell is refused (re-framed with a valid checksum, so that the
/// reader's own checks are what refuse it).
#[test]
fn the_sparse_matrices_are_read_back_or_refused() {
    use goniospec::accumulate::file::FORMAT;
    use goniospec::container::{decode, encode};
    let glass = flat_substrate("mueller-sparse", 1.5, 0.0);
    let acc = run(
        &glass,
        &mueller_config(&[20.0], Wavelengths::Monochromatic(vec![550.0]), 4),
    );
    let bytes = acc.to_bytes();
    assert_eq!(Accumulator::from_bytes(&bytes, "mem").unwrap(), acc);
    let frame = decode(&FORMAT, &bytes, "mem").unwrap();
    let (header, payload) = (frame.header.to_string(), frame.payload.to_vec());
    // One cell: the fixed part (trees, 3 x 3240 key values, 6 totals), then the count.
    let keys = 2 * 45 * 36;
    let at = 8 * (1 + 3 * keys + 6);
    let count = u64::from_le_bytes(payload[at..at + 8].try_into().unwrap());
    // The specular bucket; the transmitted beam's.
    assert_eq!(count, 2);
    assert_eq!(payload.len(), at + 8 + 2 * 33 * 8);
    let refused =
        |p: Vec<u8>| Accumulator::from_bytes(&encode(&FORMAT, &header, &p), "mem").is_err();
    assert!(refused(payload[..payload.len() - 8].to_vec()));
    let mut extra = payload.clone();
    extra.extend_from_slice(&[0; 8]);
    assert!(refused(extra));
    let mut out_of_range = payload.clone();
    out_of_range[at + 8..at + 16].copy_from_slice(&(keys as u64).to_le_bytes());
    assert!(refused(out_of_range));
    let mut disordered = payload.clone();
    let second = at + 8 + 33 * 8;
    let first_key = disordered[at + 8..at + 16].to_vec();
    disordered[second..second + 8].copy_from_slice(&first_key);
    assert!(refused(disordered));
}

#[test]
fn the_comparison_modes_are_refused_before_work() {
    let s = shipped("thin-film-600nm.toml");
    for mode in [Coherence::Bucket, Coherence::Global] {
        let cfg = SimConfig {
            coherence: mode,
            ..mueller_config(
                &[30.0],
                Wavelengths::parse("400:700:100", false).unwrap(),
                16,
            )
        };
        let err = simulate(&s, &cfg, &|_| {}).unwrap_err().to_string();
        assert!(
            err.contains("mueller") && err.contains("beamlet"),
            "{mode}: {err}"
        );
    }
}

/// The diffraction method's matrices. A flat soap film has one order, the specular: its
/// Jones matrix is the tree's exits summed coherently over the tile, so its normalised
/// Mueller matrix is the Airy sum's, within the transform's gridding error (1.5e-5
/// measured; 1e-4 allowed); its m00 is scaled to the rays' R. On the seed's wavy film under
/// `auto`, which takes the diffraction method from 0 to 40 deg, the unpolarised sums are
/// the run without --mueller bit for bit and every matrix is realisable.
#[test]
fn the_diffraction_method_carries_the_matrix() {
    let soap = soap_film("mueller-soap-diffraction");
    let lambdas = vec![450.0, 550.0, 650.0];
    let cfg = SimConfig {
        coherence: Coherence::Diffraction,
        rho_nm: f64::INFINITY,
        ..mueller_config(&[30.0], Wavelengths::Monochromatic(lambdas.clone()), 1024)
    };
    let acc = run(&soap, &cfg);
    for (j, &l) in lambdas.iter().enumerate() {
        let want = soap_film_mueller(30.0, l);
        let got = reflected(&acc, 0, j);
        let (g, w): (Vec<f64>, Vec<f64>) = (0..16)
            .map(|k| (got[k] / got[0], want[k] / want[0]))
            .unzip();
        assert_matrix(
            &g.try_into().unwrap(),
            &w.try_into().unwrap(),
            1e-4,
            &format!("soap by the diffraction method, {l} nm"),
        );
    }
    let s = shipped("thin-film-600nm.toml");
    let wl = Wavelengths::parse("400:700:100", false).unwrap();
    let plain = SimConfig {
        coherence: Coherence::Auto,
        ..config(&[0.0, 30.0, 75.0], wl, 1024)
    };
    let polar = SimConfig {
        mueller: true,
        ..plain.clone()
    };
    let (a, b) = (run(&s, &plain), run(&s, &polar));
    assert!(
        b.header.settings.methods.iter().any(|m| m.contains('d')),
        "auto took no diffraction cell: {:?}",
        b.header.settings.methods
    );
    for (x, y) in a.cells.iter().zip(&b.cells) {
        assert_eq!(x.sum, y.sum);
        for (kk, m) in y.mueller.iter().enumerate() {
            assert_eq!(m[0].to_bits(), y.sum[kk].to_bits(), "key {kk}");
        }
    }
    let r = b.realisability().unwrap();
    assert_eq!(r.failed, 0, "{r:?}");
}

#[test]
fn eval_prints_the_mueller_brdf_or_says_why_not() {
    let dir = scratch("mueller-eval");
    let gsa = dir.join("g.gsa");
    let gsa0 = dir.join("g0.gsa");
    let (code, _, err) = goniospec(&[
        "simulate",
        "meshes/rough-gold.toml",
        "--theta-i",
        "30",
        "--rays",
        "64",
        "--wavelengths",
        "500:600:50",
        "--mueller",
        "-o",
        gsa.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let (code, out, err) = goniospec(&[
        "eval",
        gsa.to_str().unwrap(),
        "--mueller",
        "--theta-i",
        "30",
        "--theta-o",
        "30",
    ]);
    assert_eq!(code, 0, "{err}");
    let lines: Vec<&str> = out.lines().collect();
    assert!(lines[0].starts_with("lambda_nm,m00,m01"), "{out}");
    assert_eq!(lines.len(), 3, "{out}");
    // The printed m00 is the unpolarised BRDF of that bucket (the same .gsa read here).
    let acc = Accumulator::read(&gsa).unwrap();
    let b = acc.header.settings.buckets();
    let wo = goniospec::geom::from_spherical(30f64.to_radians(), std::f64::consts::PI);
    let k = b.index(wo);
    let want = acc.cell(0, 0).fraction(2 * k, Coherence::Auto) / b.projected_solid_angle(k);
    let m00: f64 = lines[1].split(',').nth(1).unwrap().parse().unwrap();
    assert!(
        (m00 - want).abs() <= 1e-8 * want.abs(),
        "{m00} against {want}"
    );
    let (code, _, err) = goniospec(&[
        "simulate",
        "meshes/rough-gold.toml",
        "--theta-i",
        "30",
        "--rays",
        "16",
        "--wavelengths",
        "500:600:50",
        "-o",
        gsa0.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let (code, _, err) = goniospec(&[
        "eval",
        gsa0.to_str().unwrap(),
        "--mueller",
        "--theta-i",
        "30",
        "--theta-o",
        "30",
    ]);
    assert_ne!(code, 0);
    assert!(err.contains("--mueller"), "{err}");
    let (code, _, err) = goniospec(&[
        "eval",
        gsa.to_str().unwrap(),
        "--mueller",
        "--theta-i",
        "40",
        "--theta-o",
        "30",
    ]);
    assert_ne!(code, 0);
    assert!(err.contains("40"), "{err}");
}

/// The Mueller matrix of a general Jones matrix `j` (rows: outgoing p, s; columns: incident
/// p, s), column by column from the Stokes vectors of the fields it sends out for four
/// incident states (p, s, +45 deg, and `(E_p, E_s) = (1, i) / sqrt 2`), by the Stokes
/// definitions alone.
fn mueller_from_states(j: [[C; 2]; 2]) -> [f64; 16] {
    let stokes = |ep: C, es: C| {
        [
            ep.norm_sqr() + es.norm_sqr(),
            ep.norm_sqr() - es.norm_sqr(),
            2.0 * (ep * es.conj()).re,
            2.0 * (ep.conj() * es).im,
        ]
    };
    let out = |ep: C, es: C| stokes(j[0][0] * ep + j[0][1] * es, j[1][0] * ep + j[1][1] * es);
    let r = std::f64::consts::FRAC_1_SQRT_2;
    let (one, zero) = (C::new(1.0, 0.0), C::new(0.0, 0.0));
    let (p, s) = (out(one, zero), out(zero, one));
    let d = out(C::new(r, 0.0), C::new(r, 0.0));
    let c = out(C::new(r, 0.0), C::new(0.0, r));
    let mut m = [0.0; 16];
    for a in 0..4 {
        let col0 = 0.5 * (p[a] + s[a]);
        m[4 * a] = col0;
        m[4 * a + 1] = 0.5 * (p[a] - s[a]);
        m[4 * a + 2] = d[a] - col0;
        m[4 * a + 3] = c[a] - col0;
    }
    m
}

type V = glam::DVec3;

/// The s/p frame of a direction as the tests define it: `s = w × z` normalised, `p = s × w`.
fn sp(w: V) -> (V, V) {
    let s = w.cross(V::Z).normalize();
    (s.cross(w), s)
}

/// The Jones matrix (rows: outgoing p, s; columns: incident p, s, each in its direction's
/// frame) of a mirror facet of normal `h` reflecting light that travels along `-wi` into
/// `wo`: the facet's Fresnel coefficients at its local angle, with s and p in the facet's
/// own plane of incidence (`s_f = d × h`, `p = s_f × direction` on either side), projected
/// on the directions' frames.
fn facet_jones(wi: V, wo: V, h: V, n2: C) -> [[C; 2]; 2] {
    let (rp, rs) = fresnel_amplitudes(C::new(1.0, 0.0), n2, wi.dot(h).clamp(-1.0, 1.0).acos());
    let din = -wi;
    let sf = din.cross(h).normalize();
    let (pfi, pfo) = (sf.cross(din), sf.cross(wo));
    let field = |e: V| -> [C; 3] {
        let (a, b) = (e.dot(sf), e.dot(pfi));
        std::array::from_fn(|k| rs * a * sf.to_array()[k] + rp * b * pfo.to_array()[k])
    };
    let (pi, si) = sp(din);
    let (po, so) = sp(wo);
    let dot = |f: [C; 3], u: V| f[0] * u.x + f[1] * u.y + f[2] * u.z;
    let (fp, fs) = (field(pi), field(si));
    [[dot(fp, po), dot(fs, po)], [dot(fp, so), dot(fs, so)]]
}

/// Rough gold (GGX, alpha 0.2) against a brute-force single-scattering reference written
/// here: every facet of the sample's own mesh that faces the light reflects the fraction
/// `(wi . A_f) / (A_tile cos theta_i)` of it as a Fresnel mirror into the bucket of its
/// mirror direction, with the Mueller matrix of its Jones matrix (`facet_jones`, from the
/// Stokes definitions). The elements normalised by m00 are compared in the buckets that
/// hold the lobe. The reference leaves out shadowing and masking by other facets and light
/// that scatters twice (a few per cent of the reflected power at alpha 0.2 and 30-60 deg,
/// Heitz et al. 2016; a fifth of a grazing bucket's at 60 deg, where facets shadow): each
/// element may differ by twice that share of the bucket's power, plus 4 standard errors.
#[test]
fn rough_gold_matches_a_facet_by_facet_fresnel_reference() {
    let s = shipped("rough-gold.toml");
    // Johnson & Christy's gold at one of its tabulated wavelengths.
    let n2 = C::new(0.43, 2.455);
    let thetas = [30.0, 60.0];
    // Buckets of 6 x 30 deg, so that each holds thousands of trees.
    let buckets = goniospec::accumulate::Buckets {
        theta_bins: 15,
        phi_bins: 12,
    };
    let cfg = SimConfig {
        buckets,
        ..mueller_config(&thetas, Wavelengths::Monochromatic(vec![548.6]), 131072)
    };
    let acc = run(&s, &cfg);
    let mesh = &s.interfaces[0].mesh;
    let tile = s.tile_nm[0] * s.tile_nm[1];
    for (i, &t) in thetas.iter().enumerate() {
        let wi = V::new(t.to_radians().sin(), 0.0, t.to_radians().cos());
        let mut reference = vec![[0.0; 16]; buckets.len()];
        for f in 0..mesh.triangles.len() {
            let a = mesh.area_vector(f) * 0.5;
            let a = if a.z < 0.0 { -a } else { a };
            let lit = wi.dot(a);
            if lit <= 0.0 {
                continue;
            }
            let h = a.normalize();
            let wo = 2.0 * wi.dot(h) * h - wi;
            if wo.z <= 0.0 {
                continue;
            }
            let m = mueller_from_states(facet_jones(wi, wo, h, n2));
            let w = lit / (tile * wi.z);
            for (r, x) in reference[buckets.index(wo)].iter_mut().zip(m) {
                *r += x * w;
            }
        }
        let peak = reference.iter().map(|m| m[0]).fold(0.0, f64::max);
        let cell = acc.cell(i, 0);
        let (mut worst, mut compared) = (0.0f64, 0);
        for (k, want) in reference.iter().enumerate() {
            if want[0] < 0.3 * peak {
                continue;
            }
            compared += 1;
            let got = cell.mueller(2 * k).unwrap();
            let se = cell.mueller_stderr(2 * k).unwrap();
            // The share of the bucket's power the reference does not describe: what its
            // m00 misses (shadowing and masking take, second bounces add) and 2 % of
            // second bounces that m00 cannot show. Normalised elements lie in [-1, 1], so
            // that share moves each by at most twice itself.
            let share = (got[0] / want[0] - 1.0).abs() + 0.02;
            for e in 1..16 {
                let (g, w) = (got[e] / got[0], want[e] / want[0]);
                let sigma = se[e] / got[0].abs();
                let tol = 2.0 * share + 4.0 * sigma;
                worst = worst.max((g - w).abs() / tol);
                assert!(
                    (g - w).abs() <= tol,
                    "theta_i {t}, bucket {k}: m{}{}/m00 {g:.4} against the reference's {w:.4} (tolerance {tol:.4}: 2 x {share:.3} of the power unlike it, 4 x {sigma:.4})",
                    e / 4,
                    e % 4
                );
            }
        }
        eprintln!(
            "theta_i {t}: {compared} buckets, the worst normalised element {worst:.2} of its tolerance"
        );
        assert!(
            compared >= 4,
            "theta_i {t}: only {compared} buckets compared"
        );
    }
}

/// Polarised light in: flat glass's R and T for s, p, +45 deg and circular light against
/// the Fresnel reflectances (`R_s`, `R_p`, and their mean for the other two), by the
/// library and through `reflectance --incident`; a state that is none is refused.
#[test]
fn polarised_light_in_reflects_as_fresnel_says() {
    let glass = flat_substrate("mueller-incident", 1.5, 0.0);
    let cfg = mueller_config(&[60.0], Wavelengths::Monochromatic(vec![550.0]), 8);
    let acc = run(&glass, &cfg);
    let (rp, rs) = fresnel_amplitudes(C::new(1.0, 0.0), C::new(1.5, 0.0), 60f64.to_radians());
    let (rs2, rp2) = (rs.norm_sqr(), rp.norm_sqr());
    for (name, want) in [
        ("s", rs2),
        ("p", rp2),
        ("+45", 0.5 * (rs2 + rp2)),
        ("circular-", 0.5 * (rs2 + rp2)),
        ("1,0.6,0,0", 0.5 * (rs2 + rp2) + 0.3 * (rp2 - rs2)),
    ] {
        let state = goniospec::optics::mueller::stokes_state(name).unwrap();
        let row = acc.polarised_reflectance(60.0, None, &state).unwrap()[0];
        assert!(
            (row.r - want).abs() < 1e-12,
            "{name}: R {} against {want}",
            row.r
        );
        // Lossless glass transmits the rest of each state.
        assert!((row.t - (1.0 - want)).abs() < 1e-9, "{name}: T {}", row.t);
    }
    // The buckets a .gsb is built from, for s light: their fluxes sum to R_s.
    let s_state = goniospec::optics::mueller::stokes_state("s").unwrap();
    let data = goniospec::brdf::BucketData::from_accumulator_polarised(&acc, &s_state).unwrap();
    let r_s: f64 = data.samples[0].iter().map(|b| b.flux[0]).sum();
    assert!((r_s - rs2).abs() < 1e-12, "{r_s} against {rs2}");
    assert_eq!(data.meta.incident_stokes, Some(s_state));
    let dir = scratch("mueller-incident");
    let gsa = dir.join("glass.gsa");
    acc.write(&gsa).unwrap();
    let gsb = dir.join("glass-p.gsb");
    let (code, _, err) = goniospec(&[
        "build",
        gsa.to_str().unwrap(),
        "--incident",
        "p",
        "--repr",
        "table",
        "-o",
        gsb.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let (code, out, err) = goniospec(&["info", gsb.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains("incident light polarised: Stokes (1, 1, 0, 0)"),
        "{out}"
    );
    let (code, out, err) = goniospec(&[
        "reflectance",
        gsa.to_str().unwrap(),
        "--theta-i",
        "60",
        "--incident",
        "p",
    ]);
    assert_eq!(code, 0, "{err}");
    let r: f64 = out
        .lines()
        .nth(1)
        .unwrap()
        .split(',')
        .nth(1)
        .unwrap()
        .parse()
        .unwrap();
    assert!((r - rp2).abs() < 1e-8, "{out}");
    let (code, _, err) = goniospec(&[
        "reflectance",
        gsa.to_str().unwrap(),
        "--theta-i",
        "60",
        "--incident",
        "1,1,1,0",
    ]);
    assert_ne!(code, 0);
    assert!(err.contains("not a polarisation state"), "{err}");
}

/// A file is judged by its physics, not only its checksum: flat glass's transmitted
/// matrix scaled tenfold and resealed (realisable, and its unpolarised sums untouched) gives
/// p light T = 10 x 0.91: every command that uses the results refuses it, naming the state
/// and T; a matrix made unrealisable (m01 = -3 m00) is refused as such; the run's own
/// file passes; and a file whose run stored that it was written with --allow-unphysical
/// is read with that warning.
#[test]
fn files_whose_matrices_were_changed_and_resealed_are_refused() {
    use goniospec::simulate::{WRITTEN_UNPHYSICAL, check_file, read_judged};
    let glass = flat_substrate("mueller-forged", 1.5, 0.0);
    let cfg = mueller_config(&[60.0], Wavelengths::Monochromatic(vec![550.0]), 8);
    let honest = run(&glass, &cfg);
    assert!(check_file(&honest, "honest").is_ok());
    let dir = scratch("mueller-forged");
    let forge = |name: &str, change: &dyn Fn(&mut [f64; 16]), warnings: Vec<String>| {
        let mut acc = honest.clone();
        let c = &mut acc.cells[0];
        // The transmitted beam's bucket: the odd key holding the most power.
        let kk = (1..c.sum.len())
            .step_by(2)
            .max_by(|&a, &b| c.sum[a].total_cmp(&c.sum[b]))
            .unwrap();
        change(&mut c.mueller[kk]);
        acc.header.warnings = warnings;
        let path = dir.join(name);
        acc.write(&path).unwrap();
        path
    };
    let tenfold = forge(
        "tenfold.gsa",
        &|m| m.iter_mut().for_each(|x| *x *= 10.0),
        vec![],
    );
    let t = tenfold.to_str().unwrap();
    let out = dir.join("out");
    let o = out.to_str().unwrap();
    for args in [
        vec!["reflectance", t, "--theta-i", "60", "--incident", "p"],
        vec!["reflectance", t, "--theta-i", "60"],
        vec!["eval", t, "--mueller", "--theta-i", "60", "--theta-o", "60"],
        vec!["build", t, "-o", o],
        vec!["export", t, "--format", "pbsdf", "-o", o],
    ] {
        let (code, _, err) = goniospec(&args);
        assert_ne!(code, 0, "{args:?} accepted a forged file");
        assert!(
            err.contains("light in p (S1 = +1): T = 9.") && err.contains("changed and resealed"),
            "{args:?}: {err}"
        );
    }
    assert!(!out.exists());
    // `info` describes the file, impossible or not.
    let (code, text, err) = goniospec(&["info", t]);
    assert_eq!(code, 0, "{err}");
    assert!(text.contains("physics: IMPOSSIBLE"), "{text}");
    let skewed = forge("skewed.gsa", &|m| m[1] = -3.0 * m[0], vec![]);
    let err = read_judged(&skewed).unwrap_err().to_string();
    assert!(err.contains("not physically realisable"), "{err}");
    let kept = forge(
        "kept.gsa",
        &|m| m.iter_mut().for_each(|x| *x *= 10.0),
        vec![format!("{WRITTEN_UNPHYSICAL}T > 1")],
    );
    let (_, warning) = read_judged(&kept).unwrap();
    assert!(
        warning.is_some_and(|w| w.contains("read anyway") && w.contains("T = 9.")),
        "a file its run kept with --allow-unphysical is read with a warning"
    );
}

/// `export --format pbsdf`: Mitsuba's measured_polarized layout (the plugin's own checks:
/// 2-D float32 axes, five uint16 wavelengths, M of [phi_d, theta_d, theta_h, 5, 4, 4]),
/// NaN below the horizon only; refused without matrices. Mitsuba itself reads it in
/// tests/interop/mueller_mitsuba.py.
#[test]
fn the_pbsdf_export_has_the_plugins_layout() {
    use goniospec::export::tensor::{Dtype, from_bytes};
    let dir = scratch("mueller-pbsdf");
    let (gsa, plain, out) = (dir.join("g.gsa"), dir.join("p.gsa"), dir.join("g.pbsdf"));
    for (path, extra) in [(&gsa, Some("--mueller")), (&plain, None)] {
        let mut args = vec![
            "simulate",
            "meshes/rough-gold.toml",
            "--theta-i",
            "0,40",
            "--rays",
            "32",
            "--wavelengths",
            "440:660:110",
            "-o",
            path.to_str().unwrap(),
        ];
        args.extend(extra);
        let (code, _, err) = goniospec(&args);
        assert_eq!(code, 0, "{err}");
    }
    let (code, _, err) = goniospec(&[
        "export",
        gsa.to_str().unwrap(),
        "--format",
        "pbsdf",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    // What the file stands in for: the two angles and two bins (centres 495 and 605 nm) are
    // said, with the plugin's 450 and 650 nm held from the nearest bin.
    assert!(
        err.contains("simulated 0, 40 deg")
            && err.contains("40 deg stands in above them")
            && err.contains("centred at 495, 605 nm, and 450, 650 nm take the nearest"),
        "{err}"
    );
    let fields = from_bytes(&std::fs::read(&out).unwrap()).unwrap();
    let get = |n: &str| fields.iter().find(|f| f.name == n).unwrap();
    let (pd, td, th) = (get("phi_d"), get("theta_d"), get("theta_h"));
    for a in [pd, td, th] {
        assert_eq!((a.dtype, a.shape.len(), a.shape[0]), (Dtype::Float32, 2, 1));
    }
    let w = get("wvls");
    assert_eq!(w.dtype, Dtype::UInt16);
    assert_eq!(w.values_f64(), vec![450.0, 500.0, 550.0, 600.0, 650.0]);
    let m = get("M");
    assert_eq!(
        m.shape,
        vec![pd.shape[1], td.shape[1], th.shape[1], 5, 4, 4]
    );
    let v = m.values_f64();
    // theta_h = theta_d = 0 (both directions along the normal) is above the horizon; the
    // grid's grazing corner (theta_h = theta_d = 90 deg) is below it.
    assert!(v[..16].iter().all(|x| x.is_finite()));
    let nth = th.shape[1] as usize;
    let corner = ((td.shape[1] as usize - 1) * nth + nth - 1) * 80;
    assert!(v[corner..corner + 16].iter().all(|x| x.is_nan()));
    let (code, _, err) = goniospec(&[
        "export",
        plain.to_str().unwrap(),
        "--format",
        "pbsdf",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_ne!(code, 0);
    assert!(err.contains("--mueller"), "{err}");
}

/// One simulated incident angle standing in for every angle of a `.pbsdf` (issue 74) is
/// refused without --force, saying so; with --force it is written, with the same note.
#[test]
fn a_pbsdf_from_one_angle_says_what_it_stands_in_for() {
    let dir = scratch("mueller-pbsdf-one");
    let (gsa, out) = (dir.join("g.gsa"), dir.join("g.pbsdf"));
    let glass = flat_substrate("mueller-pbsdf-one", 1.5, 0.0);
    run(
        &glass,
        &mueller_config(&[30.0], Wavelengths::parse("500:600:50", false).unwrap(), 4),
    )
    .write(&gsa)
    .unwrap();
    let args = |force: bool| {
        let mut v = vec![
            "export",
            gsa.to_str().unwrap(),
            "--format",
            "pbsdf",
            "-o",
            out.to_str().unwrap(),
        ];
        if force {
            v.push("--force");
        }
        v
    };
    let (code, _, err) = goniospec(&args(false));
    assert_ne!(code, 0);
    assert!(
        err.contains(
            "the one simulated incident angle, 30 deg, stands in for every incident angle"
        ) && err.contains("--force"),
        "{err}"
    );
    assert!(!out.exists());
    let (code, _, err) = goniospec(&args(true));
    assert_eq!(code, 0, "{err}");
    assert!(
        err.contains("note: the one simulated incident angle"),
        "{err}"
    );
    assert!(out.is_file());
}

/// Reciprocity of the Mueller BRDF. For fixed polarisation vectors, reversing a path
/// transposes its Jones matrix (Saxon 1955); the s/p frames of a reversed direction keep p
/// and flip s (`s(-w) = -s(w)`), so the reversed matrix is `diag(1, -1) J^T diag(1, -1)`
/// and, in Mueller form, `P M^T P` with `P = diag(1, 1, -1, 1)` (checked here on a Jones
/// matrix first). Rough gold at 25 and 40 deg (azimuth 2.5 deg, so that buckets of 5 deg
/// are centred on the plane of incidence: a bucket off it reverses into its mirror image): the matrix from 25 into 40 against the one from 40 into 25, transposed,
/// normalised elements within 4 standard errors and what each bucket's 1 x 5 deg average
/// may change (0.01).
#[test]
fn the_mueller_brdf_is_reciprocal() {
    let p = [1.0, 1.0, -1.0, 1.0];
    let j = [
        [C::new(0.3, 0.1), C::new(-0.2, 0.05)],
        [C::new(0.07, -0.3), C::new(-0.6, 0.2)],
    ];
    let jt = [[j[0][0], -j[1][0]], [-j[0][1], j[1][1]]];
    let (m, mt) = (mueller_from_states(j), mueller_from_states(jt));
    for a in 0..4 {
        for b in 0..4 {
            assert!((mt[4 * a + b] - p[a] * m[4 * b + a] * p[b]).abs() < 1e-14);
        }
    }
    let s = shipped("rough-gold.toml");
    let buckets = goniospec::accumulate::Buckets {
        theta_bins: 90,
        phi_bins: 72,
    };
    let cfg = SimConfig {
        buckets,
        phi_i_deg: 2.5,
        ..mueller_config(
            &[25.0, 40.0],
            Wavelengths::Monochromatic(vec![548.6]),
            262144,
        )
    };
    let acc = run(&s, &cfg);
    let at = |i: usize, theta_o: f64| {
        let k = buckets.index(goniospec::geom::from_spherical(
            theta_o.to_radians(),
            182.5f64.to_radians(),
        ));
        let c = acc.cell(i, 0);
        let w = buckets.projected_solid_angle(k);
        let m = c.mueller(2 * k).unwrap().map(|x| x / w);
        let e = c.mueller_stderr(2 * k).unwrap().map(|x| x / w);
        (m, e)
    };
    let (fwd, fe) = at(0, 40.5);
    let (rev, re) = at(1, 25.5);
    let mut worst: f64 = 0.0;
    for a in 0..4 {
        for b in 0..4 {
            let g = fwd[4 * a + b] / fwd[0];
            let w = p[a] * rev[4 * b + a] * p[b] / rev[0];
            let sigma = fe[4 * a + b] / fwd[0] + re[4 * b + a] / rev[0];
            eprintln!("m{a}{b}: {g:.4} against {w:.4} (+- {sigma:.4})");
            worst = worst.max((g - w).abs() / (0.01 + 4.0 * sigma));
            assert!(
                (g - w).abs() <= 0.01 + 4.0 * sigma,
                "m{a}{b}: {g} against {w}"
            );
        }
    }
    eprintln!(
        "m00: {:.4e} against {:.4e}; worst {worst:.2} of the tolerance",
        fwd[0], rev[0]
    );
}
