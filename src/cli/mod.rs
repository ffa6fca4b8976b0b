//! The command line: argument types and one file per command. Shared here: the
//! top-level parser, value parsers, output guards and the `outln!` macro.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand};

use goniospec::accel::{self, Backend};
use goniospec::accumulate::file::Accumulator;
use goniospec::accumulate::{Buckets, Coherence};
use goniospec::sample::{self, MeshOptions};
use goniospec::simulate::{SimConfig, Wavelengths};

/// A virtual goniospectrometer: trace a microgeometry sample (thin films, coatings,
/// pigments, flakes, rough surfaces) with coherent spectral ray optics and turn it into a
/// measured-like BRDF.
///
/// Lengths are in nanometres unless a sample declares otherwise; angles on the command
/// line are in degrees.
#[derive(Parser)]
#[command(name = "goniospec", version, propagate_version = true)]
pub(crate) struct Cli {
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
    /// Describe a .gsa, .gsb or .bsdf (RGL tensor) file: a measured material's incident
    /// angles, grids and form.
    Info(InfoArgs),
    /// Compare two materials, a simulation beside a measurement or any two BRDFs (.gsb,
    /// .gsa, or an RGL .bsdf, measured or exported): CIEDE2000 of the reflected colour per
    /// incident angle over the lit directions, lobe peaks and widths, flop index and colour
    /// travel, on the measurement's own angles and directions; with -o, CSV, JSON and a
    /// picture (docs/measured.md).
    ///
    /// Example: goniospec compare paint.gsb data/measured/colodur_napoli_4f_rgb.bsdf -o out/cmp
    #[command(verbatim_doc_comment)]
    Compare(CompareArgs),
    /// Export a built BRDF for other tools: an RGL tensor file (.bsdf) that Mitsuba 3's and
    /// pbrt-v4's `measured` material load (the RGL parameterisation warps the tabulation
    /// by the sample's microfacet distribution, taken from --sample), or a NumPy archive.
    ///
    /// Example: goniospec export film.gsb --sample meshes/thin-film-600nm.toml -o film.bsdf
    ///          goniospec export film.gsb --format npz -o film.npz
    ///   then, in Python: import mitsuba as mi; mi.set_variant('scalar_spectral')
    ///                    bsdf = mi.load_dict({'type': 'measured', 'filename': 'film.bsdf'})
    #[command(verbatim_doc_comment)]
    Export(ExportArgs),
    /// Draw a built BRDF for one incident direction: its lobe in the plane of incidence
    /// (f cos theta_o, polar, one curve per few wavelengths) and the reflected colour
    /// under D65 over the projected hemisphere, as PNG or SVG.
    ///
    /// Example: goniospec plot film.gsb --theta-i 30 -o lobe.png
    #[command(verbatim_doc_comment)]
    Plot(PlotArgs),
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
    /// Find the recipe that reproduces a measured material: the values of the template
    /// sample's own parameters (a coat's thickness, a roughness, a pigment's amount), named
    /// by their TOML paths, whose simulation is closest to the measurement by compare's
    /// mean CIEDE2000 at the fitted incident angles. Nelder-Mead (argmin) over the ranges,
    /// every candidate simulated with the same seed and trees (common random numbers); the
    /// best is simulated at every measured angle and compared, fitted and held-out angles
    /// apart. A rerun after an interruption resumes from the candidates' records.
    ///
    /// Example (the shipped wrap film's recipe, materials/; scripts/match-materials.sh):
    ///   goniospec match materials/templates/wrap-film.toml
    ///     --measured data/measured/cc_ibiza_sunset_rgb.bsdf
    ///     --vary interface.0.generator.alpha=0.03:0.4:log
    ///     --vary interface.0.coating.0.thickness=0.1:1.2 -o out/wrap
    #[command(name = "match", verbatim_doc_comment)]
    Match(MatchArgs),
    /// Mie scattering of one sphere in a host medium: extinction, scattering and
    /// absorption efficiencies (Q = C / (pi r^2)), single-scattering albedo, asymmetry g,
    /// and the amplitude functions S1, S2 at --mu (Bohren & Huffman's conventions).
    ///
    /// Example: goniospec mie --n 2.6 --host 1.5 --radius-nm 120 --wavelength-nm 550 --mu=-1,0,1
    Mie(MieArgs),
    /// Hiding power of a paint: the film thickness that hides a black-and-white contrast
    /// chart (contrast ratio Y_black / Y_white of 0.98, ISO 6504-3), its luminous
    /// reflectance at complete hiding (R-infinity) and the area a litre covers, per pigment
    /// volume fraction. Each thickness is two runs (the chart's black and white halves,
    /// index-matched to the binder, sharing their random numbers); the search brackets the
    /// thickness and interpolates log(1 - contrast). Prints CSV; progress on stderr.
    ///
    /// Example: goniospec hiding meshes/paint-pigments.toml --volume-fraction 0.1,0.2,0.3
    Hiding(HidingArgs),
    /// Batch BRDF generation: plan many materials, run the units in shards (Slurm job
    /// arrays or GNU parallel), resume, and merge bit for bit.
    ///
    /// Example: goniospec batch plan plan.toml -o lib && goniospec batch slurm lib
    ///          bash lib/submit.sh        (or: goniospec batch run lib; goniospec batch merge lib)
    #[command(subcommand, verbatim_doc_comment)]
    Batch(BatchCommand),
    /// Benchmarks; each prints its figures.
    #[command(subcommand)]
    Bench(BenchCommand),
}

/// Wavelength sampling on the command line.
#[derive(Args, Clone, Debug)]
struct WavelengthArgs {
    /// Wavelengths, nm: A:B:STEP gives bins of width STEP from A to B (or, with
    /// --monochromatic, the wavelengths A, A+STEP, ..., B); a comma list gives bin edges
    /// (or exact wavelengths with --monochromatic).
    #[arg(long, default_value = goniospec::spectrum::DEFAULT_WAVELENGTHS)]
    wavelengths: String,
    /// Use the exact wavelengths instead of jittered bins.
    #[arg(long)]
    monochromatic: bool,
}

impl WavelengthArgs {
    fn parse(&self) -> Result<Wavelengths> {
        Wavelengths::parse(&self.wavelengths, self.monochromatic)
            .map_err(|e| anyhow::anyhow!("--wavelengths: {e}"))
    }
}

// The value parsers of settings live with the settings (`goniospec::simulate`), so every
// front end refuses the same values with the same words.
use goniospec::simulate::{backend as parse_backend, finite, radius as parse_radius};

/// Reads a `.gsa` for a command that uses its results: held to the physics its run was
/// held to before writing (`simulate::check_file`), so a file changed and resealed is
/// refused with the reason; one written with --allow-unphysical is read with a warning.
fn read_accumulator(path: &std::path::Path) -> Result<Accumulator> {
    let (acc, warning) = goniospec::simulate::read_judged(path)?;
    if let Some(w) = warning {
        eprintln!("warning: {w}");
    }
    Ok(acc)
}

/// A finite, strictly positive number (for tolerances and scales).
fn positive(s: &str) -> Result<f64, String> {
    let v = finite(s).map_err(|e| e.to_string())?;
    if v > 0.0 {
        Ok(v)
    } else {
        Err(format!("{v} must be positive"))
    }
}

/// `println!` that returns an error instead of panicking when standard output fails (a full
/// disk, a file closed for writing): the command ends with a clear message and exit status 1.
/// (A closed pipe ends it quietly: see `main`.)
macro_rules! outln {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        anyhow::Context::context(writeln!(std::io::stdout().lock(), $($t)*), "writing to standard output")?
    }};
}

mod analytic;
mod batch;
mod bench;
mod build;
mod check;
mod compare;
mod eval;
mod export;
mod fit;
mod generate;
mod hiding;
mod info;
mod matching;
mod merge;
mod mie;
mod plot;
mod reflectance;
mod render;
mod simulate;
mod study;

use analytic::{AnalyticArgs, analytic};
use batch::{BatchCommand, batch};
use bench::{
    BenchCommand, bench_converge, bench_eval, bench_large, bench_measured, bench_paints,
    bench_peer, bench_rigorous, bench_simulate, bench_trace,
};
use build::{BuildArgs, build};
use check::{CheckArgs, check};
use compare::{CompareArgs, compare};
use eval::{EvalArgs, eval};
use export::{ExportArgs, export};
use fit::{FitArgs, fit};
use generate::{GenerateArgs, generate};
use hiding::{HidingArgs, hiding};
use info::{InfoArgs, backends, info};
use matching::{MatchArgs, run_match};
use merge::{MergeArgs, merge};
use mie::{MieArgs, mie};
use plot::{PlotArgs, plot};
use reflectance::{ReflectanceArgs, reflectance};
use render::{RenderArgs, render};
use simulate::{SimulateArgs, simulate};
use study::{StudyArgs, study};

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
pub(crate) fn broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

impl Cli {
    /// Parses the process's arguments (exiting with clap's usage error, status 2, on bad
    /// usage). Negative numbers are values, not flags: `--phi-i -30`, `--theta-i -30,0`,
    /// `mie --x -1` reach the value parsers, whose range errors name the value (issue 47:
    /// they failed as "unexpected argument '-3'").
    pub(crate) fn parse_args() -> Cli {
        use clap::{CommandFactory, FromArgMatches};
        let matches = negative_numbers_are_values(Cli::command()).get_matches();
        Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit())
    }
}

/// `cmd` and its subcommands with every option's negative numbers taken as values, and a
/// comma list's leading `-` too (clap sees `-30,0` as a flag, not a number).
fn negative_numbers_are_values(cmd: clap::Command) -> clap::Command {
    cmd.allow_negative_numbers(true)
        .mut_args(|a| {
            if a.get_value_delimiter() == Some(',') {
                a.allow_hyphen_values(true)
            } else {
                a
            }
        })
        .mut_subcommands(negative_numbers_are_values)
}

pub(crate) fn run(cli: Cli) -> Result<ExitCode> {
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
        Command::Compare(a) => compare(a),
        Command::Export(a) => export(a),
        Command::Plot(a) => plot(a),
        Command::Batch(c) => batch(c),
        Command::Render(a) => render(a),
        Command::Study(a) => study(a),
        Command::Generate(a) => generate(a),
        Command::Fit(a) => fit(a),
        Command::Match(a) => run_match(a),
        Command::Mie(a) => mie(a),
        Command::Hiding(a) => hiding(a),
        Command::Bench(BenchCommand::Trace(a)) => bench_trace(a),
        Command::Bench(BenchCommand::Simulate(a)) => bench_simulate(a),
        Command::Bench(BenchCommand::Eval(a)) => bench_eval(a),
        Command::Bench(BenchCommand::Large(a)) => bench_large(a),
        Command::Bench(BenchCommand::Paints(a)) => bench_paints(a),
        Command::Bench(BenchCommand::Converge(a)) => bench_converge(a),
        Command::Bench(BenchCommand::Peer(a)) => bench_peer(a),
        Command::Bench(BenchCommand::Rigorous(a)) => bench_rigorous(a),
        Command::Bench(BenchCommand::Measured(a)) => bench_measured(a),
    }
}

use goniospec::output::OutputKind;

/// The output policy (`goniospec::output::guard`) as a command's error.
fn guard_output(
    out: &std::path::Path,
    inputs: &[&std::path::Path],
    kind: OutputKind,
    force: bool,
) -> Result<()> {
    Ok(goniospec::output::guard(out, inputs, kind, force)?)
}

/// The worker pool of a command: `threads` workers (0: one per core), at most
/// [`MAX_THREADS`]; the one set-up every command uses.
fn thread_pool(threads: usize) -> Result<rayon::ThreadPool> {
    goniospec::simulate::thread_pool(threads).map_err(flag_error)
}

/// A simulation error for the command line: a setting's error names its flag
/// (`theta_o_bins` is `--theta-o-bins`).
fn flag_error(e: goniospec::simulate::SimError) -> anyhow::Error {
    match e {
        goniospec::simulate::SimError::Setting { key, message } => {
            anyhow::anyhow!("--{}: {message}", key.replace('_', "-"))
        }
        e => e.into(),
    }
}

/// The progress bar of a long run: `len` units of `what` (trees, rows), with rate and
/// time left, on standard error. On a terminal it redraws twice a second, so a step that
/// takes long still shows its elapsed time; elsewhere (a log, a pipe, a batch node), where
/// indicatif draws nothing, a line every [`PROGRESS_LINE_SECONDS`] says how far the run is
/// (issue 47: `export`, `fit`, `batch report` and `batch run` were silent for tens of
/// seconds).
fn progress_bar(len: u64, what: &str) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(len);
    bar.set_style(
        indicatif::ProgressStyle::with_template(&format!(
            "{{bar:40}} {{pos}}/{{len}} {what}  {{per_sec}}  eta {{eta}}  ({{elapsed}}){{msg}}"
        ))
        .expect("a valid template"),
    );
    keep_alive(&bar, what);
    bar
}

/// A bar for a run of one step whose progress is not counted (a fit, a tabulation): its
/// elapsed time, as [`progress_bar`] shows it.
fn progress_spinner(what: &str) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new_spinner();
    bar.set_style(
        indicatif::ProgressStyle::with_template(&format!("{{spinner}} {what}  ({{elapsed}})"))
            .expect("a valid template"),
    );
    keep_alive(&bar, what);
    bar
}

/// Seconds between the progress lines written where standard error is not a terminal.
const PROGRESS_LINE_SECONDS: u64 = 5;

/// Redraws `bar` on a terminal; elsewhere writes a progress line every
/// [`PROGRESS_LINE_SECONDS`] until it is finished.
fn keep_alive(bar: &indicatif::ProgressBar, what: &str) {
    use std::io::IsTerminal;
    if std::io::stderr().is_terminal() {
        bar.enable_steady_tick(std::time::Duration::from_millis(500));
        return;
    }
    let (bar, what) = (bar.clone(), what.to_string());
    std::thread::spawn(move || {
        let t0 = std::time::Instant::now();
        loop {
            std::thread::sleep(std::time::Duration::from_secs(PROGRESS_LINE_SECONDS));
            if bar.is_finished() {
                break;
            }
            let done = match bar.length() {
                Some(n) => format!(": {} of {n}", bar.position()),
                None => String::new(),
            };
            eprintln!(
                "progress: {what}{done}, {:.0} s so far{}",
                t0.elapsed().as_secs_f64(),
                bar.message()
            );
        }
    });
}

/// A BRDF named on the command line: a built `.gsb`, or an RGL `.bsdf` (a material of the
/// RGL database, measured, or one goniospec exported), told apart by their magic bytes.
struct Material(Box<dyn goniospec::brdf::Brdf + Sync>);

impl Material {
    fn open(path: &std::path::Path) -> Result<Material> {
        use std::io::Read;
        let mut head = [0u8; 12];
        std::fs::File::open(path)
            .and_then(|mut f| f.read(&mut head))
            .with_context(|| format!("opening {}", path.display()))?;
        Ok(Material(
            if goniospec::export::tensor::is_tensor_file(&head) {
                Box::new(goniospec::export::measured::MeasuredBrdf::read(path)?)
            } else if head[..8] == goniospec::accumulate::file::MAGIC[..] {
                bail!(
                    "{}: an accumulator (.gsa), whose buckets are not yet a BRDF: make one with `goniospec build {} -o FILE.gsb` (eval --mueller reads a .gsa's Mueller matrices directly)",
                    path.display(),
                    path.display()
                )
            } else {
                Box::new(goniospec::brdf::file::read(path)?)
            },
        ))
    }

    fn brdf(&self) -> &(dyn goniospec::brdf::Brdf + Sync) {
        self.0.as_ref()
    }

    /// Whether the channels are linear sRGB (an RGB `.bsdf`), not wavelength bins.
    fn is_rgb(&self) -> bool {
        self.0.meta().rgb
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
