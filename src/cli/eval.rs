//! `goniospec eval`: evaluate a BRDF at direction pairs.

use super::{Args, Context, ExitCode, PathBuf, Result, bail, finite};

#[derive(Args)]
pub(super) struct EvalArgs {
    /// A built BRDF (.gsb).
    file: PathBuf,
    /// Incident polar angle, degrees.
    #[arg(long, value_parser = finite, required_unless_present = "pairs")]
    theta_i: Option<f64>,
    /// Incident azimuth, degrees.
    #[arg(long, value_parser = finite, default_value_t = 0.0)]
    phi_i: f64,
    /// Outgoing polar angle, degrees.
    #[arg(long, value_parser = finite, required_unless_present = "pairs")]
    theta_o: Option<f64>,
    /// Outgoing azimuth, degrees.
    #[arg(long, value_parser = finite, default_value_t = 180.0)]
    phi_o: f64,
    /// CSV of pairs with the header theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg (degrees;
    /// the header without `_deg` is still read).
    #[arg(long)]
    pairs: Option<PathBuf>,
}

pub(super) fn eval(a: EvalArgs) -> Result<ExitCode> {
    use goniospec::brdf::{self, Brdf};
    let r = brdf::file::read(&a.file)?;
    let lambdas = r.meta().lambda_nm.clone();
    let d = |t: f64, p: f64| -> Result<glam::DVec3> {
        if !(0.0..=90.0).contains(&t) {
            bail!("polar angles must be in [0, 90] degrees, got {t}");
        }
        Ok(goniospec::geom::from_spherical(
            t.to_radians(),
            p.to_radians(),
        ))
    };
    let mut out = vec![0.0; lambdas.len()];
    match &a.pairs {
        None => {
            let wi = d(a.theta_i.expect("clap requires it"), a.phi_i)?;
            let wo = d(a.theta_o.expect("clap requires it"), a.phi_o)?;
            r.eval(wi, wo, &mut out);
            outln!("lambda_nm,brdf");
            for (l, v) in lambdas.iter().zip(&out) {
                outln!("{l},{v:.8e}");
            }
        }
        Some(p) => {
            let text =
                goniospec::io::read_text(p).with_context(|| format!("reading {}", p.display()))?;
            let mut lines = text
                .lines()
                .enumerate()
                .filter(|(_, l)| !l.trim().is_empty());
            // The angles' names everywhere else (NPZ, Python, .gsa); the header without
            // `_deg` was this file's before issue 45 and is still read.
            match lines.next() {
                Some((_, h))
                    if matches!(
                        h.replace(' ', "").as_str(),
                        "theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg"
                            | "theta_i,phi_i,theta_o,phi_o"
                    ) => {}
                _ => bail!(
                    "{}: the first line must be the header theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg",
                    p.display()
                ),
            }
            let mut pairs = Vec::new();
            for (i, l) in lines {
                let v: Vec<f64> = l
                    .split(',')
                    .map(|x| x.trim().parse::<f64>())
                    .collect::<Result<_, _>>()
                    .map_err(|_| {
                        anyhow::anyhow!("{}:{}: not four numbers: '{l}'", p.display(), i + 1)
                    })?;
                if v.len() != 4 {
                    bail!(
                        "{}:{}: expected 4 columns, found {}",
                        p.display(),
                        i + 1,
                        v.len()
                    );
                }
                pairs.push((
                    d(v[0], v[1]).with_context(|| format!("{}:{}", p.display(), i + 1))?,
                    d(v[2], v[3]).with_context(|| format!("{}:{}", p.display(), i + 1))?,
                ));
            }
            let mut all = vec![0.0; pairs.len() * lambdas.len()];
            r.eval_batch(&pairs, &mut all);
            outln!("pair,lambda_nm,brdf");
            for (i, chunk) in all.chunks(lambdas.len()).enumerate() {
                for (l, v) in lambdas.iter().zip(chunk) {
                    outln!("{i},{l},{v:.8e}");
                }
            }
        }
    }
    Ok(ExitCode::SUCCESS)
}
