//! `goniospec hiding`: a paint's hiding thickness over a black-and-white contrast chart and
//! its reflectance at complete hiding, per pigment volume fraction.

use super::{Args, ExitCode, PathBuf, Result, Wavelengths, bail, finite, thread_pool};
use goniospec::study::hiding::{HidingConfig, hiding as find_hiding};

#[derive(Args)]
pub(super) struct HidingArgs {
    /// The paint: a sample whose [stack] has one scattering layer (particles or
    /// henyey_greenstein); what lies below it is replaced by the chart.
    sample: PathBuf,
    /// Pigment volume fractions to compare (comma-separated; default: the sample's own).
    #[arg(long, value_parser = finite, value_delimiter = ',')]
    volume_fraction: Vec<f64>,
    /// The contrast ratio Y_black / Y_white that counts as hiding (ISO 6504-3: 0.98).
    #[arg(long, value_parser = finite, default_value_t = 0.98)]
    contrast: f64,
    /// Incident polar angle, degrees (8: a d/8 instrument's specular-included reading).
    #[arg(long, value_parser = finite, default_value_t = 8.0)]
    theta_i: f64,
    /// Trees per backing at each thickness the search tries (split over 16 replicate
    /// seeds, whose spread gives the errors).
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u64).range(16..))]
    rays: u64,
    /// The relative standard error of the hiding thickness to reach: the thickness found
    /// is run again with the trees its error asks for (0: stop at the search's own).
    #[arg(long, value_parser = finite, default_value_t = 0.05)]
    target_stderr: f64,
    /// The most trees per backing the found thickness may take to reach --target-stderr.
    #[arg(long, default_value_t = 65536, value_parser = clap::value_parser!(u64).range(16..))]
    max_rays: u64,
    /// Wavelength bins, nm (A:B:STEP or a comma list of edges); Y is weighted over them.
    #[arg(long, default_value = "400:700:20")]
    wavelengths: String,
    /// Seed of every run (the two backings share it).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Worker threads (0: all cores).
    #[arg(long, default_value_t = 0)]
    threads: usize,
}

pub(super) fn hiding(a: HidingArgs) -> Result<ExitCode> {
    if !(a.contrast > 0.0 && a.contrast < 1.0) {
        bail!(
            "--contrast must lie strictly between 0 and 1, got {}",
            a.contrast
        );
    }
    if !(0.0..90.0).contains(&a.theta_i) {
        bail!("--theta-i must lie in [0, 90) degrees, got {}", a.theta_i);
    }
    if !(0.0..1.0).contains(&a.target_stderr) {
        bail!(
            "--target-stderr is a relative error in [0, 1), got {}",
            a.target_stderr
        );
    }
    let Wavelengths::Bins(edges) = Wavelengths::parse(&a.wavelengths, false)? else {
        bail!("--wavelengths must give bins");
    };
    let text = goniospec::io::read_text(&a.sample)
        .map_err(|e| anyhow::anyhow!("{}: {e}", a.sample.display()))?;
    let fractions: Vec<Option<f64>> = if a.volume_fraction.is_empty() {
        vec![None]
    } else {
        a.volume_fraction.iter().map(|&f| Some(f)).collect()
    };
    let pool = thread_pool(a.threads)?;
    outln!(
        "# hiding of {} over a black and white chart: Y (CIE 1931, D65) over {} to {} nm at {} deg, hiding at contrast ratio {}; {} trees per backing in the search, then {}",
        a.sample.display(),
        edges[0],
        edges[edges.len() - 1],
        a.theta_i,
        a.contrast,
        a.rays,
        if a.target_stderr > 0.0 {
            format!(
                "as many as a {} relative standard error of the thickness asks (at most {})",
                a.target_stderr, a.max_rays
            )
        } else {
            "no more".to_string()
        }
    );
    outln!(
        "volume_fraction,white_backing_Y,hiding_um,hiding_um_stderr,R_inf_Y,R_inf_halfwidth,spreading_m2_per_L,pigment_m2_per_L,trees_per_backing,seconds"
    );
    for f in fractions {
        let cfg = HidingConfig {
            theta_i_deg: a.theta_i,
            rays: a.rays,
            goal: (a.target_stderr > 0.0).then_some(a.target_stderr),
            max_rays: a.max_rays.max(a.rays),
            edges: edges.clone(),
            seed: a.seed,
            contrast: a.contrast,
            volume_fraction: f,
        };
        let label = f.map_or_else(
            || "the sample's own fraction".into(),
            |f| format!("volume fraction {f}"),
        );
        eprintln!("{label}:");
        let started = std::time::Instant::now();
        let h = pool
            .install(|| find_hiding(&a.sample, &text, &cfg, &|l| eprintln!("  {l}")))
            .map_err(|e| anyhow::anyhow!(e))?;
        let (t, se) = h.thickness_um;
        let (r_inf, half) = h.r_infinity();
        let spreading = 1000.0 / t;
        let per_pigment = h
            .volume_fraction
            .map_or_else(|| "".into(), |f| format!("{:.1}", spreading / f));
        let seconds = started.elapsed().as_secs_f64();
        eprintln!(
            "  hiding at {t:.1} +- {se:.1} um ({:.1} %), R-infinity {r_inf:.4} +- {half:.4}; {} trees in all, {seconds:.1} s",
            100.0 * se / t,
            h.total_trees
        );
        outln!(
            "{},{:.4},{t:.2},{se:.2},{r_inf:.4},{half:.4},{spreading:.2},{per_pigment},{},{seconds:.1}",
            h.volume_fraction
                .map_or_else(|| "".into(), |f| f.to_string()),
            h.white_backing.0,
            h.trees
        );
    }
    Ok(ExitCode::SUCCESS)
}
