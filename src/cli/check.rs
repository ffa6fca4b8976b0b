//! `goniospec check`: load a sample and look for defects.

use super::{
    Args, Backend, ExitCode, MeshOptions, PathBuf, Result, bail, finite, parse_backend,
    parse_radius, positive, resolve_backend, sample,
};

#[derive(Args)]
pub(super) struct CheckArgs {
    /// The sample description (TOML).
    sample: PathBuf,
    /// Drop degenerate (zero-area) triangles instead of refusing the mesh.
    #[arg(long)]
    drop_degenerate: bool,
    /// Parse mesh files even where their binary cache (MESH.gsmesh, written beside meshes
    /// of 16 MiB and more and checked against the file's size, time and CRC-32) is valid,
    /// and write none.
    #[arg(long)]
    no_mesh_cache: bool,
    /// Accelerator for the intersection and leak tests: embree or obvhs (default: embree
    /// where available).
    #[arg(long, value_parser = parse_backend)]
    backend: Option<Backend>,
    /// Random walks of the leak test.
    #[arg(long, default_value_t = 20_000)]
    leak_rays: usize,
    /// Seed of the leak test.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Wavelength the validity warnings judge the sample at, nm (features against the
    /// wavelength: gratings, smooth roughness, sub-wavelength structure and bodies).
    #[arg(long, default_value_t = 550.0, value_parser = positive)]
    lambda_nm: f64,
    /// Most oblique incidence the validity warnings assume, degrees.
    #[arg(long, default_value_t = 0.0, value_parser = finite)]
    theta_max_deg: f64,
    /// The method the validity warnings judge: auto (default: what a run takes by
    /// default, with the methods it would choose per angle at --lambda-nm listed), beamlet
    /// (rays) or diffraction; as `simulate --coherence`.
    #[arg(long, default_value = "auto", value_parser = goniospec::simulate::coherence)]
    coherence: goniospec::accumulate::Coherence,
    /// Illumination coherence radius the validity warnings assume, nm (or inf).
    #[arg(long, default_value_t = goniospec::simulate::defaults::COHERENCE_RADIUS_NM, value_parser = parse_radius)]
    coherence_radius_nm: f64,
}

pub(super) fn check(a: CheckArgs) -> Result<ExitCode> {
    let opts = MeshOptions {
        drop_degenerate: a.drop_degenerate,
        cache: if a.no_mesh_cache {
            sample::cache::CachePolicy::Off
        } else {
            sample::cache::CachePolicy::Large
        },
    };
    if !(0.0..90.0).contains(&a.theta_max_deg) {
        bail!(
            "--theta-max-deg must be in [0, 90) degrees, got {}",
            a.theta_max_deg
        );
    }
    let s = sample::load(&a.sample, opts)?;
    let copts = goniospec::check::CheckOptions {
        backend: resolve_backend(a.backend)?,
        leak_rays: a.leak_rays,
        seed: a.seed,
        validity: Some(goniospec::simulate::check_validity_context(
            a.lambda_nm,
            a.theta_max_deg,
            a.coherence_radius_nm,
            a.coherence,
        )),
        ..Default::default()
    };
    let report = goniospec::simulate::auto::check(&s, &copts)?;
    for f in &report.facts {
        outln!("{f}");
    }
    for w in &report.warnings {
        outln!("WARNING: {w}");
    }
    if report.defects.is_empty() {
        outln!("no defects found");
        Ok(ExitCode::SUCCESS)
    } else {
        for d in &report.defects {
            outln!("DEFECT: {d}");
        }
        outln!("{} defects found", report.defects.len());
        Ok(ExitCode::from(1))
    }
}
