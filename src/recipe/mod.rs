//! `goniospec match`: the recipe — values of a sample's own parameters (a coat's
//! thickness, a roughness, a pigment's amount) — whose simulation is closest to a measured
//! material, by `compare`'s CIEDE2000 at the measurement's own directions
//! (docs/design.md §11, "Recipes from measurements").
//!
//! [`template`] reads the sample file and names its varied numbers by TOML path;
//! [`search`] runs Nelder–Mead over them with common random numbers and resumable
//! records; [`finish`] simulates the best recipe at every measured angle, fitted and held
//! out, and [`write`] leaves the fitted sample, the search's trace and its chart.

pub mod search;
pub mod template;
mod write;

use crate::compare::{Report, Stats};

pub use search::{
    Evaluation, MAX_PARAMETERS, Outcome, Search, Stop, check_budget, fit_angles, records_in,
};
pub use template::{Template, Vary};
pub use write::{output_names, write_chart, write_trace};

/// What stops a match: bad input (named, before any simulation), a candidate that cannot
/// be simulated, a comparison or a file that fails.
#[derive(Debug, thiserror::Error)]
pub enum RecipeError {
    /// The message says what and where.
    #[error("{0}")]
    Invalid(String),
    #[error(transparent)]
    Compare(#[from] crate::compare::CompareError),
    #[error(transparent)]
    Plot(#[from] crate::plot::PlotError),
}

message_error!(RecipeError, RecipeError::Invalid);

/// What the search minimises.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Metric {
    /// CIEDE2000 of the reflected colour (`compare`'s figure): the mean over the fitted
    /// angles of each angle's mean over the lit directions weighted by projected solid
    /// angle.
    Colour,
    /// The same of the lightness alone (CIEDE2000 with a* = b* = 0): for a material whose
    /// hue the recipe cannot reach, or to fit the lobe's shape first.
    Lightness,
}

impl Metric {
    pub fn parse(s: &str) -> Result<Metric, RecipeError> {
        match s {
            "colour" | "color" | "ciede2000" => Ok(Metric::Colour),
            "lightness" => Ok(Metric::Lightness),
            _ => Err(format!("--metric {s}: expected colour or lightness").into()),
        }
    }

    pub fn describe(self) -> &'static str {
        match self {
            Metric::Colour => "mean CIEDE2000 of the reflected colour",
            Metric::Lightness => "mean CIEDE2000 of the lightness alone",
        }
    }

    /// The objective of a comparison: every compared angle counts alike.
    pub fn objective(self, r: &Report) -> f64 {
        match self {
            Metric::Colour => r.overall.mean,
            Metric::Lightness => {
                r.angles
                    .iter()
                    .map(|a| a.delta_e_lightness.mean)
                    .sum::<f64>()
                    / r.angles.len() as f64
            }
        }
    }
}

/// The weighted statistics of CIEDE2000 over the angles of `r` that `take` takes, each
/// angle's weights normalised so that every angle counts alike (as `compare`'s overall
/// figure); `None` where it takes none.
pub fn group_stats(r: &Report, take: &dyn Fn(f64) -> bool) -> Option<Stats> {
    let mut v = Vec::new();
    for a in r.angles.iter().filter(|a| take(a.theta_i_deg)) {
        let at = |n: &&crate::compare::Node| n.theta_i_deg == a.theta_i_deg;
        let total: f64 = r.nodes.iter().filter(at).map(|n| n.weight).sum();
        v.extend(r.nodes.iter().filter(at).map(|n| (n.de, n.weight / total)));
    }
    (!v.is_empty()).then(|| Stats::weighted(v))
}
