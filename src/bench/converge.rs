//! `bench converge`: the wall time to a BRDF whose buckets are not noise, the speed a user
//! feels (issue 49). The figure: at one incident direction, the median relative standard
//! error of the buckets that hold `share` (95 %) of the reflected power at each wavelength
//! (the brightest first), over every wavelength; the time is the wall time of a run from
//! scratch at a tree count that reaches the target. Tree counts are chosen by the error's
//! local rate over the last two runs (aiming 15 % beyond; one step back where a jump lands
//! far below the target), but the figure is always measured, never extrapolated: a sample
//! that does not reach the target within the time allowed is reported with what it
//! reached. The errors are the replicate groups' (`simulate::ERROR_GROUPS`, docs/design.md
//! §4, "Standard errors"). They are compared with a second seed at the same count: the
//! median over those buckets of `|a - b| / sqrt(se_a^2 + se_b^2)` is 0.674 (the median of
//! |Z| for a standard normal) where the errors are honest, less where they are overstated,
//! more where understated; and the relative error the two seeds measure is printed beside
//! the estimator's. Under quasi-Monte Carlo a run's buckets share its random shifts, so
//! one pair's figures scatter (tests/converge.rs checks the errors over 24 seeds).

use std::time::Instant;

use crate::accumulate::file::Accumulator;
use crate::sample::Sample;
use crate::simulate::{SimConfig, SimError, Wavelengths, simulate};

/// Settings of one sample's measurement.
#[derive(Clone, Debug)]
pub struct ConvergeConfig {
    pub theta_i_deg: f64,
    /// Wavelength bin edges, nm.
    pub edges: Vec<f64>,
    /// The median relative standard error to reach (0.05).
    pub target: f64,
    /// The share of each wavelength's reflected power whose buckets are judged (0.95).
    pub share: f64,
    /// Trees of the first run.
    pub start_rays: u64,
    /// Wall time allowed for the runs that search for the count, s.
    pub max_seconds: f64,
    pub seed: u64,
}

/// What one sample reached.
#[derive(Clone, Debug, PartialEq)]
pub struct ConvergeFigure {
    /// Trees of the last run, its wall time (s) and the median relative standard error it
    /// reached.
    pub trees: u64,
    pub seconds: f64,
    pub median: f64,
    pub reached: bool,
    /// The second seed's check ([`seed_check`]): the median `|a - b|` in standard errors
    /// and the measured median relative error; `None` where the target was not reached.
    pub seed_check: Option<(f64, f64)>,
}

/// The reflected buckets of direction `i` of `acc` that hold `share` of each wavelength's
/// reflected power ([`crate::simulate::bright_buckets`]).
fn bright_buckets(acc: &Accumulator, i: usize, share: f64) -> Vec<(usize, usize)> {
    crate::simulate::bright_buckets(acc.direction_cells(i), share)
}

fn median(mut v: Vec<f64>) -> Option<f64> {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied()
}

/// The median relative standard error of the buckets of direction `i` that hold `share`
/// of each wavelength's reflected power.
pub fn bucket_noise(acc: &Accumulator, i: usize, share: f64) -> Option<f64> {
    crate::simulate::bright_bucket_error(acc.direction_cells(i), share)
}

/// Two runs of the same trees on different seeds (independent randomisations: the seed
/// shifts the entry points' R2 set and draws the jitter and random events), over `a`'s
/// bright buckets: the median of `|a - b| / sqrt(se_a^2 + se_b^2)` (0.674 where the
/// estimator's errors are honest) and the measured median relative error,
/// `median(|a - b| / (a + b)) sqrt(2) / 0.674` (for normal errors of equal size, the
/// median of `|a - b|` is `0.674 sqrt(2) sigma`).
pub fn seed_check(a: &Accumulator, b: &Accumulator, i: usize, share: f64) -> Option<(f64, f64)> {
    let (z, rel): (Vec<f64>, Vec<f64>) = bright_buckets(a, i, share)
        .into_iter()
        .filter_map(|(j, k)| {
            let (ca, cb) = (a.cell(i, j), b.cell(i, j));
            let (ma, mb) = (ca.sum[k] / ca.trees as f64, cb.sum[k] / cb.trees as f64);
            let se = (ca.sum_var(k).sqrt() / ca.trees as f64)
                .hypot(cb.sum_var(k).sqrt() / cb.trees as f64);
            (se > 0.0 && ma + mb > 0.0).then(|| ((ma - mb).abs() / se, (ma - mb).abs() / (ma + mb)))
        })
        .unzip();
    Some((
        median(z)?,
        median(rel)? * std::f64::consts::SQRT_2 / MEDIAN_ABS_NORMAL,
    ))
}

/// The median of |Z| for a standard normal Z.
const MEDIAN_ABS_NORMAL: f64 = 0.674_489_750_196_081_7;

/// Runs `sample` at growing tree counts until its bright buckets reach the target, then
/// checks the errors against a second seed. `log` hears each run.
pub fn converge(
    sample: &Sample,
    cfg: &ConvergeConfig,
    log: &mut dyn FnMut(&str),
) -> Result<ConvergeFigure, SimError> {
    let run = |rays: u64, seed: u64| -> Result<(Accumulator, f64), SimError> {
        let mut sim = SimConfig::new(
            vec![cfg.theta_i_deg],
            Wavelengths::Bins(cfg.edges.clone()),
            rays,
        );
        sim.seed = seed;
        let t0 = Instant::now();
        let (acc, _) = simulate(sample, &sim, &|_| {})?;
        Ok((acc, t0.elapsed().as_secs_f64()))
    };
    let started = Instant::now();
    let mut rays = cfg.start_rays.max(64);
    // The previous run's (trees, error), for the local rate of convergence.
    let mut last: Option<(u64, f64)> = None;
    loop {
        let (acc, seconds) = run(rays, cfg.seed)?;
        let m = bucket_noise(&acc, 0, cfg.share).unwrap_or(f64::INFINITY);
        log(&format!(
            "{rays} trees: {seconds:.2} s, median relative error {m:.4}"
        ));
        if m <= cfg.target {
            // Far below the target (a jump from a count whose error was still saturated):
            // one run back at the count the local rate predicts, kept if it also reaches.
            let (mut acc, mut rays, mut seconds, mut m) = (acc, rays, seconds, m);
            if let Some((r0, m0)) = last.filter(|_| m < 0.8 * cfg.target) {
                let p = ((m0 / m).ln() / (rays as f64 / r0 as f64).ln()).clamp(0.5, 1.0);
                let back = rays as f64 * (m / cfg.target).powf(1.0 / p) * 1.15;
                let back = (back / 64.0).ceil() as u64 * 64;
                if back > r0 && (back as f64) < 0.8 * rays as f64 {
                    let (acc2, seconds2) = run(back, cfg.seed)?;
                    let m2 = bucket_noise(&acc2, 0, cfg.share).unwrap_or(f64::INFINITY);
                    log(&format!(
                        "{back} trees: {seconds2:.2} s, median relative error {m2:.4}"
                    ));
                    if m2 <= cfg.target {
                        (acc, rays, seconds, m) = (acc2, back, seconds2, m2);
                    }
                }
            }
            let (other, _) = run(rays, cfg.seed + 1)?;
            return Ok(ConvergeFigure {
                trees: rays,
                seconds,
                median: m,
                reached: true,
                seed_check: seed_check(&acc, &other, 0, cfg.share),
            });
        }
        // The error's local rate `N^-p` from the last two runs (p between Monte Carlo's
        // 1/2 and 1; 1/2 before there are two), aiming 15 % beyond (at least 1.25 times
        // the trees, at most 64): only to choose the next run. Quasi-Monte Carlo errors
        // fall faster than 1/sqrt(N), and the square law overshot rough gold's count 2x.
        let p = match last {
            Some((r0, m0)) if m.is_finite() && m0.is_finite() && m < m0 => {
                ((m0 / m).ln() / (rays as f64 / r0 as f64).ln()).clamp(0.5, 1.0)
            }
            _ => 0.5,
        };
        last = Some((rays, m));
        let factor = ((m / cfg.target).powf(1.0 / p) * 1.15).clamp(1.25, 64.0);
        let next = ((rays as f64 * factor / 64.0).ceil() as u64) * 64;
        let expected = seconds * next as f64 / rays as f64;
        if !m.is_finite() || started.elapsed().as_secs_f64() + expected > cfg.max_seconds {
            return Ok(ConvergeFigure {
                trees: rays,
                seconds,
                median: m,
                reached: false,
                seed_check: None,
            });
        }
        rays = next;
    }
}
