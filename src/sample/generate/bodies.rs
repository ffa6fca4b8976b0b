//! Closed bodies placed without overlap: icosphere pigments and (coated) flakes, with
//! an O(1) neighbour grid for random sequential addition and the size checks made
//! before anything is allocated.

use super::GenerateError;
use std::collections::HashMap;
use std::f64::consts::{PI, TAU};

use super::super::mesh::Mesh;
use super::{MAX_BODIES, MAX_GENERATED_TRIANGLES};
use crate::rng::Rng;
use glam::DVec3;

/// A unit icosphere (Loop-free midpoint subdivision of an icosahedron), outward normals.
pub fn icosphere(subdivisions: u32) -> Mesh {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut p: Vec<DVec3> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .map(DVec3::from)
    .to_vec();
    let norm = |v: DVec3| v / v.length();
    for v in &mut p {
        *v = norm(*v);
    }
    let mut tris: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut next = Vec::with_capacity(tris.len() * 4);
        let mut midpoint = |a: u32, b: u32, p: &mut Vec<DVec3>| {
            let key = (a.min(b), a.max(b));
            *mid.entry(key).or_insert_with(|| {
                let (x, y) = (p[a as usize], p[b as usize]);
                p.push(norm((x + y) / 2.0));
                (p.len() - 1) as u32
            })
        };
        for [a, b, c] in tris {
            let ab = midpoint(a, b, &mut p);
            let bc = midpoint(b, c, &mut p);
            let ca = midpoint(c, a, &mut p);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        tris = next;
    }
    Mesh {
        positions_nm: p,
        triangles: tris,
    }
}

/// Signed volume enclosed by a closed mesh (nm³), positive for outward normals
/// (divergence theorem: sum over triangles of `v0 . (v1 x v2) / 6`).
pub fn enclosed_volume(mesh: &Mesh) -> f64 {
    mesh.triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| mesh.positions_nm[i as usize]);
            a.dot(b.cross(c)) / 6.0
        })
        .sum()
}

/// Pigment spheres placed without overlap (random sequential addition) inside the layer
/// `z in [layer_nm[0], layer_nm[1]]`, fully inside the tile, to the requested volume fraction
/// of the layer. Each sphere is an icosphere scaled so its volume equals that of the ideal
/// sphere of `radius_nm`; the non-overlap test uses its circumscribed radius. Returns one
/// closed mesh per sphere, outward normals.
pub fn pigment_spheres(
    seed: u64,
    tile_nm: [f64; 2],
    radius_nm: f64,
    volume_fraction: f64,
    layer_nm: [f64; 2],
    subdivisions: u32,
) -> Result<Vec<Mesh>, GenerateError> {
    if !(radius_nm > 0.0 && radius_nm.is_finite()) {
        return Err(GenerateError::from(format!(
            "radius must be positive, got {radius_nm}"
        )));
    }
    if !(volume_fraction > 0.0 && volume_fraction < 0.5) {
        return Err(GenerateError::from(format!(
            "volume_fraction must be in (0, 0.5) (random sequential addition jams near 0.38), got {volume_fraction}"
        )));
    }
    let unit = icosphere(subdivisions);
    let scale = (4.0 / 3.0 * PI / enclosed_volume(&unit)).cbrt();
    let rc = radius_nm * scale; // circumscribed radius of the scaled icosphere
    let thickness = check_layer(layer_nm)?;
    if 2.0 * rc >= thickness || 2.0 * rc >= tile_nm[0] || 2.0 * rc >= tile_nm[1] {
        return Err(GenerateError::from(format!(
            "spheres of radius {radius_nm} nm do not fit in the layer ({thickness} nm) and tile"
        )));
    }
    // Placement tests the circumscribed radius within the room centres can take: beyond
    // the jamming limit of random sequential addition (about 0.38 for spheres, Feder 1980)
    // no placement can finish, so say so before trying.
    let room = (tile_nm[0] - 2.0 * rc) * (tile_nm[1] - 2.0 * rc) * (thickness - 2.0 * rc);
    let effective =
        volume_fraction * (rc / radius_nm).powi(3) * tile_nm[0] * tile_nm[1] * thickness / room;
    if effective > RSA_JAMMING_SPHERES {
        return Err(GenerateError::from(format!(
            "volume_fraction {volume_fraction} is {effective:.2} for placement (the icosphere's circumscribed radius and the layer's margins), above the {RSA_JAMMING_SPHERES} random sequential addition can reach: lower it, raise subdivisions, or widen the layer"
        )));
    }
    let v_sphere = 4.0 / 3.0 * PI * radius_nm.powi(3);
    let count = body_count(
        "sphere",
        volume_fraction * tile_nm[0] * tile_nm[1] * thickness / v_sphere,
        unit.triangles.len(),
    )?;
    let mut rng = Rng::new(seed, 0x5F4E);
    let mut centres: Vec<DVec3> = Vec::with_capacity(count);
    let min_d2 = (2.0 * rc * 1.001).powi(2);
    // Only spheres in neighbouring cells can overlap a candidate: O(1) per attempt.
    let mut grid = NeighbourGrid::new(1.01 * min_d2.sqrt());
    let mut attempts = 0usize;
    while centres.len() < count {
        attempts += 1;
        if attempts > 2000 * count + 100_000 {
            return Err(GenerateError::from(format!(
                "could place only {} of {count} spheres without overlap; lower volume_fraction",
                centres.len()
            )));
        }
        let c = DVec3::new(
            rng.range(rc, tile_nm[0] - rc),
            rng.range(rc, tile_nm[1] - rc),
            rng.range(layer_nm[0] + rc, layer_nm[1] - rc),
        );
        if grid
            .near(c)
            .all(|k| (centres[k] - c).length_squared() >= min_d2)
        {
            grid.insert(c, centres.len());
            centres.push(c);
        }
    }
    Ok(centres
        .iter()
        .map(|c| Mesh {
            positions_nm: unit.positions_nm.iter().map(|&v| c + v * rc).collect(),
            triangles: unit.triangles.clone(),
        })
        .collect())
}

/// An oriented box: centre, three orthonormal axes and half extents.
#[derive(Clone, Copy, Debug)]
struct Obb {
    c: DVec3,
    axes: [DVec3; 3],
    /// Half extents along the axes, nm.
    half: [f64; 3],
}

impl Obb {
    fn corners(&self) -> [DVec3; 8] {
        let mut out = [DVec3::ZERO; 8];
        for (i, o) in out.iter_mut().enumerate() {
            let s = [
                if i & 1 == 0 { -1.0 } else { 1.0 },
                if i & 2 == 0 { -1.0 } else { 1.0 },
                if i & 4 == 0 { -1.0 } else { 1.0 },
            ];
            *o = self.c
                + self.axes[0] * (s[0] * self.half[0])
                + self.axes[1] * (s[1] * self.half[1])
                + self.axes[2] * (s[2] * self.half[2]);
        }
        out
    }

    /// Closed box mesh with outward normals.
    fn mesh(&self) -> Mesh {
        let p = self.corners().to_vec();
        // Faces as quads of corner indices (bit 0 = x, 1 = y, 2 = z), outward.
        let quads = [
            [0, 2, 3, 1], // -z
            [4, 5, 7, 6], // +z
            [0, 1, 5, 4], // -y
            [2, 6, 7, 3], // +y
            [0, 4, 6, 2], // -x
            [1, 3, 7, 5], // +x
        ];
        let mut triangles = Vec::new();
        for q in quads {
            triangles.push([q[0], q[1], q[2]]);
            triangles.push([q[0], q[2], q[3]]);
        }
        let mut m = Mesh {
            positions_nm: p,
            triangles,
        };
        // A left-handed axis frame turns every face inside out: fix by the volume's sign.
        if enclosed_volume(&m) < 0.0 {
            for t in &mut m.triangles {
                t.swap(1, 2);
            }
        }
        m
    }

    /// Separating-axis test for two oriented boxes (Gottschalk, Lin & Manocha, "OBBTree",
    /// SIGGRAPH 1996): 15 candidate axes.
    fn overlaps(&self, o: &Obb) -> bool {
        let d = o.c - self.c;
        let mut axes: Vec<DVec3> = Vec::with_capacity(15);
        axes.extend(self.axes);
        axes.extend(o.axes);
        for a in self.axes {
            for b in o.axes {
                let c = a.cross(b);
                if c.dot(c) > 1e-18 {
                    axes.push(c);
                }
            }
        }
        for ax in axes {
            let ra: f64 = (0..3)
                .map(|i| self.half[i] * self.axes[i].dot(ax).abs())
                .sum();
            let rb: f64 = (0..3).map(|i| o.half[i] * o.axes[i].dot(ax).abs()).sum();
            if d.dot(ax).abs() > ra + rb {
                return false;
            }
        }
        true
    }
}

/// Square pearlescent flakes: platelets of side `size_nm` and thickness `thickness_nm`,
/// tilted from horizontal by an angle drawn from a normal distribution of standard
/// deviation `tilt_sd_deg` (about a random horizontal axis), with an optional coating shell
/// `coating_nm` thick, placed without overlap inside the layer and the tile to the
/// requested volume fraction of flake cores. Returns `(core, coating)` meshes per flake.
#[allow(clippy::too_many_arguments)]
pub fn flakes(
    seed: u64,
    tile_nm: [f64; 2],
    size_nm: f64,
    thickness_nm: f64,
    tilt_sd_deg: f64,
    coating_nm: f64,
    volume_fraction: f64,
    layer_nm: [f64; 2],
) -> Result<Vec<(Mesh, Option<Mesh>)>, GenerateError> {
    if !(size_nm > 0.0 && thickness_nm > 0.0 && thickness_nm < size_nm) {
        return Err(GenerateError::from(format!(
            "need 0 < thickness < size, got size {size_nm} nm, thickness {thickness_nm} nm"
        )));
    }
    if !(coating_nm >= 0.0 && tilt_sd_deg >= 0.0) {
        return Err("coating and tilt must be >= 0".into());
    }
    if !(volume_fraction > 0.0 && volume_fraction < 0.5) {
        return Err(GenerateError::from(format!(
            "volume_fraction must be in (0, 0.5), got {volume_fraction}"
        )));
    }
    let thickness = check_layer(layer_nm)?;
    let v_flake = size_nm * size_nm * thickness_nm;
    // 12 triangles per box, twice with a coating shell.
    let per_flake = if coating_nm > 0.0 { 24 } else { 12 };
    let count = body_count(
        "flake",
        volume_fraction * tile_nm[0] * tile_nm[1] * thickness / v_flake,
        per_flake,
    )?;
    let outer_half = [
        size_nm / 2.0 + coating_nm,
        size_nm / 2.0 + coating_nm,
        thickness_nm / 2.0 + coating_nm,
    ];
    let mut rng = Rng::new(seed, 0xF1A4E);
    let mut placed: Vec<Obb> = Vec::with_capacity(count);
    // Two boxes can overlap only if their centres are closer than twice the bounding
    // sphere radius of the (margin-enlarged) box.
    let bound = 1.001 * outer_half.iter().map(|h| h * h).sum::<f64>().sqrt();
    let mut grid = NeighbourGrid::new(1.01 * 2.0 * bound);
    let mut attempts = 0usize;
    while placed.len() < count {
        attempts += 1;
        if attempts > 5000 * count + 100_000 {
            return Err(GenerateError::from(format!(
                "could place only {} of {count} flakes without overlap; lower volume_fraction or the tilt",
                placed.len()
            )));
        }
        // Orientation: spin about z, then tilt about the rotated x axis.
        let spin = rng.range(0.0, TAU);
        let tilt = (tilt_sd_deg * rng.normal()).to_radians();
        let (cs, ss, ct, st) = (spin.cos(), spin.sin(), tilt.cos(), tilt.sin());
        let ax = DVec3::new(cs, ss, 0.0);
        let ay = DVec3::new(-ss * ct, cs * ct, st);
        let az = DVec3::new(ss * st, -cs * st, ct);
        let axes = [ax, ay, az];
        // Extent of the outer box along each world axis, to keep it inside tile and layer.
        let ext = |k: usize| {
            (0..3)
                .map(|i| outer_half[i] * axes[i][k].abs())
                .sum::<f64>()
        };
        let (ex, ey, ez) = (ext(0), ext(1), ext(2));
        if 2.0 * ex >= tile_nm[0] || 2.0 * ey >= tile_nm[1] || 2.0 * ez >= thickness {
            continue;
        }
        let c = DVec3::new(
            rng.range(ex, tile_nm[0] - ex),
            rng.range(ey, tile_nm[1] - ey),
            rng.range(layer_nm[0] + ez, layer_nm[1] - ez),
        );
        // A 0.1 % margin keeps coatings of neighbours from touching.
        let cand = Obb {
            c,
            axes,
            half: outer_half.map(|h| h * 1.001),
        };
        if grid.near(c).all(|k| !placed[k].overlaps(&cand)) {
            grid.insert(c, placed.len());
            placed.push(cand);
        }
    }
    Ok(placed
        .iter()
        .map(|o| {
            let core = Obb {
                half: [size_nm / 2.0, size_nm / 2.0, thickness_nm / 2.0],
                ..*o
            };
            let shell = (coating_nm > 0.0).then(|| {
                Obb {
                    half: outer_half,
                    ..*o
                }
                .mesh()
            });
            (core.mesh(), shell)
        })
        .collect())
}

/// The volume fraction beyond which random sequential addition of spheres cannot finish:
/// its jamming limit is 0.382 (Feder 1980, J. Theor. Biol. 87; Torquato, Uche & Stillinger
/// 2006, Phys. Rev. E 74), and the last percent takes unbounded attempts.
const RSA_JAMMING_SPHERES: f64 = 0.37;

/// Checks a body layer `[z0, z1]` (nm): finite, ordered, within the length limit; returns
/// its thickness.
fn check_layer(layer_nm: [f64; 2]) -> Result<f64, GenerateError> {
    let [z0, z1] = layer_nm;
    let lim = crate::sample::MAX_LENGTH_NM;
    if !(z0.is_finite() && z1.is_finite() && z0.abs() <= lim && z1.abs() <= lim) {
        return Err(GenerateError::from(format!(
            "layer = [{z0}, {z1}] nm must be finite and within +-{lim:e} nm"
        )));
    }
    if z1 <= z0 {
        return Err(GenerateError::from(format!(
            "layer = [z0, z1] needs z0 < z1, got [{z0}, {z1}] nm"
        )));
    }
    Ok(z1 - z0)
}

/// The number of bodies for an expected (real) count, checked before anything is
/// allocated: at least one, at most [`MAX_BODIES`] and [`MAX_GENERATED_TRIANGLES`].
fn body_count(what: &str, expected: f64, triangles_each: usize) -> Result<usize, GenerateError> {
    if !expected.is_finite() {
        return Err(GenerateError::from(format!(
            "the {what} count is not finite: check the lengths"
        )));
    }
    let count = expected.round();
    if count < 1.0 {
        return Err(GenerateError::from(format!(
            "the volume fraction gives no {what} in this tile; enlarge the tile or the fraction"
        )));
    }
    let triangles = count * triangles_each as f64;
    if count > MAX_BODIES as f64 || triangles > MAX_GENERATED_TRIANGLES as f64 {
        return Err(GenerateError::from(format!(
            "this tile and volume fraction need {count:.3e} {what}s ({triangles:.3e} triangles); the limits are {MAX_BODIES} bodies and {MAX_GENERATED_TRIANGLES} triangles: make the {what}s larger, the tile smaller or the fraction lower"
        )));
    }
    Ok(count as usize)
}

/// A uniform hash grid over points: a point's neighbours within one cell size lie in the
/// 27 cells around its own, which makes non-overlap placement O(1) per attempt instead of
/// O(n). The accept/reject decisions are those of testing every placed body.
struct NeighbourGrid {
    cell: f64,
    cells: HashMap<[i64; 3], Vec<usize>>,
}

impl NeighbourGrid {
    fn new(cell: f64) -> Self {
        NeighbourGrid {
            cell,
            cells: HashMap::new(),
        }
    }
    fn key(&self, p: DVec3) -> [i64; 3] {
        p.to_array().map(|c| (c / self.cell).floor() as i64)
    }
    fn insert(&mut self, p: DVec3, id: usize) {
        self.cells.entry(self.key(p)).or_default().push(id);
    }
    /// Ids of the points in the 27 cells around `p`.
    fn near(&self, p: DVec3) -> impl Iterator<Item = usize> + '_ {
        let k = self.key(p);
        (0..27).flat_map(move |n| {
            let d = [n % 3 - 1, n / 3 % 3 - 1, n / 9 - 1];
            let key = [k[0] + d[0], k[1] + d[1], k[2] + d[2]];
            self.cells.get(&key).into_iter().flatten().copied()
        })
    }
}
