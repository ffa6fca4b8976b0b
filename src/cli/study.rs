//! `goniospec study`: run a sweep and write its report and charts.

use super::{Args, Context, ExitCode, PathBuf, Result};

#[derive(Args)]
pub(super) struct StudyArgs {
    /// The study description (TOML).
    study: PathBuf,
    /// Output folder (made when missing): points.csv, report.md and the charts. Files of
    /// those names that goniospec did not write there are not replaced.
    #[arg(short, long)]
    output: PathBuf,
    /// Replace files of the study's names in the folder even where goniospec did not write
    /// them.
    #[arg(long)]
    force: bool,
}

pub(super) fn study(a: StudyArgs) -> Result<ExitCode> {
    let st = goniospec::study::load(&a.study)?;
    // Before the run: the folder takes the study's files (issue 47: `-o FILE` failed after
    // the whole study, and a user's report.md in the folder was replaced).
    let names = goniospec::study::output_names();
    goniospec::output::guard_folder(&a.output, &names, a.force)?;
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
    let mut written = vec!["points.csv".to_string(), "report.md".to_string()];
    written.extend(
        charts
            .iter()
            .filter_map(|c| c.file_name().map(|n| n.to_string_lossy().into_owned())),
    );
    goniospec::output::record_folder(&a.output, &written)
        .with_context(|| format!("writing into {}", a.output.display()))?;
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
