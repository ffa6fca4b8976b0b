//! The `goniospec` command line: a thin layer that validates arguments and calls the
//! library. Errors print with their whole cause chain; exit codes are 0 (success),
//! 1 (error, or defects found) and 2 (bad usage).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand};

use goniospec::accel::{self, Backend};
use goniospec::bench;
use goniospec::sample::{self, MeshOptions};

/// A virtual goniospectrometer: trace a microgeometry sample (thin films, coatings,
/// pigments, flakes, rough surfaces) with coherent spectral ray optics and turn it into a
/// measured-like BRDF.
///
/// Lengths are in nanometres unless a sample declares otherwise; angles on the command
/// line are in degrees.
#[derive(Parser)]
#[command(name = "goniospec", version, propagate_version = true)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// List the ray-tracing backends this build offers, with their library versions.
    Backends,
    /// Load a sample and look for defects before a long simulation.
    ///
    /// Reports triangle counts, bounding boxes, media and interface orientation, and checks
    /// that closed bodies are watertight, that no interfaces cut through each other, that
    /// sheets tile periodically, and (with random walks that track the current medium) that
    /// no ray ever crosses an interface from the wrong medium. Exits with status 1 when it
    /// finds a defect or cannot load the sample (the error names the file and line).
    Check(CheckArgs),
    /// Benchmarks; each prints its figures.
    #[command(subcommand)]
    Bench(BenchCommand),
}

#[derive(Args)]
struct CheckArgs {
    /// The sample description (TOML).
    sample: PathBuf,
    /// Drop degenerate (zero-area) triangles instead of refusing the mesh.
    #[arg(long)]
    drop_degenerate: bool,
    /// Accelerator for the intersection and leak tests: embree or obvhs (default: embree
    /// where available).
    #[arg(long, value_parser = parse_backend)]
    backend: Option<Backend>,
    /// Random walks of the leak test.
    #[arg(long, default_value_t = 20_000)]
    leak_rays: usize,
    /// Seed of the leak test.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

#[derive(Subcommand)]
enum BenchCommand {
    /// Raw closest-hit throughput of each backend on the same rays, in random order and
    /// sorted by position, at each thread count; plus build times and how many closest
    /// hits the backends agree on.
    ///
    /// Example: goniospec bench trace --triangles 1000000 --rays 1000000
    Trace(TraceArgs),
}

#[derive(Args)]
struct TraceArgs {
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

fn parse_backend(s: &str) -> Result<Backend, String> {
    s.parse::<Backend>().map_err(|e| e.to_string())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e}");
            for cause in e.chain().skip(1) {
                eprintln!("  caused by: {cause}");
            }
            ExitCode::from(1)
        }
    }
}

fn run(cli: Cli) -> Result<ExitCode> {
    match cli.command {
        Command::Backends => backends(),
        Command::Check(a) => check(a),
        Command::Bench(BenchCommand::Trace(a)) => bench_trace(a),
    }
}

fn backends() -> Result<ExitCode> {
    let mut any = false;
    for b in accel::available_backends() {
        match b {
            Ok(info) => {
                any = true;
                let default = if info.backend == Backend::default_available() {
                    "  (default)"
                } else {
                    ""
                };
                println!(
                    "{} {}{}  [{}]",
                    info.backend, info.version, default, info.detail
                );
            }
            Err(msg) => println!("unavailable: {msg}"),
        }
    }
    Ok(if any {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

fn check(a: CheckArgs) -> Result<ExitCode> {
    let opts = MeshOptions {
        drop_degenerate: a.drop_degenerate,
    };
    let s = sample::load(&a.sample, opts)?;
    let copts = sample::check::CheckOptions {
        backend: resolve_backend(a.backend)?,
        leak_rays: a.leak_rays,
        seed: a.seed,
        ..Default::default()
    };
    let report = sample::check::check(&s, &copts)?;
    for f in &report.facts {
        println!("{f}");
    }
    if report.defects.is_empty() {
        println!("no defects found");
        Ok(ExitCode::SUCCESS)
    } else {
        for d in &report.defects {
            println!("DEFECT: {d}");
        }
        println!("{} defects found", report.defects.len());
        Ok(ExitCode::from(1))
    }
}

/// The requested backend, or the default; refuses one this build lacks.
fn resolve_backend(b: Option<Backend>) -> Result<Backend> {
    let b = b.unwrap_or_else(Backend::default_available);
    if !b.is_available() {
        bail!(accel::AccelError::EmbreeUnavailable);
    }
    Ok(b)
}

fn bench_trace(a: TraceArgs) -> Result<ExitCode> {
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
            bench::default_surface(a.triangles, a.seed)
        }
    };
    println!(
        "bench trace: {} triangles, {} rays, backends {}",
        mesh.triangles.len(),
        a.rays,
        backends
            .iter()
            .map(|b| b.name())
            .collect::<Vec<_>>()
            .join(", ")
    );
    let cfg = bench::TraceBenchConfig {
        rays: a.rays,
        threads: a.threads.clone(),
        backends,
        seed: a.seed,
    };
    let report = bench::trace_bench(&mesh, &cfg, |line| println!("{line}"))?;
    println!("hit fraction: {:.4}", report.hit_fraction);
    if let Some(ag) = &report.agreement {
        println!(
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
                println!("obvhs/embree {o} {t}T: {:.2}", v / e);
            }
        }
    }
    Ok(ExitCode::SUCCESS)
}
