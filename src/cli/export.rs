//! `goniospec export`: a built BRDF in another tool's format.

use std::io::Write;

use super::{
    Args, Context, ExitCode, MeshOptions, OutputKind, PathBuf, Result, bail, finite, guard_output,
    sample, thread_pool,
};

#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(super) enum ExportFormat {
    /// RGL tensor file (.bsdf) for Mitsuba 3's and pbrt-v4's `measured` material.
    Rgl,
    /// NumPy archive (.npz): brdf[theta_i, phi_i, theta_o, phi_o, lambda] on a regular
    /// grid, the axes in degrees, lambda_nm, and the settings as JSON. From a .gsa
    /// simulated with --mueller: its buckets as simulated, with the Mueller matrices
    /// (mueller[theta_i, phi_i, theta_o, phi_o, lambda, 4, 4], 1/sr) and their standard
    /// errors.
    Npz,
    /// MERL binary (90 x 90 x 180 half/difference cells, isotropic, linear sRGB with the
    /// reader's scale factors) for fitting tools. It loses the spectrum.
    Merl,
    /// Mitsuba 3's measured_polarized tensor file (.pbsdf), from a .gsa simulated with
    /// --mueller: the Mueller BRDF on a grid of Rusinkiewicz angles (73 phi_d x 19 theta_d x
    /// 91 theta_h) at 450, 500, 550, 600 and 650 nm, in the plugin's frames; render it in a
    /// *_spectral_polarized variant (docs/physics.md, "Polarisation"). Isotropic samples.
    Pbsdf,
}

#[derive(Args)]
pub(super) struct ExportArgs {
    /// The built BRDF (.gsb); for --format npz, also a .gsa simulated with --mueller.
    input: PathBuf,
    /// Output format.
    #[arg(long, value_enum, default_value_t = ExportFormat::Rgl)]
    format: ExportFormat,
    /// rgl: the sample the BRDF was simulated from: its facets give the microfacet
    /// distribution D(m) the RGL parameterisation warps by (the .gsb does not carry it).
    #[arg(long, value_name = "SAMPLE.toml")]
    sample: Option<PathBuf>,
    /// npz: outgoing polar bins over [0, 90) degrees, sampled at their centres (default:
    /// the simulation's bucket grid).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=4096))]
    theta_o_bins: Option<u32>,
    /// npz: outgoing azimuth bins over [0, 360) degrees (default: the bucket grid's).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=4096))]
    phi_o_bins: Option<u32>,
    /// rgl: nodes per side of the warped grids, odd, 3 to 255: finer follows narrower lobes
    /// and costs resolution^2 x angles x wavelengths x 4 bytes.
    #[arg(long, default_value_t = 65, value_parser = clap::value_parser!(u16).range(3..=goniospec::export::rgl::MAX_RESOLUTION as i64))]
    resolution: u16,
    /// Incident angles of the tabulation, degrees in [0, 90), comma-separated (default:
    /// the angles the BRDF was simulated at; for rgl also every 5 deg between them, where
    /// the renderer's interpolation in theta_i would otherwise part from goniospec's).
    #[arg(long, value_delimiter = ',', value_parser = finite)]
    theta_i: Vec<f64>,
    /// Output file, written atomically.
    #[arg(short, long)]
    output: PathBuf,
    /// Overwrite an existing output that is not a file of the chosen format; pbsdf: also
    /// write a file in which one simulated incident angle or one wavelength stands in for
    /// all (refused without it).
    #[arg(long)]
    force: bool,
    /// Worker threads (0: all cores). The file does not depend on it.
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// rgl: also write a scene that shows the material as `goniospec render` does with the
    /// same flags (shape, camera, light, environment, image; radiance factors relative to
    /// D65): mitsuba (Mitsuba 3 XML, OUTPUT.xml), pbrt (pbrt-v4, OUTPUT.pbrt rendering to
    /// OUTPUT-pbrt.exr), or both, comma-separated. The scene names the .bsdf by its file
    /// name, so keep them together.
    #[arg(long, value_enum, value_delimiter = ',')]
    scene: Vec<SceneFormat>,
    /// With --scene: the view, as `goniospec render` takes it (sphere or plane).
    #[command(flatten)]
    view: super::render::ViewArgs,
}

#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(super) enum SceneFormat {
    /// Mitsuba 3 scene XML (measured BSDF, direct integrator).
    Mitsuba,
    /// pbrt-v4 scene (measured material, path integrator at depth 1).
    Pbrt,
}

impl SceneFormat {
    fn extension(self) -> &'static str {
        match self {
            SceneFormat::Mitsuba => "xml",
            SceneFormat::Pbrt => "pbrt",
        }
    }
}

pub(super) fn export(a: ExportArgs) -> Result<ExitCode> {
    if !a.scene.is_empty() && a.format != ExportFormat::Rgl {
        bail!("--scene writes a renderer's scene around an RGL .bsdf: use it with --format rgl");
    }
    match a.format {
        ExportFormat::Rgl => export_rgl(a),
        ExportFormat::Npz => export_npz(a),
        ExportFormat::Merl => export_merl(a),
        ExportFormat::Pbsdf => export_pbsdf(a),
    }
}

fn export_pbsdf(a: ExportArgs) -> Result<ExitCode> {
    use goniospec::export::{pbsdf, tensor};
    guard_output(&a.output, &[a.input.as_path()], OutputKind::Tensor, a.force)?;
    if a.input.extension().is_none_or(|e| e != "gsa") {
        bail!(
            "--format pbsdf takes the accumulator (.gsa) of a run simulated with --mueller: a built .gsb holds no Mueller matrices"
        );
    }
    let acc = super::read_accumulator(&a.input)?;
    // What the file stands in for: said always, refused without --force where one angle
    // or one wavelength stands in for all.
    let covers = pbsdf::stands_in(&acc);
    if covers.alone && !a.force && acc.header.settings.mueller {
        bail!(
            "{}: {}. A renderer would show that everywhere: simulate more incident angles and wavelength bins, or pass --force to write it anyway",
            a.input.display(),
            covers.sentence
        );
    }
    let grid = pbsdf::PbsdfGrid::default();
    let fields = pbsdf::pbsdf_fields(&acc, grid)
        .map_err(|m| anyhow::anyhow!("{}: {m}", a.input.display()))?;
    tensor::write(&fields, &a.output).with_context(|| format!("writing {}", a.output.display()))?;
    outln!(
        "wrote {} (Mitsuba 3 measured_polarized: M[{}, {}, {}, 5, 4, 4], phi_d x theta_d x theta_h x 450-650 nm)",
        a.output.display(),
        grid.phi_d,
        grid.theta_d,
        grid.theta_h
    );
    eprintln!("note: {}", covers.sentence);
    Ok(ExitCode::SUCCESS)
}

fn export_merl(a: ExportArgs) -> Result<ExitCode> {
    use goniospec::brdf;
    guard_output(&a.output, &[a.input.as_path()], OutputKind::Merl, a.force)?;
    let r = brdf::file::read(&a.input)?;
    angles_covered(&r, &a.input, a.force)?;
    let pool = thread_pool(a.threads)?;
    let bytes = pool
        .install(|| goniospec::export::merl::merl_bytes(&r))
        .map_err(|m| anyhow::anyhow!("{}: {m}", a.input.display()))?;
    goniospec::io::write_atomic(&a.output, |w| w.write_all(&bytes))
        .with_context(|| format!("writing {}", a.output.display()))?;
    outln!(
        "wrote {} (MERL binary, 90 x 90 x 180 cells, linear sRGB: the spectrum is not kept)",
        a.output.display()
    );
    Ok(ExitCode::SUCCESS)
}

fn export_npz(a: ExportArgs) -> Result<ExitCode> {
    use goniospec::brdf::{self, Brdf};
    use goniospec::export::npz;
    guard_output(&a.output, &[a.input.as_path()], OutputKind::Npz, a.force)?;
    if a.input.extension().is_some_and(|e| e == "gsa") {
        if a.theta_o_bins.is_some() || a.phi_o_bins.is_some() || !a.theta_i.is_empty() {
            bail!(
                "a .gsa exports its buckets as simulated: --theta-o-bins, --phi-o-bins and --theta-i resample a built BRDF (.gsb)"
            );
        }
        let acc = super::read_accumulator(&a.input)?;
        let bytes = npz::mueller_npz_bytes(&acc)
            .map_err(|m| anyhow::anyhow!("{}: {m}", a.input.display()))?;
        goniospec::io::write_atomic(&a.output, |w| w.write_all(&bytes))
            .with_context(|| format!("writing {}", a.output.display()))?;
        outln!(
            "wrote {} (NumPy archive, the Mueller matrices of the buckets, {:.1} MB)",
            a.output.display(),
            bytes.len() as f64 / 1e6
        );
        return Ok(ExitCode::SUCCESS);
    }
    let r = brdf::file::read(&a.input)?;
    let settings: toml::Table = toml::from_str(&r.meta().simulation).unwrap_or_default();
    let bins = |key: &str, flag: Option<u32>| -> Result<usize> {
        match flag {
            Some(n) => Ok(n as usize),
            None => settings
                .get(key)
                .and_then(|v| v.as_integer())
                .map(|n| n as usize)
                .with_context(|| {
                    format!(
                        "the BRDF's settings hold no {key}: give --{}",
                        key.replace('_', "-")
                    )
                }),
        }
    };
    let mut grid = npz::Grid::of(
        &r,
        bins("theta_o_bins", a.theta_o_bins)?,
        bins("phi_o_bins", a.phi_o_bins)?,
    )
    .map_err(|m| anyhow::anyhow!("{}: {m}", a.input.display()))?;
    if !a.theta_i.is_empty() {
        grid.theta_i_deg = a.theta_i.clone();
    }
    let pool = thread_pool(a.threads)?;
    let bar = super::progress_spinner("evaluating the NPZ grid");
    let bytes = pool
        .install(|| npz::npz_bytes(&r, &grid))
        .map_err(|m| anyhow::anyhow!("{}: {m}", a.input.display()))?;
    bar.finish_and_clear();
    goniospec::io::write_atomic(&a.output, |w| w.write_all(&bytes))
        .with_context(|| format!("writing {}", a.output.display()))?;
    outln!(
        "wrote {} (NumPy archive, brdf[{}, {}, {}, {}, {}], {:.1} MB)",
        a.output.display(),
        grid.theta_i_deg.len(),
        grid.phi_i_deg.len(),
        grid.theta_o_deg.len(),
        grid.phi_o_deg.len(),
        r.meta().lambda_nm.len(),
        bytes.len() as f64 / 1e6
    );
    Ok(ExitCode::SUCCESS)
}

fn export_rgl(a: ExportArgs) -> Result<ExitCode> {
    use goniospec::brdf;
    use goniospec::export::{self, tensor};
    let Some(sample_path) = a.sample.clone() else {
        bail!(
            "--format rgl needs --sample SAMPLE.toml: the sample's facets give the microfacet distribution the format warps by"
        );
    };
    guard_output(
        &a.output,
        &[a.input.as_path(), sample_path.as_path()],
        OutputKind::Tensor,
        a.force,
    )?;
    // The scenes are checked, and their view resolved, before any work.
    let scenes = scene_plan(&a, &sample_path)?;
    let r = brdf::file::read(&a.input)?;
    let theta_i =
        (!a.theta_i.is_empty()).then(|| a.theta_i.iter().map(|t| t.to_radians()).collect());
    let s = sample::load(&sample_path, MeshOptions::default())?;
    let pool = thread_pool(a.threads)?;
    let n = usize::from(a.resolution);
    let t0 = std::time::Instant::now();
    let bar = super::progress_spinner("tabulating the RGL grid");
    let (fields, report) = pool
        .install(|| export::rgl_for(&r, &s, n, theta_i))
        .map_err(|m| anyhow::anyhow!("{} ({}): {m}", a.input.display(), sample_path.display()))?;
    bar.finish_and_clear();
    angles_covered(&r, &a.input, a.force)?;
    tensor::write(&fields, &a.output).with_context(|| format!("writing {}", a.output.display()))?;
    if report.negative > 0 {
        eprintln!(
            "note: {} of the {} tabulated BRDF values were negative (beamlet cross terms, most negative {:.3e} 1/sr); the RGL format holds none, so they were written as 0",
            report.negative, report.values, report.most_negative
        );
    }
    if let Some(width) = report.sharp_mirror_deg {
        eprintln!(
            "note: the sample's surface facing the light is flat (a clear coat, a film): its mirror reflection, measured over the outgoing bucket around the mirror direction, is written as a sharp lobe of the same power about the mirror direction at every incident angle (half vectors spread by {width:.2} deg, the finest this {n} x {n} grid resolves{})",
            if 2 * n - 1 <= goniospec::export::rgl::MAX_RESOLUTION {
                format!("; --resolution {} makes it four times finer", 2 * n - 1)
            } else {
                String::new()
            }
        );
    }
    if !report.mirror_power.is_empty() {
        let list: Vec<String> = report
            .mirror_power
            .iter()
            .map(|(t, e)| format!("{t:.0} deg {e:.4}"))
            .collect();
        eprintln!(
            "note: the mirror's power, a fraction of the incident (mean over wavelength): {}",
            list.join(", ")
        );
    }
    if let Some((dtheta, dphi)) = report.mirror_aperture_deg {
        let why = report.no_sharp_mirror.as_deref().unwrap_or("");
        eprintln!(
            "note: the sample's surface facing the light is flat (a clear coat, a film): its mirror reflection is written as the simulation measured it, spread over the outgoing bucket around the mirror direction ({dtheta:.1} x {dphi:.1} degrees in theta_o x phi_o), as a goniospectrometer of that aperture measures it, not as a sharp lobe: {why}"
        );
    }
    outln!(
        "wrote {} (RGL tensor file, {n} x {n} warped grid, {} incident angles, {} fields, {:.1} MB, {:.2} s)",
        a.output.display(),
        fields
            .iter()
            .find(|f| f.name == "theta_i")
            .map_or(0, |f| f.shape[0]),
        fields.len(),
        tensor::to_bytes(&fields).len() as f64 / 1e6,
        t0.elapsed().as_secs_f64()
    );
    write_scenes(&a, &scenes)?;
    Ok(ExitCode::SUCCESS)
}

/// The scenes `--scene` asks for: each format with its path, checked against the output
/// policy, and the render configuration of the view.
fn scene_plan(
    a: &ExportArgs,
    sample_path: &std::path::Path,
) -> Result<Vec<(SceneFormat, PathBuf, goniospec::render::RenderConfig)>> {
    use goniospec::render::Shape;
    let mut out = Vec::new();
    for &f in &a.scene {
        let path = a.output.with_extension(f.extension());
        if path == a.output {
            bail!(
                "the scene {} would replace the .bsdf: give the .bsdf another extension",
                path.display()
            );
        }
        guard_output(
            &path,
            &[a.input.as_path(), sample_path],
            OutputKind::Scene,
            a.force,
        )?;
        let shape = match &a.view.shape {
            super::render::ShapeArg::Sphere => Shape::Sphere,
            super::render::ShapeArg::Plane => Shape::Plane,
            super::render::ShapeArg::Obj(p) => bail!(
                "--scene writes a sphere or a plane (--shape), not {}: put the .bsdf on your own mesh in the renderer",
                p.display()
            ),
        };
        out.push((f, path, a.view.config(&shape)?));
    }
    Ok(out)
}

/// Writes the planned scenes beside the .bsdf (atomically), naming it by its file name.
fn write_scenes(
    a: &ExportArgs,
    scenes: &[(SceneFormat, PathBuf, goniospec::render::RenderConfig)],
) -> Result<()> {
    use goniospec::export::scene::{self, SceneShape};
    let shape = match a.view.shape {
        super::render::ShapeArg::Plane => SceneShape::Plane,
        _ => SceneShape::Sphere,
    };
    let bsdf = a
        .output
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    for (f, path, cfg) in scenes {
        let text = match f {
            SceneFormat::Mitsuba => scene::mitsuba_xml(cfg, shape, &bsdf)?,
            SceneFormat::Pbrt => {
                let stem = a
                    .output
                    .file_stem()
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_default();
                scene::pbrt_scene(cfg, shape, &bsdf, &format!("{stem}-pbrt.exr"))?
            }
        };
        goniospec::io::write_atomic(path, |w| w.write_all(text.as_bytes()))
            .with_context(|| format!("writing {}", path.display()))?;
        outln!(
            "wrote {} ({} scene: {}x{} at {} spp, the view of goniospec render with the same flags)",
            path.display(),
            match f {
                SceneFormat::Mitsuba => "Mitsuba 3",
                SceneFormat::Pbrt => "pbrt-v4",
            },
            cfg.width,
            cfg.height,
            cfg.spp
        );
    }
    Ok(())
}

/// A renderer's table reaching beyond the simulated incident angles holds the last one's
/// BRDF unchanged up to 90 deg (issue 71: with 0/30/60 deg simulated, the car paint's
/// values at 60, 70 and 80 deg were the same, without the rise of its coat's Fresnel
/// reflection towards grazing). From this angle up the hold is accepted as it is.
const HELD_FROM_DEG: f64 = 75.0;

/// Refuses, without `force`, a BRDF whose simulated incident angles end below
/// [`HELD_FROM_DEG`], saying which angles a renderer would get held; with `force`, says
/// so and goes on. A BRDF whose settings name no angles (not from a simulation) passes.
fn angles_covered(
    r: &goniospec::brdf::Representation,
    input: &std::path::Path,
    force: bool,
) -> Result<()> {
    use goniospec::brdf::Brdf;
    let settings: toml::Table = toml::from_str(&r.meta().simulation).unwrap_or_default();
    let Some(list) = settings.get("theta_i_deg").and_then(|v| v.as_array()) else {
        return Ok(());
    };
    // Each polar angle once (a run over several azimuths repeats them).
    let mut angles: Vec<f64> = Vec::new();
    for t in list
        .iter()
        .filter_map(|v| v.as_float().or(v.as_integer().map(|i| i as f64)))
    {
        if !angles.contains(&t) {
            angles.push(t);
        }
    }
    let hi = angles.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if angles.is_empty() || hi >= HELD_FROM_DEG {
        return Ok(());
    }
    let said = angles
        .iter()
        .map(|t| format!("{t}"))
        .collect::<Vec<_>>()
        .join(", ");
    let sentence = format!(
        "simulated at incident angles {said} deg only: a renderer asks up to 90 deg, and from {hi} to 90 deg it would get the {hi} deg BRDF held unchanged, without the rise of the surface's reflection towards grazing"
    );
    if !force {
        bail!(
            "{}: {sentence}. Simulate up to at least {HELD_FROM_DEG} deg (e.g. --theta-i 0:80:10), or pass --force to write it anyway",
            input.display()
        );
    }
    eprintln!("note: {sentence} (written so by --force)");
    Ok(())
}
