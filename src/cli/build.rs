//! `goniospec build`: turn an accumulator into a BRDF representation.

use super::{Args, Context, ExitCode, OutputKind, PathBuf, Result, guard_output, positive};

pub(super) fn parse_repr(s: &str) -> Result<goniospec::brdf::Kind, goniospec::brdf::BrdfError> {
    goniospec::brdf::Kind::parse(s)
}

#[derive(Args)]
pub(super) struct BuildArgs {
    /// The accumulator (.gsa).
    input: PathBuf,
    /// Representation: kdtree, subdivided or table.
    #[arg(long, default_value = "kdtree", value_parser = parse_repr)]
    repr: goniospec::brdf::Kind,
    /// Output BRDF (.gsb), written atomically.
    #[arg(short, long)]
    output: PathBuf,
    /// Overwrite an existing output that is not a goniospec BRDF.
    #[arg(long)]
    force: bool,
    /// kd-tree: neighbours blended per query (1 to 1024).
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u16).range(1..=goniospec::brdf::kdtree::MAX_K as i64))]
    k: u16,
    /// Subdivided: relative RMS deviation above which a cell splits (positive).
    #[arg(long, value_parser = positive, default_value_t = 0.05)]
    tolerance: f64,
    /// kd-tree: keep absolute azimuths instead of reducing to phi_o - phi_i. The default
    /// where the run has several incident azimuths (`simulate --phi-i 0,30,60,90`).
    #[arg(long, conflicts_with = "isotropic")]
    anisotropic: bool,
    /// Reduce to phi_o - phi_i (average over the incident azimuth): the default for a
    /// rotation-symmetric sample lit from one azimuth. A sample that is not
    /// rotation-symmetric (a grating, grooves: `info` says so) lit from one azimuth is
    /// refused without this flag or --anisotropic, since no representation can make the
    /// other azimuths from it.
    #[arg(long)]
    isotropic: bool,
    /// kd-tree: also enter each bucket as its reciprocal pair (wo, wi).
    #[arg(long)]
    reciprocal: bool,
    /// The BRDF of polarised light in, from a .gsa simulated with --mueller: unpolarised,
    /// s, p, +45, -45, circular+ (S3 = +1), circular- (S3 = -1), or a Stokes vector
    /// S0,S1,S2,S3 in the incident direction's s/p frame (docs/physics.md,
    /// "Polarisation"). Each bucket's Mueller matrix applied to it; the .gsb records it.
    #[arg(long, value_parser = goniospec::optics::mueller::stokes_state, allow_hyphen_values = true)]
    incident: Option<[f64; 4]>,
}

pub(super) fn build(a: BuildArgs) -> Result<ExitCode> {
    use goniospec::brdf::{self, BucketData, Representation};
    guard_output(&a.output, &[a.input.as_path()], OutputKind::Gsb, a.force)?;
    let acc = super::read_accumulator(&a.input)?;
    let data = match &a.incident {
        Some(st) => BucketData::from_accumulator_polarised(&acc, st)
            .map_err(|m| anyhow::anyhow!("{}: {m}", a.input.display()))?,
        None => BucketData::from_accumulator(&acc),
    };
    let t0 = std::time::Instant::now();
    let opts = brdf::BuildOptions {
        k: usize::from(a.k),
        tolerance: a.tolerance,
        isotropic: brdf::symmetry::isotropic(
            &acc.header.settings,
            (a.isotropic || a.anisotropic).then_some(a.isotropic),
        )
        .map_err(|m| anyhow::anyhow!("{}: {m}", a.input.display()))?,
        reciprocal: a.reciprocal,
    };
    let r = Representation::build(a.repr, &data, &opts).map_err(|m| anyhow::anyhow!(m))?;
    let built = t0.elapsed().as_secs_f64();
    brdf::file::write(&r, &a.output).with_context(|| format!("writing {}", a.output.display()))?;
    outln!(
        "wrote {} ({} representation, built in {built:.3} s)",
        a.output.display(),
        a.repr
    );
    Ok(ExitCode::SUCCESS)
}
