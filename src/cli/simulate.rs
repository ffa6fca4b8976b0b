//! `goniospec simulate`: trace a sample and write its accumulator.

use super::{
    Args, Coherence, Context, ExitCode, MeshOptions, OutputKind, PathBuf, Result, SimConfig, bail,
    flag_error, guard_output, progress_bar, sample, thread_pool,
};
use goniospec::simulate::SimSettings;

#[derive(Args)]
pub(super) struct SimulateArgs {
    /// The sample description (TOML).
    sample: PathBuf,
    /// Output accumulator (.gsa), written atomically.
    #[arg(short, long)]
    output: PathBuf,
    #[command(flatten)]
    settings: SimSettings,
    /// Worker threads (0: all cores). Results do not depend on it.
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Drop degenerate triangles instead of refusing the mesh.
    #[arg(long)]
    drop_degenerate: bool,
    /// Parse mesh files even where their binary cache (MESH.gsmesh, written beside meshes
    /// of 16 MiB and more and checked against the file's size, time and CRC-32) is valid,
    /// and write none.
    #[arg(long)]
    no_mesh_cache: bool,
    /// Also write the run's figures as JSON (trees, segments, times, peak memory, each
    /// direction's error, the worst lost and untrusted power), for scripts and benchmarks,
    /// atomically.
    #[arg(long, value_name = "FILE")]
    report_json: Option<PathBuf>,
    /// Overwrite an existing output that is not a goniospec accumulator.
    #[arg(long)]
    force: bool,
}

pub(super) fn simulate(a: SimulateArgs) -> Result<ExitCode> {
    // The summary's time is the command's wall time (issue 71: a raised run's summary gave
    // its last try's 57 s of 5 min 48 s).
    let wall = std::time::Instant::now();
    let s = sample::load(
        &a.sample,
        MeshOptions {
            drop_degenerate: a.drop_degenerate,
            cache: if a.no_mesh_cache {
                sample::cache::CachePolicy::Off
            } else {
                sample::cache::CachePolicy::Large
            },
        },
    )?;
    {
        let inputs: Vec<&std::path::Path> = s.inputs.iter().map(|p| p.as_path()).collect();
        guard_output(&a.output, &inputs, OutputKind::Gsa, a.force)?;
        if let Some(r) = &a.report_json {
            if r == &a.output {
                bail!("--report-json and -o name the same file");
            }
            guard_output(r, &inputs, OutputKind::RunReport, a.force)?;
        }
    }
    let cfg = a.settings.resolve().map_err(flag_error)?;
    let said_before = say_before(&s, &cfg);
    // The bar's total is what the run will trace, as it knows it (`ProgressPlan`: the
    // diffraction method's lattice, raised tries, adaptive directions that stop early).
    let plan = std::sync::Arc::new(goniospec::simulate::ProgressPlan::default());
    let cfg = SimConfig {
        progress_plan: Some(plan.clone()),
        ..cfg
    };
    let pool = thread_pool(a.threads)?;
    let bar = progress_bar(a.settings.budget(), "trees");
    // A particle medium's Mie tables take seconds before the first tree: said, not shown
    // as a run stuck at 0 trees.
    let setting_up = std::sync::atomic::AtomicBool::new(false);
    if s.media.iter().any(|m| m.scattering.is_some()) {
        bar.set_message("; tabulating the particle media (Mie, every whole nm)");
        setting_up.store(true, std::sync::atomic::Ordering::Relaxed);
    }
    let progress = |n| {
        if setting_up.swap(false, std::sync::atomic::Ordering::Relaxed) {
            bar.set_message("");
        }
        let total = plan.total().max(n);
        if total != bar.length().unwrap_or(0) {
            bar.set_length(total);
        }
        let (solved, cells) = plan.cells();
        if cells > 0 {
            bar.set_message(format!("; rigorous solver: {solved} of {cells} cells"));
        }
        bar.set_position(n);
    };
    let result = pool.install(|| goniospec::simulate::simulate(&s, &cfg, &progress));
    bar.finish_and_clear();
    let (acc, stats) = match result {
        Ok(r) => r,
        Err(goniospec::simulate::SimError::Partial { cause, kept }) => {
            return Err(keep_partial(&a, &s, &kept.0, &cause));
        }
        Err(e) => return Err(e.into()),
    };
    if a.settings.allow_unphysical
        && let Err(e) = goniospec::simulate::check_physical(&acc, &s.name, Some(&stats))
    {
        eprintln!("warning (--allow-unphysical): {e}");
    }
    acc.write(&a.output)
        .with_context(|| format!("writing {}", a.output.display()))?;
    if let Some(r) = &a.report_json {
        let report = goniospec::simulate::RunReport::new(&stats, &acc);
        let text = serde_json::to_string_pretty(&report)?;
        goniospec::io::write_atomic(r, |w| std::io::Write::write_all(w, text.as_bytes()))
            .with_context(|| format!("writing {}", r.display()))?;
    }
    let wall = wall.elapsed().as_secs_f64();
    if stats.traces == 0 && stats.rigorous.iter().any(Option::is_some) {
        eprintln!("nothing traced: the rigorous solver took every cell, in {wall:.2} s");
    } else {
        eprintln!(
            "{} trees ({} per direction x {} directions), {} traced trees, {} segments; {wall:.2} s in all (the simulation {:.2} s, its set-up {:.2} s): {:.0} trees/s, {:.2} M segments/s; path sharing {}; peak memory {}",
            stats.trees,
            stats.trees / cfg.theta_i_deg.len().max(1) as u64,
            cfg.theta_i_deg.len(),
            stats.traces,
            stats.segments,
            stats.seconds,
            stats.setup_seconds,
            stats.trees as f64 / stats.trace_seconds(),
            stats.segments as f64 / stats.trace_seconds() / 1e6,
            if stats.path_sharing {
                "on"
            } else if stats.wavelength_sharing {
                "off (wavelengths traced together, rays shared up to dispersive refractions)"
            } else {
                "off"
            },
            goniospec::io::peak_rss_mb().map_or_else(|| "unknown".into(), |m| format!("{m:.0} MB"))
        );
    }
    rigorous_summary(&stats, &acc, cfg.rigorous.tolerance);
    if cfg.adaptive() {
        for d in &stats.directions {
            eprintln!("{d}");
        }
    }
    let (ray_cells, diffraction_cells) = acc.header.settings.method_counts();
    if cfg.coherence == Coherence::Auto {
        eprintln!(
            "methods (auto): rays in {ray_cells} cells, the diffraction method in {diffraction_cells}, the rigorous solver in {} (goniospec info lists them per angle)",
            acc.header.settings.rigorous_cells()
        );
    }
    if diffraction_cells > 0 {
        // The trees the run asked for its lattice: the flag's, or those it raised to.
        let asked = acc.header.rays_asked.unwrap_or(a.settings.rays);
        diffraction_summary(&stats, &s, &acc, asked);
    }
    // The warnings the `.gsa` keeps, one line per kind: the set `info` and `batch report`
    // list (issue 71). An open sample's escaped power is a note, not a warning.
    // (A warning said before the run, and only once, is not said again.)
    for g in goniospec::warning_codes::group(&acc.header.warnings) {
        if g.count == 1 && said_before.contains(&g.example) {
            continue;
        }
        let kind = if g.code == "open-sides" {
            "note"
        } else {
            "warning"
        };
        eprintln!("{kind}: {}", g.line());
    }
    outln!("wrote {}", a.output.display());
    Ok(ExitCode::SUCCESS)
}

/// Where the method asked for does not hold for `s`: said once, before the run (and after
/// the settings are known to be valid); returns what was said. Under auto, what a
/// grating does to the rays' total R (its orders meeting a surface plasmon, or a surface
/// smooth at grazing light) concerns the cells that take rays, which the run chooses per
/// cell: said after the run, where it keeps them (not where the solver took every cell).
fn say_before(s: &sample::Sample, cfg: &SimConfig) -> Vec<String> {
    let auto = cfg.coherence == Coherence::Auto;
    let said: Vec<String> =
        sample::validity::findings(s, &goniospec::simulate::validity_context(cfg))
            .into_iter()
            .map(|f| f.message)
            .filter(|m| {
                let code = goniospec::warning_codes::code_of(m);
                !(auto && (code == "grating-orders" || code == "mean-plane"))
            })
            .collect();
    for m in &said {
        let code = goniospec::warning_codes::code_of(m);
        eprintln!("warning: {m} [{code}: docs/warnings.md#{code}]");
    }
    said
}

/// What the rigorous solver did: its cells, the harmonics and slices, the largest
/// difference from the coarser check (each cell's was within the tolerance, or the run was
/// refused) and the time per cell.
fn rigorous_summary(
    stats: &goniospec::simulate::SimStats,
    acc: &goniospec::accumulate::file::Accumulator,
    tolerance: f64,
) {
    let s = &acc.header.settings;
    let nl = s.wavelength_count().max(1);
    let cells: Vec<(usize, goniospec::simulate::RigorousCell)> = stats
        .rigorous
        .iter()
        .enumerate()
        .filter_map(|(k, c)| c.map(|c| (k, c)))
        .collect();
    let Some(&(worst, w)) = cells
        .iter()
        .max_by(|a, b| a.1.difference.total_cmp(&b.1.difference))
    else {
        return;
    };
    let most = cells
        .iter()
        .map(|c| c.1.harmonics)
        .fold([0, 0], |a, h| [a[0].max(h[0]), a[1].max(h[1])]);
    let secs: f64 = cells.iter().map(|c| c.1.seconds).sum();
    let estimate: f64 = cells.iter().map(|c| c.1.estimate_s).sum();
    let sliced = cells.iter().map(|c| c.1.slices).max().unwrap_or(0);
    let curvilinear = cells.iter().filter(|c| c.1.slices == 0).count();
    let how = match (sliced, curvilinear) {
        (0, _) => "the C-method on the relief (unsliced)".to_string(),
        (k, 0) => format!("{k} slices per structured region"),
        (k, c) => format!("{k} slices per structured region, the C-method (unsliced) in {c} cells"),
    };
    let rayleigh = cells.iter().filter(|c| c.1.rayleigh).count();
    let anomaly = if rayleigh > 0 {
        format!(
            "; {rayleigh} cells at Rayleigh's anomaly (an order leaving at grazing) were solved at a wavelength {:.0e} longer, where the efficiencies are continuous",
            goniospec::reference::rigorous::RAYLEIGH_SHIFT
        )
    } else {
        String::new()
    };
    eprintln!(
        "rigorous solver: {} cells, harmonics up to {:?} per axis, {how}; converged: largest difference from the coarser check {:.1e} (tolerance {tolerance:.0e}) at theta_i {} deg, {} nm; {:.3} s per cell (estimated {:.3} s before the run){anomaly}",
        cells.len(),
        most,
        w.difference,
        s.theta_i_deg[worst / nl],
        s.wavelength(worst % nl),
        secs / cells.len() as f64,
        estimate / cells.len() as f64
    );
}

/// What the diffraction method did: the launch lattice, the orders, and how much of the
/// ray field's power its transform kept in propagating orders (the warning outside
/// `DIFFRACTION_RATIO_WARN` is `simulate::run_warnings`').
fn diffraction_summary(
    stats: &goniospec::simulate::SimStats,
    s: &goniospec::sample::Sample,
    acc: &goniospec::accumulate::file::Accumulator,
    rays: u64,
) {
    use goniospec::simulate::diffraction_lattice;
    let [nx, ny] = diffraction_lattice(rays, s.tile_nm);
    let cells: Vec<_> = stats
        .diffraction
        .iter()
        .enumerate()
        .filter(|(_, d)| d.rays_r + d.rays_t > 0.0 && !d.fell_back)
        .collect();
    let Some(&(worst_cell, worst)) = cells.iter().max_by(|a, b| {
        (a.1.ratio() - 1.0)
            .abs()
            .total_cmp(&(b.1.ratio() - 1.0).abs())
    }) else {
        return;
    };
    let orders = cells.iter().map(|(_, d)| d.orders).max().unwrap_or(0);
    let fallback: usize = cells.iter().map(|(_, d)| d.fallback_tubes).sum();
    let nl = acc.header.settings.wavelength_count().max(1);
    let theta = acc.header.settings.theta_i_deg[worst_cell / nl];
    let lambda = acc.header.settings.wavelength(worst_cell % nl);
    eprintln!(
        "diffraction: trees on a {nx} x {ny} lattice over the {:.0} x {:.0} nm tile; up to {orders} propagating orders per cell; the transform kept {:.4} of the ray field's power in propagating orders at worst (theta_i {theta} deg, {lambda} nm), and each cell's orders carry the rays' R and T{}",
        s.tile_nm[0],
        s.tile_nm[1],
        worst.ratio(),
        if fallback > 0 {
            format!(
                "; {fallback} tubes had no neighbouring tree with the same exit and took their tracked cross-section"
            )
        } else {
            String::new()
        }
    );
}

/// A run that failed after some directions finished: those directions' result written
/// beside the output (`NAME.partial.gsa`), and the error saying so. Nothing is written
/// where that file would overwrite an input or a file that is not an accumulator.
fn keep_partial(
    a: &SimulateArgs,
    s: &goniospec::sample::Sample,
    kept: &goniospec::accumulate::file::Accumulator,
    cause: &goniospec::simulate::SimError,
) -> anyhow::Error {
    let path = a.output.with_extension("partial.gsa");
    let inputs: Vec<&std::path::Path> = s.inputs.iter().map(|p| p.as_path()).collect();
    let angles: Vec<String> = kept
        .header
        .settings
        .theta_i_deg
        .iter()
        .map(|t| t.to_string())
        .collect();
    let written = guard_output(&path, &inputs, OutputKind::Gsa, a.force)
        .map_err(|e| e.to_string())
        .and_then(|()| kept.write(&path).map_err(|e| e.to_string()));
    match written {
        Ok(()) => anyhow::anyhow!(
            "{cause}\nthe angles that finished before it ({} deg) are kept in {} (a whole run of those angles: goniospec info lists it); run the others again as the message above says",
            angles.join(", "),
            path.display()
        ),
        Err(why) => anyhow::anyhow!(
            "{cause}\nthe angles that finished before it ({} deg) could not be kept in {}: {why}",
            angles.join(", "),
            path.display()
        ),
    }
}
