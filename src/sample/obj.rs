//! Wavefront OBJ loading: polygons triangulated, scaled to nanometres, and checked, with
//! every error naming the file and the line.
//!
//! The reader takes the part of OBJ that describes polygon meshes (`v`, `f`), skips what
//! does not change the geometry (`vt`, `vn`, `g`, `o`, `s`, `usemtl`, `mtllib`, points and
//! lines), and refuses what it cannot represent faithfully: free-form geometry, rational
//! vertex weights other than 1, and concave polygons (a fan would cover area outside
//! them). It accepts a UTF-8 byte-order mark, `\n`, `\r\n` and lone `\r` line endings, and
//! `#` comments at the end of a statement.
//!
//! Vertices are renumbered in order of first use by a face, so unused vertices do not
//! enter the mesh or its bounds.

use std::path::Path;

use super::mesh::Mesh;
use super::{SampleError, SampleErrorKind};
use glam::DVec3;

/// Options for loading a mesh.
#[derive(Clone, Copy, Debug, Default)]
pub struct MeshOptions {
    /// Drop degenerate (zero-area) triangles instead of refusing the mesh.
    pub drop_degenerate: bool,
    /// Whether large mesh files go through their binary cache (`sample::cache`).
    pub cache: super::cache::CachePolicy,
}

/// Lines of `text` with their 1-based numbers, split at `\n`, `\r\n` or a lone `\r`.
pub(crate) fn numbered_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut rest = Some(text);
    let mut number = 0;
    std::iter::from_fn(move || {
        let s = rest?;
        number += 1;
        match s.find(['\n', '\r']) {
            Some(i) => {
                let skip = if s[i..].starts_with("\r\n") { 2 } else { 1 };
                rest = Some(&s[i + skip..]);
                Some((number, &s[..i]))
            }
            None => {
                rest = None;
                (!s.is_empty()).then_some((number, s))
            }
        }
    })
}

/// Loads an OBJ, triangulating polygons and multiplying coordinates by `nm_per_unit`.
///
/// Errors (each naming the file, and the line where there is one): a missing or
/// unreadable file, text that is not UTF-8, malformed statements, non-finite coordinates
/// (also after scaling), concave polygons, no triangles, and degenerate triangles unless
/// `opts.drop_degenerate`.
pub fn load_obj(path: &Path, nm_per_unit: f64, opts: MeshOptions) -> Result<Mesh, SampleError> {
    let bytes = crate::io::read_input(path, u64::MAX)
        .map_err(|e| SampleError::file(path, SampleErrorKind::Io(e.to_string())))?;
    let text = match std::str::from_utf8(&bytes) {
        Ok(t) => t,
        Err(e) => {
            let line = super::line_of_bytes(&bytes, e.valid_up_to());
            return Err(SampleError::at(
                path,
                line,
                SampleErrorKind::MalformedObj(
                    "the file is not UTF-8 text (is it a binary mesh format?)".into(),
                ),
            ));
        }
    };
    parse_obj(path, text, nm_per_unit, opts)
}

/// Parses OBJ text read from `path` (named in errors); see [`load_obj`].
pub fn parse_obj(
    path: &Path,
    text: &str,
    nm_per_unit: f64,
    opts: MeshOptions,
) -> Result<Mesh, SampleError> {
    let err =
        |line: usize, msg: String| SampleError::at(path, line, SampleErrorKind::MalformedObj(msg));
    // Vertices as written (nm), and their new index once a face uses them.
    let mut positions: Vec<DVec3> = Vec::new();
    let mut renumber: Vec<u32> = Vec::new();
    let mut mesh = Mesh::default();
    let mut triangle_lines: Vec<usize> = Vec::new();
    let mut corners: Vec<usize> = Vec::new();
    for (line, raw) in numbered_lines(text) {
        let s = raw.split('#').next().unwrap_or("").trim();
        if s.ends_with('\\') {
            return Err(err(
                line,
                "line continuations ('\\' at the end of a line) are not supported; join the lines"
                    .into(),
            ));
        }
        let mut tok = s.split_whitespace();
        match tok.next() {
            Some("v") => {
                let values: Vec<&str> = tok.collect();
                let mut num = Vec::with_capacity(values.len());
                for (k, c) in values.iter().enumerate() {
                    let x: f64 = c.parse().map_err(|_| {
                        err(line, format!("vertex coordinate {} is not a number", k + 1))
                    })?;
                    if !x.is_finite() {
                        return Err(SampleError::at(
                            path,
                            line,
                            SampleErrorKind::NonFiniteVertex(c.to_string()),
                        ));
                    }
                    num.push(x);
                }
                match num.len() {
                    3 | 6 => {} // x y z, or x y z r g b (vertex colours, ignored)
                    4 if num[3] == 1.0 => {}
                    4 => {
                        return Err(err(
                            line,
                            format!(
                                "vertex weight w = {} is not supported (rational weights belong to free-form geometry; polygon meshes use w = 1)",
                                values[3]
                            ),
                        ));
                    }
                    n => {
                        return Err(err(
                            line,
                            format!("a vertex needs 3 coordinates (x y z), found {n} values"),
                        ));
                    }
                }
                let p = match super::scale_vertex([num[0], num[1], num[2]], nm_per_unit) {
                    Ok(p) => p,
                    Err(super::VertexFault::NonFinite(c)) => {
                        return Err(SampleError::at(
                            path,
                            line,
                            SampleErrorKind::NonFiniteVertex(format!(
                                "{c} after scaling to nanometres: the coordinate is too large"
                            )),
                        ));
                    }
                    Err(super::VertexFault::TooFar(c)) => {
                        return Err(err(line, super::beyond_limit(c)));
                    }
                };
                positions.push(p);
                renumber.push(u32::MAX);
            }
            Some("f") => {
                corners.clear();
                let n = positions.len();
                for c in tok {
                    let first = c.split('/').next().unwrap_or("");
                    let idx: i64 = first.parse().map_err(|_| {
                        err(
                            line,
                            format!("face corner {} is not a vertex index", corners.len() + 1),
                        )
                    })?;
                    // 1-based; negative indices count back from the last vertex defined.
                    let resolved = if idx < 0 { n as i64 + idx } else { idx - 1 };
                    if idx == 0 || resolved < 0 || resolved >= n as i64 {
                        return Err(err(
                            line,
                            format!(
                                "face refers to vertex {idx}, but only {n} vertices are defined before this line"
                            ),
                        ));
                    }
                    corners.push(resolved as usize);
                }
                if corners.len() < 3 {
                    return Err(err(
                        line,
                        format!("a face needs at least 3 vertices, found {}", corners.len()),
                    ));
                }
                if corners.len() > 3 {
                    let poly: Vec<DVec3> = corners.iter().map(|&i| positions[i]).collect();
                    if let Some(k) = concave_corner(&poly) {
                        return Err(err(
                            line,
                            format!(
                                "this {}-sided face is not convex (at its corner {}): a triangle fan would cover area outside it; split it into triangles",
                                corners.len(),
                                k + 1
                            ),
                        ));
                    }
                }
                let mut index = |i: usize| -> Result<u32, SampleError> {
                    if renumber[i] == u32::MAX {
                        renumber[i] = u32::try_from(mesh.positions_nm.len())
                            .ok()
                            .filter(|&v| v < u32::MAX)
                            .ok_or_else(|| err(line, "more than 4 billion vertices".into()))?;
                        mesh.positions_nm.push(positions[i]);
                    }
                    Ok(renumber[i])
                };
                let a = index(corners[0])?;
                for w in corners[1..].windows(2) {
                    let t = [a, index(w[0])?, index(w[1])?];
                    mesh.triangles.push(t);
                    triangle_lines.push(line);
                }
            }
            Some(kw @ ("cstype" | "curv" | "curv2" | "surf" | "deg" | "bmat" | "step")) => {
                return Err(err(
                    line,
                    format!("free-form geometry ('{kw}') is not supported; export polygons"),
                ));
            }
            // vt, vn, vp, g, o, s, usemtl, mtllib, l, p, and anything else: no geometry.
            _ => {}
        }
    }
    finish_mesh(path, mesh, opts, |i| Some(triangle_lines[i]))
}

/// The checks every loaded mesh gets, whatever its format: triangles present, and none
/// degenerate (or, with `opts.drop_degenerate`, those dropped). `line_of(i)` is the line
/// of triangle `i` where the format has lines.
pub(crate) fn finish_mesh(
    path: &Path,
    mut mesh: Mesh,
    opts: MeshOptions,
    line_of: impl Fn(usize) -> Option<usize>,
) -> Result<Mesh, SampleError> {
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
            let kind = SampleErrorKind::DegenerateTriangles {
                count: degenerate.len(),
                total: mesh.triangles.len(),
            };
            return Err(match line_of(degenerate[0]) {
                Some(line) => SampleError::at(path, line, kind),
                None => SampleError::file(path, kind),
            });
        }
    }
    Ok(mesh)
}

/// The first corner at which polygon `p` turns against its overall orientation (Newell's
/// normal, Sutherland, Sproull & Schumacker 1974), or `None` for a convex polygon.
/// Corners on a straight edge are allowed.
pub(crate) fn concave_corner(p: &[DVec3]) -> Option<usize> {
    let k = p.len();
    let mut n = DVec3::ZERO;
    for i in 0..k {
        let (a, b) = (p[i], p[(i + 1) % k]);
        n.x += (a.y - b.y) * (a.z + b.z);
        n.y += (a.z - b.z) * (a.x + b.x);
        n.z += (a.x - b.x) * (a.y + b.y);
    }
    let scale = p
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs().max_element()))
        .max(f64::MIN_POSITIVE);
    (0..k).find(|&i| {
        let (a, b, c) = (p[(i + k - 1) % k], p[i], p[(i + 1) % k]);
        let turn = (b - a).cross(c - b);
        // Relative tolerance: rounding of coordinates of size `scale`.
        turn.dot(n) < -1e-12 * scale.powi(4)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Mesh, String> {
        parse_obj(Path::new("t.obj"), text, 1.0, MeshOptions::default()).map_err(|e| e.to_string())
    }

    #[test]
    fn line_endings_bom_and_comments() {
        let want = parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
        for text in [
            "\u{feff}v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
            "v 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\nf 1 2 3\r\n",
            "v 0 0 0\rv 1 0 0\rv 0 1 0\rf 1 2 3\r",
            "v 0 0 0 # corner\nv 1 0 0 1\nv 0 1 0 0.5 0.5 0.5\nf 1/1/1 2//2 3 # face\n",
        ] {
            assert_eq!(parse(text).unwrap(), want, "{text:?}");
        }
        // Lines are counted with every kind of ending.
        let e = parse("v 0 0 0\rv 1 0 0\r\nv 0 1 0\nf 1 2 4\n").unwrap_err();
        assert!(e.contains("t.obj:4:"), "{e}");
    }

    #[test]
    fn refusals_name_the_line() {
        for (text, line, what) in [
            ("v 0 0 0 0\n", 1, "weight"),
            ("v 0 0\n", 1, "3 coordinates"),
            ("\nv 0 0 1e999\n", 2, "non-finite"),
            ("v 0 0 0\nv 1 0 0\nf 1 2\n", 3, "at least 3"),
            ("v 0 0 0\nf 1 0 1\n", 2, "vertex 0"),
            ("cstype bspline\n", 1, "free-form"),
            ("v 0 0 0\\\n", 1, "continuation"),
            (
                "v 0 0 0\nv 4 0 0\nv 4 4 0\nv 2 1 0\nv 0 4 0\nf 1 2 3 4 5\n",
                6,
                "not convex",
            ),
        ] {
            let e = parse(text).unwrap_err();
            assert!(
                e.contains(&format!("t.obj:{line}:")) && e.contains(what),
                "{text:?}: {e}"
            );
        }
    }

    #[test]
    fn convex_polygons_are_fans_and_unused_vertices_dropped() {
        let m =
            parse("v 9 9 9\nv 0 0 0\nv 2 0 0\nv 2 2 0\nv 1 2 0\nv 0 2 0\nf 2 3 4 5 6\n").unwrap();
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 3, 4]]);
        assert_eq!(m.positions_nm.len(), 5);
        assert!(!m.positions_nm.contains(&glam::DVec3::splat(9.0)));
        // Scaling overflow is caught with the line.
        let e = parse_obj(
            Path::new("t.obj"),
            "v 1e306 0 0\n",
            1e3,
            MeshOptions::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("t.obj:1:") && e.contains("too large"), "{e}");
    }
}
