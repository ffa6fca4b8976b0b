//! `goniospec render`: render a shape made of a BRDF (or simulate what the image needs first).

use super::{
    Args, Backend, Context, ExitCode, MeshOptions, OutputKind, PathBuf, Result, WavelengthArgs,
    bail, finite, guard_output, progress_bar, sample, thread_pool,
};

#[derive(Args)]
pub(super) struct RenderArgs {
    /// A built BRDF (.gsb), or an RGL .bsdf (a measured material, rendered in its RGB
    /// channels where the file is RGB); or give --simulate SAMPLE.toml instead.
    #[arg(required_unless_present = "simulate", conflicts_with = "simulate")]
    file: Option<PathBuf>,
    /// Simulate the sample first, only at the incident angles the image needs.
    #[arg(long, value_name = "SAMPLE.toml")]
    simulate: Option<PathBuf>,
    /// With --simulate: relative standard error each needed direction is simulated to
    /// (total R and every populated bucket, per wavelength bin). 0.05 is about one CIELAB
    /// unit at mid-grey: dL* = 21.8 dY/Y at Y = 0.18, from L* = 116 Y^(1/3) - 16.
    #[arg(long, value_parser = finite, default_value_t = 0.05)]
    tolerance: f64,
    /// With --simulate, instead of --tolerance: the median relative standard error of the
    /// buckets that hold 95 % of each wavelength's reflected power, per direction
    /// (`simulate --target-stderr`; the errors are the replicate groups', README,
    /// "Simulation").
    #[arg(long, value_parser = finite, conflicts_with = "tolerance")]
    target_stderr: Option<f64>,
    /// With --simulate: trees per batch per direction (the adaptive step).
    #[arg(long, default_value_t = 512)]
    rays: u64,
    /// With --simulate: the most trees per direction.
    #[arg(long, default_value_t = 16_384)]
    max_rays: u64,
    /// With --simulate: spacing of the incident-angle grid, degrees (full hemisphere:
    /// 0, STEP, ..., below 90).
    #[arg(long, value_parser = finite, default_value_t = 5.0)]
    theta_step: f64,
    /// With --simulate: the wavelength sampling.
    #[command(flatten)]
    wavelengths: WavelengthArgs,
    /// Output EXR; the PNG preview goes beside it.
    #[arg(short, long)]
    output: PathBuf,
    /// The shape, image, camera, light and environment.
    #[command(flatten)]
    view: ViewArgs,
    /// Worker threads (0: all cores). Images do not depend on it.
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Replace existing outputs (the image, its PNG preview, and with --simulate the .gsa
    /// and .gsb beside it) even when they are not files of their kind.
    #[arg(long)]
    force: bool,
    /// Also render the [stack] sample's analytic (TMM) reflectance under the same
    /// environment and report the difference (relative RMSE, mean CIE DE2000).
    #[arg(long, value_name = "SAMPLE.toml")]
    analytic: Option<PathBuf>,
}

/// What an image shows and how it is lit: `render`'s flags, shared with `export --scene`,
/// which writes a Mitsuba 3 or pbrt-v4 scene of the same view (docs/design.md §10, "Light
/// and units"). Radiometry is in radiance factors relative to illuminant D65.
#[derive(Args)]
pub(super) struct ViewArgs {
    /// sphere (radius 1 at the origin), plane (the square [-1, 1]^2 at z = 0, facing up), or
    /// an OBJ file (smooth normals are computed from its triangles).
    #[arg(long, default_value = "sphere", value_parser = parse_shape)]
    pub(super) shape: ShapeArg,
    /// Image width, pixels (1 to 16384).
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub(super) width: u32,
    /// Image height, pixels (1 to 16384).
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(1..=16384))]
    pub(super) height: u32,
    /// Samples per pixel (1 to 65536).
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub(super) spp: u32,
    /// dir:THETA,PHI (degrees, the direction towards the light), point:X,Y,Z, or none.
    #[arg(long, default_value = "dir:50,-120", value_parser = goniospec::render::Light::parse)]
    pub(super) light: goniospec::render::Light,
    /// The light's irradiance on a surface facing it, in units of pi x D65: a white
    /// Lambertian surface facing the light has radiance factor STRENGTH (a point light: at
    /// the distance of the origin, falling off as 1/r^2).
    #[arg(long, value_parser = finite, default_value_t = 0.8)]
    pub(super) light_strength: f64,
    /// constant (uniform over the sphere of directions), sky (0.25 + 0.75 max(0, z)) or
    /// none.
    #[arg(long, default_value = "constant", value_parser = goniospec::render::Env::parse)]
    pub(super) env: goniospec::render::Env,
    /// The environment's radiance, in units of D65: a white Lambertian surface under the
    /// constant environment has radiance factor STRENGTH.
    #[arg(long, value_parser = finite, default_value_t = 0.6)]
    pub(super) env_strength: f64,
    /// Camera position X,Y,Z; it looks at the shape's centre with z up (default: the
    /// centre plus (0, -4.2 r, 1.6 r), r the shape's bounding radius: 0,-4.2,1.6 for the
    /// sphere, 0,-5.94,2.26 for the plane).
    #[arg(long, value_parser = finite, value_delimiter = ',')]
    pub(super) camera: Vec<f64>,
    /// Vertical field of view, degrees.
    #[arg(long, value_parser = finite, default_value_t = 30.0)]
    pub(super) fov: f64,
    /// Seed of the pixels' random streams.
    #[arg(long, default_value_t = 1)]
    pub(super) seed: u64,
}

impl ViewArgs {
    /// The renderer's configuration for `shape` (the default camera from its bounds),
    /// checked: a field of view in (0, 180) degrees, strengths not negative.
    pub(super) fn config(
        &self,
        shape: &goniospec::render::Shape,
    ) -> Result<goniospec::render::RenderConfig> {
        let (centre, radius) = shape.bounds();
        let camera = match self.camera.len() {
            0 => [
                centre[0],
                centre[1] - 4.2 * radius,
                centre[2] + 1.6 * radius,
            ],
            3 => [self.camera[0], self.camera[1], self.camera[2]],
            _ => bail!("--camera needs X,Y,Z"),
        };
        if !(self.fov > 0.0 && self.fov < 180.0) {
            bail!("--fov must be between 0 and 180 degrees, got {}", self.fov);
        }
        if self.light_strength < 0.0 || self.env_strength < 0.0 {
            bail!("--light-strength and --env-strength must not be negative");
        }
        Ok(goniospec::render::RenderConfig {
            width: self.width as usize,
            height: self.height as usize,
            spp: self.spp as usize,
            light: self.light,
            light_strength: self.light_strength,
            env: self.env,
            env_strength: self.env_strength,
            camera: camera.into(),
            fov_deg: self.fov,
            seed: self.seed,
        })
    }
}

/// `--shape`: a built-in shape or an OBJ file.
#[derive(Clone, Debug, PartialEq)]
pub(super) enum ShapeArg {
    Sphere,
    Plane,
    Obj(PathBuf),
}

pub(super) fn parse_shape(s: &str) -> Result<ShapeArg, String> {
    match s {
        "sphere" => Ok(ShapeArg::Sphere),
        "plane" => Ok(ShapeArg::Plane),
        "" => Err("--shape needs sphere, plane or an OBJ file".into()),
        path => Ok(ShapeArg::Obj(PathBuf::from(path))),
    }
}

/// A table simulated from a sample whose surface facing the light is flat (a clear coat,
/// a flat film) is rendered with its mirror as the sharp lobe `export` writes
/// (`export::mirror::for_render`), so that the image and the renderers reading the export
/// show the same material (issue 71): the table alone shows the mirror spread over its
/// bucket, and between two simulated angles as two half-height copies at their mirrors.
/// Says why where the mirror stays as the buckets hold it.
fn sharp_mirror(path: &std::path::Path) -> Option<goniospec::export::mirror::SharpMirror> {
    let r = goniospec::brdf::file::read(path).ok()?;
    match goniospec::export::mirror::for_render(&r) {
        Ok(m) => m,
        Err(why) => {
            eprintln!(
                "note: the sample's surface facing the light is flat, but its mirror is drawn as the buckets hold it: {}",
                why.0
            );
            None
        }
    }
}

pub(super) fn render(a: RenderArgs) -> Result<ExitCode> {
    use goniospec::render::{self, Env};
    let v = &a.view;
    let shape = shape_of(&v.shape)?;
    // The output folder is made, and checked writable, before any work.
    if let Some(dir) = a.output.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    guard_outputs(&a)?;
    let cfg = v.config(&shape)?;
    let env = cfg.env;
    let pool = thread_pool(a.threads)?;
    let material = match (&a.file, &a.simulate) {
        (Some(f), _) => super::Material::open(f)?,
        (None, Some(sp)) => super::Material(Box::new(
            pool.install(|| scene_driven(&a, sp, &shape, &cfg))?,
        )),
        (None, None) => bail!("give a .gsb or .bsdf file, or --simulate SAMPLE.toml"),
    };
    let sharp = a.file.as_deref().and_then(sharp_mirror);
    let r = match &sharp {
        Some(m) => m,
        None => material.brdf(),
    };
    // The image holds RGB and a spectrum per pixel (f32): refuse what cannot fit.
    let bins = r.meta().lambda_nm.len() as f64;
    let bytes = f64::from(a.view.width) * f64::from(a.view.height) * 4.0 * (3.0 + bins) * 2.0;
    if let Some(avail) = goniospec::io::available_memory_bytes()
        && bytes > avail as f64
    {
        bail!(
            "--width {} x --height {} with {bins} wavelength bins needs about {:.1} GB, more than the {:.1} GB available",
            a.view.width,
            a.view.height,
            bytes / 1e9,
            avail as f64 / 1e9
        );
    }
    let t0 = std::time::Instant::now();
    let albedo = match (env, &sharp) {
        (Env::Constant, Some(m)) => Some(pool.install(|| m.albedo_table(90))),
        (Env::Constant, None) => Some(pool.install(|| render::albedo_table(r, 90))),
        _ => None,
    };
    let bar = progress_bar(u64::from(a.view.height), "rows");
    let img = pool
        .install(|| render::render(r, &shape, &cfg, albedo.as_deref(), &|n| bar.set_position(n)));
    bar.finish_and_clear();
    let secs = t0.elapsed().as_secs_f64();
    // Both files are written before either replaces an old one.
    let png = a.output.with_extension("png");
    let exr_file = render::stage_exr(&img, &a.output)
        .with_context(|| format!("writing {}", a.output.display()))?;
    let png_file =
        render::stage_png(&img, &png).with_context(|| format!("writing {}", png.display()))?;
    goniospec::io::commit_all(vec![exr_file, png_file])
        .with_context(|| format!("replacing {} and {}", a.output.display(), png.display()))?;
    let channels = if material.is_rgb() {
        "in RGB, the file's form (linear sRGB channels, not spectra)".to_string()
    } else {
        format!("{} wavelength bins", r.meta().lambda_nm.len())
    };
    outln!(
        "rendered {}x{} at {} spp, {channels} ({} representation) in {secs:.2} s: {} and {}",
        a.view.width,
        a.view.height,
        a.view.spp,
        r.meta().repr,
        a.output.display(),
        png.display()
    );
    if let Some(sp) = &a.analytic {
        against_analytic(&a, sp, r.meta(), &img, &shape, &cfg)?;
    }
    Ok(ExitCode::SUCCESS)
}

/// The object `--shape` names: a sphere, a plane, or an OBJ mesh (degenerate triangles
/// dropped).
fn shape_of(shape: &ShapeArg) -> Result<goniospec::render::Shape> {
    use goniospec::render::Shape;
    Ok(match shape {
        ShapeArg::Sphere => Shape::Sphere,
        ShapeArg::Plane => Shape::Plane,
        ShapeArg::Obj(p) => {
            let mesh = sample::load_obj(
                p,
                1.0,
                MeshOptions {
                    drop_degenerate: true,
                    ..MeshOptions::default()
                },
            )?;
            Shape::mesh(mesh, Backend::default_available())?
        }
    })
}

/// Checks, before any work, that the image pair (and, with `--simulate`, the `.gsa` and
/// `.gsb` written beside it) may be written: never an input of the run, and replacing only
/// files of their kind.
fn guard_outputs(a: &RenderArgs) -> Result<()> {
    let png = a.output.with_extension("png");
    let inputs: Vec<&std::path::Path> = a
        .file
        .iter()
        .chain(a.simulate.iter())
        .map(|p| p.as_path())
        .collect();
    for out in [&a.output, &png] {
        guard_output(out, &inputs, OutputKind::Image, a.force)?;
    }
    // The accumulator and BRDF written beside the image: never an input of the run, and
    // replaced only when they are of their kind (they replaced any NAME.gsa / NAME.gsb).
    if let Some(sample) = &a.simulate {
        let s = sample::load(sample, MeshOptions::default())?;
        let mut all = inputs.clone();
        all.extend(s.inputs.iter().map(|p| p.as_path()));
        guard_output(
            &a.output.with_extension("gsa"),
            &all,
            OutputKind::Gsa,
            a.force,
        )?;
        guard_output(
            &a.output.with_extension("gsb"),
            &all,
            OutputKind::Gsb,
            a.force,
        )?;
    }

    Ok(())
}

/// `render --analytic`: the exact specular image of the `[stack]` sample `sp` with the
/// same camera and light, written beside the render, and the difference printed.
fn against_analytic(
    a: &RenderArgs,
    sp: &std::path::Path,
    meta: &goniospec::brdf::Meta,
    img: &goniospec::render::Image,
    shape: &goniospec::render::Shape,
    cfg: &goniospec::render::RenderConfig,
) -> Result<()> {
    use goniospec::render::{self, Light};
    let s = sample::load(sp, MeshOptions::default())?;
    let reference = render::analytic::stack_image(&s, meta, shape, cfg)?;
    let apng = a.output.with_file_name(format!(
        "{}-analytic.png",
        a.output.file_stem().unwrap_or_default().to_string_lossy()
    ));
    render::write_png(&reference, &apng)?;
    let d = render::analytic::compare(img, &reference);
    outln!(
        "against the analytic TMM image ({}): relative RMSE {:.4}, mean CIE DE2000 {:.3} over {} object pixels{}",
        apng.display(),
        d.rel_rmse,
        d.mean_de2000,
        d.pixels,
        if cfg.light != Light::None {
            " (the light's delta reflection is left out of both)"
        } else {
            ""
        }
    );
    Ok(())
}

/// `render --simulate`: simulates the incident angles the image needs
/// (`goniospec::render::plan::simulate_scene`), writes the .gsa and .gsb beside the image,
/// reports the saving against a full-hemisphere simulation, and returns the BRDF table.
pub(super) fn scene_driven(
    a: &RenderArgs,
    sample_path: &std::path::Path,
    shape: &goniospec::render::Shape,
    cfg: &goniospec::render::RenderConfig,
) -> Result<goniospec::brdf::Representation> {
    use goniospec::render::plan::{SceneBudget, simulate_scene};
    let budget = SceneBudget {
        theta_step_deg: a.theta_step,
        rays: a.rays,
        max_rays: a.max_rays,
        tolerance: a.tolerance,
        target_stderr: a.target_stderr,
        seed: a.view.seed,
        wavelengths: a.wavelengths.parse()?,
    };
    let plan = budget.plan(shape, cfg)?;
    let s = sample::load(sample_path, MeshOptions::default())?;
    let needed = plan.needed();
    eprintln!(
        "scene-driven simulation: the image ({} object pixels) needs {} of the {} incident angles of the {}-degree grid: {:?}",
        plan.object_pixels,
        needed.len(),
        plan.grid_deg.len(),
        a.theta_step,
        needed
    );
    let bar = progress_bar(a.max_rays * needed.len() as u64, "trees (at most)");
    let run = simulate_scene(&s, plan, &budget, &|n| bar.set_position(n))?;
    bar.finish_and_clear();
    let gsa = a.output.with_extension("gsa");
    run.acc
        .write(&gsa)
        .with_context(|| format!("writing {}", gsa.display()))?;
    let gsb = a.output.with_extension("gsb");
    goniospec::brdf::file::write(&run.brdf, &gsb)
        .with_context(|| format!("writing {}", gsb.display()))?;
    let converged = run.stats.directions.iter().filter(|d| d.converged).count();
    for d in &run.stats.directions {
        eprintln!("  {d}");
    }
    let (saved, skipped) = run.saving_percent();
    let worst = run.largest_budget();
    // What the directions were run to, as the flag that set it.
    let goal = match a.target_stderr {
        Some(t) => format!("--target-stderr {t}"),
        None => format!("--tolerance {}", a.tolerance),
    };
    eprintln!(
        "simulated {} trees in {:.2} s ({} of {} directions converged to {goal}); a full-hemisphere simulation giving each of its directions the largest budget used here needs at least {} x {} = {} trees: {saved:.0} % saved ({skipped:.0} % by skipping directions, the rest by adaptive budgets). Wrote {} and {}",
        run.spent(),
        run.stats.seconds,
        converged,
        run.needed_deg.len(),
        run.plan.grid_deg.len(),
        worst,
        run.full_hemisphere_bound(),
        gsa.display(),
        gsb.display()
    );
    // Said before the image is made, so a noisy image is never a surprise (issue 49).
    let short = run.needed_deg.len() - converged;
    if short > 0 {
        let worst_error = run
            .stats
            .directions
            .iter()
            .filter(|d| !d.converged)
            .filter_map(|d| d.achieved)
            .fold(0.0f64, f64::max);
        eprintln!(
            "warning: {short} of {} directions did not reach {goal} within --max-rays {} (relative errors up to {worst_error:.3} remain); the image carries that noise. Raise --max-rays or loosen {}.",
            run.needed_deg.len(),
            a.max_rays,
            goal.split(' ').next().unwrap_or("the target")
        );
    }
    Ok(run.brdf)
}
