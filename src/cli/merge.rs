//! `goniospec merge`: add runs of different seeds.

use super::{Args, Context, ExitCode, OutputKind, PathBuf, Result, guard_output};

#[derive(Args)]
pub(super) struct MergeArgs {
    /// Accumulators to add (same sample and settings, different seeds).
    #[arg(required = true, num_args = 2..)]
    inputs: Vec<PathBuf>,
    /// Output accumulator.
    #[arg(short, long)]
    output: PathBuf,
    /// Overwrite an existing output that is not a goniospec accumulator.
    #[arg(long)]
    force: bool,
}

pub(super) fn merge(a: MergeArgs) -> Result<ExitCode> {
    let inputs: Vec<&std::path::Path> = a.inputs.iter().map(|p| p.as_path()).collect();
    guard_output(&a.output, &inputs, OutputKind::Gsa, a.force)?;
    let mut acc = super::read_accumulator(&a.inputs[0])?;
    for p in &a.inputs[1..] {
        let other = super::read_accumulator(p)?;
        acc.merge(&other)
            .with_context(|| format!("merging {}", p.display()))?;
    }
    acc.write(&a.output)
        .with_context(|| format!("writing {}", a.output.display()))?;
    outln!(
        "wrote {} ({} runs, {} rays per direction)",
        a.output.display(),
        acc.header.seeds.len(),
        acc.header.rays
    );
    Ok(ExitCode::SUCCESS)
}
