//! A kd-tree over bucket centres `(theta_i, phi_i, theta_o, phi_o)`, the seed's 4-D
//! spherical parameterisation, for exact k-nearest queries.
//!
//! Distance: the great-circle arc between the incident directions plus that between the
//! outgoing directions (radians), as in the seed. The tree partitions the points by their
//! two unit vectors, six Cartesian coordinates, which have no seam at `phi = 2 pi` and no
//! pole. A chord never exceeds its arc (`chord = 2 sin(arc / 2)`), so the Euclidean
//! distance from a query direction to an axis-aligned box of directions bounds from below
//! the arc to any direction inside it, and the sum of the two bounds a node's distance
//! (tighter than the arc sum by `arc^2 / 24` relative). A k-nearest query is therefore exact
//! (tested against brute force), and the BRDF blends the k nearest buckets' intensities with
//! a Gaussian kernel whose width is the distance to the k-th neighbour, which follows the
//! local bucket spacing.
//!
//! Layout for the cache and for SSE: each inner node holds both children's boxes (single
//! precision, rounded outwards) in two aligned cache lines, coordinate by coordinate across
//! the four directions, so one fetch and a few 4-lane operations bound both children. A
//! leaf's points are also kept in single precision, four to a group, and the sum of their
//! two chords less a stated slack rejects most points before the exact double-precision arc,
//! whose vectors sit in the same group (one stretch of memory per leaf).

use super::BrdfError;
use std::f64::consts::TAU;

use super::{BucketData, Meta, arc};
use crate::geom::from_spherical;
use glam::{DVec3, Vec4};

/// Points per leaf.
const LEAF: usize = 16;
/// A child reference with this bit is a leaf: its first group.
const LEAF_BIT: u32 = 1 << 31;
/// `Group::id` of a lane past its leaf's last point.
const PAD: u32 = u32::MAX;
/// Radians taken off every single-precision chord sum, box or point. Unit-vector
/// coordinates rounded to f32 are off by at most 3e-8 each, and the differences, squares,
/// square roots and the sum of two chords (each at most 2) add a few f32 roundings of
/// values up to 4 (2.4e-7 each): the error stays below 3e-6, so the sum less this slack
/// never exceeds the exact chord sum, which never exceeds the arc sum.
const F32_SLACK: f64 = 1e-5;

/// An axis-aligned box of `(wi, wo)`: `lo` and `hi` of the six coordinates.
type Bounds = [[f32; 6]; 2];

/// A subtree: an inner node's number, or a leaf's first group with [`LEAF_BIT`] and its
/// number of groups.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Child {
    at: u32,
    groups: u32,
}

/// An inner node: both children's boxes and references (two aligned cache lines). Lane
/// order of each vector: child 0's incident and outgoing parts, then child 1's.
#[derive(Clone, Debug, PartialEq)]
#[repr(C, align(64))]
struct Node {
    /// Lower then upper bounds of x, y and z.
    lo: [Vec4; 3],
    hi: [Vec4; 3],
    child: [Child; 2],
}

impl Node {
    fn new(boxes: [Bounds; 2], child: [Child; 2]) -> Node {
        let lanes = |side: usize, c: usize| {
            Vec4::new(
                boxes[0][side][c],
                boxes[0][side][c + 3],
                boxes[1][side][c],
                boxes[1][side][c + 3],
            )
        };
        Node {
            lo: [0, 1, 2].map(|c| lanes(0, c)),
            hi: [0, 1, 2].map(|c| lanes(1, c)),
            child,
        }
    }

    /// Child `c`'s box.
    fn bounds(&self, c: usize) -> Bounds {
        let get = |v: &[Vec4; 3], d: usize| v[d % 3][2 * c + d / 3];
        [
            std::array::from_fn(|d| get(&self.lo, d)),
            std::array::from_fn(|d| get(&self.hi, d)),
        ]
    }

    /// Lower bounds (radians, [`F32_SLACK`] included) of the distance from the query to
    /// any point in each child's box: the Euclidean distance from `wi` to the box's
    /// incident part plus that from `wo` to its outgoing part, each at most the chord and
    /// so at most the arc. `q` holds `(wi, wo, wi, wo)` lane-wise for x, y and z.
    #[inline]
    fn bounds_to(&self, q: &[Vec4; 3]) -> (f64, f64) {
        let mut d2 = Vec4::ZERO;
        for ((lo, hi), q) in self.lo.iter().zip(&self.hi).zip(q) {
            let e = (*lo - *q).max(*q - *hi).max(Vec4::ZERO);
            d2 += e * e;
        }
        let d = sqrt4(d2);
        (
            f64::from(d.x + d.y) - F32_SLACK,
            f64::from(d.z + d.w) - F32_SLACK,
        )
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

/// Lane-wise square root written so that LLVM emits one `sqrtps` (glam's `Vec4::sqrt`
/// takes four scalar roots).
#[inline(always)]
fn sqrt4(v: Vec4) -> Vec4 {
    Vec4::from_array(v.to_array().map(f32::sqrt))
}

/// The chords (single precision) from the query direction `q` (each coordinate splat) to
/// four points' incident (`off` 0) or outgoing (`off` 3) directions.
#[inline(always)]
fn chords(v: &[Vec4; 6], off: usize, q: &[Vec4; 3]) -> Vec4 {
    let (dx, dy, dz) = (v[off] - q[0], v[off + 1] - q[1], v[off + 2] - q[2]);
    sqrt4(dx * dx + dy * dy + dz * dz)
}

/// An upper bound of the arc (radians) whose chord is `c`: the arc `2 asin(c / 2)` is at
/// most `c (1 + c^2 / 12)` for `c <= 1` (its series is `c + c^3/24 + 3 c^5/640 + ...`) and
/// at most `c pi / 2` beyond (`arc / c` grows with `c` to `pi / 2` at `c = 2`).
#[inline]
fn arc_upper(c: f32) -> f32 {
    if c <= 1.0 {
        c * (1.0 + c * c / 12.0)
    } else {
        c * std::f32::consts::FRAC_PI_2
    }
}

/// Four points of a leaf: single-precision coordinates lane by lane (`wi` x, y, z, then
/// `wo`), their original indices, and their exact vectors for the arcs, side by side so a
/// point's arc reads memory next to what its bound read. A leaf's lanes past its last
/// point repeat that point with the index [`PAD`].
#[derive(Clone, Debug, PartialEq)]
#[repr(C, align(16))]
struct Group {
    v: [Vec4; 6],
    id: [u32; 4],
    /// `wi` then `wo` of each lane.
    w: [[f64; 6]; 4],
}

/// A kd-tree over points `(theta_i, phi_i, theta_o, phi_o)` (radians).
#[derive(Clone, Debug, PartialEq)]
pub struct KdTree {
    nodes: Vec<Node>,
    /// The root and its box.
    root: Child,
    root_box: Bounds,
    /// Four points per group, each leaf's starting a new group.
    groups: Vec<Group>,
    /// Points held (padding not counted).
    len: usize,
}

impl KdTree {
    /// Builds the tree over `points` (any order).
    pub fn build(points: &[[f64; 4]]) -> KdTree {
        assert!(
            (points.len() as u64) < u64::from(LEAF_BIT) / 4,
            "a kd-tree holds fewer than 2^29 points"
        );
        let all: Vec<[f64; 6]> = points
            .iter()
            .map(|c| {
                let (a, b) = (from_spherical(c[0], c[1]), from_spherical(c[2], c[3]));
                [a.x, a.y, a.z, b.x, b.y, b.z]
            })
            .collect();
        let mut idx: Vec<u32> = (0..points.len() as u32).collect();
        let mut tree = KdTree {
            nodes: Vec::new(),
            root: Child {
                at: LEAF_BIT,
                groups: 0,
            },
            root_box: [[0.0; 6]; 2],
            groups: Vec::new(),
            len: points.len(),
        };
        if !points.is_empty() {
            let (root, root_box) = tree.build_rec(&all, &mut idx, 0, points.len());
            tree.root = root;
            tree.root_box = root_box;
        }
        // A query walks some 30 nodes and groups at random places in arrays of up to a few
        // hundred MB: on 2 MiB pages most of those walks stay within the TLB.
        tree.nodes = crate::machine::with_huge_pages(tree.nodes);
        tree.groups = crate::machine::with_huge_pages(tree.groups);
        tree
    }

    /// Starts loading the first cache line of a child (a node, or a leaf's first group),
    /// so that its fetch overlaps the work on its parent.
    #[inline(always)]
    fn prefetch(&self, c: Child) {
        let at = (c.at & !LEAF_BIT) as usize;
        if c.at & LEAF_BIT == 0 {
            if let Some(n) = self.nodes.get(at) {
                crate::machine::prefetch(n);
            }
        } else if let Some(g) = self.groups.get(at) {
            crate::machine::prefetch(g);
        }
    }

    /// Builds the subtree over `idx[start..end]`: its reference and box.
    fn build_rec(
        &mut self,
        all: &[[f64; 6]],
        idx: &mut [u32],
        start: usize,
        end: usize,
    ) -> (Child, Bounds) {
        let mut lo = [f64::INFINITY; 6];
        let mut hi = [f64::NEG_INFINITY; 6];
        for &i in &idx[start..end] {
            for d in 0..6 {
                lo[d] = lo[d].min(all[i as usize][d]);
                hi[d] = hi[d].max(all[i as usize][d]);
            }
        }
        let bounds = [
            lo.map(|v| f32_outward(v, true)),
            hi.map(|v| f32_outward(v, false)),
        ];
        // Split the coordinate of largest extent at the median (ties by index).
        let dim = (0..6)
            .max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])))
            .unwrap_or(0);
        if end - start <= LEAF || hi[dim] - lo[dim] <= 0.0 {
            // A leaf (also when all points coincide).
            let first = self.groups.len() as u32;
            let ids = &idx[start..end];
            for chunk in ids.chunks(4) {
                let lane = |l: usize| chunk[l.min(chunk.len() - 1)] as usize;
                let v = |d: usize| {
                    Vec4::new(
                        all[lane(0)][d] as f32,
                        all[lane(1)][d] as f32,
                        all[lane(2)][d] as f32,
                        all[lane(3)][d] as f32,
                    )
                };
                self.groups.push(Group {
                    v: std::array::from_fn(v),
                    id: std::array::from_fn(|l| chunk.get(l).copied().unwrap_or(PAD)),
                    w: std::array::from_fn(|l| all[lane(l)]),
                });
            }
            let child = Child {
                at: first | LEAF_BIT,
                groups: self.groups.len() as u32 - first,
            };
            return (child, bounds);
        }
        let me = self.nodes.len();
        let none = Child { at: 0, groups: 0 };
        self.nodes.push(Node::new([[[0.0; 6]; 2]; 2], [none; 2]));
        let mid = (start + end) / 2;
        idx[start..end].select_nth_unstable_by(mid - start, |&a, &b| {
            all[a as usize][dim]
                .total_cmp(&all[b as usize][dim])
                .then(a.cmp(&b))
        });
        let (a, box_a) = self.build_rec(all, idx, start, mid);
        let (b, box_b) = self.build_rec(all, idx, mid, end);
        self.nodes[me] = Node::new([box_a, box_b], [a, b]);
        (
            Child {
                at: me as u32,
                groups: 0,
            },
            bounds,
        )
    }

    pub fn len(&self) -> usize {
        self.len
    }

    /// Bytes the tree holds on the heap (nodes, and the groups with their vectors).
    pub fn heap_bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<Node>()
            + self.groups.len() * std::mem::size_of::<Group>()
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The `k` nearest points to `(wi, wo)`: `(distance, original index)`, sorted by
    /// distance then index, into `out` (cleared first).
    pub fn nearest(&self, wi: DVec3, wo: DVec3, k: usize, out: &mut Vec<(f64, u32)>) {
        out.clear();
        if self.is_empty() || k == 0 {
            return;
        }
        let (fi, fo) = (wi.as_vec3(), wo.as_vec3());
        let q = [0, 1, 2].map(|c| Vec4::new(fi[c], fo[c], fi[c], fo[c]));
        // The distance a candidate must not exceed (`<=` keeps exact ties, equal distance
        // and lower index, reachable).
        let worst = |out: &Vec<(f64, u32)>| {
            if out.len() < k {
                f64::INFINITY
            } else {
                out[k - 1].0
            }
        };
        // Subtrees still to visit, with their bounds; at most one per level.
        let mut stack = [(0.0, self.root); 64];
        let mut top = 0;
        let mut cur = self.root;
        loop {
            if cur.at & LEAF_BIT == 0 {
                let n = &self.nodes[cur.at as usize];
                self.prefetch(n.child[0]);
                self.prefetch(n.child[1]);
                let (ba, bb) = n.bounds_to(&q);
                let (near, far, bn, bf) = if ba <= bb {
                    (n.child[0], n.child[1], ba, bb)
                } else {
                    (n.child[1], n.child[0], bb, ba)
                };
                let w = worst(out);
                if bf <= w {
                    stack[top] = (bf, far);
                    top += 1;
                }
                if bn <= w {
                    cur = near;
                    continue;
                }
            } else {
                self.scan_leaf(cur, wi, wo, &q, k, out);
            }
            // The next pending subtree still within reach.
            let w = worst(out);
            loop {
                if top == 0 {
                    return;
                }
                top -= 1;
                if stack[top].0 <= w {
                    break;
                }
            }
            cur = stack[top].1;
        }
    }

    /// Offers a leaf's points to the k nearest in `out`. A point whose two
    /// single-precision chords (less [`F32_SLACK`]) already exceed the k-th distance held
    /// cannot qualify; the others get their exact arcs.
    fn scan_leaf(
        &self,
        leaf: Child,
        wi: DVec3,
        wo: DVec3,
        q: &[Vec4; 3],
        k: usize,
        out: &mut Vec<(f64, u32)>,
    ) {
        let first = (leaf.at & !LEAF_BIT) as usize;
        let groups = &self.groups[first..first + leaf.groups as usize];
        let (qi, qo) = (
            [0, 1, 2].map(|c| Vec4::splat(q[c].x)),
            [0, 1, 2].map(|c| Vec4::splat(q[c].y)),
        );
        let mut limit = f32::INFINITY;
        if out.len() == k {
            limit = (out[k - 1].0 + F32_SLACK) as f32;
        } else if out.is_empty() && k <= LEAF {
            // The first leaf: the k-th smallest upper bound of its points' distances bounds
            // the k-th distance from above, so points whose lower bound exceeds it need no
            // arc. A leaf of coincident points may hold more than LEAF: its first LEAF
            // points serve.
            let mut ub = [f32::INFINITY; LEAF];
            let mut n = 0;
            for group in groups.iter().take(LEAF / 4) {
                let (ci, co) = (chords(&group.v, 0, &qi), chords(&group.v, 3, &qo));
                for lane in 0..4 {
                    if group.id[lane] != PAD {
                        ub[n] = arc_upper(ci[lane]) + arc_upper(co[lane]);
                        n += 1;
                    }
                }
            }
            if n >= k {
                let (_, kth, _) = ub[..n].select_nth_unstable_by(k - 1, f32::total_cmp);
                limit = (f64::from(*kth) + 2.0 * F32_SLACK) as f32;
            }
        }
        for group in groups {
            let sum = chords(&group.v, 0, &qi) + chords(&group.v, 3, &qo);
            let mut mask = sum.cmple(Vec4::splat(limit)).bitmask();
            while mask != 0 {
                let lane = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                let id = group.id[lane];
                if id == PAD {
                    break;
                }
                let v = &group.w[lane];
                let d =
                    arc(wi, DVec3::new(v[0], v[1], v[2])) + arc(wo, DVec3::new(v[3], v[4], v[5]));
                let better = out.len() < k || {
                    let w = out[k - 1];
                    d < w.0 || (d == w.0 && id < w.1)
                };
                if better {
                    let pos = out.partition_point(|e| e.0 < d || (e.0 == d && e.1 < id));
                    out.insert(pos, (d, id));
                    out.truncate(k);
                    if out.len() == k {
                        limit = (out[k - 1].0 + F32_SLACK) as f32;
                    }
                }
            }
        }
    }

    /// Every point: its slot in `w` and its original index.
    fn points(&self) -> impl Iterator<Item = (usize, u32)> + '_ {
        self.groups.iter().enumerate().flat_map(|(g, group)| {
            (0..4).filter_map(move |l| (group.id[l] != PAD).then_some((4 * g + l, group.id[l])))
        })
    }

    /// Brute-force k nearest, same ordering: the reference for tests and benchmarks.
    pub fn nearest_brute(&self, wi: DVec3, wo: DVec3, k: usize) -> Vec<(f64, u32)> {
        let mut all: Vec<(f64, u32)> = self
            .points()
            .map(|(p, id)| {
                let v = &self.groups[p / 4].w[p % 4];
                let (pi, po) = (DVec3::new(v[0], v[1], v[2]), DVec3::new(v[3], v[4], v[5]));
                (arc(wi, pi) + arc(wo, po), id)
            })
            .collect();
        // The k smallest by (distance, index), a total order, then sorted: the same list a
        // full sort's first k would give, in linear time.
        let order = |a: &(f64, u32), b: &(f64, u32)| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1));
        if k < all.len() {
            all.select_nth_unstable_by(k, order);
            all.truncate(k);
        }
        all.sort_by(order);
        all
    }

    /// Checks the tree's invariants: every child's box lies inside its parent's, every
    /// point inside its leaf's box (both precisions agreeing), and every point is in
    /// exactly one leaf.
    pub fn validate(&self) -> Result<(), BrdfError> {
        if self.is_empty() {
            return Ok(());
        }
        let mut seen = vec![false; self.len()];
        let inside = |inner: &Bounds, outer: &Bounds| {
            (0..6).all(|d| inner[0][d] >= outer[0][d] && inner[1][d] <= outer[1][d])
        };
        let mut stack = vec![(self.root, self.root_box)];
        while let Some((c, b)) = stack.pop() {
            if c.at & LEAF_BIT == 0 {
                let n = &self.nodes[c.at as usize];
                for i in 0..2 {
                    if !inside(&n.bounds(i), &b) {
                        return Err(BrdfError::from(format!(
                            "node {}: child {i}'s box exceeds the node's",
                            c.at
                        )));
                    }
                    stack.push((n.child[i], n.bounds(i)));
                }
                continue;
            }
            let first = (c.at & !LEAF_BIT) as usize;
            for g in first..first + c.groups as usize {
                let group = &self.groups[g];
                for l in 0..4 {
                    let v = &group.w[l];
                    if !(0..6).all(|d| {
                        f64::from(b[0][d]) <= v[d]
                            && v[d] <= f64::from(b[1][d])
                            && group.v[d][l] == v[d] as f32
                    }) {
                        return Err(BrdfError::from(format!(
                            "group {g} lane {l} outside its leaf's box"
                        )));
                    }
                    let id = group.id[l];
                    if id == PAD {
                        continue;
                    }
                    match seen.get_mut(id as usize) {
                        Some(s) if !*s => *s = true,
                        _ => {
                            return Err(BrdfError::from(format!(
                                "point {id} in two leaves or out of range"
                            )));
                        }
                    }
                }
            }
        }
        match seen.iter().position(|s| !s) {
            Some(p) => Err(BrdfError::from(format!("point {p} in no leaf"))),
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
        let nl = data.lambda_nm.len();
        let mut pts = Vec::new();
        let mut values = Vec::new();
        for per in &data.samples {
            for s in per {
                let (pi, po) = if isotropic {
                    (0.0, (s.phi_o_rad - s.phi_i_rad).rem_euclid(TAU))
                } else {
                    (s.phi_i_rad, s.phi_o_rad)
                };
                pts.push([s.theta_i_rad, pi, s.theta_o_rad, po]);
                values.extend_from_slice(&s.f);
                if reciprocal {
                    // (wo, wi): with phi_i moved to 0 when isotropic.
                    let (pi2, po2) = if isotropic {
                        (0.0, (pi - po).rem_euclid(TAU))
                    } else {
                        (po, pi)
                    };
                    pts.push([s.theta_o_rad, pi2, s.theta_i_rad, po2]);
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
            // Read at four random places per query.
            values: crate::machine::with_huge_pages(values),
            k: k.max(1),
            meta,
        }
    }

    /// The query as two unit vectors; for an isotropic tree both turned about the normal by
    /// `-phi_i`, which puts `wi` in the half-plane `y = 0, x >= 0` (`phi_i = 0`; at normal
    /// incidence, where `phi_i` is undefined, no turn).
    fn query_dirs(&self, wi: DVec3, wo: DVec3) -> (DVec3, DVec3) {
        let (wi, wo) = (wi.normalize(), wo.normalize());
        if !self.meta.isotropic {
            return (wi, wo);
        }
        let rho = wi.x.hypot(wi.y);
        let (c, s) = if rho > 0.0 {
            (wi.x / rho, wi.y / rho)
        } else {
            (1.0, 0.0)
        };
        (
            DVec3::new(rho, 0.0, wi.z),
            DVec3::new(c * wo.x + s * wo.y, c * wo.y - s * wo.x, wo.z),
        )
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
mod tests;
