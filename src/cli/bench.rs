//! `goniospec bench …`: benchmarks that print `name: value unit` lines.

use super::{
    Args, Backend, Buckets, Context, ExitCode, MeshOptions, PathBuf, Result, SimConfig, Subcommand,
    Wavelengths, accel, bail, emit, finite, parse_backend, sample, thread_pool,
};

#[derive(Subcommand)]
pub(super) enum BenchCommand {
    /// Raw closest-hit throughput of each backend on the same rays, in random order and
    /// sorted by position, at each thread count; plus build times and how many closest
    /// hits the backends agree on.
    ///
    /// Example: goniospec bench trace --triangles 1000000 --rays 1000000
    Trace(TraceArgs),
    /// End-to-end simulation speed: launched rays/s and traced segments/s against the
    /// raw intersector, path sharing on against off, Embree against obvhs; the diffraction
    /// method's wall time against rays on the same sample (at most 16,384 trees); the
    /// particle media's against rays in the same layers without particles (the white paint,
    /// at most 2,048 trees); and the wall time and TMM error of a flat film at 40 bins x 10
    /// incident angles.
    Simulate(SimBenchArgs),
    /// BRDF representations: query time (median, p99), memory and build time at 10^4,
    /// 10^5 and 10^6 buckets of a smooth analytic BRDF with its accuracy; the kd-tree
    /// against brute-force search; and accuracy on a rough simulated sample against a
    /// high-sample dense table.
    Eval(EvalBenchArgs),
    /// Large imported meshes: for a generated rough gold of 1M and 10M triangles and the
    /// seed's film at 2M triangles (or the samples given with --sample), the time to read
    /// the mesh files once, to load them parsing the text and from the binary mesh cache,
    /// to build the Embree scene, the raw Embree random-ray rate, trees/s and segments/s
    /// of a simulation and their fraction of the raw rate, and the peak memory. Each
    /// sample runs in a child process, so its peak memory is its own. The generated
    /// samples are kept in --dir and reused.
    ///
    /// Example: goniospec bench large --samples gold_1m --rays 20000
    Large(LargeBenchArgs),
    /// The shipped paints (white: a TiO2 particle medium, as shipped at 10 % by volume and
    /// at 20 %; pearlescent: coated mica flakes; metallic: aluminium flakes) at default
    /// settings: wall time (the Mie set-up included), trees/s and segments
    /// per tree for --rays trees x 40 wavelength bins (380-780 nm) at one incident angle,
    /// and R at 550 nm with its standard error. Goal: at most 10 s each on 2 cores.
    ///
    /// Example: goniospec bench paints --rays 4096
    Paints(PaintBenchArgs),
    /// Time to a converged BRDF, the speed a user feels: for each sample, at one incident
    /// angle and 40 bins (380-780 nm) on the default bucket grid, the wall time of a run
    /// (from scratch) whose buckets holding 95 % of the reflected power at each wavelength
    /// have a median relative standard error of at most --target; tree counts chosen by
    /// the error's rate over the last two runs, the figure always measured. The errors are
    /// the replicate groups' (README, "Simulation"). They are compared with a second seed
    /// (`seed_check`: the median of |a - b| over their combined standard error, 0.674 for
    /// honest errors, and `two_seed_median_rel_error`); under quasi-Monte Carlo a run's
    /// buckets share its random shifts, so one pair's figure scatters (0.53-1.01 on the
    /// seed's film; tests/converge.rs checks the errors over 24 seeds). A sample that does
    /// not get there within --max-seconds says what it reached.
    ///
    /// Example: goniospec bench converge --samples rough-gold,paint-pigments
    Converge(ConvergeBenchArgs),
    /// A peer on the same work: Mitsuba 3's closest-hit query (`ray_intersect_preliminary`,
    /// the `mitsuba` wheel's `llvm_ad_rgb` variant, in a Python process) against goniospec's
    /// raw intersector on the same mesh (the sample's interfaces) and the same random rays at
    /// the same thread count, and the goniospec tracer's segments per second at one
    /// wavelength, as fractions of Mitsuba's rate. The tracer carries fields, phases and
    /// splits per segment; the figure shows what that costs. Needs a Python with mitsuba
    /// and numpy (`make interop` makes .venv-interop, the default here).
    ///
    /// Example: goniospec bench peer --rays 1000000
    Peer(PeerBenchArgs),
    /// The rigorous solver (--coherence rigorous): the wall time of one cell (one
    /// wavelength and incident angle) on one thread, for a 1-D grating (period 2 um) at 41
    /// orders and a crossed grating (period 1 um) at 11 x 11 orders, each a metal relief of
    /// 24 slices: one solve, and the cell as a run takes it (with its convergence check at
    /// two thirds of the orders and half the slices); and the 1-D relief by the C-method,
    /// unsliced, as a run takes a bare smooth relief.
    ///
    /// Example: goniospec bench rigorous
    Rigorous(RigorousBenchArgs),
    /// Measured materials (RGL .bsdf): reading each file, evaluating one at 10^6 random
    /// direction pairs, and `compare` at all of a measurement's incident angles, against
    /// another measurement and against a simulated table (rough gold, 0 to 80 degrees,
    /// simulated first and not timed), with and without writing its files and pictures.
    ///
    /// Example: goniospec bench measured
    Measured(MeasuredBenchArgs),
}

mod measured;
mod rigorous;
pub(crate) use measured::{MeasuredBenchArgs, bench_measured};
pub(crate) use rigorous::{RigorousBenchArgs, bench_rigorous};

#[derive(Args)]
pub(super) struct PeerBenchArgs {
    /// Sample whose interfaces are the mesh.
    /// (A relative path missing from the working directory is taken from the goniospec
    /// checkout this binary was built from.)
    #[arg(default_value = "meshes/thin-film-600nm.toml")]
    sample: PathBuf,
    /// Random rays over the mesh for the closest-hit comparison.
    #[arg(long, default_value_t = 1_000_000, value_parser = clap::value_parser!(u64).range(1..))]
    rays: u64,
    /// Trees of the tracer's run (30 degrees, 550 nm).
    #[arg(long, default_value_t = 20_000, value_parser = clap::value_parser!(u64).range(1..))]
    trees: u64,
    /// Python with the mitsuba and numpy wheels (default: the checkout's .venv-interop).
    #[arg(long)]
    python: Option<PathBuf>,
    /// goniospec's accelerator (default: embree where available).
    #[arg(long, value_parser = parse_backend)]
    backend: Option<Backend>,
    /// Worker threads, for both (0: all cores).
    #[arg(long, default_value_t = 0)]
    threads: usize,
}

/// `bench peer`: Mitsuba 3 against goniospec on the same mesh and rays.
pub(super) fn bench_peer(a: PeerBenchArgs) -> Result<ExitCode> {
    let sample_path = goniospec::bench::shipped(&a.sample);
    let s = sample::load(&sample_path, MeshOptions::default())?;
    let pool = thread_pool(a.threads)?;
    let python = a.python.unwrap_or_else(|| {
        goniospec::bench::shipped(std::path::Path::new(".venv-interop/bin/python"))
    });
    let dir = std::env::temp_dir().join(format!("goniospec-peer-{}", std::process::id()));
    let cfg = goniospec::bench::PeerConfig {
        rays: usize::try_from(a.rays)?,
        trees: a.trees,
        python,
        script: goniospec::bench::shipped(std::path::Path::new("scripts/bench-peer-mitsuba.py")),
        threads: pool.current_num_threads(),
        backend: a.backend.unwrap_or_else(Backend::default_available),
        seed: 1,
    };
    let result = pool.install(|| goniospec::bench::peer_bench(&s, &cfg, &dir, emit));
    let _ = std::fs::remove_dir_all(&dir);
    result?;
    Ok(ExitCode::SUCCESS)
}

#[derive(Args)]
pub(super) struct ConvergeBenchArgs {
    /// Shipped samples (names in meshes/, comma-separated).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "thin-film-600nm,rough-gold,rough-glass,metallic-paint,pearlescent-paint,paint-pigments,car-paint"
    )]
    samples: Vec<String>,
    /// Incident polar angle, degrees.
    #[arg(long, value_parser = finite, default_value_t = 30.0)]
    theta_i: f64,
    /// The median relative standard error to reach.
    #[arg(long, value_parser = finite, default_value_t = 0.05)]
    target: f64,
    /// Trees of the first run (from 1024, every replicate group has trees: fewer fall back
    /// to the per-tree spread).
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u64).range(64..))]
    start_rays: u64,
    /// Wall time allowed per sample for the search, s.
    #[arg(long, value_parser = finite, default_value_t = 600.0)]
    max_seconds: f64,
    /// Worker threads (0: all cores).
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// A whole material: each sample at 8 incident angles, 0 to 80 degrees in equal steps
    /// (0, 11.4, 22.9, ... 80), each measured as one angle is (--theta-i is then unused),
    /// and their sum per sample (`NAME_material_seconds`). Each angle is a run of its own,
    /// so the sum pays the fixed costs (scene, Mie tables) eight times, as a user running
    /// the angles apart would.
    #[arg(long)]
    material: bool,
}

/// The incident angles of `bench converge --material`, degrees.
const MATERIAL_ANGLES: usize = 8;

/// `bench converge`: each sample's wall time to a BRDF of the target noise.
pub(super) fn bench_converge(a: ConvergeBenchArgs) -> Result<ExitCode> {
    if !(a.target > 0.0 && a.target < 1.0) {
        bail!(
            "--target must lie strictly between 0 and 1, got {}",
            a.target
        );
    }
    if a.max_seconds <= 0.0 {
        bail!("--max-seconds must be positive, got {}", a.max_seconds);
    }
    if !(0.0..90.0).contains(&a.theta_i) {
        bail!("--theta-i must lie in [0, 90) degrees, got {}", a.theta_i);
    }
    let pool = thread_pool(a.threads)?;
    outln!("threads: {} count", pool.current_num_threads());
    let angles: Vec<f64> = if a.material {
        (0..MATERIAL_ANGLES)
            .map(|k| 80.0 * k as f64 / (MATERIAL_ANGLES - 1) as f64)
            .collect()
    } else {
        vec![a.theta_i]
    };
    for name in &a.samples {
        let path = goniospec::bench::shipped(std::path::Path::new(&format!("meshes/{name}.toml")));
        let s = sample::load(&path, MeshOptions::default())?;
        let (mut total, mut all_reached) = (0.0, true);
        for &theta in &angles {
            let cfg = goniospec::bench::ConvergeConfig {
                theta_i_deg: theta,
                edges: visible_bins(),
                target: a.target,
                share: 0.95,
                start_rays: a.start_rays,
                max_seconds: a.max_seconds,
                seed: 1,
            };
            let f = pool
                .install(|| {
                    goniospec::bench::converge(&s, &cfg, &mut |l| {
                        eprintln!("{name} at {theta:.1} deg: {l}")
                    })
                })
                .with_context(|| format!("measuring {name} at {theta} deg"))?;
            let key = if a.material {
                format!("{}_theta_{theta:.0}", name.replace('-', "_"))
            } else {
                name.replace('-', "_")
            };
            outln!("{key}_target_reached: {} bool", u8::from(f.reached));
            outln!("{key}_seconds: {:.2} s", f.seconds);
            outln!("{key}_trees: {} trees", f.trees);
            outln!("{key}_median_rel_stderr: {:.4} 1", f.median);
            if let Some((z, rel)) = f.seed_check {
                outln!("{key}_seed_check: {z:.3} 1");
                outln!("{key}_two_seed_median_rel_error: {rel:.4} 1");
            }
            total += f.seconds;
            all_reached &= f.reached;
        }
        if a.material {
            let key = name.replace('-', "_");
            outln!(
                "{key}_material_target_reached: {} bool",
                u8::from(all_reached)
            );
            outln!("{key}_material_seconds: {total:.2} s");
        }
    }
    Ok(ExitCode::SUCCESS)
}

#[derive(Args)]
pub(super) struct PaintBenchArgs {
    /// Trees per run.
    #[arg(long, default_value_t = 4096, value_parser = clap::value_parser!(u64).range(1..))]
    rays: u64,
    /// Incident polar angle, degrees.
    #[arg(long, value_parser = finite, default_value_t = 30.0)]
    theta_i: f64,
    /// Worker threads (0: all cores).
    #[arg(long, default_value_t = 0)]
    threads: usize,
}

/// `bench paints`: each shipped paint simulated at default settings.
pub(super) fn bench_paints(a: PaintBenchArgs) -> Result<ExitCode> {
    let pool = thread_pool(a.threads)?;
    outln!("threads: {} count", pool.current_num_threads());
    // The white paint as shipped (10 % TiO2 by volume), and at 20 %, where real white
    // paints are (issue 50's goal).
    for (name, fraction) in [
        ("paint-pigments", None),
        ("paint-pigments", Some(0.2)),
        ("pearlescent-paint", None),
        ("metallic-paint", None),
    ] {
        let path = goniospec::bench::shipped(std::path::Path::new(&format!("meshes/{name}.toml")));
        let mut s = sample::load(&path, MeshOptions::default())?;
        if let Some(f) = fraction {
            for m in &mut s.media {
                if let Some(sample::Scattering::Particles {
                    volume_fraction, ..
                }) = &mut m.scattering
                {
                    *volume_fraction = f;
                }
            }
        }
        let edges = visible_bins();
        let cfg = SimConfig::new(vec![a.theta_i], Wavelengths::Bins(edges), a.rays);
        let t0 = std::time::Instant::now();
        let (acc, stats) = pool
            .install(|| goniospec::simulate::simulate(&s, &cfg, &|_| {}))
            .with_context(|| format!("simulating {name}"))?;
        let secs = t0.elapsed().as_secs_f64();
        let key = match fraction {
            None => name.replace('-', "_"),
            Some(f) => format!("{}_{:.0}pct", name.replace('-', "_"), 100.0 * f),
        };
        outln!("{key}_seconds: {secs:.2} s");
        outln!("{key}_trees_per_s: {:.0} trees/s", a.rays as f64 / secs);
        outln!(
            "{key}_segments_per_tree: {:.0} segments",
            stats.segments as f64 / (stats.traces.max(1)) as f64
        );
        let refl = acc
            .reflectance(a.theta_i, None)
            .map_err(anyhow::Error::msg)?;
        if let Some(row) = refl.rows.iter().find(|r| (r.lambda_nm - 555.0).abs() < 5.1) {
            outln!("{key}_R_{:.0}nm: {:.4} 1", row.lambda_nm, row.r);
            if let Some(se) = row.r_stderr {
                outln!("{key}_R_stderr_{:.0}nm: {se:.4} 1", row.lambda_nm);
            }
        }
    }
    Ok(ExitCode::SUCCESS)
}

#[derive(Args)]
pub(super) struct LargeBenchArgs {
    /// Generated samples to measure, comma-separated: gold_1m, film_2m, gold_10m.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "gold_1m,film_2m,gold_10m"
    )]
    samples: Vec<String>,
    /// Measure these sample files (TOML naming large meshes) instead.
    #[arg(long = "sample", value_name = "SAMPLE.toml")]
    sample_files: Vec<PathBuf>,
    /// Where generated samples are written and reused.
    #[arg(long, default_value = "target/bench-large")]
    dir: PathBuf,
    /// Trees of each simulation (30 degrees, 40 bins).
    #[arg(long, default_value_t = 20_000)]
    rays: u64,
    /// Internal: measure one sample in this process, naming its figures KEY.
    #[arg(long, hide = true, num_args = 2, value_names = ["KEY", "SAMPLE"])]
    one: Vec<String>,
}

#[derive(Args)]
pub(super) struct EvalBenchArgs {
    /// Rough sample for the accuracy comparison.
    /// (A relative path missing from the working directory is taken from the goniospec
    /// checkout this binary was built from.)
    #[arg(default_value = "meshes/rough-glass.toml")]
    sample: PathBuf,
    /// Rays of the low- and high-sample simulations.
    #[arg(long, value_delimiter = ',', default_values_t = [4000u64, 40000])]
    rays: Vec<u64>,
}

#[derive(Args)]
pub(super) struct SimBenchArgs {
    /// Sample to benchmark.
    /// (A relative path missing from the working directory is taken from the goniospec
    /// checkout this binary was built from.)
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
    /// (A relative path missing from the working directory is taken from the goniospec
    /// checkout this binary was built from.)
    #[arg(long, default_value = "meshes/flat-soap-film.toml")]
    flat: PathBuf,
    /// Particle-medium sample for the particles' cost against rays in the same layers
    /// without particles (at most 2,048 trees).
    /// (A relative path missing from the working directory is taken from the goniospec
    /// checkout this binary was built from.)
    #[arg(long, default_value = "meshes/paint-pigments.toml")]
    paint: PathBuf,
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
    let s = sample::load(
        &goniospec::bench::shipped(&a.sample),
        MeshOptions::default(),
    )?;
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
    let sample_path = goniospec::bench::shipped(&a.sample);
    let s = sample::load(&sample_path, MeshOptions::default())?;
    let flat = sample::load(&goniospec::bench::shipped(&a.flat), MeshOptions::default())?;
    let paint = sample::load(&goniospec::bench::shipped(&a.paint), MeshOptions::default())?;
    let cfg = goniospec::bench::SimulateBenchConfig {
        rays: a.rays,
        theta_i_deg: a.theta_i,
        bins: visible_bins(),
        backends: Backend::ALL
            .into_iter()
            .filter(|b| b.is_available())
            .collect(),
        seed: 1,
    };
    let pool = thread_pool(a.threads)?;
    pool.install(|| goniospec::bench::simulate_bench(&s, &flat, &paint, &cfg, emit))?;
    // Peak memory must not grow with the ray count: two child processes, 10x apart (each
    // process's own high-water mark; one process could not measure the second run).
    let dir = std::env::temp_dir().join(format!("goniospec-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let mut peaks = Vec::new();
    for rays in [a.rays, 10 * a.rays] {
        let report = dir.join("bench.json");
        let out = std::process::Command::new(std::env::current_exe()?)
            .arg("simulate")
            .arg(&sample_path)
            .args([
                "--theta-i",
                &a.theta_i.to_string(),
                "--rays",
                &rays.to_string(),
            ])
            .args(["--threads", &a.threads.to_string()])
            .arg("-o")
            .arg(dir.join("bench.gsa"))
            .arg("--report-json")
            .arg(&report)
            .output()?;
        if !out.status.success() {
            bail!(
                "bench simulate: the memory run at {rays} rays failed: {}",
                String::from_utf8_lossy(&out.stderr)
            );
        }
        // The run's figures as numbers (`simulate --report-json`), not read from prose.
        let figures: goniospec::simulate::RunReport =
            serde_json::from_slice(&std::fs::read(&report)?)?;
        let mb = figures
            .peak_memory_mb
            .context("this platform does not report peak memory")?;
        outln!("peak_rss_{rays}_rays: {mb:.1} MB");
        peaks.push(mb);
    }
    let _ = std::fs::remove_dir_all(&dir);
    outln!("peak_rss_growth_10x_rays: {:.1} MB", peaks[1] - peaks[0]);
    Ok(ExitCode::SUCCESS)
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

pub(super) fn bench_large(a: LargeBenchArgs) -> Result<ExitCode> {
    use goniospec::bench::LargeSample;
    if a.rays == 0 {
        bail!("--rays must be at least 1");
    }
    if let [key, sample] = &a.one[..] {
        goniospec::bench::large_case(std::path::Path::new(sample), key, a.rays, emit)?;
        return Ok(ExitCode::SUCCESS);
    }
    let mut cases: Vec<(String, PathBuf)> = Vec::new();
    if a.sample_files.is_empty() {
        for name in &a.samples {
            let which = LargeSample::parse(name).with_context(|| {
                format!("unknown sample '{name}' (use gold_1m, film_2m, gold_10m)")
            })?;
            let path = goniospec::bench::large_sample(&a.dir, which, |l| eprintln!("{l}"))?;
            cases.push((which.name().to_string(), path));
        }
    } else {
        for (k, p) in a.sample_files.iter().enumerate() {
            if !p.is_file() {
                bail!("{}: no such sample file", p.display());
            }
            cases.push((format!("sample{k}"), p.clone()));
        }
    }
    let exe = std::env::current_exe().context("finding this program to run each sample")?;
    let mut figures: Vec<(String, f64)> = Vec::new();
    for (key, path) in &cases {
        outln!("# {key}: {}", path.display());
        let out = std::process::Command::new(&exe)
            .args([
                "bench",
                "large",
                "--rays",
                &a.rays.to_string(),
                "--one",
                key,
            ])
            .arg(path)
            .stderr(std::process::Stdio::inherit())
            .output()
            .with_context(|| format!("running the {key} measurement"))?;
        let text = String::from_utf8_lossy(&out.stdout);
        for line in text.lines() {
            outln!("{line}");
            if let Some((name, rest)) = line.split_once(": ")
                && let Some(v) = rest.split_whitespace().next().and_then(|v| v.parse().ok())
            {
                figures.push((name.to_string(), v));
            }
        }
        if !out.status.success() {
            bail!("the {key} measurement failed ({})", out.status);
        }
    }
    // The goals of the large-mesh issue and of the speed issue that followed it (film: 10^7
    // trees in 45 s; rough gold at 10M triangles: 6 M segments/s), where their samples were
    // measured.
    let get = |n: &str| figures.iter().find(|(k, _)| k == n).map(|f| f.1);
    let goal =
        |name: &str, value: Option<f64>, unit: &str, limit: f64, below: bool| -> Result<()> {
            if let Some(v) = value {
                let met = if below { v <= limit } else { v >= limit };
                outln!(
                    "{name}: {v:.3} {unit} (goal {} {limit} {unit}: {})",
                    if below { "<=" } else { ">=" },
                    if met { "met" } else { "not met" }
                );
            }
            Ok(())
        };
    goal(
        "goal_film_2m_1e7_rays_projected_s",
        get("film_2m_projected_1e7_rays_s"),
        "s",
        45.0,
        true,
    )?;
    goal(
        "goal_gold_10m_segments_per_s",
        get("gold_10m_segments_per_s"),
        "segments/s",
        6.0e6,
        false,
    )?;
    goal(
        "goal_gold_10m_load_cached_s",
        get("gold_10m_load_cached_s"),
        "s",
        3.0,
        true,
    )?;
    goal(
        "goal_gold_10m_peak_rss_mb",
        get("gold_10m_peak_rss_mb"),
        "MB",
        4096.0,
        true,
    )?;
    if let (Some(g), Some(f)) = (
        get("gold_10m_segments_per_s"),
        get("film_2m_segments_per_s"),
    ) {
        goal(
            "goal_gold_10m_segment_rate_vs_film_percent",
            Some(100.0 * g / f),
            "%",
            100.0,
            false,
        )?;
    }
    Ok(ExitCode::SUCCESS)
}

/// The benchmarks' spectrum: 40 bins of 10 nm from 380 to 780 nm (edges).
fn visible_bins() -> Vec<f64> {
    (0..=40).map(|i| 380.0 + 10.0 * f64::from(i)).collect()
}
