//! `goniospec eval`: evaluate a BRDF at direction pairs.

use super::{Args, Context, ExitCode, PathBuf, Result, bail, finite};

#[derive(Args)]
pub(super) struct EvalArgs {
    /// A built BRDF (.gsb), or an RGL .bsdf (a measured material of the RGL database, or
    /// one goniospec exported), evaluated as the database's loader and Mitsuba 3 evaluate
    /// it; with --mueller, the accumulator (.gsa) of a run simulated with --mueller. An
    /// RGB .bsdf prints linear sRGB triples, r,g,b (or pair,r,g,b), instead of spectra.
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
    /// Print the Mueller-matrix BRDF (1/sr, row-major m00..m33, in each direction's own
    /// s/p frame: p in the plane of the direction and the sample's normal, s across it,
    /// p x s along the direction of travel), each element's standard error, and the
    /// degree of polarisation for unpolarised light in, per wavelength: the matrix of the
    /// bucket the outgoing direction falls in, at a simulated incident angle, read from a
    /// .gsa simulated with --mueller (docs/physics.md, "Polarisation"). An outgoing polar
    /// angle above 90 deg reads the transmission side. Stokes parameters with x = p, y = s:
    /// S1 = I_p - I_s, S2 = I_+45 - I_-45, S3 = 2 Im(conj E_p E_s) (circular+ is S3 = +1);
    /// a perfect mirror at normal incidence is diag(1, 1, -1, -1). NIST SCATMECH's
    /// basis is this one under D = diag(1, -1, -1, 1): flip the signs of S1 and S2, and
    /// take D M D of a matrix (the elements with exactly one index in {1, 2} flip) to
    /// compare.
    #[arg(long, conflicts_with = "pairs")]
    mueller: bool,
    /// With --mueller: the light in is polarised (unpolarised, s, p, +45, -45, circular+,
    /// circular-, or S0,S1,S2,S3 in the incident direction's s/p frame, S1 = I_p - I_s as
    /// above); prints instead the Stokes vector of the light sent out,
    /// lambda_nm,S0,S1,S2,S3,dop (1/sr, in the outgoing direction's frame; S0 the BRDF for
    /// that state).
    #[arg(long, requires = "mueller", value_parser = goniospec::optics::mueller::stokes_state, allow_hyphen_values = true)]
    incident: Option<[f64; 4]>,
}

pub(super) fn eval(a: EvalArgs) -> Result<ExitCode> {
    if a.mueller {
        return eval_mueller(&a);
    }
    let material = super::Material::open(&a.file)?;
    let r = material.brdf();
    let rgb = material.is_rgb();
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
            if rgb {
                outln!("r,g,b");
                outln!("{:.8e},{:.8e},{:.8e}", out[0], out[1], out[2]);
            } else {
                outln!("lambda_nm,brdf");
                for (l, v) in lambdas.iter().zip(&out) {
                    outln!("{l},{v:.8e}");
                }
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
            let mut out = std::io::BufWriter::new(std::io::stdout().lock());
            use std::io::Write as _;
            if rgb {
                writeln!(out, "pair,r,g,b")?;
                for (i, c) in all.chunks(3).enumerate() {
                    writeln!(out, "{i},{:.8e},{:.8e},{:.8e}", c[0], c[1], c[2])?;
                }
            } else {
                writeln!(out, "pair,lambda_nm,brdf")?;
                for (i, chunk) in all.chunks(lambdas.len()).enumerate() {
                    for (l, v) in lambdas.iter().zip(chunk) {
                        writeln!(out, "{i},{l},{v:.8e}")?;
                    }
                }
            }
            out.flush().context("writing to standard output")?;
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// `eval --mueller`: a `.gsa`'s Mueller-matrix BRDF at one pair of directions.
fn eval_mueller(a: &EvalArgs) -> Result<ExitCode> {
    let acc = super::read_accumulator(&a.file)?;
    let (ti, to) = (
        a.theta_i.expect("clap requires it"),
        a.theta_o.expect("clap requires it"),
    );
    if !(0.0..180.0).contains(&to) || to == 90.0 {
        bail!(
            "--theta-o must be in [0, 90) (reflection) or (90, 180) (transmission) degrees, got {to}"
        );
    }
    let wo = goniospec::geom::from_spherical(to.to_radians(), a.phi_o.to_radians());
    let rows = acc.mueller_brdf(ti, Some(a.phi_i), wo)?;
    if let Some(state) = &a.incident {
        outln!("lambda_nm,S0,S1,S2,S3,dop");
        for r in rows {
            let v = goniospec::optics::mueller::apply(&r.m, state);
            let dop = if v[0] > 0.0 {
                (v[1] * v[1] + v[2] * v[2] + v[3] * v[3]).sqrt() / v[0]
            } else {
                0.0
            };
            outln!(
                "{},{:.8e},{:.8e},{:.8e},{:.8e},{dop:.6}",
                r.lambda_nm,
                v[0],
                v[1],
                v[2],
                v[3]
            );
        }
        return Ok(ExitCode::SUCCESS);
    }
    let names: Vec<String> = (0..16).map(|e| format!("m{}{}", e / 4, e % 4)).collect();
    let se: Vec<String> = names.iter().map(|n| format!("se_{n}")).collect();
    outln!("lambda_nm,{},{},dop", names.join(","), se.join(","));
    for r in rows {
        let m: Vec<String> = r.m.iter().map(|v| format!("{v:.8e}")).collect();
        let e: Vec<String> = match r.stderr {
            Some(e) => e.iter().map(|v| format!("{v:.3e}")).collect(),
            None => vec!["nan".into(); 16],
        };
        outln!(
            "{},{},{},{:.6}",
            r.lambda_nm,
            m.join(","),
            e.join(","),
            r.dop
        );
    }
    Ok(ExitCode::SUCCESS)
}
