//! `goniospec compare`: two materials side by side (a simulation beside a measurement).

use super::{Args, Context, ExitCode, PathBuf, Result, bail, finite};

#[derive(Args)]
pub(super) struct CompareArgs {
    /// The first material: a simulated BRDF (.gsb, or a .gsa, built into a table), or an
    /// RGL .bsdf (measured, or exported by goniospec).
    a: PathBuf,
    /// The second material, of any of the same kinds.
    b: PathBuf,
    /// A folder for every figure (angles.csv, nodes.csv, travel.csv, compare.json) and
    /// the picture (compare.png, compare.svg); created if missing, and only the files
    /// goniospec wrote there are replaced.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Replace files of those names in --output that goniospec did not write.
    #[arg(long)]
    force: bool,
    /// Exit with status 1 when the mean CIEDE2000 over every compared angle exceeds this
    /// (for scripts); the report is printed either way.
    #[arg(long, value_parser = finite)]
    max_delta_e: Option<f64>,
}

pub(super) fn compare(a: CompareArgs) -> Result<ExitCode> {
    use goniospec::compare::{self, Material};
    if let Some(x) = a.max_delta_e
        && x < 0.0
    {
        bail!("--max-delta-e must be at least 0, got {x}");
    }
    if let Some(dir) = &a.output {
        for input in [&a.a, &a.b] {
            if goniospec::output::same_file(dir, input) {
                bail!("--output {} is an input of the comparison", dir.display());
            }
            for name in compare::output_names() {
                if goniospec::output::same_file(&dir.join(&name), input) {
                    bail!(
                        "--output {}: its {name} would replace {}, an input of the comparison",
                        dir.display(),
                        input.display()
                    );
                }
            }
        }
        goniospec::output::guard_folder(dir, &compare::output_names(), a.force)?;
    }
    let t0 = std::time::Instant::now();
    let ma = Material::read(&a.a)?;
    let mb = Material::read(&a.b)?;
    let label = |p: &PathBuf| {
        p.file_name().map_or_else(
            || p.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        )
    };
    let report = compare::compare(&ma, &mb, [&label(&a.a), &label(&a.b)])?;
    print_report(&report)?;
    if let Some(dir) = &a.output {
        let written = compare::write_outputs(&report, &ma, &mb, dir)
            .with_context(|| format!("writing into {}", dir.display()))?;
        let names: Vec<String> = written
            .iter()
            .filter_map(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
            .collect();
        goniospec::output::record_folder(dir, &names)
            .with_context(|| format!("writing into {}", dir.display()))?;
        outln!("wrote {} files into {}", names.len(), dir.display());
    }
    outln!("compared in {:.2} s", t0.elapsed().as_secs_f64());
    if let Some(x) = a.max_delta_e
        && report.overall.mean > x
    {
        eprintln!(
            "compare: the mean CIEDE2000 {:.3} exceeds --max-delta-e {x}",
            report.overall.mean
        );
        return Ok(ExitCode::from(1));
    }
    Ok(ExitCode::SUCCESS)
}

/// The report on standard output: the materials, the colour space and grid, a row per
/// incident angle, what was left out, then the figures under 45 degree light.
fn print_report(r: &goniospec::compare::Report) -> Result<()> {
    outln!("A: {} [{}]", r.a, r.a_kind);
    outln!("B: {} [{}]", r.b, r.b_kind);
    outln!("colour: {}", r.colour_space);
    outln!(
        "grid: {}'s incident angles and outgoing directions; CIEDE2000 of the radiance factor pi f, weighted by projected solid angle",
        r.grid_from
    );
    // The azimuth's column where the grid has several (an anisotropic material).
    let several = r
        .angles
        .iter()
        .any(|a| a.phi_i_deg != r.angles[0].phi_i_deg);
    outln!(
        "theta_i_deg{}  nodes  dE_mean  dE_median  dE_p95  dL_mean  dL_p95  peak_A_1/sr  peak_B_1/sr  fwhm_A_deg  fwhm_B_deg",
        if several { "  phi_i_deg" } else { "" }
    );
    let w = |v: Option<f64>| v.map_or_else(|| "wide".to_string(), |x| format!("{x:.1}"));
    for a in &r.angles {
        let phi = if several {
            format!("  {:>9.2}", a.phi_i_deg)
        } else {
            String::new()
        };
        outln!(
            "{:>11.2}{phi}  {:>5}  {:>7.2}  {:>9.2}  {:>6.2}  {:>7.2}  {:>6.2}  {:>11.4}  {:>11.4}  {:>10}  {:>10}",
            a.theta_i_deg,
            a.nodes,
            a.delta_e.mean,
            a.delta_e.median,
            a.delta_e.p95,
            a.delta_e_lightness.mean,
            a.delta_e_lightness.p95,
            a.lobe_a.peak_per_sr,
            a.lobe_b.peak_per_sr,
            w(a.lobe_a.fwhm_deg),
            w(a.lobe_b.fwhm_deg)
        );
    }
    for (t, why) in &r.skipped {
        outln!("{t:>11.2}  left out: {why}");
    }
    outln!(
        "all angles: dE mean {:.2}, median {:.2}, p95 {:.2}",
        r.overall.mean,
        r.overall.median,
        r.overall.p95
    );
    if let Some(f) = &r.flop {
        let fi = |s: &goniospec::compare::shape::FlopSide| match s.flop_index {
            Some(x) => format!("{x:.2}"),
            None if s.l15 <= s.l110 => "none: L*15 <= L*110".into(),
            None => "none: L*45 = 0".into(),
        };
        outln!(
            "45 deg light, L* at 15/45/110 deg aspecular: A {:.1}/{:.1}/{:.1} (flop index {}), B {:.1}/{:.1}/{:.1} (flop index {})",
            f.a.l15,
            f.a.l45,
            f.a.l110,
            fi(&f.a),
            f.b.l15,
            f.b.l45,
            f.b.l110,
            fi(&f.b)
        );
        let travel: Vec<String> = r
            .travel
            .iter()
            .map(|t| {
                format!(
                    "{:.0}: A L{:.0} C{:.0} h{:.0}, B L{:.0} C{:.0} h{:.0} (dE {:.1})",
                    t.aspecular_deg,
                    t.a_lch[0],
                    t.a_lch[1],
                    t.a_lch[2],
                    t.b_lch[0],
                    t.b_lch[1],
                    t.b_lch[2],
                    t.delta_e
                )
            })
            .collect();
        outln!("colour travel (aspecular deg): {}", travel.join("; "));
    } else {
        outln!("45 deg light: not compared (outside a material's incidence)");
    }
    Ok(())
}
