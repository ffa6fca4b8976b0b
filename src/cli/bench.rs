//! `goniospec bench …`: benchmarks that print `name: value unit` lines.

use super::*;

#[derive(Subcommand)]
pub(super) enum BenchCommand {
    /// Raw closest-hit throughput of each backend on the same rays, in random order and
    /// sorted by position, at each thread count; plus build times and how many closest
    /// hits the backends agree on.
    ///
    /// Example: goniospec bench trace --triangles 1000000 --rays 1000000
    Trace(TraceArgs),
    /// End-to-end simulation speed: launched rays/s and traced segments/s against the
    /// raw intersector, path sharing on against off, Embree against obvhs; and the wall
    /// time and TMM error of a flat film at 40 bins x 10 incident angles.
    Simulate(SimBenchArgs),
    /// BRDF representations: query time (median, p99), memory and build time at 10^4,
    /// 10^5 and 10^6 buckets of a smooth analytic BRDF with its accuracy; the kd-tree
    /// against brute-force search; and accuracy on a rough simulated sample against a
    /// high-sample dense table.
    Eval(EvalBenchArgs),
}

#[derive(Args)]
pub(super) struct EvalBenchArgs {
    /// Rough sample for the accuracy comparison.
    #[arg(default_value = "meshes/rough-glass.toml")]
    sample: PathBuf,
    /// Rays of the low- and high-sample simulations.
    #[arg(long, value_delimiter = ',', default_values_t = [4000u64, 40000])]
    rays: Vec<u64>,
}

#[derive(Args)]
pub(super) struct SimBenchArgs {
    /// Sample to benchmark.
    #[arg(default_value = "meshes/thin-film-600nm.toml")]
    sample: PathBuf,
    /// Trees per run.
    #[arg(long, default_value_t = 20_000)]
    rays: u64,
    /// Incident angle, degrees.
    #[arg(long, value_parser = finite, default_value_t = 30.0)]
    theta_i: f64,
    /// Worker threads (0: all cores).
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Flat film for the TMM comparison.
    #[arg(long, default_value = "meshes/flat-soap-film.toml")]
    flat: PathBuf,
}

#[derive(Args)]
pub(super) struct TraceArgs {
    /// Triangles of the generated periodic height field (20 µm tile, 300 nm RMS).
    #[arg(long, default_value_t = 1_000_000)]
    triangles: usize,
    /// Rays traced per measurement.
    #[arg(long, default_value_t = 1_000_000)]
    rays: usize,
    /// Benchmark this OBJ instead of the generated height field.
    #[arg(long, value_name = "FILE.obj")]
    mesh: Option<PathBuf>,
    /// Unit of the OBJ's coordinates (nm or um).
    #[arg(long, default_value = "nm")]
    unit: String,
    /// Thread counts to measure, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "1,2")]
    threads: Vec<usize>,
    /// Backends to measure, comma-separated: embree, obvhs (default: every available one).
    #[arg(long, value_delimiter = ',', value_parser = parse_backend)]
    backend: Vec<Backend>,
    /// Seed of the surface and the rays.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

pub(super) fn bench_eval(a: EvalBenchArgs) -> Result<ExitCode> {
    use goniospec::brdf::BucketData;
    if a.rays.len() != 2 || a.rays[0] == 0 || a.rays[0] >= a.rays[1] {
        bail!("--rays needs two counts LOW,HIGH with 0 < LOW < HIGH");
    }
    let s = sample::load(&a.sample, MeshOptions::default())?;
    let run = |rays: u64| -> Result<BucketData> {
        let cfg = SimConfig {
            seed: rays,
            buckets: Buckets {
                theta_bins: 30,
                phi_bins: 24,
            },
            ..SimConfig::new(
                vec![0.0, 15.0, 30.0, 45.0, 60.0, 75.0],
                Wavelengths::Bins(vec![450.0, 550.0, 650.0]),
                rays,
            )
        };
        let (acc, _) = goniospec::simulate::simulate(&s, &cfg, &|_| {})?;
        Ok(BucketData::from_accumulator(&acc))
    };
    eprintln!(
        "simulating '{}' at {} and {} rays for the rough-sample comparison",
        s.name, a.rays[0], a.rays[1]
    );
    let (low, high) = (run(a.rays[0])?, run(a.rays[1])?);
    goniospec::bench::eval_bench(Some((&low, &high)), emit);
    Ok(ExitCode::SUCCESS)
}

pub(super) fn bench_simulate(a: SimBenchArgs) -> Result<ExitCode> {
    let s = sample::load(&a.sample, MeshOptions::default())?;
    let flat = sample::load(&a.flat, MeshOptions::default())?;
    let cfg = goniospec::bench::SimulateBenchConfig {
        rays: a.rays,
        theta_i_deg: a.theta_i,
        bins: (0..=40).map(|i| 380.0 + 10.0 * i as f64).collect(),
        backends: Backend::ALL
            .into_iter()
            .filter(|b| b.is_available())
            .collect(),
        seed: 1,
    };
    let pool = thread_pool(a.threads)?;
    pool.install(|| goniospec::bench::simulate_bench(&s, &flat, &cfg, emit))?;
    // Peak memory must not grow with the ray count: two child processes, 10x apart (each
    // process's own high-water mark; one process could not measure the second run).
    let dir = std::env::temp_dir().join(format!("goniospec-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let mut peaks = Vec::new();
    for rays in [a.rays, 10 * a.rays] {
        let out = std::process::Command::new(std::env::current_exe()?)
            .arg("simulate")
            .arg(&a.sample)
            .args([
                "--theta-i",
                &a.theta_i.to_string(),
                "--rays",
                &rays.to_string(),
            ])
            .args(["--threads", &a.threads.to_string()])
            .arg("-o")
            .arg(dir.join("bench.gsa"))
            .output()?;
        let err = String::from_utf8_lossy(&out.stderr);
        if !out.status.success() {
            bail!("bench simulate: the memory run at {rays} rays failed: {err}");
        }
        let mb = peak_memory_of(&err).context("the simulate summary has no peak memory")?;
        outln!("peak_rss_{rays}_rays: {mb:.1} MB");
        peaks.push(mb);
    }
    let _ = std::fs::remove_dir_all(&dir);
    outln!("peak_rss_growth_10x_rays: {:.1} MB", peaks[1] - peaks[0]);
    Ok(ExitCode::SUCCESS)
}

/// The "peak memory N MB" figure of a `simulate` summary line.
pub(super) fn peak_memory_of(summary: &str) -> Option<f64> {
    let rest = &summary[summary.find("peak memory ")? + "peak memory ".len()..];
    rest.split_whitespace().next()?.parse().ok()
}

pub(super) fn bench_trace(a: TraceArgs) -> Result<ExitCode> {
    if a.rays == 0 {
        bail!("--rays must be at least 1");
    }
    if a.threads.is_empty() || a.threads.contains(&0) {
        bail!("--threads needs positive thread counts, e.g. --threads 1,2");
    }
    let backends: Vec<Backend> = if a.backend.is_empty() {
        Backend::ALL
            .into_iter()
            .filter(|b| b.is_available())
            .collect()
    } else {
        for b in &a.backend {
            if !b.is_available() {
                bail!(accel::AccelError::EmbreeUnavailable);
            }
        }
        a.backend.clone()
    };
    let mesh = match &a.mesh {
        Some(p) => {
            let scale = sample::nm_per_unit(&a.unit)
                .with_context(|| format!("unknown --unit '{}' (use nm or um)", a.unit))?;
            sample::load_obj(p, scale, MeshOptions::default())?
        }
        None => {
            if a.triangles < 2 {
                bail!("--triangles must be at least 2");
            }
            eprintln!(
                "generating a periodic height field of about {} triangles",
                a.triangles
            );
            goniospec::accel::workload::default_surface(a.triangles, a.seed)
        }
    };
    outln!(
        "bench trace: {} triangles, {} rays, backends {}",
        mesh.triangles.len(),
        a.rays,
        backends
            .iter()
            .map(|b| b.name())
            .collect::<Vec<_>>()
            .join(", ")
    );
    let cfg = goniospec::bench::TraceBenchConfig {
        rays: a.rays,
        threads: a.threads.clone(),
        backends,
        seed: a.seed,
    };
    let report = goniospec::bench::trace_bench(&mesh, &cfg, emit)?;
    outln!("hit fraction: {:.4}", report.hit_fraction);
    if let Some(ag) = &report.agreement {
        outln!(
            "agreement: {} of {} closest hits identical ({:.4} %), {} edge ties, {} other differences",
            ag.identical,
            ag.rays,
            100.0 * ag.identical as f64 / ag.rays as f64,
            ag.ties,
            ag.rays - ag.identical - ag.ties
        );
    }
    let rate = |b: Backend, o: &str, t: usize| {
        report
            .throughput
            .iter()
            .find(|x| x.backend == b && x.order == o && x.threads == t)
            .map(|x| x.mrays_per_s)
    };
    for o in ["random", "sorted"] {
        for &t in &a.threads {
            if let (Some(e), Some(v)) = (rate(Backend::Embree, o, t), rate(Backend::Obvhs, o, t)) {
                outln!("obvhs/embree {o} {t}T: {:.2}", v / e);
            }
        }
    }
    Ok(ExitCode::SUCCESS)
}
