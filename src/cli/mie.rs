//! `goniospec mie`: the Mie scattering of one sphere (efficiencies, asymmetry, amplitude
//! functions), as the particle media use it.

use super::{Args, ExitCode, Result, bail, finite};

#[derive(Args)]
pub(super) struct MieArgs {
    /// The sphere's refractive index, real part.
    #[arg(long, value_parser = finite)]
    n: f64,
    /// The sphere's extinction coefficient (k >= 0 absorbs).
    #[arg(long, value_parser = finite, default_value_t = 0.0)]
    k: f64,
    /// The host medium's (real) refractive index.
    #[arg(long, value_parser = finite, default_value_t = 1.0)]
    host: f64,
    /// Size parameter x = 2 pi r n_host / lambda; or give --radius-nm and --wavelength-nm.
    #[arg(long, value_parser = finite, conflicts_with_all = ["radius_nm", "wavelength_nm"])]
    x: Option<f64>,
    /// Sphere radius, nm.
    #[arg(long, value_parser = finite, requires = "wavelength_nm")]
    radius_nm: Option<f64>,
    /// Vacuum wavelength, nm.
    #[arg(long, value_parser = finite, requires = "radius_nm")]
    wavelength_nm: Option<f64>,
    /// Cosines of scattering angles at which to print S1 and S2 (comma-separated).
    #[arg(long, value_parser = finite, value_delimiter = ',', allow_hyphen_values = true)]
    mu: Vec<f64>,
    /// Print one JSON object (every number to full precision) instead of lines.
    #[arg(long)]
    json: bool,
}

pub(super) fn mie(a: MieArgs) -> Result<ExitCode> {
    use goniospec::optics::{C64, mie::Mie};
    use goniospec::sample::media::{K_MAX, N_MAX, N_MIN};
    // The indices a sample accepts (issue 74: --n 1e-100 printed NaN with exit 0).
    for (flag, v) in [("--n", a.n), ("--host", a.host)] {
        if !(N_MIN..=N_MAX).contains(&v) {
            bail!(
                "{flag} must be between {N_MIN:e} and {N_MAX} (a real material's index, as samples accept), got {v:e}"
            );
        }
    }
    if !(0.0..=K_MAX).contains(&a.k) {
        bail!(
            "--k must be between 0 and {K_MAX} (as samples accept), got {:e}",
            a.k
        );
    }
    let x = match (a.x, a.radius_nm, a.wavelength_nm) {
        (Some(x), _, _) => x,
        (None, Some(r), Some(l)) => {
            if r <= 0.0 || l <= 0.0 {
                bail!("--radius-nm and --wavelength-nm must be positive");
            }
            2.0 * std::f64::consts::PI * r * a.host / l
        }
        _ => bail!("give --x, or --radius-nm and --wavelength-nm"),
    };
    if let Some(bad) = a.mu.iter().find(|m| !(-1.0..=1.0).contains(*m)) {
        bail!("--mu {bad} is not the cosine of an angle (-1 to 1)");
    }
    let m = C64::new(a.n, a.k) / a.host;
    let mie = Mie::new(m, x)?;
    // An index-matched sphere (m = 1 exactly) does not scatter: its coefficients are
    // rounding alone (Q_sca 1e-31), and the asymmetry of no scattering is 0/0 (issue 74:
    // g printed 0.845 there).
    let matched = m == C64::new(1.0, 0.0);
    let (q_ext, q_sca) = if matched {
        (0.0, 0.0)
    } else {
        (mie.q_ext(), mie.q_sca())
    };
    let g = (!matched).then(|| mie.g());
    let s: Vec<(C64, C64)> =
        a.mu.iter()
            .map(|&mu| {
                if matched {
                    (C64::new(0.0, 0.0), C64::new(0.0, 0.0))
                } else {
                    mie.s1_s2(mu)
                }
            })
            .collect();
    if a.json {
        let v = serde_json::json!({
            "x": x, "m_re": m.re, "m_im": m.im, "orders": mie.a.len(),
            "q_ext": q_ext, "q_sca": q_sca, "q_abs": q_ext - q_sca, "g": g,
            "g_undefined_because": (matched).then_some("the sphere's index matches the host's: it does not scatter"),
            "mu": a.mu,
            "s1_re": s.iter().map(|p| p.0.re).collect::<Vec<_>>(),
            "s1_im": s.iter().map(|p| p.0.im).collect::<Vec<_>>(),
            "s2_re": s.iter().map(|p| p.1.re).collect::<Vec<_>>(),
            "s2_im": s.iter().map(|p| p.1.im).collect::<Vec<_>>(),
        });
        outln!("{v}");
        return Ok(ExitCode::SUCCESS);
    }
    outln!("size_parameter: {x}");
    outln!("relative_index: {} + {}i", m.re, m.im);
    outln!("orders: {}", mie.a.len());
    outln!("q_ext: {q_ext:.10e}");
    outln!("q_sca: {q_sca:.10e}");
    outln!("q_abs: {:.10e}", q_ext - q_sca);
    match g {
        Some(g) => {
            outln!("single_scattering_albedo: {:.10}", q_sca / q_ext);
            outln!("g: {g:.10}");
        }
        None => {
            outln!("single_scattering_albedo: undefined (nothing is extinguished)");
            outln!("g: undefined (the sphere's index matches the host's: it does not scatter)");
        }
    }
    if !s.is_empty() {
        outln!("mu,S1_re,S1_im,S2_re,S2_im");
        for (mu, (s1, s2)) in a.mu.iter().zip(&s) {
            outln!(
                "{mu},{:.10e},{:.10e},{:.10e},{:.10e}",
                s1.re,
                s1.im,
                s2.re,
                s2.im
            );
        }
    }
    Ok(ExitCode::SUCCESS)
}
