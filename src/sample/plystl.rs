//! PLY and STL meshes, as scanners and CAD tools export them.
//!
//! - PLY (Turk 1994; the Stanford format as Paul Bourke documents it): `ascii`,
//!   `binary_little_endian` and `binary_big_endian`; the `vertex` element's `x`, `y`, `z`
//!   of any numeric type, and the `face` element's `vertex_indices` (or `vertex_index`)
//!   list; every other element and property is read past and ignored. Polygons are fanned
//!   into triangles (convex ones only, as for OBJ).
//! - STL (3D Systems' StereoLithography format): binary (80-byte header, a triangle
//!   count, 50 bytes per triangle with float32 corners) or ASCII (`solid` ... `facet` ...
//!   `vertex x y z`). A binary file is recognised by its size, since binary headers may
//!   also start with "solid". STL repeats shared corners in every triangle: corners at the
//!   same position are merged, so the mesh is connected as the surface is. The stored
//!   facet normals are ignored: orientation follows the corner order, as in OBJ.
//!
//! Coordinates are multiplied by `nm_per_unit` like OBJ's; the mesh's checks (finite,
//! within range, no degenerate triangles unless dropped) are OBJ's.

use std::collections::HashMap;
use std::path::Path;

use super::mesh::Mesh;
use super::obj::MeshOptions;
use super::{SampleError, SampleErrorKind};
use glam::DVec3;

/// A PLY or STL error, named by the file's extension (these readers are chosen by it).
fn malformed(path: &Path, msg: String) -> SampleError {
    let ply = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("ply"));
    let format = if ply { "PLY" } else { "STL" };
    SampleError::file(path, SampleErrorKind::MalformedMesh { format, msg })
}

/// Scales a corner to nm and checks it (`sample::scale_vertex`).
fn corner(path: &Path, p: [f64; 3], nm_per_unit: f64, what: &str) -> Result<DVec3, SampleError> {
    super::scale_vertex(p, nm_per_unit).map_err(|fault| match fault {
        super::VertexFault::NonFinite(c) => SampleError::file(
            path,
            SampleErrorKind::NonFiniteVertex(format!("{c} ({what})")),
        ),
        super::VertexFault::TooFar(c) => {
            malformed(path, format!("{what}: {}", super::beyond_limit(c)))
        }
    })
}

/// OBJ's checks (`obj::finish_mesh`); these formats have no line per triangle.
fn finish(path: &Path, mesh: Mesh, opts: MeshOptions) -> Result<Mesh, SampleError> {
    super::obj::finish_mesh(path, mesh, opts, |_| None)
}

/// Loads a binary or ASCII STL.
pub fn load_stl(path: &Path, nm_per_unit: f64, opts: MeshOptions) -> Result<Mesh, SampleError> {
    let bytes = crate::io::read_input(path, u64::MAX)
        .map_err(|e| SampleError::file(path, SampleErrorKind::Io(e.to_string())))?;
    parse_stl(path, &bytes, nm_per_unit, opts)
}

/// An STL mesh from its bytes (`path` names it in errors).
pub fn parse_stl(
    path: &Path,
    bytes: &[u8],
    nm_per_unit: f64,
    opts: MeshOptions,
) -> Result<Mesh, SampleError> {
    let binary_count = (bytes.len() >= 84)
        .then(|| u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as u64)
        .filter(|&n| 84 + 50 * n == bytes.len() as u64);
    let mut corners: Vec<[f64; 3]> = Vec::new();
    if let Some(n) = binary_count {
        corners.reserve(3 * n as usize);
        for t in bytes[84..].chunks_exact(50) {
            for k in 0..3 {
                let at = 12 + 12 * k;
                let f = |o: usize| {
                    f64::from(f32::from_le_bytes(
                        t[at + o..at + o + 4].try_into().expect("4 bytes"),
                    ))
                };
                corners.push([f(0), f(4), f(8)]);
            }
        }
    } else {
        let text = std::str::from_utf8(bytes).map_err(|_| {
            malformed(
                path,
                if bytes.len() >= 84 {
                    let n = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]);
                    let want = 84 + 50 * u64::from(n);
                    format!(
                        "neither ASCII STL nor binary STL: a binary STL of {n} triangles is {want} bytes, this file is {} ({})",
                        bytes.len(),
                        if (bytes.len() as u64) < want {
                            "truncated?"
                        } else {
                            "bytes after the last triangle: padding or another file appended"
                        }
                    )
                } else {
                    "too short for a binary STL and not ASCII".into()
                },
            )
        })?;
        let mut tok = text.split_whitespace();
        if tok.next() != Some("solid") {
            return Err(malformed(path, "an ASCII STL starts with \"solid\"".into()));
        }
        while let Some(t) = tok.next() {
            if t == "vertex" {
                let mut p = [0.0; 3];
                for c in &mut p {
                    *c = tok.next().and_then(|v| v.parse().ok()).ok_or_else(|| {
                        malformed(
                            path,
                            format!("vertex {} needs three numbers", corners.len() + 1),
                        )
                    })?;
                }
                corners.push(p);
            }
        }
        if corners.len() % 3 != 0 {
            return Err(malformed(
                path,
                format!("{} vertices do not form whole triangles", corners.len()),
            ));
        }
    }
    // Merge corners at the same position (in order of first use).
    let mut mesh = Mesh::default();
    let mut index: HashMap<[u64; 3], u32> = HashMap::new();
    let mut tri = [0u32; 3];
    for (k, c) in corners.iter().enumerate() {
        let key = c.map(|v| (v + 0.0).to_bits());
        let i = match index.get(&key) {
            Some(&i) => i,
            None => {
                let p = corner(path, *c, nm_per_unit, &format!("triangle {}", k / 3 + 1))?;
                let i = u32::try_from(mesh.positions_nm.len())
                    .map_err(|_| malformed(path, "more than 4 billion vertices".into()))?;
                mesh.positions_nm.push(p);
                index.insert(key, i);
                i
            }
        };
        tri[k % 3] = i;
        if k % 3 == 2 {
            mesh.triangles.push(tri);
        }
    }
    finish(path, mesh, opts)
}

/// A PLY scalar type: its size in bytes and whether it is a float / signed.
#[derive(Clone, Copy, Debug)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(s: &str) -> Option<Scalar> {
        Some(match s {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }
    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }
}

enum Property {
    Scalar(String, Scalar),
    List(String, Scalar, Scalar),
}

/// Reads a PLY header: the elements it declares (names, counts, properties) and a
/// source positioned at the first data value, in the declared format.
fn ply_header<'a>(path: &Path, bytes: &'a [u8]) -> Result<(Source<'a>, Vec<Element>), SampleError> {
    let bad = |m: String| malformed(path, m);
    const END: &[u8] = b"end_header";
    let end = bytes
        .windows(END.len())
        .position(|w| w == END)
        .ok_or_else(|| bad("no end_header: not a PLY file, or its header is cut".into()))?;
    let header =
        std::str::from_utf8(&bytes[..end]).map_err(|_| bad("the PLY header is not text".into()))?;
    // The data start after end_header's line ending.
    let mut data_at = end + END.len();
    if bytes.get(data_at) == Some(&b'\r') {
        data_at += 1;
    }
    if bytes.get(data_at) == Some(&b'\n') {
        data_at += 1;
    }
    let mut lines = header.lines().map(str::trim);
    if lines.next() != Some("ply") {
        return Err(bad("a PLY file starts with the line \"ply\"".into()));
    }
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    for line in lines {
        let w: Vec<&str> = line.split_whitespace().collect();
        match w.as_slice() {
            [] | ["comment", ..] | ["obj_info", ..] => {}
            ["format", f, _version] => format = Some(f.to_string()),
            ["element", name, count] => elements.push(Element {
                name: name.to_string(),
                count: count
                    .parse()
                    .map_err(|_| bad(format!("element {name}: count {count:?} is not a number")))?,
                props: Vec::new(),
            }),
            ["property", "list", ct, it, name] => {
                let (Some(c), Some(i)) = (Scalar::parse(ct), Scalar::parse(it)) else {
                    return Err(bad(format!("unknown PLY type in {line:?}")));
                };
                elements
                    .last_mut()
                    .ok_or_else(|| bad(format!("{line:?} before any element")))?
                    .props
                    .push(Property::List(name.to_string(), c, i));
            }
            ["property", t, name] => {
                let s = Scalar::parse(t).ok_or_else(|| bad(format!("unknown PLY type {t:?}")))?;
                elements
                    .last_mut()
                    .ok_or_else(|| bad(format!("{line:?} before any element")))?
                    .props
                    .push(Property::Scalar(name.to_string(), s));
            }
            _ => return Err(bad(format!("unexpected PLY header line {line:?}"))),
        }
    }
    let src = match format.as_deref() {
        Some("binary_little_endian") => Source::Binary {
            data: &bytes[data_at..],
            at: 0,
            big: false,
        },
        Some("binary_big_endian") => Source::Binary {
            data: &bytes[data_at..],
            at: 0,
            big: true,
        },
        Some("ascii") => Source::Ascii(
            std::str::from_utf8(&bytes[data_at..])
                .map_err(|_| bad("ASCII PLY data are not text".into()))?
                .split_ascii_whitespace(),
        ),
        other => return Err(bad(format!("unknown PLY format {other:?}"))),
    };
    Ok((src, elements))
}

struct Element {
    name: String,
    count: u64,
    props: Vec<Property>,
}

/// Where PLY values come from: binary bytes in either order, or ASCII tokens.
enum Source<'a> {
    Binary {
        data: &'a [u8],
        at: usize,
        big: bool,
    },
    Ascii(std::str::SplitAsciiWhitespace<'a>),
}

impl Source<'_> {
    fn read(&mut self, t: Scalar) -> Option<f64> {
        match self {
            Source::Ascii(tok) => tok.next()?.parse().ok(),
            Source::Binary { data, at, big } => {
                let n = t.size();
                let b = data.get(*at..*at + n)?;
                *at += n;
                let mut a = [0u8; 8];
                a[..n].copy_from_slice(b);
                if *big {
                    a[..n].reverse();
                }
                Some(match t {
                    Scalar::I8 => f64::from(a[0] as i8),
                    Scalar::U8 => f64::from(a[0]),
                    Scalar::I16 => f64::from(i16::from_le_bytes([a[0], a[1]])),
                    Scalar::U16 => f64::from(u16::from_le_bytes([a[0], a[1]])),
                    Scalar::I32 => f64::from(i32::from_le_bytes([a[0], a[1], a[2], a[3]])),
                    Scalar::U32 => f64::from(u32::from_le_bytes([a[0], a[1], a[2], a[3]])),
                    Scalar::F32 => f64::from(f32::from_le_bytes([a[0], a[1], a[2], a[3]])),
                    Scalar::F64 => f64::from_le_bytes(a),
                })
            }
        }
    }
}

/// Loads an ASCII or binary PLY.
pub fn load_ply(path: &Path, nm_per_unit: f64, opts: MeshOptions) -> Result<Mesh, SampleError> {
    let bytes = crate::io::read_input(path, u64::MAX)
        .map_err(|e| SampleError::file(path, SampleErrorKind::Io(e.to_string())))?;
    parse_ply(path, &bytes, nm_per_unit, opts)
}

/// A PLY mesh from its bytes (`path` names it in errors).
pub fn parse_ply(
    path: &Path,
    bytes: &[u8],
    nm_per_unit: f64,
    opts: MeshOptions,
) -> Result<Mesh, SampleError> {
    let bad = |m: String| malformed(path, m);
    let (mut src, elements) = ply_header(path, bytes)?;
    // Before reading, the counts must fit the file (each value takes at least a byte).
    let least: u64 = elements
        .iter()
        .map(|e| e.count.saturating_mul(e.props.len() as u64))
        .fold(0u64, u64::saturating_add);
    if least > bytes.len() as u64 {
        return Err(bad(format!(
            "the header declares {least} values, more than the file's {} bytes (truncated?)",
            bytes.len()
        )));
    }
    let mut mesh = Mesh::default();
    let mut vertices = 0usize;
    let mut poly: Vec<u32> = Vec::new();
    let cut = |what: &str| bad(format!("the PLY data end inside {what} (truncated?)"));
    for e in &elements {
        if e.props.is_empty() {
            // An element without properties holds no data, however many it declares (a
            // count of 2^64 - 1 looped for minutes); a vertex needs its coordinates.
            if e.name == "vertex" && e.count > 0 {
                return Err(bad("the vertex element needs x, y and z".into()));
            }
            continue;
        }
        for k in 0..e.count {
            let mut p = [f64::NAN; 3];
            poly.clear();
            for prop in &e.props {
                match prop {
                    Property::Scalar(name, t) => {
                        let v = src
                            .read(*t)
                            .ok_or_else(|| cut(&format!("{} {}", e.name, k + 1)))?;
                        if e.name == "vertex" {
                            match name.as_str() {
                                "x" => p[0] = v,
                                "y" => p[1] = v,
                                "z" => p[2] = v,
                                _ => {}
                            }
                        }
                    }
                    Property::List(name, ct, it) => {
                        let n = src
                            .read(*ct)
                            .ok_or_else(|| cut(&format!("{} {}", e.name, k + 1)))?;
                        if !(n >= 0.0 && n.fract() == 0.0 && n <= 1e6) {
                            return Err(bad(format!("{} {}: list length {n}", e.name, k + 1)));
                        }
                        let is_face = e.name == "face"
                            && (name == "vertex_indices" || name == "vertex_index");
                        for _ in 0..n as usize {
                            let v = src
                                .read(*it)
                                .ok_or_else(|| cut(&format!("{} {}", e.name, k + 1)))?;
                            if is_face {
                                if !(v >= 0.0 && v.fract() == 0.0 && (v as usize) < vertices) {
                                    return Err(bad(format!(
                                        "face {} refers to vertex {v}, but there are {vertices} vertices",
                                        k + 1
                                    )));
                                }
                                poly.push(v as u32);
                            }
                        }
                    }
                }
            }
            if e.name == "vertex" {
                if p.iter().any(|c| c.is_nan()) {
                    return Err(bad("the vertex element needs x, y and z".into()));
                }
                mesh.positions_nm
                    .push(corner(path, p, nm_per_unit, &format!("vertex {}", k + 1))?);
                vertices += 1;
            } else if e.name == "face" && !poly.is_empty() {
                if poly.len() < 3 {
                    return Err(bad(format!("face {} has {} corners", k + 1, poly.len())));
                }
                if poly.len() > 3 {
                    let pts: Vec<DVec3> = poly
                        .iter()
                        .map(|&i| mesh.positions_nm[i as usize])
                        .collect();
                    if let Some(c) = super::obj::concave_corner(&pts) {
                        return Err(bad(format!(
                            "face {} is not convex (at its corner {}): split it into triangles",
                            k + 1,
                            c + 1
                        )));
                    }
                }
                for w in poly[1..].windows(2) {
                    mesh.triangles.push([poly[0], w[0], w[1]]);
                }
            }
        }
    }
    finish(path, mesh, opts)
}
