//! Gondek, Meyer & Newman's adaptively subdivided hemisphere ("Wavelength Dependent
//! Reflectance Functions", SIGGRAPH 1994, §4): for each simulated incident direction the
//! outgoing hemisphere is a quad-tree of (theta, phi) cells over the fine simulation
//! buckets. A cell splits into four where the RMS deviation of its children's spectral
//! reflectance from its own exceeds a tolerance (relative), and the deviation is
//! significant (twice) against the children's statistical error, so the samples support it. A leaf
//! keeps its spectral flux and its exact projected solid angle, so the flux of all leaves is
//! the accumulated total. Queries locate the leaf of the outgoing direction and interpolate
//! linearly between the two nearest simulated incident angles.

use std::f64::consts::TAU;

use super::{BucketData, Meta};
use crate::accumulate::Buckets;
use crate::geom::angles;
use glam::DVec3;

/// A quad-tree cell over bucket index ranges `[t0, t1) x [p0, p1)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cell {
    pub t0: u32,
    pub t1: u32,
    pub p0: u32,
    pub p1: u32,
    /// First child (four consecutive cells), or `u32::MAX` for a leaf.
    pub child: u32,
    /// Projected solid angle, sr.
    pub omega: f64,
}

#[derive(Clone, Debug)]
pub struct SubdividedBrdf {
    /// Simulated incident angles, ascending (radians).
    pub theta_i_rad: Vec<f64>,
    /// Incident azimuth, radians.
    pub phi_i_rad: f64,
    pub buckets: Buckets,
    /// Per incident angle: the cells (root first) and their spectral flux
    /// (`flux[c * bins + j]`, fraction of launched power).
    pub cells: Vec<Vec<Cell>>,
    pub flux: Vec<Vec<f64>>,
    pub tolerance: f64,
    pub meta: Meta,
}

impl SubdividedBrdf {
    /// Builds with relative RMS tolerance `tolerance` (e.g. 0.05).
    pub fn build(data: &BucketData, tolerance: f64) -> SubdividedBrdf {
        let nl = data.lambda_nm.len();
        let b = data.buckets;
        let (tb, pb) = (b.theta_bins, b.phi_bins);
        let mut order: Vec<usize> = (0..data.theta_i_rad.len()).collect();
        order.sort_by(|&a, &c| data.theta_i_rad[a].total_cmp(&data.theta_i_rad[c]));
        let mut all_cells = Vec::new();
        let mut all_flux = Vec::new();
        for &i in &order {
            let samples = &data.samples[i];
            let mut cells = vec![Cell {
                t0: 0,
                t1: tb,
                p0: 0,
                p1: pb,
                child: u32::MAX,
                omega: 0.0,
            }];
            let mut flux: Vec<f64> = Vec::new();
            let sum_cell = |c: &Cell| -> (Vec<f64>, f64, f64) {
                let mut f = vec![0.0; nl];
                let (mut om, mut err, mut wsum) = (0.0, 0.0, 0.0);
                for t in c.t0..c.t1 {
                    for p in c.p0..c.p1 {
                        let s = &samples[(t * pb + p) as usize];
                        for (a, x) in f.iter_mut().zip(&s.flux) {
                            *a += x;
                        }
                        om += s.omega;
                        let w: f64 = s.flux.iter().map(|x| x.abs()).sum();
                        if let Some(e) = s.rel_stderr {
                            err += w * e;
                            wsum += w;
                        }
                    }
                }
                (f, om, if wsum > 0.0 { err / wsum } else { 0.0 })
            };
            // Breadth-first: cells are appended, children as four consecutive entries.
            let mut k = 0;
            while k < cells.len() {
                let c = cells[k];
                let (f, om, noise) = sum_cell(&c);
                cells[k].omega = om;
                flux.extend_from_slice(&f);
                let can_t = c.t1 - c.t0 > 1;
                let can_p = c.p1 - c.p0 > 1;
                if can_t || can_p {
                    let tm = if can_t { (c.t0 + c.t1) / 2 } else { c.t1 };
                    let pm = if can_p { (c.p0 + c.p1) / 2 } else { c.p1 };
                    let kids = [
                        Cell {
                            t0: c.t0,
                            t1: tm,
                            p0: c.p0,
                            p1: pm,
                            child: u32::MAX,
                            omega: 0.0,
                        },
                        Cell {
                            t0: c.t0,
                            t1: tm,
                            p0: pm,
                            p1: c.p1,
                            child: u32::MAX,
                            omega: 0.0,
                        },
                        Cell {
                            t0: tm,
                            t1: c.t1,
                            p0: c.p0,
                            p1: pm,
                            child: u32::MAX,
                            omega: 0.0,
                        },
                        Cell {
                            t0: tm,
                            t1: c.t1,
                            p0: pm,
                            p1: c.p1,
                            child: u32::MAX,
                            omega: 0.0,
                        },
                    ];
                    // Deviation of the children's reflectance (flux / omega) from the cell's.
                    let parent: Vec<f64> = f.iter().map(|x| x / om.max(1e-300)).collect();
                    let mean = parent.iter().map(|x| x.abs()).sum::<f64>() / nl as f64;
                    let (mut dev, mut n) = (0.0, 0.0);
                    for kid in kids.iter().filter(|k| k.t1 > k.t0 && k.p1 > k.p0) {
                        let (kf, kom, _) = sum_cell(kid);
                        for (a, p) in kf.iter().zip(&parent) {
                            dev += (a / kom.max(1e-300) - p).powi(2) * kom;
                            n += kom;
                        }
                    }
                    let rms = if n > 0.0 { (dev / n).sqrt() } else { 0.0 };
                    let rel = if mean > 0.0 { rms / mean } else { 0.0 };
                    // A child averages its buckets, so its relative error is about the
                    // buckets' divided by the square root of how many it holds.
                    let smallest = kids
                        .iter()
                        .filter(|k| k.t1 > k.t0 && k.p1 > k.p0)
                        .map(|k| ((k.t1 - k.t0) * (k.p1 - k.p0)) as f64)
                        .fold(f64::INFINITY, f64::min);
                    let child_noise = noise / smallest.max(1.0).sqrt();
                    if rel > tolerance && rel > 2.0 * child_noise {
                        cells[k].child = cells.len() as u32;
                        cells.extend(kids);
                    }
                }
                k += 1;
            }
            all_cells.push(cells);
            all_flux.push(flux);
        }
        let mut meta = data.meta.clone();
        meta.repr = super::Kind::Subdivided;
        meta.isotropic = true;
        SubdividedBrdf {
            theta_i_rad: order.iter().map(|&i| data.theta_i_rad[i]).collect(),
            phi_i_rad: data.phi_i_rad,
            buckets: b,
            cells: all_cells,
            flux: all_flux,
            tolerance,
            meta,
        }
    }

    /// Leaves of incident angle `i`: indices into `cells[i]`.
    pub fn leaves(&self, i: usize) -> impl Iterator<Item = usize> + '_ {
        self.cells[i]
            .iter()
            .enumerate()
            .filter(|(_, c)| c.child == u32::MAX)
            .map(|(k, _)| k)
    }

    /// Empty child cells (zero-width ranges) are skipped when descending.
    fn locate(&self, i: usize, t: u32, p: u32) -> usize {
        let cells = &self.cells[i];
        let mut k = 0usize;
        loop {
            let c = &cells[k];
            if c.child == u32::MAX {
                return k;
            }
            let first = c.child as usize;
            k = (first..first + 4)
                .find(|&m| {
                    let d = &cells[m];
                    t >= d.t0 && t < d.t1 && p >= d.p0 && p < d.p1
                })
                .expect("children partition their parent");
        }
    }

    fn eval_at(&self, i: usize, t: u32, p: u32, w: f64, out: &mut [f64]) {
        let nl = out.len();
        let k = self.locate(i, t, p);
        let om = self.cells[i][k].omega.max(1e-300);
        for (o, f) in out.iter_mut().zip(&self.flux[i][k * nl..(k + 1) * nl]) {
            *o += w * f / om;
        }
    }
}

impl super::Brdf for SubdividedBrdf {
    fn eval(&self, wi: DVec3, wo: DVec3, out: &mut [f64]) {
        out.fill(0.0);
        if wi[2] <= 0.0 || wo[2] <= 0.0 {
            return;
        }
        let (ti, pi) = angles(wi);
        let (to, po) = angles(wo);
        let phi = (po - pi + self.phi_i_rad).rem_euclid(TAU);
        let k = self.buckets.index(crate::geom::from_spherical(to, phi));
        let (t, p) = (
            k as u32 / self.buckets.phi_bins,
            k as u32 % self.buckets.phi_bins,
        );
        // At theta_o = 0 every azimuth is one direction: the pole takes the mean of the
        // first ring's cells, whatever phi_o says (the table's pole: `table.rs`).
        let pole = wo[0] == 0.0 && wo[1] == 0.0;
        let at = |i: usize, w: f64, out: &mut [f64]| {
            if pole {
                let n = self.buckets.phi_bins;
                for q in 0..n {
                    self.eval_at(i, 0, q, w / f64::from(n), out);
                }
            } else {
                self.eval_at(i, t, p, w, out);
            }
        };
        let xs = &self.theta_i_rad;
        if xs.len() == 1 || ti <= xs[0] {
            at(0, 1.0, out);
        } else if ti >= xs[xs.len() - 1] {
            at(xs.len() - 1, 1.0, out);
        } else {
            let i = xs.partition_point(|&v| v <= ti) - 1;
            let w = (ti - xs[i]) / (xs[i + 1] - xs[i]);
            at(i, 1.0 - w, out);
            at(i + 1, w, out);
        }
    }

    fn meta(&self) -> &Meta {
        &self.meta
    }
}
