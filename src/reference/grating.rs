//! The sample's periodic tile sliced into layers along z for the rigorous solver
//! (`optics::rcwa`; docs/physics.md, "The rigorous solver").
//!
//! Each pixel column of the tile (centres `((ix + ½) Lx / nx, (iy + ½) Ly / ny)`) is crossed
//! by a vertical line; every triangle it meets, of any interface, says which medium lies
//! below it (the normal points to `front`). A coated interface adds its layers at their
//! vertical thickness `t / |n_z|` (conformal to the facet). Walking down a column from the
//! medium above, the medium at any height is the one below the nearest crossing above it.
//!
//! Heights where every column has a crossing are flat planes: they bound slices exactly.
//! Between two such planes the region is one homogeneous slice when every column holds one
//! medium there (flat layers and coatings stay exact), and is otherwise cut into `slices`
//! equal slices sampled at their mid-heights: the staircase the solver takes. A structure
//! that does not change along an axis is kept as one pixel along it, and a tile that holds
//! several periods of its structure along an axis is reduced to one period.

use crate::optics::C64;
use crate::optics::rcwa::{Grid, Layer, Slab, Structure};
use crate::sample::Sample;

/// How finely the tile is sampled: pixels per axis (over the whole tile), and slices per
/// structured region.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SliceSpec {
    pub pixels: [usize; 2],
    pub slices: usize,
}

/// A slice's media: one, or one per pixel (`ids[iy * nx + ix]`).
#[derive(Clone, Debug, PartialEq)]
pub enum SlabIds {
    Uniform(usize),
    Grid { n: [usize; 2], ids: Vec<u16> },
}

/// Whether two slicings are the same slabs: as many, of the same media, each of the same
/// thickness to 1e-9 of it (their sums of slice thicknesses round apart).
pub fn same_slabs(a: &Sliced, b: &Sliced) -> bool {
    a.period_nm == b.period_nm
        && a.layers.len() == b.layers.len()
        && a.layers
            .iter()
            .zip(&b.layers)
            .all(|((ta, ia), (tb, ib))| ia == ib && (ta - tb).abs() <= 1e-9 * ta.max(*tb))
}

/// The tile as slices of media, wavelength-independent (`structure` gives the permittivities
/// at one wavelength).
#[derive(Clone, Debug, PartialEq)]
pub struct Sliced {
    /// One period of the structure, nm (the tile, or a fraction of it).
    pub period_nm: [f64; 2],
    /// Whether the structure changes along x and along y.
    pub patterned: [bool; 2],
    pub above: usize,
    pub below: usize,
    /// `(thickness_nm, media)`, top first.
    pub layers: Vec<(f64, SlabIds)>,
}

/// Why a tile cannot be sliced.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SliceError {
    #[error(
        "the rigorous solver needs a periodic tile; this sample has open sides with a guard band"
    )]
    Guarded,
    #[error(
        "the pixel column at ({x:.1}, {y:.1}) nm crosses no interface: the sample's sheets do not cover the tile"
    )]
    Uncovered { x: f64, y: f64 },
    #[error(
        "the pixel columns do not agree on the medium {which} the structure ('{a}' and '{b}'): every column must start and end in the same half-spaces"
    )]
    Outer {
        which: &'static str,
        a: String,
        b: String,
    },
    #[error("pixels and slices must be at least 1 (got {0:?})")]
    Spec(SliceSpec),
}

/// One column's transitions: `(z, medium below z)`, sorted from the top down.
type Column = Vec<(f64, usize)>;

/// Every pixel column's crossings, and the medium above the first.
fn columns(sample: &Sample, n: [usize; 2]) -> Result<(Vec<Column>, Vec<usize>), SliceError> {
    let [nx, ny] = n;
    let [lx, ly] = sample.tile_nm;
    let (dx, dy) = (lx / nx as f64, ly / ny as f64);
    let mut cols: Vec<Column> = vec![Vec::new(); nx * ny];
    // The medium above each column's topmost crossing, with that crossing's height.
    let mut tops: Vec<(f64, usize)> = vec![(f64::NEG_INFINITY, usize::MAX); nx * ny];
    for iface in &sample.interfaces {
        let mesh = &iface.mesh;
        let depth: f64 = iface.coating.iter().map(|c| c.1).sum();
        for (t, tri) in mesh.triangles.iter().enumerate() {
            let a = mesh.area_vector(t);
            if a.z == 0.0 {
                continue; // vertical: no column crosses it
            }
            let [p0, p1, p2] = tri.map(|k| mesh.positions_nm[k as usize]);
            let up = a.z > 0.0;
            let nz = a.z.abs() / a.length();
            let (lo_x, hi_x) = (p0.x.min(p1.x).min(p2.x), p0.x.max(p1.x).max(p2.x));
            let (lo_y, hi_y) = (p0.y.min(p1.y).min(p2.y), p0.y.max(p1.y).max(p2.y));
            for sy in [-1.0, 0.0, 1.0] {
                for sx in [-1.0, 0.0, 1.0] {
                    let (ox, oy) = (sx * lx, sy * ly);
                    let ix0 = (((lo_x + ox) / dx - 0.5).ceil().max(0.0)) as usize;
                    let ix1 = ((hi_x + ox) / dx - 0.5).floor().min(nx as f64 - 1.0);
                    let iy0 = (((lo_y + oy) / dy - 0.5).ceil().max(0.0)) as usize;
                    let iy1 = ((hi_y + oy) / dy - 0.5).floor().min(ny as f64 - 1.0);
                    if ix1 < 0.0 || iy1 < 0.0 {
                        continue;
                    }
                    for iy in iy0..=iy1 as usize {
                        for ix in ix0..=ix1 as usize {
                            let (x, y) = ((ix as f64 + 0.5) * dx - ox, (iy as f64 + 0.5) * dy - oy);
                            let Some(z) = height_in(p0, p1, p2, x, y) else {
                                continue;
                            };
                            let col = &mut cols[iy * nx + ix];
                            let above = if up { iface.front } else { iface.back };
                            push_crossing(col, z, up, nz, iface, depth);
                            let top = &mut tops[iy * nx + ix];
                            let z_top = if up { z + depth / nz } else { z };
                            if z_top > top.0 {
                                *top = (z_top, above);
                            }
                        }
                    }
                }
            }
        }
    }
    for (i, c) in cols.iter_mut().enumerate() {
        if c.is_empty() {
            return Err(SliceError::Uncovered {
                x: ((i % nx) as f64 + 0.5) * dx,
                y: ((i / nx) as f64 + 0.5) * dy,
            });
        }
        c.sort_by(|a, b| b.0.total_cmp(&a.0));
    }
    Ok((cols, tops.into_iter().map(|t| t.1).collect()))
}

/// The height of the triangle's plane over `(x, y)` where the point lies in its projection
/// (edges included, so a column through a shared edge meets both triangles, which agree).
fn height_in(p0: glam::DVec3, p1: glam::DVec3, p2: glam::DVec3, x: f64, y: f64) -> Option<f64> {
    let det = (p1.x - p0.x) * (p2.y - p0.y) - (p2.x - p0.x) * (p1.y - p0.y);
    if det == 0.0 {
        return None;
    }
    let u = ((x - p0.x) * (p2.y - p0.y) - (p2.x - p0.x) * (y - p0.y)) / det;
    let v = ((p1.x - p0.x) * (y - p0.y) - (x - p0.x) * (p1.y - p0.y)) / det;
    let eps = 1e-12;
    if u < -eps || v < -eps || u + v > 1.0 + eps {
        return None;
    }
    Some(p0.z + u * (p1.z - p0.z) + v * (p2.z - p0.z))
}

/// A crossing's transitions: the coating's layers at their vertical thickness, then the
/// medium on the far side.
fn push_crossing(
    col: &mut Column,
    z: f64,
    up: bool,
    nz: f64,
    iface: &crate::sample::Interface,
    depth: f64,
) {
    if up {
        // Front (and its coating, outermost first) above the facet.
        let mut top = z + depth / nz;
        for &(m, t) in &iface.coating {
            col.push((top, m));
            top -= t / nz;
        }
        col.push((z, iface.back));
    } else {
        let mut top = z;
        for &(m, t) in iface.coating.iter().rev() {
            col.push((top, m));
            top -= t / nz;
        }
        col.push((top, iface.front));
    }
}

/// The medium at height `z` of a column whose medium above every crossing is `above`.
fn medium_at(col: &Column, above: usize, z: f64) -> usize {
    let mut m = above;
    for &(h, below) in col {
        if h > z {
            m = below;
        } else {
            break;
        }
    }
    m
}

/// The tile's relief for the C-method: one interface `z = a(x)` whose heights (nm) are
/// `heights`, at `x_i = (i + ½) Λ / samples` over one period `period_nm` along x, under
/// `planes`: flat interfaces every column crosses at one height with the same media, all
/// above the relief's highest point, top first as `(z nm, medium below)` (a lacquer's
/// top). The last plane's medium below (or the medium above the tile) covers the relief.
#[derive(Clone, Debug, PartialEq)]
pub struct Relief {
    pub heights: Vec<f64>,
    pub planes: Vec<(f64, usize)>,
}

/// The tile as a [`Relief`], where every column crosses the flat planes and exactly one
/// uncoated interface below them, and the structure does not change along y (`None`
/// elsewhere: several reliefs, coatings, overhangs, a flat plane below the relief, a crossed
/// pattern).
pub fn relief(sample: &Sample, period_nm: f64, samples: usize) -> Option<Relief> {
    let periods = (sample.tile_nm[0] / period_nm).round();
    if periods < 1.0 || (periods * period_nm - sample.tile_nm[0]).abs() > 1e-6 * period_nm {
        return None;
    }
    let row = samples * periods as usize;
    let dedup = |c: &Column| {
        let mut c = c.clone();
        // A column through a shared edge meets both triangles, at one height.
        c.dedup_by(|a, b| (a.0 - b.0).abs() < 1e-9 && a.1 == b.1);
        c
    };
    let (cols, _) = columns(sample, [row, 1]).ok()?;
    let cols: Vec<Column> = cols.iter().map(dedup).collect();
    // The flat planes: crossings of the first column that every column has, at one height
    // to 1e-6 nm, into the same medium.
    let flat = |c: &(f64, usize)| {
        cols.iter()
            .all(|o| o.iter().any(|x| (x.0 - c.0).abs() < 1e-6 && x.1 == c.1))
    };
    let planes: Vec<(f64, usize)> = cols.first()?.iter().copied().filter(flat).collect();
    let lowest = planes.last().map_or(f64::INFINITY, |p| p.0);
    // Each column: the planes, then one crossing below them all, the same medium below.
    let rest = |c: &Column| -> Option<(f64, usize)> {
        let left: Vec<&(f64, usize)> = c
            .iter()
            .filter(|x| {
                !planes
                    .iter()
                    .any(|p| (x.0 - p.0).abs() < 1e-6 && x.1 == p.1)
            })
            .collect();
        (left.len() == 1 && c.len() == planes.len() + 1 && left[0].0 < lowest - 1e-6)
            .then(|| *left[0])
    };
    let crossings: Vec<(f64, usize)> =
        cols.iter().take(samples).map(rest).collect::<Option<_>>()?;
    if crossings.iter().any(|c| c.1 != crossings[0].1) {
        return None;
    }
    let heights: Vec<f64> = crossings.iter().map(|c| c.0).collect();
    // The same relief along y: a second row, across the tile, sees the same heights.
    let (cross, _) = columns(sample, [row, 2]).ok()?;
    let same = (0..samples).all(|i| {
        [&cross[i], &cross[row + i]]
            .iter()
            .all(|c| rest(&dedup(c)).is_some_and(|c| (c.0 - heights[i]).abs() < 1e-6))
    });
    same.then_some(Relief { heights, planes })
}

/// Slices `sample`'s tile (see the module's documentation).
pub fn slice(sample: &Sample, spec: SliceSpec) -> Result<Sliced, SliceError> {
    if sample.guard_nm.is_some() {
        return Err(SliceError::Guarded);
    }
    if spec.pixels.contains(&0) || spec.slices == 0 {
        return Err(SliceError::Spec(spec));
    }
    let n = spec.pixels;
    let (cols, tops) = columns(sample, n)?;
    let name = |m: usize| sample.media[m].name.clone();
    let above = tops[0];
    let below = cols[0].last().expect("non-empty").1;
    for (c, &t) in cols.iter().zip(&tops) {
        if t != above {
            return Err(SliceError::Outer {
                which: "above",
                a: name(above),
                b: name(t),
            });
        }
        let b = c.last().expect("non-empty").1;
        if b != below {
            return Err(SliceError::Outer {
                which: "below",
                a: name(below),
                b: name(b),
            });
        }
    }
    let planes = boundaries(sample, &cols);
    let mut layers = Vec::new();
    for w in planes.windows(2) {
        let (top, bottom) = (w[0], w[1]);
        if top - bottom < 1e-9 {
            continue;
        }
        let mid = 0.5 * (top + bottom);
        let first = medium_at(&cols[0], above, mid);
        let uniform = cols.iter().all(|c| {
            medium_at(c, above, mid) == first
                && !c.iter().any(|&(h, _)| h < top - 1e-9 && h > bottom + 1e-9)
        });
        if uniform {
            layers.push((top - bottom, SlabIds::Uniform(first)));
            continue;
        }
        let k = spec.slices;
        let d = (top - bottom) / k as f64;
        // Neighbouring slices of one band with the same media are one slab, solved once
        // (exact: a slab that does not change with height has one set of modes, however
        // thick; lamellae and pillars are one slab per band).
        let mut same = 0usize;
        for s in 0..k {
            let z = top - (s as f64 + 0.5) * d;
            let ids: Vec<u16> = cols.iter().map(|c| medium_at(c, above, z) as u16).collect();
            match layers.last_mut() {
                Some((t, SlabIds::Grid { ids: prev, .. })) if s > 0 && *prev == ids => {
                    same += 1;
                    *t = d * (same + 1) as f64;
                }
                _ => {
                    same = 0;
                    layers.push((d, SlabIds::Grid { n, ids }));
                }
            }
        }
    }
    Ok(reduce(Sliced {
        period_nm: sample.tile_nm,
        patterned: [true, true],
        above,
        below,
        layers,
    }))
}

/// The heights that bound slices, from the top down: the top and bottom transitions of all
/// columns, every height where all columns have a transition (to 1e-9 nm), and each
/// interface's extent in z (with its coating's, at the steepest facet's vertical
/// thickness), so that a structured band is sliced on its own and the flat layers between
/// bands stay single exact slices.
fn boundaries(sample: &Sample, cols: &[Column]) -> Vec<f64> {
    let top = cols
        .iter()
        .map(|c| c[0].0)
        .fold(f64::NEG_INFINITY, f64::max);
    let bottom = cols
        .iter()
        .map(|c| c.last().expect("non-empty").0)
        .fold(f64::INFINITY, f64::min);
    let mut planes = vec![top, bottom];
    for &(h, _) in &cols[0] {
        if cols
            .iter()
            .all(|c| c.iter().any(|&(g, _)| (g - h).abs() < 1e-9))
        {
            planes.push(h);
        }
    }
    for iface in &sample.interfaces {
        let m = &iface.mesh;
        let (lo, hi) = m
            .positions_nm
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
                (a.min(p.z), b.max(p.z))
            });
        let depth: f64 = iface.coating.iter().map(|c| c.1).sum();
        let nz_min = (0..m.triangles.len())
            .map(|t| m.area_vector(t))
            .filter(|a| a.z != 0.0)
            .map(|a| a.z.abs() / a.length())
            .fold(1.0, f64::min);
        planes.extend([lo, hi, lo - depth / nz_min, hi + depth / nz_min]);
    }
    planes.retain(|&h| h <= top && h >= bottom);
    planes.sort_by(|a, b| b.total_cmp(a));
    planes.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
    planes
}

/// The grids kept as one pixel along an axis where they do not change, and as one period
/// where the tile holds several (the smallest divisor `k` of the pixel count for which every
/// grid repeats after `n / k` pixels).
fn reduce(mut s: Sliced) -> Sliced {
    for axis in 0..2 {
        let grids = || {
            s.layers.iter().filter_map(|l| match &l.1 {
                SlabIds::Grid { n, ids } => Some((*n, ids)),
                SlabIds::Uniform(_) => None,
            })
        };
        let Some((n, _)) = grids().next() else {
            s.patterned = [false, false];
            return s;
        };
        let len = n[axis];
        let repeats = |shift: usize| {
            grids().all(|(n, ids)| {
                (0..ids.len()).all(|i| {
                    let (ix, iy) = (i % n[0], i / n[0]);
                    let j = if axis == 0 {
                        iy * n[0] + (ix + shift) % n[0]
                    } else {
                        ((iy + shift) % n[1]) * n[0] + ix
                    };
                    ids[i] == ids[j]
                })
            })
        };
        let keep = if repeats(1) {
            1
        } else {
            (2..=len)
                .filter(|d| len % d == 0)
                .find(|&d| repeats(d))
                .unwrap_or(len)
        };
        s.patterned[axis] = keep > 1;
        if keep == len {
            continue;
        }
        s.period_nm[axis] *= keep as f64 / len as f64;
        for l in &mut s.layers {
            if let SlabIds::Grid { n, ids } = &mut l.1 {
                let old = *n;
                n[axis] = keep;
                *ids = (0..n[0] * n[1])
                    .map(|i| {
                        let (ix, iy) = (i % n[0], i / n[0]);
                        ids[iy * old[0] + ix]
                    })
                    .collect();
            }
        }
    }
    s
}

impl Sliced {
    /// The structure at one wavelength: `idx` each medium's complex index there
    /// (`Sample::indices_into`), permittivity `ε = (n + ik)^2`.
    pub fn structure(&self, idx: &[C64]) -> Structure {
        let eps = |m: usize| idx[m] * idx[m];
        Structure {
            period_nm: self.period_nm,
            eps_above: eps(self.above).re,
            layers: self
                .layers
                .iter()
                .map(|(d, ids)| Layer {
                    thickness_nm: *d,
                    slab: match ids {
                        SlabIds::Uniform(m) => Slab::Uniform(eps(*m)),
                        SlabIds::Grid { n, ids } => Slab::Grid(Grid {
                            n: *n,
                            eps: ids.iter().map(|&m| eps(m as usize)).collect(),
                        }),
                    },
                })
                .collect(),
            eps_below: eps(self.below),
        }
    }
}
