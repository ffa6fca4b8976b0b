//! `goniospec export`: a built BRDF in another tool's format.

use super::*;

#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(super) enum ExportFormat {
    /// RGL tensor file (.bsdf) for Mitsuba 3's and pbrt-v4's `measured` material.
    Rgl,
}

#[derive(Args)]
pub(super) struct ExportArgs {
    /// The built BRDF (.gsb).
    input: PathBuf,
    /// Output format.
    #[arg(long, value_enum, default_value_t = ExportFormat::Rgl)]
    format: ExportFormat,
    /// The sample the BRDF was simulated from: its facets give the microfacet
    /// distribution D(m) the RGL parameterisation warps by (the .gsb does not carry it).
    #[arg(long, value_name = "SAMPLE.toml")]
    sample: PathBuf,
    /// Nodes per side of the warped grids, odd, 3 to 255: finer follows narrower lobes
    /// and costs resolution^2 x angles x wavelengths x 4 bytes.
    #[arg(long, default_value_t = 65, value_parser = clap::value_parser!(u16).range(3..=goniospec::export::rgl::MAX_RESOLUTION as i64))]
    resolution: u16,
    /// Incident angles of the tabulation, degrees in [0, 90), comma-separated (default:
    /// the angles the BRDF was simulated at).
    #[arg(long, value_delimiter = ',', value_parser = finite)]
    theta_i: Vec<f64>,
    /// Output file, written atomically.
    #[arg(short, long)]
    output: PathBuf,
    /// Overwrite an existing output that is not an RGL tensor file.
    #[arg(long)]
    force: bool,
    /// Worker threads (0: all cores). The file does not depend on it.
    #[arg(long, default_value_t = 0)]
    threads: usize,
}

pub(super) fn export(a: ExportArgs) -> Result<ExitCode> {
    use goniospec::brdf::{self, Brdf};
    use goniospec::export::{self, rgl, tensor};
    guard_output(
        &a.output,
        &[a.input.as_path(), a.sample.as_path()],
        OutputKind::Tensor,
        a.force,
    )?;
    let r = brdf::file::read(&a.input)?;
    let theta_i = if a.theta_i.is_empty() {
        export::simulated_incidence(&r).map_err(|m| anyhow::anyhow!(m))?
    } else {
        a.theta_i.iter().map(|t| t.to_radians()).collect()
    };
    let s = sample::load(&a.sample, MeshOptions::default())?;
    if s.name != r.meta().sample_name {
        bail!(
            "{} is the sample '{}', but {} was simulated from '{}'",
            a.sample.display(),
            s.name,
            a.input.display(),
            r.meta().sample_name
        );
    }
    let pool = thread_pool(a.threads)?;
    let n = usize::from(a.resolution);
    let t0 = std::time::Instant::now();
    let (fields, report) = pool.install(|| -> Result<_> {
        let scene = goniospec::trace::Scene::new(&s, resolve_backend(None)?)?;
        let d = rgl::FacetDistribution::from_sample(&s, scene.ambient, n, r.meta().isotropic)
            .map_err(|m| anyhow::anyhow!("{}: {m}", a.sample.display()))?;
        let opts = rgl::RglOptions {
            resolution: n,
            theta_i,
            description: format!(
                "goniospec {} export of '{}' ({} representation, {} wavelengths)",
                env!("CARGO_PKG_VERSION"),
                r.meta().sample_name,
                r.meta().repr,
                r.meta().wavelengths_nm.len()
            ),
        };
        rgl::rgl_fields(&r, &d, &opts).map_err(|m| anyhow::anyhow!("{}: {m}", a.input.display()))
    })?;
    tensor::write(&fields, &a.output).with_context(|| format!("writing {}", a.output.display()))?;
    if report.negative > 0 {
        eprintln!(
            "note: {} of the {} tabulated BRDF values were negative (beamlet cross terms, most negative {:.3e} 1/sr); the RGL format holds none, so they were written as 0",
            report.negative, report.values, report.most_negative
        );
    }
    outln!(
        "wrote {} (RGL tensor file, {n} x {n} warped grid, {} fields, {:.1} MB, {:.2} s)",
        a.output.display(),
        fields.len(),
        tensor::to_bytes(&fields).len() as f64 / 1e6,
        t0.elapsed().as_secs_f64()
    );
    Ok(ExitCode::SUCCESS)
}
