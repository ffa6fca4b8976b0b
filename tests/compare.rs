//! `goniospec compare`: identical materials differ by nothing; two materials of known
//! colours differ by the published CIEDE2000 of those colours (Sharma, Wu & Dalal 2005,
//! Table 1), computed here from CIELAB through an independent inverse of the colour
//! chain; the grid, what is left out and why, the exit status for scripts, and the files.

mod common;

use common::measured::lambertian_file;
use common::*;
use goniospec::export::tensor;

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

fn write(d: &std::path::Path, name: &str, lab: [f64; 3]) -> String {
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
        let fa = write(&d, &format!("a{k}.bsdf"), a);
        let fb = write(&d, &format!("b{k}.bsdf"), b);
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
    let fa = write(&d, "a.bsdf", [50.0, 2.5, 0.0]);
    let fb = write(&d, "b.bsdf", [73.0, 25.0, -18.0]);
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
