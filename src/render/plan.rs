//! Scene-driven simulation (`goniospec render --simulate`): which incident directions a
//! render needs, found by a pre-pass over the image before anything is simulated.
//!
//! The renderer queries the BRDF at the light's local incident angle (light term) and, for
//! a constant environment, the albedo at the outgoing angle (by reciprocity, the
//! directional-hemispherical reflectance for light arriving from the viewing direction:
//! see [`super::albedo_table`]). The table representation interpolates linearly between
//! simulated incident angles and holds the last one beyond it, so an angle theta needs
//! the grid angles that bracket it. A sky environment integrates over every incident
//! direction: it needs the whole grid.

use super::{Env, Light, RenderConfig, Shape, camera_frame};
use glam::DVec3;

/// What an image needs of the incident-angle grid.
#[derive(Clone, Debug, PartialEq)]
pub struct Plan {
    /// The candidate incident angles (degrees), ascending: the full-hemisphere grid.
    pub grid_deg: Vec<f64>,
    /// Per grid angle: how many pixel queries need it (0: not simulated).
    pub queries: Vec<u64>,
    /// Pixels that show the object.
    pub object_pixels: u64,
}

impl Plan {
    /// The grid angles with at least one query.
    pub fn needed(&self) -> Vec<f64> {
        self.grid_deg
            .iter()
            .zip(&self.queries)
            .filter(|(_, q)| **q > 0)
            .map(|(g, _)| *g)
            .collect()
    }
}

/// The grid angles bracketing `theta_deg` widened by `margin_deg` on each side (pixels are
/// sampled at their centres; the render jitters within them).
fn bracket(grid: &[f64], theta_deg: f64, margin_deg: f64, q: &mut [u64]) {
    let (lo, hi) = (theta_deg - margin_deg, theta_deg + margin_deg);
    let last = grid.len() - 1;
    let below = |t: f64| grid.iter().rposition(|g| *g <= t).unwrap_or(0);
    let above = |t: f64| grid.iter().position(|g| *g >= t).unwrap_or(last);
    let (a, b) = (below(lo), above(hi));
    q[a..=b].iter_mut().for_each(|c| *c += 1);
}

/// Traces one ray per pixel centre and records the incident angles the light and the
/// environment will query. `grid_deg` must be ascending and non-empty.
pub fn plan(shape: &Shape, cfg: &RenderConfig, grid_deg: &[f64]) -> Plan {
    assert!(!grid_deg.is_empty(), "an incident-angle grid");
    let mut queries = vec![0u64; grid_deg.len()];
    let mut object_pixels = 0;
    let cam = camera_frame(shape, cfg);
    let (_, radius) = shape.bounds();
    let step = grid_deg
        .windows(2)
        .map(|w| w[1] - w[0])
        .fold(f64::INFINITY, f64::min);
    let margin = if step.is_finite() { 0.1 * step } else { 0.0 };
    for y in 0..cfg.height {
        for x in 0..cfg.width {
            let d = cam.ray(cfg, x as f64 + 0.5, y as f64 + 0.5);
            let Some((t, n)) = shape.hit(cfg.camera, d) else {
                continue;
            };
            let wo_z = -d.dot(n);
            if wo_z <= 0.0 {
                continue;
            }
            object_pixels += 1;
            let p = cfg.camera + (d * t);
            let lit = |wi: DVec3, q: &mut [u64]| {
                let c = wi.dot(n);
                if c > 0.0 && !shape.occluded(p + n * (1e-6 * radius.max(1.0)), wi) {
                    bracket(grid_deg, c.min(1.0).acos().to_degrees(), margin, q);
                }
            };
            match cfg.light {
                Light::None => {}
                Light::Directional(l) => lit(l, &mut queries),
                Light::Point(q) => lit((q - p).normalize(), &mut queries),
            }
            match cfg.env {
                Env::None => {}
                Env::Constant => bracket(
                    grid_deg,
                    wo_z.min(1.0).acos().to_degrees(),
                    margin,
                    &mut queries,
                ),
                Env::Sky => queries.iter_mut().for_each(|q| *q += 1),
            }
        }
    }
    Plan {
        grid_deg: grid_deg.to_vec(),
        queries,
        object_pixels,
    }
}

/// The budget of a scene-driven simulation.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneBudget {
    /// Spacing of the full-hemisphere incident-angle grid, degrees, in (0, 90).
    pub theta_step_deg: f64,
    /// Trees per batch and per direction (the adaptive run's step), at least 1.
    pub rays: u64,
    /// At most this many trees per direction, at least `rays`.
    pub max_rays: u64,
    /// Target relative standard error of the reflectance per direction (positive).
    pub tolerance: f64,
    /// Instead of `tolerance`: the target median relative standard error of the bright
    /// buckets (`simulate --target-stderr`, [`crate::simulate::bright_bucket_error`]).
    pub target_stderr: Option<f64>,
    pub seed: u64,
    pub wavelengths: crate::spectrum::Wavelengths,
}

/// What a scene-driven simulation did: the plan, the accumulator of the needed angles, its
/// run statistics and the BRDF table built from it.
pub struct SceneRun {
    pub plan: Plan,
    pub needed_deg: Vec<f64>,
    pub acc: crate::accumulate::file::Accumulator,
    pub stats: crate::simulate::SimStats,
    pub brdf: crate::brdf::Representation,
}

/// Why a scene-driven simulation could not run.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("{0}")]
    Budget(String),
    #[error(
        "the image needs no incident direction: the object is not visible or not lit (check --camera, --light and --env)"
    )]
    NothingNeeded,
    #[error(
        "sample '{0}' is not rotation-symmetric (a grating, grooves: its facets lean along some azimuths, so its BRDF depends on the incident azimuth), and --simulate lights it from one azimuth, which its table would average over: simulate it from several (`simulate --phi-i 0,45,90,135,180,225,270,315`), build the .gsa (an anisotropic kd-tree) and render that .gsb"
    )]
    Anisotropic(String),
    #[error(transparent)]
    Simulate(#[from] crate::simulate::SimError),
}

impl SceneBudget {
    /// Every field in range, or what is not.
    pub fn validate(&self) -> Result<(), SceneError> {
        // The range simulate's own check holds it to, said here before planning.
        let lowest = crate::simulate::MIN_TOLERANCE;
        if let Some(t) = self.target_stderr
            && !(lowest..1.0).contains(&t)
        {
            return Err(SceneError::Budget(format!(
                "--target-stderr must be a median relative standard error in [{lowest:e}, 1), got {t}"
            )));
        }
        if !(self.tolerance > 0.0 && self.tolerance.is_finite()) {
            return Err(SceneError::Budget(format!(
                "--tolerance must be a positive number, got {}",
                self.tolerance
            )));
        }
        if self.rays == 0 || self.max_rays < self.rays {
            return Err(SceneError::Budget(format!(
                "--rays must be positive and at most --max-rays (got {} and {})",
                self.rays, self.max_rays
            )));
        }
        if !(self.theta_step_deg > 0.0 && self.theta_step_deg < 90.0) {
            return Err(SceneError::Budget(format!(
                "--theta-step must lie between 0 and 90 degrees, got {}",
                self.theta_step_deg
            )));
        }
        Ok(())
    }

    /// The full-hemisphere grid: `0, step, 2 step, ...` below 90 degrees.
    pub fn grid_deg(&self) -> Vec<f64> {
        let steps = (90.0 / self.theta_step_deg - 1e-9).ceil() as usize;
        (0..steps).map(|k| k as f64 * self.theta_step_deg).collect()
    }
}

impl SceneBudget {
    /// Validates the budget and plans the image on its grid; refuses an image that needs
    /// no incident direction.
    pub fn plan(&self, shape: &Shape, cfg: &RenderConfig) -> Result<Plan, SceneError> {
        self.validate()?;
        let p = plan(shape, cfg, &self.grid_deg());
        if p.needed().is_empty() {
            return Err(SceneError::NothingNeeded);
        }
        Ok(p)
    }
}

/// Simulates only the incident angles `plan` needs (adaptively, to the budget's tolerance)
/// and builds the BRDF table the render reads. `progress` receives the trees traced so far
/// (at most `max_rays` per needed angle).
pub fn simulate_scene(
    sample: &crate::sample::Sample,
    plan: Plan,
    budget: &SceneBudget,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<SceneRun, SceneError> {
    use crate::brdf::{BucketData, Representation, table::TableBrdf};
    budget.validate()?;
    if crate::sample::symmetry::anisotropy(sample).anisotropic() {
        return Err(SceneError::Anisotropic(sample.name.clone()));
    }
    let needed_deg = plan.needed();
    if needed_deg.is_empty() {
        return Err(SceneError::NothingNeeded);
    }
    // Render's planner asks for its needed angles, adaptively, with the simulation's
    // defaults for everything else.
    let sim = crate::simulate::SimSettings {
        theta_i_deg: needed_deg.clone(),
        rays: budget.rays,
        seed: budget.seed,
        tolerance: budget.target_stderr.is_none().then_some(budget.tolerance),
        target_stderr: budget.target_stderr,
        max_rays: budget.max_rays,
        ..Default::default()
    }
    .config(budget.wavelengths.clone());
    let (acc, stats) = crate::simulate::simulate(sample, &sim, progress)?;
    let brdf = Representation::Table(TableBrdf::build(&BucketData::from_accumulator(&acc)));
    Ok(SceneRun {
        plan,
        needed_deg,
        acc,
        stats,
        brdf,
    })
}

impl SceneRun {
    /// Trees traced over all directions.
    pub fn spent(&self) -> u64 {
        self.stats.directions.iter().map(|d| d.rays).sum()
    }

    /// A lower bound on the trees of a full-hemisphere simulation of the same quality: one
    /// fixed budget must give every grid angle what the hardest needed angle took.
    pub fn full_hemisphere_bound(&self) -> u64 {
        self.largest_budget() * self.plan.grid_deg.len() as u64
    }

    /// The most trees one direction took.
    pub fn largest_budget(&self) -> u64 {
        self.stats
            .directions
            .iter()
            .map(|d| d.rays)
            .max()
            .unwrap_or(0)
    }

    /// The saving against [`SceneRun::full_hemisphere_bound`], and the part of it that
    /// skipping directions alone gives, both in percent.
    pub fn saving_percent(&self) -> (f64, f64) {
        let full = self.full_hemisphere_bound().max(1) as f64;
        let grid = self.plan.grid_deg.len() as f64;
        (
            100.0 * (1.0 - self.spent() as f64 / full),
            100.0 * (1.0 - self.needed_deg.len() as f64 / grid),
        )
    }
}
