//! `goniospec analytic`: the transfer-matrix reference of a flat stack.

use super::*;

#[derive(Args)]
pub(super) struct AnalyticArgs {
    /// A sample written as a [stack].
    sample: PathBuf,
    /// Incident polar angle, degrees.
    #[arg(long, value_parser = finite)]
    theta_i: f64,
    #[command(flatten)]
    wavelengths: WavelengthArgs,
}

pub(super) fn analytic(a: AnalyticArgs) -> Result<ExitCode> {
    if !(0.0..90.0).contains(&a.theta_i) {
        bail!("--theta-i must be in [0, 90) degrees, got {}", a.theta_i);
    }
    use goniospec::optics::tmm;
    let s = sample::load(&a.sample, MeshOptions::default())?;
    if s.stack.is_none() {
        bail!(
            "{} is not written as a [stack]: the analytic reference needs a flat layered sample",
            a.sample.display()
        );
    }
    if !(0.0..90.0).contains(&a.theta_i) {
        bail!("--theta-i must be in [0, 90) degrees");
    }
    let stack_at = |l: f64| -> Result<tmm::StackIndices> {
        tmm::stack_indices(&s, l).map_err(|e| anyhow::anyhow!(e))
    };
    let th = a.theta_i.to_radians();
    outln!("lambda_nm,Rs,Rp,R,Ts,Tp,T");
    let print = |l: f64, rt: tmm::Rt| -> Result<()> {
        outln!(
            "{l},{:.8},{:.8},{:.8},{:.8},{:.8},{:.8}",
            rt.r_s,
            rt.r_p,
            rt.r(),
            rt.t_s,
            rt.t_p,
            rt.t()
        );
        Ok(())
    };
    match a.wavelengths.parse()? {
        Wavelengths::Monochromatic(v) => {
            for l in v {
                print(l, tmm::solve(&stack_at(l)?, l, th))?;
            }
        }
        Wavelengths::Bins(e) => {
            for w in e.windows(2) {
                stack_at(w[0])?;
                stack_at(w[1])?;
                let rt = tmm::solve_band(
                    |l| stack_at(l).expect("range checked at the edges"),
                    w[0],
                    w[1],
                    th,
                );
                print(0.5 * (w[0] + w[1]), rt)?;
            }
        }
    }
    Ok(ExitCode::SUCCESS)
}
