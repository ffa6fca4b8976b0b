//! `goniospec analytic`: the transfer-matrix reference of a flat stack.

use super::{Args, ExitCode, MeshOptions, PathBuf, Result, WavelengthArgs, finite, sample};

#[derive(Args)]
pub(super) struct AnalyticArgs {
    /// A sample written as a [stack].
    sample: PathBuf,
    /// Incident polar angle, degrees. The CSV gives Rs, Rp, R, Ts, Tp, T (fractions of
    /// the incident power) and delta_deg, the phase difference arg(r_p conj r_s) of the
    /// reflected p and s amplitudes in the s/p frames of docs/physics.md ("Polarisation"),
    /// of the bin-averaged r_p conj r_s for bins.
    #[arg(long, value_parser = finite)]
    theta_i: f64,
    #[command(flatten)]
    wavelengths: WavelengthArgs,
}

pub(super) fn analytic(a: AnalyticArgs) -> Result<ExitCode> {
    let s = sample::load(&a.sample, MeshOptions::default())?;
    let rows = goniospec::reference::analytic(&s, a.theta_i, &a.wavelengths.parse()?)
        .map_err(|m| anyhow::anyhow!("{}: {m}", a.sample.display()))?;
    outln!("lambda_nm,Rs,Rp,R,Ts,Tp,T,delta_deg");
    for (l, rt) in rows {
        outln!(
            "{l},{:.8},{:.8},{:.8},{:.8},{:.8},{:.8},{:.6}",
            rt.r_s,
            rt.r_p,
            rt.r(),
            rt.t_s,
            rt.t_p,
            rt.t(),
            rt.delta_deg()
        );
    }
    Ok(ExitCode::SUCCESS)
}
