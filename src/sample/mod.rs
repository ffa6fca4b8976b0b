//! Samples: the TOML description of DESIGN.md §2 (tile, media, interfaces) and the meshes
//! it names, loaded into nanometres and checked.
//!
//! ```toml
//! [sample]
//! name = "wavy soap film"
//! unit = "nm"              # unit of tile size and OBJ coordinates: nm or um
//! tile = [20000.0, 20000.0]
//! [media.air]
//! n = 1.0
//! [media.soap]
//! n = 1.33                 # k = ... for absorbing media
//! [[interface]]
//! mesh = "wavy-top.obj"    # relative to the TOML file
//! front = "air"            # medium on the side the triangle normals point to
//! back = "soap"
//! ```
//!
//! Every error names the file, and the line where there is one.

pub mod generate;
pub mod mesh;
pub mod obj;

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};

use serde::Deserialize;
use toml::Spanned;

use crate::accel::TriangleSoup;
pub use mesh::Mesh;
pub use obj::{MeshOptions, load_obj};

/// A sample input error: the file, the line where known, and what is wrong.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub struct SampleError {
    pub path: PathBuf,
    pub line: Option<usize>,
    pub kind: SampleErrorKind,
}

impl fmt::Display for SampleError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(l) => write!(f, "{}:{}: {}", self.path.display(), l, self.kind),
            None => write!(f, "{}: {}", self.path.display(), self.kind),
        }
    }
}

impl SampleError {
    pub fn at(path: &Path, line: usize, kind: SampleErrorKind) -> Self {
        SampleError {
            path: path.to_path_buf(),
            line: Some(line),
            kind,
        }
    }
    pub fn file(path: &Path, kind: SampleErrorKind) -> Self {
        SampleError {
            path: path.to_path_buf(),
            line: None,
            kind,
        }
    }
}

/// What is wrong with a sample input.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SampleErrorKind {
    #[error("cannot read file: {0}")]
    Io(String),
    #[error("invalid sample description: {0}")]
    Toml(String),
    #[error("malformed OBJ: {0}")]
    MalformedObj(String),
    #[error("non-finite vertex coordinate ({0}); coordinates must be finite numbers")]
    NonFiniteVertex(String),
    #[error("the mesh has no triangles")]
    EmptyMesh,
    #[error(
        "{count} of {total} triangles are degenerate (zero area); fix the mesh, or pass --drop-degenerate to drop them"
    )]
    DegenerateTriangles { count: usize, total: usize },
    #[error("unknown medium '{name}' (the sample defines: {known})")]
    UnknownMedium { name: String, known: String },
    #[error("tile size must be positive and finite in x and y, got [{0}, {1}]")]
    BadTile(f64, f64),
    #[error("unknown unit '{0}' (use \"nm\" or \"um\")")]
    BadUnit(String),
    #[error("medium '{name}': {message}")]
    BadMedium { name: String, message: String },
    #[error("the sample declares no [[interface]]")]
    NoInterfaces,
    #[error("in mesh {mesh}: {error}")]
    Mesh {
        mesh: String,
        error: Box<SampleError>,
    },
}

/// A homogeneous medium with a constant complex refractive index `n + i k`
/// (dimensionless; `k >= 0` absorbs).
#[derive(Clone, Debug, PartialEq)]
pub struct Medium {
    pub name: String,
    pub n: f64,
    pub k: f64,
}

/// One interface: a triangle mesh with a medium on each side.
#[derive(Clone, Debug)]
pub struct Interface {
    pub mesh: Mesh,
    /// Where the mesh came from (for messages).
    pub mesh_path: PathBuf,
    /// Medium on the side the triangle normals point to (index into `Sample::media`).
    pub front: usize,
    /// Medium on the other side.
    pub back: usize,
}

/// A loaded sample: a periodic tile `[0, Lx) x [0, Ly)` in nanometres, its media and its
/// interfaces.
#[derive(Clone, Debug)]
pub struct Sample {
    pub name: String,
    pub path: PathBuf,
    pub tile_nm: [f64; 2],
    /// Sorted by name, so ids are deterministic.
    pub media: Vec<Medium>,
    pub interfaces: Vec<Interface>,
}

impl Sample {
    /// Every interface's triangles in one soup for an accelerator, and for each interface
    /// the index of its first triangle (so `prim` maps back to its interface).
    pub fn triangle_soup(&self) -> (TriangleSoup, Vec<u32>) {
        let mut all = Mesh::default();
        let mut first = Vec::with_capacity(self.interfaces.len());
        for i in &self.interfaces {
            first.push(all.triangles.len() as u32);
            all.append(&i.mesh);
        }
        (all.to_soup(), first)
    }

    pub fn triangle_count(&self) -> usize {
        self.interfaces.iter().map(|i| i.mesh.triangles.len()).sum()
    }

    pub fn medium_id(&self, name: &str) -> Option<usize> {
        self.media.iter().position(|m| m.name == name)
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSample {
    sample: RawHeader,
    #[serde(default)]
    media: BTreeMap<String, Spanned<RawMedium>>,
    #[serde(default)]
    interface: Vec<RawInterface>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawHeader {
    name: String,
    unit: Spanned<String>,
    tile: Spanned<[f64; 2]>,
    #[serde(default)]
    #[allow(dead_code)]
    description: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMedium {
    n: f64,
    #[serde(default)]
    k: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawInterface {
    mesh: Spanned<String>,
    front: Spanned<String>,
    back: Spanned<String>,
}

/// 1-based line of byte offset `pos` in `text`.
fn line_of(text: &str, pos: usize) -> usize {
    text[..pos.min(text.len())]
        .bytes()
        .filter(|&b| b == b'\n')
        .count()
        + 1
}

/// Nanometres per unit for the sample's declared unit.
pub fn nm_per_unit(unit: &str) -> Option<f64> {
    match unit {
        "nm" => Some(1.0),
        "um" | "µm" | "μm" => Some(1000.0),
        _ => None,
    }
}

/// Loads a sample description and every mesh it names.
pub fn load(path: &Path, opts: MeshOptions) -> Result<Sample, SampleError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| SampleError::file(path, SampleErrorKind::Io(e.to_string())))?;
    parse(path, &text, opts)
}

/// Parses a sample description whose text was read from `path` (meshes are resolved
/// relative to `path`'s folder).
pub fn parse(path: &Path, text: &str, opts: MeshOptions) -> Result<Sample, SampleError> {
    let at =
        |span: std::ops::Range<usize>, kind| SampleError::at(path, line_of(text, span.start), kind);
    let raw: RawSample = toml::from_str(text).map_err(|e| {
        let kind = SampleErrorKind::Toml(e.message().trim().to_string());
        match e.span() {
            Some(s) => at(s, kind),
            None => SampleError::file(path, kind),
        }
    })?;

    let unit = raw.sample.unit.get_ref();
    let scale = nm_per_unit(unit).ok_or_else(|| {
        at(
            raw.sample.unit.span(),
            SampleErrorKind::BadUnit(unit.clone()),
        )
    })?;
    let [tx, ty] = *raw.sample.tile.get_ref();
    if !(tx.is_finite() && ty.is_finite() && tx > 0.0 && ty > 0.0) {
        return Err(at(raw.sample.tile.span(), SampleErrorKind::BadTile(tx, ty)));
    }

    let mut media = Vec::new();
    for (name, m) in &raw.media {
        let span = m.span();
        let m = m.get_ref();
        let bad = |message: String| {
            at(
                span.clone(),
                SampleErrorKind::BadMedium {
                    name: name.clone(),
                    message,
                },
            )
        };
        if !(m.n.is_finite() && m.n > 0.0) {
            return Err(bad(format!("n must be positive and finite, got {}", m.n)));
        }
        if !(m.k.is_finite() && m.k >= 0.0) {
            return Err(bad(format!("k must be finite and >= 0, got {}", m.k)));
        }
        media.push(Medium {
            name: name.clone(),
            n: m.n,
            k: m.k,
        });
    }
    let known = || {
        if media.is_empty() {
            "no media".to_string()
        } else {
            media
                .iter()
                .map(|m| m.name.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        }
    };
    let medium = |s: &Spanned<String>| -> Result<usize, SampleError> {
        media
            .iter()
            .position(|m| &m.name == s.get_ref())
            .ok_or_else(|| {
                at(
                    s.span(),
                    SampleErrorKind::UnknownMedium {
                        name: s.get_ref().clone(),
                        known: known(),
                    },
                )
            })
    };

    if raw.interface.is_empty() {
        return Err(SampleError::file(path, SampleErrorKind::NoInterfaces));
    }
    let base = path.parent().unwrap_or(Path::new(""));
    let mut interfaces = Vec::new();
    for ri in &raw.interface {
        let front = medium(&ri.front)?;
        let back = medium(&ri.back)?;
        let mesh_path = base.join(ri.mesh.get_ref());
        let mesh = load_obj(&mesh_path, scale, opts).map_err(|e| {
            at(
                ri.mesh.span(),
                SampleErrorKind::Mesh {
                    mesh: ri.mesh.get_ref().clone(),
                    error: Box::new(e),
                },
            )
        })?;
        interfaces.push(Interface {
            mesh,
            mesh_path,
            front,
            back,
        });
    }

    Ok(Sample {
        name: raw.sample.name,
        path: path.to_path_buf(),
        tile_nm: [tx * scale, ty * scale],
        media,
        interfaces,
    })
}
