//! Helpers shared by the physics tests: scratch folders, samples written on the fly, an
//! independent transfer-matrix method, and a simulation with test defaults.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use goniospec::accumulate::file::Accumulator;
use goniospec::sample::{self, MeshOptions, Sample};
use goniospec::simulate::{SimConfig, Wavelengths, simulate};
use num_complex::Complex64 as C;

pub fn scratch(tag: &str) -> PathBuf {
    static N: AtomicUsize = AtomicUsize::new(0);
    let d = std::env::temp_dir().join(format!(
        "goniospec-phys-{}-{tag}-{}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    ));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Writes `toml` as a sample file in a fresh folder and loads it.
pub fn sample_from(tag: &str, toml: &str) -> Sample {
    let d = scratch(tag);
    std::fs::write(d.join("s.toml"), toml).unwrap();
    sample::load(&d.join("s.toml"), MeshOptions::default()).unwrap_or_else(|e| panic!("{e}"))
}

pub fn sample_in(dir: &Path, toml: &str) -> Sample {
    std::fs::write(dir.join("s.toml"), toml).unwrap();
    sample::load(&dir.join("s.toml"), MeshOptions::default()).unwrap_or_else(|e| panic!("{e}"))
}

/// A flat stack sample: `media` lines, then ambient / layers / substrate, every layer
/// boundary meshed and ray-traced (`mode = "mesh"`: these tests check the tracer).
pub fn stack_sample(
    tag: &str,
    media: &str,
    ambient: &str,
    layers: &[(&str, f64)],
    substrate: &str,
) -> Sample {
    let layers: Vec<String> = layers
        .iter()
        .map(|(m, t)| format!("{{ medium = \"{m}\", thickness = {t:?} }}"))
        .collect();
    sample_from(
        tag,
        &format!(
            "[sample]\nname = \"{tag}\"\nunit = \"nm\"\ntile = [20000.0, 20000.0]\n{media}\n[stack]\nmode = \"mesh\"\nambient = \"{ambient}\"\nlayers = [{}]\nsubstrate = \"{substrate}\"\n",
            layers.join(", ")
        ),
    )
}

/// The library's defaults (beamlet, 5 um, 45 x 36 buckets, seed 1) for the tests.
pub fn config(theta_i: &[f64], wavelengths: Wavelengths, rays: u64) -> SimConfig {
    SimConfig::new(theta_i.to_vec(), wavelengths, rays)
}

pub fn run(s: &Sample, cfg: &SimConfig) -> Accumulator {
    simulate(s, cfg, &|_| {})
        .unwrap_or_else(|e| panic!("{e}"))
        .0
}

/// (R, T) totals of cell (i, j).
pub fn totals(acc: &Accumulator, i: usize, j: usize) -> (f64, f64) {
    let s = &acc.header.settings;
    acc.cell(i, j).totals(s.coherence_mode(), &s.buckets())
}

/// Independent transfer-matrix method, written here without the library: the recursive
/// (Airy / Rouard) form. Working upwards from the substrate, the reflection coefficient
/// seen from the top of layer j is `r_j = (r_{j,j+1} + R_{j+1} e^{2 i beta}) / (1 + r_{j,j+1}
/// R_{j+1} e^{2 i beta})` with `beta = 2 pi n_j cos_j d_j / lambda` (Heavens, Optical
/// Properties of Thin Solid Films, 1955, §4; Macleod, Thin-Film Optical Filters, §2.6), and
/// the transmission coefficients multiply likewise. Returns (R, T) for unpolarised light.
pub fn tmm_ref(n: &[C], d: &[f64], lambda: f64, theta0: f64) -> (f64, f64) {
    let kx = n[0] * theta0.sin();
    let ncos: Vec<C> = n
        .iter()
        .map(|&nj| {
            let mut v = (nj * nj - kx * kx).sqrt();
            if v.im < 0.0 || (v.im.abs() < 1e-15 && v.re < 0.0) {
                v = -v;
            }
            v
        })
        .collect();
    let last = n.len() - 1;
    let mut out = (0.0, 0.0);
    for p in [false, true] {
        // Interface coefficients between j and j+1.
        let coef = |j: usize| -> (C, C) {
            let (a, b) = (ncos[j], ncos[j + 1]);
            if p {
                // p: in terms of n and cos: cos = ncos / n.
                let (ca, cb) = (a / n[j], b / n[j + 1]);
                let den = n[j + 1] * ca + n[j] * cb;
                ((n[j + 1] * ca - n[j] * cb) / den, 2.0 * n[j] * ca / den)
            } else {
                ((a - b) / (a + b), 2.0 * a / (a + b))
            }
        };
        let (mut r, mut t) = coef(last - 1);
        for j in (1..last).rev() {
            let beta = 2.0 * std::f64::consts::PI * ncos[j] * d[j - 1] / lambda;
            let e1 = (C::i() * beta).exp();
            let e2 = e1 * e1;
            let (rj, tj) = coef(j - 1);
            let den = C::new(1.0, 0.0) + rj * r * e2;
            let r_new = (rj + r * e2) / den;
            t = tj * t * e1 / den;
            r = r_new;
        }
        let ratio = if p {
            (n[last] * (ncos[last] / n[last]).conj()).re / (n[0] * (ncos[0] / n[0]).conj()).re
        } else {
            ncos[last].re / ncos[0].re
        };
        out.0 += 0.5 * r.norm_sqr();
        out.1 += 0.5 * t.norm_sqr() * ratio;
    }
    out
}

/// The reflectances `(R_s, R_p)` of [`tmm_ref`]'s recursion, per polarisation.
pub fn tmm_ref_pol(n: &[C], d: &[f64], lambda: f64, theta0: f64) -> (f64, f64) {
    let kx = n[0] * theta0.sin();
    let ncos: Vec<C> = n
        .iter()
        .map(|&nj| {
            let mut v = (nj * nj - kx * kx).sqrt();
            if v.im < 0.0 || (v.im.abs() < 1e-15 && v.re < 0.0) {
                v = -v;
            }
            v
        })
        .collect();
    let last = n.len() - 1;
    let pol = |p: bool| {
        let coef = |j: usize| -> (C, C) {
            let (a, b) = (ncos[j], ncos[j + 1]);
            if p {
                let (ca, cb) = (a / n[j], b / n[j + 1]);
                let den = n[j + 1] * ca + n[j] * cb;
                ((n[j + 1] * ca - n[j] * cb) / den, 2.0 * n[j] * ca / den)
            } else {
                ((a - b) / (a + b), 2.0 * a / (a + b))
            }
        };
        let (mut r, _) = coef(last - 1);
        for j in (1..last).rev() {
            let e2 = (C::i() * 4.0 * std::f64::consts::PI * ncos[j] * d[j - 1] / lambda).exp();
            let (rj, _) = coef(j - 1);
            r = (rj + r * e2) / (C::new(1.0, 0.0) + rj * r * e2);
        }
        r.norm_sqr()
    };
    (pol(false), pol(true))
}

/// The independent TMM averaged over a wavelength band by fine sampling (midpoint rule).
pub fn tmm_band(n: impl Fn(f64) -> Vec<C>, d: &[f64], lo: f64, hi: f64, theta0: f64) -> (f64, f64) {
    let steps = 4000;
    let (mut r, mut t) = (0.0, 0.0);
    for i in 0..steps {
        let l = lo + (hi - lo) * (i as f64 + 0.5) / steps as f64;
        let (a, b) = tmm_ref(&n(l), d, l, theta0);
        r += a / steps as f64;
        t += b / steps as f64;
    }
    (r, t)
}

pub fn c(n: f64, k: f64) -> C {
    C::new(n, k)
}
