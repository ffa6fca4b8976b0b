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
    /// Generate a periodic microgeometry mesh and write it as an OBJ.
    ///
    /// Kinds and their parameters (lengths in --unit):
    ///   flat             z
    ///   gaussian         rms, correlation_length, resolution, [seed, z]
    ///   wavy-film        surface = top|bottom, thickness, thickness_rms, roughness_rms,
    ///                    correlation_length, resolution, [seed, z]
    ///   microfacet       distribution = ggx|beckmann, alpha, resolution, [seed, z]
    ///   v-grooves        angle_deg, count, [z]
    ///   pigment-spheres  radius, volume_fraction, layer = [z0, z1], [subdivisions, seed]
    ///   flakes           size, thickness, tilt_sd_deg, volume_fraction, layer = [z0, z1],
    ///                    [coating, seed]   (coatings go to FILE-coating.obj)
    ///
    /// Example: goniospec generate gaussian --tile 20,20 --unit um
    ///            --param rms=0.1 --param correlation_length=2 --param resolution=128 -o rough.obj
    #[command(verbatim_doc_comment)]
    Generate(GenerateArgs),
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

#[derive(Args)]
struct GenerateArgs {
    /// Generator kind (see above).
    kind: String,
    /// Parameters as key=value (TOML values: numbers, "strings", [arrays]); repeatable.
    #[arg(long = "param", short = 'p', value_name = "KEY=VALUE")]
    params: Vec<String>,
    /// Tile size Lx,Ly in --unit.
    #[arg(long, value_delimiter = ',', default_values_t = [20.0, 20.0])]
    tile: Vec<f64>,
    /// Unit of the tile, the lengths and the OBJ coordinates: nm or um.
    #[arg(long, default_value = "um")]
    unit: String,
    /// Output OBJ (written atomically).
    #[arg(short, long)]
    output: PathBuf,
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
        Command::Generate(a) => generate(a),
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

fn generate(a: GenerateArgs) -> Result<ExitCode> {
    use goniospec::sample::generate::{Generated, GeneratorSpec};
    let u = sample::nm_per_unit(&a.unit)
        .with_context(|| format!("unknown --unit '{}' (use nm or um)", a.unit))?;
    if a.tile.len() != 2 {
        bail!("--tile needs two sizes Lx,Ly, got {:?}", a.tile);
    }
    let tile_nm = [a.tile[0] * u, a.tile[1] * u];
    if !tile_nm.iter().all(|t| t.is_finite() && *t > 0.0) {
        bail!("--tile must be two positive sizes, got {:?}", a.tile);
    }
    let mut text = format!("kind = {:?}\n", a.kind);
    for p in &a.params {
        let (k, v) = p
            .split_once('=')
            .with_context(|| format!("--param '{p}' is not KEY=VALUE"))?;
        let (k, v) = (k.trim(), v.trim());
        // A bare word that is not a TOML value (ggx, top) is taken as a string.
        let value = if toml::from_str::<toml::Table>(&format!("x = {v}")).is_ok() {
            v.to_string()
        } else {
            format!("{v:?}")
        };
        text.push_str(&format!("{k} = {value}\n"));
    }
    let spec: GeneratorSpec = toml::from_str(&text)
        .map_err(|e| anyhow::anyhow!("generator '{}': {}", a.kind, e.message().trim()))?;
    let comment = format!(
        "goniospec generate {} {} --tile {},{} --unit {}\nCoordinates in {}.",
        a.kind,
        a.params
            .iter()
            .map(|p| format!("--param {p}"))
            .collect::<Vec<_>>()
            .join(" "),
        a.tile[0],
        a.tile[1],
        a.unit,
        a.unit
    );
    let out = spec
        .generate(tile_nm, u)
        .map_err(|e| anyhow::anyhow!("generator '{}': {e}", a.kind))?;
    match out {
        Generated::Sheet(mesh) => {
            mesh.write_obj(&a.output, u, &comment)
                .with_context(|| format!("writing {}", a.output.display()))?;
            println!(
                "wrote {} ({} triangles)",
                a.output.display(),
                mesh.triangles.len()
            );
        }
        Generated::Bodies(bodies) => {
            let mut cores = sample::Mesh::default();
            let mut shells = sample::Mesh::default();
            for (c, s) in &bodies {
                cores.append(c);
                if let Some(s) = s {
                    shells.append(s);
                }
            }
            cores
                .write_obj(&a.output, u, &format!("{comment}\n{} bodies", bodies.len()))
                .with_context(|| format!("writing {}", a.output.display()))?;
            println!(
                "wrote {} ({} bodies, {} triangles)",
                a.output.display(),
                bodies.len(),
                cores.triangles.len()
            );
            if !shells.triangles.is_empty() {
                let stem = a.output.file_stem().unwrap_or_default().to_string_lossy();
                let p = a.output.with_file_name(format!("{stem}-coating.obj"));
                shells
                    .write_obj(
                        &p,
                        u,
                        &format!("{comment}\ncoating shells of {} bodies", bodies.len()),
                    )
                    .with_context(|| format!("writing {}", p.display()))?;
                println!(
                    "wrote {} ({} triangles)",
                    p.display(),
                    shells.triangles.len()
                );
            }
        }
    }
    Ok(ExitCode::SUCCESS)
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
