//! Light from several azimuths (`--phi-i A,B,...`): each direction lit from its own
//! azimuth, held to a closed form; runs at other azimuths joined by `merge`; `build`
//! keeping a grating anisotropic; `batch` giving the bytes of one run.

mod common;

use common::*;
use goniospec::sample::generate;
use goniospec::simulate::Wavelengths;
use num_complex::Complex64 as C;

type V = [f64; 3];

fn dot(a: V, b: V) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: V, b: V) -> V {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn unit(a: V) -> V {
    let l = dot(a, a).sqrt();
    [a[0] / l, a[1] / l, a[2] / l]
}

fn reflect(d: V, n: V) -> V {
    let k = 2.0 * dot(d, n);
    [d[0] - k * n[0], d[1] - k * n[1], d[2] - k * n[2]]
}

/// A complex field (three components) reflected by the facet of normal `n` from the
/// metal of index `m` (air above): decomposed on `s = d x n / |d x n|` and `p = s x d`,
/// leaving as `r_s E_s s + r_p E_p p'` with `p' = s x d'` (Born & Wolf §1.5.2; with
/// `fresnel_amplitudes`' sign of `r_p` this is the image field `2 (E.n) n - E` of a
/// perfect conductor, checked below).
fn reflect_field(e: [C; 3], d: V, n: V, m: C) -> ([C; 3], V) {
    let cos_i = -dot(d, n);
    let (rp, rs) = fresnel_amplitudes(C::new(1.0, 0.0), m, cos_i.acos());
    let s = unit(cross(d, n));
    let p = cross(s, d);
    let d2 = reflect(d, n);
    let p2 = cross(s, d2);
    let proj = |v: V| e[0] * v[0] + e[1] * v[1] + e[2] * v[2];
    let (es, ep) = (proj(s), proj(p));
    let out = [0, 1, 2].map(|k| rs * es * s[k] + rp * ep * p2[k]);
    (out, d2)
}

/// Unpolarised reflectance of 90-degree V-grooves along y (period `w`, ridges at `z = 0`,
/// valleys at `z = -w/2`) for light travelling along `d`, by brute force: `points`
/// entries spread evenly over one period of the ridge line, each followed in the x-z
/// cross-section (the facets do not change the y component) from facet to facet until it
/// leaves upwards, its field reflected at each facet in full polarisation; the mean of
/// `|E_out|^2` over two orthogonal polarisations in and over the entries.
fn grooves_brute_force(d: V, m: C, points: usize) -> f64 {
    let w = 2000.0;
    let h = std::f64::consts::FRAC_1_SQRT_2;
    // Left facet z = -x (x in [0, w/2]), normal (1, 0, 1)/sqrt 2; right facet z = x - w.
    // (normal, x range, the ridge it rises to).
    let facets = [
        ([h, 0.0, h], 0.0, w / 2.0, 0.0),
        ([-h, 0.0, h], w / 2.0, w, w),
    ];
    let e1 = unit(cross(d, [0.0, 0.0, 1.0]));
    let e2 = cross(e1, d);
    let mut total = 0.0;
    for k in 0..points {
        let x0 = w * (k as f64 + 0.5) / points as f64;
        for e in [e1, e2] {
            let (mut x, mut z, mut dir) = (x0, 0.0, d);
            let mut field = e.map(|v| C::new(v, 0.0));
            for _bounce in 0..8 {
                // The nearest facet ahead: a facet is the line n_x x + n_z z = c_k with
                // c = n . (a point on it).
                let mut hit: Option<(f64, V)> = None;
                for &(n, lo, hi, ridge) in &facets {
                    let c = n[0] * ridge;
                    let along = n[0] * dir[0] + n[2] * dir[2];
                    if along >= 0.0 {
                        continue;
                    }
                    let t = (c - n[0] * x - n[2] * z) / along;
                    let xh = x + t * dir[0];
                    if t > 1e-9 && (lo..=hi).contains(&xh) && hit.is_none_or(|(tb, _)| t < tb) {
                        hit = Some((t, n));
                    }
                }
                let Some((t, n)) = hit else { break };
                x += t * dir[0];
                z += t * dir[2];
                let (f, d2) = reflect_field(field, dir, n, m);
                field = f;
                dir = d2;
            }
            assert!(dir[2] > 0.0, "a path that does not leave");
            total += field.iter().map(|v| v.norm_sqr()).sum::<f64>();
        }
    }
    total / (2 * points) as f64
}

/// Aluminium-like V-grooves along y lit from 2 polar angles at 4 azimuths in one run: each
/// direction's R against the brute-force cross-section above (the facets' paths, written
/// here from vectors and Fresnel's amplitudes alone). Every tree follows one of a few
/// deterministic paths, so the run differs from the reference only by how its R2 entry
/// points split the period among them (an error of order 1/N: 4e-4 at 4,096 trees for
/// paths whose R differ by 0.3 at most) and by the ridge and valley lines: held to 1e-3.
#[test]
fn v_grooves_reflect_as_two_facets_do_from_every_azimuth() {
    // The closed form's convention: a perfect conductor gives the image field.
    let (d, n) = (unit([0.3, 0.2, -1.0]), unit([0.1, -0.4, 1.0]));
    let e = unit(cross(d, [1.0, 0.0, 0.0]));
    let (out, _) = reflect_field(e.map(|x| C::new(x, 0.0)), d, n, C::new(1e-9, 1e9));
    let image = [0, 1, 2].map(|k| 2.0 * dot(e, n) * n[k] - e[k]);
    for k in 0..3 {
        assert!((out[k].re - image[k]).abs() < 1e-6 && out[k].im.abs() < 1e-6);
    }

    let dir = scratch("azimuth-grooves");
    generate::v_grooves([20_000.0, 20_000.0], 10, 90.0, 0.0)
        .unwrap()
        .write_obj(&dir.join("v.obj"), 1.0, "v")
        .unwrap();
    let metal = C::new(1.0, 6.5);
    let s = sample_in(
        &dir,
        &format!(
            "[sample]\nname = \"metal grooves\"\nunit = \"nm\"\ntile = [20000.0, 20000.0]\n[media.air]\nn = 1.0\n[media.metal]\nn = {}\nk = {}\n[[interface]]\nmesh = \"v.obj\"\nfront = \"air\"\nback = \"metal\"\n",
            metal.re, metal.im
        ),
    );
    let (thetas, phis) = ([20.0, 40.0], [0.0, 45.0, 90.0, 210.0]);
    let cfg =
        config(&[], Wavelengths::Monochromatic(vec![550.0]), 4096).with_directions(&thetas, &phis);
    let acc = run(&s, &cfg);
    assert_eq!(acc.header.settings.theta_i_deg.len(), 8);
    let mut spread = Vec::new();
    for (k, &phi) in phis.iter().enumerate() {
        for (l, &theta) in thetas.iter().enumerate() {
            let i = acc.direction_of(theta, Some(phi)).unwrap();
            assert_eq!(i, k * thetas.len() + l, "azimuth-major order");
            let (t, p) = (f64::to_radians(theta), f64::to_radians(phi));
            let d = [-t.sin() * p.cos(), -t.sin() * p.sin(), -t.cos()];
            let expected = grooves_brute_force(d, metal, 20_000);
            let (r, _) = totals(&acc, i, 0);
            eprintln!("theta {theta} phi {phi}: R {r:.6}, brute force {expected:.6}");
            assert!(
                (r - expected).abs() < 1e-3,
                "theta {theta} phi {phi}: R {r} against {expected}"
            );
            spread.push(expected);
        }
    }
    // The azimuths light the grooves differently: the check has teeth.
    let (lo, hi) = spread
        .iter()
        .fold((1.0f64, 0.0f64), |(a, b), &x| (a.min(x), b.max(x)));
    assert!(hi - lo > 0.01, "R from {lo} to {hi}");
}

fn ok(args: &[&str]) -> String {
    let (code, out, err) = goniospec(args);
    assert_eq!(code, 0, "{args:?}: {err}");
    out
}

fn refused(args: &[&str]) -> String {
    let (code, _, err) = goniospec(args);
    assert_ne!(code, 0, "{args:?} was accepted");
    err
}

/// `simulate --phi-i 0,90` on the shipped aluminium grooves; runs at each azimuth joined
/// by `merge` hold each direction's cells as its own run had them; `build` keeps the
/// grooves anisotropic, refuses to average one azimuth unless asked, and refuses a table of
/// several; `batch` with `phi_i = [0, 90]` gives the bytes of the one run.
#[test]
fn azimuths_are_joined_kept_apart_by_build_and_batched_to_the_same_bytes() {
    let d = scratch("azimuth-cli");
    let p = |f: &str| d.join(f).display().to_string();
    // The sample named as the plan below names it: warnings quote its mesh's path.
    let grooves = root().join("meshes/v-grooves-aluminium.toml");
    let grooves = grooves.to_str().unwrap();
    let sim = |phi: &str, out: &str| {
        ok(&[
            "simulate",
            grooves,
            "--theta-i",
            "0,30",
            "--phi-i",
            phi,
            "--wavelengths",
            "400:700:100",
            "--rays",
            "1024",
            "-o",
            &p(out),
        ])
    };
    sim("0", "a.gsa");
    sim("90", "b.gsa");
    sim("0,90", "ab.gsa");
    let err = refused(&[
        "simulate",
        "meshes/v-grooves-aluminium.toml",
        "--phi-i",
        "0,360",
        "-o",
        &p("x.gsa"),
    ]);
    assert!(err.contains("listed twice"), "{err}");

    // Joined: a's directions then b's, each cell as its run wrote it.
    ok(&["merge", &p("a.gsa"), &p("b.gsa"), "-o", &p("j.gsa")]);
    let read = |f: &str| goniospec::accumulate::file::Accumulator::read(&d.join(f)).unwrap();
    let (a, b, j) = (read("a.gsa"), read("b.gsa"), read("j.gsa"));
    let s = &j.header.settings;
    assert_eq!(s.theta_i_deg, [0.0, 30.0, 0.0, 30.0]);
    assert_eq!(s.azimuths(), [0.0, 90.0]);
    assert_eq!(j.cells[..a.cells.len()], a.cells[..]);
    assert_eq!(j.cells[a.cells.len()..], b.cells[..]);
    assert_eq!(j.direction_of(30.0, Some(90.0)), Ok(3));
    let info = ok(&["info", &p("j.gsa")]);
    assert!(info.contains("[0.0, 30.0] at phi_i 90"), "{info}");
    // The same direction twice from the same seed is refused.
    let err = refused(&["merge", &p("a.gsa"), &p("ab.gsa"), "-o", &p("k.gsa")]);
    assert!(err.contains("counted twice"), "{err}");

    // build: one azimuth of grooves is refused unless asked; several stay anisotropic.
    let err = refused(&["build", &p("a.gsa"), "-o", &p("a.gsb")]);
    assert!(
        err.contains("not rotation-symmetric") && err.contains("--phi-i"),
        "{err}"
    );
    ok(&["build", &p("a.gsa"), "--isotropic", "-o", &p("a.gsb")]);
    ok(&["build", &p("ab.gsa"), "-o", &p("ab.gsb")]);
    let info = ok(&["info", &p("ab.gsb")]);
    assert!(info.contains("isotropic false"), "{info}");
    let err = refused(&["build", &p("ab.gsa"), "--repr", "table", "-o", &p("t.gsb")]);
    assert!(err.contains("holds one incident azimuth"), "{err}");
    // compare: each incidence read from its own azimuth's table. At phi_i 0 the two runs
    // hold the same trees (same seed, same direction index), so nothing differs; at 90 the
    // single-azimuth run's table, which turns with phi_i, is wrong for the grooves.
    let out = ok(&["compare", &p("ab.gsa"), &p("a.gsa")]);
    let rows: Vec<Vec<f64>> = out
        .lines()
        .filter_map(|l| {
            let v: Vec<f64> = l
                .split_whitespace()
                .filter_map(|x| x.parse().ok())
                .collect();
            (v.len() == 12).then_some(v)
        })
        .collect();
    assert!(out.contains("theta_i_deg  phi_i_deg  nodes"), "{out}");
    assert_eq!(rows.len(), 4, "{out}");
    for r in &rows {
        // theta, phi, nodes, dE mean: zero at phi 0, not at phi 90 and normal incidence.
        match (r[0], r[1]) {
            (_, 0.0) => assert_eq!(r[3], 0.0, "{out}"),
            (0.0, 90.0) => assert!(r[3] > 1.0, "{out}"),
            _ => {}
        }
    }
    // render: the anisotropic BRDF renders; --simulate, which lights one azimuth, refuses
    // the grooves before any work.
    ok(&[
        "render",
        &p("ab.gsb"),
        "-o",
        &p("ab.exr"),
        "--width",
        "16",
        "--height",
        "16",
    ]);
    let err = refused(&[
        "render",
        "--simulate",
        grooves,
        "-o",
        &p("sim.exr"),
        "--width",
        "16",
        "--height",
        "16",
    ]);
    assert!(
        err.contains("not rotation-symmetric") && !d.join("sim.gsa").exists(),
        "{err}"
    );

    // batch: the units of both azimuths merge to the one run's bytes.
    let plan = d.join("plan.toml");
    std::fs::write(
        &plan,
        format!(
            "[defaults]\ntheta_i = [0, 30]\nphi_i = [0, 90]\nwavelengths = \"400:700:100\"\nrays = 1024\nrepresentations = [\"kdtree\"]\n\n[[material]]\nsample = \"{}/meshes/v-grooves-aluminium.toml\"\nname = \"grooves\"\n",
            root().display()
        ),
    )
    .unwrap();
    let bd = p("batch");
    let out = ok(&["batch", "plan", plan.to_str().unwrap(), "-o", &bd]);
    assert!(out.contains("planned 4 units"), "{out}");
    ok(&["batch", "run", &bd]);
    ok(&["batch", "merge", &bd]);
    assert!(
        std::fs::read(d.join("batch/out/grooves.gsa")).unwrap()
            == std::fs::read(d.join("ab.gsa")).unwrap(),
        "batch against simulate --phi-i 0,90"
    );
}

/// A lossless sinusoidal grating (grooves along y, `z = A sin(2 pi x / L)`) under the
/// rigorous solver from six azimuths. The relief is mirror-symmetric in x (about a crest)
/// and in y, so light from `phi`, `180 - phi`, `180 + phi` and `-phi` must reflect alike:
/// to rounding, which the solver reaches (1e-9 here, where its convergence check compares
/// truncations to 5e-3). Off the classical mount TE and TM couple (conical diffraction),
/// so 30 degrees differs from 0 and 90; each balances R + T = 1.
#[test]
fn a_grating_reflects_alike_from_its_mirror_azimuths_under_the_rigorous_solver() {
    let s = sinusoid("azimuth-rigorous", 1000.0, 100.0, (1.5, 0.0), 256, 1);
    let mut cfg = config(&[], Wavelengths::Bins(vec![540.0, 560.0]), 64)
        .with_directions(&[30.0], &[0.0, 30.0, 90.0, 150.0, 210.0, 330.0]);
    cfg.coherence = goniospec::accumulate::Coherence::Rigorous;
    let acc = run(&s, &cfg);
    let r: Vec<f64> = (0..6)
        .map(|i| {
            let (r, t) = totals(&acc, i, 0);
            assert!(
                (r + t - 1.0).abs() < 1e-7,
                "direction {i}: R + T = {}",
                r + t
            );
            r
        })
        .collect();
    eprintln!("R at phi 0, 30, 90, 150, 210, 330: {r:?}");
    for (i, phi) in [(3, 150), (4, 210), (5, 330)] {
        assert!(
            (r[i] - r[1]).abs() < 1e-9,
            "phi {phi}: {} against {}",
            r[i],
            r[1]
        );
    }
    assert!(
        (r[1] - r[0]).abs() > 5e-4 && (r[1] - r[2]).abs() > 5e-4,
        "{r:?}"
    );
}
