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
    /// grid, the axes in degrees, lambda_nm, and the settings as JSON.
    Npz,
    /// MERL binary (90 x 90 x 180 half/difference cells, isotropic, linear sRGB with the
    /// reader's scale factors) for fitting tools. It loses the spectrum.
    Merl,
}

#[derive(Args)]
pub(super) struct ExportArgs {
    /// The built BRDF (.gsb).
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
    /// the angles the BRDF was simulated at).
    #[arg(long, value_delimiter = ',', value_parser = finite)]
    theta_i: Vec<f64>,
    /// Output file, written atomically.
    #[arg(short, long)]
    output: PathBuf,
    /// Overwrite an existing output that is not a file of the chosen format.
    #[arg(long)]
    force: bool,
    /// Worker threads (0: all cores). The file does not depend on it.
    #[arg(long, default_value_t = 0)]
    threads: usize,
}

pub(super) fn export(a: ExportArgs) -> Result<ExitCode> {
    match a.format {
        ExportFormat::Rgl => export_rgl(a),
        ExportFormat::Npz => export_npz(a),
        ExportFormat::Merl => export_merl(a),
    }
}

fn export_merl(a: ExportArgs) -> Result<ExitCode> {
    use goniospec::brdf;
    guard_output(&a.output, &[a.input.as_path()], OutputKind::Merl, a.force)?;
    let r = brdf::file::read(&a.input)?;
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
    let bytes = pool
        .install(|| npz::npz_bytes(&r, &grid))
        .map_err(|m| anyhow::anyhow!("{}: {m}", a.input.display()))?;
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
    let r = brdf::file::read(&a.input)?;
    let theta_i =
        (!a.theta_i.is_empty()).then(|| a.theta_i.iter().map(|t| t.to_radians()).collect());
    let s = sample::load(&sample_path, MeshOptions::default())?;
    let pool = thread_pool(a.threads)?;
    let n = usize::from(a.resolution);
    let t0 = std::time::Instant::now();
    let (fields, report) = pool
        .install(|| export::rgl_for(&r, &s, n, theta_i))
        .map_err(|m| anyhow::anyhow!("{} ({}): {m}", a.input.display(), sample_path.display()))?;
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
