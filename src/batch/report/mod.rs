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
use std::io::Write as _;
use std::path::{Component, Path, PathBuf};

use crate::accumulate::file::Accumulator;
use crate::brdf::{self, Kind, Representation};
use crate::output::{self, OutputKind};
use crate::render::{self, Env, Light, RenderConfig, Shape, colour};

use super::Manifest;

mod html;
pub mod tidy;
pub use html::page_html;
use html::percent_encode;

/// What the report spends on each material.
#[derive(Clone, Debug)]
pub struct ReportOptions {
    /// Side of the rendered sphere, pixels.
    pub sphere_px: usize,
    /// Samples per pixel of the sphere.
    pub spp: usize,
    /// Points per side of the lobe plot's hemisphere map.
    pub map_resolution: usize,
    /// Fit a real-time material to each accumulator (10-60 s each: 23 s for the car paint at 5 angles and 40 bins).
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
    /// The methods each incident angle used (`tidy::methods_line`).
    pub methods: String,
    pub swatches: Vec<Swatch>,
    /// Mean luminous reflectance Y over every simulated incident angle (the sort key).
    pub mean_y: f64,
    pub lobe_theta_deg: f64,
    /// The BRDF the lobe and the sphere were drawn from.
    pub brdf_source: String,
    pub fit: Option<FitSummary>,
    /// (label, link relative to the page).
    pub files: Vec<(String, String)>,
    /// The warnings its simulation left (those its merged `.gsa` holds; `out/NAME.warnings`
    /// is a copy with each one's incident angle) and the report's own notes (a
    /// representation missing).
    pub warnings: Vec<String>,
    /// Why the material is left out of the library (not merged, refused by its simulation,
    /// or not readable as this material), where it is: the page marks its row with it.
    pub failure: Option<String>,
}

impl Entry {
    /// The marked row of a material left out, with `why`.
    fn left_out(mat: &super::Material, why: String) -> Entry {
        Entry {
            name: mat.name.clone(),
            sample: mat.sample.display().to_string(),
            settings: String::new(),
            methods: String::new(),
            swatches: Vec::new(),
            mean_y: -1.0,
            lobe_theta_deg: 0.0,
            brdf_source: String::new(),
            fit: None,
            files: Vec::new(),
            warnings: Vec::new(),
            failure: Some(why),
        }
    }
}

/// The files the report writes for one material, relative to the page's folder.
fn image_names(name: &str) -> [String; 3] {
    [
        format!("{name}-lobe.png"),
        format!("{name}-sphere.png"),
        format!("{name}-fit.json"),
    ]
}

/// The images a goniospec page at `page` shows (its `src` attributes, unescaped), or none
/// where `page` is missing or not a goniospec page.
fn images_of_page(page: &Path) -> std::collections::BTreeSet<String> {
    let Ok(text) = crate::io::read_input(page, 64 << 20) else {
        return Default::default();
    };
    let text = String::from_utf8_lossy(&text);
    if !text.starts_with(output::HTML_MARK) {
        return Default::default();
    }
    text.split("src=\"")
        .skip(1)
        .filter_map(|rest| rest.split('"').next())
        .map(html::unescape_src)
        .collect()
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
    // Which materials are in the library: merged, and not refused since (a material left
    // out keeps a marked row with its reason; the rest make the page).
    let left_out: Vec<Option<String>> = m
        .materials
        .iter()
        .map(|mat| {
            let gsa = out.join(format!("{}.gsa", mat.name));
            let failed = out.join(format!("{}.failed", mat.name));
            if let Ok(why) = std::fs::read_to_string(&failed) {
                Some(format!("not merged: {}", why.trim()))
            } else if !gsa.is_file() {
                Some(format!(
                    "not merged: {} is missing (run goniospec batch merge)",
                    gsa.display()
                ))
            } else {
                None
            }
        })
        .collect();
    // Every input, and every output checked against them, before any work.
    let mut inputs: Vec<PathBuf> = vec![dir.join("manifest.toml")];
    for mat in &m.materials {
        inputs.push(out.join(format!("{}.gsa", mat.name)));
        inputs.extend(
            mat.representations
                .iter()
                .map(|k| out.join(format!("{}-{k}.gsb", mat.name))),
        );
    }
    inputs.retain(|p| p.exists());
    let input_refs: Vec<&Path> = inputs.iter().map(|p| p.as_path()).collect();
    output::guard(page, &input_refs, OutputKind::Report, force)?;
    // The images beside the page: a PNG of a material's image name is replaced only where
    // goniospec wrote it (the folder's list, or a goniospec page there that shows it; issue
    // 47: a user's photos/gold-sphere.png was replaced).
    let shown_by_page = images_of_page(page);
    let mut images = Vec::new();
    for (mat, gone) in m.materials.iter().zip(&left_out) {
        if gone.is_some() {
            continue;
        }
        let [lobe, sphere, fit] = image_names(&mat.name);
        output::guard(&folder.join(&lobe), &input_refs, OutputKind::Image, force)?;
        output::guard(&folder.join(&sphere), &input_refs, OutputKind::Image, force)?;
        if opts.fit {
            output::guard(&folder.join(fit), &input_refs, OutputKind::FitJson, force)?;
        }
        images.extend([lobe, sphere]);
    }
    let unshown: Vec<String> = images
        .iter()
        .filter(|n| !shown_by_page.contains(*n))
        .cloned()
        .collect();
    output::guard_folder(&folder, &unshown, force)?;
    // Materials in parallel (each writes only its own files); rows in the plan's order.
    use rayon::prelude::*;
    let done = std::sync::atomic::AtomicU64::new(0);
    let entries: Vec<Entry> = m
        .materials
        .par_iter()
        .zip(&left_out)
        .map(|(mat, gone)| {
            let e = match gone {
                Some(why) => Entry::left_out(mat, why.clone()),
                // A material that cannot be shown is marked, not the end of the page.
                None => material_entry(dir, &folder, mat, opts)
                    .unwrap_or_else(|e| Entry::left_out(mat, e.to_string())),
            };
            progress(done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1);
            e
        })
        .collect();
    // Paths relative to the page: it is shared, the machine's folders are not.
    let entries: Vec<Entry> = entries
        .into_iter()
        .zip(&m.materials)
        .map(|(mut e, mat)| {
            let tidy = |t: &str| tidy::relative_paths(t, &folder, &[dir, &out, &mat.sample]);
            e.sample = tidy(&e.sample);
            e.warnings = e.warnings.iter().map(|w| tidy(w)).collect();
            e.failure = e.failure.as_deref().map(tidy);
            e
        })
        .collect();
    let html = page_html(&entries, opts);
    let written: Vec<String> = entries
        .iter()
        .filter(|e| e.failure.is_none())
        .flat_map(|e| {
            let [lobe, sphere, _] = image_names(&e.name);
            [lobe, sphere]
        })
        .collect();
    output::record_folder(&folder, &written).map_err(|source| ReportError::Write {
        path: folder.join(output::WRITTEN_LIST).display().to_string(),
        source,
    })?;
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
    if s.sample_hash != mat.sample_hash {
        return Err(fail(format!(
            "{} is not this material's: it was simulated from '{}' (hash {}), the plan's sample is {} (hash {}); run goniospec batch merge again",
            gsa.display(),
            s.sample_name,
            s.sample_hash,
            mat.sample.display(),
            mat.sample_hash
        )));
    }
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

    write_sphere(&brdf, &folder.join(&sphere_name), opts)?;

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

    let (files, warnings) = entry_files(
        folder,
        &out,
        mat,
        opts.fit.then_some(&fit_name),
        &acc.header.warnings,
    );
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
        methods: tidy::methods_line(
            &thetas,
            &(0..thetas.len())
                .map(|i| s.methods_of(i))
                .collect::<Vec<_>>(),
        ),
        swatches,
        mean_y,
        lobe_theta_deg,
        brdf_source,
        fit,
        files,
        warnings,
        failure: None,
    })
}

/// Renders the sphere of `brdf` with `goniospec render`'s default light and environment
/// to the PNG `path`, a flat top's mirror sharp as `render` draws it.
fn write_sphere(
    brdf: &Representation,
    path: &Path,
    opts: &ReportOptions,
) -> Result<(), ReportError> {
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
    // A flat top's mirror as `goniospec render` and `export` draw it (issue 71).
    let img = match crate::export::mirror::for_render(brdf) {
        Ok(Some(m)) => render::render(&m, &shape, &cfg, Some(&m.albedo_table(90)), &|_| {}),
        _ => {
            let albedo = render::albedo_table(brdf, 90);
            render::render(brdf, &shape, &cfg, Some(&albedo), &|_| {})
        }
    };
    render::write_png(&img, path).map_err(|source| ReportError::Write {
        path: path.display().to_string(),
        source,
    })?;

    Ok(())
}

/// The files of a material's row (its `.gsa`, each representation merge wrote, the fit's
/// JSON when `fit_name` is given) and its warnings: `stored`, the ones its merged,
/// checksummed `.gsa` holds (not the text copy `out/NAME.warnings`, which a hand can
/// change), and a representation merge did not write (no dead links).
fn entry_files(
    folder: &Path,
    out: &Path,
    mat: &super::Material,
    fit_name: Option<&String>,
    stored: &[String],
) -> (Vec<(String, String)>, Vec<String>) {
    let mut files = vec![(
        format!("{}.gsa", mat.name),
        link(folder, &out.join(format!("{}.gsa", mat.name))),
    )];
    let mut warnings = stored.to_vec();
    for k in &mat.representations {
        let name = format!("{}-{k}.gsb", mat.name);
        // No dead links: a representation merge did not write is said.
        if out.join(&name).is_file() {
            files.push((name.clone(), link(folder, &out.join(&name))));
        } else {
            warnings.push(format!(
                "{name} is missing from {}: run goniospec batch merge",
                out.display()
            ));
        }
    }
    if let Some(f) = fit_name {
        files.push((f.clone(), f.clone()));
    }
    (files, warnings)
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
            html::esc("<a href=\"x\">&'</a>"),
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
