//! What a run refuses before tracing: methods the sample cannot take, wavelengths outside
//! a medium's range, an absorbing or dispersive ambient medium, and diffraction runs too
//! large for memory.

use super::{DIFFRACTION_MAX_BYTES, SimConfig, SimError};
use crate::accumulate::{Coherence, diffraction};
use crate::optics::C64;
use crate::sample::Sample;
use crate::trace::Scene;

/// The media's indices at `lambda_nm`.
fn index_at(sample: &Sample, lambda_nm: f64) -> Vec<C64> {
    let mut v = Vec::new();
    sample.indices_into(lambda_nm, &mut v);
    v
}

/// The methods a sample cannot take: particle media (`scattering`) need the beamlet
/// estimator and per-wavelength paths; the diffraction method needs a periodic tile of
/// deterministic ray fields and a fixed budget.
pub(super) fn method_refusals(
    sample: &Sample,
    cfg: &SimConfig,
    scattering: bool,
) -> Result<(), SimError> {
    rigorous_refusals(sample, cfg)?;
    // Particle media: properties change with the wavelength and free paths are random,
    // so every wavelength is traced on its own; scattered light has random phases, so
    // only the beamlet estimator (which pairs exits of one coherence group) applies.
    if scattering {
        if !matches!(cfg.coherence, Coherence::Beamlet | Coherence::Auto) {
            return Err(SimError::Config(format!(
                "--coherence {} sums the fields of every path in a bucket, but light scattered by this sample's particle media has random phases; use --coherence auto (the default) or beamlet",
                cfg.coherence
            )));
        }
        if cfg.path_sharing == Some(true) {
            return Err(SimError::Config(
                "path sharing needs wavelength-independent paths: this sample has scattering media, whose free paths and directions are drawn per wavelength".into(),
            ));
        }
    }
    if cfg.coherence == Coherence::Diffraction {
        if sample.guard_nm.is_some() {
            return Err(SimError::Config(
                "--coherence diffraction takes the far field of a periodic tile, but this sample's sides are open (a guard band): give the height map periodic edges, or use --coherence beamlet".into(),
            ));
        }
        if sample.interfaces.iter().any(|i| i.closed) {
            return Err(SimError::Config(
                "--coherence diffraction sums deterministic ray fields, but this sample has closed bodies (pigments, flakes) whose long trees end by Russian roulette with random weights; use --coherence beamlet, and a particle medium for sub-wavelength particles".into(),
            ));
        }
        if cfg.adaptive() {
            return Err(SimError::Config(
                "--coherence diffraction sums all trees of a direction at once, so it has no per-tree error to stop on: give a fixed --rays instead of --tolerance or --target-stderr".into(),
            ));
        }
    }
    Ok(())
}

/// Every wavelength the run evaluates (`lambdas`, nm) inside every medium's range, and
/// scattering media with a lossless host.
pub(super) fn media_in_range(sample: &Sample, lambdas: &[f64]) -> Result<(), SimError> {
    for m in &sample.media {
        for &l in lambdas {
            let (_, k) = m
                .model
                .eval(l)
                .map_err(|e| SimError::Config(format!("medium '{}': {e}", m.name)))?;
            if m.scattering.is_some() && k != 0.0 {
                return Err(SimError::Config(format!(
                    "medium '{}' scatters but its host index absorbs (k = {k} at {l} nm): a scattering medium's own index must be lossless; put the absorption in its particles or in absorption_per_um",
                    m.name
                )));
            }
        }
    }
    Ok(())
}

/// The medium above the sample is lossless at every wavelength, and constant when the
/// sample is `dispersive`.
pub(super) fn ambient_lossless(
    sample: &Sample,
    scene: &Scene,
    lambdas: &[f64],
    dispersive: bool,
) -> Result<(), SimError> {
    if let Some(&l) = lambdas
        .iter()
        .find(|&&l| index_at(sample, l)[scene.ambient].im != 0.0)
    {
        // Which sheets face up into it: where the user meant another medium in front (air
        // over a gold film), one of them rises above the rest somewhere (issue 47: a gold
        // roof film of 0 nm at its ridge read as if the user had put gold in front).
        let fronts: Vec<String> = sample
            .interfaces
            .iter()
            .enumerate()
            .filter(|(_, itf)| !itf.closed && itf.front == scene.ambient)
            .map(|(i, itf)| format!("interface {i} ({})", itf.mesh_path.display()))
            .collect();
        let other_fronts = sample
            .interfaces
            .iter()
            .any(|itf| !itf.closed && itf.front != scene.ambient);
        let hint = if other_fronts && !fronts.is_empty() {
            format!(
                "; vertical rays from above meet {} first, whose front is '{}'. If another medium was meant in front, that sheet rises above the others somewhere (a layer of zero or negative thickness, or sheets that cross): run goniospec check",
                fronts.join(" and "),
                sample.media[scene.ambient].name
            )
        } else {
            String::new()
        };
        return Err(SimError::Config(format!(
            "the medium above the sample ('{}') absorbs at {l} nm: reflectance is defined in a lossless ambient medium{hint}",
            sample.media[scene.ambient].name
        )));
    }
    if dispersive
        && (index_at(sample, lambdas[0])[scene.ambient]
            != index_at(sample, lambdas.iter().copied().fold(0.0, f64::max))[scene.ambient])
    {
        return Err(SimError::Config(
            "the medium above the sample is dispersive; use a constant index for the ambient medium".into(),
        ));
    }
    Ok(())
}

/// The diffraction method's memory: every kept exit of a direction and each wavelength's
/// grid (ambient index `n_up`).
pub(super) fn diffraction_budget(
    sample: &Sample,
    cfg: &SimConfig,
    scene: &Scene,
    lambdas: &[f64],
    n_up: f64,
) -> Result<(), SimError> {
    let nl = cfg.wavelengths.count();
    // Every exit of a direction is kept (about 160 bytes each, two per tree as a
    // guide) and each wavelength's grid must fit.
    let bytes = 2.0 * 160.0 * cfg.rays as f64 * nl as f64;
    if bytes > DIFFRACTION_MAX_BYTES || cfg.rays > u64::from(u32::MAX) {
        return Err(SimError::Config(format!(
            "--coherence diffraction keeps every exit of an incident direction in memory: {} trees x {nl} wavelengths needs about {:.1} GB (at most {:.0} GB): use fewer rays or fewer wavelengths per run (batch plans split a spectrum into units)",
            cfg.rays,
            bytes / 1e9,
            DIFFRACTION_MAX_BYTES / 1e9
        )));
    }
    for &l in lambdas {
        let n_sub = index_at(sample, l)[scene.substrate];
        for n_out in [Some(n_up), (n_sub.im == 0.0).then_some(n_sub.re)]
            .into_iter()
            .flatten()
        {
            let lattice = super::launch::diffraction_lattice(cfg.rays, sample.tile_nm);
            let [mx, my] = diffraction::grid_cells(sample.tile_nm, l, n_out, lattice);
            if mx.saturating_mul(my) > diffraction::MAX_GRID_CELLS {
                return Err(SimError::Config(format!(
                    "--coherence diffraction needs a {mx} x {my} grid over the {:.0} x {:.0} nm tile at {l} nm (at most {} cells): use a smaller tile (a period, or a few correlation lengths); features this large against the wavelength are where rays alone hold",
                    sample.tile_nm[0],
                    sample.tile_nm[1],
                    diffraction::MAX_GRID_CELLS
                )));
            }
        }
    }
    Ok(())
}

/// Each cell's method (`auto::Choice`) and, under `--coherence auto`, what the choice says
/// of each direction alone (kept in the `.gsa`): all cells the diffraction method's for an
/// explicit run (whose memory is checked here), `auto::choose` for an auto run (a cell's
/// grid and kept exits checked as `diffraction_budget` checks them), rays otherwise.
pub(super) fn method_choice(
    sample: &Sample,
    cfg: &SimConfig,
    scene: &Scene,
    lambdas: &[f64],
    n_up: f64,
    sheets: &[Option<crate::sample::validity::Scales>],
) -> Result<(super::auto::Choice, Vec<Vec<String>>), SimError> {
    use super::auto::{Choice, choose};
    use crate::reference::rigorous::Rigorous;
    let cells = cfg.theta_i_deg.len() * cfg.wavelengths.count();
    let mut direction_notes = vec![Vec::new(); cfg.theta_i_deg.len()];
    let choice = match cfg.coherence {
        Coherence::Diffraction => {
            diffraction_budget(sample, cfg, scene, lambdas, n_up)?;
            Choice {
                diffraction: vec![true; cells],
                rigorous: vec![false; cells],
                solver: None,
                notes: Vec::new(),
            }
        }
        Coherence::Rigorous => Choice {
            diffraction: vec![false; cells],
            rigorous: vec![true; cells],
            solver: Some(
                Rigorous::new(sample, cfg.rigorous)
                    .map_err(|e| SimError::Config(format!("sample '{}': {e}", sample.name)))?,
            ),
            notes: Vec::new(),
        },
        Coherence::Auto => {
            let fits = |l: f64| {
                diffraction_budget(sample, cfg, scene, &[l], n_up).map_err(|e| {
                    e.to_string()
                        .replacen("--coherence diffraction", "the diffraction method", 1)
                })
            };
            for (notes, &t) in direction_notes.iter_mut().zip(&cfg.theta_i_deg) {
                let one = SimConfig {
                    theta_i_deg: vec![t],
                    ..cfg.clone()
                };
                *notes = choose(sample, &one, sheets, &fits).notes;
            }
            choose(sample, cfg, sheets, &fits)
        }
        _ => Choice {
            diffraction: vec![false; cells],
            rigorous: vec![false; cells],
            solver: None,
            notes: Vec::new(),
        },
    };
    if let Some(solver) = &choice.solver {
        super::rigorous_fit::check_budget(sample, cfg, solver, &choice.rigorous)?;
    }
    Ok((choice, direction_notes))
}

/// Path sharing (asked for with `path_sharing`) where the sample's interfaces change with
/// the wavelength: refused, naming why.
pub(super) fn sharing_refusal(
    sharing: bool,
    dispersive: bool,
    coated: bool,
    absorbing: bool,
) -> Result<(), SimError> {
    if sharing && dispersive {
        return Err(SimError::Config(
            "path sharing needs non-dispersive media: this sample's indices change with wavelength"
                .into(),
        ));
    }
    if sharing && coated {
        return Err(SimError::Config(
            "path sharing needs wavelength-independent interfaces: this sample has coatings, whose coefficients change with wavelength"
                .into(),
        ));
    }
    if sharing && absorbing {
        return Err(SimError::Config(
            "path sharing needs wavelength-independent interfaces: this sample has an absorbing medium, whose thin films are taken by the transfer matrix, which changes with wavelength"
                .into(),
        ));
    }
    Ok(())
}

/// What `--coherence rigorous` cannot take (`rigorous_fit::rigorous_refused`: open sides,
/// particle media, adaptive budgets; `rigorous_fit::untiled`: a mesh that does not tile),
/// before any work.
fn rigorous_refusals(sample: &Sample, cfg: &SimConfig) -> Result<(), SimError> {
    if cfg.coherence != Coherence::Rigorous {
        return Ok(());
    }
    if let Some(why) = super::rigorous_fit::rigorous_refused(sample, cfg) {
        return Err(SimError::Config(format!(
            "--coherence rigorous solves a deterministic periodic tile, but {why}; use --coherence auto (the default)"
        )));
    }
    match super::rigorous_fit::untiled(sample) {
        Some(why) => Err(SimError::Config(format!(
            "--coherence rigorous solves one period of a periodic structure, but {why}: make the mesh's opposite sides meet (or give it a guard band and use --coherence auto)"
        ))),
        None => Ok(()),
    }
}

/// Tabulates the particle media's scattering over the run's wavelengths `lambdas`, nm
/// (each whole nm between the extremes; a Mie table refuses an absorbing host at any of
/// them too), stopping when the run is cancelled.
pub(super) fn tabulate_scattering(
    scene: &mut Scene,
    cfg: &SimConfig,
    lambdas: &[f64],
) -> Result<(), SimError> {
    let lo = lambdas.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = lambdas.iter().copied().fold(0.0, f64::max);
    let cancelled = || {
        cfg.cancel
            .as_ref()
            .is_some_and(|c| c.load(std::sync::atomic::Ordering::Relaxed))
    };
    // Ctrl-C in Python stops the tabulation too (it can take seconds for large
    // spheres).
    if let Err(e) = scene.prepare_scattering(lo, hi, &cancelled) {
        return Err(if cancelled() {
            SimError::Cancelled
        } else {
            e.into()
        });
    }
    Ok(())
}
