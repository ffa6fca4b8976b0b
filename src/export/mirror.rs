//! A flat surface's mirror reflection, written as sharp as the RGL grid holds (issue 71).
//!
//! A flat clear coat (or a flat film) reflects a delta lobe: power `E(theta_i, lambda)` (a
//! fraction of the incident power) into the mirror direction. The simulation measures it
//! over the outgoing bucket that holds the mirror direction, 2 x 10 degrees in `theta_o x
//! phi_o` at the default 45 x 36 buckets, and a table interpolated at a fixed `theta_o`
//! between two simulated incident angles shows two half-height copies of it, one at each
//! angle's mirror. For the renderer, [`SharpMirror`] takes each simulated angle's mirror
//! out of the table, as the buckets' excess over their surround, and puts it back as a
//! microfacet lobe about the mirror direction (Walter et al., "Microfacet Models for
//! Refraction through Rough Surfaces", EGSR 2007, eq. 20, with `F G` folded into `E`):
//!
//! ```text
//! f_m(wi, wo) = E(theta_i) D_s(h) / (4 (wi . h) cos theta_o),   h = (wi + wo) / |wi + wo|
//! ```
//!
//! `D_s` is a von Mises–Fisher distribution of half vectors about the normal (Fisher 1953),
//! normalised over the sphere (`int D_s dw_h = 1`), so that with `dw_o = 4 (wi . h) dw_h`
//! (Walter et al. eq. 14) the lobe carries `int f_m cos(theta_o) dw_o = E` up to the part of
//! `D_s` whose reflection falls below the horizon (below 1e-6 of it at 80 degrees for the
//! default width). `E` is interpolated linearly in `theta_i` between the simulated angles,
//! so the lobe follows the mirror between them.

use glam::DVec3;
use std::f64::consts::{FRAC_PI_2, PI, TAU};

use crate::brdf::table::TableBrdf;
use crate::brdf::{Brdf, Meta, Representation};

/// A table whose mirror buckets have become a sharp lobe (module docs).
pub struct SharpMirror {
    /// The table with each simulated angle's mirror buckets set to their surround's median.
    background: TableBrdf,
    /// `E`, `[theta_i index][lambda]`: the mirror's power, a fraction of the incident.
    power: Vec<Vec<f64>>,
    /// `D_s = norm exp(kappa (h . z - 1))`.
    kappa: f64,
    norm: f64,
}

/// Why a table's mirror is left at the bucket aperture.
#[derive(Clone, Debug, PartialEq)]
pub struct NoMirror(pub String);

/// The sharp mirror `goniospec render` and the batch report draw for `r`: a table
/// simulated from a sample whose surface facing the light is flat (`flat_top` in its
/// settings), at the lobe width of the default RGL grid, so that images and the exported
/// file show the same material. `Ok(None)` for other BRDFs; `Err` where the table's
/// mirror cannot be told from its surround (the image then shows the buckets).
pub fn for_render(r: &Representation) -> Result<Option<SharpMirror>, NoMirror> {
    let Representation::Table(t) = r else {
        return Ok(None);
    };
    let flat = toml::from_str::<crate::accumulate::file::Settings>(&t.meta.simulation)
        .is_ok_and(|s| s.flat_top);
    if !flat {
        return Ok(None);
    }
    SharpMirror::from_table(t, SharpMirror::width_for(SharpMirror::DEFAULT_GRID)).map(Some)
}

/// The buckets around one simulated angle's mirror direction.
struct Block {
    /// The buckets the mirror may have fallen into (two where it lies on an edge).
    inside: Vec<(usize, usize)>,
    /// Their neighbours, whose median stands for what lies under the mirror.
    around: Vec<(usize, usize)>,
}

impl SharpMirror {
    /// The RGL grid `export` writes by default (`--resolution`), whose lobe `render` draws.
    pub const DEFAULT_GRID: usize = 65;

    /// The spread of `D_s` (radians of half vector) for an RGL grid of `n` nodes a side:
    /// the polar angle of its fifth node from the pole (`u = 4 / (n - 1)`, `theta = u^2 pi
    /// / 2`: 0.35 degrees at 65 nodes), so that four intervals of the grid's `D` resolve
    /// the peak's width, at most 3 degrees.
    pub fn width_for(n: usize) -> f64 {
        let u = 4.0 / (n.max(2) - 1) as f64;
        (u * u * FRAC_PI_2).min(3f64.to_radians())
    }

    /// The mirror of `table` as a lobe of half-vector spread `width` radians; refused
    /// where some simulated angle's mirror buckets hold no excess above three standard
    /// errors of their surround's level (no flat surface reflects there).
    pub fn from_table(table: &TableBrdf, width: f64) -> Result<SharpMirror, NoMirror> {
        let nl = table.meta.lambda_nm.len();
        let (tb, pb) = (table.theta_bins, table.phi_bins);
        let dt = FRAC_PI_2 / tb as f64;
        let dp = TAU / pb as f64;
        // int cos(theta) dw over a bucket of row t: (sin^2 theta_1 - sin^2 theta_0) / 2 dphi.
        let proj = |t: usize| {
            let (a, b) = ((t as f64 * dt).sin(), ((t + 1) as f64 * dt).sin());
            0.5 * (b * b - a * a) * dp
        };
        let mut background = table.clone();
        let mut power = Vec::with_capacity(table.theta_i_rad.len());
        for (i, &ti) in table.theta_i_rad.iter().enumerate() {
            let block = mirror_block(ti, table.phi_i_rad, tb, pb);
            if block.around.is_empty() {
                return Err(NoMirror(format!(
                    "at {:.1} deg the outgoing grid ({tb} x {pb} buckets) has no bucket beside the mirror's to tell it from",
                    ti.to_degrees()
                )));
            }
            let at = |t: usize, p: usize| ((i * tb + t) * pb + p) * nl;
            let mut e = Vec::with_capacity(nl);
            for j in 0..nl {
                let mut vals: Vec<f64> = block
                    .around
                    .iter()
                    .map(|&(t, p)| table.values[at(t, p) + j])
                    .collect();
                // The surround's median and its spread by the median absolute deviation
                // (1.4826 MAD estimates a normal standard deviation; Huber 1981, §5.1): a
                // flake's glint in one neighbour would carry a mean and a standard
                // deviation with it.
                let level = median(&mut vals);
                let mut dev: Vec<f64> = vals.iter().map(|v| (v - level).abs()).collect();
                let sd = 1.4826 * median(&mut dev);
                let (mut ej, mut omega) = (0.0, 0.0);
                for &(t, p) in &block.inside {
                    ej += (table.values[at(t, p) + j] - level) * proj(t);
                    omega += proj(t);
                    background.values[at(t, p) + j] = level;
                }
                // Three standard errors of the surround's level (the median's is 1.253 times
                // the mean's for normal noise), over the block.
                let noise = 3.0 * 1.253 * sd / (vals.len() as f64).sqrt() * omega;
                let found = ej > noise && ej > 0.0;
                if !found {
                    return Err(NoMirror(format!(
                        "at {:.1} deg and {:.0} nm the mirror buckets hold {:.3e} above their surround, within its noise ({noise:.3e})",
                        ti.to_degrees(),
                        table.meta.lambda_nm[j],
                        ej
                    )));
                }
                e.push(ej);
            }
            power.push(e);
        }
        let kappa = 1.0 / (width * width);
        Ok(SharpMirror {
            background,
            power,
            kappa,
            norm: kappa / (TAU * (1.0 - (-2.0 * kappa).exp())),
        })
    }

    /// [`crate::render::albedo_table`] of the lobe and the rest: the rest's by quadrature,
    /// the lobe's exactly, its power (a 48 x 96 quadrature would miss a 0.7-degree lobe).
    pub fn albedo_table(&self, n: usize) -> Vec<Vec<f64>> {
        let mut t = crate::render::albedo_table(&self.background, n);
        let mut e = vec![0.0; self.background.meta.lambda_nm.len()];
        for (k, row) in t.iter_mut().enumerate() {
            self.power_at((k as f64 + 0.5) / n as f64 * FRAC_PI_2, &mut e);
            row.iter_mut().zip(&e).for_each(|(v, x)| *v += x);
        }
        t
    }

    /// The table without its mirror.
    pub fn background(&self) -> &TableBrdf {
        &self.background
    }

    /// The mirror's power at the `i`-th simulated angle, per wavelength bin.
    pub fn power(&self, i: usize) -> &[f64] {
        &self.power[i]
    }

    /// The simulated angles around `theta_i` (radians) and the weight of the second: `E`
    /// is linear in `theta_i` between them, held beyond them.
    fn bracket(&self, theta_i: f64) -> (usize, usize, f64) {
        let ts = &self.background.theta_i_rad;
        let last = ts.len() - 1;
        if theta_i <= ts[0] {
            (0, 0, 0.0)
        } else if theta_i >= ts[last] {
            (last, last, 0.0)
        } else {
            let k = ts.partition_point(|&v| v <= theta_i) - 1;
            (k, k + 1, (theta_i - ts[k]) / (ts[k + 1] - ts[k]))
        }
    }

    /// The mirror's power for light arriving at `theta_i` radians, per wavelength bin (the
    /// lobe's albedo: `int f_m cos(theta_o) dw_o`), into `out`.
    pub fn power_at(&self, theta_i: f64, out: &mut [f64]) {
        let (i0, i1, a) = self.bracket(theta_i);
        for (j, o) in out.iter_mut().enumerate() {
            *o = (1.0 - a) * self.power[i0][j] + a * self.power[i1][j];
        }
    }

    /// Each simulated angle (degrees) with its mirror's power, the mean over wavelength.
    pub fn powers(&self) -> Vec<(f64, f64)> {
        self.background
            .theta_i_rad
            .iter()
            .zip(&self.power)
            .map(|(t, e)| {
                (
                    t.to_degrees(),
                    e.iter().sum::<f64>() / e.len().max(1) as f64,
                )
            })
            .collect()
    }

    /// `D_s(h)`, 1/sr, for a half vector at `theta_h` radians from the normal.
    pub fn facet_density(&self, theta_h: f64) -> f64 {
        self.norm * (self.kappa * (theta_h.cos() - 1.0)).exp()
    }

    /// The half-vector spread of `D_s`, degrees.
    pub fn width_deg(&self) -> f64 {
        self.kappa.sqrt().recip().to_degrees()
    }
}

/// The buckets that hold the mirror of light arriving at `theta_i` (radians) and the
/// ring of buckets around them. At normal incidence the mirror is the pole: the first
/// ring of buckets, surrounded by the second.
fn mirror_block(theta_i: f64, phi_i: f64, tb: usize, pb: usize) -> Block {
    let dt = FRAC_PI_2 / tb as f64;
    let dp = TAU / pb as f64;
    const EDGE: f64 = 1e-6;
    let x = theta_i / dt;
    if x < EDGE {
        return Block {
            inside: (0..pb).map(|p| (0, p)).collect(),
            around: (0..pb).map(|p| (1.min(tb - 1), p)).collect(),
        };
    }
    let t_lo = ((x - EDGE).floor().max(0.0) as usize).min(tb - 1);
    let t_hi = ((x + EDGE).floor() as usize).min(tb - 1);
    // The table stores phi_o - phi_i + the simulation's phi_i; the mirror is half a turn
    // from the incidence.
    let y = (PI + phi_i).rem_euclid(TAU) / dp;
    let p_lo = (y - EDGE).floor().rem_euclid(pb as f64) as usize;
    let p_hi = (y + EDGE).floor().rem_euclid(pb as f64) as usize;
    let rows: Vec<usize> = (t_lo..=t_hi).collect();
    let cols: Vec<usize> = if p_lo == p_hi {
        vec![p_lo]
    } else {
        vec![p_lo, p_hi]
    };
    let inside: Vec<(usize, usize)> = rows
        .iter()
        .flat_map(|&t| cols.iter().map(move |&p| (t, p)))
        .collect();
    let mut around = Vec::new();
    let (r0, r1) = (t_lo.saturating_sub(1), (t_hi + 1).min(tb - 1));
    for t in r0..=r1 {
        for k in 0..cols.len() + 2 {
            let p = (p_lo + pb - 1 + k) % pb;
            if !inside.contains(&(t, p)) && !around.contains(&(t, p)) {
                around.push((t, p));
            }
        }
    }
    Block { inside, around }
}

/// The median of `v` (reordered), the mean of the middle two for an even count.
fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

impl Brdf for SharpMirror {
    fn eval(&self, wi: DVec3, wo: DVec3, out: &mut [f64]) {
        self.background.eval(wi, wo, out);
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return;
        }
        let h = (wi + wo).normalize();
        let d = self.norm * (self.kappa * (h.z - 1.0)).exp();
        if d == 0.0 {
            return;
        }
        let w = d / (4.0 * wi.dot(h) * wo.z);
        let (i0, i1, a) = self.bracket(wi.z.clamp(-1.0, 1.0).acos());
        for (j, o) in out.iter_mut().enumerate() {
            *o += w * ((1.0 - a) * self.power[i0][j] + a * self.power[i1][j]);
        }
    }

    fn meta(&self) -> &Meta {
        &self.background.meta
    }
}

#[cfg(test)]
#[path = "mirror_tests.rs"]
mod tests;
