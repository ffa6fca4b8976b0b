//! `goniospec batch`: plan, run in shards, check and merge many materials.

use std::io::Write;

use goniospec::batch::{self, Manifest};

use super::{
    Args, Context, ExitCode, MeshOptions, PathBuf, Result, Subcommand, bail, progress_bar, sample,
    thread_pool,
};

#[derive(Subcommand)]
pub(super) enum BatchCommand {
    /// Expand a plan (PLAN.toml: [defaults] and [[material]] entries, each with sample,
    /// theta_i, wavelengths, monochromatic, rays, seed, representations) into work units,
    /// one per material and incident direction; every sample is loaded now. Writes
    /// DIR/manifest.toml and prints the unit count and an estimate of the work.
    Plan(BatchPlanArgs),
    /// Run the units of one shard. With neither --shard nor Slurm's array variables, runs
    /// shard 1/1 (everything). Units whose output exists and verifies are skipped, so a
    /// rerun resumes where a crash or a cancelled task stopped.
    Run(BatchRunArgs),
    /// Check every unit and assemble each material's accumulator (DIR/out/NAME.gsa),
    /// byte-identical to simulating it in one run, then build its representations
    /// (DIR/out/NAME-REPR.gsb). Refuses, naming them, units missing, corrupt or from
    /// another plan.
    Merge(BatchDirArgs),
    /// List done, missing and failed units.
    Status(BatchDirArgs),
    /// Write Slurm scripts: units.sbatch (an array, one task per shard), merge.sbatch and
    /// submit.sh, which chains the merge with --dependency=afterok.
    Slurm(BatchSlurmArgs),
    /// Print a GNU parallel command that runs every shard, with --joblog and
    /// --resume-failed.
    Parallel(BatchParallelArgs),
    /// Write one static HTML page over a merged library (after `merge`): per material its
    /// sample and settings, the colour it reflects under D65 at a few incident angles, the
    /// lobe plot, a small rendered sphere, the real-time fit with its error, and links to
    /// its files; sortable by name and reflectance; works offline. The images and fits go
    /// beside the page.
    Report(BatchReportArgs),
}

#[derive(Args)]
pub(super) struct BatchReportArgs {
    /// The batch folder (merged).
    dir: PathBuf,
    /// The page (default DIR/report/index.html); its images go beside it.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Side of each rendered sphere, pixels (a small budget keeps a large library quick).
    #[arg(long, default_value_t = 160, value_parser = clap::value_parser!(u32).range(1..=4096))]
    sphere_size: u32,
    /// Samples per pixel of each sphere.
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(1..=4096))]
    spp: u32,
    /// Incident angles whose colour is shown per material, at most (evenly picked, the
    /// first and last included).
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(1..=90))]
    colours: u32,
    /// Do not fit real-time materials (a fit takes 10-60 s a material: 23 s for the car paint at 5 angles and 40 bins).
    #[arg(long)]
    no_fit: bool,
    /// Worker threads (0: all cores). The page and images do not depend on it.
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Replace the page, images and fits even when they are not files of their kind.
    #[arg(long)]
    force: bool,
}

#[derive(Args)]
pub(super) struct BatchPlanArgs {
    /// The plan (TOML).
    plan: PathBuf,
    /// The batch folder (made if missing).
    #[arg(short, long)]
    output: PathBuf,
}

#[derive(Args)]
pub(super) struct BatchDirArgs {
    /// The batch folder.
    dir: PathBuf,
}

#[derive(Args)]
pub(super) struct BatchRunArgs {
    /// The batch folder.
    dir: PathBuf,
    /// I/N: run shard I of N (1-based). Default: Slurm's SLURM_ARRAY_TASK_ID and
    /// SLURM_ARRAY_TASK_COUNT, else 1/1.
    #[arg(long, value_parser = parse_shard)]
    shard: Option<(usize, usize)>,
    /// Worker threads per unit (0: all cores). Results do not depend on it.
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Run again the units the simulation refused before (their reason is kept beside
    /// them); by default they are skipped, as a rerun refuses them again.
    #[arg(long)]
    retry_refused: bool,
}

#[derive(Args)]
pub(super) struct BatchSlurmArgs {
    /// The batch folder.
    dir: PathBuf,
    /// Array tasks (shards).
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    shards: u32,
    /// At most this many tasks running at once.
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    limit: u32,
}

#[derive(Args)]
pub(super) struct BatchParallelArgs {
    /// The batch folder.
    dir: PathBuf,
    /// Shards.
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    shards: u32,
    /// Shards running at once.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    jobs: u32,
}

fn parse_shard(s: &str) -> Result<(usize, usize), String> {
    let (i, n) = s.split_once('/').ok_or("--shard is I/N, e.g. 2/8")?;
    let (i, n): (usize, usize) = (
        i.trim()
            .parse()
            .map_err(|_| format!("--shard: '{i}' is not a number"))?,
        n.trim()
            .parse()
            .map_err(|_| format!("--shard: '{n}' is not a number"))?,
    );
    if n == 0 || i == 0 || i > n {
        return Err(format!("--shard {s}: need 1 <= I <= N"));
    }
    Ok((i, n))
}

pub(super) fn batch(c: BatchCommand) -> Result<ExitCode> {
    match c {
        BatchCommand::Plan(a) => plan(a),
        BatchCommand::Run(a) => run(a),
        BatchCommand::Merge(a) => merge(a),
        BatchCommand::Status(a) => status(a),
        BatchCommand::Slurm(a) => slurm(a),
        BatchCommand::Report(a) => report(a),
        BatchCommand::Parallel(a) => parallel(a),
    }
}

/// `batch plan`: expands a plan into a manifest of units.
fn plan(a: BatchPlanArgs) -> Result<ExitCode> {
    let manifest = a.output.join("manifest.toml");
    if goniospec::output::same_file(&manifest, &a.plan) {
        bail!(
            "the plan {} is the manifest this would write: refusing to overwrite it",
            a.plan.display()
        );
    }
    let m = Manifest::plan(&a.plan)?;
    m.write(&a.output)?;
    let trees: u64 = m.materials.iter().map(|x| x.settings.budget()).sum();
    outln!(
        "planned {} units ({} materials, {trees} trees) in {}",
        m.units.len(),
        m.materials.len(),
        a.output.join("manifest.toml").display()
    );
    Ok(ExitCode::SUCCESS)
}

/// `batch run`: runs this shard's units, skipping those already done (and those refused
/// before, unless --retry-refused). A unit the simulation refuses does not stop the shard:
/// its reason is kept beside it, the others run, and the shard exits 1 naming it. Each
/// unit's warnings are kept beside it and printed.
fn run(a: BatchRunArgs) -> Result<ExitCode> {
    use goniospec::batch::UnitProblem;
    let m = Manifest::read(&a.dir)?;
    let (i, n) = match (a.shard, batch::shard_from_env()) {
        (Some(s), _) => s,
        (None, Some(env)) => env.map_err(anyhow::Error::msg)?,
        (None, None) => (1, 1),
    };
    let units = m.shard(i, n)?;
    let pool = thread_pool(a.threads)?;
    let bar = progress_bar(units.len() as u64, "units");
    let (mut ran, mut skipped, mut refused, mut warned) = (0usize, 0usize, Vec::new(), 0usize);
    let t0 = std::time::Instant::now();
    let mut loaded: Option<(String, sample::Sample)> = None;
    for u in units {
        match m.verify(&a.dir, u) {
            None => skipped += 1,
            Some(UnitProblem::Refused(why)) if !a.retry_refused => {
                refused.push(format!(
                    "unit {} ({} at {} deg), refused before (--retry-refused runs it again): {why}",
                    u.id, u.material, u.theta_i_deg
                ));
            }
            Some(_) => {
                let mat = m.material(&u.material);
                if loaded.as_ref().is_none_or(|(name, _)| *name != mat.name) {
                    let s = sample::load(&mat.sample, MeshOptions::default())?;
                    if goniospec::simulate::sample_hash(&s) != mat.sample_hash {
                        bail!(
                            "{}: the sample changed since the plan was made; plan again",
                            mat.sample.display()
                        );
                    }
                    loaded = Some((mat.name.clone(), s));
                }
                let s = &loaded.as_ref().expect("loaded").1;
                bar.suspend(|| {
                    eprintln!(
                        "unit {} ({} at {} deg): running",
                        u.id, u.material, u.theta_i_deg
                    )
                });
                match pool.install(|| m.run_unit(&a.dir, u, s)) {
                    Ok(warnings) => {
                        ran += 1;
                        if !warnings.is_empty() {
                            warned += 1;
                        }
                        bar.suspend(|| {
                            for w in &warnings {
                                eprintln!("warning: unit {} ({}): {w}", u.id, u.material);
                            }
                        });
                    }
                    Err(e @ batch::BatchError::Simulation { .. }) => {
                        bar.suspend(|| eprintln!("refused: {e}"));
                        refused.push(e.to_string());
                    }
                    Err(e) => return Err(e.into()),
                }
            }
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    outln!(
        "shard {i}/{n}: ran {ran} units, skipped {skipped} already done, {} refused, {warned} with warnings (kept beside each unit as NNNN.warnings), in {:.2} s",
        refused.len(),
        t0.elapsed().as_secs_f64()
    );
    if refused.is_empty() {
        Ok(ExitCode::SUCCESS)
    } else {
        for r in &refused {
            eprintln!("refused: {r}");
        }
        Ok(ExitCode::from(1))
    }
}

/// A material's representations, built as `build` builds them by default.
fn representations(
    acc: &goniospec::accumulate::file::Accumulator,
    kinds: &[goniospec::brdf::Kind],
) -> std::result::Result<
    Vec<(goniospec::brdf::Kind, goniospec::brdf::Representation)>,
    goniospec::brdf::BrdfError,
> {
    let data = goniospec::brdf::BucketData::from_accumulator(acc);
    let opts = goniospec::brdf::BuildOptions {
        isotropic: goniospec::brdf::symmetry::isotropic(&acc.header.settings, None)?,
        ..Default::default()
    };
    kinds
        .iter()
        .map(|&kind| {
            Ok((
                kind,
                goniospec::brdf::Representation::build(kind, &data, &opts)?,
            ))
        })
        .collect()
}

/// `batch merge`: assembles each material's accumulator and its representations, with its
/// units' warnings (`out/NAME.warnings`, each line prefixed with its incident angle). A
/// material whose units are not all done is left out with its reasons in
/// `out/NAME.failed`, which `batch report` shows; the others are merged, and the command
/// exits 1 naming what was left out.
fn merge(a: BatchDirArgs) -> Result<ExitCode> {
    let m = Manifest::read(&a.dir)?;
    let out = a.dir.join("out");
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    let t0 = std::time::Instant::now();
    let bar = progress_bar(m.materials.len() as u64, "materials");
    let mut problems = Vec::new();
    let mut merged = 0usize;
    let mut warned = 0usize;
    for mat in &m.materials {
        let failed = out.join(format!("{}.failed", mat.name));
        let acc = match m.merge_material(&a.dir, &mat.name) {
            Ok(acc) => acc,
            Err(e) => {
                goniospec::io::write_atomic(&failed, |w| w.write_all(format!("{e}\n").as_bytes()))
                    .with_context(|| format!("writing {}", failed.display()))?;
                problems.push(e.to_string());
                bar.inc(1);
                continue;
            }
        };
        let p = out.join(format!("{}.gsa", mat.name));
        acc.write(&p)
            .with_context(|| format!("writing {}", p.display()))?;
        // As `build` decides: anisotropic for several azimuths, refused for a sample that
        // is not rotation-symmetric lit from one (the material is then marked failed).
        let built = representations(&acc, &mat.representations);
        let built = match built {
            Ok(b) => b,
            Err(e) => {
                let e = format!("material '{}': {e}", mat.name);
                goniospec::io::write_atomic(&failed, |w| w.write_all(format!("{e}\n").as_bytes()))
                    .with_context(|| format!("writing {}", failed.display()))?;
                problems.push(e);
                bar.inc(1);
                continue;
            }
        };
        for (kind, r) in built {
            let g = out.join(format!("{}-{kind}.gsb", mat.name));
            goniospec::brdf::file::write(&r, &g)
                .with_context(|| format!("writing {}", g.display()))?;
        }
        let warnings: Vec<String> = m
            .units
            .iter()
            .filter(|u| u.material == mat.name)
            .flat_map(|u| {
                m.unit_warnings(&a.dir, u)
                    .into_iter()
                    .map(move |w| match u.phi_i_deg {
                        Some(p) => format!("theta_i {} deg, phi_i {p} deg: {w}", u.theta_i_deg),
                        None => format!("theta_i {} deg: {w}", u.theta_i_deg),
                    })
            })
            .collect();
        let log = out.join(format!("{}.warnings", mat.name));
        if warnings.is_empty() {
            std::fs::remove_file(&log).ok();
        } else {
            warned += 1;
            goniospec::io::write_atomic(&log, |w| {
                w.write_all((warnings.join("\n") + "\n").as_bytes())
            })
            .with_context(|| format!("writing {}", log.display()))?;
            bar.suspend(|| {
                for w in &warnings {
                    eprintln!("warning: {}: {w}", mat.name);
                }
            });
        }
        std::fs::remove_file(&failed).ok();
        merged += 1;
        bar.inc(1);
    }
    bar.finish_and_clear();
    outln!(
        "merged {} of {} materials ({} units) in {}, {warned} with warnings (out/NAME.warnings), {:.2} s",
        merged,
        m.materials.len(),
        m.units.len(),
        out.display(),
        t0.elapsed().as_secs_f64()
    );
    if problems.is_empty() {
        Ok(ExitCode::SUCCESS)
    } else {
        eprintln!(
            "cannot merge (left out, the reasons in out/NAME.failed):\n{}",
            problems.join("\n")
        );
        Ok(ExitCode::from(1))
    }
}

/// `batch status`: units done, missing and failed; exit 1 unless all are done.
fn status(a: BatchDirArgs) -> Result<ExitCode> {
    let m = Manifest::read(&a.dir)?;
    let (done, missing, failed) = m.status(&a.dir);
    let warned = done
        .iter()
        .filter(|&&id| !m.unit_warnings(&a.dir, &m.units[id]).is_empty())
        .count();
    outln!(
        "{} units: {} done, {} missing, {} failed; {warned} done with warnings (units/MATERIAL/NNNN.warnings)",
        m.units.len(),
        done.len(),
        missing.len(),
        failed.len()
    );
    for (id, why) in &failed {
        outln!(
            "failed: unit {id} ({}): {why}",
            m.units[*id].output.display()
        );
    }
    if !missing.is_empty() {
        let shown: Vec<String> = missing.iter().take(20).map(|i| i.to_string()).collect();
        outln!(
            "missing: units {}{}",
            shown.join(", "),
            if missing.len() > 20 { ", ..." } else { "" }
        );
    }
    Ok(if failed.is_empty() && missing.is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

/// `batch slurm`: writes the Slurm scripts.
fn slurm(a: BatchSlurmArgs) -> Result<ExitCode> {
    Manifest::read(&a.dir)?;
    let exe = std::env::current_exe().context("locating the goniospec binary")?;
    let dir = std::fs::canonicalize(&a.dir).with_context(|| format!("{}", a.dir.display()))?;
    let scripts = batch::slurm_scripts(&dir, &exe, a.shards as usize, a.limit as usize)?;
    for (p, text) in scripts {
        goniospec::io::write_atomic(&p, |w| w.write_all(text.as_bytes()))
            .with_context(|| format!("writing {}", p.display()))?;
        outln!("wrote {}", p.display());
    }
    outln!(
        "submit with: bash {}",
        batch::shell_quote(&dir.join("submit.sh").display().to_string())
    );
    Ok(ExitCode::SUCCESS)
}

/// `batch report`: the HTML report of every material.
fn report(a: BatchReportArgs) -> Result<ExitCode> {
    use goniospec::batch::report::{ReportOptions, write_report};
    let page = a
        .output
        .clone()
        .unwrap_or_else(|| a.dir.join("report").join("index.html"));
    let opts = ReportOptions {
        sphere_px: a.sphere_size as usize,
        spp: a.spp as usize,
        colours: a.colours as usize,
        fit: !a.no_fit,
        ..ReportOptions::default()
    };
    let count = Manifest::read(&a.dir)?.materials.len();
    let pool = thread_pool(a.threads)?;
    let bar = progress_bar(count as u64, "materials");
    let t0 = std::time::Instant::now();
    let entries =
        pool.install(|| write_report(&a.dir, &page, &opts, a.force, &|n| bar.set_position(n)))?;
    bar.finish_and_clear();
    let gone: Vec<&goniospec::batch::report::Entry> =
        entries.iter().filter(|e| e.failure.is_some()).collect();
    let marked = if gone.is_empty() {
        String::new()
    } else {
        format!(", {} left out and marked", gone.len())
    };
    outln!(
        "wrote {} ({} materials{marked}) in {:.2} s",
        page.display(),
        entries.len(),
        t0.elapsed().as_secs_f64()
    );
    for e in &gone {
        eprintln!(
            "left out: {}: {}",
            e.name,
            e.failure.as_deref().unwrap_or_default()
        );
    }
    Ok(if gone.is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

/// `batch parallel`: prints the GNU parallel command line.
fn parallel(a: BatchParallelArgs) -> Result<ExitCode> {
    Manifest::read(&a.dir)?;
    let exe = std::env::current_exe().context("locating the goniospec binary")?;
    let dir = std::fs::canonicalize(&a.dir).with_context(|| format!("{}", a.dir.display()))?;
    let cmd = batch::parallel_command(&dir, &exe, a.shards as usize, a.jobs as usize)?;
    outln!("{cmd}");
    Ok(ExitCode::SUCCESS)
}
