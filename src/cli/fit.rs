//! `goniospec fit`: fit a real-time material and write glTF / OpenPBR / Standard Surface.

use super::{Args, Context, ExitCode, OutputKind, PathBuf, Result, bail, guard_output};

#[derive(Args)]
pub(super) struct FitArgs {
    /// A .gsa accumulator with several incident angles (more angles separate a film's
    /// thickness from its index).
    file: PathBuf,
    /// Output prefix: writes PREFIX.json (the fit, OpenPBR and Standard Surface parameter
    /// sets) and PREFIX.gltf (a sphere with the material).
    #[arg(short, long)]
    output: PathBuf,
    /// Base under the film: a dielectric (one real index), a conductor (a complex index per
    /// wavelength), or whichever fits better.
    #[arg(long, value_enum, default_value_t = FitBase::Auto)]
    base: FitBase,
    /// Do not try a thin film.
    #[arg(long)]
    no_film: bool,
    /// A clear coat over base and film: auto (where the simulation shows a mirror lobe
    /// beyond the lobe around it, a coat of fitted index, kept where it matches better),
    /// none, or the coat's index (a sample with a known clear coat, e.g. 1.52).
    #[arg(long, default_value = "auto", value_parser = parse_coat)]
    coat: goniospec::fit::CoatChoice,
    /// Replace PREFIX.json or PREFIX.gltf even when they are not files goniospec fit wrote.
    #[arg(long)]
    force: bool,
}

/// `--coat`: auto, none, or an index in (1, 3].
fn parse_coat(s: &str) -> Result<goniospec::fit::CoatChoice, String> {
    use goniospec::fit::CoatChoice;
    match s {
        "auto" => Ok(CoatChoice::Auto),
        "none" => Ok(CoatChoice::None),
        v => match v.parse::<f64>() {
            Ok(n) if n > 1.0 && n <= 3.0 => Ok(CoatChoice::Ior(n)),
            _ => Err(format!(
                "--coat takes auto, none or the coat's index in (1, 3], got '{v}'"
            )),
        },
    }
}

#[derive(Clone, Copy, clap::ValueEnum)]
pub(super) enum FitBase {
    Auto,
    Dielectric,
    Conductor,
}

pub(super) fn fit(a: FitArgs) -> Result<ExitCode> {
    use goniospec::fit;
    // The prefix names files: it must end in a name (`-o .` wrote `..json`).
    let name = a.output.file_name().and_then(|n| n.to_str()).unwrap_or("");
    if name.is_empty() || name == "." || name == ".." || a.output.is_dir() {
        bail!(
            "-o {} is not a file prefix: give one such as out/gold (writes out/gold.json and out/gold.gltf)",
            a.output.display()
        );
    }
    let acc = super::read_accumulator(&a.file)?;
    let with_ext = |ext: &str| {
        let mut p = a.output.clone().into_os_string();
        p.push(ext);
        PathBuf::from(p)
    };
    let (json_path, gltf_path) = (with_ext(".json"), with_ext(".gltf"));
    for p in [&json_path, &gltf_path] {
        guard_output(p, &[a.file.as_path()], OutputKind::FitJson, a.force)?;
    }
    let data = fit::Data::from_accumulator(&acc);
    let kind = match a.base {
        FitBase::Auto => fit::BaseKind::Auto,
        FitBase::Dielectric => fit::BaseKind::Dielectric,
        FitBase::Conductor => fit::BaseKind::Conductor,
    };
    let bar = super::progress_spinner("fitting (roughness, base, film, coat)");
    let started = std::time::Instant::now();
    let f = fit::fit(&data, kind, !a.no_film, a.coat);
    let seconds = started.elapsed().as_secs_f64();
    bar.finish_and_clear();
    fit::write_json(&json_path, &fit::to_json(&f, &data))
        .with_context(|| format!("writing {}", json_path.display()))?;
    let name = acc.header.settings.sample_name.clone();
    fit::write_json(&gltf_path, &fit::to_gltf(&f, &data, &name))
        .with_context(|| format!("writing {}", gltf_path.display()))?;
    outln!("ggx_alpha: {:.4}", f.alpha);
    match &f.base {
        fit::Base::Dielectric { n } => outln!("base: dielectric, ior {n:.4}"),
        fit::Base::Conductor { n } => outln!(
            "base: conductor, n + ik from {:.3} + {:.3}i to {:.3} + {:.3}i",
            n[0].re,
            n[0].im,
            n[n.len() - 1].re,
            n[n.len() - 1].im
        ),
    }
    match f.film {
        Some(m) => outln!(
            "film: thickness {:.1} nm, ior {:.4}, weight {:.3}",
            m.thickness_nm,
            m.n,
            m.weight
        ),
        None => outln!("film: none"),
    }
    match f.coat {
        Some(c) => outln!(
            "coat: clear, ior {:.4}, ggx_alpha {:.3} (OpenPBR coat_weight 1; glTF KHR_materials_clearcoat, whose index is 1.5)",
            c.ior,
            c.alpha
        ),
        None => outln!("coat: none"),
    }
    outln!("rms_reflectance_error: {:.2e}", f.rms_residual);
    outln!("fit_seconds: {seconds:.1}");
    for (t, de) in data.theta_i_rad.iter().zip(&f.delta_e2000) {
        outln!("delta_e2000_theta_{:.0}: {de:.2}", t.to_degrees());
    }
    for w in &f.warnings {
        eprintln!("warning: {w}");
    }
    outln!("wrote {} and {}", json_path.display(), gltf_path.display());
    Ok(ExitCode::SUCCESS)
}
