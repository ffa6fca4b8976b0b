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
