//! Samples: the TOML description of docs/design.md §2 (tile, media, interfaces) and the meshes
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
//! Media may also be dispersive (`cauchy`, `sellmeier`, `table = "x.csv"`, or
//! `model = "x.toml"`: see [`media`]). A flat layered sample can be written as a `[stack]`;
//! interfaces and closed `[[body]]`s can come from a `generator = { kind = "...", ... }`
//! instead of an OBJ (see [`generate`]).
//!
//! Every error names the file, and the line where there is one.

pub mod cache;
pub mod generate;
pub mod heightmap;
pub mod media;
pub mod mesh;
pub mod obj;
pub mod plystl;
pub mod validity;

mod limits;
mod raw;
mod resolve;
pub mod symmetry;

use std::fmt;
use std::path::{Path, PathBuf};

use crate::geom::TriangleSoup;
pub use limits::{MAX_LENGTH_NM, f32_resolution_nm};
pub(crate) use limits::{VertexFault, beyond_limit, scale_vertex};
pub use media::{IndexModel, Medium, Scattering};
pub use mesh::Mesh;
pub use obj::{MeshOptions, load_obj, parse_obj};
pub use resolve::parse;

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
    /// A PLY or STL file that does not follow its format (`format` names it).
    #[error("malformed {format}: {msg}")]
    MalformedMesh { format: &'static str, msg: String },
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
    #[error("the sample declares no interface ([stack], [[interface]] or [[body]])")]
    NoInterfaces,
    #[error("{0}")]
    Invalid(String),
    #[error("generator '{kind}': {message}")]
    Generator { kind: String, message: String },
    #[error("in medium table or model {file}: {message}")]
    MediumFile { file: String, message: String },
    #[error("in mesh {mesh}: {error}")]
    Mesh {
        mesh: String,
        error: Box<SampleError>,
    },
}

message_error!(SampleErrorKind, SampleErrorKind::Invalid);

/// One interface: a triangle mesh with a medium on each side.
#[derive(Clone, Debug)]
pub struct Interface {
    pub mesh: Mesh,
    /// Where the mesh came from: an OBJ path, or a description of its generator.
    pub mesh_path: PathBuf,
    /// A closed body (checked for watertightness) rather than a sheet spanning the tile
    /// (checked for periodicity).
    pub closed: bool,
    /// Medium on the side the triangle normals point to (index into `Sample::media`).
    pub front: usize,
    /// Medium on the other side.
    pub back: usize,
    /// Thin layers on the front side, outermost first: `(medium, thickness_nm)`. Not
    /// meshed: the tracer applies the stack's transfer-matrix coefficients at the
    /// interface (layers thin against the beamlet and flat across it; docs/physics.md).
    pub coating: Vec<(usize, f64)>,
}

/// A loaded sample: a periodic tile `[0, Lx) x [0, Ly)` in nanometres, its media and its
/// interfaces.
#[derive(Clone, Debug)]
pub struct Sample {
    pub name: String,
    pub path: PathBuf,
    /// Every file the description names (itself, meshes, height maps, media tables and
    /// models): what an output must never replace.
    pub inputs: Vec<PathBuf>,
    pub tile_nm: [f64; 2],
    /// Sorted by name, so ids are deterministic.
    pub media: Vec<Medium>,
    pub interfaces: Vec<Interface>,
    /// The layer structure when the sample was written as a `[stack]`, for analytic
    /// references.
    pub stack: Option<Stack>,
    /// Open sides with a guard band (`[sample] guard`, nm): trees launch at least this far
    /// from every side of the tile, and light that reaches a side leaves the sample as
    /// escaped power. `None`: periodic sides, where rays wrap around the tile.
    pub guard_nm: Option<f64>,
}

/// A flat layered sample: media from top to bottom and the layer thicknesses (nm).
#[derive(Clone, Debug, PartialEq)]
pub struct Stack {
    /// Medium above the stack (index into `Sample::media`).
    pub ambient: usize,
    /// `(medium, thickness_nm)`, top layer first.
    pub layers: Vec<(usize, f64)>,
    /// Medium below the stack.
    pub substrate: usize,
}

impl Sample {
    /// Each medium's complex index `n + i k` at `lambda_nm` (nm), into `out` in medium
    /// order (cleared first, so a run reuses one buffer per thread).
    ///
    /// # Panics
    /// When a medium's model does not cover `lambda_nm`: a run checks every medium's range
    /// before it traces (`simulate`'s refusals).
    pub fn indices_into(&self, lambda_nm: f64, out: &mut Vec<crate::optics::C64>) {
        out.clear();
        out.extend(self.media.iter().map(|m| {
            let (n, k) = m
                .model
                .eval(lambda_nm)
                .expect("a run checks the media's ranges before tracing");
            crate::optics::C64::new(n, k)
        }));
    }

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

    /// The same sample repeated `k[0] x k[1]` times over a larger tile: a larger sampled
    /// area with identical statistics (for the darkening experiment). Periodic sides only:
    /// an open sample is one patch.
    ///
    /// # Panics
    /// When a count is zero, or the sample has open sides.
    pub fn tiled(&self, k: [usize; 2]) -> Sample {
        assert!(k[0] > 0 && k[1] > 0, "tile at least once");
        assert!(self.guard_nm.is_none(), "an open sample cannot be tiled");
        let [lx, ly] = self.tile_nm;
        let mut out = self.clone();
        out.tile_nm = [lx * k[0] as f64, ly * k[1] as f64];
        for itf in &mut out.interfaces {
            let base = itf.mesh.clone();
            let mut m = Mesh::default();
            for i in 0..k[0] {
                for j in 0..k[1] {
                    let mut c = base.clone();
                    for p in &mut c.positions_nm {
                        p.x += i as f64 * lx;
                        p.y += j as f64 * ly;
                    }
                    m.append(&c);
                }
            }
            itf.mesh = m;
        }
        out
    }

    pub fn triangle_count(&self) -> usize {
        self.interfaces.iter().map(|i| i.mesh.triangles.len()).sum()
    }

    pub fn medium_id(&self, name: &str) -> Option<usize> {
        self.media.iter().position(|m| m.name == name)
    }
}

/// 1-based line of byte offset `pos` in `text`.
pub(crate) fn line_of(text: &str, pos: usize) -> usize {
    line_of_bytes(text.as_bytes(), pos)
}

/// Loads a mesh file by its extension: OBJ (the default), PLY or STL.
/// Large files go through their binary cache (`cache`, per `opts.cache`).
pub fn load_mesh(path: &Path, nm_per_unit: f64, opts: MeshOptions) -> Result<Mesh, SampleError> {
    load_mesh_with(path, nm_per_unit, opts).map(|(m, _)| m)
}

/// [`load_mesh`], also saying whether the mesh came from its cache.
pub fn load_mesh_with(
    path: &Path,
    nm_per_unit: f64,
    opts: MeshOptions,
) -> Result<(Mesh, cache::Loaded), SampleError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    cache::load(
        path,
        nm_per_unit,
        opts.drop_degenerate,
        opts.cache,
        || match ext.as_deref() {
            Some("ply") => plystl::load_ply(path, nm_per_unit, opts),
            Some("stl") => plystl::load_stl(path, nm_per_unit, opts),
            _ => load_obj(path, nm_per_unit, opts),
        },
    )
}

/// 1-based line of byte offset `pos` in `bytes` (`\n` ends a line).
pub(crate) fn line_of_bytes(bytes: &[u8], pos: usize) -> usize {
    bytes[..pos.min(bytes.len())]
        .iter()
        .filter(|&&b| b == b'\n')
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

/// The guard band of an open sample whose `[sample]` does not give one, as a fraction of
/// the shorter tile side: trees launch in the central 80 % of each side.
pub const DEFAULT_GUARD_FRACTION: f64 = 0.1;

/// Loads a sample description and every mesh it names.
pub fn load(path: &Path, opts: MeshOptions) -> Result<Sample, SampleError> {
    let text = crate::io::read_text(path)
        .map_err(|e| SampleError::file(path, SampleErrorKind::Io(e.to_string())))?;
    parse(path, &text, opts)
}

/// A surface facing the light is flat when more than this fraction of the projected area
/// of its facets facing the ambient medium lies within [`FLAT_WITHIN_RAD`] of the normal.
pub const FLAT_TOP_FRACTION: f64 = 0.99;
/// The facet tilt within which a facet counts as flat, radians (0.5 degrees).
pub const FLAT_WITHIN_RAD: f64 = 0.5 * std::f64::consts::PI / 180.0;

/// The fraction of the projected area (`int cos(theta_m) dA`) of the facets that face the
/// medium `ambient` (the medium above the sample) lying within [`FLAT_WITHIN_RAD`] of the
/// normal: near 1 for a clear coat or a flat film, whose mirror reflection is a delta.
/// 0 where no facet faces it.
pub fn flat_fraction(sample: &Sample, ambient: usize) -> f64 {
    let (mut projected, mut flat) = (0.0, 0.0);
    for itf in &sample.interfaces {
        let sign = if itf.front == ambient {
            1.0
        } else if itf.back == ambient {
            -1.0
        } else {
            continue;
        };
        for k in 0..itf.mesh.triangles.len() {
            let a = itf.mesh.area_vector(k) * sign;
            let len = a.length();
            if len.is_nan() || len <= 0.0 || a.z <= 0.0 {
                continue;
            }
            projected += 0.5 * a.z;
            if a.z / len > FLAT_WITHIN_RAD.cos() {
                flat += 0.5 * a.z;
            }
        }
    }
    if projected > 0.0 {
        flat / projected
    } else {
        0.0
    }
}

/// Whether the surface facing the medium `ambient` is flat ([`flat_fraction`] above
/// [`FLAT_TOP_FRACTION`]): its mirror reflection is a delta.
pub fn flat_top(sample: &Sample, ambient: usize) -> bool {
    flat_fraction(sample, ambient) > FLAT_TOP_FRACTION
}
