//! The seed's 4-D spherically parameterised kd-tree over bucket centres
//! `(theta_i, phi_i, theta_o, phi_o)`.
//!
//! Distance: the great-circle arc between the incident directions plus that between the
//! outgoing directions. Every node keeps the bounds of its points in each of the four
//! coordinates, and a query prunes a node with a lower bound that never over-estimates:
//! for each direction the larger of the polar-band bound `|theta - band|` (an arc is at
//! least its change in polar angle) and the azimuth-wedge bound, the arc to the nearer
//! bounding meridian. For a meridian within 90 degrees of azimuth that arc is half the arc
//! to the query's mirror image about the meridian plane (the seed's "reflected point"
//! trick): `asin(sin(theta) |sin(dphi)|)`, used through its lower bound
//! `sin(theta) |sin(dphi)|` so no trigonometric call is needed per node; beyond 90 degrees
//! the nearest point of the meridian is a pole. A k-nearest query is therefore exact (tested against brute force),
//! and the BRDF blends the k nearest buckets' intensities with a Gaussian kernel whose width
//! is the distance to the k-th neighbour, which follows the local bucket spacing.

use std::f64::consts::{PI, TAU};

use super::{BucketData, Meta, angles, arc, dir};
use glam::DVec3;

/// Points per leaf.
const LEAF: usize = 16;
/// `Node::a` of a leaf carries this bit.
const LEAF_BIT: u32 = 1 << 31;
/// Radians taken off every node bound, which is formed from single-precision bounds and
/// trigonometric values (relative error below 1e-7): the bound stays a lower bound.
const BOUND_SLACK: f64 = 1e-6;
/// Radians taken off the chord lower bound of a point's distance: a chord `sqrt(2 - 2
/// cos)` formed from a rounded cosine is off by at most `sqrt(1e-15)` near zero.
const CHORD_SLACK: f64 = 1e-7;

/// A node in 72 bytes (a leaf's points follow it in memory order of the build).
#[derive(Clone, Debug, PartialEq)]
struct Node {
    /// Bounds of `(theta_i, phi_i, theta_o, phi_o)`, rounded outwards to f32.
    lo: [f32; 4],
    hi: [f32; 4],
    /// Cosine and sine of the azimuth bounds, `[cos lo, sin lo, cos hi, sin hi]`, for the
    /// incident and the outgoing azimuth (f32; see [`BOUND_SLACK`]).
    trig: [[f32; 4]; 2],
    /// Inner node: children `a` and `b`; leaf (`a & LEAF_BIT`): points `a & !LEAF_BIT..b`.
    a: u32,
    b: u32,
}

impl Node {
    fn is_leaf(&self) -> bool {
        self.a & LEAF_BIT != 0
    }
}

/// `x` (finite) rounded to f32 towards minus (`down`) or plus infinity.
fn f32_outward(x: f64, down: bool) -> f32 {
    let f = x as f32;
    // One f32 step towards minus (`up` false) or plus infinity.
    let step = |f: f32, up: bool| {
        if f == 0.0 {
            let tiny = f32::from_bits(1);
            return if up { tiny } else { -tiny };
        }
        let b = f.to_bits();
        f32::from_bits(if (f > 0.0) == up { b + 1 } else { b - 1 })
    };
    match (down, f64::from(f) > x, f64::from(f) < x) {
        (true, true, _) => step(f, false),
        (false, _, true) => step(f, true),
        _ => f,
    }
}

/// A query: angles, their sines, and unit vectors.
struct Query {
    c: [f64; 4],
    /// Cosine and sine of the two azimuths.
    cs: [f64; 4],
    sin_i: f64,
    sin_o: f64,
    wi: DVec3,
    wo: DVec3,
}

/// A kd-tree over points `(theta_i, phi_i, theta_o, phi_o)` (radians).
///
/// Layout for the cache: nodes of 72 bytes with single-precision bounds in depth-first
/// order, and each point's two unit vectors side by side (48 bytes) in tree order, so a
/// leaf's points are contiguous.
#[derive(Clone, Debug, PartialEq)]
pub struct KdTree {
    nodes: Vec<Node>,
    /// Points in tree order: coordinates, and `wi` then `wo`.
    coords: Vec<[f64; 4]>,
    w: Vec<[f64; 6]>,
    /// Tree order -> original index.
    index: Vec<u32>,
}

/// Lower bound of the arc from a query direction (polar angle `tq`, its sine, azimuth `pq`
/// with cosine and sine `cq`, `sq`) to any direction with theta in `[tlo, thi]` and phi in
/// `[plo, phi_hi]` (whose cosines and sines are `trig`). Never over-estimates:
/// - an arc is at least its change in polar angle (band bound);
/// - outside the azimuth wedge, the arc to the nearer bounding meridian: for a meridian
///   within 90 degrees, `asin(sin(theta) |sin(dphi)|)` (half the arc to the mirror image),
///   bounded below by its argument since `asin(x) >= x`; beyond 90 degrees the nearest
///   point of the meridian is a pole, `min(theta, pi - theta)`.
#[inline]
#[allow(clippy::too_many_arguments)]
fn direction_bound(
    tq: f64,
    sin_tq: f64,
    pq: f64,
    cq: f64,
    sq: f64,
    tlo: f64,
    thi: f64,
    plo: f64,
    phi_hi: f64,
    trig: &[f64; 4],
) -> f64 {
    let band = (tlo - tq).max(tq - thi).max(0.0);
    if pq >= plo && pq <= phi_hi {
        return band;
    }
    let semicircle = |c: f64, s: f64| {
        if cq * c + sq * s >= 0.0 {
            sin_tq * (sq * c - cq * s).abs()
        } else {
            tq.min(PI - tq)
        }
    };
    band.max(semicircle(trig[0], trig[1]).min(semicircle(trig[2], trig[3])))
}

impl KdTree {
    /// Builds the tree over `points` (any order).
    pub fn build(points: &[[f64; 4]]) -> KdTree {
        assert!(
            (points.len() as u64) < u64::from(LEAF_BIT),
            "a kd-tree holds fewer than 2^31 points"
        );
        let mut idx: Vec<u32> = (0..points.len() as u32).collect();
        let mut nodes = Vec::new();
        if !points.is_empty() {
            Self::build_rec(points, &mut idx, 0, points.len(), &mut nodes);
        }
        let coords: Vec<[f64; 4]> = idx.iter().map(|&i| points[i as usize]).collect();
        KdTree {
            nodes,
            w: coords
                .iter()
                .map(|c| {
                    let (a, b) = (dir(c[0], c[1]), dir(c[2], c[3]));
                    [a.x, a.y, a.z, b.x, b.y, b.z]
                })
                .collect(),
            coords,
            index: idx,
        }
    }

    fn build_rec(
        points: &[[f64; 4]],
        idx: &mut [u32],
        start: usize,
        end: usize,
        nodes: &mut Vec<Node>,
    ) -> u32 {
        let mut lo = [f64::INFINITY; 4];
        let mut hi = [f64::NEG_INFINITY; 4];
        for &i in &idx[start..end] {
            for d in 0..4 {
                lo[d] = lo[d].min(points[i as usize][d]);
                hi[d] = hi[d].max(points[i as usize][d]);
            }
        }
        let me = nodes.len() as u32;
        let t = |d: usize| [lo[d].cos(), lo[d].sin(), hi[d].cos(), hi[d].sin()].map(|v| v as f32);
        nodes.push(Node {
            lo: lo.map(|v| f32_outward(v, true)),
            hi: hi.map(|v| f32_outward(v, false)),
            trig: [t(1), t(3)],
            a: start as u32 | LEAF_BIT,
            b: end as u32,
        });
        if end - start <= LEAF {
            return me;
        }
        // Split the dimension of largest extent (azimuths count half: they matter less
        // near the poles), at the median.
        let ext = |d: usize| (hi[d] - lo[d]) * if d % 2 == 1 { 0.5 } else { 1.0 };
        let dim = (0..4)
            .max_by(|&a, &b| ext(a).total_cmp(&ext(b)))
            .unwrap_or(0);
        if ext(dim) <= 0.0 {
            return me; // all points coincide
        }
        let mid = (start + end) / 2;
        idx[start..end].select_nth_unstable_by(mid - start, |&a, &b| {
            points[a as usize][dim]
                .total_cmp(&points[b as usize][dim])
                .then(a.cmp(&b))
        });
        let a = Self::build_rec(points, idx, start, mid, nodes);
        let b = Self::build_rec(points, idx, mid, end, nodes);
        let n = &mut nodes[me as usize];
        n.a = a;
        n.b = b;
        me
    }

    pub fn len(&self) -> usize {
        self.coords.len()
    }

    /// Bytes the tree holds on the heap (nodes, points, vectors, index).
    pub fn heap_bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<Node>()
            + self.coords.len() * std::mem::size_of::<[f64; 4]>()
            + self.w.len() * std::mem::size_of::<[f64; 6]>()
            + self.index.len() * 4
    }

    pub fn is_empty(&self) -> bool {
        self.coords.is_empty()
    }

    #[inline]
    fn node_bound(&self, n: &Node, q: &Query) -> f64 {
        let (lo, hi) = (n.lo.map(f64::from), n.hi.map(f64::from));
        let (ti, to) = (n.trig[0].map(f64::from), n.trig[1].map(f64::from));
        direction_bound(
            q.c[0], q.sin_i, q.c[1], q.cs[0], q.cs[1], lo[0], hi[0], lo[1], hi[1], &ti,
        ) + direction_bound(
            q.c[2], q.sin_o, q.c[3], q.cs[2], q.cs[3], lo[2], hi[2], lo[3], hi[3], &to,
        ) - 2.0 * BOUND_SLACK
    }

    /// The `k` nearest points to `(wi, wo)`: `(distance, original index)`, sorted by
    /// distance then index, into `out` (cleared first).
    pub fn nearest(&self, wi: DVec3, wo: DVec3, k: usize, out: &mut Vec<(f64, u32)>) {
        out.clear();
        if self.nodes.is_empty() || k == 0 {
            return;
        }
        let (ti, pi) = angles(wi);
        let (to, po) = angles(wo);
        let q = Query {
            c: [ti, pi, to, po],
            cs: [pi.cos(), pi.sin(), po.cos(), po.sin()],
            sin_i: ti.sin(),
            sin_o: to.sin(),
            wi,
            wo,
        };
        self.search(0, &q, k, out);
    }

    fn search(&self, node: u32, q: &Query, k: usize, out: &mut Vec<(f64, u32)>) {
        let n = &self.nodes[node as usize];
        if n.is_leaf() {
            let (wi, wo) = (q.wi, q.wo);
            // Once k candidates are held, two tests reject most points without a
            // trigonometric call: each arc alone is at most the full distance, so a point
            // whose incident or outgoing cosine is below cos(worst) cannot qualify (the
            // 1e-12 margin keeps the test conservative where cosines of tiny arcs round to
            // 1); and an arc is at least its chord `sqrt(2 - 2 cos)`, so the sum of the two
            // chords (less CHORD_SLACK) bounds the distance from below.
            let mut worst = if out.len() < k {
                f64::INFINITY
            } else {
                out[out.len() - 1].0
            };
            let mut cos_worst = if out.len() < k {
                -2.0
            } else {
                worst.min(PI).cos() - 1e-12
            };
            for p in (n.a & !LEAF_BIT) as usize..n.b as usize {
                let v = &self.w[p];
                let (pi, po) = (DVec3::new(v[0], v[1], v[2]), DVec3::new(v[3], v[4], v[5]));
                let (ci, co) = (wi.dot(pi), wo.dot(po));
                if ci < cos_worst || co < cos_worst {
                    continue;
                }
                let chords = (2.0 - 2.0 * ci).max(0.0).sqrt() + (2.0 - 2.0 * co).max(0.0).sqrt();
                if chords - CHORD_SLACK > worst {
                    continue;
                }
                let d = arc(wi, pi) + arc(wo, po);
                let id = self.index[p];
                let better = out.len() < k || {
                    let w = out[out.len() - 1];
                    d < w.0 || (d == w.0 && id < w.1)
                };
                if better {
                    let pos = out.partition_point(|e| e.0 < d || (e.0 == d && e.1 < id));
                    out.insert(pos, (d, id));
                    if out.len() > k {
                        out.pop();
                    }
                    if out.len() == k {
                        worst = out[k - 1].0;
                        cos_worst = worst.min(PI).cos() - 1e-12;
                    }
                }
            }
            return;
        }
        let (ba, bb) = (
            self.node_bound(&self.nodes[n.a as usize], q),
            self.node_bound(&self.nodes[n.b as usize], q),
        );
        let (first, second, b1, b2) = if ba <= bb {
            (n.a, n.b, ba, bb)
        } else {
            (n.b, n.a, bb, ba)
        };
        for (child, bound) in [(first, b1), (second, b2)] {
            // `<=` keeps exact ties (equal distance, lower index) reachable.
            if out.len() < k || bound <= out[out.len() - 1].0 {
                self.search(child, q, k, out);
            }
        }
    }

    /// Brute-force k nearest, same ordering: the reference for tests and benchmarks.
    pub fn nearest_brute(&self, wi: DVec3, wo: DVec3, k: usize) -> Vec<(f64, u32)> {
        let mut all: Vec<(f64, u32)> = (0..self.len())
            .map(|p| {
                let v = &self.w[p];
                let (pi, po) = (DVec3::new(v[0], v[1], v[2]), DVec3::new(v[3], v[4], v[5]));
                (arc(wi, pi) + arc(wo, po), self.index[p])
            })
            .collect();
        all.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        all.truncate(k);
        all
    }

    /// Checks the tree's invariants: every point lies inside its leaf's and ancestors'
    /// bounds, and every point is in exactly one leaf.
    #[allow(clippy::needless_range_loop)] // p indexes points and their flags alike
    pub fn validate(&self) -> Result<(), String> {
        let mut seen = vec![false; self.len()];
        let mut stack = vec![(0u32, [f64::NEG_INFINITY; 4], [f64::INFINITY; 4])];
        while let Some((i, plo, phi)) = stack.pop() {
            let n = &self.nodes[i as usize];
            let (lo, hi) = (n.lo.map(f64::from), n.hi.map(f64::from));
            for d in 0..4 {
                if lo[d] < plo[d] || hi[d] > phi[d] {
                    return Err(format!(
                        "node {i} exceeds its parent's bounds in dimension {d}"
                    ));
                }
            }
            if n.is_leaf() {
                for p in (n.a & !LEAF_BIT) as usize..n.b as usize {
                    if seen[p] {
                        return Err(format!("point {p} in two leaves"));
                    }
                    seen[p] = true;
                    for d in 0..4 {
                        if self.coords[p][d] < lo[d] || self.coords[p][d] > hi[d] {
                            return Err(format!("point {p} outside leaf {i}"));
                        }
                    }
                }
            } else {
                stack.push((n.a, lo, hi));
                stack.push((n.b, lo, hi));
            }
        }
        match seen.iter().position(|s| !s) {
            Some(p) => Err(format!("point {p} in no leaf")),
            None => Ok(()),
        }
    }
}

/// Most neighbours a kd-tree BRDF blends per query (`build --k`; checked on reading).
pub const MAX_K: usize = 1024;

/// The kd-tree BRDF: the tree plus a spectrum per point.
pub struct KdTreeBrdf {
    pub tree: KdTree,
    /// The points in their original order (what the file stores; the tree is rebuilt,
    /// deterministically, on load).
    pub points: Vec<[f64; 4]>,
    /// BRDF values, point-major (`values[i * bins + j]`).
    pub values: Vec<f64>,
    pub k: usize,
    pub meta: Meta,
}

impl KdTreeBrdf {
    /// Builds from buckets. `isotropic` stores `phi_o - phi_i` with `phi_i = 0`;
    /// `reciprocal` also enters every bucket as `(wo, wi)`.
    pub fn build(data: &BucketData, k: usize, isotropic: bool, reciprocal: bool) -> KdTreeBrdf {
        let nl = data.wavelengths_nm.len();
        let mut pts = Vec::new();
        let mut values = Vec::new();
        for per in &data.samples {
            for s in per {
                let (pi, po) = if isotropic {
                    (0.0, (s.phi_o - s.phi_i).rem_euclid(TAU))
                } else {
                    (s.phi_i, s.phi_o)
                };
                pts.push([s.theta_i, pi, s.theta_o, po]);
                values.extend_from_slice(&s.f);
                if reciprocal {
                    // (wo, wi): with phi_i moved to 0 when isotropic.
                    let (pi2, po2) = if isotropic {
                        (0.0, (pi - po).rem_euclid(TAU))
                    } else {
                        (po, pi)
                    };
                    pts.push([s.theta_o, pi2, s.theta_i, po2]);
                    values.extend_from_slice(&s.f);
                }
            }
        }
        debug_assert_eq!(values.len(), pts.len() * nl);
        let mut meta = data.meta.clone();
        meta.repr = super::Kind::Kdtree;
        meta.isotropic = isotropic;
        meta.reciprocal = reciprocal;
        KdTreeBrdf::from_parts(pts, values, k, meta)
    }

    /// Rebuilds from stored points and values.
    pub fn from_parts(points: Vec<[f64; 4]>, values: Vec<f64>, k: usize, meta: Meta) -> KdTreeBrdf {
        KdTreeBrdf {
            tree: KdTree::build(&points),
            points,
            values,
            k: k.max(1),
            meta,
        }
    }

    fn query_dirs(&self, wi: DVec3, wo: DVec3) -> (DVec3, DVec3) {
        if !self.meta.isotropic {
            return (wi, wo);
        }
        let (ti, pi) = angles(wi);
        let (to, po) = angles(wo);
        (dir(ti, 0.0), dir(to, (po - pi).rem_euclid(TAU)))
    }
}

impl super::Brdf for KdTreeBrdf {
    /// With the reciprocal option the result is the mean of the blends at `(wi, wo)` and
    /// `(wo, wi)` over the symmetric point set, so it is reciprocal exactly.
    fn eval(&self, wi: DVec3, wo: DVec3, out: &mut [f64]) {
        if self.meta.reciprocal {
            let mut other = vec![0.0; out.len()];
            self.blend(wi, wo, out);
            self.blend(wo, wi, &mut other);
            for (o, x) in out.iter_mut().zip(&other) {
                *o = 0.5 * (*o + x);
            }
        } else {
            self.blend(wi, wo, out);
        }
    }

    fn meta(&self) -> &Meta {
        &self.meta
    }
}

impl KdTreeBrdf {
    fn blend(&self, wi: DVec3, wo: DVec3, out: &mut [f64]) {
        thread_local! {
            static NEAR: std::cell::RefCell<Vec<(f64, u32)>> = const { std::cell::RefCell::new(Vec::new()) };
        }
        let (qi, qo) = self.query_dirs(wi, wo);
        let nl = out.len();
        out.fill(0.0);
        NEAR.with(|cell| {
            let mut near = cell.borrow_mut();
            self.tree.nearest(qi, qo, self.k, &mut near);
            if near.is_empty() {
                return;
            }
            let h = near[near.len() - 1].0.max(1e-9);
            let mut wsum = 0.0;
            for &(d, i) in near.iter() {
                let w = (-(d / h).powi(2)).exp();
                wsum += w;
                let v = &self.values[i as usize * nl..(i as usize + 1) * nl];
                for (o, x) in out.iter_mut().zip(v) {
                    *o += w * x;
                }
            }
            for o in out.iter_mut() {
                *o /= wsum;
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outward_rounding_brackets_the_value() {
        let mut x = 0.37f64;
        for k in 0..100_000 {
            x = (x * 7.13 + 0.31).fract() * TAU - if k % 3 == 0 { PI } else { 0.0 };
            for v in [x, -x, 0.0, 1e-300, -1e-300, PI, TAU] {
                let (lo, hi) = (f32_outward(v, true), f32_outward(v, false));
                assert!(f64::from(lo) <= v && v <= f64::from(hi), "{v}: {lo} {hi}");
                // At most one f32 step apart from the nearest.
                assert!(
                    f64::from(hi) - f64::from(lo)
                        <= 2.0 * f64::from(f32::EPSILON) * v.abs().max(1e-38)
                );
            }
        }
    }
}
