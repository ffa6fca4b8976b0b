//! `goniospec analytic`: the transfer-matrix reference of a flat stack.

use super::{Args, ExitCode, MeshOptions, PathBuf, Result, WavelengthArgs, finite, sample};

#[derive(Args)]
pub(super) struct AnalyticArgs {
    /// A sample written as a [stack].
    sample: PathBuf,
    /// Incident polar angles, degrees, comma-separated (as simulate takes them). The CSV
    /// gives Rs, Rp, R, Ts, Tp, T (fractions of the incident power) and delta_deg, the
    /// phase difference arg(r_p conj r_s) of the reflected p and s amplitudes in the s/p
    /// frames of docs/physics.md ("Polarisation"), of the bin-averaged r_p conj r_s for
    /// bins. With several angles each row starts with its theta_i_deg.
    #[arg(long, value_name = "DEG,...", value_parser = finite, value_delimiter = ',', required = true)]
    theta_i: Vec<f64>,
    #[command(flatten)]
    wavelengths: WavelengthArgs,
}

pub(super) fn analytic(a: AnalyticArgs) -> Result<ExitCode> {
    let s = sample::load(&a.sample, MeshOptions::default())?;
    let wavelengths = a.wavelengths.parse()?;
    // Every angle solved before anything is printed: a bad one prints no partial table.
    let tables = (a.theta_i.iter())
        .map(|&t| {
            goniospec::reference::analytic(&s, t, &wavelengths)
                .map(|rows| (t, rows))
                .map_err(|m| anyhow::anyhow!("{}: {m}", a.sample.display()))
        })
        .collect::<Result<Vec<_>>>()?;
    let several = tables.len() > 1;
    outln!(
        "{}lambda_nm,Rs,Rp,R,Ts,Tp,T,delta_deg",
        if several { "theta_i_deg," } else { "" }
    );
    for (theta, rows) in tables {
        let lead = if several {
            format!("{theta},")
        } else {
            String::new()
        };
        for (l, rt) in rows {
            outln!(
                "{lead}{l},{:.8},{:.8},{:.8},{:.8},{:.8},{:.8},{:.6}",
                rt.r_s,
                rt.r_p,
                rt.r(),
                rt.t_s,
                rt.t_p,
                rt.t(),
                rt.delta_deg()
            );
        }
    }
    Ok(ExitCode::SUCCESS)
}
