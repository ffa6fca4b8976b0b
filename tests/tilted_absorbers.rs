//! Thin absorbing films whose faces are not parallel, against the transfer-matrix method
//! averaged over the local thickness (written here, independent of the tracer).
//!
//! A 20 nm-class gold film on glass: flat top, back face a periodic roof tilted by
//! `alpha`, so the local thickness is `t(x) = t_max - tan(alpha) |x - L/2|` (`Roof`). The film is far
//! thinner than the wavelength, so its local reflectance is the flat film's at the local
//! thickness (the tangent-plane or local-film model): the ray series of one point recombines
//! within the beamlet, and the reflectance averaged over the tile is the average of
//! `R_TMM(t(x))` over x, for light entering at uniformly spread points (the tracer's entry
//! points are a low-discrepancy sequence over the tile). Before issue 25 the tracer
//! flux-normalised every event at a facet more than 1e-6 rad off the wave's entry facet:
//! R 0.80 against 0.405 at a tilt of 1e-4 degrees.

mod common;

use common::*;
use goniospec::simulate::Wavelengths;
use num_complex::Complex64 as C;

/// Gold (Johnson & Christy 1972, as in data/au-johnson.csv) at three wavelengths, as
/// constant indices so the reference can use the same numbers.
const GOLD: [(f64, f64, f64); 3] = [
    (450.0, 1.38, 1.92),
    (550.0, 0.43, 2.455),
    (650.0, 0.166, 3.15),
];
const GLASS: f64 = 1.5;
/// Writes `GOLD` as the media table `gold.csv` in `dir`.
fn write_gold_table(dir: &std::path::Path) {
    let table: String = GOLD
        .iter()
        .map(|(w, n, k)| format!("{w},{n},{k}\n"))
        .collect();
    std::fs::write(dir.join("gold.csv"), format!("lambda_nm,n,k\n{table}")).unwrap();
}

/// A gold roof on glass: flat top at z = 0, back face tilted by `tilt_deg` either way of
/// the ridge line, where the film is `t_max` nm thick, down to `t_max - rise` nm at the
/// valleys, over a square tile of side `2 rise / tan(tilt)` (at most 20 um).
#[derive(Clone, Copy, Debug)]
struct Roof {
    tilt_deg: f64,
    t_max: f64,
    rise: f64,
}

impl Roof {
    /// The film of issue 25: 15 to 25 nm thick (facets of 573 nm at 1 degree).
    fn thin(tilt_deg: f64) -> Roof {
        Roof {
            tilt_deg,
            t_max: 25.0,
            rise: 10.0,
        }
    }

    fn tile(&self) -> f64 {
        (2.0 * self.rise / self.tilt_deg.to_radians().tan()).min(20_000.0)
    }

    fn thickness(&self, x: f64) -> f64 {
        self.t_max - self.tilt_deg.to_radians().tan() * (x - self.tile() / 2.0).abs()
    }

    /// Writes the film: `top.obj` (z = 0) and `back.obj` (the roof), and the sample.
    fn sample(&self) -> goniospec::sample::Sample {
        let l = self.tile();
        let d = scratch("tilted-film");
        std::fs::write(
            d.join("top.obj"),
            format!("v 0 0 0\nv {l} 0 0\nv {l} {l} 0\nv 0 {l} 0\nf 1 2 3\nf 1 3 4\n"),
        )
        .unwrap();
        let (zl, zc) = (-self.thickness(0.0), -self.t_max);
        let h = l / 2.0;
        std::fs::write(
            d.join("back.obj"),
            format!(
                "v 0 0 {zl}\nv {h} 0 {zc}\nv {l} 0 {zl}\nv 0 {l} {zl}\nv {h} {l} {zc}\nv {l} {l} {zl}\nf 1 2 5\nf 1 5 4\nf 2 3 6\nf 2 6 5\n"
            ),
        )
        .unwrap();
        write_gold_table(&d);
        sample_in(
            &d,
            &format!(
                "[sample]\nname = \"gold roof {}\"\nunit = \"nm\"\ntile = [{l:?}, {l:?}]\n[media.air]\nn = 1.0\n[media.gold]\ntable = \"gold.csv\"\n[media.glass]\nn = {GLASS:?}\n[[interface]]\nmesh = \"top.obj\"\nfront = \"air\"\nback = \"gold\"\n[[interface]]\nmesh = \"back.obj\"\nfront = \"gold\"\nback = \"glass\"\n",
                self.tilt_deg
            ),
        )
    }

    /// The reference: unpolarised (R, T) of the flat film at each local thickness,
    /// averaged over the tile (midpoint rule on 2,000 points; `R_TMM(t)` is smooth in t).
    fn local_tmm(&self, lambda: f64, n: f64, k: f64, theta_deg: f64) -> (f64, f64) {
        let (l, m) = (self.tile(), 2000);
        let (mut r, mut t) = (0.0, 0.0);
        for i in 0..m {
            let x = (i as f64 + 0.5) / m as f64 * l;
            let (ri, ti) = tmm_ref(
                &[C::new(1.0, 0.0), C::new(n, k), C::new(GLASS, 0.0)],
                &[self.thickness(x)],
                lambda,
                theta_deg.to_radians(),
            );
            r += ri;
            t += ti;
        }
        (r / m as f64, t / m as f64)
    }
}

/// (R, T) of the film at each tilt, incident angle and wavelength: `[tilt][theta][lambda]`.
fn simulate_films(tilts: &[f64], thetas: &[f64]) -> Vec<Vec<Vec<(f64, f64)>>> {
    let lambdas: Vec<f64> = GOLD.iter().map(|g| g.0).collect();
    tilts
        .iter()
        .map(|&tilt| {
            let s = Roof::thin(tilt).sample();
            let acc = run(
                &s,
                &config(thetas, Wavelengths::Monochromatic(lambdas.clone()), 256),
            );
            (0..thetas.len())
                .map(|i| (0..lambdas.len()).map(|j| totals(&acc, i, j)).collect())
                .collect()
        })
        .collect()
}

/// Where the run is not exact, it says so: the power that met facets tilted against the
/// planes of constant amplitude of the wave inside the absorber (`SimStats::limited`,
/// `trace::event_weights`) above `LIMITED_WARN`, or the power its series created above
/// `CREATED_WARN` (what `simulate` warns about). Over gold roofs with faces meeting at
/// 1e-4 to 40 degrees and facets of 0.01 to 9.2 um, at 0/30/60 degrees and 450-650 nm:
/// where the run is silent, R and T are within 2e-3 (issue 25's tolerance) of the local
/// TMM; where it warns, within `LIMITED_FILM_FACTOR` times the limited and created power
/// together, the bound the warning states. Films whose faces meet within
/// `FILM_TILT_FULL` (20 degrees) are taken by the local film (`trace::film`) and are silent:
/// measured at most 5.1e-4 off (4.1e-7 at 1e-4 degree; from 0.2 degree on, the tile's
/// quadrature by 256 trees), where the ray series
/// were 1.0e-2 off at 1 degree (warned) and 0.47 at 8. Between 20 and 30 degrees the ray
/// series take a growing share, reported as limited, and the run warns: at 21 degrees
/// 2.4e-2 off with 2.5e-2 limited, at 25 0.35 with 0.57; at 40 degrees (the ray series
/// alone) 0.48 with 0.27 limited and 1.7e-2 created.
#[test]
fn the_run_is_within_2e_3_of_the_local_tmm_or_warns_with_a_bound_that_holds() {
    use goniospec::simulate::{CREATED_WARN, LIMITED_FILM_FACTOR, LIMITED_WARN, simulate};
    let lambdas: Vec<f64> = GOLD.iter().map(|g| g.0).collect();
    let thetas = [0.0, 30.0, 60.0];
    let roof = |tilt_deg, t_max, rise| Roof {
        tilt_deg,
        t_max,
        rise,
    };
    // The roof, and whether the run must warn.
    let cases = [
        (Roof::thin(1e-4), false),
        (Roof::thin(1e-2), false),
        (Roof::thin(0.2), false),
        (Roof::thin(0.5), false),
        (Roof::thin(1.0), false),
        (roof(1.0, 40.0, 20.0), false),
        (roof(1.0, 100.0, 80.0), false),
        (roof(1.0, 180.0, 160.0), false),
        (roof(2.0, 200.0, 160.0), false),
        (roof(0.7, 40.0, 20.0), false),
        (Roof::thin(10.0), false),
        (roof(10.0, 120.0, 100.0), false),
        (Roof::thin(21.0), true),
        (Roof::thin(25.0), true),
        (Roof::thin(40.0), true),
    ];
    for (roof, must_warn) in cases {
        let s = roof.sample();
        let cfg = config(&thetas, Wavelengths::Monochromatic(lambdas.clone()), 256);
        let (acc, stats) = simulate(&s, &cfg, &|_| {}).unwrap_or_else(|e| panic!("{roof:?}: {e}"));
        let (limited, created) = (stats.worst_limited(&acc).0, stats.worst_created(&acc).0);
        let warned = limited > LIMITED_WARN || created > CREATED_WARN;
        let bound = if warned {
            LIMITED_FILM_FACTOR * (limited + created)
        } else {
            2e-3
        };
        let mut worst = 0.0f64;
        for (i, &th) in thetas.iter().enumerate() {
            for (j, &(lambda, n, k)) in GOLD.iter().enumerate() {
                let (r, t) = totals(&acc, i, j);
                let (r_ref, t_ref) = roof.local_tmm(lambda, n, k, th);
                worst = worst.max((r - r_ref).abs().max((t - t_ref).abs()));
            }
        }
        eprintln!(
            "{roof:?}: {worst:.2e} off the local TMM; limited {limited:.1e}, created {created:.1e}, warned {warned}"
        );
        assert!(
            worst <= bound,
            "{roof:?}: {worst} off the local TMM, beyond {bound} (warned: {warned})"
        );
        assert_eq!(warned, must_warn, "{roof:?}: warned {warned}");
    }
}

/// Where a film's series create a tenth of the power, the run is refused and says why: a
/// 5-15 nm gold roof whose faces meet at 60 degrees over 6 nm facets, lit at 60 degrees
/// (thousands of times the power per tree created; features thinner than the wave's decay
/// length seen from its direction, where no ray model holds, and too steep for the local
/// film, `trace::film`). (At 3 degrees this roof created 1.3 and was refused before the
/// local film took it: now it is 3.9e-4 off the local TMM.)
#[test]
fn a_sub_skin_depth_wedge_is_refused_and_says_why() {
    use goniospec::simulate::{SimError, simulate};
    let roof = Roof {
        tilt_deg: 60.0,
        t_max: 15.0,
        rise: 10.0,
    };
    let lambdas: Vec<f64> = GOLD.iter().map(|g| g.0).collect();
    let cfg = config(&[60.0], Wavelengths::Monochromatic(lambdas), 256);
    match simulate(&roof.sample(), &cfg, &|_| {}) {
        Err(SimError::Unphysical(m)) => assert!(
            m.contains("came from ray series that created energy"),
            "the refusal does not name its cause: {m}"
        ),
        other => panic!("expected a refusal, got {:?}", other.map(|_| ())),
    }
}

/// Tilts from 1e-6 to 20 degrees, 0/30/60 degrees, 450-650 nm: R and T within 2e-3 of the
/// local TMM, and no jump between neighbouring tilts beyond the reference's own change
/// (plus the same 2e-3). Issue 25 asks this up to 1 degree. The tracer takes such films by
/// the local film (`trace::film`): measured at most 3.6e-4 off at every tilt (4e-7 at 1e-4
/// degree; from 0.2 degree on 3.0e-4 to 3.6e-4, the tile's quadrature by 256 trees). As ray series they were 2.9e-4 off at 0.2 degree, 1.5e-3 at
/// 0.5 and 1.0e-2 at 1 (warned), and like bulk gold from a few degrees (0.47 off at 8).
/// RCWA confirms the reference at 1 degree, within 2.3e-3 for TE (tests/interop/roof_rcwa.py)
/// and within 3e-3 for TM except T at 30 degrees and 650 nm, 5e-3 to 8e-3
/// (tests/interop/roof_rcwa_tm.py); at larger tilts this roof's period falls below the
/// wavelength and TM departs from any local model (docs/physics.md).
#[test]
fn a_gold_film_with_a_tilted_back_face_matches_the_local_tmm_up_to_20_degrees() {
    let tilts = [
        1e-6, 1e-4, 3e-3, 1e-2, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0,
    ];
    let thetas = [0.0, 30.0, 60.0];
    let got = simulate_films(&tilts, &thetas);
    let mut refs = Vec::new();
    for (a, &tilt) in tilts.iter().enumerate() {
        let mut per_tilt = Vec::new();
        for (i, &th) in thetas.iter().enumerate() {
            let mut row = Vec::new();
            for (j, &(lambda, n, k)) in GOLD.iter().enumerate() {
                let (r_ref, t_ref) = Roof::thin(tilt).local_tmm(lambda, n, k, th);
                let (r, t) = got[a][i][j];
                eprintln!(
                    "tilt {tilt:e} deg, theta {th}, {lambda} nm: R {r:.5} (local TMM {r_ref:.5}), T {t:.5} ({t_ref:.5})"
                );
                assert!(
                    (r - r_ref).abs() < 2e-3 && (t - t_ref).abs() < 2e-3,
                    "tilt {tilt} deg, theta {th}, {lambda} nm: R {r} T {t} against the local TMM {r_ref} {t_ref}"
                );
                row.push((r_ref, t_ref));
            }
            per_tilt.push(row);
        }
        refs.push(per_tilt);
    }
    for a in 1..tilts.len() {
        for i in 0..thetas.len() {
            for j in 0..GOLD.len() {
                let (dr, dt) = (
                    (got[a][i][j].0 - got[a - 1][i][j].0).abs(),
                    (got[a][i][j].1 - got[a - 1][i][j].1).abs(),
                );
                let (rr, rt) = (
                    (refs[a][i][j].0 - refs[a - 1][i][j].0).abs(),
                    (refs[a][i][j].1 - refs[a - 1][i][j].1).abs(),
                );
                assert!(
                    dr <= rr + 2e-3 && dt <= rt + 2e-3,
                    "a jump between tilts {} and {}: R by {dr}, T by {dt}, the local TMM by {rr}, {rt}",
                    tilts[a - 1],
                    tilts[a]
                );
            }
        }
    }
}

/// The wavy film of issue 25: gold `t` nm thick (vertically) on glass, both faces one
/// Gaussian height field of RMS `rms` nm and correlation length 2 um (`wavy-film` with no
/// thickness variation) on a 20 um tile of 128 x 128 cells. Returns the sample and the top
/// face's triangles (nm) as generated.
fn wavy_gold(t: f64, rms: f64) -> (goniospec::sample::Sample, goniospec::sample::mesh::Mesh) {
    use goniospec::sample::generate::{Generated, GeneratorSpec};
    let spec = |surface: &str| {
        format!(
            "kind = \"wavy-film\", surface = \"{surface}\", thickness = {t:?}, thickness_rms = 0.0, roughness_rms = {rms:?}, correlation_length = 2000.0, resolution = 128, seed = 11"
        )
    };
    let top = match toml::from_str::<GeneratorSpec>(&spec("top").replace(", ", "\n"))
        .unwrap()
        .generate([20_000.0, 20_000.0], 1.0)
        .unwrap()
    {
        Generated::Sheet(m) => m,
        _ => panic!("a sheet"),
    };
    let text = format!(
        "[sample]\nname = \"wavy gold {t} nm\"\nunit = \"nm\"\ntile = [20000.0, 20000.0]\n[media.air]\nn = 1.0\n[media.gold]\ntable = \"gold.csv\"\n[media.glass]\nn = {GLASS:?}\n[[interface]]\ngenerator = {{ {} }}\nfront = \"air\"\nback = \"gold\"\n[[interface]]\ngenerator = {{ {} }}\nfront = \"gold\"\nback = \"glass\"\n",
        spec("top"),
        spec("bottom")
    );
    let dir = scratch("wavy-gold");
    write_gold_table(&dir);
    (sample_in(&dir, &text), top)
}

/// The facet-wise TMM: every top facet a flat film of its own normal thickness `t cos(s)`
/// (the faces are vertical offsets of one another) lit at its own angle, weighted by the
/// power it intercepts (area times the cosine of the local angle; at these slopes and
/// angles no facet shadows another, and reflected and transmitted light leaves without
/// meeting the film again). Unpolarised light is unpolarised in every facet's own s/p
/// basis, so `(R_s + R_p) / 2` holds per facet.
fn facet_wise_tmm(
    top: &goniospec::sample::mesh::Mesh,
    t: f64,
    theta_deg: f64,
    g: (f64, f64, f64),
) -> (f64, f64) {
    let (lambda, n, k) = g;
    let th = theta_deg.to_radians();
    let d = glam::DVec3::new(th.sin(), 0.0, -th.cos());
    let (mut r, mut tr, mut w) = (0.0, 0.0, 0.0);
    for i in 0..top.triangles.len() {
        let av = top.area_vector(i);
        let m = av.normalize();
        let cos_l = -d.dot(m);
        let wi = 0.5 * av.length() * cos_l;
        let (ri, ti) = tmm_ref(
            &[C::new(1.0, 0.0), C::new(n, k), C::new(GLASS, 0.0)],
            &[t * m.z],
            lambda,
            cos_l.acos(),
        );
        r += wi * ri;
        tr += wi * ti;
        w += wi;
    }
    (r / w, tr / w)
}

/// A wavy gold film, 5 and 20 nm, against the facet-wise TMM (issue 25). Its faces are
/// parallel facet by facet, but the film's series walks from facet to facet (tens to a
/// hundred nm per round trip at 30 degrees and 650 nm, against 156 nm facets), so the
/// faces it meets are tilted against each other by up to a few tenths of a degree (the
/// curvature times the walk). With slopes up to 3.8, 7.5 and 10 degrees, at 0 and 30
/// degrees, every case is within 2e-3, tighter than the 1e-2 (measured: at most
/// 5.2e-4, 20 nm at 30 degrees and 650 nm, slopes to 10 degrees; 5.9e-3 with the event
/// weight `exp(-x)` of the stop before), for the beamlet estimator and for the plane-wave
/// limit, which recombine the film's inhomogeneous partial waves over the same amplitude
/// window and agree within 1e-3. (Two stops before: 7.5-degree slopes 1.8e-2 off at 30
/// degrees, the plane-wave estimator up to 0.46.)
#[test]
fn a_wavy_thin_gold_film_matches_the_facet_wise_tmm_with_either_estimator() {
    let lambdas: Vec<f64> = GOLD.iter().map(|g| g.0).collect();
    let thetas = [0.0, 30.0];
    for (rms, slope_deg) in [(25.0, 3.8), (50.0, 7.5), (67.0, 10.0)] {
        for t in [5.0, 20.0] {
            let (s, top) = wavy_gold(t, rms);
            let max_slope = (0..top.triangles.len())
                .map(|i| top.area_vector(i).normalize().z.acos().to_degrees())
                .fold(0.0, f64::max);
            assert!(
                (max_slope - slope_deg).abs() < 0.1,
                "the film's steepest facet: {max_slope} degrees"
            );
            // The beamlet estimator at its default radius, and the plane-wave limit.
            let mut runs = Vec::new();
            for rho in [5000.0, f64::INFINITY] {
                let mut cfg = config(&thetas, Wavelengths::Monochromatic(lambdas.clone()), 4096);
                cfg.rho_nm = rho;
                let (acc, stats) = goniospec::simulate::simulate(&s, &cfg, &|_| {}).unwrap();
                let (limited, _) = stats.worst_limited(&acc);
                runs.push((acc, limited, rho));
            }
            for (i, &th) in thetas.iter().enumerate() {
                for (j, &g) in GOLD.iter().enumerate() {
                    let (r_ref, t_ref) = facet_wise_tmm(&top, t, th, g);
                    let mut got = Vec::new();
                    for (acc, limited, rho) in &runs {
                        let (r, tr) = totals(acc, i, j);
                        let err = (r - r_ref).abs().max((tr - t_ref).abs());
                        eprintln!(
                            "{t} nm gold, slopes to {max_slope:.1} deg, theta {th}, {} nm, rho {rho}: R {r:.4} (facet-wise TMM {r_ref:.4}), T {tr:.4} ({t_ref:.4}); off by {err:.1e}; limited {limited:.1e}",
                            g.0
                        );
                        assert!(
                            err < 2e-3,
                            "{t} nm, rms {rms}, theta {th}, {} nm: off by {err}",
                            g.0
                        );
                        got.push((r, tr));
                    }
                    let apart = (got[0].0 - got[1].0).abs().max((got[0].1 - got[1].1).abs());
                    assert!(
                        apart < 1e-3,
                        "{t} nm, rms {rms}, theta {th}, {} nm: the estimators {apart} apart",
                        g.0
                    );
                }
            }
        }
    }
}

/// The deflection that sets the recombination weight, against its first-order form: a
/// wave that entered gold through a horizontal face (`N = (kappa, 0, q)`, `N''` vertical)
/// meeting a facet tilted by `beta` in azimuth `phi` has its reflected index turned by `2
/// beta (q e + (N . e) z)`, `e` the tilt's horizontal direction: `2 beta |Re(q) e + (N' .
/// e) z|`, and not at all at a parallel facet.
#[test]
fn the_deflection_of_a_tilted_facet_is_first_order_in_the_tilt() {
    use goniospec::trace::deflection;
    for &(n, k) in &[(0.43, 2.455), (1.38, 1.92), (0.166, 3.15)] {
        for kappa in [0.0, 0.5, 0.85] {
            let q = (C::new(n, k) * C::new(n, k) - kappa * kappa).sqrt();
            let (n_re, n_im) = (
                glam::DVec3::new(kappa, 0.0, q.re),
                glam::DVec3::new(0.0, 0.0, q.im),
            );
            assert!(deflection(n_re, n_im, glam::DVec3::Z) < 1e-15);
            for beta in [1e-4f64, 1e-3, 1e-2] {
                for phi in [0.0f64, 1.0, 2.5] {
                    let m = glam::DVec3::new(
                        beta.sin() * phi.cos(),
                        beta.sin() * phi.sin(),
                        beta.cos(),
                    );
                    let d = deflection(n_re, n_im, m);
                    let e_dot = kappa * phi.cos();
                    let first = 2.0 * beta * (q.re * q.re + e_dot * e_dot).sqrt();
                    // Second-order terms: beta^2 |N'| against the first-order one.
                    let tol = 4.0 * beta * beta * (kappa + q.re) + 1e-15;
                    assert!(
                        (d - first).abs() <= tol,
                        "n {n} + {k}i, kappa {kappa}, beta {beta}, phi {phi}: {d} against {first}"
                    );
                }
            }
        }
    }
}

/// The event weight: 1 at a facet parallel to the wave's planes of constant amplitude,
/// falling continuously with the tilt, as `exp(-x^2)`, `x = e |Delta|^2 / (2 a^2)`, to
/// first order for a wave that entered gold from air (`|Delta| = 2 beta |N|` for a tilt
/// about the axis across the plane of incidence, `N = (kappa, 0, q)`); and for the
/// evanescent wave a lossless medium of index `n` carries beside a metal (`N = (sqrt(n^2 +
/// g^2), 0, 0) + i (0, 0, g)`), whose evanescence `(n^2 + 2 g^2) / n^2` multiplies `x`,
/// against the homogeneous-like wave of the same `|Delta|`.
#[test]
fn the_event_weight_falls_with_the_tilt_and_faster_for_evanescent_waves() {
    use goniospec::trace::{PLANE_WAVE_TILT, recombination_weight};
    let a2 = PLANE_WAVE_TILT * PLANE_WAVE_TILT;
    let q = (C::new(0.43, 2.455) * C::new(0.43, 2.455) - 0.25).sqrt();
    let (n_re, n_im) = (
        glam::DVec3::new(0.5, 0.0, q.re),
        glam::DVec3::new(0.0, 0.0, q.im),
    );
    assert_eq!(recombination_weight(n_re, n_im, glam::DVec3::Z), 1.0);
    let mut last = 1.0;
    let evanescence = (0.25 + q.norm_sqr()) / (C::new(0.43, 2.455) * C::new(0.43, 2.455)).norm();
    for beta in [1e-4f64, 1e-3, 1e-2, 3e-2, 0.1] {
        let m = glam::DVec3::new(beta.sin(), 0.0, beta.cos());
        let w = recombination_weight(n_re, n_im, m);
        assert!(w < last && w > 0.0, "beta {beta}: {w} after {last}");
        last = w;
        let delta = 2.0 * beta * (n_re.length_squared() + n_im.length_squared()).sqrt();
        let x = evanescence * delta * delta / (2.0 * a2);
        let first = (-x * x).exp();
        assert!(
            (w.ln() / first.ln() - 1.0).abs() < 8.0 * beta,
            "beta {beta}: {w} against {first}"
        );
    }
    // An evanescent wave in a lossless medium (index 1.49, |N''| = 4.9) against the wave
    // in gold, at facets giving both the same |Delta|.
    let (n, g) = (1.49f64, 4.9f64);
    let (e_re, e_im) = (
        glam::DVec3::new((n * n + g * g).sqrt(), 0.0, 0.0),
        glam::DVec3::new(0.0, 0.0, g),
    );
    let beta = 1e-3f64;
    let m = glam::DVec3::new(beta.sin(), 0.0, beta.cos());
    let scale = (n_re.length_squared() + n_im.length_squared()).sqrt()
        / (e_re.length_squared() + e_im.length_squared()).sqrt();
    let m_gold = glam::DVec3::new((beta / scale).sin(), 0.0, (beta / scale).cos());
    // ln w = -x^2, x proportional to the evanescence at equal |Delta|.
    let ratio = (recombination_weight(e_re, e_im, m).ln()
        / recombination_weight(n_re, n_im, m_gold).ln())
    .sqrt()
        * evanescence;
    let expected = (n * n + 2.0 * g * g) / (n * n);
    assert!(
        (ratio / expected - 1.0).abs() < 1e-2,
        "{ratio} against {expected}"
    );
}

/// The event weights of a wave bouncing in a gold wedge (faces meeting at 1 degree, 650
/// nm, normal incidence), its index vector reflected by hand (`N - 2 (N . m) m` for its
/// real and imaginary parts): against the wave's own planes of constant amplitude the
/// facets tilt further each round trip and `w0` falls (below 0.5 by the sixth event),
/// while against the facet that made the wave the tilt stays 1 degree and `w` stays above
/// 0.999 (its closed form at `|Delta| = 2 beta |N|`). At a ridge tip (the wave entered
/// through a facet 60 degrees from the one it meets) both weights are the same and small.
#[test]
fn event_weights_spare_a_wedges_series_and_still_limit_a_ridge_tip() {
    use goniospec::trace::{PLANE_WAVE_TILT, event_weights};
    let gold = C::new(0.166, 3.15);
    let beta = 1f64.to_radians();
    let (top, back) = (
        glam::DVec3::Z,
        glam::DVec3::new(beta.sin(), 0.0, beta.cos()),
    );
    let reflect = |v: glam::DVec3, m: glam::DVec3| v - m * (2.0 * v.dot(m));
    // Entered through the top at normal incidence: N = -gold z.
    let (mut n_re, mut n_im) = (
        glam::DVec3::new(0.0, 0.0, -gold.re),
        glam::DVec3::new(0.0, 0.0, -gold.im),
    );
    let a2 = PLANE_WAVE_TILT * PLANE_WAVE_TILT;
    let delta = 2.0 * beta.sin() * gold.norm();
    let closed = (-(delta * delta / (2.0 * a2)).powi(2)).exp();
    let mut w0s = Vec::new();
    let mut last = top;
    for event in 0..8 {
        let facet = if event % 2 == 0 { back } else { top };
        let (w, w0) = event_weights(n_re, n_im, facet, last);
        assert!(w >= w0, "event {event}: w {w} below w0 {w0}");
        assert!(
            w > 0.999 && (w.ln() / closed.ln() - 1.0).abs() < 0.05,
            "event {event}: w {w}, closed form {closed}"
        );
        w0s.push(w0);
        (n_re, n_im) = (reflect(n_re, facet), reflect(n_im, facet));
        last = facet;
    }
    assert!(
        w0s.windows(2).all(|p| p[1] < p[0]) && w0s[5] < 0.5,
        "w0 along the series: {w0s:?}"
    );
    // A ridge tip: entered through a wall at 60 degrees, meeting the other wall.
    let wall = glam::DVec3::new(60f64.to_radians().sin(), 0.0, 60f64.to_radians().cos());
    let other = glam::DVec3::new(-wall.x, 0.0, wall.z);
    let (n_re, n_im) = (-wall * gold.re, -wall * gold.im);
    let (w, w0) = event_weights(n_re, n_im, other, wall);
    assert!(w == w0 && w < 1e-3, "ridge tip: w {w}, w0 {w0}");
}

/// Gold V-grooves (60 degree opening, 2 um period, walls 60 degrees from the horizontal),
/// light across the grooves, by geometric optics written here: a 2-D ray bounces between
/// the two walls of its groove, each bounce multiplying the s and p powers by the
/// conductor's Fresnel `|r|^2` (Born & Wolf §14.2; with `w = sqrt(N^2 - sin^2)`,
/// `r_s = (cos - w) / (cos + w)`, `r_p = (N^2 cos - w) / (N^2 cos + w)`), no light
/// entering the metal. In this plane every wall normal lies in the plane of incidence, so
/// s and p never mix. Entry points are spread uniformly over one period (midpoint rule on
/// `m` points). Returns the unpolarised R.
fn v_groove_geometric(theta_deg: f64, n: C, m: usize) -> f64 {
    let p = 2000.0;
    let (s60, c60) = (60f64.to_radians().sin(), 60f64.to_radians().cos());
    // Left wall through (0, 0), right wall through (p, 0); normals point into the air.
    let walls = [((s60, c60), 0.0), ((-s60, c60), p)];
    let fresnel = |cos_i: f64| {
        let sin2 = 1.0 - cos_i * cos_i;
        let w = (n * n - sin2).sqrt();
        let rs = (cos_i - w) / (cos_i + w);
        let rp = (n * n * cos_i - w) / (n * n * cos_i + w);
        (rs.norm_sqr(), rp.norm_sqr())
    };
    let th = theta_deg.to_radians();
    let mut sum = 0.0;
    for i in 0..m {
        let (mut x, mut z) = ((i as f64 + 0.5) / m as f64 * p, 0.0);
        let (mut dx, mut dz) = (-th.sin(), -th.cos());
        let (mut ps, mut pp) = (1.0, 1.0);
        for _ in 0..1000 {
            // The nearest wall the ray approaches, in front of it.
            let hit = walls
                .iter()
                .filter_map(|&((nx, nz), x0)| {
                    let dn = dx * nx + dz * nz;
                    let t = -((x - x0) * nx + z * nz) / dn;
                    (dn < 0.0 && t > 1e-9).then_some((t, (nx, nz)))
                })
                .min_by(|a, b| a.0.total_cmp(&b.0));
            let Some((t, (nx, nz))) = hit else { break };
            let (hx, hz) = (x + t * dx, z + t * dz);
            if hz > 0.0 {
                break; // left the groove through its opening first
            }
            let cos_i = -(dx * nx + dz * nz);
            let (rs, rp) = fresnel(cos_i);
            ps *= rs;
            pp *= rp;
            (x, z) = (hx, hz);
            (dx, dz) = (dx + 2.0 * cos_i * nx, dz + 2.0 * cos_i * nz);
        }
        sum += 0.5 * (ps + pp);
    }
    sum / m as f64
}

/// The gold V-grooves of the tests below: `goniospec generate v-grooves` with a 60 degree
/// opening, 10 grooves on a 20 um tile (period 2 um, depth 1732 nm), gold as the constant
/// index `n + ik` at 550 nm.
fn gold_v_grooves(n: f64, k: f64) -> goniospec::sample::Sample {
    let d = scratch("gold-v-grooves");
    let mesh = goniospec::sample::generate::v_grooves([20_000.0, 20_000.0], 10, 60.0, 0.0).unwrap();
    mesh.write_obj(&d.join("v.obj"), 1.0, "gold V-grooves")
        .unwrap();
    sample_in(
        &d,
        &format!(
            "[sample]\nname = \"gold grooves\"\nunit = \"nm\"\ntile = [20000.0, 20000.0]\n[media.air]\nn = 1.0\n[media.gold]\nn = {n:?}\nk = {k:?}\n[[interface]]\nmesh = \"v.obj\"\nfront = \"air\"\nback = \"gold\"\n"
        ),
    )
}

/// One V-groove run at 550 nm and `theta` (light across the grooves): R, its standard
/// error, and the mean power per tree the run reports as created and as limited (what
/// `simulate` warns about above `CREATED_WARN` and `LIMITED_WARN`).
fn v_groove_run(s: &goniospec::sample::Sample, theta: f64) -> (f64, f64, f64, f64) {
    let cfg = config(&[theta], Wavelengths::Monochromatic(vec![550.0]), 20_000);
    let (acc, stats) = goniospec::simulate::simulate(s, &cfg, &|_| {}).unwrap();
    let trees = acc.cell(0, 0).trees as f64;
    let (r, _) = totals(&acc, 0, 0);
    let se = acc
        .cell(0, 0)
        .r_stderr(acc.header.settings.coherence_mode())
        .unwrap();
    (r, se, stats.created[0] / trees, stats.limited[0] / trees)
}

/// Where no ray model is exact, the run says so. Gold V-grooves (60 degrees, 2 um) lit
/// across the grooves: light that enters the gold within about 100 nm of a ridge tip, on
/// the side where its skin-depth wave runs towards the tip, crosses to the other wall
/// through events no ray model holds (tree by tree, R rises from 0.497 to 0.84 within 20
/// nm of a tip at 0 degrees). Against geometric optics without that light (above), R
/// agrees within the noise and 1e-3 where the run reports no more than `CREATED_WARN`
/// created and `LIMITED_WARN` limited power; otherwise the run warns, and R is within
/// `LIMITED_EDGE_FACTOR` times their sum, the bound the warning states: at 89 degrees
/// too, where 0.17 of the power per tree is limited and R is 0.085 above geometric optics.
/// (Before the exits of inhomogeneous TM waves were written on the power basis,
/// `fresnel::on_power_basis`, the run created a quarter of the power there and was
/// refused.)
#[test]
fn gold_v_grooves_match_geometric_optics_or_warn() {
    use goniospec::simulate::{CREATED_WARN, LIMITED_EDGE_FACTOR, LIMITED_WARN};
    let (n, k) = (0.43, 2.455);
    let s = gold_v_grooves(n, k);
    for th in [0.0, 60.0, 80.0, 85.0, 89.0] {
        let (r, se, created, limited) = v_groove_run(&s, th);
        let r_geo = v_groove_geometric(th, C::new(n, k), 200_000);
        let err = (r - r_geo).abs();
        println!(
            "theta {th}: R {r:.4} +- {se:.1e}, geometric optics {r_geo:.4}, off {err:.1e}; created {created:.1e}, limited {limited:.1e}"
        );
        let noise = 5.0 * se + 1e-3;
        if created <= CREATED_WARN && limited <= LIMITED_WARN {
            assert!(
                err <= noise,
                "theta {th}: off by {err:.2e} without a warning"
            );
        } else {
            assert!(
                err <= noise + LIMITED_EDGE_FACTOR * (created + limited),
                "theta {th}: off by {err:.2e}, more than the warnings state"
            );
        }
    }
}

/// The rays' reflectance of each incident polarisation, traced tree by tree without the
/// estimator (exits of one V-groove tree leave in different directions and do not
/// interfere; the test checks their mean against `simulate`): (R_s, R_p) at 550 nm, for
/// `m` entry points spread evenly across one period. Here s is E along the grooves (TE),
/// p across them (TM).
fn v_groove_traced_by_polarisation(
    s: &goniospec::sample::Sample,
    theta: f64,
    m: usize,
) -> (f64, f64) {
    use goniospec::optics::fresnel::field_power;
    use goniospec::trace::{Scene, TraceLimits, TraceStack, Tree, launch_fields};
    let scene = Scene::new(s, goniospec::accel::Backend::default_available()).unwrap();
    let indices: Vec<C> = s
        .media
        .iter()
        .map(|m| {
            let (n, k) = m.model.eval(550.0).unwrap();
            C::new(n, k)
        })
        .collect();
    let t = theta.to_radians();
    let dir = glam::DVec3::new(-t.sin(), 0.0, -t.cos());
    let e0 = launch_fields(dir);
    // TE is the launched field with E along y, the grooves' direction (the first, s,
    // off normal incidence; at normal incidence the launch takes s along x).
    let te = (0..2)
        .find(|&p| (e0[p][1].re.abs() - 1.0).abs() < 1e-12)
        .expect("a launched field along the grooves");
    let (mut rs, mut rp) = (0.0, 0.0);
    let mut stack = TraceStack::default();
    for i in 0..m {
        let x = 2000.0 + (i as f64 + 0.5) / m as f64 * 2000.0;
        let mut tree = Tree::default();
        scene.trace(
            glam::DVec3::new(x, 5000.0, scene.z_top),
            dir,
            e0,
            &indices,
            550.0,
            &TraceLimits::default(),
            &mut stack,
            &mut tree,
        );
        for e in tree.exits.iter().filter(|e| e.up) {
            let att = (-4.0 * std::f64::consts::PI / 550.0 * e.opl.im).exp();
            rs += field_power(&e.e[te]) * att;
            rp += field_power(&e.e[1 - te]) * att;
        }
    }
    (rs / m as f64, rp / m as f64)
}

/// The same V-grooves against a rigorous solver: RCWA (PyPI grcwa) for TE, E along the
/// grooves, converged in orders and slices with a stated uncertainty
/// (tests/interop/vgroove_rcwa.py; its JSON kept in tests/reference/interop/ and made
/// again when the script changes; `make interop` sets GONIOSPEC_VGROOVE_JSON). TM is not compared: a staircase of a metal profile does not
/// converge for TM in RCWA. The rays' TE reflectance agrees within the reference's
/// uncertainty plus 2e-3, or the run warns and is within `LIMITED_EDGE_FACTOR` times
/// the created and limited power it reports. (At grazing light the rigorous R is above
/// the rays': the ridge tops diffract, which no ray model has.)
#[test]
#[ignore = "needs the RCWA reference: make interop"]
fn gold_v_grooves_against_rigorous_te_or_warn() {
    use goniospec::simulate::{CREATED_WARN, LIMITED_EDGE_FACTOR, LIMITED_WARN};
    let path =
        std::env::var("GONIOSPEC_VGROOVE_JSON").expect("GONIOSPEC_VGROOVE_JSON: run make interop");
    let refs: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    let (n, k) = (refs["n"].as_f64().unwrap(), refs["k"].as_f64().unwrap());
    let s = gold_v_grooves(n, k);
    for case in refs["cases"].as_array().unwrap() {
        let th = case["theta_deg"].as_f64().unwrap();
        let (r_ref, unc) = (
            case["r_te"].as_f64().unwrap(),
            case["uncertainty"].as_f64().unwrap(),
        );
        let (r, se, created, limited) = v_groove_run(&s, th);
        let (rs, rp) = v_groove_traced_by_polarisation(&s, th, 20_000);
        // The traced polarisations are the tool's R: their mean is simulate's.
        assert!(
            (0.5 * (rs + rp) - r).abs() <= 5.0 * se + 1e-3,
            "theta {th}: traced (R_s + R_p) / 2 = {} against simulate's {r}",
            0.5 * (rs + rp)
        );
        let err = (rs - r_ref).abs();
        println!(
            "theta {th}: rays' TE R {rs:.4} (TM {rp:.4}, unpolarised {r:.4} +- {se:.1e}), RCWA TE {r_ref:.4} +- {unc:.1e}: off {err:.1e}; created {created:.1e}, limited {limited:.1e}"
        );
        let tol = unc + 2e-3 + 5.0 * se;
        if created <= CREATED_WARN && limited <= LIMITED_WARN {
            assert!(err <= tol, "theta {th}: off by {err:.2e} without a warning");
        } else {
            assert!(
                err <= tol + LIMITED_EDGE_FACTOR * (created + limited),
                "theta {th}: off by {err:.2e}, more than the warnings state"
            );
        }
    }
}
