//! Triangle meshes in nanometres (f64), as interfaces of a sample are made of.

use std::io::Write;
use std::path::Path;

use crate::geom::TriangleSoup;
use glam::DVec3;

/// An indexed triangle mesh. Positions in nanometres in the sample frame (z up); the
/// front of a triangle is the side `(v1 - v0) x (v2 - v0)` points to.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    pub positions_nm: Vec<DVec3>,
    pub triangles: Vec<[u32; 3]>,
}

impl Mesh {
    /// Twice the area of triangle `i` as a vector: `(v1 - v0) x (v2 - v0)`, in nm².
    pub fn area_vector(&self, i: usize) -> DVec3 {
        let [a, b, c] = self.triangles[i].map(|k| self.positions_nm[k as usize]);
        (b - a).cross(c - a)
    }

    /// Whether triangle `i` has (numerically) no area: repeated corners, or corners on one
    /// line. The test is relative, `|e1 x e2| <= 1e-12 * max_edge²`, so it does not
    /// depend on the unit.
    pub fn is_degenerate(&self, i: usize) -> bool {
        degenerate(self.triangles[i].map(|k| self.positions_nm[k as usize]))
    }

    /// Indices of the degenerate triangles.
    pub fn degenerate_triangles(&self) -> Vec<usize> {
        (0..self.triangles.len())
            .filter(|&i| self.is_degenerate(i))
            .collect()
    }

    /// Indices of the triangles that are degenerate once their corners are rounded to f32,
    /// as the accelerators store them.
    pub fn degenerate_triangles_f32(&self) -> Vec<usize> {
        let f32_corner = |k: u32| self.positions_nm[k as usize].as_vec3().as_dvec3();
        (0..self.triangles.len())
            .filter(|&i| degenerate(self.triangles[i].map(f32_corner)))
            .collect()
    }

    /// Axis-aligned bounds `(min, max)` in nm, or `None` for an empty mesh.
    pub fn bounds(&self) -> Option<(DVec3, DVec3)> {
        let mut it = self.positions_nm.iter();
        let first = *it.next()?;
        Some(it.fold((first, first), |(lo, hi), &p| (lo.min(p), hi.max(p))))
    }

    /// Appends `other`, offsetting its indices.
    pub fn append(&mut self, other: &Mesh) {
        let off = self.positions_nm.len() as u32;
        self.positions_nm.extend_from_slice(&other.positions_nm);
        self.triangles
            .extend(other.triangles.iter().map(|t| t.map(|i| i + off)));
    }

    /// The mesh as f32 triangles for an accelerator.
    pub fn to_soup(&self) -> TriangleSoup {
        TriangleSoup {
            vertices: self
                .positions_nm
                .iter()
                .map(|p| p.as_vec3().to_array())
                .collect(),
            triangles: self.triangles.clone(),
        }
    }

    /// Writes the mesh as a Wavefront OBJ with coordinates in `unit` (nm per file unit),
    /// atomically (temporary file, then rename).
    pub fn write_obj(&self, path: &Path, nm_per_unit: f64, comment: &str) -> std::io::Result<()> {
        crate::io::write_atomic(path, |w| {
            for line in comment.lines() {
                writeln!(w, "# {line}")?;
            }
            for p in &self.positions_nm {
                // Rust prints the shortest decimal that round-trips the f64 exactly.
                writeln!(
                    w,
                    "v {} {} {}",
                    p[0] / nm_per_unit,
                    p[1] / nm_per_unit,
                    p[2] / nm_per_unit
                )?;
            }
            for t in &self.triangles {
                writeln!(w, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1)?;
            }
            Ok(())
        })
    }
}

/// Whether the triangle `[a, b, c]` has (numerically) no area (see [`Mesh::is_degenerate`]).
fn degenerate([a, b, c]: [DVec3; 3]) -> bool {
    let d2 = |p: DVec3, q: DVec3| (p - q).length_squared();
    let max_edge2 = d2(a, b).max(d2(b, c)).max(d2(c, a));
    let cross = (b - a).cross(c - a).length();
    max_edge2 == 0.0 || cross <= 1e-12 * max_edge2
}
