//! `goniospec plot`: pictures of a built BRDF.

use super::{Args, ExitCode, OutputKind, PathBuf, Result, bail, finite, guard_output, thread_pool};

#[derive(Args)]
pub(super) struct PlotArgs {
    /// The built BRDF (.gsb), or an RGL .bsdf (measured, or exported); an RGB .bsdf is
    /// drawn with one curve per channel, coloured as the channel.
    input: PathBuf,
    /// Incident polar angle, degrees in [0, 90).
    #[arg(long, value_parser = finite)]
    theta_i: f64,
    /// Incident azimuth, degrees.
    #[arg(long, value_parser = finite, default_value_t = 0.0)]
    phi_i: f64,
    /// Output image: .png or .svg, written atomically.
    #[arg(short, long)]
    output: PathBuf,
    /// Draw the lobe's radius on a log scale over this many decades below its peak (1 to
    /// 12): one bright order or mirror lobe then leaves the others visible. Default: linear.
    #[arg(long, value_name = "DECADES", value_parser = clap::value_parser!(u32).range(1..=12))]
    log_decades: Option<u32>,
    /// Points per side of the hemisphere colour map (8 to 1024).
    #[arg(long, default_value_t = 160, value_parser = clap::value_parser!(u16).range(8..=1024))]
    map_resolution: u16,
    /// Worker threads (0: all cores). The image does not depend on it.
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Replace an existing output even when it is not an image.
    #[arg(long)]
    force: bool,
}

pub(super) fn plot(a: PlotArgs) -> Result<ExitCode> {
    guard_output(&a.output, &[a.input.as_path()], OutputKind::Image, a.force)?;
    if !matches!(
        a.output.extension().and_then(|e| e.to_str()),
        Some("png" | "svg")
    ) {
        bail!(
            "{}: the plot is written as .png or .svg",
            a.output.display()
        );
    }
    let material = super::Material::open(&a.input)?;
    let r = material.brdf();
    let pool = thread_pool(a.threads)?;
    let mut plot = pool
        .install(|| {
            goniospec::plot::LobePlot::new(r, a.theta_i, a.phi_i, usize::from(a.map_resolution))
        })
        .map_err(anyhow::Error::msg)?;
    plot.log_decades = a.log_decades;
    plot.write(&a.output)?;
    if material.is_rgb() {
        outln!(
            "wrote {} (an RGB file: curves and colours of its linear sRGB channels)",
            a.output.display()
        );
    } else {
        outln!("wrote {}", a.output.display());
    }
    Ok(ExitCode::SUCCESS)
}
