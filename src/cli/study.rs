//! `goniospec study`: run a sweep and write its report and charts.

use super::{Args, Context, ExitCode, PathBuf, Result};

#[derive(Args)]
pub(super) struct StudyArgs {
    /// The study description (TOML).
    study: PathBuf,
    /// Output folder.
    #[arg(short, long)]
    output: PathBuf,
}

pub(super) fn study(a: StudyArgs) -> Result<ExitCode> {
    let st = goniospec::study::load(&a.study)?;
    let (points, reference) =
        goniospec::study::run(&st, |l| eprintln!("{l}")).map_err(|e| anyhow::anyhow!(e))?;
    goniospec::study::write(&st, &points, &reference, &a.output)
        .with_context(|| format!("writing into {}", a.output.display()))?;
    let mut charts = goniospec::study::charts(&points, &a.output)
        .map_err(|e| anyhow::anyhow!("drawing the charts: {e}"))?;
    let area =
        goniospec::study::run_area(&st, |l| eprintln!("{l}")).map_err(|e| anyhow::anyhow!(e))?;
    charts.extend(
        goniospec::study::write_area(&area, &a.output)
            .map_err(|e| anyhow::anyhow!("sampled-area chart: {e}"))?,
    );
    for c in &charts {
        outln!("wrote {}", c.display());
    }
    outln!(
        "wrote {} and {} ({} points)",
        a.output.join("points.csv").display(),
        a.output.join("report.md").display(),
        points.len()
    );
    Ok(ExitCode::SUCCESS)
}
