//! Measured materials in the RGL database's `.bsdf` form (`export::measured`): the shipped
//! files read, their directions against the data they carry, a synthetic material whose
//! BRDF is known in closed form, goniospec's own spectral export read back at its nodes,
//! and damaged files refused; and `goniospec compare`: identical materials differ by
//! nothing, two materials of known colours differ by the published CIEDE2000 of those
//! colours (Sharma, Wu & Dalal 2005, Table 1), computed here from CIELAB through an
//! independent inverse of the colour chain; the grid, what is left out and why, the exit
//! status for scripts, and the files. Mitsuba 3's reading of the same files and
//! colour-science's CIEDE2000 are `make interop` (`tests/interop/measured_mitsuba.py`).

mod common;

use common::measured::lambertian_file;
use common::*;
use glam::DVec3;
use goniospec::brdf::Brdf;
use goniospec::export::measured::MeasuredBrdf;
use goniospec::export::tensor::{self, Field};
use std::f64::consts::PI;

const SHIPPED: [&str; 3] = [
    "paper_white_rgb",
    "colodur_napoli_4f_rgb",
    "cc_ibiza_sunset_rgb",
];

fn shipped_path(name: &str) -> std::path::PathBuf {
    root().join(format!("data/measured/{name}.bsdf"))
}

/// `info` and `eval` on the shipped files: the description, the form, the eight incident
/// angles, and RGB triples that are finite and positive for light reflected off them.
#[test]
fn shipped_files_read_everywhere_a_brdf_is_read() {
    for name in SHIPPED {
        let p = shipped_path(name);
        let (code, out, err) = goniospec(&["info", p.to_str().unwrap()]);
        assert_eq!(code, 0, "{err}");
        assert!(out.contains("form: RGB"), "{out}");
        assert!(out.contains("(8); phi_i 0.00 deg (isotropic)"), "{out}");
        let (code, out, err) = goniospec(&[
            "eval",
            p.to_str().unwrap(),
            "--theta-i",
            "30",
            "--theta-o",
            "20",
            "--phi-o",
            "180",
        ]);
        assert_eq!(code, 0, "{err}");
        let lines: Vec<&str> = out.lines().collect();
        assert_eq!(lines[0], "r,g,b");
        let v: Vec<f64> = lines[1].split(',').map(|x| x.parse().unwrap()).collect();
        assert!(v.iter().all(|x| x.is_finite() && *x > 0.0), "{name}: {v:?}");
    }
}

/// The files' `valid` field is a bit per incident angle and node; below 90 degrees its
/// bits coincide node for node with the horizon as the VNDF warp's forward map places
/// each node (above it for the wrap film, below it for the paper and the paint). The
/// forward map is goniospec's (`MeasuredBrdf::node_direction`), the bits the measurement's:
/// a node placed on the wrong side of the horizon anywhere would show here.
#[test]
fn valid_bits_mark_the_horizon_the_forward_warp_finds() {
    for name in SHIPPED {
        let m = MeasuredBrdf::read(&shipped_path(name)).unwrap();
        let per_angle = m.valid_agreement().unwrap();
        assert_eq!(per_angle.len(), 7, "{name}");
        let above = per_angle.iter().all(|(n, a, _)| a == n);
        let below = per_angle.iter().all(|(n, _, b)| b == n);
        assert!(above != below, "{name}: {per_angle:?}");
    }
}

/// The reader's density of outgoing directions (the warp's over `2 pi^2 u_theta
/// sin(theta_m) 4 (wi . m)`, the `pdf` of `measured.cpp`) is the solid-angle measure of
/// the warped square: integrated over the square by a fine midpoint rule, `cos(theta_o)`
/// gives the projected hemisphere's pi sr (0.3 %: the rule's error where the
/// wrap film's VNDF peaks). Each node stands for its cell, a trapezoidal rule on the 32 x
/// 32 grid, whose sum is within 4 % of the same (measured 0.1-2.3 %) up to 60 degrees.
#[test]
fn node_patches_tile_the_projected_hemisphere() {
    for name in SHIPPED {
        let m = MeasuredBrdf::read(&shipped_path(name)).unwrap();
        let (w, h) = m.grid;
        for &ti in m.theta_i_rad.iter().filter(|t| t.to_degrees() < 61.0) {
            let q = 256;
            let fine: f64 = (0..q * q)
                .filter_map(|k| {
                    let s = [
                        ((k % q) as f64 + 0.5) / q as f64,
                        ((k / q) as f64 + 0.5) / q as f64,
                    ];
                    m.sample_direction(ti, 0.0, s)
                })
                .map(|(wo, sr)| sr * wo.z)
                .sum::<f64>()
                / (q * q) as f64;
            assert!(
                (fine / PI - 1.0).abs() < 3e-3,
                "{name} at {:.1} deg: {fine}",
                ti.to_degrees()
            );
            let nodes: f64 = (0..w * h)
                .filter_map(|k| m.node_direction(ti, 0.0, k % w, k / w))
                .map(|(_, wt)| wt)
                .sum();
            assert!(
                (nodes / PI - 1.0).abs() < 0.04,
                "{name} at {:.1} deg: {nodes}",
                ti.to_degrees()
            );
        }
    }
}

/// The synthetic Lambertian file evaluates to `rho / pi` at every lit node (to f32), and
/// between nodes within the bilinear interpolation of `cos(theta_o)` over a cell (2 %
/// on a 33-node grid away from the horizon); the jacobian flag scales by `ndf / (4
/// sigma)` as the readers do.
#[test]
fn a_synthetic_lambertian_material_evaluates_to_its_albedo_over_pi() {
    let rho = [0.8, 0.5, 0.2];
    let theta_i = [0.0, 0.4, 0.9];
    let fields = lambertian_file(rho, &theta_i, 33);
    let m = MeasuredBrdf::from_fields(&fields).unwrap();
    assert!(m.meta().rgb);
    let mut f = [0.0; 3];
    for &ti in &theta_i {
        let wi = goniospec::geom::from_spherical(ti, 0.0);
        let mut nodes = 0;
        for k in 0..33 * 33 {
            if let Some((wo, _)) = m.node_direction(ti, 0.0, k % 33, k / 33) {
                if wo.z < 1e-3 {
                    continue;
                }
                m.eval(wi, wo, &mut f);
                for c in 0..3 {
                    assert!(
                        (f[c] * PI / rho[c] - 1.0).abs() < 2e-5 / wo.z,
                        "node {k} at {ti}: {f:?}"
                    );
                }
                nodes += 1;
            }
        }
        assert!(nodes > 400, "{nodes}");
        for (to, po) in [(10.0f64, 30.0f64), (45.0, 200.0), (70.0, 95.0)] {
            let wo = goniospec::geom::from_spherical(to.to_radians(), po.to_radians());
            m.eval(wi, wo, &mut f);
            assert!((f[1] * PI / rho[1] - 1.0).abs() < 0.02, "{to} {po}: {f:?}");
        }
    }
    // jacobian = 1 with ndf 2 and sigma 0.5: the value times ndf / (4 sigma) = 1.
    let mut scaled = fields.clone();
    scaled[3] = Field::f32("ndf", &[2, 2], &[2.0; 4]);
    scaled[4] = Field::f32("sigma", &[2, 2], &[0.5; 4]);
    scaled[8] = Field::u8("jacobian", &[1]);
    let s = MeasuredBrdf::from_fields(&scaled).unwrap();
    let (wi, wo) = (
        goniospec::geom::from_spherical(0.4, 0.0),
        goniospec::geom::from_spherical(0.7, 2.0),
    );
    let (mut a, mut b) = ([0.0; 3], [0.0; 3]);
    m.eval(wi, wo, &mut a);
    s.eval(wi, wo, &mut b);
    assert!(
        a.iter()
            .zip(&b)
            .all(|(x, y)| (x - y).abs() < 1e-12 * x.abs())
    );
    // Light from below or to below is no reflection; at the horizon itself (cos 90 deg is
    // 6e-17 in floating point) the file's f cos(theta_o) holds no BRDF: 0, not 1e13 f.
    m.eval(DVec3::new(0.0, 0.0, -1.0), wo, &mut a);
    assert_eq!(a, [0.0; 3]);
    let horizon = goniospec::geom::from_spherical(std::f64::consts::FRAC_PI_2, 1.0);
    m.eval(wi, horizon, &mut a);
    assert_eq!(a, [0.0; 3]);
}

/// goniospec's own spectral export read back: at the nodes of its warped grid the reader
/// gives the simulated BRDF the writer tabulated (the writer places nodes by bisection of
/// its own warp, the reader by the closed-form forward map: two implementations), to the
/// file's f32 and the warps' agreement.
#[test]
fn a_spectral_export_reads_back_to_the_simulated_brdf_at_its_nodes() {
    let d = scratch("measured-export");
    let gsa = d.join("gold.gsa");
    let gsb = d.join("gold.gsb");
    let bsdf = d.join("gold.bsdf");
    for args in [
        vec![
            "simulate",
            "meshes/rough-gold.toml",
            "--theta-i",
            "0,30,60",
            "--rays",
            "256",
            "--wavelengths",
            "400:700:100",
            "-o",
            gsa.to_str().unwrap(),
        ],
        vec![
            "build",
            gsa.to_str().unwrap(),
            "--repr",
            "table",
            "-o",
            gsb.to_str().unwrap(),
        ],
        vec![
            "export",
            gsb.to_str().unwrap(),
            "--sample",
            "meshes/rough-gold.toml",
            "--resolution",
            "17",
            // Simulated at 0, 30 and 60 deg: held from 60 to 90.
            "--force",
            "-o",
            bsdf.to_str().unwrap(),
        ],
    ] {
        let (code, _, err) = goniospec(&args);
        assert_eq!(code, 0, "{args:?}: {err}");
    }
    let source = goniospec::brdf::file::read(&gsb).unwrap();
    let m = MeasuredBrdf::read(&bsdf).unwrap();
    assert!(!m.meta().rgb);
    assert_eq!(m.channels(), 3);
    let (mut got, mut want, mut scratch) = (vec![0.0; 3], vec![0.0; 3], vec![0.0; 3]);
    let (mut checked, mut worst) = (0, 0.0f64);
    for &ti in &m.theta_i_rad {
        let wi = goniospec::geom::from_spherical(ti, 0.0);
        let nodes: Vec<DVec3> = (0..17 * 17)
            .filter_map(|k| m.node_direction(ti, 0.0, k % 17, k / 17))
            .map(|(wo, _)| wo)
            .filter(|wo| wo.z > 0.05)
            .collect();
        let mut pairs = Vec::new();
        for &wo in &nodes {
            m.eval(wi, wo, &mut got);
            goniospec::export::rgl::symmetric_eval(&source, wi, wo, true, &mut want, &mut scratch);
            pairs.push((got.clone(), want.clone()));
        }
        // Relative to the slice's peak: the f32 file and the two warps' agreement.
        let peak = pairs
            .iter()
            .flat_map(|(_, w)| w.iter().copied())
            .fold(0.0f64, f64::max);
        for (g, w) in &pairs {
            for (a, b) in g.iter().zip(w) {
                worst = worst.max((a - b.max(0.0)).abs() / peak);
            }
        }
        checked += pairs.len();
    }
    assert!(checked > 500, "{checked}");
    // Measured: 1.7e-5 of the slice's peak.
    assert!(worst < 1e-4, "worst relative difference {worst}");
}

fn write(d: &std::path::Path, name: &str, fields: &[Field]) -> std::path::PathBuf {
    let p = d.join(name);
    tensor::write(fields, &p).unwrap();
    p
}

/// Damaged files are refused with the reason, before anything large is allocated.
#[test]
fn damaged_measured_files_are_refused_with_the_reason() {
    let d = scratch("measured-bad");
    let good = lambertian_file([0.5; 3], &[0.0, 0.5], 9);
    let bytes = tensor::to_bytes(&good);
    let cases: Vec<(&str, Vec<u8>, &str)> = {
        let mut v = Vec::new();
        v.push((
            "truncated",
            bytes[..bytes.len() / 2].to_vec(),
            "past the end",
        ));
        v.push(("header", bytes[..30].to_vec(), "truncated"));
        let mut nan = good.clone();
        let mut rgb = vec![0.1f32; 2 * 3 * 81];
        rgb[7] = f32::NAN;
        nan[7] = Field::f32("rgb", &[1, 2, 3, 9, 9], &rgb);
        v.push(("nan", tensor::to_bytes(&nan), "holds NaN"));
        let mut shape = good.clone();
        shape[5] = Field::f32("vndf", &[1, 3, 9, 9], &[1.0; 3 * 81]);
        v.push((
            "shape",
            tensor::to_bytes(&shape),
            "field 'vndf' is [1, 3, 9, 9]",
        ));
        let mut negative = good.clone();
        let mut vndf = vec![1.0f32; 2 * 81];
        vndf[3] = -1.0;
        negative[5] = Field::f32("vndf", &[1, 2, 9, 9], &vndf);
        v.push(("negative", tensor::to_bytes(&negative), "negative"));
        let mut missing = good.clone();
        missing.retain(|f| f.name != "sigma");
        v.push(("missing", tensor::to_bytes(&missing), "no field 'sigma'"));
        // A shape of 2^40 elements: refused from the header, not allocated.
        let mut huge = bytes.clone();
        let at = huge.windows(4).position(|w| w == b"vndf").unwrap() + 4 + 2 + 1 + 8;
        huge[at..at + 8].copy_from_slice(&(1u64 << 40).to_le_bytes());
        v.push(("huge", huge, "past the end"));
        v
    };
    for (tag, b, want) in cases {
        let p = d.join(format!("{tag}.bsdf"));
        std::fs::write(&p, &b).unwrap();
        let e = MeasuredBrdf::read(&p).unwrap_err().to_string();
        assert!(e.contains(want), "{tag}: {e}");
        let (code, _, err) = goniospec(&[
            "eval",
            p.to_str().unwrap(),
            "--theta-i",
            "0",
            "--theta-o",
            "0",
        ]);
        assert_eq!(code, 1, "{tag}");
        assert!(err.contains(want), "{tag}: {err}");
    }
    // The good file evaluates.
    let p = write(&d, "good.bsdf", &good);
    assert!(MeasuredBrdf::read(&p).is_ok());
}

// ---- goniospec compare ----

/// CIELAB (white `w`) to XYZ, CIE 15:2004 §8.2.1 inverted.
fn lab_to_xyz(lab: [f64; 3], w: [f64; 3]) -> [f64; 3] {
    let fy = (lab[0] + 16.0) / 116.0;
    let (fx, fz) = (fy + lab[1] / 500.0, fy - lab[2] / 200.0);
    let inv = |f: f64| {
        if f > 6.0 / 29.0 {
            f * f * f
        } else {
            3.0 * (6.0f64 / 29.0).powi(2) * (f - 4.0 / 29.0)
        }
    };
    [w[0] * inv(fx), w[1] * inv(fy), w[2] * inv(fz)]
}

/// The IEC 61966-2-1 XYZ-to-linear-sRGB matrix, and the white it maps to (1, 1, 1): its
/// inverse applied to (1, 1, 1), by Cramer's rule.
const M: [[f64; 3]; 3] = [
    [3.2406, -1.5372, -0.4986],
    [-0.9689, 1.8758, 0.0415],
    [0.0557, -0.2040, 1.0570],
];

fn solve(b: [f64; 3]) -> [f64; 3] {
    let det = |m: [[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(M);
    let mut x = [0.0; 3];
    for (c, xc) in x.iter_mut().enumerate() {
        let mut m = M;
        for r in 0..3 {
            m[r][c] = b[r];
        }
        *xc = det(m) / d;
    }
    x
}

fn rgb_of(lab: [f64; 3]) -> [f64; 3] {
    let white = solve([1.0, 1.0, 1.0]);
    let x = lab_to_xyz(lab, white);
    [0, 1, 2].map(|r| M[r][0] * x[0] + M[r][1] * x[1] + M[r][2] * x[2])
}

fn write_lab(d: &std::path::Path, name: &str, lab: [f64; 3]) -> String {
    let p = d.join(name);
    let rgb = rgb_of(lab);
    assert!(rgb.iter().all(|c| (0.0..=1.0).contains(c)), "{rgb:?}");
    tensor::write(&lambertian_file(rgb, &[0.0, 0.4, 0.8], 25), &p).unwrap();
    p.to_str().unwrap().to_string()
}

/// The per-angle rows of `angles.csv`: (theta_i, mean, median, p95).
fn angle_rows(dir: &std::path::Path) -> Vec<[f64; 4]> {
    let text = std::fs::read_to_string(dir.join("angles.csv")).unwrap();
    text.lines()
        .skip(1)
        .map(|l| {
            let v: Vec<f64> = l.split(',').take(6).map(|x| x.parse().unwrap()).collect();
            [v[0], v[3], v[4], v[5]]
        })
        .collect()
}

/// Lambertian materials of one colour each: every lit direction at every angle differs by
/// the pair's CIEDE2000 as Sharma et al. publish it; identical files by exactly 0.
#[test]
fn materials_of_known_colours_differ_by_their_published_ciede2000() {
    let d = scratch("compare-tint");
    // Sharma, Wu & Dalal 2005, Table 1: pairs 7, 17 and 25, inside the sRGB gamut.
    for (k, (a, b, want)) in [
        ([50.0, 0.0, 0.0], [50.0, -1.0, 2.0], 2.3669),
        ([50.0, 2.5, 0.0], [73.0, 25.0, -18.0], 27.1492),
        (
            [60.2574, -34.0099, 36.2677],
            [60.4626, -34.1751, 39.4387],
            1.2644,
        ),
    ]
    .into_iter()
    .enumerate()
    {
        let fa = write_lab(&d, &format!("a{k}.bsdf"), a);
        let fb = write_lab(&d, &format!("b{k}.bsdf"), b);
        let out = d.join(format!("out{k}"));
        let (code, text, err) = goniospec(&["compare", &fa, &fb, "-o", out.to_str().unwrap()]);
        assert_eq!(code, 0, "{err}");
        assert!(text.contains("linear sRGB"), "{text}");
        let rows = angle_rows(&out);
        assert_eq!(rows.len(), 3, "{text}");
        for r in rows {
            // The f32 file and the colour chain's rounding: 1e-3.
            for v in &r[1..] {
                assert!(
                    (v - want).abs() < 1e-3,
                    "pair {k} at {}: {r:?} vs {want}",
                    r[0]
                );
            }
        }
        // The same file twice: nothing differs.
        let same = d.join(format!("same{k}"));
        let (code, _, err) = goniospec(&["compare", &fa, &fa, "-o", same.to_str().unwrap()]);
        assert_eq!(code, 0, "{err}");
        for r in angle_rows(&same) {
            assert_eq!(&r[1..], &[0.0; 3]);
        }
    }
}

/// `--max-delta-e` makes the exit status 1 where the mean over every angle exceeds it,
/// with the report printed either way; a negative bound is refused.
#[test]
fn max_delta_e_sets_the_exit_status() {
    let d = scratch("compare-exit");
    let fa = write_lab(&d, "a.bsdf", [50.0, 2.5, 0.0]);
    let fb = write_lab(&d, "b.bsdf", [73.0, 25.0, -18.0]);
    let (code, text, _) = goniospec(&["compare", &fa, &fb, "--max-delta-e", "30"]);
    assert_eq!(code, 0);
    assert!(text.contains("all angles: dE mean 27.15"), "{text}");
    let (code, text, err) = goniospec(&["compare", &fa, &fb, "--max-delta-e", "20"]);
    assert_eq!(code, 1);
    assert!(text.contains("all angles"), "{text}");
    assert!(err.contains("exceeds --max-delta-e 20"), "{err}");
    let (code, _, err) = goniospec(&["compare", &fa, &fb, "--max-delta-e", "-1"]);
    assert_eq!(code, 1);
    assert!(err.contains("at least 0"), "{err}");
}

/// A simulation against a measurement: the measurement's angles within the simulated
/// range are compared on its own nodes, the others left out with the reason (outside the
/// simulation; grazing); the files hold every figure; the output folder's foreign files
/// are kept unless --force; the folder may not be an input.
#[test]
fn a_simulation_is_compared_on_the_measurements_grid() {
    let d = scratch("compare-sim");
    let gsa = d.join("gold.gsa");
    let (code, _, err) = goniospec(&[
        "simulate",
        "meshes/rough-gold.toml",
        "--theta-i",
        "0,30,60",
        "--rays",
        "128",
        "--wavelengths",
        "400:700:100",
        "-o",
        gsa.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let paper = root().join("data/measured/paper_white_rgb.bsdf");
    let out = d.join("cmp");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("angles.csv"), "mine").unwrap();
    let args = |force: bool| {
        let mut v = vec![
            "compare".to_string(),
            gsa.to_str().unwrap().into(),
            paper.to_str().unwrap().into(),
            "-o".into(),
            out.to_str().unwrap().into(),
        ];
        if force {
            v.push("--force".into());
        }
        v
    };
    let run = |v: Vec<String>| {
        let refs: Vec<&str> = v.iter().map(|s| s.as_str()).collect();
        goniospec(&refs)
    };
    let (code, _, err) = run(args(false));
    assert_eq!(code, 1);
    assert!(err.contains("angles.csv"), "{err}");
    assert_eq!(
        std::fs::read_to_string(out.join("angles.csv")).unwrap(),
        "mine"
    );
    let (code, text, err) = run(args(true));
    assert_eq!(code, 0, "{err}");
    assert!(text.contains("grid: B's incident angles"), "{text}");
    assert!(
        text.contains("A: gold.gsa") && text.contains("[simulated]"),
        "{text}"
    );
    assert!(text.contains("B: paper_white_rgb.bsdf (White A4 paper (160 gsm)) [measured]"));
    for t in ["68.57", "78.46"] {
        assert!(
            text.lines()
                .any(|l| l.contains(t) && l.contains("outside the simulated incidence 0.0-60.0")),
            "{t}: {text}"
        );
    }
    assert!(text.contains("grazing incidence"), "{text}");
    let rows = angle_rows(&out);
    let angles: Vec<f64> = rows.iter().map(|r| r[0]).collect();
    assert_eq!(angles.len(), 5, "{angles:?}");
    assert!(
        rows.iter()
            .all(|r| r[1..].iter().all(|v| v.is_finite() && *v > 1.0))
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("compare.json")).unwrap()).unwrap();
    assert_eq!(json["angles"].as_array().unwrap().len(), 5);
    assert_eq!(json["travel"].as_array().unwrap().len(), 6);
    let png = std::fs::read(out.join("compare.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    let svg = std::fs::read_to_string(out.join("compare.svg")).unwrap();
    assert_eq!(svg.matches("data:image/png;base64,").count(), 15);
    // The folder may not be an input.
    let (code, _, err) = goniospec(&[
        "compare",
        gsa.to_str().unwrap(),
        paper.to_str().unwrap(),
        "-o",
        gsa.to_str().unwrap(),
    ]);
    assert_eq!(code, 1);
    assert!(err.contains("input"), "{err}");
    // Two simulations: the first one's angles and buckets; a .gsa against itself is 0.
    let (code, text, err) = goniospec(&["compare", gsa.to_str().unwrap(), gsa.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    assert!(text.contains("grid: A's incident angles"), "{text}");
    assert!(
        text.contains("all angles: dE mean 0.00, median 0.00, p95 0.00"),
        "{text}"
    );
}
