//! The search: Nelder–Mead (argmin's) over the varied parameters, each candidate a
//! simulation at the fitted angles compared with the measurement.
//!
//! - **Common random numbers.** Every candidate is simulated with the same seed, trees
//!   and settings, so two candidates differ by their recipes, not by their noise: the
//!   objective is a deterministic function of the values, and a simplex step compares
//!   like with like (docs/design.md §11, "Recipes from measurements").
//! - **Box constraints.** The simplex moves in the unit cube of the ranges; a point outside
//!   is folded back in (reflected at the faces, `fold`), so every candidate lies in the
//!   ranges the user gave, and a step across a face looks at the mirror point instead.
//! - **Resumable.** Each candidate's figures are kept in `candidates/KEY.json` (written
//!   atomically; KEY hashes the candidate's sample text and everything else that decides
//!   its simulation and comparison). The search is deterministic, so a rerun after an
//!   interruption replays it, reads what was done and simulates only the rest, reaching
//!   the bytes an uninterrupted run writes. The same records serve a candidate the
//!   simplex visits twice.

use std::cell::RefCell;
use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::{Deserialize, Serialize};

use super::template::{Template, Vary};
use super::{Metric, RecipeError};
use crate::compare::{self, Material};
use crate::simulate::SimConfig;

/// What one evaluation found.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Evaluation {
    /// The candidate's values, in the order of the varied parameters.
    pub values: Vec<f64>,
    /// The objective: the mean over the fitted angles of the weighted mean CIEDE2000
    /// (colour, or lightness alone: [`Metric`]).
    pub objective: f64,
    /// Each fitted angle (degrees) and its weighted mean CIEDE2000 (colour).
    pub per_angle: Vec<(f64, f64)>,
    /// Wall time of the simulation and comparison when they ran, s.
    pub seconds: f64,
    /// Whether it was read from an earlier run's record instead of simulated.
    #[serde(skip)]
    pub cached: bool,
}

/// Why the search stopped.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Stop {
    /// The simplex's objectives agree within the tolerance.
    Converged,
    /// The evaluations allowed were spent.
    Budget,
}

/// What the search leaves: every evaluation in order, the best, and why it stopped.
#[derive(Clone, Debug)]
pub struct Outcome {
    pub trace: Vec<Evaluation>,
    /// Index into `trace` of the lowest objective (the first, where several tie).
    pub best: usize,
    pub stop: Stop,
}

/// Everything the search holds fixed.
pub struct Search<'a> {
    pub template: &'a Template,
    pub vary: &'a [Vary],
    pub measured: &'a Material,
    /// Identifies the measurement in the records' keys (its file's bytes' hash).
    pub measured_key: u64,
    /// The measurement's incident angles fitted, degrees (its own values).
    pub fit_deg: Vec<f64>,
    /// The simulation of a candidate, at the fitted angles.
    pub config: SimConfig,
    pub metric: Metric,
    pub max_evaluations: usize,
    /// The search stops when the simplex's objectives have a standard deviation below
    /// this (CIEDE2000 units).
    pub tolerance: f64,
    /// Where the candidates' records live; `None` keeps none.
    pub records: Option<PathBuf>,
}

impl Search<'_> {
    /// Runs the search from `start` (values within the ranges). `report` sees every
    /// evaluation as it finishes, with the best objective so far.
    pub fn run(
        &self,
        start: &[f64],
        report: &mut dyn FnMut(usize, &Evaluation, f64),
    ) -> Result<Outcome, RecipeError> {
        use argmin::core::{Executor, State};
        use argmin::solver::neldermead::NelderMead;
        let n = self.vary.len();
        check_budget(n, self.max_evaluations)?;
        let x0: Vec<f64> = self
            .vary
            .iter()
            .zip(start)
            .map(|(v, &s)| v.unit_of(s))
            .collect();
        // The first simplex: the start and a step of a quarter of each range, inwards.
        let mut simplex = vec![x0.clone()];
        for k in 0..n {
            let mut p = x0.clone();
            p[k] += if p[k] + 0.25 <= 1.0 { 0.25 } else { -0.25 };
            simplex.push(p);
        }
        let state = RefCell::new(Progress {
            trace: Vec::new(),
            failure: None,
            report,
        });
        let problem = Problem {
            search: self,
            state: &state,
        };
        let solver = NelderMead::new(simplex)
            .with_sd_tolerance(self.tolerance)
            .map_err(|e| RecipeError::from(e.to_string()))?;
        let result = Executor::new(problem, solver)
            .configure(|s| s.max_iters(self.max_evaluations as u64))
            .timer(false)
            .run();
        // An error is the budget, or a failed candidate (kept in the state).
        let converged = result.is_ok_and(|r| {
            matches!(
                r.state().get_termination_reason(),
                Some(argmin::core::TerminationReason::SolverConverged)
            )
        });
        let Progress { trace, failure, .. } = state.into_inner();
        if let Some(e) = failure {
            return Err(e);
        }
        let best = (0..trace.len())
            .min_by(|&a, &b| trace[a].objective.total_cmp(&trace[b].objective))
            .ok_or_else(|| RecipeError::from("the search evaluated no candidate"))?;
        Ok(Outcome {
            trace,
            best,
            stop: if converged {
                Stop::Converged
            } else {
                Stop::Budget
            },
        })
    }

    /// The values of a point of the unit cube (folded into it).
    pub fn values_at(&self, u: &[f64]) -> Vec<f64> {
        self.vary
            .iter()
            .zip(u)
            .map(|(v, &x)| v.value_at(fold(x)))
            .collect()
    }

    /// Simulates the candidate `values` at the fitted angles and compares it with the
    /// measurement, or reads what an earlier run found for it.
    pub fn evaluate(&self, values: &[f64]) -> Result<Evaluation, RecipeError> {
        let text = self.template.with_values(self.vary, values);
        let key = self.key(&text);
        let record = self
            .records
            .as_ref()
            .map(|d| d.join(format!("{key:016x}.json")));
        if let Some(path) = &record
            && let Ok(bytes) = std::fs::read(path)
            && let Ok(mut e) = serde_json::from_slice::<Evaluation>(&bytes)
            && e.values == values
        {
            e.cached = true;
            return Ok(e);
        }
        let t0 = Instant::now();
        let sample = self.template.load(&text).map_err(|e| {
            RecipeError::from(format!(
                "the candidate {} is refused: {e}",
                self.shown(values)
            ))
        })?;
        let (acc, _) = crate::simulate::simulate(&sample, &self.config, &|_| {}).map_err(|e| {
            RecipeError::from(format!(
                "the candidate {}: the simulation failed: {e}",
                self.shown(values)
            ))
        })?;
        let simulated = Material::from_accumulator(&acc)?;
        let report =
            compare::compare_only(&simulated, self.measured, ["candidate", "measured"], &|t| {
                self.fit_deg.iter().any(|f| (f - t).abs() < 1e-6)
            })?;
        let e = Evaluation {
            values: values.to_vec(),
            objective: self.metric.objective(&report),
            per_angle: report
                .angles
                .iter()
                .map(|a| (a.theta_i_deg, a.delta_e.mean))
                .collect(),
            seconds: t0.elapsed().as_secs_f64(),
            cached: false,
        };
        if !e.objective.is_finite() {
            return Err(format!(
                "the candidate {}: the comparison's error is not finite",
                self.shown(values)
            )
            .into());
        }
        if let Some(path) = &record {
            let dir = path.parent().expect("a record's folder");
            std::fs::create_dir_all(dir)
                .and_then(|_| {
                    crate::io::write_atomic(path, |w| {
                        serde_json::to_writer(&mut *w, &e).map_err(std::io::Error::other)
                    })
                })
                .map_err(|err| RecipeError::from(format!("{}: {err}", path.display())))?;
        }
        Ok(e)
    }

    /// The candidate's values as `path = value` pairs.
    pub fn shown(&self, values: &[f64]) -> String {
        self.vary
            .iter()
            .zip(values)
            .map(|(v, x)| format!("{} = {x}", v.path))
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// The record key: the candidate's text and everything else that decides its figures.
    fn key(&self, text: &str) -> u64 {
        let c = &self.config;
        let parts = [
            text.to_string(),
            self.measured_key.to_string(),
            format!("{:?}", self.fit_deg),
            format!("{:?}", self.metric),
            format!(
                "{} {:?} {:?} {:?}",
                c.rays, c.target_stderr, c.tolerance, c.max_rays
            ),
            format!("{:?}", c.wavelengths),
            format!("{:?} {} {}", c.coherence, c.backend.name(), c.rho_nm),
            format!("{} {:?} {:?}", c.seed, c.limits, c.rigorous),
            format!("{} {}", c.buckets.theta_bins, c.buckets.phi_bins),
        ];
        let settings = parts.join("\u{0}");
        crate::io::fnv1a(settings.as_bytes())
    }
}

/// Refuses a budget below twice Nelder–Mead's first simplex (`n + 1` candidates for `n`
/// parameters): it would stop before the simplex moved.
pub fn check_budget(n: usize, max_evaluations: usize) -> Result<(), RecipeError> {
    if max_evaluations < 2 * (n + 1) {
        return Err(format!(
            "--max-evaluations {max_evaluations} is too few for {n} parameter{}: Nelder-Mead's first simplex alone takes {}; allow at least {}",
            if n == 1 { "" } else { "s" },
            n + 1,
            2 * (n + 1)
        )
        .into());
    }
    Ok(())
}

/// Folds a coordinate into [0, 1] by reflection at the faces (a triangle wave of period 2).
pub fn fold(x: f64) -> f64 {
    let y = x.rem_euclid(2.0);
    if y > 1.0 { 2.0 - y } else { y }
}

struct Progress<'r> {
    trace: Vec<Evaluation>,
    failure: Option<RecipeError>,
    report: &'r mut dyn FnMut(usize, &Evaluation, f64),
}

/// The objective as argmin sees it; what it finds stays in `state`, outside argmin.
struct Problem<'s, 'r> {
    search: &'s Search<'s>,
    state: &'s RefCell<Progress<'r>>,
}

impl argmin::core::CostFunction for Problem<'_, '_> {
    type Param = Vec<f64>;
    type Output = f64;

    /// The objective at `u`. argmin's Nelder–Mead unwraps the first simplex's costs, so
    /// a failure there answers infinity and stops the search at its next call; the
    /// budget (at least the first simplex) and later failures stop it with an error.
    fn cost(&self, u: &Self::Param) -> Result<f64, argmin::core::Error> {
        let mut p = self.state.borrow_mut();
        if p.failure.is_some() {
            return Err(argmin::core::Error::msg("a candidate failed"));
        }
        if p.trace.len() >= self.search.max_evaluations {
            return Err(argmin::core::Error::msg("the evaluations are spent"));
        }
        let values = self.search.values_at(u);
        match self.search.evaluate(&values) {
            Ok(e) => {
                let cost = e.objective;
                p.trace.push(e);
                let best = p
                    .trace
                    .iter()
                    .map(|e| e.objective)
                    .fold(f64::INFINITY, f64::min);
                let k = p.trace.len();
                let last = p.trace[k - 1].clone();
                (p.report)(k, &last, best);
                Ok(cost)
            }
            Err(e) => {
                p.failure = Some(e);
                Ok(f64::INFINITY)
            }
        }
    }
}

/// The measured angle nearest each asked one (within 5 degrees), and the measured angles
/// below grazing that are not fitted (held out).
pub fn fit_angles(asked: &[f64], measured: &[f64]) -> Result<(Vec<f64>, Vec<f64>), RecipeError> {
    const WITHIN_DEG: f64 = 5.0;
    let lit: Vec<f64> = measured.iter().copied().filter(|&t| t < 89.999).collect();
    let list = || {
        lit.iter()
            .map(|t| format!("{t:.2}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let mut fit = Vec::new();
    for &a in asked {
        let near = lit
            .iter()
            .copied()
            .min_by(|x, y| (x - a).abs().total_cmp(&(y - a).abs()))
            .filter(|t| (t - a).abs() <= WITHIN_DEG)
            .ok_or_else(|| {
                RecipeError::from(format!(
                    "--fit-angles {a}: the measurement has no incident angle within {WITHIN_DEG} deg of it (it has {} deg)",
                    list()
                ))
            })?;
        if fit.contains(&near) {
            return Err(format!(
                "--fit-angles: two asked angles fall on the measured {near:.2} deg"
            )
            .into());
        }
        fit.push(near);
    }
    fit.sort_by(f64::total_cmp);
    let held = lit.into_iter().filter(|t| !fit.contains(t)).collect();
    Ok((fit, held))
}

/// The path of the records of a search writing into `out`.
pub fn records_in(out: &Path) -> PathBuf {
    out.join("candidates")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn folding_reflects_at_the_faces() {
        for (x, y) in [
            (0.3, 0.3),
            (1.2, 0.8),
            (-0.25, 0.25),
            (2.1, 0.1),
            (-1.5, 0.5),
        ] {
            assert!((fold(x) - y).abs() < 1e-12, "fold({x}) = {}", fold(x));
        }
    }

    #[test]
    fn fitted_angles_are_the_measured_ones() {
        let m = [0.0, 29.62, 42.53, 52.94, 62.23, 71.02, 79.76, 90.0];
        let (fit, held) = fit_angles(&[45.0, 0.0, 30.0], &m).unwrap();
        assert_eq!(fit, vec![0.0, 29.62, 42.53]);
        assert_eq!(held, vec![52.94, 62.23, 71.02, 79.76]);
        assert!(
            fit_angles(&[20.0], &m)
                .unwrap_err()
                .to_string()
                .contains("within 5")
        );
        assert!(fit_angles(&[29.0, 31.0], &m).is_err());
        // Grazing incidence is neither fitted nor held out.
        assert!(fit_angles(&[88.0], &m).is_err());
    }
}
