//! `goniospec batch report`: one static HTML page over a merged batch library, so a person
//! can choose a material by looking at it.
//!
//! Per material the page shows its name, sample and settings; the colour it reflects at a
//! few incident angles under CIE D65 with its luminous reflectance Y; the lobe plot
//! ([`crate::plot::LobePlot`]); a small rendered sphere ([`crate::render::render`]); the
//! real-time fit ([`crate::fit::fit`]) with its errors; and links to its files. The table
//! sorts by name and by reflectance. Everything is local: the images are PNG files beside
//! the page, the style and the sorting script are inline, so the page works offline and
//! from `file://`.
//!
//! The page holds no date or timing, so the same library gives the same bytes (images
//! included) whatever the thread count.

use crate::fit::{BaseKind, CoatChoice};
use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Component, Path, PathBuf};

use crate::accumulate::file::Accumulator;
use crate::brdf::{self, Kind, Representation};
use crate::output::{self, OutputKind};
use crate::render::{self, Env, Light, RenderConfig, Shape, colour};

use super::Manifest;

use crate::output::HTML_MARK;

/// What the report spends on each material.
#[derive(Clone, Debug)]
pub struct ReportOptions {
    /// Side of the rendered sphere, pixels.
    pub sphere_px: usize,
    /// Samples per pixel of the sphere.
    pub spp: usize,
    /// Points per side of the lobe plot's hemisphere map.
    pub map_resolution: usize,
    /// Fit a real-time material to each accumulator (about a second each).
    pub fit: bool,
    /// Incident angles whose colour is shown, at most.
    pub colours: usize,
}

impl Default for ReportOptions {
    fn default() -> Self {
        ReportOptions {
            sphere_px: 160,
            spp: 4,
            map_resolution: 96,
            fit: true,
            colours: 4,
        }
    }
}

/// Why a report could not be made.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    #[error("{material}: {path} is missing; run `goniospec batch merge` on the batch folder first")]
    NotMerged { material: String, path: String },
    #[error("{path}: {message}")]
    Read { path: String, message: String },
    #[error("{material}: {message}")]
    Material { material: String, message: String },
    #[error(transparent)]
    Output(#[from] output::OutputError),
    #[error("writing {path}: {source}")]
    Write {
        path: String,
        source: std::io::Error,
    },
    #[error("the report's options: {0}")]
    Options(String),
}

/// The colour of the light a material reflects at one incident angle.
#[derive(Clone, Debug, PartialEq)]
pub struct Swatch {
    pub theta_i_deg: f64,
    /// CIE XYZ of the directional-hemispherical reflectance under D65 (a perfect white has
    /// Y = 1).
    pub xyz: [f64; 3],
    /// 8-bit sRGB of the swatch (clipped to the gamut when `clipped`).
    pub srgb8: [u8; 3],
    /// Whether the linear sRGB colour lay outside [0, 1] and was clipped for display.
    pub clipped: bool,
}

/// The fit's figures the page shows.
#[derive(Clone, Debug)]
pub struct FitSummary {
    pub ggx_alpha: f64,
    pub base: String,
    pub film: String,
    pub rms_reflectance_error: f64,
    pub max_delta_e2000: f64,
    pub warnings: Vec<String>,
}

/// One material's row.
#[derive(Clone, Debug)]
pub struct Entry {
    pub name: String,
    pub sample: String,
    pub settings: String,
    pub swatches: Vec<Swatch>,
    /// Mean luminous reflectance Y over every simulated incident angle (the sort key).
    pub mean_y: f64,
    pub lobe_theta_deg: f64,
    /// The BRDF the lobe and the sphere were drawn from.
    pub brdf_source: String,
    pub fit: Option<FitSummary>,
    /// (label, link relative to the page).
    pub files: Vec<(String, String)>,
}

/// The files the report writes for one material, relative to the page's folder.
fn image_names(name: &str) -> [String; 3] {
    [
        format!("{name}-lobe.png"),
        format!("{name}-sphere.png"),
        format!("{name}-fit.json"),
    ]
}

/// Writes the report of the merged library in `dir` to `page` (an `.html` file; its images
/// and fits go beside it). Refuses, before any work, outputs that are inputs or foreign
/// files (unless `force`), and materials not merged yet. `progress` receives the count of
/// materials done.
pub fn write_report(
    dir: &Path,
    page: &Path,
    opts: &ReportOptions,
    force: bool,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Vec<Entry>, ReportError> {
    if opts.sphere_px == 0 || opts.sphere_px > 4096 || opts.spp == 0 || opts.spp > 4096 {
        return Err(ReportError::Options(format!(
            "the sphere needs 1 to 4096 pixels a side and 1 to 4096 samples per pixel, got {} and {}",
            opts.sphere_px, opts.spp
        )));
    }
    if !(8..=1024).contains(&opts.map_resolution) || opts.colours == 0 {
        return Err(ReportError::Options(format!(
            "the lobe map needs 8 to 1024 points a side and at least one colour, got {} and {}",
            opts.map_resolution, opts.colours
        )));
    }
    let m = Manifest::read(dir).map_err(|e| ReportError::Read {
        path: dir.join("manifest.toml").display().to_string(),
        message: e.to_string(),
    })?;
    let folder = match page.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    std::fs::create_dir_all(&folder).map_err(|source| ReportError::Write {
        path: folder.display().to_string(),
        source,
    })?;
    let out = dir.join("out");
    // Every input, and every output checked against them, before any work.
    let mut inputs: Vec<PathBuf> = vec![dir.join("manifest.toml")];
    for mat in &m.materials {
        let gsa = out.join(format!("{}.gsa", mat.name));
        if !gsa.is_file() {
            return Err(ReportError::NotMerged {
                material: mat.name.clone(),
                path: gsa.display().to_string(),
            });
        }
        inputs.push(gsa);
        inputs.extend(
            mat.representations
                .iter()
                .map(|k| out.join(format!("{}-{k}.gsb", mat.name))),
        );
    }
    let input_refs: Vec<&Path> = inputs.iter().map(|p| p.as_path()).collect();
    output::guard(page, &input_refs, OutputKind::Report, force)?;
    for mat in &m.materials {
        let [lobe, sphere, fit] = image_names(&mat.name);
        output::guard(&folder.join(lobe), &input_refs, OutputKind::Image, force)?;
        output::guard(&folder.join(sphere), &input_refs, OutputKind::Image, force)?;
        if opts.fit {
            output::guard(&folder.join(fit), &input_refs, OutputKind::FitJson, force)?;
        }
    }
    // Materials in parallel (each writes only its own files); rows in the plan's order.
    use rayon::prelude::*;
    let done = std::sync::atomic::AtomicU64::new(0);
    let entries = m
        .materials
        .par_iter()
        .map(|mat| {
            let e = material_entry(dir, &folder, mat, opts);
            progress(done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1);
            e
        })
        .collect::<Result<Vec<Entry>, ReportError>>()?;
    let html = page_html(&entries, opts);
    crate::io::write_atomic(page, |w| w.write_all(html.as_bytes())).map_err(|source| {
        ReportError::Write {
            path: page.display().to_string(),
            source,
        }
    })?;
    Ok(entries)
}

/// Computes one material's row and writes its lobe plot, sphere and fit beside the page.
fn material_entry(
    dir: &Path,
    folder: &Path,
    mat: &super::Material,
    opts: &ReportOptions,
) -> Result<Entry, ReportError> {
    let out = dir.join("out");
    let gsa = out.join(format!("{}.gsa", mat.name));
    let acc = Accumulator::read(&gsa).map_err(|e| ReportError::Read {
        path: gsa.display().to_string(),
        message: format!("{e:#}"),
    })?;
    let fail = |message: String| ReportError::Material {
        material: mat.name.clone(),
        message,
    };
    let s = &acc.header.settings;
    let thetas = s.theta_i_deg.clone();
    let centres: Vec<f64> = (0..s.wavelength_count()).map(|j| s.wavelength(j)).collect();
    let weights = colour::bin_weights(&centres);

    // Colours: Y at every angle for the sort key; swatches at a few, evenly picked.
    let mut ys = Vec::new();
    let mut all = Vec::new();
    for &t in &thetas {
        let refl = acc.reflectance(t, None).map_err(|e| fail(e.to_string()))?;
        let r: Vec<f64> = refl.rows.iter().map(|row| row.r).collect();
        if let Some(bad) = r.iter().find(|v| !v.is_finite() || **v < 0.0 || **v > 1.0) {
            return Err(fail(format!(
                "reflectance {bad} at theta_i = {t} deg is not a fraction of the incident power"
            )));
        }
        let xyz = colour::xyz(&r, &weights);
        ys.push(xyz[1]);
        all.push(swatch(t, xyz));
    }
    let mean_y = ys.iter().sum::<f64>() / ys.len() as f64;
    let swatches = pick_evenly(&all, opts.colours);

    // The BRDF: the plan's table when merge built it, else a table built now.
    let table = out.join(format!("{}-table.gsb", mat.name));
    let (brdf, brdf_source) = if mat.representations.contains(&Kind::Table) && table.is_file() {
        let r = brdf::file::read(&table).map_err(|e| ReportError::Read {
            path: table.display().to_string(),
            message: format!("{e:#}"),
        })?;
        (r, format!("{}-table.gsb", mat.name))
    } else {
        let data = brdf::BucketData::from_accumulator(&acc);
        let r = Representation::build(Kind::Table, &data, &Default::default())
            .map_err(|e| fail(e.to_string()))?;
        (r, "a table built from the accumulator".to_string())
    };

    // The lobe at the simulated angle nearest 30 degrees (a typical viewing angle).
    let lobe_theta_deg = thetas
        .iter()
        .copied()
        .min_by(|a, b| (a - 30.0).abs().total_cmp(&(b - 30.0).abs()))
        .expect("a material has at least one incident angle");
    let [lobe_name, sphere_name, fit_name] = image_names(&mat.name);
    let plot = crate::plot::LobePlot::new(&brdf, lobe_theta_deg, s.phi_i_deg, opts.map_resolution)
        .map_err(|e| fail(e.to_string()))?;
    plot.write(&folder.join(&lobe_name))
        .map_err(|e| fail(e.to_string()))?;

    // The sphere, with `goniospec render`'s default light and environment.
    let shape = Shape::Sphere;
    let (centre, radius) = shape.bounds();
    let cfg = RenderConfig {
        width: opts.sphere_px,
        height: opts.sphere_px,
        spp: opts.spp,
        light: Light::parse("dir:50,-120").expect("a valid light"),
        light_strength: 0.8,
        env: Env::Constant,
        env_strength: 0.6,
        camera: [
            centre[0],
            centre[1] - 4.2 * radius,
            centre[2] + 1.6 * radius,
        ]
        .into(),
        fov_deg: 30.0,
        seed: 1,
    };
    let albedo = render::albedo_table(&brdf, 90);
    let img = render::render(&brdf, &shape, &cfg, Some(&albedo), &|_| {});
    let sphere_path = folder.join(&sphere_name);
    render::write_png(&img, &sphere_path).map_err(|source| ReportError::Write {
        path: sphere_path.display().to_string(),
        source,
    })?;

    let fit = if opts.fit {
        let data = crate::fit::Data::from_accumulator(&acc);
        let f = crate::fit::fit(&data, BaseKind::Auto, true, CoatChoice::Auto);
        let p = folder.join(&fit_name);
        crate::fit::write_json(&p, &crate::fit::to_json(&f, &data)).map_err(|source| {
            ReportError::Write {
                path: p.display().to_string(),
                source,
            }
        })?;
        Some(summarise_fit(&f))
    } else {
        None
    };

    let mut files = vec![(
        format!("{}.gsa", mat.name),
        link(folder, &out.join(format!("{}.gsa", mat.name))),
    )];
    for k in &mat.representations {
        let name = format!("{}-{k}.gsb", mat.name);
        files.push((name.clone(), link(folder, &out.join(&name))));
    }
    if opts.fit {
        files.push((fit_name.clone(), fit_name));
    }
    Ok(Entry {
        name: mat.name.clone(),
        sample: mat.sample.display().to_string(),
        settings: format!(
            "theta_i {} deg; {} ({} bins{}); {} trees per angle; seed {}; coherence {}",
            thetas
                .iter()
                .map(|t| format!("{t}"))
                .collect::<Vec<_>>()
                .join(", "),
            mat.settings.wavelengths,
            centres.len(),
            if mat.settings.monochromatic {
                ", monochromatic"
            } else {
                ""
            },
            mat.settings.rays,
            mat.settings.seed,
            s.coherence_mode()
        ),
        swatches,
        mean_y,
        lobe_theta_deg,
        brdf_source,
        fit,
        files,
    })
}

/// The swatch of XYZ `xyz` (D65 white): linear sRGB (IEC 61966-2-1), clipped to [0, 1]
/// for display and marked so when it had to be, then encoded to 8 bits.
fn swatch(theta_i_deg: f64, xyz: [f64; 3]) -> Swatch {
    let lin = colour::xyz_to_linear_srgb(xyz);
    // A tolerance of half an 8-bit step in linear light keeps rounding from marking greys.
    let clipped = lin
        .iter()
        .any(|&c| !(-0.5 / 255.0..=1.0 + 0.5 / 255.0).contains(&c));
    Swatch {
        theta_i_deg,
        xyz,
        srgb8: lin.map(|c| (colour::srgb_encode(c) * 255.0).round() as u8),
        clipped,
    }
}

/// At most `n` items, evenly spaced, the first and the last included.
fn pick_evenly<T: Clone>(items: &[T], n: usize) -> Vec<T> {
    if items.len() <= n {
        return items.to_vec();
    }
    if n == 1 {
        return vec![items[0].clone()];
    }
    (0..n)
        .map(|k| items[(k * (items.len() - 1) + (n - 1) / 2) / (n - 1)].clone())
        .collect()
}

fn summarise_fit(f: &crate::fit::Fit) -> FitSummary {
    use crate::fit::Base;
    FitSummary {
        ggx_alpha: f.alpha,
        base: match &f.base {
            Base::Dielectric { n } => format!("dielectric, ior {n:.3}"),
            Base::Conductor { n } => format!(
                "conductor, n + ik {:.2} + {:.2}i to {:.2} + {:.2}i",
                n[0].re,
                n[0].im,
                n[n.len() - 1].re,
                n[n.len() - 1].im
            ),
        },
        film: match (f.film, f.coat) {
            (Some(m), None) => format!(
                "{:.1} nm of ior {:.3}, weight {:.2}",
                m.thickness_nm, m.n, m.weight
            ),
            (Some(m), Some(c)) => format!(
                "{:.1} nm of ior {:.3}, weight {:.2}; under a clear coat of ior {:.3}",
                m.thickness_nm, m.n, m.weight, c.ior
            ),
            (None, Some(c)) => format!("none; under a clear coat of ior {:.3}", c.ior),
            (None, None) => "none".to_string(),
        },
        rms_reflectance_error: f.rms_residual,
        max_delta_e2000: f.delta_e2000.iter().copied().fold(0.0, f64::max),
        warnings: f.warnings.clone(),
    }
}

/// A link from `folder` to `target`: relative when both resolve (the page then works
/// wherever the library is copied), percent-encoded for an `href`.
fn link(folder: &Path, target: &Path) -> String {
    let rel = match (std::fs::canonicalize(folder), std::fs::canonicalize(target)) {
        (Ok(f), Ok(t)) => relative(&f, &t),
        _ => target.to_path_buf(),
    };
    let parts: Vec<String> = rel
        .components()
        .map(|c| match c {
            Component::ParentDir => "..".to_string(),
            Component::RootDir => String::new(),
            c => percent_encode(&c.as_os_str().to_string_lossy()),
        })
        .collect();
    parts.join("/")
}

/// `to` relative to the folder `from` (both absolute and canonical).
fn relative(from: &Path, to: &Path) -> PathBuf {
    let (f, t): (Vec<_>, Vec<_>) = (from.components().collect(), to.components().collect());
    let common = f.iter().zip(&t).take_while(|(a, b)| a == b).count();
    let mut p = PathBuf::new();
    for _ in common..f.len() {
        p.push("..");
    }
    for c in &t[common..] {
        p.push(c);
    }
    p
}

/// Percent-encodes every byte outside RFC 3986's unreserved set.
fn percent_encode(s: &str) -> String {
    let mut out = String::new();
    for b in s.bytes() {
        if b.is_ascii_alphanumeric() || b"-._~".contains(&b) {
            out.push(b as char);
        } else {
            let _ = write!(out, "%{b:02X}");
        }
    }
    out
}

/// Escapes text for HTML content and quoted attribute values.
fn esc(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

const STYLE: &str = "body{font-family:system-ui,sans-serif;margin:1.5em;color:#222}
table{border-collapse:collapse;width:100%}
th,td{border-bottom:1px solid #ddd;padding:.4em;vertical-align:top;text-align:left}
th button{font:inherit;font-weight:bold;background:none;border:0;padding:0;cursor:pointer}
th button::after{content:' \\2195';color:#888}
.refl{min-width:15em}
.sw{display:inline-block;margin:0 .4em .4em 0;text-align:center;font-size:.8em}
.sw span{display:block;width:3.2em;height:3.2em;border:1px solid #999}
.small{font-size:.85em;color:#555}
img{display:block}
.lobe{width:360px;height:auto}
";

/// Sorts the table's rows by the clicked column's `data-KEY` attribute of each row,
/// numerically for `y`; clicking again reverses the order.
const SCRIPT: &str = "'use strict';
document.querySelectorAll('th button[data-key]').forEach(function (b) {
  b.addEventListener('click', function () {
    var key = b.getAttribute('data-key');
    var th = b.parentElement;
    var asc = th.getAttribute('aria-sort') !== 'ascending';
    document.querySelectorAll('th[aria-sort]').forEach(function (h) { h.setAttribute('aria-sort', 'none'); });
    th.setAttribute('aria-sort', asc ? 'ascending' : 'descending');
    var body = document.getElementById('materials');
    var rows = Array.prototype.slice.call(body.rows);
    rows.sort(function (r1, r2) {
      var a = r1.getAttribute('data-' + key), c = r2.getAttribute('data-' + key);
      var d = key === 'y' ? parseFloat(a) - parseFloat(c) : (a < c ? -1 : a > c ? 1 : 0);
      return asc ? d : -d;
    });
    rows.forEach(function (r) { body.appendChild(r); });
  });
});
";

/// The page: a header saying what each column means and what the report spent, then one
/// row per material.
pub fn page_html(entries: &[Entry], opts: &ReportOptions) -> String {
    let mut h = String::new();
    let _ = write!(
        h,
        "{HTML_MARK}\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n\
         <title>goniospec material library ({n} materials)</title>\n\
         <link rel=\"icon\" href=\"data:,\">\n<style>\n{STYLE}</style>\n</head>\n<body>\n\
         <h1>Material library: {n} materials</h1>\n",
        n = entries.len()
    );
    let _ = write!(
        h,
        "<p class=\"small\">Colour: the directional-hemispherical reflectance R(&lambda;) at the \
         incident angle shown, under CIE illuminant D65 with the CIE 1931 2&deg; observer, \
         displayed in sRGB; Y is the luminous reflectance (a perfect white has Y = 1). A swatch \
         marked &dagger; lies outside the sRGB gamut and is shown clipped. Lobe: f cos&theta;<sub>o</sub> \
         in the plane of incidence (1/sr) and the reflected colour over the hemisphere, at the \
         simulated incident angle nearest 30&deg;. Sphere: <code>goniospec render</code> of the \
         table BRDF at a small budget ({px}&times;{px} pixels, {spp} samples per pixel: expect \
         noise), light from &theta; = 50&deg;, &phi; = &minus;120&deg; and a constant environment. \
         Fit: <code>goniospec fit</code> (GGX, base, thin film) with its RMS reflectance error and \
         its largest CIE &Delta;E2000 over the incident angles. Click a column's name to sort.</p>",
        px = opts.sphere_px,
        spp = opts.spp
    );
    h.push('\n');
    h.push_str(
        "<table>\n<thead>\n<tr>\
         <th aria-sort=\"none\"><button type=\"button\" data-key=\"name\">Material</button></th>\
         <th aria-sort=\"none\"><button type=\"button\" data-key=\"y\">Reflectance</button></th>\
         <th>Lobe</th><th>Sphere</th><th>Fit</th><th>Files</th></tr>\n</thead>\n\
         <tbody id=\"materials\">\n",
    );
    for e in entries {
        row_html(&mut h, e);
    }
    let _ = write!(
        h,
        "</tbody>\n</table>\n<script>\n{SCRIPT}</script>\n</body>\n</html>\n"
    );
    h
}

fn row_html(h: &mut String, e: &Entry) {
    let [lobe, sphere, _] = image_names(&e.name);
    let _ = write!(
        h,
        "<tr data-name=\"{name}\" data-y=\"{y:.6}\">\n<td><strong>{name}</strong>\
         <div class=\"small\">sample {sample}</div><div class=\"small\">{settings}</div></td>\n\
         <td class=\"refl\">",
        name = esc(&e.name),
        y = e.mean_y,
        sample = esc(&e.sample),
        settings = esc(&e.settings)
    );
    for s in &e.swatches {
        let [r, g, b] = s.srgb8;
        let _ = write!(
            h,
            "<div class=\"sw\"><span style=\"background:#{r:02x}{g:02x}{b:02x}\" \
             title=\"XYZ {x:.4}, {y:.4}, {z:.4}{clip}\"></span>{t}&deg;: Y {y:.3}{mark}</div>",
            x = s.xyz[0],
            y = s.xyz[1],
            z = s.xyz[2],
            t = s.theta_i_deg,
            clip = if s.clipped {
                " (outside sRGB, clipped)"
            } else {
                ""
            },
            mark = if s.clipped { "&dagger;" } else { "" }
        );
    }
    let _ = write!(
        h,
        "<div class=\"small\">mean Y over the simulated angles {:.4}</div></td>",
        e.mean_y
    );
    h.push('\n');
    let _ = write!(
        h,
        "<td><img class=\"lobe\" src=\"{lobe}\" width=\"1200\" height=\"600\" \
         alt=\"lobe of {name} at {t} degrees\"><div class=\"small\">from {src}</div></td>\n\
         <td><img src=\"{sphere}\" alt=\"sphere of {name}\"></td>\n",
        lobe = percent_encode(&lobe),
        sphere = percent_encode(&sphere),
        name = esc(&e.name),
        t = e.lobe_theta_deg,
        src = esc(&e.brdf_source)
    );
    match &e.fit {
        Some(f) => {
            let _ = write!(
                h,
                "<td>GGX &alpha; {:.3}<br>base {}<br>film {}<br>RMS R error {:.2e}<br>\
                 &Delta;E2000 up to {:.2}",
                f.ggx_alpha,
                esc(&f.base),
                esc(&f.film),
                f.rms_reflectance_error,
                f.max_delta_e2000
            );
            for w in &f.warnings {
                let _ = write!(h, "<div class=\"small\">{}</div>", esc(w));
            }
            h.push_str("</td>\n");
        }
        None => h.push_str("<td>not fitted</td>\n"),
    }
    h.push_str("<td>");
    for (label, href) in &e.files {
        let _ = write!(h, "<a href=\"{}\">{}</a><br>", esc(href), esc(label));
    }
    h.push_str("</td>\n</tr>\n");
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn evenly_picked_angles_keep_both_ends() {
        let v: Vec<u32> = (0..10).collect();
        assert_eq!(pick_evenly(&v, 4), vec![0, 3, 6, 9]);
        assert_eq!(pick_evenly(&v, 2), vec![0, 9]);
        assert_eq!(pick_evenly(&v, 1), vec![0]);
        assert_eq!(pick_evenly(&v[..3], 4), vec![0, 1, 2]);
    }

    #[test]
    fn relative_links_climb_and_descend() {
        assert_eq!(
            relative(Path::new("/a/b/report"), Path::new("/a/b/out/x.gsa")),
            PathBuf::from("../out/x.gsa")
        );
        assert_eq!(
            relative(Path::new("/a/b"), Path::new("/a/b/x.png")),
            PathBuf::from("x.png")
        );
        assert_eq!(percent_encode("a b&c.gsa"), "a%20b%26c.gsa");
    }

    #[test]
    fn text_is_escaped() {
        assert_eq!(
            esc("<a href=\"x\">&'</a>"),
            "&lt;a href=&quot;x&quot;&gt;&amp;&#39;&lt;/a&gt;"
        );
    }

    #[test]
    fn a_perfect_white_is_white_and_not_clipped() {
        // XYZ of R = 1 under D65 is the D65 white: sRGB (1, 1, 1) within the matrix's
        // four-digit rounding (IEC 61966-2-1).
        let s = swatch(0.0, colour::white_xyz());
        assert_eq!(s.srgb8, [255, 255, 255]);
        assert!(!s.clipped);
        // A saturated spectral green lies outside sRGB.
        let g = swatch(0.0, [0.1, 0.6, 0.05]);
        assert!(g.clipped);
    }
}
