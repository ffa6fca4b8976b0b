//! `goniospec check`: load a sample and look for defects.

use super::*;

#[derive(Args)]
pub(super) struct CheckArgs {
    /// The sample description (TOML).
    sample: PathBuf,
    /// Drop degenerate (zero-area) triangles instead of refusing the mesh.
    #[arg(long)]
    drop_degenerate: bool,
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
}

pub(super) fn check(a: CheckArgs) -> Result<ExitCode> {
    let opts = MeshOptions {
        drop_degenerate: a.drop_degenerate,
    };
    let s = sample::load(&a.sample, opts)?;
    let copts = sample::check::CheckOptions {
        backend: resolve_backend(a.backend)?,
        leak_rays: a.leak_rays,
        seed: a.seed,
        ..Default::default()
    };
    let report = sample::check::check(&s, &copts)?;
    for f in &report.facts {
        outln!("{f}");
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
