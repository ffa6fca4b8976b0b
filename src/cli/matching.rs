//! `goniospec match`: the recipe whose simulation is closest to a measured material.

use std::path::Path;

use super::{Args, Context, ExitCode, PathBuf, Result, bail, finite};
use goniospec::compare::{self, Material};
use goniospec::recipe::{self, Metric, Search, Stop, Template, Vary};

#[derive(Args)]
pub(super) struct MatchArgs {
    /// The template: a sample file (.toml) holding the recipe to start from. The numbers
    /// --vary names are changed in it; everything else is kept.
    template: PathBuf,
    /// The measured material: an RGL .bsdf (the database's, or one goniospec exported).
    #[arg(long)]
    measured: PathBuf,
    /// A parameter to fit and its range: its TOML path in the template (keys joined by
    /// dots, array elements by their index from 0), `=LO:HI`, and `:log` to search its
    /// logarithm (for a value spanning decades). Repeat for each parameter, e.g.
    /// --vary stack.layers.0.thickness=100:800
    /// --vary media.paint.particles.volume_fraction=0.02:0.3:log
    #[arg(long = "vary", value_name = "PATH=LO:HI[:log]", required = true)]
    vary: Vec<String>,
    /// The measured incident angles fitted, degrees (each the measurement's nearest, within
    /// 5 deg); the others below 90 deg are held out and reported apart.
    #[arg(long, value_name = "DEG,...", value_parser = finite, value_delimiter = ',', default_values_t = [0.0, 30.0, 45.0])]
    fit_angles: Vec<f64>,
    /// A folder for the fitted sample (fitted.toml), its simulation at every measured angle
    /// (fitted.gsa), the search's trace (trace.csv, trace.png, trace.svg), a summary
    /// (match.json), the comparison with the measurement (compare/) and each candidate's
    /// record (candidates/, which a rerun after an interruption resumes from).
    #[arg(short, long)]
    output: PathBuf,
    /// Trees per incident angle of every candidate. Every candidate is simulated with the
    /// same seed, trees and settings (common random numbers), so the search compares
    /// recipes, not noise.
    #[arg(long, default_value_t = 2048)]
    rays: u64,
    /// Size each candidate's budget by the BRDF's quality instead of a fixed count: its
    /// trees grow from --rays' first batch until the median relative standard error of
    /// the buckets holding 95 % of the reflected power is at most this (simulate's
    /// --target-stderr). Candidates then differ in trees, and share only their first
    /// trees' random numbers.
    #[arg(long, value_parser = finite)]
    target_stderr: Option<f64>,
    /// Polar bins of each candidate's outgoing hemisphere. Coarser than simulate's default
    /// (45): a candidate's error is read bucket by bucket, and a bucket's noise, not the
    /// recipe, dominates CIEDE2000 where buckets hold few trees (two seeds of a rough metal
    /// at 16,384 trees differ by a mean 8 at 45 x 36 buckets).
    #[arg(long, default_value_t = 18)]
    theta_o_bins: u32,
    /// Azimuth bins of each candidate's outgoing hemisphere.
    #[arg(long, default_value_t = 24)]
    phi_o_bins: u32,
    /// Trees per incident angle of the fitted recipe's simulation at every measured angle,
    /// which the report and fitted.gsa give (default: 4 times --rays, so that its error
    /// is less the buckets' noise than the search's).
    #[arg(long)]
    final_rays: Option<u64>,
    /// Points of a Halton sequence over the ranges tried before Nelder-Mead, which starts
    /// from the best of them and the template's values: for errors with several minima
    /// (a film's interference orders). Each counts against --max-evaluations.
    #[arg(long, default_value_t = 0)]
    starts: usize,
    /// Evaluate only shard I of N of the starting points (--starts) into the records and
    /// stop, so that separate processes share them: GNU parallel
    /// (`parallel goniospec match ... --starts 32 --shard {}/4 ::: 1 2 3 4`) or a Slurm
    /// array (`--shard $SLURM_ARRAY_TASK_ID/4`); then the same command without --shard
    /// searches from them, reading what the shards recorded (the bytes are a single
    /// process's).
    #[arg(long, value_name = "I/N", value_parser = shard)]
    shard: Option<(usize, usize)>,
    /// Seed of every candidate's simulation.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Wavelengths, nm, as for simulate (A:B:STEP bins).
    #[arg(long, default_value = goniospec::spectrum::DEFAULT_WAVELENGTHS)]
    wavelengths: String,
    /// The most candidates simulated (Nelder-Mead's first simplex takes one more than the
    /// parameters; each step one to the parameters plus two).
    #[arg(long, default_value_t = 60)]
    max_evaluations: usize,
    /// Stop when the simplex's candidates agree within this (the standard deviation of
    /// their errors, CIEDE2000 units).
    #[arg(long, value_parser = finite, default_value_t = 0.02)]
    tolerance: f64,
    /// What is minimised: colour (mean CIEDE2000 of the reflected colour, compare's
    /// figure) or lightness (the same of L* alone).
    #[arg(long, default_value = "colour")]
    metric: String,
    /// Replace files of those names in --output that goniospec did not write.
    #[arg(long)]
    force: bool,
}

pub(super) fn run_match(a: MatchArgs) -> Result<ExitCode> {
    let t0 = std::time::Instant::now();
    let metric = Metric::parse(&a.metric)?;
    if a.tolerance < 0.0 {
        bail!("--tolerance must be at least 0, got {}", a.tolerance);
    }
    let vary = a
        .vary
        .iter()
        .map(|s| Vary::parse(s))
        .collect::<Result<Vec<_>, _>>()?;
    recipe::check_budget(vary.len(), a.starts, a.max_evaluations)?;
    if vary.len() > recipe::MAX_PARAMETERS {
        bail!(
            "{} parameters: a match varies at most {}",
            vary.len(),
            recipe::MAX_PARAMETERS
        );
    }
    let final_rays = a.final_rays.unwrap_or(4 * a.rays);
    guard(&a)?;
    let template = Template::read(&a.template, &vary)?;
    let measured = Material::read(&a.measured)?;
    let (fit, held) = fitted_angles(&a, &measured)?;
    let start = start_of(&vary, &template.values);
    template.check_ranges(&vary, &start)?;
    let settings = |theta: Vec<f64>, rays: u64| goniospec::simulate::SimSettings {
        theta_i_deg: theta,
        rays,
        seed: a.seed,
        wavelengths: a.wavelengths.clone(),
        theta_o_bins: a.theta_o_bins,
        phi_o_bins: a.phi_o_bins,
        target_stderr: a.target_stderr,
        ..Default::default()
    };
    let config = settings(fit.clone(), a.rays).resolve()?;
    // The report's simulation is checked now, not after the search.
    settings(fit.clone(), final_rays)
        .resolve()
        .context("--final-rays")?;
    let measured_key = goniospec::io::fnv1a(&std::fs::read(&a.measured)?);
    std::fs::create_dir_all(&a.output)
        .with_context(|| format!("creating {}", a.output.display()))?;
    // Listed before the search, so that a rerun after an interruption resumes unasked.
    goniospec::output::record_folder(&a.output, &["candidates".into(), "compare".into()])
        .with_context(|| format!("writing into {}", a.output.display()))?;
    let search = Search {
        template: &template,
        vary: &vary,
        measured: &measured,
        measured_key,
        fit_deg: fit.clone(),
        config,
        metric,
        max_evaluations: a.max_evaluations,
        starts: a.starts,
        tolerance: a.tolerance,
        records: Some(recipe::records_in(&a.output)),
    };
    let shown = |v: &[f64]| -> String { search.shown(v) };
    if let Some((i, n)) = a.shard {
        let done = search.run_shard(&start, (i, n), &mut |k, e, best| {
            eprintln!(
                "shard {i}/{n}, point {k}: {} -> {:.3} (best {best:.3})",
                shown(&e.values),
                e.objective
            );
        })?;
        outln!(
            "shard {i}/{n}: {} starting points recorded in {}; the same command without --shard searches from them",
            done.len(),
            recipe::records_in(&a.output).display()
        );
        return Ok(ExitCode::SUCCESS);
    }
    outln!(
        "# match {} to {} ({}): {} over the fitted angles {} deg ({} held out: {} deg); {} trees a candidate, seed {}, at most {} candidates",
        a.template.display(),
        a.measured.display(),
        measured.name(),
        metric.describe(),
        list(&fit),
        held.len(),
        list(&held),
        a.rays,
        a.seed,
        a.max_evaluations
    );
    outln!("# start: {}", shown(&start));
    let mut simulated_s = 0.0;
    let mut simulated = 0usize;
    let max = a.max_evaluations;
    let outcome = search.run(&start, &mut |k, e, best| {
        if !e.cached {
            simulated_s += e.seconds;
            simulated += 1;
        }
        let left = if simulated > 0 {
            format!(
                "; at most {:.0} s left",
                simulated_s / simulated as f64 * (max - k) as f64
            )
        } else {
            String::new()
        };
        eprintln!(
            "candidate {k} of at most {max}: {} -> {:.3} (best {best:.3}){}{left}",
            shown(&e.values),
            e.objective,
            if e.cached {
                " [repeated, or from an earlier run's record]".to_string()
            } else {
                format!(" in {:.1} s", e.seconds)
            },
        );
    })?;
    let best = &outcome.trace[outcome.best];
    outln!(
        "# search: {} candidates ({} simulated, {} repeated or read from records), {}; best {} at candidate {}: {}",
        outcome.trace.len(),
        simulated,
        outcome.trace.len() - simulated,
        match outcome.stop {
            Stop::Converged => format!("converged (the simplex agrees within {})", a.tolerance),
            Stop::Budget => "stopped at --max-evaluations".to_string(),
        },
        format_args!("{:.3}", best.objective),
        outcome.best + 1,
        shown(&best.values)
    );
    finish(
        &a,
        &template,
        &vary,
        &measured,
        &fit,
        &held,
        &outcome,
        settings(Vec::new(), final_rays),
    )?;
    outln!("matched in {:.1} s", t0.elapsed().as_secs_f64());
    Ok(ExitCode::SUCCESS)
}

/// Refuses an output folder that is an input, or holds files of the names match writes
/// that goniospec did not write (unless --force).
fn guard(a: &MatchArgs) -> Result<()> {
    for input in [&a.template, &a.measured] {
        if goniospec::output::same_file(&a.output, input) {
            bail!("--output {} is an input of the match", a.output.display());
        }
    }
    let mut names = recipe::output_names();
    names.push("compare".into());
    names.push("candidates".into());
    goniospec::output::guard_folder(&a.output, &names, a.force)?;
    Ok(())
}

/// The measurement's fitted and held-out angles, degrees; refused where it is not a
/// measured isotropic tensor file.
fn fitted_angles(a: &MatchArgs, measured: &Material) -> Result<(Vec<f64>, Vec<f64>)> {
    let Material::Tabulated(m) = measured else {
        bail!(
            "--measured {}: a simulation, not a measured material; match fits a measured RGL .bsdf (compare puts two simulations side by side)",
            a.measured.display()
        );
    };
    if m.phi_i_rad.len() > 1 {
        bail!(
            "--measured {}: an anisotropic measurement ({} incident azimuths); match fits isotropic measurements",
            a.measured.display(),
            m.phi_i_rad.len()
        );
    }
    let angles: Vec<f64> = m.theta_i_rad.iter().map(|t| t.to_degrees()).collect();
    Ok(recipe::fit_angles(&a.fit_angles, &angles)?)
}

/// The template's values where they lie in the ranges, else the ranges' middles (said).
fn start_of(vary: &[Vary], values: &[f64]) -> Vec<f64> {
    vary.iter()
        .zip(values)
        .map(|(v, &x)| {
            if (v.lo..=v.hi).contains(&x) {
                x
            } else {
                eprintln!(
                    "note: {} = {x} in the template lies outside {}:{}; the search starts from the range's middle",
                    v.path, v.lo, v.hi
                );
                v.value_at(0.5)
            }
        })
        .collect()
}

/// `I/N`: shard I (from 1) of N.
fn shard(s: &str) -> Result<(usize, usize), String> {
    let bad = || format!("'{s}': expected I/N with 1 <= I <= N, e.g. 2/4");
    let (i, n) = s.split_once('/').ok_or_else(bad)?;
    let (i, n) = (
        i.trim().parse().map_err(|_| bad())?,
        n.trim().parse().map_err(|_| bad())?,
    );
    if i == 0 || i > n {
        return Err(bad());
    }
    Ok((i, n))
}

fn metric_of(a: &MatchArgs) -> Metric {
    Metric::parse(&a.metric).expect("checked before the search")
}

fn list(v: &[f64]) -> String {
    if v.is_empty() {
        return "none".into();
    }
    v.iter()
        .map(|t| format!("{t:.2}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Simulates the best recipe at every measured angle below grazing, compares it with the
/// measurement (fitted and held-out angles apart) and writes the outputs.
#[allow(clippy::too_many_arguments)]
fn finish(
    a: &MatchArgs,
    template: &Template,
    vary: &[Vary],
    measured: &Material,
    fit: &[f64],
    held: &[f64],
    outcome: &recipe::Outcome,
    mut settings: goniospec::simulate::SimSettings,
) -> Result<()> {
    let best = &outcome.trace[outcome.best];
    let mut all: Vec<f64> = fit.iter().chain(held).copied().collect();
    all.sort_by(f64::total_cmp);
    let text = template.with_values(vary, &best.values);
    let sample = template.load(&text)?;
    let final_rays = settings.rays;
    settings.theta_i_deg = all;
    // The report's budget is fixed, whatever sized the candidates'.
    settings.target_stderr = None;
    let (acc, _) = goniospec::simulate::simulate(&sample, &settings.resolve()?, &|_| {})?;
    let fitted = Material::from_accumulator(&acc)?;
    let report = compare::compare(&fitted, measured, ["fitted", "measured"])?;
    let is_fit = |t: f64| fit.iter().any(|f| (f - t).abs() < 1e-6);
    let on_fit = recipe::group_stats(&report, &is_fit);
    let on_held = recipe::group_stats(&report, &|t| !is_fit(t));
    outln!("theta_i_deg,role,mean_delta_e,median_delta_e,p95_delta_e,mean_delta_e_lightness");
    for g in &report.angles {
        outln!(
            "{:.2},{},{:.3},{:.3},{:.3},{:.3}",
            g.theta_i_deg,
            if is_fit(g.theta_i_deg) {
                "fitted"
            } else {
                "held out"
            },
            g.delta_e.mean,
            g.delta_e.median,
            g.delta_e.p95,
            g.delta_e_lightness.mean
        );
    }
    for (name, s) in [("fitted angles", &on_fit), ("held-out angles", &on_held)] {
        if let Some(s) = s {
            outln!(
                "# {name}: mean CIEDE2000 {:.3}, 95th percentile {:.3}",
                s.mean,
                s.p95
            );
        }
    }

    let out = &a.output;
    let stats = |s: &Option<compare::Stats>| {
        s.map_or("-".into(), |s| format!("{:.3} (p95 {:.3})", s.mean, s.p95))
    };
    let header = format!(
        "Fitted by goniospec match to {} ({}), fitting theta_i {} deg.\n\
         The search's {}: {:.3} ({} trees an angle).\n\
         This recipe simulated with {} trees an angle: mean CIEDE2000 {} at the fitted angles, {} at the held-out angles {} deg.\n\
         Varied: {}.\n\
         Seed {}, wavelengths {}, {} x {} outgoing buckets{}.",
        a.measured.display(),
        measured.name(),
        list(fit),
        metric_of(a).describe(),
        best.objective,
        a.rays,
        final_rays,
        stats(&on_fit),
        stats(&on_held),
        list(held),
        vary.iter()
            .map(|v| format!(
                "{} in {}:{}{}",
                v.path,
                v.lo,
                v.hi,
                if v.log { " (log)" } else { "" }
            ))
            .collect::<Vec<_>>()
            .join(", "),
        a.seed,
        a.wavelengths,
        a.theta_o_bins,
        a.phi_o_bins,
        a.target_stderr.map_or(String::new(), |t| format!(
            ", trees grown to a {t} relative standard error (--rays the first batch)"
        ))
    );
    let fitted_text = template.fitted(vary, &best.values, out, &header);
    write_text(&out.join("fitted.toml"), &fitted_text)?;
    acc.write(&out.join("fitted.gsa"))
        .with_context(|| format!("writing {}", out.join("fitted.gsa").display()))?;
    recipe::write_trace(&out.join("trace.csv"), vary, outcome)?;
    recipe::write_chart(out, outcome, metric_of(a).describe())?;
    let summary = serde_json::json!({
        "template": a.template.display().to_string(),
        "measured": a.measured.display().to_string(),
        "metric": a.metric,
        "parameters": vary.iter().zip(&best.values).map(|(v, x)| serde_json::json!({
            "path": v.path, "lo": v.lo, "hi": v.hi, "log": v.log, "fitted": x,
        })).collect::<Vec<_>>(),
        "fit_angles_deg": fit,
        "held_out_angles_deg": held,
        "search_objective": best.objective,
        "evaluations": outcome.trace.len(),
        "stopped": match outcome.stop { Stop::Converged => "converged", Stop::Budget => "max-evaluations" },
        "fitted": on_fit,
        "held_out": on_held,
        "angles": report.angles,
        "rays": a.rays,
        "final_rays": final_rays,
        "starts": a.starts,
        "target_stderr": a.target_stderr,
        "seed": a.seed,
        "wavelengths": a.wavelengths,
    });
    write_text(
        &out.join("match.json"),
        &serde_json::to_string_pretty(&summary)?,
    )?;
    let dir = out.join("compare");
    goniospec::output::guard_folder(&dir, &compare::output_names(), a.force)?;
    std::fs::create_dir_all(&dir)?;
    let written = compare::write_outputs(&report, &fitted, measured, &dir)?;
    let names: Vec<String> = written
        .iter()
        .filter_map(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        .collect();
    goniospec::output::record_folder(&dir, &names)?;
    goniospec::output::record_folder(out, &recipe::output_names())?;
    outln!(
        "wrote fitted.toml, fitted.gsa, trace.csv, trace.png, trace.svg, match.json and compare/ into {}",
        out.display()
    );
    Ok(())
}

fn write_text(path: &Path, text: &str) -> Result<()> {
    goniospec::io::write_atomic(path, |w| std::io::Write::write_all(w, text.as_bytes()))
        .with_context(|| format!("writing {}", path.display()))
}
