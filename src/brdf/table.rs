//! The dense baseline: a regular `(theta_i, theta_o, phi_o - phi_i)` grid at the simulated
//! incident angles and the bucket centres, with trilinear interpolation (periodic in
//! azimuth, clamped at the ends of the polar axes).

use std::f64::consts::TAU;

use super::{BucketData, Meta};
use crate::geom::angles;
use glam::DVec3;

#[derive(Clone, Debug)]
pub struct TableBrdf {
    /// Simulated incident angles, ascending (radians).
    pub theta_i_rad: Vec<f64>,
    pub theta_bins: usize,
    pub phi_bins: usize,
    /// Azimuth of the simulation's incidence, radians (the table stores phi_o - phi_i).
    pub phi_i_rad: f64,
    /// `values[((i * theta_bins + t) * phi_bins + p) * bins + j]`.
    pub values: Vec<f64>,
    pub meta: Meta,
}

/// Index and weight of linear interpolation in ascending `xs` (clamped at the ends).
#[inline]
fn bracket(xs: &[f64], x: f64) -> (usize, usize, f64) {
    if xs.len() == 1 || x <= xs[0] {
        return (0, 0, 0.0);
    }
    if x >= xs[xs.len() - 1] {
        let n = xs.len() - 1;
        return (n, n, 0.0);
    }
    let i = xs.partition_point(|&v| v <= x) - 1;
    (i, i + 1, (x - xs[i]) / (xs[i + 1] - xs[i]))
}

impl TableBrdf {
    pub fn build(data: &BucketData) -> TableBrdf {
        let nl = data.lambda_nm.len();
        let (tb, pb) = (
            data.buckets.theta_bins as usize,
            data.buckets.phi_bins as usize,
        );
        let mut order: Vec<usize> = (0..data.theta_i_rad.len()).collect();
        order.sort_by(|&a, &b| data.theta_i_rad[a].total_cmp(&data.theta_i_rad[b]));
        let mut values = Vec::with_capacity(order.len() * tb * pb * nl);
        for &i in &order {
            // Buckets are stored theta-major, phi-minor, as the table wants.
            for s in &data.samples[i] {
                values.extend_from_slice(&s.f);
            }
        }
        let mut meta = data.meta.clone();
        meta.repr = super::Kind::Table;
        meta.isotropic = true;
        TableBrdf {
            theta_i_rad: order.iter().map(|&i| data.theta_i_rad[i]).collect(),
            theta_bins: tb,
            phi_bins: pb,
            phi_i_rad: data.phi_i_rad,
            values,
            meta,
        }
    }
}

impl super::Brdf for TableBrdf {
    fn eval(&self, wi: DVec3, wo: DVec3, out: &mut [f64]) {
        let nl = out.len();
        out.fill(0.0);
        if wi[2] <= 0.0 || wo[2] <= 0.0 {
            return;
        }
        let (ti, pi) = angles(wi);
        let (to, po) = angles(wo);
        let (i0, i1, wi_t) = bracket(&self.theta_i_rad, ti);
        // theta_o between bucket centres. Below the first ring's centres the value runs
        // from the ring's to the pole's, the ring's mean: at theta_o = 0 every azimuth is
        // one direction, so the value may not depend on it (issue 71: the foil's BRDF
        // there was 32.9 or 60.7 1/sr by phi_o, through the sign of a zero).
        let dt = std::f64::consts::FRAC_PI_2 / self.theta_bins as f64;
        let raw = to / dt - 0.5;
        let pole = if raw < 0.0 { -2.0 * raw } else { 0.0 };
        let xt = raw.clamp(0.0, (self.theta_bins - 1) as f64);
        let t0 = xt.floor() as usize;
        let t1 = (t0 + 1).min(self.theta_bins - 1);
        let wt = xt - t0 as f64;
        // Relative azimuth in the simulation's frame, between bucket centres (periodic).
        let phi = (po - pi + self.phi_i_rad).rem_euclid(TAU);
        let dp = TAU / self.phi_bins as f64;
        let xp = (phi / dp - 0.5).rem_euclid(self.phi_bins as f64);
        let p0 = xp.floor() as usize % self.phi_bins;
        let p1 = (p0 + 1) % self.phi_bins;
        let wp = xp - xp.floor();
        for (i, wi_w) in [(i0, 1.0 - wi_t), (i1, wi_t)] {
            if wi_w == 0.0 {
                continue;
            }
            let mut add = |t: usize, p: usize, w: f64| {
                let base = ((i * self.theta_bins + t) * self.phi_bins + p) * nl;
                for (o, v) in out.iter_mut().zip(&self.values[base..base + nl]) {
                    *o += w * v;
                }
            };
            for (t, wt_w) in [(t0, 1.0 - wt), (t1, wt)] {
                for (p, wp_w) in [(p0, 1.0 - wp), (p1, wp)] {
                    let w = wi_w * wt_w * wp_w * (1.0 - pole);
                    if w != 0.0 {
                        add(t, p, w);
                    }
                }
            }
            if pole > 0.0 {
                for p in 0..self.phi_bins {
                    add(0, p, wi_w * pole / self.phi_bins as f64);
                }
            }
        }
    }

    fn meta(&self) -> &Meta {
        &self.meta
    }
}
