//! Spectra to colour: CIE 1931 2-degree colour matching functions and illuminant D65
//! (tables shipped in `data/colour/`, sources named there), XYZ to linear sRGB, the sRGB
//! transfer function, CIELAB and CIE DE2000.

use std::sync::OnceLock;

const CMF_CSV: &str = include_str!("../../data/colour/cie1931-2deg.csv");
const D65_CSV: &str = include_str!("../../data/colour/cie-d65.csv");

fn parse(text: &str, cols: usize) -> Vec<Vec<f64>> {
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with("lambda"))
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let v: Vec<f64> = l
                .split(',')
                .map(|x| x.trim().parse().expect("shipped table is numeric"))
                .collect();
            assert_eq!(v.len(), cols, "shipped table row has {cols} columns");
            v
        })
        .collect()
}

/// The colour-matching functions at 1 nm from 360 to 830 nm and D65 interpolated to them.
struct Tables {
    lambda: Vec<f64>,
    xyz: Vec<[f64; 3]>,
    d65: Vec<f64>,
    /// `1 / sum(D65 y_bar)` over the whole table: a perfect white has Y = 1.
    norm: f64,
}

fn tables() -> &'static Tables {
    static T: OnceLock<Tables> = OnceLock::new();
    T.get_or_init(|| {
        let cmf = parse(CMF_CSV, 4);
        let d65 = parse(D65_CSV, 2);
        let d65_at = |l: f64| -> f64 {
            if l < d65[0][0] || l > d65[d65.len() - 1][0] {
                return 0.0;
            }
            let i = d65.partition_point(|r| r[0] <= l).clamp(1, d65.len() - 1);
            let t = (l - d65[i - 1][0]) / (d65[i][0] - d65[i - 1][0]);
            d65[i - 1][1] + t * (d65[i][1] - d65[i - 1][1])
        };
        let lambda: Vec<f64> = cmf.iter().map(|r| r[0]).collect();
        let s: Vec<f64> = lambda.iter().map(|&l| d65_at(l)).collect();
        let y: f64 = cmf.iter().zip(&s).map(|(r, s)| r[2] * s).sum();
        Tables {
            xyz: cmf.iter().map(|r| [r[1], r[2], r[3]]).collect(),
            d65: s,
            lambda,
            norm: 1.0 / y,
        }
    })
}

/// Per-bin weights that turn a reflectance spectrum into XYZ under D65:
/// `XYZ = sum_b R_b W_b` with `W_b = k * integral over bin b of D65 * cmf` (1 nm steps),
/// `k` normalising a perfect white (R = 1 everywhere) to Y = 1 (CIE 15:2004 §7.1).
/// Bins are given by their centres (edges at the midpoints; the outer bins as wide as
/// their neighbours).
pub fn bin_weights(centres_nm: &[f64]) -> Vec<[f64; 3]> {
    let t = tables();
    let n = centres_nm.len();
    let edge = |i: usize| -> f64 {
        if n == 1 {
            return if i == 0 {
                centres_nm[0] - 5.0
            } else {
                centres_nm[0] + 5.0
            };
        }
        if i == 0 {
            centres_nm[0] - 0.5 * (centres_nm[1] - centres_nm[0])
        } else if i == n {
            centres_nm[n - 1] + 0.5 * (centres_nm[n - 1] - centres_nm[n - 2])
        } else {
            0.5 * (centres_nm[i - 1] + centres_nm[i])
        }
    };
    (0..n)
        .map(|b| {
            let (lo, hi) = (edge(b), edge(b + 1));
            let mut w = [0.0; 3];
            for (k, &l) in t.lambda.iter().enumerate() {
                // 1 nm cells [l - 0.5, l + 0.5) overlapping the bin.
                let overlap = ((l + 0.5).min(hi) - (l - 0.5).max(lo)).max(0.0);
                for (wc, xc) in w.iter_mut().zip(&t.xyz[k]) {
                    *wc += overlap * t.d65[k] * xc * t.norm;
                }
            }
            w
        })
        .collect()
}

/// XYZ of a reflectance (or radiance factor) spectrum with the weights of [`bin_weights`].
pub fn xyz(spectrum: &[f64], weights: &[[f64; 3]]) -> [f64; 3] {
    let mut x = [0.0; 3];
    for (r, w) in spectrum.iter().zip(weights) {
        for (xc, wc) in x.iter_mut().zip(w) {
            *xc += r * wc;
        }
    }
    x
}

/// XYZ (D65 white) to linear sRGB: IEC 61966-2-1:1999, eq. for the inverse matrix.
pub fn xyz_to_linear_srgb(x: [f64; 3]) -> [f64; 3] {
    [
        3.2406 * x[0] - 1.5372 * x[1] - 0.4986 * x[2],
        -0.9689 * x[0] + 1.8758 * x[1] + 0.0415 * x[2],
        0.0557 * x[0] - 0.2040 * x[1] + 1.0570 * x[2],
    ]
}

/// Linear sRGB to XYZ (D65 white, Y = 1 for white): the exact inverse of
/// [`xyz_to_linear_srgb`]'s matrix, so that a colour goes there and back unchanged, and
/// `(1, 1, 1)` is the matrix's own white `(0.9505, 1.0000, 1.0890)`.
pub fn linear_srgb_to_xyz(rgb: [f64; 3]) -> [f64; 3] {
    static M: OnceLock<glam::DMat3> = OnceLock::new();
    let m = M.get_or_init(|| {
        glam::DMat3::from_cols_array(&[
            3.2406, -0.9689, 0.0557, -1.5372, 1.8758, -0.2040, -0.4986, 0.0415, 1.0570,
        ])
        .inverse()
    });
    (*m * glam::DVec3::from_array(rgb)).to_array()
}

/// The XYZ weights of each channel of a BRDF under D65 (`XYZ = sum_c value_c W_c` for a
/// reflectance-like quantity): [`bin_weights`] for wavelength bins, and for linear sRGB
/// channels (`Meta::rgb`, a measured file in the RGB form) the columns of
/// [`linear_srgb_to_xyz`].
pub fn channel_weights(meta: &crate::brdf::Meta) -> Vec<[f64; 3]> {
    if meta.rgb {
        [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
            .iter()
            .map(|&c| linear_srgb_to_xyz(c))
            .collect()
    } else {
        bin_weights(&meta.lambda_nm)
    }
}

/// sRGB transfer function (IEC 61966-2-1), input clamped to [0, 1].
pub fn srgb_encode(v: f64) -> f64 {
    let v = v.clamp(0.0, 1.0);
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// The D65 white point of the shipped tables (X, Y, Z with Y = 1).
pub fn white_xyz() -> [f64; 3] {
    let t = tables();
    let mut w = [0.0; 3];
    for (s, x) in t.d65.iter().zip(&t.xyz) {
        for (wc, xc) in w.iter_mut().zip(x) {
            *wc += s * xc * t.norm;
        }
    }
    w
}

/// CIELAB of XYZ relative to `white` (CIE 15:2004 §8.2.1).
pub fn lab(x: [f64; 3], white: [f64; 3]) -> [f64; 3] {
    let f = |t: f64| {
        if t > (6.0f64 / 29.0).powi(3) {
            t.cbrt()
        } else {
            t / (3.0 * (6.0f64 / 29.0).powi(2)) + 4.0 / 29.0
        }
    };
    let (fx, fy, fz) = (f(x[0] / white[0]), f(x[1] / white[1]), f(x[2] / white[2]));
    [116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)]
}

/// CIE DE2000 colour difference (Sharma, Wu & Dalal, "The CIEDE2000 color-difference
/// formula: implementation notes, supplementary test data, and mathematical
/// observations", Color Res. Appl. 30(1), 2005, eqs. 1–23).
pub fn delta_e2000(l1: [f64; 3], l2: [f64; 3]) -> f64 {
    use std::f64::consts::PI;
    let deg = PI / 180.0;
    let (c1, c2) = (
        (l1[1].powi(2) + l1[2].powi(2)).sqrt(),
        (l2[1].powi(2) + l2[2].powi(2)).sqrt(),
    );
    let cbar7 = ((c1 + c2) / 2.0).powi(7);
    let g = 0.5 * (1.0 - (cbar7 / (cbar7 + 25f64.powi(7))).sqrt());
    let (a1, a2) = ((1.0 + g) * l1[1], (1.0 + g) * l2[1]);
    let (cp1, cp2) = (
        (a1 * a1 + l1[2] * l1[2]).sqrt(),
        (a2 * a2 + l2[2] * l2[2]).sqrt(),
    );
    let hue = |b: f64, a: f64| {
        if b == 0.0 && a == 0.0 {
            0.0
        } else {
            b.atan2(a).rem_euclid(2.0 * PI)
        }
    };
    let (h1, h2) = (hue(l1[2], a1), hue(l2[2], a2));
    let dl = l2[0] - l1[0];
    let dc = cp2 - cp1;
    let dh = if cp1 * cp2 == 0.0 {
        0.0
    } else {
        let d = h2 - h1;
        if d.abs() <= PI {
            d
        } else if d > PI {
            d - 2.0 * PI
        } else {
            d + 2.0 * PI
        }
    };
    let dhh = 2.0 * (cp1 * cp2).sqrt() * (dh / 2.0).sin();
    let lbar = (l1[0] + l2[0]) / 2.0;
    let cbar = (cp1 + cp2) / 2.0;
    let hbar = if cp1 * cp2 == 0.0 {
        h1 + h2
    } else if (h1 - h2).abs() <= PI {
        (h1 + h2) / 2.0
    } else if h1 + h2 < 2.0 * PI {
        (h1 + h2 + 2.0 * PI) / 2.0
    } else {
        (h1 + h2 - 2.0 * PI) / 2.0
    };
    let t = 1.0 - 0.17 * (hbar - 30.0 * deg).cos()
        + 0.24 * (2.0 * hbar).cos()
        + 0.32 * (3.0 * hbar + 6.0 * deg).cos()
        - 0.20 * (4.0 * hbar - 63.0 * deg).cos();
    let dtheta = 30.0 * deg * (-((hbar / deg - 275.0) / 25.0).powi(2)).exp();
    let rc = 2.0 * (cbar.powi(7) / (cbar.powi(7) + 25f64.powi(7))).sqrt();
    let sl = 1.0 + 0.015 * (lbar - 50.0).powi(2) / (20.0 + (lbar - 50.0).powi(2)).sqrt();
    let sc = 1.0 + 0.045 * cbar;
    let sh = 1.0 + 0.015 * cbar * t;
    let rt = -(2.0 * dtheta).sin() * rc;
    ((dl / sl).powi(2) + (dc / sc).powi(2) + (dhh / sh).powi(2) + rt * (dc / sc) * (dhh / sh))
        .sqrt()
}
