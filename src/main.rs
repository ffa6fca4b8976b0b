//! The `goniospec` command line: a thin layer that validates arguments and calls the
//! library. Errors print with their whole cause chain; exit codes are 0 (success),
//! 1 (error, or defects found) and 2 (bad usage).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand};

use goniospec::accel::{self, Backend};
use goniospec::accumulate::file::Accumulator;
use goniospec::accumulate::{Buckets, Coherence};
use goniospec::bench;
use goniospec::sample::{self, MeshOptions};
use goniospec::simulate::{SimConfig, Wavelengths};
use goniospec::trace::TraceLimits;

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
    /// Simulate the virtual goniospectrometer: trace coherent ray trees through a sample
    /// and accumulate its BRDF and BTDF into a .gsa file.
    ///
    /// For each incident direction, RAYS trees are launched on a low-discrepancy grid of
    /// entry points over the periodic tile; each splits at every interface into reflected
    /// and transmitted children carrying the complex E-field of both polarisations and the
    /// optical path. Exits are accumulated with the beamlet estimator (contributions of one
    /// tree interfere within a Gaussian beamlet of --coherence-radius-nm; trees add
    /// incoherently), so estimates converge as RAYS grows and do not darken with the
    /// sampled area. Example:
    ///
    ///   goniospec simulate meshes/thin-film-600nm.toml --theta-i 0,30,60 --rays 4096 -o film.gsa
    #[command(verbatim_doc_comment)]
    Simulate(SimulateArgs),
    /// Add runs of the same sample and settings made with different seeds.
    Merge(MergeArgs),
    /// Print the directional-hemispherical reflectance of a .gsa file as CSV:
    /// lambda_nm,R,T,absorbed,dropped,R_stderr.
    Reflectance(ReflectanceArgs),
    /// Print the analytic transfer-matrix R and T of a [stack] sample as CSV:
    /// lambda_nm,Rs,Rp,R,Ts,Tp,T (bin-averaged for wavelength bins).
    Analytic(AnalyticArgs),
    /// Build a queryable BRDF (.gsb) from an accumulator: the seed's 4-D spherical
    /// kd-tree, Gondek's adaptively subdivided hemisphere, or a dense table.
    Build(BuildArgs),
    /// Evaluate a built BRDF: CSV lambda_nm,brdf for one direction pair, or
    /// pair,lambda_nm,brdf for the pairs of --pairs FILE.csv (columns theta_i,phi_i,
    /// theta_o,phi_o in degrees).
    Eval(EvalArgs),
    /// Describe a .gsa or .gsb file.
    Info(InfoArgs),
    /// Render an object made of a built BRDF: a spectral image written as a linear-sRGB
    /// EXR and an sRGB PNG preview beside it (same name, .png).
    ///
    /// With --simulate SAMPLE.toml instead of a .gsb, it first simulates only what the
    /// image needs: a pre-pass finds the incident angles (on a --theta-step grid) that the
    /// light and the environment query, each is simulated adaptively to --tolerance, and
    /// the saving against a full-hemisphere simulation is reported. The accumulator and
    /// the BRDF table are written beside the image (.gsa, .gsb).
    ///
    /// Examples: goniospec render film.gsb -o out/film.exr --shape sphere --spp 16
    ///           goniospec render --simulate meshes/flat-soap-film.toml -o out/panel.exr --shape plane
    Render(RenderArgs),
    /// Run a speed-against-accuracy study (a sweep of rays, bucket resolution, estimator,
    /// beamlet radius, backend and representation) and write points.csv and report.md.
    ///
    /// Example: goniospec study studies/flat-film.toml -o out/study
    Study(StudyArgs),
    /// Generate a periodic microgeometry mesh and write it as an OBJ.
    ///
    /// Kinds and their parameters (lengths in --unit):
    ///   flat             z
    ///   gaussian         rms, correlation_length, resolution, [seed, z]
    ///   wavy-film        surface = top|bottom, thickness, thickness_rms, roughness_rms,
    ///                    correlation_length, resolution, [seed, z]
    ///   microfacet       distribution = ggx|beckmann, alpha, resolution, [correlation_length, seed, z]
    ///   v-grooves        angle_deg, count, [z]
    ///   cosine           amplitude, resolution, [z]   (z + amplitude cos(2 pi x / Lx))
    ///   wedge            slope_deg, [z]   (z + tan(slope) |x - Lx/2|, a periodic roof)
    ///   pigment-spheres  radius, volume_fraction, layer = [z0, z1], [subdivisions, seed]
    ///   flakes           size, thickness, tilt_sd_deg, volume_fraction, layer = [z0, z1],
    ///                    [coating, seed]   (coatings go to FILE-coating.obj)
    ///
    /// Example: goniospec generate gaussian --tile 20,20 --unit um
    ///            --param rms=0.1 --param correlation_length=2 --param resolution=128 -o rough.obj
    #[command(verbatim_doc_comment)]
    Generate(GenerateArgs),
    /// Fits a real-time material (GGX roughness, a base and an optional thin film) to a
    /// simulated one and writes it for glTF 2.0 (KHR_materials_iridescence / _ior), OpenPBR
    /// and Standard Surface. Example: goniospec fit film.gsa -o film  (writes film.json and
    /// film.gltf; prints the parameters, their residual and Delta E2000 per angle).
    Fit(FitArgs),
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

/// Wavelength sampling on the command line.
#[derive(Args, Clone, Debug)]
struct WavelengthArgs {
    /// Wavelengths, nm: A:B:STEP gives bins of width STEP from A to B (or, with
    /// --monochromatic, the wavelengths A, A+STEP, ..., B); a comma list gives bin edges
    /// (or exact wavelengths with --monochromatic).
    #[arg(long, default_value = "380:780:10")]
    wavelengths: String,
    /// Use the exact wavelengths instead of jittered bins.
    #[arg(long)]
    monochromatic: bool,
}

/// Most worker threads a command may ask for (each holds its own scratch buffers).
const MAX_THREADS: usize = 1024;

impl WavelengthArgs {
    fn parse(&self) -> Result<Wavelengths> {
        Wavelengths::parse(&self.wavelengths, self.monochromatic).map_err(anyhow::Error::msg)
    }
}

fn parse_radius(s: &str) -> Result<f64, String> {
    if s.eq_ignore_ascii_case("inf") {
        return Ok(f64::INFINITY);
    }
    match s.parse::<f64>() {
        Ok(v) if v > 0.0 && v.is_finite() => Ok(v),
        _ => Err(format!("'{s}' is not a positive radius in nm (or inf)")),
    }
}

fn parse_coherence(s: &str) -> Result<Coherence, String> {
    Coherence::parse(s)
        .ok_or_else(|| format!("unknown coherence '{s}' (beamlet, bucket or global)"))
}

#[derive(Args)]
struct SimulateArgs {
    /// The sample description (TOML).
    sample: PathBuf,
    /// Output accumulator (.gsa), written atomically.
    #[arg(short, long)]
    output: PathBuf,
    /// Incident polar angles, degrees, comma-separated.
    #[arg(long, value_parser = finite, value_delimiter = ',', default_value = "0,15,30,45,60,75")]
    theta_i: Vec<f64>,
    /// Incident azimuth, degrees.
    #[arg(long, value_parser = finite, default_value_t = 0.0)]
    phi_i: f64,
    /// Launched rays (trees) per incident direction; each covers every wavelength.
    #[arg(long, default_value_t = 4096)]
    rays: u64,
    #[command(flatten)]
    wavelengths: WavelengthArgs,
    /// Accelerator: embree or obvhs (default: embree where available).
    #[arg(long, value_parser = parse_backend)]
    backend: Option<Backend>,
    /// Seed of entry points and wavelength jitter.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Worker threads (0: all cores). Results do not depend on it.
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Estimator: beamlet (default), or the failing comparison modes bucket and global.
    #[arg(long, default_value = "beamlet", value_parser = parse_coherence)]
    coherence: Coherence,
    /// Beamlet radius in nm, or inf for the plane-wave limit.
    #[arg(long, default_value = "5000", value_parser = parse_radius)]
    coherence_radius_nm: f64,
    /// Polar bins of the outgoing hemispheres (equal in theta).
    #[arg(long, default_value_t = 45)]
    theta_o_bins: u32,
    /// Azimuth bins of the outgoing hemispheres.
    #[arg(long, default_value_t = 36)]
    phi_o_bins: u32,
    /// Children below this fraction of the launched power are dropped (and reported).
    #[arg(long, value_parser = finite, default_value_t = 1e-10)]
    cutoff: f64,
    /// Interface events along one path before it is dropped.
    #[arg(long, default_value_t = 64)]
    max_depth: u32,
    /// Segments of one tree before its remaining rays are dropped (multiply scattering
    /// samples; raise --cutoff to 1e-4..1e-6 for pigments and flakes).
    #[arg(long, default_value_t = 20_000)]
    max_segments: u32,
    /// Adaptive budget: launch batches of --rays per incident direction until the relative
    /// standard error of the reflectance (total and every populated bucket) is at most
    /// this, e.g. 0.01; reports per direction whether it converged or ran out of budget.
    #[arg(long, value_parser = finite)]
    tolerance: Option<f64>,
    /// Largest number of rays per incident direction with --tolerance.
    #[arg(long, default_value_t = 1_000_000)]
    max_rays: u64,
    /// Trace every wavelength separately even when no medium is dispersive.
    #[arg(long)]
    no_path_sharing: bool,
    /// Drop degenerate triangles instead of refusing the mesh.
    #[arg(long)]
    drop_degenerate: bool,
    /// Debugging only: write results that are physically impossible (R > 1, negative
    /// power, energy created) instead of refusing them with exit status 1. The run still
    /// prints what failed.
    #[arg(long)]
    allow_unphysical: bool,
    /// Overwrite an existing output that is not a goniospec accumulator.
    #[arg(long)]
    force: bool,
}

#[derive(Args)]
struct MergeArgs {
    /// Accumulators to add (same sample and settings, different seeds).
    #[arg(required = true, num_args = 2..)]
    inputs: Vec<PathBuf>,
    /// Output accumulator.
    #[arg(short, long)]
    output: PathBuf,
    /// Overwrite an existing output that is not a goniospec accumulator.
    #[arg(long)]
    force: bool,
}

#[derive(Args)]
struct FitArgs {
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
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum FitBase {
    Auto,
    Dielectric,
    Conductor,
}

#[derive(Args)]
struct ReflectanceArgs {
    /// A .gsa accumulator.
    file: PathBuf,
    /// Incident polar angle, degrees (one of those simulated).
    #[arg(long, value_parser = finite)]
    theta_i: f64,
    /// Incident azimuth, degrees (must match the simulation's).
    #[arg(long, value_parser = finite)]
    phi_i: Option<f64>,
}

#[derive(Args)]
struct AnalyticArgs {
    /// A sample written as a [stack].
    sample: PathBuf,
    /// Incident polar angle, degrees.
    #[arg(long, value_parser = finite)]
    theta_i: f64,
    #[command(flatten)]
    wavelengths: WavelengthArgs,
}

/// A finite number: every floating-point flag goes through this, so NaN and infinity are
/// refused before any work starts, with the flag's name (clap's usage error, exit 2).
fn finite(s: &str) -> Result<f64, String> {
    let v: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("'{s}' is not a number"))?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(format!("{s} is not a finite number"))
    }
}

fn parse_repr(s: &str) -> Result<String, String> {
    match s {
        "kdtree" | "subdivided" | "table" => Ok(s.to_string()),
        _ => Err(format!(
            "unknown representation '{s}' (kdtree, subdivided or table)"
        )),
    }
}

#[derive(Args)]
struct BuildArgs {
    /// The accumulator (.gsa).
    input: PathBuf,
    /// Representation: kdtree, subdivided or table.
    #[arg(long, default_value = "kdtree", value_parser = parse_repr)]
    repr: String,
    /// Output BRDF (.gsb), written atomically.
    #[arg(short, long)]
    output: PathBuf,
    /// Overwrite an existing output that is not a goniospec BRDF.
    #[arg(long)]
    force: bool,
    /// kd-tree: neighbours blended per query.
    #[arg(long, default_value_t = 4)]
    k: usize,
    /// Subdivided: relative RMS deviation above which a cell splits.
    #[arg(long, value_parser = finite, default_value_t = 0.05)]
    tolerance: f64,
    /// kd-tree: keep absolute azimuths instead of reducing to phi_o - phi_i.
    #[arg(long)]
    anisotropic: bool,
    /// kd-tree: also enter each bucket as its reciprocal pair (wo, wi).
    #[arg(long)]
    reciprocal: bool,
}

#[derive(Args)]
struct EvalArgs {
    /// A built BRDF (.gsb).
    file: PathBuf,
    /// Incident polar angle, degrees.
    #[arg(long, value_parser = finite, required_unless_present = "pairs")]
    theta_i: Option<f64>,
    /// Incident azimuth, degrees.
    #[arg(long, value_parser = finite, default_value_t = 0.0)]
    phi_i: f64,
    /// Outgoing polar angle, degrees.
    #[arg(long, value_parser = finite, required_unless_present = "pairs")]
    theta_o: Option<f64>,
    /// Outgoing azimuth, degrees.
    #[arg(long, value_parser = finite, default_value_t = 180.0)]
    phi_o: f64,
    /// CSV of pairs with the header theta_i,phi_i,theta_o,phi_o (degrees).
    #[arg(long)]
    pairs: Option<PathBuf>,
}

#[derive(Args)]
struct RenderArgs {
    /// A built BRDF (.gsb); or give --simulate SAMPLE.toml instead.
    #[arg(required_unless_present = "simulate", conflicts_with = "simulate")]
    file: Option<PathBuf>,
    /// Simulate the sample first, only at the incident angles the image needs.
    #[arg(long, value_name = "SAMPLE.toml")]
    simulate: Option<PathBuf>,
    /// With --simulate: relative standard error each needed direction is simulated to
    /// (total R and every populated bucket, per wavelength bin). 0.05 is about one CIELAB
    /// unit at mid-grey: dL* = 21.8 dY/Y at Y = 0.18, from L* = 116 Y^(1/3) - 16.
    #[arg(long, value_parser = finite, default_value_t = 0.05)]
    tolerance: f64,
    /// With --simulate: trees per batch per direction (the adaptive step).
    #[arg(long, default_value_t = 512)]
    rays: u64,
    /// With --simulate: the most trees per direction.
    #[arg(long, default_value_t = 16_384)]
    max_rays: u64,
    /// With --simulate: spacing of the incident-angle grid, degrees (full hemisphere:
    /// 0, STEP, ..., below 90).
    #[arg(long, value_parser = finite, default_value_t = 5.0)]
    theta_step: f64,
    /// With --simulate: the wavelength sampling.
    #[command(flatten)]
    wavelengths: WavelengthArgs,
    /// Output EXR; the PNG preview goes beside it.
    #[arg(short, long)]
    output: PathBuf,
    /// sphere, plane (a flat square panel facing up), or an OBJ file (smooth normals are
    /// computed from its triangles).
    #[arg(long, default_value = "sphere")]
    shape: String,
    /// Image width, pixels (1 to 16384).
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(1..=16384))]
    width: u32,
    /// Image height, pixels (1 to 16384).
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(1..=16384))]
    height: u32,
    /// Samples per pixel (1 to 65536).
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u32).range(1..=65536))]
    spp: u32,
    /// dir:THETA,PHI (degrees, towards the light), point:X,Y,Z, or none.
    #[arg(long, default_value = "dir:50,-120")]
    light: String,
    #[arg(long, value_parser = finite, default_value_t = 0.8)]
    light_strength: f64,
    /// constant, sky or none.
    #[arg(long, default_value = "constant")]
    env: String,
    #[arg(long, value_parser = finite, default_value_t = 0.6)]
    env_strength: f64,
    /// Camera position X,Y,Z; it looks at the shape's centre (default: in front of it,
    /// slightly above).
    #[arg(long, value_parser = finite, value_delimiter = ',')]
    camera: Vec<f64>,
    /// Vertical field of view, degrees.
    #[arg(long, value_parser = finite, default_value_t = 30.0)]
    fov: f64,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Worker threads (0: all cores). Images do not depend on it.
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Also render the [stack] sample's analytic (TMM) reflectance under the same
    /// environment and report the difference (relative RMSE, mean CIE DE2000).
    #[arg(long, value_name = "SAMPLE.toml")]
    analytic: Option<PathBuf>,
}

#[derive(Args)]
struct StudyArgs {
    /// The study description (TOML).
    study: PathBuf,
    /// Output folder.
    #[arg(short, long)]
    output: PathBuf,
}

#[derive(Args)]
struct InfoArgs {
    /// A .gsa or .gsb file.
    file: PathBuf,
}

#[derive(Args)]
struct GenerateArgs {
    /// Generator kind (see above).
    kind: String,
    /// Parameters as key=value (TOML values: numbers, "strings", [arrays]); repeatable.
    #[arg(long = "param", short = 'p', value_name = "KEY=VALUE")]
    params: Vec<String>,
    /// Tile size Lx,Ly in --unit.
    #[arg(long, value_parser = finite, value_delimiter = ',', default_values_t = [20.0, 20.0])]
    tile: Vec<f64>,
    /// Unit of the tile, the lengths and the OBJ coordinates: nm or um.
    #[arg(long, default_value = "um")]
    unit: String,
    /// Output OBJ (written atomically).
    #[arg(short, long)]
    output: PathBuf,
    /// Overwrite an existing output that is not an OBJ written by goniospec generate.
    #[arg(long)]
    force: bool,
}

#[derive(Subcommand)]
enum BenchCommand {
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
struct EvalBenchArgs {
    /// Rough sample for the accuracy comparison.
    #[arg(default_value = "meshes/rough-glass.toml")]
    sample: PathBuf,
    /// Rays of the low- and high-sample simulations.
    #[arg(long, value_delimiter = ',', default_values_t = [4000u64, 40000])]
    rays: Vec<u64>,
}

#[derive(Args)]
struct SimBenchArgs {
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

/// `println!` that returns an error instead of panicking when standard output fails (a full
/// disk, a file closed for writing): the command ends with a clear message and exit status 1.
/// (A closed pipe ends it quietly: see `main`.)
macro_rules! outln {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        writeln!(std::io::stdout().lock(), $($t)*).context("writing to standard output")?
    }};
}

/// Prints one line of a long-running command's report from a callback (benchmarks): a
/// closed pipe ends the process quietly, any other failure with a message and status 1.
fn emit(line: &str) {
    use std::io::Write as _;
    if let Err(e) = writeln!(std::io::stdout().lock(), "{line}") {
        if e.kind() != std::io::ErrorKind::BrokenPipe {
            eprintln!("error: writing to standard output: {e}");
            std::process::exit(1);
        }
        std::process::exit(0);
    }
}

/// Whether an error comes from writing into a closed pipe.
fn broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(code) => code,
        // `goniospec reflectance f.gsa | head`: the reader has what it wanted. End quietly,
        // as ripgrep does (Rust ignores SIGPIPE, so the write returns BrokenPipe).
        Err(e) if broken_pipe(&e) => ExitCode::SUCCESS,
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
        Command::Simulate(a) => simulate(a),
        Command::Merge(a) => merge(a),
        Command::Reflectance(a) => reflectance(a),
        Command::Analytic(a) => analytic(a),
        Command::Build(a) => build(a),
        Command::Eval(a) => eval(a),
        Command::Info(a) => info(a),
        Command::Render(a) => render(a),
        Command::Study(a) => study(a),
        Command::Generate(a) => generate(a),
        Command::Fit(a) => fit(a),
        Command::Bench(BenchCommand::Trace(a)) => bench_trace(a),
        Command::Bench(BenchCommand::Simulate(a)) => bench_simulate(a),
        Command::Bench(BenchCommand::Eval(a)) => bench_eval(a),
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
                outln!(
                    "{} {}{}  [{}]",
                    info.backend,
                    info.version,
                    default,
                    info.detail
                );
            }
            Err(msg) => outln!("unavailable: {msg}"),
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
        outln!("{f}");
    }
    if report.defects.is_empty() {
        outln!("no defects found");
        Ok(ExitCode::SUCCESS)
    } else {
        for d in &report.defects {
            outln!("DEFECT: {d}");
        }
        outln!("{} defects found", report.defects.len());
        Ok(ExitCode::from(1))
    }
}

fn simulate(a: SimulateArgs) -> Result<ExitCode> {
    let s = sample::load(
        &a.sample,
        MeshOptions {
            drop_degenerate: a.drop_degenerate,
        },
    )?;
    {
        let meshes: Vec<PathBuf> = s
            .interfaces
            .iter()
            .map(|i| {
                a.sample
                    .parent()
                    .unwrap_or(std::path::Path::new("."))
                    .join(&i.mesh_path)
            })
            .collect();
        let mut inputs: Vec<&std::path::Path> = vec![a.sample.as_path()];
        inputs.extend(meshes.iter().map(|p| p.as_path()));
        guard_output(&a.output, &inputs, OutputKind::Gsa, a.force)?;
    }
    let cfg = SimConfig {
        phi_i_deg: a.phi_i,
        backend: resolve_backend(a.backend)?,
        seed: a.seed,
        coherence: a.coherence,
        rho_nm: a.coherence_radius_nm,
        limits: TraceLimits {
            cutoff: a.cutoff,
            max_depth: a.max_depth,
            max_segments: a.max_segments,
            ..Default::default()
        },
        buckets: Buckets {
            theta_bins: a.theta_o_bins,
            phi_bins: a.phi_o_bins,
        },
        path_sharing: a.no_path_sharing.then_some(false),
        allow_unphysical: a.allow_unphysical,
        tolerance: a.tolerance,
        max_rays: a.max_rays,
        ..SimConfig::new(a.theta_i.clone(), a.wavelengths.parse()?, a.rays)
    };
    let total = if a.tolerance.is_some() {
        a.max_rays
    } else {
        a.rays
    } * a.theta_i.len() as u64;
    let bar = indicatif::ProgressBar::new(total);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} trees  {per_sec}  eta {eta}")
            .expect("a valid template"),
    );
    if a.threads > MAX_THREADS {
        bail!(
            "--threads {} is more than {MAX_THREADS}; 0 uses every core",
            a.threads
        );
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(a.threads)
        .build()?;
    let (acc, stats) =
        pool.install(|| goniospec::simulate::simulate(&s, &cfg, &|n| bar.set_position(n)))?;
    bar.finish_and_clear();
    if a.allow_unphysical
        && let Err(e) =
            goniospec::simulate::check_physical(&acc, &s.name, Some(&stats.limit_dropped))
    {
        eprintln!("warning (--allow-unphysical): {e}");
    }
    acc.write(&a.output)
        .with_context(|| format!("writing {}", a.output.display()))?;
    eprintln!(
        "{} trees ({} per direction x {} directions), {} traced trees, {} segments in {:.2} s: {:.0} trees/s, {:.2} M segments/s; path sharing {}; peak memory {}",
        stats.trees,
        a.rays,
        a.theta_i.len(),
        stats.traces,
        stats.segments,
        stats.seconds,
        stats.trees as f64 / stats.seconds,
        stats.segments as f64 / stats.seconds / 1e6,
        if stats.path_sharing { "on" } else { "off" },
        goniospec::io::peak_rss_mb().map_or_else(|| "unknown".into(), |m| format!("{m:.0} MB"))
    );
    if a.tolerance.is_some() {
        for d in &stats.directions {
            eprintln!(
                "theta_i {} deg: {} rays, relative standard error {} ({})",
                d.theta_i_deg,
                d.rays,
                d.achieved.map_or("undefined".into(), |v| format!("{v:.4}")),
                if d.converged {
                    "converged"
                } else {
                    "budget exhausted"
                }
            );
        }
    }
    let cut = stats.worst_limit_dropped(&acc);
    if cut > 1e-6 {
        eprintln!(
            "warning: up to {cut:.1e} of the launched power per tree was cut by --max-depth or --max-segments before the ray series converged; R and T can be off by up to about 2 sqrt({cut:.1e}) = {:.1e} (raise the limits, or model thin layers as a flat [stack])",
            2.0 * cut.sqrt()
        );
    }
    if stats.leaks > 0 {
        eprintln!(
            "warning: {} rays met an interface from the wrong medium (leaky geometry); their power is counted as dropped. Run goniospec check.",
            stats.leaks
        );
    }
    outln!("wrote {}", a.output.display());
    Ok(ExitCode::SUCCESS)
}

fn fit(a: FitArgs) -> Result<ExitCode> {
    use goniospec::fit;
    let acc = Accumulator::read(&a.file)?;
    let with_ext = |ext: &str| {
        let mut p = a.output.clone().into_os_string();
        p.push(ext);
        PathBuf::from(p)
    };
    let (json_path, gltf_path) = (with_ext(".json"), with_ext(".gltf"));
    for p in [&json_path, &gltf_path] {
        guard_output(p, &[a.file.as_path()], OutputKind::Any, false)?;
    }
    let data = fit::Data::from_accumulator(&acc);
    let kind = match a.base {
        FitBase::Auto => fit::BaseKind::Auto,
        FitBase::Dielectric => fit::BaseKind::Dielectric,
        FitBase::Conductor => fit::BaseKind::Conductor,
    };
    let f = fit::fit(&data, kind, !a.no_film);
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
    outln!("rms_reflectance_error: {:.2e}", f.rms_residual);
    for (t, de) in data.theta_i_rad.iter().zip(&f.delta_e2000) {
        outln!("delta_e2000_theta_{:.0}: {de:.2}", t.to_degrees());
    }
    for w in &f.warnings {
        eprintln!("warning: {w}");
    }
    outln!("wrote {} and {}", json_path.display(), gltf_path.display());
    Ok(ExitCode::SUCCESS)
}

/// What kind of file an output may replace without `--force`.
#[derive(Clone, Copy)]
enum OutputKind {
    Gsa,
    Gsb,
    Obj,
    /// Images and JSON: only the same-file and directory checks.
    Any,
}

/// Refuses an output path that is a directory, that is the same file as an input, or (for
/// goniospec's own formats) that holds a file of another kind, unless `force`: an output
/// never destroys an input or an unrelated file (writes are atomic, so a refused run
/// changes nothing).
fn guard_output(
    out: &std::path::Path,
    inputs: &[&std::path::Path],
    kind: OutputKind,
    force: bool,
) -> Result<()> {
    if out.is_dir() {
        bail!("output {} is a directory; give a file name", out.display());
    }
    for i in inputs {
        if same_file(out, i) {
            bail!(
                "output {} is the input {}: refusing to overwrite it",
                out.display(),
                i.display()
            );
        }
    }
    // Before any work: the folder exists and takes a new file.
    goniospec::io::check_writable(out).with_context(|| {
        format!(
            "cannot write {} (does its folder exist, and may you write there?)",
            out.display()
        )
    })?;
    if force || !out.exists() {
        return Ok(());
    }
    let head = {
        use std::io::Read;
        let mut b = [0u8; 32];
        let n = std::fs::File::open(out)
            .and_then(|mut f| f.read(&mut b))
            .with_context(|| format!("reading {}", out.display()))?;
        b[..n].to_vec()
    };
    let (ok, what) = match kind {
        OutputKind::Gsa => (
            head.starts_with(goniospec::accumulate::file::MAGIC),
            "a goniospec accumulator (.gsa)",
        ),
        OutputKind::Gsb => (
            head.starts_with(goniospec::brdf::file::MAGIC),
            "a goniospec BRDF (.gsb)",
        ),
        OutputKind::Obj => (
            head.starts_with(b"# goniospec generate"),
            "an OBJ written by goniospec generate",
        ),
        OutputKind::Any => (true, ""),
    };
    if !ok {
        bail!(
            "refusing to overwrite {}: it is not {what}; remove it, choose another name, or pass --force",
            out.display()
        );
    }
    Ok(())
}

/// Whether two paths name the same existing file.
fn same_file(a: &std::path::Path, b: &std::path::Path) -> bool {
    match (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
        (Ok(x), Ok(y)) => x == y,
        _ => false,
    }
}

fn merge(a: MergeArgs) -> Result<ExitCode> {
    let inputs: Vec<&std::path::Path> = a.inputs.iter().map(|p| p.as_path()).collect();
    guard_output(&a.output, &inputs, OutputKind::Gsa, a.force)?;
    let mut acc = Accumulator::read(&a.inputs[0])?;
    for p in &a.inputs[1..] {
        let other = Accumulator::read(p)?;
        acc.merge(&other)
            .with_context(|| format!("merging {}", p.display()))?;
    }
    acc.write(&a.output)
        .with_context(|| format!("writing {}", a.output.display()))?;
    outln!(
        "wrote {} ({} runs, {} rays per direction)",
        a.output.display(),
        acc.header.seeds.len(),
        acc.header.rays
    );
    Ok(ExitCode::SUCCESS)
}

fn reflectance(a: ReflectanceArgs) -> Result<ExitCode> {
    let acc = Accumulator::read(&a.file)?;
    let s = &acc.header.settings;
    if let Some(p) = a.phi_i
        && (p - s.phi_i_deg).abs() > 1e-9
    {
        bail!(
            "{} was simulated at phi_i = {} deg, not {p}",
            a.file.display(),
            s.phi_i_deg
        );
    }
    let i = s
        .theta_i_deg
        .iter()
        .position(|t| (t - a.theta_i).abs() < 1e-9)
        .with_context(|| {
            format!(
                "{} has no incident angle {} deg (it has {:?})",
                a.file.display(),
                a.theta_i,
                s.theta_i_deg
            )
        })?;
    let mode = s.coherence_mode();
    let buckets = s.buckets();
    outln!("lambda_nm,R,T,absorbed,dropped,R_stderr");
    let mut negative = 0usize;
    for j in 0..s.wavelength_count() {
        let c = acc.cell(i, j);
        let (r, t) = c.totals(mode, &buckets);
        let n = c.trees.max(1) as f64;
        negative += (0..2 * buckets.len())
            .filter(|&k| c.fraction(k, mode) < 0.0)
            .count();
        let se = c
            .r_stderr(mode)
            .map_or_else(|| "NA".to_string(), |v| format!("{v:.6e}"));
        outln!(
            "{},{:.8},{:.8},{:.8},{:.3e},{}",
            s.wavelength(j),
            r,
            t,
            c.absorbed / n,
            c.dropped / n,
            se
        );
    }
    if negative > 0 {
        eprintln!(
            "note: {negative} buckets hold a negative estimate (cross terms); they are kept, not clamped"
        );
    }
    if mode == Coherence::Global {
        eprintln!("note: --coherence global has no per-tree error estimate (R_stderr = NA)");
    }
    Ok(ExitCode::SUCCESS)
}

fn analytic(a: AnalyticArgs) -> Result<ExitCode> {
    if !(0.0..90.0).contains(&a.theta_i) {
        bail!("--theta-i must be in [0, 90) degrees, got {}", a.theta_i);
    }
    use goniospec::optics::tmm;
    let s = sample::load(&a.sample, MeshOptions::default())?;
    if s.stack.is_none() {
        bail!(
            "{} is not written as a [stack]: the analytic reference needs a flat layered sample",
            a.sample.display()
        );
    }
    if !(0.0..90.0).contains(&a.theta_i) {
        bail!("--theta-i must be in [0, 90) degrees");
    }
    let stack_at = |l: f64| -> Result<tmm::StackIndices> {
        tmm::stack_indices(&s, l).map_err(|e| anyhow::anyhow!(e))
    };
    let th = a.theta_i.to_radians();
    outln!("lambda_nm,Rs,Rp,R,Ts,Tp,T");
    let print = |l: f64, rt: tmm::Rt| -> Result<()> {
        outln!(
            "{l},{:.8},{:.8},{:.8},{:.8},{:.8},{:.8}",
            rt.r_s,
            rt.r_p,
            rt.r(),
            rt.t_s,
            rt.t_p,
            rt.t()
        );
        Ok(())
    };
    match a.wavelengths.parse()? {
        Wavelengths::Monochromatic(v) => {
            for l in v {
                print(l, tmm::solve(&stack_at(l)?, l, th))?;
            }
        }
        Wavelengths::Bins(e) => {
            for w in e.windows(2) {
                stack_at(w[0])?;
                stack_at(w[1])?;
                let rt = tmm::solve_band(
                    |l| stack_at(l).expect("range checked at the edges"),
                    w[0],
                    w[1],
                    th,
                );
                print(0.5 * (w[0] + w[1]), rt)?;
            }
        }
    }
    Ok(ExitCode::SUCCESS)
}

fn build(a: BuildArgs) -> Result<ExitCode> {
    use goniospec::brdf::{self, BucketData, Representation};
    guard_output(&a.output, &[a.input.as_path()], OutputKind::Gsb, a.force)?;
    let acc = Accumulator::read(&a.input)?;
    let data = BucketData::from_accumulator(&acc);
    let t0 = std::time::Instant::now();
    let r = match a.repr.as_str() {
        "kdtree" => {
            if a.k == 0 {
                bail!("--k must be at least 1");
            }
            Representation::KdTree(brdf::kdtree::KdTreeBrdf::build(
                &data,
                a.k,
                !a.anisotropic,
                a.reciprocal,
            ))
        }
        "subdivided" => {
            if !(a.tolerance > 0.0 && a.tolerance.is_finite()) {
                bail!("--tolerance must be positive");
            }
            Representation::Subdivided(brdf::subdivided::SubdividedBrdf::build(&data, a.tolerance))
        }
        _ => Representation::Table(brdf::table::TableBrdf::build(&data)),
    };
    let built = t0.elapsed().as_secs_f64();
    brdf::file::write(&r, &a.output).with_context(|| format!("writing {}", a.output.display()))?;
    outln!(
        "wrote {} ({} representation, built in {built:.3} s)",
        a.output.display(),
        a.repr
    );
    Ok(ExitCode::SUCCESS)
}

fn eval(a: EvalArgs) -> Result<ExitCode> {
    use goniospec::brdf::{self, Brdf};
    let r = brdf::file::read(&a.file)?;
    let lambdas = r.meta().wavelengths_nm.clone();
    let d = |t: f64, p: f64| -> Result<[f64; 3]> {
        if !(0.0..=90.0).contains(&t) {
            bail!("polar angles must be in [0, 90] degrees, got {t}");
        }
        Ok(brdf::dir(t.to_radians(), p.to_radians()))
    };
    let mut out = vec![0.0; lambdas.len()];
    match &a.pairs {
        None => {
            let wi = d(a.theta_i.expect("clap requires it"), a.phi_i)?;
            let wo = d(a.theta_o.expect("clap requires it"), a.phi_o)?;
            r.eval(wi, wo, &mut out);
            outln!("lambda_nm,brdf");
            for (l, v) in lambdas.iter().zip(&out) {
                outln!("{l},{v:.8e}");
            }
        }
        Some(p) => {
            let text =
                goniospec::io::read_text(p).with_context(|| format!("reading {}", p.display()))?;
            let mut lines = text
                .lines()
                .enumerate()
                .filter(|(_, l)| !l.trim().is_empty());
            match lines.next() {
                Some((_, h)) if h.replace(' ', "") == "theta_i,phi_i,theta_o,phi_o" => {}
                _ => bail!(
                    "{}: the first line must be the header theta_i,phi_i,theta_o,phi_o",
                    p.display()
                ),
            }
            let mut pairs = Vec::new();
            for (i, l) in lines {
                let v: Vec<f64> = l
                    .split(',')
                    .map(|x| x.trim().parse::<f64>())
                    .collect::<Result<_, _>>()
                    .map_err(|_| {
                        anyhow::anyhow!("{}:{}: not four numbers: '{l}'", p.display(), i + 1)
                    })?;
                if v.len() != 4 {
                    bail!(
                        "{}:{}: expected 4 columns, found {}",
                        p.display(),
                        i + 1,
                        v.len()
                    );
                }
                pairs.push((
                    d(v[0], v[1]).with_context(|| format!("{}:{}", p.display(), i + 1))?,
                    d(v[2], v[3]).with_context(|| format!("{}:{}", p.display(), i + 1))?,
                ));
            }
            let mut all = vec![0.0; pairs.len() * lambdas.len()];
            r.eval_batch(&pairs, &mut all);
            outln!("pair,lambda_nm,brdf");
            for (i, chunk) in all.chunks(lambdas.len()).enumerate() {
                for (l, v) in lambdas.iter().zip(chunk) {
                    outln!("{i},{l},{v:.8e}");
                }
            }
        }
    }
    Ok(ExitCode::SUCCESS)
}

fn render(a: RenderArgs) -> Result<ExitCode> {
    use goniospec::brdf::{self, Brdf};
    use goniospec::render::{self, Env, Light, RenderConfig, Shape};
    if a.width == 0 || a.height == 0 || a.spp == 0 {
        bail!("--width, --height and --spp must be positive");
    }
    let light = Light::parse(&a.light).map_err(anyhow::Error::msg)?;
    let env = Env::parse(&a.env).map_err(anyhow::Error::msg)?;
    let shape = if a.shape == "sphere" {
        Shape::Sphere
    } else if a.shape == "plane" {
        Shape::Plane
    } else {
        let p = PathBuf::from(&a.shape);
        let mesh = sample::load_obj(
            &p,
            1.0,
            MeshOptions {
                drop_degenerate: true,
            },
        )?;
        Shape::mesh(mesh, Backend::default_available())?
    };
    let (centre, radius) = shape.bounds();
    let camera = match a.camera.len() {
        0 => [
            centre[0],
            centre[1] - 4.2 * radius,
            centre[2] + 1.6 * radius,
        ],
        3 => [a.camera[0], a.camera[1], a.camera[2]],
        _ => bail!("--camera needs X,Y,Z"),
    };
    // The output folder is made, and checked writable, before any work.
    if let Some(dir) = a.output.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    {
        let png = a.output.with_extension("png");
        let inputs: Vec<&std::path::Path> = a
            .file
            .iter()
            .chain(a.simulate.iter())
            .map(|p| p.as_path())
            .collect();
        for out in [&a.output, &png] {
            guard_output(out, &inputs, OutputKind::Any, false)?;
        }
    }
    if !(a.fov > 0.0 && a.fov < 180.0) {
        bail!("--fov must be between 0 and 180 degrees, got {}", a.fov);
    }
    if a.light_strength < 0.0 || a.env_strength < 0.0 {
        bail!("--light-strength and --env-strength must not be negative");
    }
    let cfg = RenderConfig {
        width: a.width as usize,
        height: a.height as usize,
        spp: a.spp as usize,
        light,
        light_strength: a.light_strength,
        env,
        env_strength: a.env_strength,
        camera,
        fov_deg: a.fov,
        seed: a.seed,
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(a.threads)
        .build()?;
    let r = match (&a.file, &a.simulate) {
        (Some(f), _) => brdf::file::read(f)?,
        (None, Some(sp)) => pool.install(|| scene_driven(&a, sp, &shape, &cfg))?,
        (None, None) => bail!("give a .gsb file or --simulate SAMPLE.toml"),
    };
    // The image holds RGB and a spectrum per pixel (f32): refuse what cannot fit.
    let bins = r.meta().wavelengths_nm.len() as f64;
    let bytes = f64::from(a.width) * f64::from(a.height) * 4.0 * (3.0 + bins) * 2.0;
    if let Some(avail) = goniospec::io::available_memory_bytes()
        && bytes > avail as f64
    {
        bail!(
            "--width {} x --height {} with {bins} wavelength bins needs about {:.1} GB, more than the {:.1} GB available",
            a.width,
            a.height,
            bytes / 1e9,
            avail as f64 / 1e9
        );
    }
    let t0 = std::time::Instant::now();
    let albedo = if env == Env::Constant {
        Some(pool.install(|| render::albedo_table(&r, 90)))
    } else {
        None
    };
    let bar = indicatif::ProgressBar::new(a.height as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} rows  eta {eta}")
            .expect("a valid template"),
    );
    let img = pool.install(|| {
        render::render(&r, &shape, &cfg, albedo.as_deref(), &|n| {
            bar.set_position(n)
        })
    });
    bar.finish_and_clear();
    let secs = t0.elapsed().as_secs_f64();
    // Both files are written before either replaces an old one.
    let png = a.output.with_extension("png");
    let exr_file = render::stage_exr(&img, &a.output)
        .with_context(|| format!("writing {}", a.output.display()))?;
    let png_file =
        render::stage_png(&img, &png).with_context(|| format!("writing {}", png.display()))?;
    goniospec::io::commit_all(vec![exr_file, png_file])
        .with_context(|| format!("replacing {} and {}", a.output.display(), png.display()))?;
    outln!(
        "rendered {}x{} at {} spp, {} wavelength bins ({} representation) in {secs:.2} s: {} and {}",
        a.width,
        a.height,
        a.spp,
        r.meta().wavelengths_nm.len(),
        r.meta().repr,
        a.output.display(),
        png.display()
    );
    if let Some(sp) = &a.analytic {
        let s = sample::load(sp, MeshOptions::default())?;
        let reference = render::analytic::stack_image(&s, &r.meta().wavelengths_nm, &shape, &cfg)?;
        let apng = a.output.with_file_name(format!(
            "{}-analytic.png",
            a.output.file_stem().unwrap_or_default().to_string_lossy()
        ));
        render::write_png(&reference, &apng)?;
        let d = render::analytic::compare(&img, &reference);
        outln!(
            "against the analytic TMM image ({}): relative RMSE {:.4}, mean CIE DE2000 {:.3} over {} object pixels{}",
            apng.display(),
            d.rel_rmse,
            d.mean_de2000,
            d.pixels,
            if cfg.light != Light::None {
                " (the light's delta reflection is left out of both)"
            } else {
                ""
            }
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// `render --simulate`: simulates the incident angles the image needs (see
/// `goniospec::render::plan`), writes the .gsa and .gsb beside the image, reports the
/// saving against a full-hemisphere simulation, and returns the BRDF table.
fn scene_driven(
    a: &RenderArgs,
    sample_path: &std::path::Path,
    shape: &goniospec::render::Shape,
    cfg: &goniospec::render::RenderConfig,
) -> Result<goniospec::brdf::Representation> {
    use goniospec::brdf::{BucketData, Representation, table::TableBrdf};
    if !(a.tolerance > 0.0 && a.tolerance.is_finite()) {
        bail!("--tolerance must be a positive number, got {}", a.tolerance);
    }
    if a.rays == 0 || a.max_rays < a.rays {
        bail!(
            "--rays must be positive and at most --max-rays (got {} and {})",
            a.rays,
            a.max_rays
        );
    }
    if !(a.theta_step > 0.0 && a.theta_step < 90.0) {
        bail!(
            "--theta-step must lie between 0 and 90 degrees, got {}",
            a.theta_step
        );
    }
    let s = sample::load(sample_path, MeshOptions::default())?;
    let steps = (90.0 / a.theta_step - 1e-9).ceil() as usize;
    let grid: Vec<f64> = (0..steps).map(|k| k as f64 * a.theta_step).collect();
    let plan = goniospec::render::plan::plan(shape, cfg, &grid);
    let needed = plan.needed();
    if needed.is_empty() {
        bail!(
            "the image needs no incident direction: the object is not visible or not lit (check --camera, --light and --env)"
        );
    }
    eprintln!(
        "scene-driven simulation: the image ({} object pixels) needs {} of the {} incident angles of the {}-degree grid: {:?}",
        plan.object_pixels,
        needed.len(),
        grid.len(),
        a.theta_step,
        needed
    );
    let sim = SimConfig {
        seed: a.seed,
        tolerance: Some(a.tolerance),
        max_rays: a.max_rays,
        ..SimConfig::new(needed.clone(), a.wavelengths.parse()?, a.rays)
    };
    let bar = indicatif::ProgressBar::new(a.max_rays * needed.len() as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} trees (at most)  eta {eta}")
            .expect("a valid template"),
    );
    let (acc, stats) = goniospec::simulate::simulate(&s, &sim, &|n| bar.set_position(n))?;
    bar.finish_and_clear();
    let gsa = a.output.with_extension("gsa");
    acc.write(&gsa)
        .with_context(|| format!("writing {}", gsa.display()))?;
    let rep = Representation::Table(TableBrdf::build(&BucketData::from_accumulator(&acc)));
    let gsb = a.output.with_extension("gsb");
    goniospec::brdf::file::write(&rep, &gsb)
        .with_context(|| format!("writing {}", gsb.display()))?;
    let spent: u64 = stats.directions.iter().map(|d| d.rays).sum();
    let worst = stats.directions.iter().map(|d| d.rays).max().unwrap_or(0);
    let converged = stats.directions.iter().filter(|d| d.converged).count();
    for d in &stats.directions {
        eprintln!(
            "  theta_i {:>4.1} deg: {:>6} trees, achieved {} ({})",
            d.theta_i_deg,
            d.rays,
            d.achieved.map_or("n/a".to_string(), |e| format!("{e:.4}")),
            if d.converged {
                "converged"
            } else {
                "budget exhausted"
            }
        );
    }
    // A full-hemisphere run with one fixed budget must give every grid angle at least what
    // the hardest needed angle took: a lower bound on its cost.
    let full = worst * grid.len() as u64;
    eprintln!(
        "simulated {} trees in {:.2} s ({} of {} directions converged to {}); a full-hemisphere simulation giving each of its directions the largest budget used here needs at least {} x {} = {} trees: {:.0} % saved ({:.0} % by skipping directions, the rest by adaptive budgets). Wrote {} and {}",
        spent,
        stats.seconds,
        converged,
        needed.len(),
        a.tolerance,
        grid.len(),
        worst,
        full,
        100.0 * (1.0 - spent as f64 / full.max(1) as f64),
        100.0 * (1.0 - needed.len() as f64 / grid.len() as f64),
        gsa.display(),
        gsb.display()
    );
    Ok(rep)
}

fn study(a: StudyArgs) -> Result<ExitCode> {
    let st = goniospec::study::load(&a.study).map_err(|e| anyhow::anyhow!(e))?;
    let (points, reference) =
        goniospec::study::run(&st, |l| eprintln!("{l}")).map_err(|e| anyhow::anyhow!(e))?;
    goniospec::study::write(&st, &points, &reference, &a.output)
        .with_context(|| format!("writing into {}", a.output.display()))?;
    let mut charts = goniospec::study::charts(&points, &a.output)
        .map_err(|e| anyhow::anyhow!("drawing the charts: {e}"))?;
    let area =
        goniospec::study::run_area(&st, |l| eprintln!("{l}")).map_err(|e| anyhow::anyhow!(e))?;
    charts.extend(
        goniospec::study::write_area(&area, &a.output)
            .map_err(|e| anyhow::anyhow!("sampled-area chart: {e}"))?,
    );
    for c in &charts {
        outln!("wrote {}", c.display());
    }
    outln!(
        "wrote {} and {} ({} points)",
        a.output.join("points.csv").display(),
        a.output.join("report.md").display(),
        points.len()
    );
    Ok(ExitCode::SUCCESS)
}

fn info(a: InfoArgs) -> Result<ExitCode> {
    use goniospec::brdf::{self, Brdf};
    let head = {
        use std::io::Read;
        let mut f = std::fs::File::open(&a.file)
            .with_context(|| format!("opening {}", a.file.display()))?;
        let mut b = [0u8; 8];
        f.read_exact(&mut b).ok();
        b
    };
    if &head == goniospec::accumulate::file::MAGIC {
        let acc = Accumulator::read(&a.file)?;
        let h = &acc.header;
        outln!("{}: goniospec accumulator (.gsa)", a.file.display());
        outln!(
            "sample: '{}' (hash {})",
            h.settings.sample_name,
            h.settings.sample_hash
        );
        outln!(
            "incident angles (deg): {:?}, phi_i {} deg",
            h.settings.theta_i_deg,
            h.settings.phi_i_deg
        );
        outln!(
            "wavelengths: {} {} ({}..{} nm)",
            h.settings.wavelength_count(),
            h.settings.wavelength_mode,
            h.settings.wavelengths_nm.first().unwrap_or(&0.0),
            h.settings.wavelengths_nm.last().unwrap_or(&0.0)
        );
        outln!(
            "estimator: {}, coherence radius {} nm, cutoff {:e}, max depth {}",
            h.settings.coherence,
            h.settings.coherence_radius_nm,
            h.settings.cutoff,
            h.settings.max_depth
        );
        outln!(
            "buckets: {} x {} per hemisphere",
            h.settings.theta_o_bins,
            h.settings.phi_o_bins
        );
        outln!(
            "rays per direction: {:?} (seeds {:?}), backend {}, path sharing {}, leaks {}",
            h.rays_per_direction,
            h.seeds,
            h.backend,
            h.settings.path_sharing,
            h.leaks
        );
        let st = &h.settings;
        outln!(
            "limits: cutoff {:e}, max depth {}, max wraps {}, max segments {}; entry points {}{}",
            st.cutoff,
            st.max_depth,
            st.max_wraps,
            st.max_segments,
            st.entry_points,
            match (st.tolerance, st.max_rays) {
                (Some(t), Some(m)) => format!("; adaptive to {t} relative error, at most {m} rays"),
                _ => String::new(),
            }
        );
    } else if &head == brdf::file::MAGIC {
        let r = brdf::file::read(&a.file)?;
        let m = r.meta();
        outln!(
            "{}: goniospec BRDF (.gsb), representation {}",
            a.file.display(),
            m.repr
        );
        outln!("sample: '{}' (hash {})", m.sample_name, m.sample_hash);
        outln!(
            "wavelengths: {} ({}..{} nm)",
            m.wavelengths_nm.len(),
            m.wavelengths_nm.first().unwrap_or(&0.0),
            m.wavelengths_nm.last().unwrap_or(&0.0)
        );
        outln!(
            "isotropic {}, reciprocal {}, median relative stderr of the buckets {}",
            m.isotropic,
            m.reciprocal,
            m.median_rel_stderr
                .map_or("unknown".to_string(), |v| format!("{v:.3}"))
        );
        match &r {
            brdf::Representation::KdTree(k) => {
                outln!("kd-tree: {} points, k = {}", k.points.len(), k.k)
            }
            brdf::Representation::Table(t) => outln!(
                "table: {} incident angles x {} x {}",
                t.theta_i.len(),
                t.theta_bins,
                t.phi_bins
            ),
            brdf::Representation::Subdivided(s) => outln!(
                "subdivided: {} incident angles, {} leaves, tolerance {}",
                s.theta_i.len(),
                (0..s.theta_i.len())
                    .map(|i| s.leaves(i).count())
                    .sum::<usize>(),
                s.tolerance
            ),
        }
    } else {
        bail!(
            "{}: neither a .gsa nor a .gsb file (unknown magic bytes)",
            a.file.display()
        );
    }
    Ok(ExitCode::SUCCESS)
}

fn generate(a: GenerateArgs) -> Result<ExitCode> {
    use goniospec::sample::generate::{Generated, GeneratorSpec};
    guard_output(&a.output, &[], OutputKind::Obj, a.force)?;
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
            outln!(
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
            outln!(
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
                outln!(
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

fn bench_eval(a: EvalBenchArgs) -> Result<ExitCode> {
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
    bench::eval_bench(Some((&low, &high)), emit);
    Ok(ExitCode::SUCCESS)
}

fn bench_simulate(a: SimBenchArgs) -> Result<ExitCode> {
    let s = sample::load(&a.sample, MeshOptions::default())?;
    let flat = sample::load(&a.flat, MeshOptions::default())?;
    let cfg = bench::SimulateBenchConfig {
        rays: a.rays,
        theta_i_deg: a.theta_i,
        bins: (0..=40).map(|i| 380.0 + 10.0 * i as f64).collect(),
        backends: Backend::ALL
            .into_iter()
            .filter(|b| b.is_available())
            .collect(),
        seed: 1,
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(a.threads)
        .build()?;
    pool.install(|| bench::simulate_bench(&s, &flat, &cfg, emit))?;
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
fn peak_memory_of(summary: &str) -> Option<f64> {
    let rest = &summary[summary.find("peak memory ")? + "peak memory ".len()..];
    rest.split_whitespace().next()?.parse().ok()
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
    let cfg = bench::TraceBenchConfig {
        rays: a.rays,
        threads: a.threads.clone(),
        backends,
        seed: a.seed,
    };
    let report = bench::trace_bench(&mesh, &cfg, emit)?;
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
