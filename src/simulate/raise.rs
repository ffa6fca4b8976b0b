//! The diffraction method raising its own trees (issue 48): where its transform cannot hold
//! the rays' power at the trees asked (`Run::diffraction_refusal`), the run is made again
//! with four times the trees (the launch lattice twice as fine along each axis), within
//! `max_rays`, for as long as each raise brings the transform materially nearer the rays'
//! power. The first direction traced is the most oblique, where the rays sample the field
//! most coarsely, so a run that must be raised is found out on that direction: it is the
//! pilot, and a raise costs one direction's work at the trees tried.
//!
//! Whether more trees help cannot be told from the sample alone. The tangent-plane margin
//! says where physical optics may fail, yet rough glass at 40 deg and 500 nm, below that
//! margin, held 0.25, 0.50 and 0.92 of the rays' power at 64, 256 and 1,024 trees, while
//! the seed's film at 75 deg and 495 nm held 1.276, 1.252 and 1.270 at 4,096, 16,384 and
//! 65,536. So the run measures it: a raise is kept up only while it cuts the transform's
//! log-distance from the rays' power, `|ln ratio|`, by at least [`MIN_GAIN`].
//!
//! A raised run is the run at those trees, byte for byte, but for the warning stored with
//! it that says what was raised and why.
//!
//! Under `--coherence auto` a cell whose transform cannot hold takes rays rather than
//! refusing the run; while a raise is possible, such a cell stops the run after its
//! direction all the same (`Run::pilot`, the most oblique traced first), and the run is
//! raised as an explicit one is. Once raising stops (past `max_rays`, or not helping), the
//! run is made at the last trees that helped without stopping, and the cells it still
//! cannot hold take rays, as they would unraised. The seed's film at 50 deg and 385 nm held
//! 0.67 at 16 trees and holds at 64; the holographic foil at 40 deg and 500 nm held 0.28,
//! 0.52 and 0.51 at 16, 64 and 256, so it runs at 64.

use super::{SimConfig, SimError, run_once};
use crate::accumulate::Coherence;
use crate::accumulate::file::Accumulator;
use crate::sample::Sample;

use super::SimStats;

/// Where a transform could not hold the rays' power: its cell's incident angle (degrees)
/// and wavelength (nm), and the share it held.
#[derive(Clone, Copy, Debug)]
pub(super) struct Unheld {
    pub theta_deg: f64,
    pub lambda_nm: f64,
    pub ratio: f64,
}

/// Each raise multiplies the trees by this (twice as fine a lattice along each axis).
const FACTOR: u64 = 4;

/// A raise is kept up only where it brought `|ln ratio|` down to at most this fraction of
/// what it was: a tenth nearer, at least. (The film's 1.276 to 1.252 is 0.92 of it; rough
/// glass's 0.25 to 0.50, 0.50; rough gold's 0.128 to 0.174, 0.85.)
const MIN_GAIN: f64 = 0.9;

/// [`super::simulate`]: one run, raised while the diffraction method needs it and it helps.
///
/// An explicit diffraction run that cannot be raised further is refused, with what it
/// tried. An auto run whose cells cannot hold takes rays in them, as it would unraised: it
/// is a pilot only while a raise is possible, and once raising stops it is made without
/// stopping, at the last trees that helped, saying what it tried.
pub(super) fn simulate_raising(
    sample: &Sample,
    cfg: &SimConfig,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<(Accumulator, SimStats), SimError> {
    let auto = cfg.coherence == Coherence::Auto;
    let mut now = cfg.clone();
    // Each try's trees count on from the tries before it (`ProgressPlan`).
    let plan = cfg.progress_plan.as_deref();
    let last = std::sync::atomic::AtomicU64::new(0);
    let progress = |n: u64| {
        last.fetch_max(n, std::sync::atomic::Ordering::Relaxed);
        progress(plan.map_or(0, |p| p.before()) + n);
    };
    let mut tried: Vec<(u64, Unheld)> = Vec::new();
    // An auto run's raising stopped, and why: its last run takes rays where it cannot hold.
    let mut settled: Option<String> = None;
    loop {
        let next = now.rays.saturating_mul(FACTOR);
        let pilot = auto && settled.is_none() && barrier(sample, cfg, &now, next, &[]).is_none();
        let mut unheld = None;
        let result = run_once(sample, &now, &progress, &mut unheld, pilot);
        let Some(u) = unheld else {
            // Said where the run's own warnings are: printed, and stored in the `.gsa`.
            return result.map(|(mut acc, mut stats)| {
                let rays_fell = stats.diffraction.iter().any(|d| d.fell_back);
                if let Some(w) = raised_warning(&tried, now.rays, settled.as_deref(), rays_fell) {
                    acc.header.warnings.push(w.clone());
                    stats.auto_notes.push(w);
                }
                (acc, stats)
            });
        };
        // A transform that held nothing (or NaN) is infinitely far (or not comparable): a
        // raise from it helps only where the next one holds something.
        let distance = |u: &Unheld| u.ratio.ln().abs();
        let helped = tried.last().is_none_or(|(_, before)| {
            distance(&u).is_finite() && distance(&u) <= MIN_GAIN * distance(before)
        });
        tried.push((now.rays, u));
        let cancelled = cfg
            .cancel
            .as_ref()
            .is_some_and(|c| c.load(std::sync::atomic::Ordering::Relaxed));
        let stop = if cancelled || !(auto || cfg.coherence == Coherence::Diffraction) {
            Some(String::new())
        } else if !helped {
            Some(if auto {
                " Raising them further did not bring it nearer.".to_string()
            } else {
                format!(
                    " Raising the trees did not bring it nearer ({}).",
                    history(&tried)
                )
            })
        } else {
            // An auto run's warning lists what it tried once (`raised_warning`).
            barrier(sample, cfg, &now, next, if auto { &[] } else { &tried })
        };
        if let Some(p) = plan {
            p.next_try(last.swap(0, std::sync::atomic::Ordering::Relaxed));
        }
        match stop {
            None => now.rays = next,
            Some(why) if auto && !cancelled => {
                // Made once more, not stopping: at the trees before a raise that did not
                // help (the same result for less), else at these.
                if !helped {
                    now.rays = tried[tried.len() - 2].0;
                }
                settled = Some(why);
            }
            Some(why) => return result.map_err(|e| with_history(e, &why)),
        }
    }
}

/// Why the run at `now`'s trees could not be raised to `next` (`None`: it could): no
/// budget, past `--max-rays`, or past what the run's memory takes.
fn barrier(
    sample: &Sample,
    cfg: &SimConfig,
    now: &SimConfig,
    next: u64,
    tried: &[(u64, Unheld)],
) -> Option<String> {
    if !cfg.raise_trees {
        Some(
            " A batch unit runs at its plan's trees and does not raise them (its material's units must merge into one run): raise the plan's rays."
                .to_string(),
        )
    } else if cfg.max_rays < now.rays {
        Some(format!(
            " Give --max-rays (at least {next}) for the run to raise its trees itself."
        ))
    } else if next > cfg.max_rays {
        // `tried` holds this try too: more than it, and the run has raised already.
        Some(if tried.len() > 1 {
            format!(
                " The run raised its trees within --max-rays {} ({}); {next} would pass it.",
                cfg.max_rays,
                history(tried)
            )
        } else {
            format!(
                " Raising the trees to {next}, as the run would, passes --max-rays {}.",
                cfg.max_rays
            )
        })
    } else {
        let raised = SimConfig {
            rays: next,
            ..now.clone()
        };
        // A raise the run's memory cannot take is not tried.
        match super::preflight(sample, &raised) {
            Ok(()) => None,
            Err(e) => Some(format!(" Raising the trees to {next} was refused: {e}")),
        }
    }
}

/// `e` (the refusal, or its partial result) with what the run tried appended.
fn with_history(e: SimError, why: &str) -> SimError {
    if why.is_empty() {
        return e;
    }
    match e {
        SimError::Unphysical(m) => SimError::Unphysical(format!("{m}{why}")),
        SimError::Partial { cause, kept } => SimError::Partial {
            cause: Box::new(with_history(*cause, why)),
            kept,
        },
        other => other,
    }
}

/// The trees tried and the share each held, e.g. `256 trees: 0.500 at 40 deg, 500 nm`.
fn history(tried: &[(u64, Unheld)]) -> String {
    tried
        .iter()
        .map(|(n, u)| {
            format!(
                "{n} trees: {:.3} at {} deg, {} nm",
                u.ratio, u.theta_deg, u.lambda_nm
            )
        })
        .collect::<Vec<_>>()
        .join("; ")
}

/// The warning a raised run stores: what the transform held at the trees asked and each
/// raise, and the trees it ran at. An auto run's cells that still could not hold took rays
/// where `rays_fell`; `settled` says why its raising stopped.
fn raised_warning(
    tried: &[(u64, Unheld)],
    rays: u64,
    settled: Option<&str>,
    rays_fell: bool,
) -> Option<String> {
    let first = tried.first()?;
    let history = history(tried);
    let why = settled.unwrap_or("");
    Some(if rays == first.0 {
        // Raising did not help: the run is the one asked for.
        format!(
            "the diffraction transform could not hold the rays' power at {rays} trees ({history}), and raising them did not bring it nearer, so the run is that of --rays {rays}; the cells it cannot hold took rays (the warning on them says which; docs/physics.md, \"Diffraction\")"
        )
    } else if rays_fell {
        format!(
            "the diffraction transform could not hold the rays' power at {} trees ({history}), so the run raised its trees to {rays} per direction (within --max-rays); the cells it still could not hold there took rays (the warning on them says which).{why} The result is that of --rays {rays} (docs/physics.md, \"Diffraction\")",
            first.0
        )
    } else {
        format!(
            "the diffraction transform could not hold the rays' power at {} trees ({history}), so the run raised its trees to {rays} per direction (within --max-rays), where it held; the result is that of --rays {rays} (docs/physics.md, \"Diffraction\")",
            first.0
        )
    })
}
