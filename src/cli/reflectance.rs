//! `goniospec reflectance`: the directional reflectance of an accumulator as CSV.

use super::{Args, Coherence, ExitCode, PathBuf, Result, finite};

#[derive(Args)]
pub(super) struct ReflectanceArgs {
    /// A .gsa accumulator.
    file: PathBuf,
    /// Incident polar angle, degrees (one of those simulated).
    #[arg(long, value_parser = finite)]
    theta_i: f64,
    /// Incident azimuth, degrees (must match the simulation's).
    #[arg(long, value_parser = finite)]
    phi_i: Option<f64>,
    /// Polarised light in, from a .gsa simulated with --mueller: unpolarised, s, p, +45,
    /// -45, circular+ (S3 = +1), circular- (S3 = -1), or a Stokes vector S0,S1,S2,S3 in the
    /// incident direction's s/p frame (docs/physics.md, "Polarisation"). Prints
    /// lambda_nm,R,T for that state: each bucket's Mueller matrix applied to it.
    #[arg(long, value_parser = goniospec::optics::mueller::stokes_state, allow_hyphen_values = true)]
    incident: Option<[f64; 4]>,
}

pub(super) fn reflectance(a: ReflectanceArgs) -> Result<ExitCode> {
    let acc = super::read_accumulator(&a.file)?;
    if let Some(state) = &a.incident {
        let rows = acc
            .polarised_reflectance(a.theta_i, a.phi_i, state)
            .map_err(|m| anyhow::anyhow!("{}: {m}", a.file.display()))?;
        outln!("lambda_nm,R,T");
        for r in rows {
            outln!("{},{:.8},{:.8}", r.lambda_nm, r.r, r.t);
        }
        return Ok(ExitCode::SUCCESS);
    }
    let refl = acc
        .reflectance(a.theta_i, a.phi_i)
        .map_err(|m| anyhow::anyhow!("{}: {m}", a.file.display()))?;
    outln!("lambda_nm,R,T,absorbed,dropped,R_stderr");
    for row in &refl.rows {
        let se = row
            .r_stderr
            .map_or_else(|| "NA".to_string(), |v| format!("{v:.6e}"));
        outln!(
            "{},{:.8},{:.8},{:.8},{:.3e},{}",
            row.lambda_nm,
            row.r,
            row.t,
            row.absorbed,
            row.dropped,
            se
        );
    }
    if refl.negative_buckets > 0 {
        eprintln!(
            "note: {} buckets hold a negative estimate (cross terms); they are kept, not clamped",
            refl.negative_buckets
        );
    }
    if acc.header.settings.coherence_mode() == Coherence::Global {
        eprintln!("note: --coherence global has no per-tree error estimate (R_stderr = NA)");
    }
    Ok(ExitCode::SUCCESS)
}
