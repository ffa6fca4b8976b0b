//! `goniospec bench measured`: reading and evaluating measured RGL materials, and
//! `compare` at all of a measurement's incident angles.

use std::time::Instant;

use super::super::{Args, ExitCode, MeshOptions, PathBuf, Result, SimConfig, Wavelengths, emit};
use super::super::{sample, thread_pool};

#[derive(Args)]
pub(crate) struct MeasuredBenchArgs {
    /// Measured files (RGL .bsdf). (A relative path missing from the working directory is
    /// taken from the goniospec checkout this binary was built from.)
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "data/measured/paper_white_rgb.bsdf,data/measured/colodur_napoli_4f_rgb.bsdf,data/measured/cc_ibiza_sunset_rgb.bsdf"
    )]
    files: Vec<PathBuf>,
    /// Random direction pairs for the evaluation figure.
    #[arg(long, default_value_t = 1_000_000, value_parser = clap::value_parser!(u64).range(1..=100_000_000))]
    pairs: u64,
    /// Worker threads (0: all cores).
    #[arg(long, default_value_t = 0)]
    threads: usize,
}

/// `bench measured`: the figures of issue 72's goals (eval of 10^6 pairs under 1 s,
/// compare of a table against a measurement at all its angles under 2 s).
pub(crate) fn bench_measured(a: MeasuredBenchArgs) -> Result<ExitCode> {
    use goniospec::compare::{self, Material};
    use goniospec::export::measured::MeasuredBrdf;
    if a.files.len() < 2 {
        anyhow::bail!("--files needs at least two measured files (the comparison uses two)");
    }
    let pool = thread_pool(a.threads)?;
    emit(&format!("threads: {} 1", pool.current_num_threads()));
    let files: Vec<PathBuf> = a
        .files
        .iter()
        .map(|f| goniospec::bench::shipped(f))
        .collect();
    for f in &files {
        let t0 = Instant::now();
        MeasuredBrdf::read(f)?;
        let name = f
            .file_stem()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        emit(&format!(
            "measured_read_{name}_s: {:.4} s",
            t0.elapsed().as_secs_f64()
        ));
    }
    let m = MeasuredBrdf::read(&files[0])?;
    let n = a.pairs as usize;
    let mut rng = goniospec::rng::Rng::new(72, 0);
    let mut dir = || {
        let (z, phi) = (rng.uniform(), std::f64::consts::TAU * rng.uniform());
        let r = (1.0 - z * z).max(0.0).sqrt();
        glam::DVec3::new(r * phi.cos(), r * phi.sin(), z)
    };
    let pairs: Vec<(glam::DVec3, glam::DVec3)> = (0..n).map(|_| (dir(), dir())).collect();
    let mut out = vec![0.0; n * goniospec::brdf::Brdf::meta(&m).lambda_nm.len()];
    let t0 = Instant::now();
    pool.install(|| goniospec::brdf::Brdf::eval_batch(&m, &pairs, &mut out));
    let secs = t0.elapsed().as_secs_f64();
    emit(&format!("measured_eval_pairs: {n} 1"));
    emit(&format!("measured_eval_s: {secs:.4} s"));
    emit(&format!(
        "measured_eval_ns_per_pair: {:.1} ns",
        secs * 1e9 / n as f64
    ));
    // Two measurements.
    let (ma, mb) = (Material::read(&files[0])?, Material::read(&files[1])?);
    let t0 = Instant::now();
    let r = pool.install(|| compare::compare(&ma, &mb, ["a", "b"]))?;
    emit(&format!(
        "compare_measured_vs_measured_s: {:.4} s",
        t0.elapsed().as_secs_f64()
    ));
    emit(&format!(
        "compare_measured_vs_measured_angles: {} 1",
        r.angles.len()
    ));
    // A simulated table (not timed) against the first measurement.
    eprintln!("simulating rough gold at 0 to 80 degrees (not timed)");
    let s = sample::load(
        &goniospec::bench::shipped(std::path::Path::new("meshes/rough-gold.toml")),
        MeshOptions::default(),
    )?;
    let cfg = SimConfig::new(
        (0..=8).map(|k| 10.0 * f64::from(k)).collect(),
        Wavelengths::parse(goniospec::spectrum::DEFAULT_WAVELENGTHS, false)?,
        64,
    );
    let (acc, _) = pool.install(|| goniospec::simulate::simulate(&s, &cfg, &|_| {}))?;
    let tmp = std::env::temp_dir().join(format!("goniospec-bench-measured-{}", std::process::id()));
    std::fs::create_dir_all(&tmp)?;
    let gsa = tmp.join("gold.gsa");
    acc.write(&gsa)?;
    let t0 = Instant::now();
    let table = Material::read(&gsa)?;
    let read = t0.elapsed().as_secs_f64();
    let t0 = Instant::now();
    let r = pool.install(|| compare::compare(&table, &ma, ["gold", "measured"]))?;
    let figures = t0.elapsed().as_secs_f64();
    emit(&format!(
        "compare_table_vs_measured_read_gsa_s: {read:.4} s"
    ));
    emit(&format!("compare_table_vs_measured_s: {figures:.4} s"));
    emit(&format!(
        "compare_table_vs_measured_angles: {} 1",
        r.angles.len()
    ));
    let t0 = Instant::now();
    pool.install(|| compare::write_outputs(&r, &table, &ma, &tmp.join("out")))?;
    emit(&format!(
        "compare_table_vs_measured_files_s: {:.4} s",
        t0.elapsed().as_secs_f64()
    ));
    let _ = std::fs::remove_dir_all(&tmp);
    Ok(ExitCode::SUCCESS)
}
