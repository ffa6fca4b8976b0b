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
//!   atomically; KEY hashes the candidate's sample (its content, not its comments) and
//!   everything else that decides its simulation and comparison). The search is
//!   deterministic, so a rerun after an interruption replays it, reads what was done and
//!   simulates only the rest, reaching the bytes an uninterrupted run writes. A candidate
//!   the simplex visits twice is not simulated again.

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
    /// Points of a Halton sequence over the ranges evaluated before the simplex, which
    /// starts from the best of them and the start (0: from the start alone). Thin films
    /// have an error with a minimum per interference order; a few spread points find the
    /// right basin before the simplex refines it.
    pub starts: usize,
    /// The search stops when the simplex's objectives have a standard deviation below
    /// this (CIEDE2000 units).
    pub tolerance: f64,
    /// Where the candidates' records live; `None` keeps none.
    pub records: Option<PathBuf>,
}

impl Search<'_> {
    /// Evaluates and records the starting points of shard `i` of `n` (1-based): of the
    /// start and the `starts` Halton points, those whose place in that list is `i - 1`
    /// modulo `n`. Shards run as separate processes (GNU parallel, a Slurm array) fill the
    /// records a search without a shard then reads; nothing else is searched.
    pub fn run_shard(
        &self,
        start: &[f64],
        (i, n): (usize, usize),
        report: &mut dyn FnMut(usize, &Evaluation, f64),
    ) -> Result<Vec<Evaluation>, RecipeError> {
        if self.records.is_none() || self.starts == 0 || i == 0 || i > n {
            return Err(format!(
                "--shard {i}/{n}: shards evaluate the starting points (--starts K, K > 0) into the records, 1 <= I <= N"
            )
            .into());
        }
        let state = RefCell::new(Progress {
            trace: Vec::new(),
            memo: std::collections::HashMap::new(),
            failure: None,
            report,
        });
        for (k, u) in self.starting_points(start).iter().enumerate() {
            if k % n == i - 1 {
                self.counted(&state, u)?;
            }
        }
        Ok(state.into_inner().trace)
    }

    /// The start (as a point of the unit cube) and the first `starts` Halton points.
    fn starting_points(&self, start: &[f64]) -> Vec<Vec<f64>> {
        let n = self.vary.len();
        let x0: Vec<f64> = self
            .vary
            .iter()
            .zip(start)
            .map(|(v, &s)| v.unit_of(s))
            .collect();
        std::iter::once(x0)
            .chain((1..=self.starts).map(|i| (0..n).map(|d| halton(i, PRIMES[d])).collect()))
            .collect()
    }

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
        check_budget(n, self.starts, self.max_evaluations)?;
        if n > MAX_PARAMETERS {
            return Err(format!("{n} parameters: a match varies at most {MAX_PARAMETERS}").into());
        }
        let state = RefCell::new(Progress {
            trace: Vec::new(),
            memo: std::collections::HashMap::new(),
            failure: None,
            report,
        });
        let points = self.starting_points(start);
        let mut x0 = points[0].clone();
        if self.starts > 0 {
            let mut best = f64::INFINITY;
            for u in points {
                let e = self.counted(&state, &u)?;
                if e < best {
                    (best, x0) = (e, u);
                }
            }
        }
        // The first simplex: the start and a step of a quarter of each range, inwards.
        let mut simplex = vec![x0.clone()];
        for k in 0..n {
            let mut p = x0.clone();
            p[k] += if p[k] + 0.25 <= 1.0 { 0.25 } else { -0.25 };
            simplex.push(p);
        }
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

    /// The objective at the point `u` of the unit cube, counted against the budget and
    /// reported; a candidate met before in this run is not simulated again.
    fn counted(&self, state: &RefCell<Progress>, u: &[f64]) -> Result<f64, RecipeError> {
        let mut p = state.borrow_mut();
        if let Some(e) = p.failure.take() {
            return Err(e);
        }
        if p.trace.len() >= self.max_evaluations {
            return Err(RecipeError::from(SPENT));
        }
        let values = self.values_at(u);
        let bits: Vec<u64> = values.iter().map(|v| v.to_bits()).collect();
        let e = match p.memo.get(&bits) {
            Some(&k) => {
                let mut e = p.trace[k].clone();
                e.cached = true;
                e.seconds = 0.0;
                e
            }
            None => self.evaluate(&values)?,
        };
        let cost = e.objective;
        let at = p.trace.len();
        p.memo.entry(bits).or_insert(at);
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

    /// The record key: the candidate's content and everything else that decides its
    /// figures.
    fn key(&self, text: &str) -> u64 {
        let c = &self.config;
        // The sample's content, not its comments or layout: a template whose comments
        // are edited keeps its records.
        let content = text
            .parse::<toml::Table>()
            .map_or_else(|_| text.to_string(), |t| t.to_string());
        let parts = [
            content,
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

/// Refuses a budget below the starting points (`starts` and the start itself) and twice
/// Nelder–Mead's first simplex (`n + 1` candidates for `n` parameters): it would stop
/// before the simplex moved.
pub fn check_budget(n: usize, starts: usize, max_evaluations: usize) -> Result<(), RecipeError> {
    let first = if starts > 0 { starts + 1 } else { 0 };
    let least = first + 2 * (n + 1);
    if max_evaluations < least {
        return Err(format!(
            "--max-evaluations {max_evaluations} is too few for {n} parameter{}{}: Nelder-Mead's first simplex alone takes {}; allow at least {least}",
            if n == 1 { "" } else { "s" },
            if starts > 0 { format!(" and {starts} starting points") } else { String::new() },
            n + 1,
        )
        .into());
    }
    Ok(())
}

/// What a search answers once its evaluations are spent.
const SPENT: &str = "the evaluations are spent";

/// The first primes: the Halton sequence's bases, one per parameter.
const PRIMES: [u64; 12] = [2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37];

/// The most parameters one match varies (a Halton base each).
pub const MAX_PARAMETERS: usize = PRIMES.len();

/// The radical inverse of `i` in `base`: the `i`-th point of the Halton sequence's
/// coordinate of that base (Halton 1960, Numerische Mathematik 2, 84-90), in (0, 1).
pub fn halton(mut i: usize, base: u64) -> f64 {
    let (mut f, mut r) = (1.0, 0.0);
    while i > 0 {
        f /= base as f64;
        r += f * (i as u64 % base) as f64;
        i /= base as usize;
    }
    r
}

/// Folds a coordinate into [0, 1] by reflection at the faces (a triangle wave of period 2).
pub fn fold(x: f64) -> f64 {
    let y = x.rem_euclid(2.0);
    if y > 1.0 { 2.0 - y } else { y }
}

struct Progress<'r> {
    trace: Vec<Evaluation>,
    /// Each candidate's values (their bits) and its first place in `trace`.
    memo: std::collections::HashMap<Vec<u64>, usize>,
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
        if self.state.borrow().failure.is_some() {
            return Err(argmin::core::Error::msg("a candidate failed"));
        }
        match self.search.counted(self.state, u) {
            Ok(cost) => Ok(cost),
            Err(RecipeError::Invalid(m)) if m == SPENT => Err(argmin::core::Error::msg(SPENT)),
            Err(e) => {
                self.state.borrow_mut().failure = Some(e);
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
    fn halton_points_are_radical_inverses() {
        // Base 2: 1/2, 1/4, 3/4, 1/8; base 3: 1/3, 2/3, 1/9, 4/9.
        let b2: Vec<f64> = (1..=4).map(|i| halton(i, 2)).collect();
        assert_eq!(b2, [0.5, 0.25, 0.75, 0.125]);
        let b3: Vec<f64> = (1..=4).map(|i| halton(i, 3)).collect();
        for (got, want) in b3.iter().zip([1.0 / 3.0, 2.0 / 3.0, 1.0 / 9.0, 4.0 / 9.0]) {
            assert!((got - want).abs() < 1e-15, "{got} against {want}");
        }
        assert!(check_budget(2, 0, 5).is_err() && check_budget(2, 0, 6).is_ok());
        assert!(check_budget(2, 8, 14).is_err() && check_budget(2, 8, 15).is_ok());
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
