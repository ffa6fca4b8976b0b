//! Wavefront OBJ loading through tobj: triangulated, scaled to nanometres, and checked.
//!
//! tobj's errors carry no line numbers, so the file is first scanned line by line for the
//! defects users make (malformed or non-finite vertices, faces with bad indices); those
//! errors name the line. tobj then does the actual loading.

use std::path::Path;

use super::mesh::Mesh;
use super::{SampleError, SampleErrorKind};

/// Options for loading a mesh.
#[derive(Clone, Copy, Debug, Default)]
pub struct MeshOptions {
    /// Drop degenerate (zero-area) triangles instead of refusing the mesh.
    pub drop_degenerate: bool,
}

/// What the line scan learnt: the line of every vertex and of every triangle tobj will
/// produce (faces are fan-triangulated, in file order).
struct Scan {
    triangle_lines: Vec<usize>,
}

fn scan(path: &Path, text: &str) -> Result<Scan, SampleError> {
    let err = |line: usize, kind| SampleError::at(path, line, kind);
    let mut nverts: i64 = 0;
    let mut triangle_lines = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let s = raw.split('#').next().unwrap_or("").trim();
        let mut tok = s.split_whitespace();
        match tok.next() {
            Some("v") => {
                let coords: Vec<&str> = tok.collect();
                if coords.len() < 3 {
                    return Err(err(
                        line,
                        SampleErrorKind::MalformedObj(format!(
                            "vertex needs 3 coordinates, found {}: '{s}'",
                            coords.len()
                        )),
                    ));
                }
                for c in &coords[..3] {
                    let x: f64 = c.parse().map_err(|_| {
                        err(
                            line,
                            SampleErrorKind::MalformedObj(format!(
                                "vertex coordinate '{c}' is not a number"
                            )),
                        )
                    })?;
                    if !x.is_finite() {
                        return Err(err(line, SampleErrorKind::NonFiniteVertex(c.to_string())));
                    }
                }
                nverts += 1;
            }
            Some("f") => {
                let corners: Vec<&str> = tok.collect();
                if corners.len() < 3 {
                    return Err(err(
                        line,
                        SampleErrorKind::MalformedObj(format!(
                            "a face needs at least 3 vertices, found {}",
                            corners.len()
                        )),
                    ));
                }
                for c in &corners {
                    let first = c.split('/').next().unwrap_or("");
                    let idx: i64 = first.parse().map_err(|_| {
                        err(
                            line,
                            SampleErrorKind::MalformedObj(format!(
                                "face vertex '{c}' is not an index"
                            )),
                        )
                    })?;
                    let resolved = if idx < 0 { nverts + 1 + idx } else { idx };
                    if resolved < 1 || resolved > nverts {
                        return Err(err(
                            line,
                            SampleErrorKind::MalformedObj(format!(
                                "face refers to vertex {idx}, but only {nverts} vertices are defined before this line"
                            )),
                        ));
                    }
                }
                triangle_lines.extend(std::iter::repeat_n(line, corners.len() - 2));
            }
            _ => {}
        }
    }
    Ok(Scan { triangle_lines })
}

/// Loads an OBJ, triangulating polygons and multiplying coordinates by `nm_per_unit`.
///
/// Errors (each naming the file, and the line where there is one): a missing or
/// unreadable file, malformed statements, non-finite coordinates, no triangles, and
/// degenerate triangles unless `opts.drop_degenerate`.
pub fn load_obj(path: &Path, nm_per_unit: f64, opts: MeshOptions) -> Result<Mesh, SampleError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| SampleError::file(path, SampleErrorKind::Io(e.to_string())))?;
    let scan = scan(path, &text)?;

    let load_opts = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ignore_points: true,
        ignore_lines: true,
    };
    let mut reader = std::io::BufReader::new(text.as_bytes());
    // Materials are irrelevant here: the sample's TOML says which medium is on each side.
    let (models, _materials) = tobj::load_obj_buf(&mut reader, &load_opts, |_| {
        Err(tobj::LoadError::OpenFileFailed)
    })
    .map_err(|e| SampleError::file(path, SampleErrorKind::MalformedObj(format!("tobj: {e}"))))?;

    let mut mesh = Mesh::default();
    for m in &models {
        let p = &m.mesh.positions;
        let part = Mesh {
            positions_nm: p
                .chunks_exact(3)
                .map(|c| [c[0] * nm_per_unit, c[1] * nm_per_unit, c[2] * nm_per_unit])
                .collect(),
            triangles: m
                .mesh
                .indices
                .chunks_exact(3)
                .map(|c| [c[0], c[1], c[2]])
                .collect(),
        };
        mesh.append(&part);
    }
    if let Some(bad) = mesh
        .positions_nm
        .iter()
        .position(|p| p.iter().any(|c| !c.is_finite()))
    {
        // Finite in the file but not after scaling: coordinates too large.
        return Err(SampleError::file(
            path,
            SampleErrorKind::NonFiniteVertex(format!(
                "vertex {} overflows when scaled to nanometres",
                bad + 1
            )),
        ));
    }
    if mesh.triangles.is_empty() {
        return Err(SampleError::file(path, SampleErrorKind::EmptyMesh));
    }
    let degenerate = mesh.degenerate_triangles();
    if !degenerate.is_empty() {
        if opts.drop_degenerate {
            let mut keep = vec![true; mesh.triangles.len()];
            for &i in &degenerate {
                keep[i] = false;
            }
            let mut k = keep.iter();
            mesh.triangles.retain(|_| *k.next().unwrap_or(&true));
            if mesh.triangles.is_empty() {
                return Err(SampleError::file(path, SampleErrorKind::EmptyMesh));
            }
        } else {
            // The line is known when triangulation matched the scan one to one.
            let line = (scan.triangle_lines.len() == mesh.triangles.len())
                .then(|| scan.triangle_lines[degenerate[0]]);
            let kind = SampleErrorKind::DegenerateTriangles {
                count: degenerate.len(),
                total: mesh.triangles.len(),
            };
            return Err(match line {
                Some(l) => SampleError::at(path, l, kind),
                None => SampleError::file(path, kind),
            });
        }
    }
    Ok(mesh)
}
