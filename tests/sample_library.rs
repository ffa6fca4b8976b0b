//! The sample library against independent references: analytic microfacet distributions
//! (chi-square), requested height statistics, volume fractions, tile periodicity, published
//! optical constants, and `check` on every shipped sample.

mod common;

use std::f64::consts::PI;
use std::path::Path;

use common::{root, scratch};
use goniospec::check::{CheckOptions, check, periodicity, watertightness};
use goniospec::sample::generate::{self, Distribution, enclosed_volume};
use goniospec::sample::media::{IndexModel, load_table};
use goniospec::sample::{self, Mesh, MeshOptions};

// ---------------------------------------------------------------- microfacet chi-square

/// D(m) written independently of the library: Walter, Marschner, Li & Torrance, EGSR 2007,
/// eq. 25 (Beckmann) and eq. 33 (GGX).
fn d_ref(dist: Distribution, alpha: f64, theta: f64) -> f64 {
    let c = theta.cos();
    let t2 = theta.tan().powi(2);
    let a2 = alpha * alpha;
    match dist {
        Distribution::Beckmann => (-t2 / a2).exp() / (PI * a2 * c.powi(4)),
        Distribution::Ggx => a2 / (PI * c.powi(4) * (a2 + t2).powi(2)),
    }
}

/// Probability that the normal's polar angle lies in [t0, t1]: the integral of
/// D(m) cos(theta) over the band, by Simpson's rule.
fn band_probability(dist: Distribution, alpha: f64, t0: f64, t1: f64) -> f64 {
    let n = 2000;
    let h = (t1 - t0) / n as f64;
    let f = |t: f64| 2.0 * PI * d_ref(dist, alpha, t) * t.cos() * t.sin();
    let mut s = f(t0) + f(t1.min(PI / 2.0 - 1e-9));
    for i in 1..n {
        let t = (t0 + i as f64 * h).min(PI / 2.0 - 1e-9);
        s += if i % 2 == 1 { 4.0 } else { 2.0 } * f(t);
    }
    s * h / 3.0
}

/// Chi-square critical value at significance 1e-3 (Wilson–Hilferty approximation).
fn chi2_critical(dof: usize) -> f64 {
    let k = dof as f64;
    let z = 3.090;
    k * (1.0 - 2.0 / (9.0 * k) + z * (2.0 / (9.0 * k)).sqrt()).powi(3)
}

/// Chi-square statistic of the mesh's projected-area-weighted facet normals against
/// `expect_dist`, over 4 azimuth bins times polar bands of >= 5 % expected each.
fn facet_chi2(mesh: &Mesh, cell_area: f64, expect_dist: Distribution, alpha: f64) -> (f64, usize) {
    // Polar band edges: steps of 0.5 degree merged until each band holds >= 5 %.
    let mut edges = vec![0.0];
    let mut acc = 0.0;
    let step = 0.5f64.to_radians();
    let mut t = 0.0;
    while t < PI / 2.0 - step {
        acc += band_probability(expect_dist, alpha, t, t + step);
        t += step;
        if acc >= 0.05 {
            edges.push(t);
            acc = 0.0;
        }
    }
    *edges.last_mut().unwrap() = PI / 2.0;
    let total_p = band_probability(expect_dist, alpha, 0.0, PI / 2.0);
    assert!(
        (total_p - 1.0).abs() < 2e-3,
        "D(m) cos(theta) integrates to {total_p}"
    );
    let nb = edges.len() - 1;
    let mut observed = vec![0.0; nb * 4];
    let mut cells = 0.0;
    for i in 0..mesh.triangles.len() {
        let a = mesh.area_vector(i);
        let len = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
        if a[2] <= 1e-9 * len {
            assert!(a[2].abs() <= 1e-9 * len, "a triangle faces down: {a:?}");
            continue; // vertical walls: no projected area
        }
        let theta = (a[2] / len).acos();
        let phi = a[1].atan2(a[0]).rem_euclid(2.0 * PI);
        let b = edges.partition_point(|&e| e <= theta).clamp(1, nb) - 1;
        let q = ((phi / (PI / 2.0)) as usize).min(3);
        // Half the cross product's z is the projected area; in units of one cell.
        let w = 0.5 * a[2] / cell_area;
        observed[b * 4 + q] += w;
        cells += w;
    }
    let n = cells.round();
    let mut chi2 = 0.0;
    for b in 0..nb {
        let e = n * band_probability(expect_dist, alpha, edges[b], edges[b + 1]) / 4.0;
        for q in 0..4 {
            chi2 += (observed[b * 4 + q] - e).powi(2) / e;
        }
    }
    (chi2, nb * 4 - 1)
}

#[test]
fn microfacet_normals_follow_ggx_and_beckmann() {
    let (l, n) = (1000.0, 128usize);
    let cell_area = (l / n as f64).powi(2);
    for (dist, other) in [
        (Distribution::Ggx, Distribution::Beckmann),
        (Distribution::Beckmann, Distribution::Ggx),
    ] {
        for alpha in [0.15, 0.5] {
            let mesh =
                generate::microfacet_surface(42, [l, l], n, dist, alpha, l / 8.0, 0.0).unwrap();
            let (chi2, dof) = facet_chi2(&mesh, cell_area, dist, alpha);
            let crit = chi2_critical(dof);
            eprintln!("{dist:?} alpha {alpha}: chi2 {chi2:.1} on {dof} dof (critical {crit:.1})");
            assert!(
                chi2 < crit,
                "{dist:?} alpha {alpha}: chi2 {chi2} >= {crit} on {dof} dof"
            );
            // The test has power: the other distribution at the same alpha is rejected.
            let (wrong, dof2) = facet_chi2(&mesh, cell_area, other, alpha);
            assert!(
                wrong > chi2_critical(dof2),
                "{dist:?} alpha {alpha} not told apart from {other:?}: {wrong}"
            );
        }
    }
}

// ---------------------------------------------------------------- height statistics

/// Heights on the periodic n x n grid (dropping the repeated last row and column).
fn periodic_grid(h: &[f64], n: usize) -> Vec<f64> {
    (0..n)
        .flat_map(|j| (0..n).map(move |i| h[j * (n + 1) + i]))
        .collect()
}

/// Lag (in grid steps, interpolated) where the normalised periodic autocorrelation along
/// one axis falls to 1/e.
fn correlation_lag(g: &[f64], n: usize, along_x: bool) -> f64 {
    let mean = g.iter().sum::<f64>() / g.len() as f64;
    let c = |k: usize| {
        let mut s = 0.0;
        for j in 0..n {
            for i in 0..n {
                let (i2, j2) = if along_x {
                    ((i + k) % n, j)
                } else {
                    (i, (j + k) % n)
                };
                s += (g[j * n + i] - mean) * (g[j2 * n + i2] - mean);
            }
        }
        s / (n * n) as f64
    };
    let c0 = c(0);
    let target = (-1.0f64).exp();
    let mut prev = 1.0;
    for k in 1..n / 2 {
        let ck = c(k) / c0;
        if ck <= target {
            return (k - 1) as f64 + (prev - target) / (prev - ck);
        }
        prev = ck;
    }
    panic!("autocorrelation never fell to 1/e");
}

#[test]
fn gaussian_height_field_has_the_requested_rms_and_correlation_length() {
    let (l, n) = (20_000.0, 256usize);
    for (seed, rms, corr) in [(1u64, 100.0, 1000.0), (2, 35.0, 1500.0)] {
        let h = generate::gaussian_heights(seed, [l, l], n, rms, corr).unwrap();
        let g = periodic_grid(&h, n);
        let mean = g.iter().sum::<f64>() / g.len() as f64;
        let got_rms = (g.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / g.len() as f64).sqrt();
        assert!((got_rms / rms - 1.0).abs() < 0.05, "rms {got_rms} vs {rms}");
        let dx = l / n as f64;
        for along_x in [true, false] {
            let lc = correlation_lag(&g, n, along_x) * dx;
            assert!(
                (lc / corr - 1.0).abs() < 0.05,
                "correlation length {lc} vs {corr} (x: {along_x})"
            );
        }
    }
}

#[test]
fn wavy_film_has_the_requested_mean_thickness() {
    use generate::{Generated, GeneratorSpec};
    let tile = [20_000.0, 20_000.0];
    let spec = |top: bool| {
        let s = if top { "top" } else { "bottom" };
        toml::from_str::<GeneratorSpec>(&format!(
            "kind = \"wavy-film\"\nsurface = \"{s}\"\nthickness = 600.0\nthickness_rms = 30.0\nroughness_rms = 150.0\ncorrelation_length = 2000.0\nresolution = 64\nseed = 7"
        ))
        .unwrap()
    };
    let get = |top| match spec(top).generate(tile, 1.0).unwrap() {
        Generated::Sheet(m) => m,
        _ => panic!("a sheet"),
    };
    let (t, b) = (get(true), get(false));
    let n = 64;
    let th: Vec<f64> = (0..n * n)
        .map(|k| {
            let idx = (k / n) * (n + 1) + k % n;
            t.positions_nm[idx][2] - b.positions_nm[idx][2]
        })
        .collect();
    let mean = th.iter().sum::<f64>() / th.len() as f64;
    let rms = (th.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / th.len() as f64).sqrt();
    assert!((mean - 600.0).abs() < 1e-6, "mean thickness {mean}");
    assert!((rms / 30.0 - 1.0).abs() < 0.05, "thickness rms {rms}");
    assert!(th.iter().all(|&v| v > 0.0));
}

// ---------------------------------------------------------------- bodies

#[test]
fn pigment_spheres_have_the_volume_fraction_and_never_overlap() {
    let tile = [5000.0, 5000.0];
    let layer = [100.0, 2900.0];
    for (fraction, subdiv) in [(0.1, 2), (0.25, 1)] {
        let spheres = generate::pigment_spheres(3, tile, 150.0, fraction, layer, subdiv).unwrap();
        let v: f64 = spheres.iter().map(enclosed_volume).sum();
        let got = v / (tile[0] * tile[1] * (layer[1] - layer[0]));
        assert!(
            (got / fraction - 1.0).abs() < 0.02,
            "volume fraction {got} vs {fraction}"
        );
        // Centres and circumscribed radii measured from the meshes themselves.
        let geo: Vec<([f64; 3], f64)> = spheres
            .iter()
            .map(|m| {
                let n = m.positions_nm.len() as f64;
                let c = [0, 1, 2].map(|k| m.positions_nm.iter().map(|p| p[k]).sum::<f64>() / n);
                let r = m
                    .positions_nm
                    .iter()
                    .map(|p| {
                        ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2))
                            .sqrt()
                    })
                    .fold(0.0, f64::max);
                (c, r)
            })
            .collect();
        for (i, (a, ra)) in geo.iter().enumerate() {
            assert!(
                a[0] - ra >= 0.0
                    && a[0] + ra <= tile[0]
                    && a[1] - ra >= 0.0
                    && a[1] + ra <= tile[1]
            );
            assert!(
                a[2] - ra >= layer[0] && a[2] + ra <= layer[1],
                "sphere {i} leaves the layer"
            );
            for (b, rb) in &geo[i + 1..] {
                let d =
                    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
                assert!(d >= ra + rb, "spheres overlap: {d} < {}", ra + rb);
            }
        }
        for m in &spheres {
            assert_eq!(watertightness(m), Default::default());
        }
    }
}

#[test]
fn flakes_are_closed_and_coated() {
    let out = generate::flakes(
        5,
        [40_000.0, 40_000.0],
        8000.0,
        400.0,
        8.0,
        120.0,
        0.03,
        [200.0, 9800.0],
    )
    .unwrap();
    assert!(out.len() >= 10);
    for (core, shell) in &out {
        assert_eq!(watertightness(core), Default::default());
        let shell = shell.as_ref().expect("coated");
        assert_eq!(watertightness(shell), Default::default());
        let (vc, vs) = (enclosed_volume(core), enclosed_volume(shell));
        assert!(
            (vc - 8000.0 * 8000.0 * 400.0).abs() < 1e-6 * vc,
            "core volume {vc}"
        );
        assert!(
            (vs - 8240.0 * 8240.0 * 640.0).abs() < 1e-6 * vs,
            "shell volume {vs}"
        );
    }
}

// ---------------------------------------------------------------- periodicity

#[test]
fn every_generated_sheet_tiles() {
    let tile = [2000.0, 1500.0];
    let tol = 1e-6 * 2000.0;
    let h = generate::gaussian_heights(9, tile, 64, 40.0, 200.0).unwrap();
    let sheets = vec![
        ("flat", generate::flat(tile, 5.0)),
        ("gaussian", generate::grid_mesh(tile, 64, &h, 0.0)),
        (
            "ggx",
            generate::microfacet_surface(1, tile, 64, Distribution::Ggx, 0.6, 200.0, 0.0).unwrap(),
        ),
        (
            "beckmann",
            generate::microfacet_surface(2, tile, 64, Distribution::Beckmann, 0.3, 200.0, 0.0)
                .unwrap(),
        ),
        (
            "v-grooves",
            generate::v_grooves(tile, 7, 60.0, 0.0).unwrap(),
        ),
        (
            "cosine",
            generate::height_field([9, 5], tile, generate::cosine_surface(4, tile, 30.0, 8, 3)),
        ),
    ];
    for (name, m) in &sheets {
        let p = periodicity(m, tile, tol);
        assert_eq!(p.interior_boundary_edges, 0, "{name} has holes");
        assert_eq!(p.unmatched, 0, "{name} does not tile");
    }
    // The check can fail: lift one vertex on the x = Lx side and the sides no longer match.
    let mut bent = generate::height_field([4, 4], tile, |_, _| 0.0);
    let v = bent
        .positions_nm
        .iter()
        .position(|p| p[0] == tile[0] && p[1] > 0.0 && p[1] < tile[1])
        .unwrap();
    bent.positions_nm[v][2] += 10.0;
    assert!(periodicity(&bent, tile, tol).unmatched > 0);
    // ... and a hole is seen.
    let mut holed = generate::flat(tile, 0.0);
    holed.append(&generate::height_field([4, 4], tile, |_, _| 1.0));
    holed.triangles.remove(20);
    assert!(periodicity(&holed, tile, tol).interior_boundary_edges > 0);
}

// ---------------------------------------------------------------- optical constants

#[test]
fn index_models_reproduce_published_values() {
    let silica =
        sample::media::load_model_file(&root().join("data/fused-silica-malitson.toml")).unwrap();
    let (n, k) = silica.eval(587.6).unwrap();
    assert!((n - 1.45846).abs() < 1e-5, "fused silica n(587.6 nm) = {n}");
    assert_eq!(k, 0.0);
    assert!(
        silica.eval(5000.0).is_err(),
        "outside Malitson's 0.21-3.71 um"
    );

    let gold = load_table(&root().join("data/au-johnson.csv")).unwrap();
    let (n, k) = gold.eval(548.6).unwrap();
    assert!(
        (n - 0.43).abs() < 1e-12 && (k - 2.455).abs() < 1e-12,
        "gold at 548.6 nm: {n} + {k}i"
    );
    let e = gold.eval(100.0).unwrap_err().to_string();
    assert!(e.contains("100 nm is outside the range 187.9..1937"), "{e}");

    // Linear interpolation half way between the 548.6 and 582.1 nm rows (0.29, 2.863).
    let (n, k) = gold.eval((548.6 + 582.1) / 2.0).unwrap();
    assert!(
        (n - 0.36).abs() < 1e-9 && (k - 2.659).abs() < 1e-9,
        "{n} {k}"
    );

    let mgf2 = sample::media::load_model_file(&root().join("data/mgf2-dodge.toml")).unwrap();
    let (n, _) = mgf2.eval(550.0).unwrap();
    assert!((n - 1.3786).abs() < 5e-4, "MgF2 n(550) = {n}");

    let water =
        sample::media::load_model_file(&root().join("data/soap-film-water-daimon.toml")).unwrap();
    let (n, _) = water.eval(589.3).unwrap();
    assert!((n - 1.3330).abs() < 5e-4, "water n(589.3) = {n}");

    let cauchy = IndexModel::Cauchy {
        a: 1.5,
        b_nm2: 4200.0,
        c_nm4: 0.0,
        range_nm: [400.0, 800.0],
    };
    assert_eq!(cauchy.eval(600.0).unwrap().0, 1.5 + 4200.0 / 360000.0);
    assert!(cauchy.eval(399.0).is_err() && cauchy.eval(801.0).is_err());
    assert!(cauchy.is_dispersive() && !IndexModel::Constant { n: 1.0, k: 0.0 }.is_dispersive());
}

#[test]
fn every_shipped_data_file_loads() {
    for e in std::fs::read_dir(root().join("data")).unwrap() {
        let p = e.unwrap().path();
        let m = match p.extension().and_then(|e| e.to_str()) {
            Some("csv") => load_table(&p),
            Some("toml") => sample::media::load_model_file(&p),
            _ => continue,
        }
        .unwrap_or_else(|e| panic!("{}: {e:?}", p.display()));
        let [lo, hi] = m.range_nm().unwrap();
        assert!(
            lo <= 400.0 && hi >= 700.0,
            "{} does not cover the visible: {lo}..{hi}",
            p.display()
        );
        let text = std::fs::read_to_string(&p).unwrap();
        let header: Vec<&str> = text.lines().take_while(|l| l.starts_with('#')).collect();
        assert!(
            header.iter().any(|l| l.contains("Source:")),
            "{} must name its source in a header comment",
            p.display()
        );
    }
}

#[test]
fn malformed_tables_are_refused_with_their_line() {
    let d = scratch("tables");
    let cases = [
        (
            "unsorted",
            "# x\nlambda_nm,n,k\n400,1.5,0\n500,1.5,0\n450,1.5,0\n",
            "must be sorted strictly increasing",
            Some(5),
        ),
        (
            "missing-col",
            "lambda_nm,n\n400,1.5\n",
            "missing column k",
            Some(1),
        ),
        (
            "short-row",
            "lambda_nm,n,k\n400,1.5,0\n500,1.5\n",
            "missing column k",
            Some(3),
        ),
        (
            "negative-k",
            "lambda_nm,n,k\n400,1.5,0\n500,1.5,-0.1\n",
            "k must be >= 0",
            Some(3),
        ),
        (
            "nan",
            "lambda_nm,n,k\n400,abc,0\n500,1.5,0\n",
            "n is not a finite number",
            Some(2),
        ),
        (
            // A file that is not a table: its content is never quoted back.
            "not-a-table",
            "root:secret:20228:0\n",
            "missing column lambda_nm, n, k",
            Some(1),
        ),
        (
            // Lone CR line endings are line ends (the error is on the third line).
            "cr-endings",
            "lambda_nm,n,k\r400,1.5,0\r300,1.5,0\r",
            "sorted strictly increasing",
            Some(3),
        ),
        (
            "one-row",
            "lambda_nm,n,k\n400,1.5,0\n",
            "at least 2 rows",
            None,
        ),
    ];
    for (tag, text, msg, line) in cases {
        let p = d.join(format!("{tag}.csv"));
        std::fs::write(&p, text).unwrap();
        let e = load_table(&p).unwrap_err();
        assert!(e.message.contains(msg), "{tag}: {e:?}");
        assert!(
            !e.message.contains("secret"),
            "{tag}: file content echoed: {e:?}"
        );
        let (file, l) = e.file.clone().unwrap();
        assert_eq!(file, p);
        assert_eq!(l, line, "{tag}: {e:?}");
    }
    // A UTF-8 byte-order mark (as spreadsheet programs write) is not part of the header.
    std::fs::write(
        d.join("bom.csv"),
        "\u{feff}lambda_nm,n,k\r\n400,1.5,0.1\r\n500,1.7,0.3\r\n",
    )
    .unwrap();
    let m = load_table(&d.join("bom.csv")).expect("a table with a byte-order mark loads");
    // Linear interpolation halfway between the rows.
    let (n, k) = m.eval(450.0).unwrap();
    assert!(
        (n - 1.6).abs() < 1e-12 && (k - 0.2).abs() < 1e-12,
        "{n} {k}"
    );
    // Through a sample: the error names the table file and line.
    std::fs::write(d.join("bad.csv"), "lambda_nm,n,k\n400,1.5,0\n300,1.5,0\n").unwrap();
    std::fs::write(
        d.join("s.toml"),
        "[sample]\nname = \"x\"\nunit = \"nm\"\ntile = [10.0, 10.0]\n[media.air]\nn = 1.0\n[media.m]\ntable = \"bad.csv\"\n[stack]\nambient = \"air\"\nlayers = []\nsubstrate = \"m\"\n",
    )
    .unwrap();
    let e = sample::load(&d.join("s.toml"), MeshOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("s.toml:7:") && e.contains("bad.csv:3:") && e.contains("sorted"),
        "{e}"
    );
}

#[test]
fn medium_definitions_need_exactly_one_model() {
    let d = scratch("media");
    let load = |media: &str| {
        std::fs::write(
            d.join("s.toml"),
            format!("[sample]\nname = \"x\"\nunit = \"nm\"\ntile = [10.0, 10.0]\n[media.air]\nn = 1.0\n[media.m]\n{media}\n[stack]\nambient = \"air\"\nlayers = []\nsubstrate = \"m\"\n"),
        )
        .unwrap();
        sample::load(&d.join("s.toml"), MeshOptions::default())
    };
    let e = load("n = 1.5\ncauchy = { a = 1.5 }")
        .unwrap_err()
        .to_string();
    assert!(e.contains("several index models (n, cauchy)"), "{e}");
    let e = load("k = 0.1").unwrap_err().to_string();
    assert!(e.contains("needs one index model"), "{e}");
    let e = load("cauchy = { a = -3.0, b_nm2 = 10.0 }")
        .unwrap_err()
        .to_string();
    assert!(e.contains("gives n = "), "{e}");
    let e = load("sellmeier = { b = [1.0], c_um2 = [] }")
        .unwrap_err()
        .to_string();
    assert!(e.contains("as many b as c_um2"), "{e}");
    let s = load("cauchy = { a = 1.45, b_nm2 = 3540.0 }\nrange_nm = [400.0, 700.0]").unwrap();
    assert_eq!(s.media[1].model.range_nm(), Some([400.0, 700.0]));
}

// ---------------------------------------------------------------- stack and generators in samples

#[test]
fn a_stack_generates_its_planar_interfaces() {
    let path = root().join("meshes/ar-coating.toml");
    // Default: one flat interface carrying the layer as a coating.
    let s = sample::load(&path, MeshOptions::default()).unwrap();
    let name = |i: usize| s.media[i].name.as_str();
    assert_eq!(s.interfaces.len(), 1);
    let itf = &s.interfaces[0];
    assert_eq!((name(itf.front), name(itf.back)), ("air", "glass"));
    assert_eq!(itf.coating.len(), 1);
    assert_eq!(name(itf.coating[0].0), "mgf2");
    assert!((itf.coating[0].1 - 99.6).abs() < 1e-12);
    // `mode = "mesh"`: every layer boundary is a flat mesh.
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace("[stack]", "[stack]\nmode = \"mesh\"");
    let s = sample::parse(&path, &text, MeshOptions::default()).unwrap();
    let st = s.stack.as_ref().unwrap();
    assert_eq!(st.layers.len(), 1);
    assert!((st.layers[0].1 - 99.6).abs() < 1e-12);
    assert_eq!(s.interfaces.len(), 2);
    let name = |i: usize| s.media[i].name.as_str();
    let top = &s.interfaces[0];
    assert_eq!((name(top.front), name(top.back)), ("air", "mgf2"));
    assert!(
        top.mesh
            .positions_nm
            .iter()
            .all(|p| (p[2] - 99.6).abs() < 1e-12)
    );
    let bottom = &s.interfaces[1];
    assert_eq!((name(bottom.front), name(bottom.back)), ("mgf2", "glass"));
    assert!(bottom.mesh.positions_nm.iter().all(|p| p[2] == 0.0));
    assert_eq!(top.mesh.triangles.len(), 2);
    assert_eq!(
        top.mesh.bounds().unwrap().1,
        glam::DVec3::new(20_000.0, 20_000.0, 99.6)
    );
}

#[test]
fn generators_run_from_a_sample_toml() {
    let d = scratch("gen");
    std::fs::write(
        d.join("s.toml"),
        r#"[sample]
name = "generated"
unit = "um"
tile = [5.0, 5.0]
[media.air]
n = 1.0
[media.glass]
n = 1.5
[media.tio2]
n = 2.6
[[interface]]
generator = { kind = "gaussian", rms = 0.05, correlation_length = 0.5, resolution = 48, z = 3.0 }
front = "air"
back = "glass"
[[interface]]
generator = { kind = "flat", z = 0.0 }
front = "glass"
back = "air"
[[body]]
generator = { kind = "pigment-spheres", radius = 0.2, volume_fraction = 0.05, layer = [0.5, 2.5], subdivisions = 1 }
inside = "tio2"
outside = "glass"
"#,
    )
    .unwrap();
    let s = sample::load(&d.join("s.toml"), MeshOptions::default()).unwrap();
    assert!(s.interfaces.len() > 3);
    assert!(s.interfaces[2..].iter().all(|i| i.closed));
    assert_leak_free(&s, 3000, "flakes");

    // A sheet generator in [[body]] is refused, with the line.
    let t = std::fs::read_to_string(d.join("s.toml")).unwrap().replace("kind = \"pigment-spheres\", radius = 0.2, volume_fraction = 0.05, layer = [0.5, 2.5], subdivisions = 1", "kind = \"flat\"");
    std::fs::write(d.join("s2.toml"), t).unwrap();
    let e = sample::load(&d.join("s2.toml"), MeshOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("s2.toml:20:") && e.contains("makes a sheet, so it belongs in [[interface]]"),
        "{e}"
    );
    // An unknown generator parameter names the line.
    let t = std::fs::read_to_string(d.join("s.toml"))
        .unwrap()
        .replace("rms = 0.05", "rms = 0.05, wobble = 2");
    std::fs::write(d.join("s3.toml"), t).unwrap();
    let e = sample::load(&d.join("s3.toml"), MeshOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("s3.toml:12:") && e.contains("unknown field `wobble`"),
        "{e}"
    );
}

// ---------------------------------------------------------------- check

/// Runs `check` with `rays` leak-test walks and asserts no defect, no leak, and that the
/// walks crossed the interfaces at least `rays` times (the test had something to test).
fn assert_leak_free(s: &sample::Sample, rays: usize, what: &str) {
    let r = check(
        s,
        &CheckOptions {
            leak_rays: rays,
            ..Default::default()
        },
    )
    .unwrap();
    assert!(r.defects.is_empty(), "{what}: {:?}", r.defects);
    assert_eq!(r.leak.leaks, 0, "{what}: leaks");
    assert!(
        r.leak.crossings >= rays,
        "{what}: the leak test crossed too little"
    );
}

#[test]
fn every_shipped_sample_passes_check_with_zero_leaks() {
    let mut n = 0;
    for e in std::fs::read_dir(root().join("meshes")).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_none_or(|x| x != "toml") {
            continue;
        }
        let s = sample::load(&p, MeshOptions::default()).unwrap_or_else(|e| panic!("{e}"));
        assert_leak_free(&s, 4000, &p.display().to_string());
        n += 1;
    }
    assert!(n >= 6);
}

fn write_sample(d: &Path, body: &str, objs: &[(&str, &Mesh)]) -> sample::Sample {
    for (name, m) in objs {
        m.write_obj(&d.join(name), 1.0, "test").unwrap();
    }
    std::fs::write(
        d.join("s.toml"),
        format!("[sample]\nname = \"t\"\nunit = \"nm\"\ntile = [1000.0, 1000.0]\n[media.air]\nn = 1.0\n[media.glass]\nn = 1.5\n[media.tio2]\nn = 2.6\n{body}"),
    )
    .unwrap();
    sample::load(&d.join("s.toml"), MeshOptions::default()).unwrap()
}

#[test]
fn check_finds_defects() {
    let opts = CheckOptions {
        leak_rays: 3000,
        ..Default::default()
    };
    let tile = [1000.0, 1000.0];
    let top = generate::flat(tile, 500.0);
    let bottom = generate::flat(tile, 0.0);
    let sphere = |c: glam::DVec3, r: f64| {
        let mut m = generate::icosphere(2);
        for p in &mut m.positions_nm {
            *p = c + *p * r;
        }
        m
    };
    let sheets = "[[interface]]\nmesh = \"top.obj\"\nfront = \"air\"\nback = \"glass\"\n[[interface]]\nmesh = \"bottom.obj\"\nfront = \"glass\"\nback = \"air\"\n";

    // Overlapping bodies.
    let d = scratch("overlap");
    let mut two = sphere(glam::DVec3::new(400.0, 500.0, 330.0), 100.0);
    two.append(&sphere(glam::DVec3::new(520.0, 500.0, 250.0), 100.0));
    let s = write_sample(
        &d,
        &format!("{sheets}[[body]]\nmesh = \"two.obj\"\ninside = \"tio2\"\noutside = \"glass\"\n"),
        &[
            ("top.obj", &top),
            ("bottom.obj", &bottom),
            ("two.obj", &two),
        ],
    );
    let r = check(&s, &opts).unwrap();
    assert!(
        r.defects.iter().any(|d| d.contains("leaks")),
        "{:?}",
        r.defects
    );

    // Two separate overlapping bodies are reported as intersecting interfaces.
    let d = scratch("overlap2");
    let body =
        |f: &str| format!("[[body]]\nmesh = \"{f}\"\ninside = \"tio2\"\noutside = \"glass\"\n");
    let s = write_sample(
        &d,
        &format!("{sheets}{}{}", body("a.obj"), body("b.obj")),
        &[
            ("top.obj", &top),
            ("bottom.obj", &bottom),
            (
                "a.obj",
                &sphere(glam::DVec3::new(400.0, 500.0, 250.0), 100.0),
            ),
            (
                "b.obj",
                &sphere(glam::DVec3::new(520.0, 500.0, 250.0), 100.0),
            ),
        ],
    );
    let r = check(&s, &opts).unwrap();
    assert!(
        r.defects
            .iter()
            .any(|d| d.contains("interfaces 2 and 3 intersect")),
        "{:?}",
        r.defects
    );

    // A sphere poking through the top sheet.
    let d = scratch("poke");
    let s = write_sample(
        &d,
        &format!("{sheets}{}", body("p.obj")),
        &[
            ("top.obj", &top),
            ("bottom.obj", &bottom),
            (
                "p.obj",
                &sphere(glam::DVec3::new(500.0, 500.0, 480.0), 100.0),
            ),
        ],
    );
    let r = check(&s, &opts).unwrap();
    assert!(
        r.defects
            .iter()
            .any(|d| d.contains("interfaces 0 and 2 intersect")),
        "{:?}",
        r.defects
    );

    // A sheet whose normals point down.
    let d = scratch("flipped");
    let mut flipped = generate::flat(tile, 500.0);
    for t in &mut flipped.triangles {
        t.swap(1, 2);
    }
    let s = write_sample(
        &d,
        sheets,
        &[("top.obj", &flipped), ("bottom.obj", &bottom)],
    );
    let r = check(&s, &opts).unwrap();
    assert!(
        r.defects.iter().any(|d| d.contains("normals point down")),
        "{:?}",
        r.defects
    );
    assert!(
        r.defects.iter().any(|d| d.contains("leaks")),
        "{:?}",
        r.defects
    );

    // An open body.
    let d = scratch("open");
    let mut open = sphere(glam::DVec3::new(500.0, 500.0, 250.0), 100.0);
    open.triangles.pop();
    let s = write_sample(
        &d,
        &format!("{sheets}{}", body("o.obj")),
        &[("top.obj", &top), ("bottom.obj", &bottom), ("o.obj", &open)],
    );
    let r = check(&s, &opts).unwrap();
    assert!(
        r.defects
            .iter()
            .any(|d| d.contains("not watertight: 3 open edges")),
        "{:?}",
        r.defects
    );

    // A sheet with a hole, and one that does not reach across the tile.
    let d = scratch("hole");
    let mut holed = generate::height_field([4, 4], tile, |_, _| 500.0);
    holed.triangles.remove(7);
    let s = write_sample(&d, sheets, &[("top.obj", &holed), ("bottom.obj", &bottom)]);
    let r = check(&s, &opts).unwrap();
    assert!(
        r.defects
            .iter()
            .any(|d| d.contains("boundary edges inside the tile")),
        "{:?}",
        r.defects
    );
}

#[test]
fn the_leak_test_counts_crossings_from_the_wrong_medium() {
    // Media that do not chain: air|glass above, then tio2|air below (the ray arrives in
    // glass at an interface whose upper side is tio2).
    let d = scratch("chain");
    let tile = [1000.0, 1000.0];
    let s = write_sample(
        &d,
        "[[interface]]\nmesh = \"top.obj\"\nfront = \"air\"\nback = \"glass\"\n[[interface]]\nmesh = \"bottom.obj\"\nfront = \"tio2\"\nback = \"air\"\n",
        &[
            ("top.obj", &generate::flat(tile, 500.0)),
            ("bottom.obj", &generate::flat(tile, 0.0)),
        ],
    );
    let r = check(
        &s,
        &CheckOptions {
            leak_rays: 2000,
            ..Default::default()
        },
    )
    .unwrap();
    assert!(r.leak.leaks > 100, "{:?}", r.leak);
}

#[test]
fn generated_microfacet_height_fields_pass_check_with_zero_leaks() {
    // The steep cases: walled facet grids leaked here (5 leaks in `check` on GGX alpha 0.5).
    let d = std::env::temp_dir().join(format!("goniospec-mf-leaks-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    for (dist, name) in [
        (Distribution::Ggx, "ggx"),
        (Distribution::Beckmann, "beckmann"),
    ] {
        for alpha in [0.2, 0.5] {
            let m = generate::microfacet_surface(
                7,
                [20_000.0, 20_000.0],
                160,
                dist,
                alpha,
                2500.0,
                0.0,
            )
            .unwrap();
            m.write_obj(&d.join("mf.obj"), 1.0, "mf").unwrap();
            std::fs::write(
                d.join("mf.toml"),
                "[sample]\nname = \"mf\"\nunit = \"nm\"\ntile = [20000.0, 20000.0]\n[media.air]\nn = 1.0\n[media.gold]\nn = 0.43\nk = 2.455\n[[interface]]\nmesh = \"mf.obj\"\nfront = \"air\"\nback = \"gold\"\n",
            )
            .unwrap();
            let s = sample::load(&d.join("mf.toml"), MeshOptions::default()).unwrap();
            assert_leak_free(&s, 4000, &format!("{name} {alpha}"));
        }
    }
}

/// The sample hash (what merges compare) covers the physics, not how it was written down:
/// the same table under another file name hashes the same, other rows do not.
#[test]
fn the_sample_hash_covers_physics_not_file_names() {
    use goniospec::simulate::sample_hash;
    let d = scratch("hash");
    let rows = "lambda_nm,n,k\n400,1.5,0\n800,1.4,0\n";
    std::fs::write(d.join("a.csv"), rows).unwrap();
    std::fs::write(d.join("b.csv"), rows).unwrap();
    std::fs::write(d.join("c.csv"), rows.replace("1.4,0", "1.41,0")).unwrap();
    let hash = |table: &str| {
        std::fs::write(
            d.join("s.toml"),
            format!("[sample]\nname = \"x\"\nunit = \"nm\"\ntile = [10.0, 10.0]\n[media.air]\nn = 1.0\n[media.m]\ntable = \"{table}\"\n[stack]\nambient = \"air\"\nlayers = []\nsubstrate = \"m\"\n"),
        )
        .unwrap();
        sample_hash(&sample::load(&d.join("s.toml"), MeshOptions::default()).unwrap())
    };
    assert_eq!(hash("a.csv"), hash("b.csv"));
    assert_ne!(hash("a.csv"), hash("c.csv"));
}
