//! Helpers shared by the physics tests: scratch folders, samples written on the fly, an
//! independent transfer-matrix method, and a simulation with test defaults.
#![allow(dead_code)]

pub mod measured;

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

/// The repository root.
pub fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// A shipped sample, `meshes/NAME`.
pub fn shipped(name: &str) -> Sample {
    sample::load(&root().join("meshes").join(name), MeshOptions::default())
        .unwrap_or_else(|e| panic!("{e}"))
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

/// `cfg` run on `s` in a pool of one thread (results must not depend on the count).
pub fn run_on_one_thread(s: &Sample, cfg: &SimConfig) -> Accumulator {
    rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| run(s, cfg))
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
    let ([(rs, ts), (rp, tp)], ncos) = tmm_ref_amplitudes(n, d, lambda, theta0);
    let last = n.len() - 1;
    let ratio_s = ncos[last].re / ncos[0].re;
    let ratio_p =
        (n[last] * (ncos[last] / n[last]).conj()).re / (n[0] * (ncos[0] / n[0]).conj()).re;
    (
        0.5 * (rs.norm_sqr() + rp.norm_sqr()),
        0.5 * (ts.norm_sqr() * ratio_s + tp.norm_sqr() * ratio_p),
    )
}

/// The reflectances `(R_s, R_p)` of [`tmm_ref`]'s recursion, per polarisation.
pub fn tmm_ref_pol(n: &[C], d: &[f64], lambda: f64, theta0: f64) -> (f64, f64) {
    let ([(rs, _), (rp, _)], _) = tmm_ref_amplitudes(n, d, lambda, theta0);
    (rs.norm_sqr(), rp.norm_sqr())
}

/// The recursion of [`tmm_ref`]: amplitude `(r, t)` for s and p, and the normal indices
/// `n_j cos(theta_j)` of every medium.
fn tmm_ref_amplitudes(n: &[C], d: &[f64], lambda: f64, theta0: f64) -> ([(C, C); 2], Vec<C>) {
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
    let pol = |p: bool| -> (C, C) {
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
        (r, t)
    };
    ([pol(false), pol(true)], ncos)
}

/// A quarter-wave mirror `(HL)^pairs` of n = 2.4 / 1.46 centred at 550 nm on glass 1.52:
/// the media lines (air, h, l, glass) and the layers, top first.
pub fn quarter_wave_mirror(pairs: usize) -> (&'static str, Vec<(&'static str, f64)>) {
    let (dh, dl) = (550.0 / (4.0 * 2.4), 550.0 / (4.0 * 1.46));
    (
        "[media.air]\nn = 1.0\n[media.h]\nn = 2.4\n[media.l]\nn = 1.46\n[media.glass]\nn = 1.52\n",
        (0..pairs).flat_map(|_| [("h", dh), ("l", dl)]).collect(),
    )
}

/// TOML for a `[stack]` sample in `mode` ("coating" or "mesh") from `media` lines and layers.
pub fn stack_toml(
    name: &str,
    mode: &str,
    media: &str,
    layers: &[(&str, f64)],
    substrate: &str,
) -> String {
    let layers: Vec<String> = layers
        .iter()
        .map(|(m, t)| format!("{{ medium = \"{m}\", thickness = {t:?} }}"))
        .collect();
    format!(
        "[sample]\nname = \"{name}\"\nunit = \"nm\"\ntile = [20000.0, 20000.0]\n{media}\n[stack]\nmode = \"{mode}\"\nambient = \"air\"\nlayers = [{}]\nsubstrate = \"{substrate}\"\n",
        layers.join(", ")
    )
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

/// Runs the `goniospec` binary from the crate's root: `(exit status, stdout, stderr)`.
pub fn goniospec(args: &[&str]) -> (i32, String, String) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_goniospec"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("run goniospec");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Fresnel amplitude coefficients from `n1` onto `n2` at `theta` (radians, in `n1`):
/// `(r_p, r_s)`, `r_s` of the electric field and `r_p` of the magnetic field (the transverse
/// one of a TM wave), Born & Wolf §1.5.2, with `n cos theta_t = sqrt(n^2 - n1^2 sin^2
/// theta)` on the decaying branch (imaginary part not negative); written independently of
/// the library.
pub fn fresnel_amplitudes(n1: C, n2: C, theta: f64) -> (C, C) {
    let s = n1 * theta.sin();
    let nc = |n: C| {
        let v = (n * n - s * s).sqrt();
        if v.im < 0.0 { -v } else { v }
    };
    let (q1, q2) = (nc(n1), nc(n2));
    let (c1, c2) = (q1 / n1, q2 / n2);
    let rs = (q1 - q2) / (q1 + q2);
    let rp = (n2 * c1 - n1 * c2) / (n2 * c1 + n1 * c2);
    (rp, rs)
}

/// A flat interface from air (n = 1) onto a substrate of index `n + i k`, meshed.
pub fn flat_substrate(tag: &str, n: f64, k: f64) -> Sample {
    stack_sample(
        tag,
        &format!("[media.air]\nn = 1.0\n[media.substrate]\nn = {n:?}\nk = {k:?}\n"),
        "air",
        &[],
        "substrate",
    )
}

/// A sinusoidal grating `z = A sin(2 pi x / period)` (nm) between air above and a medium of
/// index `n + ik`, `periods` periods wide and `period / 8` deep in y, `segments` facets per
/// period.
pub fn sinusoid(
    tag: &str,
    period: f64,
    amp: f64,
    (n, k): (f64, f64),
    segments: usize,
    periods: usize,
) -> Sample {
    let d = scratch(tag);
    let ly = period / 8.0;
    let total = segments * periods;
    let width = period * periods as f64;
    let mut obj = String::new();
    for i in 0..=total {
        let x = width * i as f64 / total as f64;
        let z = amp * (2.0 * std::f64::consts::PI * x / period).sin();
        obj.push_str(&format!("v {x:?} 0 {z:?}\nv {x:?} {ly:?} {z:?}\n"));
    }
    for i in 0..total {
        let (a, b, c, e) = (2 * i + 1, 2 * i + 3, 2 * i + 4, 2 * i + 2);
        obj.push_str(&format!("f {a} {b} {c}\nf {a} {c} {e}\n"));
    }
    std::fs::write(d.join("grating.obj"), obj).unwrap();
    sample_in(
        &d,
        &format!(
            "[sample]\nname = \"grating\"\nunit = \"nm\"\ntile = [{width:?}, {ly:?}]\n[media.air]\nn = 1.0\n[media.m]\nn = {n:?}\nk = {k:?}\n[[interface]]\nmesh = \"grating.obj\"\nfront = \"air\"\nback = \"m\"\n"
        ),
    )
}

/// Solves `a x = b` by Gaussian elimination with partial pivoting (`a` row-major, n x n).
pub fn gauss(mut a: Vec<C>, mut b: Vec<C>) -> Vec<C> {
    let n = b.len();
    for c in 0..n {
        let p = (c..n)
            .max_by(|&i, &j| a[i * n + c].norm().total_cmp(&a[j * n + c].norm()))
            .unwrap();
        if p != c {
            for k in 0..n {
                a.swap(p * n + k, c * n + k);
            }
            b.swap(p, c);
        }
        let piv = a[c * n + c];
        for r in c + 1..n {
            let f = a[r * n + c] / piv;
            if f == C::new(0.0, 0.0) {
                continue;
            }
            for k in c..n {
                let v = a[c * n + k];
                a[r * n + k] -= f * v;
            }
            let v = b[c];
            b[r] -= f * v;
        }
    }
    let mut x = vec![C::new(0.0, 0.0); n];
    for r in (0..n).rev() {
        let mut s = b[r];
        for k in r + 1..n {
            s -= a[r * n + k] * x[k];
        }
        x[r] = s / a[r * n + r];
    }
    x
}

/// `kz / k0 = sqrt(eps − kt²)` on the branch with `Im ≥ 0` (a down-going or downward-decaying
/// wave's, as `e^{−i kz z}`; the up-going one's as `e^{i kz z}`).
pub fn kz(eps: C, alpha: f64) -> C {
    let b = (eps - alpha * alpha).sqrt();
    if b.im < 0.0 || (b.im == 0.0 && b.re < 0.0) {
        -b
    } else {
        b
    }
}
