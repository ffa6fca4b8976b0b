//! `goniospec reflectance`: the directional reflectance of an accumulator as CSV.

use super::*;

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
}

pub(super) fn reflectance(a: ReflectanceArgs) -> Result<ExitCode> {
    let acc = Accumulator::read(&a.file)?;
    let s = &acc.header.settings;
    if let Some(p) = a.phi_i
        && (p - s.phi_i_deg).abs() > 1e-9
    {
        bail!(
            "{} was simulated at phi_i = {} deg, not {p}",
            a.file.display(),
            s.phi_i_deg
        );
    }
    let i = s
        .theta_i_deg
        .iter()
        .position(|t| (t - a.theta_i).abs() < 1e-9)
        .with_context(|| {
            format!(
                "{} has no incident angle {} deg (it has {:?})",
                a.file.display(),
                a.theta_i,
                s.theta_i_deg
            )
        })?;
    let mode = s.coherence_mode();
    let buckets = s.buckets();
    outln!("lambda_nm,R,T,absorbed,dropped,R_stderr");
    let mut negative = 0usize;
    for j in 0..s.wavelength_count() {
        let c = acc.cell(i, j);
        let (r, t) = c.totals(mode, &buckets);
        let n = c.trees.max(1) as f64;
        negative += (0..2 * buckets.len())
            .filter(|&k| c.fraction(k, mode) < 0.0)
            .count();
        let se = c
            .r_stderr(mode)
            .map_or_else(|| "NA".to_string(), |v| format!("{v:.6e}"));
        outln!(
            "{},{:.8},{:.8},{:.8},{:.3e},{}",
            s.wavelength(j),
            r,
            t,
            c.absorbed / n,
            c.dropped / n,
            se
        );
    }
    if negative > 0 {
        eprintln!(
            "note: {negative} buckets hold a negative estimate (cross terms); they are kept, not clamped"
        );
    }
    if mode == Coherence::Global {
        eprintln!("note: --coherence global has no per-tree error estimate (R_stderr = NA)");
    }
    Ok(ExitCode::SUCCESS)
}
