//! `goniospec export --format rgl`: what a user sees, and what the file holds (read back
//! with the tensor reader; Mitsuba's own reading is `make interop`).

mod common;

use common::*;
use goniospec::export::tensor;

fn built(d: &std::path::Path, toml: &str, name: &str) -> String {
    let gsa = d.join(format!("{name}.gsa"));
    let gsb = d.join(format!("{name}.gsb"));
    let (code, _, err) = goniospec(&[
        "simulate",
        toml,
        "--theta-i",
        "0,30,60",
        "--rays",
        "256",
        "--wavelengths",
        "400:700:50",
        "-o",
        gsa.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let (code, _, err) = goniospec(&[
        "build",
        gsa.to_str().unwrap(),
        "--repr",
        "table",
        "-o",
        gsb.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    gsb.to_str().unwrap().to_string()
}

/// The fields Mitsuba's measured.cpp requires, with its dtypes and shape relations; the
/// file is the same whatever the thread count; `info` describes it.
#[test]
fn rgl_export_writes_the_fields_the_readers_require() {
    let d = scratch("export-rgl");
    let gsb = built(&d, "meshes/rough-gold.toml", "gold");
    let out = |threads: &str| {
        let p = d.join(format!("gold-{threads}.bsdf"));
        let (code, text, err) = goniospec(&[
            "export",
            &gsb,
            "--sample",
            "meshes/rough-gold.toml",
            "--resolution",
            "17",
            "--threads",
            threads,
            // Simulated at 0, 30 and 60 deg: held from 60 to 90.
            "--force",
            "-o",
            p.to_str().unwrap(),
        ]);
        assert_eq!(code, 0, "{err}");
        assert!(text.contains("17 x 17 warped grid"), "{text}");
        std::fs::read(p).unwrap()
    };
    let bytes = out("1");
    assert_eq!(bytes, out("2"), "thread count changed the file");
    let fields = tensor::from_bytes(&bytes).unwrap();
    let get = |n: &str| {
        fields
            .iter()
            .find(|f| f.name == n)
            .unwrap_or_else(|| panic!("{n}"))
    };
    use tensor::Dtype::{Float32, UInt8};
    for (name, dtype, shape) in [
        ("description", UInt8, None),
        ("theta_i", Float32, Some(vec![13])),
        ("phi_i", Float32, Some(vec![1])),
        ("wavelengths", Float32, Some(vec![6])),
        ("ndf", Float32, Some(vec![17, 17])),
        ("sigma", Float32, Some(vec![17, 17])),
        ("vndf", Float32, Some(vec![1, 13, 17, 17])),
        ("luminance", Float32, Some(vec![1, 13, 17, 17])),
        ("spectra", Float32, Some(vec![1, 13, 6, 17, 17])),
        ("jacobian", UInt8, Some(vec![1])),
    ] {
        let f = get(name);
        assert_eq!(f.dtype, dtype, "{name}");
        if let Some(s) = shape {
            assert_eq!(f.shape, s, "{name}");
        }
    }
    assert_eq!(get("jacobian").data, vec![1]);
    // Simulated at 0, 30 and 60 deg, tabulated every 5 deg between them (the reader's
    // interpolation in theta_i then follows the table's: export::rgl_incidence).
    let theta: Vec<f64> = get("theta_i").values_f64();
    assert_eq!(theta.len(), 13);
    for (k, t) in theta.iter().enumerate() {
        assert!(
            (t - (5.0 * k as f64).to_radians()).abs() < 1e-6,
            "{theta:?}"
        );
    }
    // D(m) is normalised over projected area: int D cos dm = 1 (trapezoid over u, with
    // dm = 2 pi^2 u sin(theta) du), to the quadrature error of a 17^2 grid.
    let ndf = get("ndf").values_f64();
    let n = 17;
    let mut integral = 0.0;
    for p in 0..n {
        for t in 0..n {
            let u = t as f64 / (n - 1) as f64;
            let theta = u * u * std::f64::consts::FRAC_PI_2;
            let w = |k: usize| if k == 0 || k == n - 1 { 0.5 } else { 1.0 };
            integral += w(p)
                * w(t)
                * ndf[p * n + t]
                * theta.cos()
                * 2.0
                * std::f64::consts::PI.powi(2)
                * u
                * theta.sin();
        }
    }
    integral /= ((n - 1) * (n - 1)) as f64;
    assert!((integral - 1.0).abs() < 0.05, "int D cos = {integral}");
    for name in ["ndf", "sigma", "vndf", "luminance", "spectra"] {
        assert!(
            get(name)
                .values_f64()
                .iter()
                .all(|v| v.is_finite() && *v >= 0.0),
            "{name}"
        );
    }
    std::fs::write(d.join("gold.bsdf"), &bytes).unwrap();
    let (code, text, err) = goniospec(&["info", d.join("gold.bsdf").to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    assert!(
        text.contains("RGL tensor file")
            && text.contains("field spectra      float32  [1, 13, 6, 17, 17]"),
        "{text}"
    );
}

/// The stored albedo of a `.bsdf`'s slice `k` at wavelength `j`, as the reader integrates
/// it: `A = (int vndf du / sigma(wi)) int V(s) ds` with the exact trapezoid sums of the
/// bilinear interpolants (the change of variables `wo <- m <- u <- s` of Dupuy & Jakob
/// 2018; tests/interop/rgl_mitsuba.py step 3 does the same).
fn stored_albedo(fields: &[tensor::Field], k: usize, j: usize) -> f64 {
    let get = |n: &str| fields.iter().find(|f| f.name == n).unwrap();
    let n = get("ndf").shape[0] as usize;
    let nl = get("wavelengths").shape[0] as usize;
    let theta = get("theta_i").values_f64()[k];
    let trapezoid = |v: &[f64]| {
        let w = |i: usize| if i == 0 || i == n - 1 { 0.5 } else { 1.0 };
        let mut s = 0.0;
        for y in 0..n {
            for x in 0..n {
                s += w(x) * w(y) * v[y * n + x];
            }
        }
        s / ((n - 1) * (n - 1)) as f64
    };
    // sigma at u = (sqrt(2 theta / pi), phi2u(0) = 1/2), bilinear.
    let sigma = get("sigma").values_f64();
    let (ut, up) = ((theta * 2.0 / std::f64::consts::PI).sqrt(), 0.5);
    let (px, py) = (ut * (n - 1) as f64, up * (n - 1) as f64);
    let (ox, oy) = ((px as usize).min(n - 2), (py as usize).min(n - 2));
    let (fx, fy) = (px - ox as f64, py - oy as f64);
    let at = |x: usize, y: usize| sigma[y * n + x];
    let s = (1.0 - fy) * ((1.0 - fx) * at(ox, oy) + fx * at(ox + 1, oy))
        + fy * ((1.0 - fx) * at(ox, oy + 1) + fx * at(ox + 1, oy + 1));
    let vndf = get("vndf").values_f64();
    let spectra = get("spectra").values_f64();
    let slice = |v: &[f64], off: usize| v[off..off + n * n].to_vec();
    trapezoid(&slice(&vndf, k * n * n)) / s * trapezoid(&slice(&spectra, (k * nl + j) * n * n))
}

/// A flat film's mirror lobe (issue 46: it was refused) is written as the simulation
/// measured it, at the bucket aperture, with a note naming it. The stored albedo is the
/// table's own (its reflectance integrated over the hemisphere on a 720 x 720 midpoint
/// grid) within 3 % and 1e-3 at 0 and 30 degrees: the export keeps the lobe's energy;
/// and both are the flat soap film's reflectance from the independent transfer-matrix
/// method (600 nm, n 1.33, band-averaged over each 50 nm bin) within 10 %: a lobe one
/// bucket wide, interpolated between bucket centres in angle, gains up to 7 % at the pole,
/// where the interpolated tent covers more solid angle than the bucket (measured 6.8 % at
/// 0 degrees and 475 nm). Refusals: another sample than the BRDF's, an even resolution,
/// and an output that is another kind of file.
#[test]
fn rgl_export_holds_a_mirror_lobe_and_refuses_what_it_cannot_write() {
    let d = scratch("export-refusals");
    let flat = built(&d, "meshes/flat-soap-film.toml", "flat");
    let p = d.join("x.bsdf");
    // Simulated at 0, 30 and 60 deg only: refused, naming the angles held, unless forced
    // (issue 71).
    let (code, _, err) = goniospec(&[
        "export",
        &flat,
        "--sample",
        "meshes/flat-soap-film.toml",
        "-o",
        p.to_str().unwrap(),
    ]);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("simulated at incident angles 0, 30, 60 deg only")
            && err.contains("from 60 to 90 deg")
            && err.contains("--force"),
        "{err}"
    );
    assert!(!p.exists());
    let (code, _, err) = goniospec(&[
        "export",
        &flat,
        "--sample",
        "meshes/flat-soap-film.toml",
        "--force",
        "-o",
        p.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("written so by --force"), "{err}");
    assert!(
        err.contains("written as a sharp lobe of the same power")
            && err.contains("spread by 0.35 deg"),
        "{err}"
    );
    let fields = tensor::from_bytes(&std::fs::read(&p).unwrap()).unwrap();
    let lambdas: Vec<f64> = fields
        .iter()
        .find(|f| f.name == "wavelengths")
        .unwrap()
        .values_f64();
    // The mirror is written as a sharp lobe carrying the buckets' power: the file holds
    // the run's own R (the sum over its buckets) and the film's, by an independent TMM. The
    // table's interpolant is no reference at the pole: it spreads the first ring's value
    // over a tent to the second ring's centres, 8 % more than the ring holds.
    let gsa = flat.replace(".gsb", ".gsa");
    // The file's slices are every 5 deg: 30 deg is the seventh.
    for (k, theta) in [(0usize, 0.0f64), (6, 30.0)] {
        let (code, csv, err) = goniospec(&["reflectance", &gsa, "--theta-i", &theta.to_string()]);
        assert_eq!(code, 0, "{err}");
        let own: Vec<f64> = csv
            .lines()
            .skip(1)
            .map(|l| l.split(',').nth(1).unwrap().parse().unwrap())
            .collect();
        for (j, &l) in lambdas.iter().enumerate() {
            let (r, _) = tmm_band(
                |_| vec![c(1.0, 0.0), c(1.33, 0.0), c(1.0, 0.0)],
                &[600.0],
                l - 25.0,
                l + 25.0,
                theta.to_radians(),
            );
            let a = stored_albedo(&fields, k, j);
            assert!(
                (a - own[j]).abs() <= 0.03 * own[j] + 1e-3,
                "{theta} deg, {l} nm: stored albedo {a}, the run's R {}",
                own[j]
            );
            assert!(
                (a - r).abs() <= 0.03 * r + 1e-3,
                "{theta} deg, {l} nm: stored albedo {a}, the run's R {}, TMM {r}",
                own[j]
            );
        }
    }
    // Sharp: read back as the renderers read it, the mirror's value at 30 deg is many
    // times its bucket's (2 x 10 deg), and 3 deg off it the lobe is gone.
    let read = |to: f64, po: f64| -> f64 {
        let (code, out, err) = goniospec(&[
            "eval",
            p.to_str().unwrap(),
            "--theta-i",
            "30",
            "--theta-o",
            &to.to_string(),
            "--phi-o",
            &po.to_string(),
        ]);
        assert_eq!(code, 0, "{err}");
        out.lines()
            .nth(3)
            .unwrap()
            .split(',')
            .nth(1)
            .unwrap()
            .parse()
            .unwrap()
    };
    let (peak, off) = (read(30.0, 180.0), read(33.0, 180.0));
    let table = goniospec::brdf::file::read(std::path::Path::new(&flat)).unwrap();
    let mut bucket = vec![0.0; lambdas.len()];
    let (wi, wo) = (
        goniospec::geom::from_spherical(30f64.to_radians(), 0.0),
        goniospec::geom::from_spherical(31f64.to_radians(), std::f64::consts::PI),
    );
    goniospec::brdf::Brdf::eval(&table, wi, wo, &mut bucket);
    assert!(
        peak > 3.0 * bucket[2],
        "peak {peak}, the bucket's {}",
        bucket[2]
    );
    assert!(off < 0.01 * peak, "3 deg off {off}, peak {peak}");
    // The run knew its top was flat, and `render` draws the same sharp lobe (it says
    // where it cannot); rough gold's top is not flat.
    let flat_top = |gsb: &str| {
        let r = goniospec::brdf::file::read(std::path::Path::new(gsb)).unwrap();
        let s: goniospec::accumulate::file::Settings =
            toml::from_str(&goniospec::brdf::Brdf::meta(&r).simulation).unwrap();
        s.flat_top
    };
    assert!(flat_top(&flat));
    let drawn = |gsb: &str| {
        let r = goniospec::brdf::file::read(std::path::Path::new(gsb)).unwrap();
        goniospec::export::mirror::for_render(&r).unwrap().is_some()
    };
    assert!(
        drawn(&flat),
        "render and the report draw the flat film's mirror sharp"
    );
    let exr = d.join("flat.exr");
    let (code, _, err) = goniospec(&[
        "render",
        &flat,
        "-o",
        exr.to_str().unwrap(),
        "--width",
        "16",
        "--height",
        "16",
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(!err.contains("drawn as the buckets hold it"), "{err}");
    std::fs::remove_file(&p).unwrap();
    let (code, _, err) = goniospec(&[
        "export",
        &flat,
        "--sample",
        "meshes/rough-gold.toml",
        "-o",
        p.to_str().unwrap(),
    ]);
    assert_eq!(code, 1);
    assert!(err.contains("was simulated from"), "{err}");
    // Issue 30: the same name over other media is another sample (only names were
    // compared). Rough gold's description with silver for gold, same name and mesh.
    let gold = built(&d, "meshes/rough-gold.toml", "gold");
    assert!(!flat_top(&gold));
    assert!(!drawn(&gold));
    let other = d.join("other");
    std::fs::create_dir_all(&other).unwrap();
    std::fs::copy(
        root().join("meshes/rough-gold-ggx.obj"),
        other.join("rough-gold-ggx.obj"),
    )
    .unwrap();
    let text = std::fs::read_to_string(root().join("meshes/rough-gold.toml"))
        .unwrap()
        .replace(
            "../data/au-johnson.csv",
            &root().join("data/ag-johnson.csv").display().to_string(),
        );
    std::fs::write(other.join("s.toml"), text).unwrap();
    let (code, _, err) = goniospec(&[
        "export",
        &gold,
        "--sample",
        other.join("s.toml").to_str().unwrap(),
        "-o",
        p.to_str().unwrap(),
    ]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("geometry or media differ"), "{err}");
    assert!(!p.exists());
    let (code, _, err) = goniospec(&[
        "export",
        &flat,
        "--sample",
        "meshes/flat-soap-film.toml",
        "--resolution",
        "16",
        "-o",
        p.to_str().unwrap(),
    ]);
    assert_eq!(code, 1);
    assert!(err.contains("must be odd"), "{err}");
    std::fs::write(&p, "precious").unwrap();
    let (code, _, err) = goniospec(&[
        "export",
        &flat,
        "--sample",
        "meshes/flat-soap-film.toml",
        "-o",
        p.to_str().unwrap(),
    ]);
    assert_eq!(code, 1);
    assert!(err.contains("not an RGL tensor file"), "{err}");
    assert_eq!(std::fs::read_to_string(&p).unwrap(), "precious");
}

/// `--format npz`: the same bytes whatever the thread count; the archive's `brdf` array
/// (read back with npyz from the zip) equals the library's eval on the documented grid.
#[test]
fn npz_export_holds_the_brdf_on_its_grid() {
    use goniospec::brdf::{Brdf, file};
    use goniospec::geom::from_spherical;
    use std::io::Read;
    let d = scratch("export-npz");
    let gsb = built(&d, "meshes/rough-gold.toml", "gold");
    let write = |threads: &str| {
        let p = d.join(format!("g{threads}.npz"));
        let (code, text, err) = goniospec(&[
            "export",
            &gsb,
            "--format",
            "npz",
            "--theta-o-bins",
            "6",
            "--phi-o-bins",
            "4",
            "--threads",
            threads,
            "-o",
            p.to_str().unwrap(),
        ]);
        assert_eq!(code, 0, "{err}");
        assert!(text.contains("brdf[3, 1, 6, 4, 6]"), "{text}");
        std::fs::read(p).unwrap()
    };
    let bytes = write("1");
    assert_eq!(bytes, write("2"));
    let mut zip = zip::ZipArchive::new(std::io::Cursor::new(bytes)).unwrap();
    let mut npy = Vec::new();
    zip.by_name("brdf.npy")
        .unwrap()
        .read_to_end(&mut npy)
        .unwrap();
    let arr = npyz::NpyFile::new(&npy[..]).unwrap();
    assert_eq!(arr.shape(), &[3, 1, 6, 4, 6]);
    let values: Vec<f64> = arr.into_vec().unwrap();
    let r = file::read(std::path::Path::new(&gsb)).unwrap();
    let mut out = vec![0.0; 6];
    for (i, ti) in [0.0f64, 30.0, 60.0].iter().enumerate() {
        for o in 0..6 {
            for q in 0..4 {
                let wi = from_spherical(ti.to_radians(), 0.0);
                let wo = from_spherical(
                    ((o as f64 + 0.5) * 15.0).to_radians(),
                    ((q as f64 + 0.5) * 90.0).to_radians(),
                );
                r.eval(wi, wo, &mut out);
                let at = ((i * 6 + o) * 4 + q) * 6;
                assert_eq!(&values[at..at + 6], &out[..], "{i} {o} {q}");
            }
        }
    }
    for name in [
        "theta_i_deg",
        "phi_i_deg",
        "theta_o_deg",
        "phi_o_deg",
        "lambda_nm",
        "settings_json",
    ] {
        assert!(zip.by_name(&format!("{name}.npy")).is_ok(), "{name}");
    }
}

/// `goniospec plot`: PNG and SVG files that are real images, and the flat film's lobe
/// peaks at the mirror angle (within the table's 2-degree buckets) at every wavelength.
#[test]
fn plot_draws_the_lobe_and_a_flat_film_peaks_at_the_mirror_angle() {
    let d = scratch("plot");
    let gsb = built(&d, "meshes/flat-soap-film.toml", "flat");
    let r = goniospec::brdf::file::read(std::path::Path::new(&gsb)).unwrap();
    let lobe = goniospec::plot::lobe(&r, 30.0, 0.0, 4);
    assert_eq!(lobe.curves.len(), 4);
    for (l, v) in &lobe.curves {
        let peak = v
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
            .map(|(k, _)| lobe.theta_o_deg[k])
            .unwrap();
        assert!((peak - 30.0).abs() <= 2.0, "{l} nm peaks at {peak} deg");
    }
    for ext in ["png", "svg"] {
        let p = d.join(format!("lobe.{ext}"));
        let (code, _, err) = goniospec(&[
            "plot",
            &gsb,
            "--theta-i",
            "30",
            "--map-resolution",
            "32",
            "-o",
            p.to_str().unwrap(),
        ]);
        assert_eq!(code, 0, "{err}");
        let bytes = std::fs::read(&p).unwrap();
        assert!(bytes.len() > 10_000, "{ext}: {} bytes", bytes.len());
        if ext == "png" {
            assert!(bytes.starts_with(b"\x89PNG\r\n\x1a\n"));
        } else {
            assert!(String::from_utf8_lossy(&bytes).contains("<svg"));
        }
    }
    let (code, _, err) = goniospec(&[
        "plot",
        &gsb,
        "--theta-i",
        "95",
        "-o",
        d.join("x.png").to_str().unwrap(),
    ]);
    assert_eq!(code, 1);
    assert!(err.contains("[0, 90)"), "{err}");
    let (code, _, err) = goniospec(&[
        "plot",
        &gsb,
        "--theta-i",
        "30",
        "-o",
        d.join("x.jpg").to_str().unwrap(),
    ]);
    assert_eq!(code, 1);
    assert!(err.contains(".png or .svg"), "{err}");
}

/// `--format merl`: a reader written here from the MERL database's BRDFRead.cpp (half/diff
/// coordinates by rotating wi by -phi_h about the normal and -theta_h about the binormal,
/// the square-root theta_h index, phi_d reduced by reciprocity, the channel scales)
/// recovers goniospec's sRGB at the centres of 2,000 random cells within 1 % wherever the
/// BRDF is lit (luminance above 1 % of the largest).
#[test]
fn merl_export_round_trips_through_the_readers_indexing() {
    use glam::DVec3;
    use goniospec::brdf::{Brdf, file};
    use goniospec::render::colour;
    use std::f64::consts::{FRAC_PI_2, PI};
    let d = scratch("export-merl");
    let gsb = built(&d, "meshes/rough-gold.toml", "gold");
    let p = d.join("gold.binary");
    let (code, text, err) = goniospec(&[
        "export",
        &gsb,
        "--format",
        "merl",
        "--force",
        "-o",
        p.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(text.contains("spectrum is not kept"), "{text}");
    let bytes = std::fs::read(&p).unwrap();
    let dims: Vec<i32> = (0..3)
        .map(|k| i32::from_le_bytes(bytes[4 * k..4 * k + 4].try_into().unwrap()))
        .collect();
    assert_eq!(dims, vec![90, 90, 180]);
    let n = 90 * 90 * 180;
    assert_eq!(bytes.len(), 12 + 3 * 8 * n);
    let value = |ch: usize, ind: usize| {
        let at = 12 + 8 * (ch * n + ind);
        f64::from_le_bytes(bytes[at..at + 8].try_into().unwrap())
    };
    // The reader (BRDFRead.cpp).
    let rot = |v: DVec3, axis: DVec3, a: f64| {
        v * a.cos() + axis * (axis.dot(v) * (1.0 - a.cos())) + axis.cross(v) * a.sin()
    };
    let lookup = |wi: DVec3, wo: DVec3| -> [f64; 3] {
        let h = (wi + wo).normalize();
        let (th, ph) = (h.z.acos(), h.y.atan2(h.x));
        let diff = rot(rot(wi, DVec3::Z, -ph), DVec3::Y, -th);
        let (td, mut pd) = (diff.z.acos(), diff.y.atan2(diff.x));
        let th_i = if th <= 0.0 {
            0
        } else {
            (((th / FRAC_PI_2 * 90.0) * 90.0).sqrt() as usize).min(89)
        };
        let td_i = ((td / FRAC_PI_2 * 90.0) as usize).min(89);
        if pd < 0.0 {
            pd += PI;
        }
        let pd_i = ((pd / PI * 180.0) as usize).min(179);
        let ind = pd_i + td_i * 180 + th_i * 180 * 90;
        [
            value(0, ind) / 1500.0,
            value(1, ind) * 1.15 / 1500.0,
            value(2, ind) * 1.66 / 1500.0,
        ]
    };
    let r = file::read(std::path::Path::new(&gsb)).unwrap();
    let weights = colour::bin_weights(&r.meta().lambda_nm);
    let mut rng = goniospec::rng::Rng::new(5, 0);
    let mut cases = Vec::new();
    for _ in 0..2000 {
        let (i, j, k) = (
            (rng.uniform() * 90.0) as usize,
            (rng.uniform() * 90.0) as usize,
            (rng.uniform() * 180.0) as usize,
        );
        // The cell's centre, and its directions (phi_h = 0).
        let th = ((i as f64 + 0.5) / 90.0).powi(2) * FRAC_PI_2;
        let td = (j as f64 + 0.5).to_radians();
        let pd = (k as f64 + 0.5).to_radians();
        let diff = DVec3::new(td.sin() * pd.cos(), td.sin() * pd.sin(), td.cos());
        let wi = rot(diff, DVec3::Y, th);
        let h = DVec3::new(th.sin(), 0.0, th.cos());
        let wo = h * (2.0 * wi.dot(h)) - wi;
        if wi.z <= 0.0 || wo.z <= 0.0 {
            continue;
        }
        let mut f = vec![0.0; weights.len()];
        r.eval(wi, wo, &mut f);
        let want = colour::xyz_to_linear_srgb(colour::xyz(&f, &weights));
        cases.push((lookup(wi, wo), want));
    }
    let lum = |c: &[f64; 3]| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
    let max = cases.iter().map(|c| lum(&c.1)).fold(0.0, f64::max);
    let lit: Vec<_> = cases.iter().filter(|c| lum(&c.1) > 0.01 * max).collect();
    assert!(lit.len() > 200, "{} lit cells", lit.len());
    for (got, want) in lit {
        for ch in 0..3 {
            assert!(
                (got[ch] - want[ch]).abs() <= 0.01 * lum(want).max(want[ch].abs()),
                "{got:?} against {want:?}"
            );
        }
    }
}

/// `export --scene` (issue 46): the Mitsuba 3 and pbrt-v4 scenes carry `goniospec render`'s
/// view with the same flags, in both renderers' units (radiance factors relative to D65:
/// a light of strength s is an irradiance of pi s, a constant environment of strength e a
/// radiance e; README, "Using a material in Mitsuba 3 or pbrt-v4"), and name the .bsdf.
/// Mitsuba renders such a scene against `goniospec render` in `make interop`
/// (tests/interop/rgl_mitsuba.py, step 8).
#[test]
fn export_scene_carries_the_render_view_in_both_renderers_units() {
    let d = scratch("export-scene");
    let gsb = built(&d, "meshes/rough-gold.toml", "gold");
    let p = d.join("gold.bsdf");
    let args = |extra: &[&str]| {
        let mut v = vec![
            "export".to_string(),
            gsb.clone(),
            "--sample".into(),
            "meshes/rough-gold.toml".into(),
            "--resolution".into(),
            "9".into(),
            "-o".into(),
            p.to_str().unwrap().into(),
            "--force".into(),
        ];
        v.extend(extra.iter().map(|s| s.to_string()));
        v
    };
    let run = |extra: &[&str]| {
        let a = args(extra);
        let refs: Vec<&str> = a.iter().map(String::as_str).collect();
        goniospec(&refs)
    };
    let (code, text, err) = run(&[
        "--scene",
        "mitsuba,pbrt",
        "--light",
        "dir:45,-60",
        "--light-strength",
        "1",
        "--env-strength",
        "0.5",
        "--width",
        "64",
        "--height",
        "32",
        "--spp",
        "4",
        "--camera",
        "0,-5,2",
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(
        text.contains("gold.xml") && text.contains("gold.pbrt"),
        "{text}"
    );
    let xml = std::fs::read_to_string(d.join("gold.xml")).unwrap();
    let doc = roxmltree::Document::parse(&xml).unwrap();
    let find = |tag: &str, name: &str| {
        doc.descendants()
            .find(|n| n.has_tag_name(tag) && n.attribute("name") == Some(name))
            .and_then(|n| n.attribute("value").map(str::to_string))
            .unwrap_or_else(|| panic!("no {tag} {name}: {xml}"))
    };
    let nums = |s: &str| -> Vec<f64> { s.split(',').map(|x| x.trim().parse().unwrap()).collect() };
    assert_eq!(find("float", "fov"), "30.0");
    assert_eq!(find("string", "fov_axis"), "y");
    assert_eq!(find("integer", "width"), "64");
    assert_eq!(find("integer", "height"), "32");
    assert_eq!(find("integer", "sample_count"), "4");
    assert_eq!(find("string", "filename"), "gold.bsdf");
    assert_eq!(find("boolean", "hide_emitters"), "true");
    let look = doc
        .descendants()
        .find(|n| n.has_tag_name("lookat"))
        .unwrap();
    assert_eq!(
        nums(look.attribute("origin").unwrap()),
        vec![0.0, -5.0, 2.0]
    );
    assert_eq!(nums(look.attribute("target").unwrap()), vec![0.0, 0.0, 0.0]);
    // The light travels along -l, l = (sin 45 cos -60, sin 45 sin -60, cos 45).
    let (t, ph) = (45f64.to_radians(), (-60f64).to_radians());
    let l = [t.sin() * ph.cos(), t.sin() * ph.sin(), t.cos()];
    let dir = nums(&find("vector", "direction"));
    for k in 0..3 {
        assert!((dir[k] + l[k]).abs() < 1e-12, "{dir:?}");
    }
    let scales: Vec<f64> = doc
        .descendants()
        .filter(|n| n.has_tag_name("float") && n.attribute("name") == Some("scale"))
        .map(|n| n.attribute("value").unwrap().parse().unwrap())
        .collect();
    assert_eq!(scales.len(), 2, "{xml}");
    assert!(
        (scales[0] - std::f64::consts::PI).abs() < 1e-12,
        "irradiance {scales:?}"
    );
    assert_eq!(scales[1], 0.5, "radiance");
    assert!(xml.contains("type=\"d65\""));
    let pbrt = std::fs::read_to_string(d.join("gold.pbrt")).unwrap();
    for want in [
        "Scale -1 1 1",
        "LookAt 0.0 -5.0 2.0",
        "Camera \"perspective\" \"float fov\" [ 30.0 ]",
        "\"integer pixelsamples\" [ 4 ]",
        "\"integer xresolution\" [ 64 ] \"integer yresolution\" [ 32 ]",
        "\"string filename\" [ \"gold-pbrt.exr\" ]",
        "LightSource \"distant\"",
        "\"spectrum L\" \"stdillum-D65\"",
        "LightSource \"infinite\" \"spectrum L\" \"stdillum-D65\" \"float scale\" [ 0.5 ]",
        "Material \"measured\" \"string filename\" [ \"gold.bsdf\" ]",
        "Shape \"sphere\" \"float radius\" [ 1 ]",
    ] {
        assert!(pbrt.contains(want), "{want} not in\n{pbrt}");
    }
    assert!(
        pbrt.contains(&format!("\"float scale\" [ {:?} ]", std::f64::consts::PI)),
        "{pbrt}"
    );
    // A portrait image: pbrt's fov is the shorter side's, the horizontal one.
    let (code, _, err) = run(&["--scene", "pbrt", "--width", "32", "--height", "64"]);
    assert_eq!(code, 0, "{err}");
    let pbrt = std::fs::read_to_string(d.join("gold.pbrt")).unwrap();
    let want = 2.0 * ((15f64.to_radians()).tan() * 0.5).atan().to_degrees();
    assert!(pbrt.contains(&format!("[ {want:?} ]")), "{want}: {pbrt}");
    // The default view: render's default camera (0, -4.2, 1.6) for the sphere.
    let (code, _, err) = run(&["--scene", "mitsuba"]);
    assert_eq!(code, 0, "{err}");
    let xml = std::fs::read_to_string(d.join("gold.xml")).unwrap();
    assert!(xml.contains("origin=\"0.0, -4.2, 1.6\""), "{xml}");
    // Refusals, before any file is written.
    for (extra, says) in [
        (vec!["--scene", "mitsuba", "--env", "sky"], "sky"),
        (
            vec!["--scene", "mitsuba", "--shape", "meshes/al-flakes.obj"],
            "sphere or a plane",
        ),
        (
            vec!["--scene", "mitsuba", "--format", "npz"],
            "--format rgl",
        ),
    ] {
        std::fs::remove_file(d.join("gold.xml")).ok();
        let (code, _, err) = run(&extra);
        assert_eq!(code, 1, "{extra:?}: {err}");
        assert!(err.contains(says), "{extra:?}: {err}");
        assert!(!d.join("gold.xml").exists(), "{extra:?} wrote the scene");
    }
}
