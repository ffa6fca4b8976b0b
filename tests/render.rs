//! Rendering and colour against independent references: a white Lambertian reflector, a
//! grey, the colour of a 600 nm soap film integrated here from CIE tables and an independent
//! TMM, CIEDE2000 test data, and thread-count independence.

mod common;

use std::path::Path;

use common::*;
use goniospec::brdf::{Brdf, Meta};
use goniospec::render::{self, Env, Light, RenderConfig, Shape, colour};
use goniospec::simulate::Wavelengths;

fn centres() -> Vec<f64> {
    (0..40).map(|i| 385.0 + 10.0 * i as f64).collect()
}

/// A Lambertian reflector of constant albedo, written here (not a library representation).
struct Lambert {
    albedo: f64,
    meta: Meta,
}

impl Brdf for Lambert {
    fn eval(&self, wi: glam::DVec3, wo: glam::DVec3, out: &mut [f64]) {
        let v = if wi[2] > 0.0 && wo[2] > 0.0 {
            self.albedo / std::f64::consts::PI
        } else {
            0.0
        };
        out.fill(v);
    }
    fn meta(&self) -> &Meta {
        &self.meta
    }
}

fn lambert(albedo: f64) -> Lambert {
    Lambert {
        albedo,
        meta: Meta {
            repr: goniospec::brdf::Kind::Analytic,
            lambda_nm: centres(),
            spectrum: None,
            sample_name: "white".into(),
            sample_hash: String::new(),
            simulation: String::new(),
            isotropic: true,
            reciprocal: true,
            median_rel_stderr: None,
            trees_per_direction: None,
            incident_stokes: None,
            rgb: false,
        },
    }
}

fn cfg(env: Env) -> RenderConfig {
    RenderConfig {
        width: 48,
        height: 40,
        spp: 4,
        light: Light::None,
        light_strength: 1.0,
        env,
        env_strength: 1.0,
        camera: glam::DVec3::new(0.0, -4.2, 1.6),
        fov_deg: 30.0,
        seed: 1,
    }
}

#[test]
fn white_lambertian_under_d65_renders_as_srgb_white_and_grey_as_neutral() {
    // Colour pipeline alone: a perfect white and a 50 % grey.
    let w = colour::bin_weights(&centres());
    let white = colour::xyz_to_linear_srgb(colour::xyz(&[1.0; 40], &w));
    for c in white {
        assert!((c - 1.0).abs() < 1e-3, "white -> {white:?}");
    }
    let grey = colour::xyz_to_linear_srgb(colour::xyz(&[0.5; 40], &w));
    for c in grey {
        assert!((c - 0.5).abs() < 1e-3, "grey -> {grey:?}");
    }
    // Through the renderer: a white Lambertian sphere under a constant unit environment has
    // radiance factor 1 everywhere it is seen.
    for (albedo, want) in [(1.0, 1.0), (0.5, 0.5)] {
        let b = lambert(albedo);
        let table = render::albedo_table(&b, 45);
        let img = render::render(
            &b,
            &Shape::Sphere,
            &cfg(Env::Constant),
            Some(&table),
            &|_| {},
        );
        let centre = img.rgb[(img.height / 2) * img.width + img.width / 2];
        for c in centre {
            assert!(
                (f64::from(c) - want).abs() < 1e-3,
                "albedo {albedo}: centre pixel {centre:?}"
            );
        }
        // Neutral wherever the sphere is hit.
        for px in &img.rgb {
            if px[1] > 0.0 {
                assert!(
                    (px[0] - px[1]).abs() < 1e-3 && (px[2] - px[1]).abs() < 1e-3,
                    "{px:?}"
                );
            }
        }
    }
}

/// The tables parsed here from the shipped CSVs.
fn table(name: &str, cols: usize) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("data/colour")
            .join(name),
    )
    .unwrap();
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with("lambda") && !l.trim().is_empty())
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            assert_eq!(v.len(), cols);
            v
        })
        .collect()
}

#[test]
fn soap_film_colour_matches_xyz_integrated_from_the_tmm_spectrum() {
    // Reference: XYZ of the TMM reflectance at 1 nm under D65, integrated here.
    let cmf = table("cie1931-2deg.csv", 4);
    let d65 = table("cie-d65.csv", 2);
    let d65_at = |l: f64| {
        let i = d65.partition_point(|r| r[0] <= l).clamp(1, d65.len() - 1);
        let t = (l - d65[i - 1][0]) / (d65[i][0] - d65[i - 1][0]);
        d65[i - 1][1] + t * (d65[i][1] - d65[i - 1][1])
    };
    let (mut xyz, mut norm) = ([0.0; 3], 0.0);
    for r in &cmf {
        let l = r[0];
        if !(380.0..=780.0).contains(&l) {
            continue;
        }
        let (refl, _) = tmm_ref(&[c(1.0, 0.0), c(1.33, 0.0), c(1.0, 0.0)], &[600.0], l, 0.0);
        let s = d65_at(l);
        for k in 0..3 {
            xyz[k] += refl * s * r[k + 1];
        }
        norm += s * r[2];
    }
    let reference = xyz.map(|v| v / norm);
    // The simulated film's spectrum in 10 nm bins, through the library's colour path.
    let s = stack_sample(
        "soapcolour",
        "[media.air]\nn = 1.0\n[media.soap]\nn = 1.33\n",
        "air",
        &[("soap", 600.0)],
        "air",
    );
    let edges: Vec<f64> = (0..=40).map(|i| 380.0 + 10.0 * i as f64).collect();
    let acc = run(&s, &config(&[0.0], Wavelengths::Bins(edges), 512));
    let spectrum: Vec<f64> = (0..40).map(|j| totals(&acc, 0, j).0).collect();
    let got = colour::xyz(&spectrum, &colour::bin_weights(&centres()));
    let white = colour::white_xyz();
    let de = colour::delta_e2000(colour::lab(got, white), colour::lab(reference, white));
    eprintln!("soap film XYZ {got:?} vs reference {reference:?}: DE2000 {de:.3}");
    for k in 0..3 {
        assert!(
            (got[k] - reference[k]).abs() < 2e-3,
            "XYZ {got:?} vs {reference:?}"
        );
    }
    assert!(de < 1.0, "DE2000 {de}");
}

#[test]
fn ciede2000_matches_published_test_data() {
    // Sharma, Wu & Dalal 2005, Table 1, pairs 1, 7 and 17.
    for (a, b, want) in [
        ([50.0, 2.6772, -79.7751], [50.0, 0.0, -82.7485], 2.0425),
        ([50.0, 0.0, 0.0], [50.0, -1.0, 2.0], 2.3669),
        ([50.0, 2.5, 0.0], [73.0, 25.0, -18.0], 27.1492),
    ] {
        let got = colour::delta_e2000(a, b);
        assert!((got - want).abs() < 1e-4, "{a:?} {b:?}: {got} vs {want}");
    }
}

#[test]
fn images_do_not_depend_on_the_thread_count() {
    let b = lambert(0.7);
    let mut c = cfg(Env::Sky);
    c.light = Light::Directional(glam::DVec3::new(0.3, -0.5, 0.81));
    let img = |t: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build()
            .unwrap();
        pool.install(|| render::render(&b, &Shape::Sphere, &c, None, &|_| {}))
    };
    assert!(img(1) == img(2));
}
