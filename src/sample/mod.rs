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

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};

use serde::Deserialize;
use toml::Spanned;

use crate::geom::TriangleSoup;
use generate::{Generated, GeneratorSpec};
use media::RawMedium;
pub use media::{IndexModel, Medium, Scattering};
pub use mesh::Mesh;
pub use obj::{MeshOptions, load_obj, parse_obj};

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
    /// area with identical statistics (for the darkening experiment).
    ///
    /// # Panics
    /// When a count is zero.
    /// The sample repeated `k` times along x and y (periodic sides only: an open sample is
    /// one patch).
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

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSample {
    sample: RawHeader,
    #[serde(default)]
    media: BTreeMap<String, Spanned<RawMedium>>,
    stack: Option<Spanned<RawStack>>,
    #[serde(default)]
    interface: Vec<RawInterface>,
    #[serde(default)]
    body: Vec<RawBody>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawStack {
    /// `"coating"` (default): one flat interface carrying the layers, exact by the
    /// transfer-matrix method; `"mesh"`: every layer boundary meshed and ray-traced.
    mode: Option<Spanned<String>>,
    ambient: Spanned<String>,
    #[serde(default)]
    layers: Vec<RawLayer>,
    substrate: Spanned<String>,
}

#[derive(Deserialize, Clone)]
#[serde(deny_unknown_fields)]
struct RawLayer {
    medium: Spanned<String>,
    thickness: Spanned<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawBody {
    mesh: Option<Spanned<String>>,
    generator: Option<Spanned<GeneratorSpec>>,
    inside: Spanned<String>,
    outside: Spanned<String>,
    coating: Option<RawCoating>,
}

/// A body's `coating`: a medium name for a meshed shell, or a list of thin layers. (Inside
/// an untagged enum serde buffers the value, which loses TOML spans, and a `Spanned` there
/// matches no variant at all: errors in either form point at the body's `inside` line.)
#[derive(Deserialize)]
#[serde(untagged)]
enum RawCoating {
    Shell(String),
    Layers(Vec<RawPlainLayer>),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPlainLayer {
    medium: String,
    thickness: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawHeader {
    name: String,
    unit: Spanned<String>,
    /// Optional where a height map sets the tile.
    tile: Option<Spanned<Vec<f64>>>,
    /// Open sides with a guard band this wide (sample units).
    guard: Option<Spanned<f64>>,
    #[serde(default)]
    #[allow(dead_code)]
    description: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawInterface {
    mesh: Option<Spanned<String>>,
    generator: Option<Spanned<GeneratorSpec>>,
    /// A measured surface (`heightmap` module), with its scale where the format has none,
    /// how its edges are made periodic and what happens to missing points.
    heightmap: Option<Spanned<String>>,
    pixel_size: Option<Spanned<RawPixelSize>>,
    height_scale: Option<Spanned<f64>>,
    edges: Option<heightmap::Edges>,
    missing: Option<heightmap::Missing>,
    front: Spanned<String>,
    back: Spanned<String>,
    /// Thin layers on the front side, outermost first.
    coating: Option<Vec<RawLayer>>,
}

/// `pixel_size = 0.05` or `pixel_size = [0.05, 0.08]` (x, y), sample units.
#[derive(Deserialize, Clone, Copy)]
#[serde(untagged)]
enum RawPixelSize {
    Both(f64),
    Each([f64; 2]),
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

/// Reads an interface's height map and meshes it: (mesh, tile in nm, description).
fn load_heightmap(
    ri: &RawInterface,
    h: &Spanned<String>,
    base: &Path,
    nm_per_unit: f64,
    open: bool,
) -> Result<(Mesh, [f64; 2], String), String> {
    let file = base.join(h.get_ref());
    let scale = match (ri.pixel_size.as_ref(), ri.height_scale.as_ref()) {
        (None, None) => None,
        (Some(p), Some(z)) => {
            let [dx, dy] = match *p.get_ref() {
                RawPixelSize::Both(d) => [d, d],
                RawPixelSize::Each(d) => d,
            };
            let z = *z.get_ref();
            if !(dx.is_finite() && dy.is_finite() && dx > 0.0 && dy > 0.0) {
                return Err(format!(
                    "pixel_size must be positive and finite, got [{dx}, {dy}]"
                ));
            }
            if !(z.is_finite() && z != 0.0) {
                return Err(format!("height_scale must be finite and non-zero, got {z}"));
            }
            Some(heightmap::Scale {
                dx_nm: dx * nm_per_unit,
                dy_nm: dy * nm_per_unit,
                dz_nm: z * nm_per_unit,
            })
        }
        _ => return Err("give both pixel_size and height_scale, or neither".into()),
    };
    let mut map = heightmap::read(&file, scale).map_err(|e| e.to_string())?;
    let filled = map
        .resolve_missing(ri.missing.unwrap_or_default())
        .map_err(|e| e.to_string())?;
    let edges = match (ri.edges, open) {
        (None, true) => heightmap::Edges::Guard,
        (None, false) => heightmap::Edges::default(),
        (Some(e @ (heightmap::Edges::Mirror | heightmap::Edges::Periodic)), true) => {
            return Err(format!(
                "edges = \"{}\" makes the patch periodic, but [sample] guard opens the sample's sides: use edges = \"guard\" (the default with a guard band) or remove guard",
                e.name()
            ));
        }
        (Some(e), _) => e,
    };
    let (mesh, tile) = map.mesh(edges).map_err(|e| e.to_string())?;
    let desc = format!(
        "height map {} ({} x {} points, {} x {} nm apart{}, edges {})",
        file.display(),
        map.nx,
        map.ny,
        map.dx_nm,
        map.dy_nm,
        if filled > 0 {
            format!(", {filled} missing points filled")
        } else {
            String::new()
        },
        match edges {
            heightmap::Edges::Mirror => "mirrored",
            heightmap::Edges::Periodic => "periodic",
            heightmap::Edges::Guard => "open, with a guard band",
        }
    );
    Ok((mesh, tile, desc))
}

/// 1-based line of byte offset `pos` in `bytes` (`\n` ends a line).
pub(crate) fn line_of_bytes(bytes: &[u8], pos: usize) -> usize {
    bytes[..pos.min(bytes.len())]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
        + 1
}

/// Every coordinate finite and within [`MAX_LENGTH_NM`], and no triangle that collapses
/// when the accelerator rounds its corners to f32 (it would be invisible, or hide its
/// neighbour). The message names the interface.
fn check_geometry(interfaces: &[Interface], tile_nm: [f64; 2]) -> Result<(), SampleErrorKind> {
    let mut extent = tile_nm[0].max(tile_nm[1]);
    for itf in interfaces {
        for p in &itf.mesh.positions_nm {
            for c in p.to_array() {
                if !(c.is_finite() && c.abs() <= MAX_LENGTH_NM) {
                    return Err(format!("{}: {}", itf.mesh_path.display(), beyond_limit(c)).into());
                }
                extent = extent.max(c.abs());
            }
        }
    }
    for itf in interfaces {
        let collapsed = itf.mesh.degenerate_triangles_f32();
        if !collapsed.is_empty() {
            return Err(format!(
                "{}: {} of {} triangles collapse when the accelerator rounds coordinates to f32 (spacing {:.2e} nm where the sample reaches {extent:e} nm): enlarge the features or shrink the sample",
                itf.mesh_path.display(),
                collapsed.len(),
                itf.mesh.triangles.len(),
                f32_resolution_nm(extent)
            )
            .into());
        }
    }
    Ok(())
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

/// The largest tile side, layer thickness or coordinate a sample may have, nm (10 cm).
///
/// The accelerators hold vertices in f32 (a 24-bit significand): at 1e8 nm neighbouring
/// f32 values are 8 nm apart, already coarser than a thin film. Phases are formed in f64:
/// over 1e8 nm at 380 nm, `k L` is 1.7e6 rad with a rounding error near 4e-10 rad
/// (docs/design.md §1). Microgeometry tiles are micrometres to millimetres.
pub const MAX_LENGTH_NM: f64 = 1e8;

/// Why a vertex cannot be scaled to nanometres.
pub(crate) enum VertexFault {
    /// Not finite after scaling (the coordinate, nm).
    NonFinite(f64),
    /// Beyond [`MAX_LENGTH_NM`] (the coordinate, nm).
    TooFar(f64),
}

/// A vertex `p` in file units scaled to nanometres and checked: finite, and every
/// coordinate within [`MAX_LENGTH_NM`]. Shared by the OBJ, PLY and STL readers, which
/// place the fault in their own terms.
pub(crate) fn scale_vertex(p: [f64; 3], nm_per_unit: f64) -> Result<glam::DVec3, VertexFault> {
    let q = p.map(|c| c * nm_per_unit);
    if let Some(&c) = q.iter().find(|c| !c.is_finite()) {
        return Err(VertexFault::NonFinite(c));
    }
    if let Some(&c) = q.iter().find(|c| c.abs() > MAX_LENGTH_NM) {
        return Err(VertexFault::TooFar(c));
    }
    Ok(glam::DVec3::from(q))
}

/// The message for a coordinate `c` (nm) beyond [`MAX_LENGTH_NM`].
pub(crate) fn beyond_limit(c: f64) -> String {
    format!(
        "coordinate {c:e} nm is beyond the {MAX_LENGTH_NM:e} nm (10 cm) limit of f32 geometry and f64 phase"
    )
}

/// The separation f32 vertices can resolve in a scene whose coordinates reach `extent_nm`:
/// the f32 spacing there (`extent * 2^-23`), floored at the tracer's 1e-4 nm restart
/// offset. Interfaces closer than a few of these cannot be told apart by the accelerator.
pub fn f32_resolution_nm(extent_nm: f64) -> f64 {
    (extent_nm * f64::from(f32::EPSILON)).max(1e-4)
}

/// Interfaces meshed closer than this many [`f32_resolution_nm`] are refused.
const MIN_SEPARATION_RESOLUTIONS: f64 = 16.0;

/// Checks a length after scaling to nanometres: finite, positive and at most
/// [`MAX_LENGTH_NM`]; `what` names it in the message.
fn check_length(what: &str, value: f64, unit: &str, nm: f64) -> Result<(), SampleErrorKind> {
    // Very large or small values in scientific notation, not hundreds of digits.
    let value = if value == 0.0 || (1e-4..1e6).contains(&value.abs()) {
        format!("{value}")
    } else {
        format!("{value:e}")
    };
    if !(nm.is_finite() && nm > 0.0) {
        return Err(SampleErrorKind::from(format!(
            "{what} must be positive and finite, got {value} {unit}"
        )));
    }
    if nm > MAX_LENGTH_NM {
        return Err(SampleErrorKind::from(format!(
            "{what} {value} {unit} ({nm:e} nm) exceeds the {MAX_LENGTH_NM:e} nm (10 cm) limit of f32 geometry and f64 phase"
        )));
    }
    Ok(())
}

/// Loads a sample description and every mesh it names.
pub fn load(path: &Path, opts: MeshOptions) -> Result<Sample, SampleError> {
    let text = crate::io::read_text(path)
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

    let inputs = input_files(path, &raw);
    let unit = raw.sample.unit.get_ref();
    let scale = nm_per_unit(unit).ok_or_else(|| {
        at(
            raw.sample.unit.span(),
            SampleErrorKind::BadUnit(unit.clone()),
        )
    })?;
    let base = path.parent().unwrap_or(Path::new(""));
    // Open sides: asked for in [sample], or by a height map's edges.
    let open = raw.sample.guard.is_some()
        || raw
            .interface
            .iter()
            .any(|ri| ri.edges == Some(heightmap::Edges::Guard));
    // Measured surfaces first: they set the tile.
    let mut measured: Vec<Option<(Mesh, [f64; 2], String)>> = Vec::new();
    for ri in &raw.interface {
        measured.push(match &ri.heightmap {
            None => {
                if ri.pixel_size.is_some()
                    || ri.height_scale.is_some()
                    || ri.edges.is_some()
                    || ri.missing.is_some()
                {
                    return Err(at(
                        ri.front.span(),
                        SampleErrorKind::Invalid(
                            "pixel_size, height_scale, edges and missing belong to an interface with a heightmap".into(),
                        ),
                    ));
                }
                None
            }
            Some(h) => Some(load_heightmap(ri, h, base, scale, open).map_err(|m| {
                at(
                    h.span(),
                    SampleErrorKind::Invalid(format!(
                        "height map {}: {m}",
                        base.join(h.get_ref()).display()
                    )),
                )
            })?),
        });
    }
    let measured_tile = measured.iter().flatten().next().map(|m| m.1);
    let [tx, ty] = match (&raw.sample.tile, measured_tile) {
        (Some(tile), _) => match tile.get_ref()[..] {
            [x, y] => [x, y],
            ref other => {
                return Err(at(
                    tile.span(),
                    SampleErrorKind::Invalid(format!(
                        "tile must be [Lx, Ly] (two lengths; the tile is periodic in x and y only), got {} values",
                        other.len()
                    )),
                ));
            }
        },
        (None, Some(t)) => [t[0] / scale, t[1] / scale],
        (None, None) => {
            return Err(SampleError::file(
                path,
                SampleErrorKind::Invalid(
                    "[sample] needs tile = [Lx, Ly] (only a heightmap interface sets the tile itself)"
                        .into(),
                ),
            ));
        }
    };
    let tile_span = raw.sample.tile.as_ref().map_or(0..0, |t| t.span());
    if !(tx.is_finite() && ty.is_finite() && tx > 0.0 && ty > 0.0) {
        return Err(at(tile_span, SampleErrorKind::BadTile(tx, ty)));
    }
    // Every measured surface spans the tile exactly.
    for (ri, m) in raw.interface.iter().zip(&measured) {
        if let (Some((_, t, _)), Some(h)) = (m, &ri.heightmap) {
            let (ex, ey) = (t[0] / scale, t[1] / scale);
            if (ex - tx).abs() > 1e-9 * tx || (ey - ty).abs() > 1e-9 * ty {
                return Err(at(
                    h.span(),
                    SampleErrorKind::Invalid(format!(
                        "height map {} spans [{ex}, {ey}] {unit} (with its edges made periodic), but the tile is [{tx}, {ty}] {unit}: remove tile from [sample] or make it match",
                        h.get_ref()
                    )),
                ));
            }
        }
    }

    let mut media = Vec::new();
    for (name, m) in &raw.media {
        let model = media::build_model(m.get_ref(), base, true).map_err(|e| match e.file {
            Some((file, line)) => {
                let inner = SampleError {
                    path: file.clone(),
                    line,
                    kind: SampleErrorKind::Invalid(e.message.clone()),
                };
                at(
                    m.span(),
                    SampleErrorKind::MediumFile {
                        file: file.display().to_string(),
                        message: format!("medium '{name}': {inner}"),
                    },
                )
            }
            None => at(
                m.span(),
                SampleErrorKind::BadMedium {
                    name: name.clone(),
                    message: e.message,
                },
            ),
        })?;
        media.push(Medium {
            name: name.clone(),
            model,
            scattering: None,
        });
    }
    // Scattering: particles name another medium, so every medium exists first.
    for (name, m) in &raw.media {
        let raw_m = m.get_ref();
        let bad = |message: String| {
            at(
                m.span(),
                SampleErrorKind::BadMedium {
                    name: name.clone(),
                    message,
                },
            )
        };
        let scattering = match (&raw_m.particles, &raw_m.henyey_greenstein) {
            (None, None) => continue,
            (Some(_), Some(_)) => {
                return Err(bad(
                    "has both particles and henyey_greenstein; give one".into()
                ));
            }
            (Some(p), None) => {
                let Some(pm) = media.iter().position(|x| x.name == p.medium) else {
                    return Err(bad(format!("particles of unknown medium '{}'", p.medium)));
                };
                if pm
                    == media
                        .iter()
                        .position(|x| &x.name == name)
                        .unwrap_or(usize::MAX)
                {
                    return Err(bad("particles cannot be of the medium they are in".into()));
                }
                if raw.media[&p.medium].get_ref().particles.is_some()
                    || raw.media[&p.medium].get_ref().henyey_greenstein.is_some()
                {
                    return Err(bad(format!(
                        "particles of '{}', itself a scattering medium: a particle is one homogeneous medium",
                        p.medium
                    )));
                }
                use crate::optics::particles::Radius;
                let radius = match (p.radius_nm, &p.log_normal) {
                    (Some(r), None) => {
                        if !(r.is_finite() && r > 0.0 && r <= 1e6) {
                            return Err(bad(format!(
                                "particles: radius_nm must be between 0 and 1e6 nm, got {r}"
                            )));
                        }
                        Radius::Fixed { radius_nm: r }
                    }
                    (None, Some(ln)) => {
                        let (r, sg) = (ln.median_radius_nm, ln.sigma);
                        if !(r.is_finite() && r > 0.0 && r <= 1e6) {
                            return Err(bad(format!(
                                "particles: median_radius_nm must be between 0 and 1e6 nm, got {r}"
                            )));
                        }
                        if !(sg.is_finite() && sg > 0.0 && sg <= 1.0) {
                            return Err(bad(format!(
                                "particles: the log-normal sigma (of ln r) must lie in (0, 1], got {sg}"
                            )));
                        }
                        Radius::LogNormal {
                            median_nm: r,
                            sigma: sg,
                        }
                    }
                    _ => {
                        return Err(bad(
                            "particles need radius_nm or log_normal = { median_radius_nm, sigma }, not both"
                                .into(),
                        ));
                    }
                };
                let f = p.volume_fraction;
                if !(f.is_finite() && f > 0.0 && f < 0.74) {
                    return Err(bad(format!(
                        "particles: volume_fraction must lie in (0, 0.74), got {f}"
                    )));
                }
                crate::sample::Scattering::Particles {
                    medium: pm,
                    radius,
                    volume_fraction: f,
                }
            }
            (None, Some(h)) => {
                crate::optics::particles::ScatterModel::henyey_greenstein(
                    h.g,
                    h.scattering_per_um,
                    h.absorption_per_um,
                )
                .map_err(|e| bad(format!("henyey_greenstein: {e}")))?;
                crate::sample::Scattering::HenyeyGreenstein {
                    g: h.g,
                    scattering_per_um: h.scattering_per_um,
                    absorption_per_um: h.absorption_per_um,
                }
            }
        };
        if let Some(m) = media.iter_mut().find(|x| &x.name == name) {
            m.scattering = Some(scattering);
        }
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
    let tile_nm = [tx * scale, ty * scale];
    for (axis, v, nm) in [("x", tx, tile_nm[0]), ("y", ty, tile_nm[1])] {
        check_length(&format!("tile side {axis}"), v, unit, nm)
            .map_err(|m| at(tile_span.clone(), m))?;
    }
    // The guard band: as given, or a tenth of the shorter side; it must leave an interior
    // to launch trees in.
    let short = tx.min(ty);
    let guard_nm = match (&raw.sample.guard, open) {
        (Some(g), _) => {
            let v = *g.get_ref();
            if !(v.is_finite() && v > 0.0 && v < 0.5 * short) {
                return Err(at(
                    g.span(),
                    SampleErrorKind::Invalid(format!(
                        "guard must leave an interior to launch trees in: 0 < guard < {} {unit} (half the shorter tile side), got {v} {unit}",
                        0.5 * short
                    )),
                ));
            }
            Some(v * scale)
        }
        (None, true) => Some(DEFAULT_GUARD_FRACTION * short * scale),
        (None, false) => None,
    };
    let mut interfaces = Vec::new();

    // Layers (of a [stack] or a coating) as (medium, thickness in nm).
    let layers_of = |raw: &Option<Vec<RawLayer>>| -> Result<Vec<(usize, f64)>, SampleError> {
        let mut layers = Vec::new();
        for l in raw.iter().flatten() {
            let t = *l.thickness.get_ref();
            check_length("layer thickness", t, unit, t * scale)
                .map_err(|m| at(l.thickness.span(), m))?;
            layers.push((medium(&l.medium)?, t * scale));
        }
        Ok(layers)
    };
    // A coating is a thin stack applied by transfer matrices: no volume to scatter in.
    let coating_of = |raw: &Option<Vec<RawLayer>>| -> Result<Vec<(usize, f64)>, SampleError> {
        let layers = layers_of(raw)?;
        for (l, &(m, _)) in raw.iter().flatten().zip(&layers) {
            if media[m].scattering.is_some() {
                return Err(at(
                    l.medium.span(),
                    SampleErrorKind::Invalid(format!(
                        "coating layer '{}' scatters (particles or henyey_greenstein), but a coating is a thin film applied by transfer matrices; make it a meshed layer",
                        media[m].name
                    )),
                ));
            }
        }
        Ok(layers)
    };

    // [stack]: one coated flat interface (default), or flat meshed interfaces, top
    // (ambient side) first.
    let mut stack = None;
    if let Some(st) = &raw.stack {
        let ambient = medium(&st.get_ref().ambient)?;
        let substrate = medium(&st.get_ref().substrate)?;
        let layers = layers_of(&Some(st.get_ref().layers.clone()))?;
        // Default: a pure stack is one exact coated interface; a stack that shares the
        // sample with bodies or other interfaces (a binder holding pigments) is meshed,
        // since those live inside its layers.
        let others = !raw.interface.is_empty() || !raw.body.is_empty();
        // A scattering layer is a volume the tracer walks through: meshed.
        let scattering = layers.iter().any(|&(m, _)| media[m].scattering.is_some());
        let meshed = match st.get_ref().mode.as_ref() {
            None => others || scattering,
            Some(m) => match m.get_ref().as_str() {
                "coating" if scattering => {
                    return Err(at(
                        m.span(),
                        SampleErrorKind::Invalid(
                            "a [stack] with a scattering layer (particles or henyey_greenstein) cannot be an exact coating: remove mode or use mode = \"mesh\"".into(),
                        ),
                    ));
                }
                "coating" => false,
                "mesh" => true,
                other => {
                    return Err(at(
                        m.span(),
                        SampleErrorKind::Invalid(format!(
                            "unknown [stack] mode '{other}' (use \"coating\", the exact default, or \"mesh\")"
                        )),
                    ));
                }
            },
        };
        if meshed {
            // Every layer becomes two meshed planes: they must stay apart in f32.
            let total: f64 = layers.iter().map(|l| l.1).sum();
            if !layers.is_empty() {
                check_length("total stack thickness", total / scale, unit, total)
                    .map_err(|m| at(st.span(), m))?;
            }
            let res = f32_resolution_nm(tile_nm[0].max(tile_nm[1]).max(total));
            for (l, &(_, t)) in st.get_ref().layers.iter().zip(&layers) {
                if t < MIN_SEPARATION_RESOLUTIONS * res {
                    return Err(at(
                        l.thickness.span(),
                        SampleErrorKind::Invalid(format!(
                            "a meshed layer of {t:e} nm is thinner than f32 geometry can separate at this tile size ({MIN_SEPARATION_RESOLUTIONS} x {res:.2e} nm); use the exact [stack] mode = \"coating\""
                        )),
                    ));
                }
            }
        }
        stack = Some(Stack {
            ambient,
            layers: layers.clone(),
            substrate,
        });
        if !meshed {
            interfaces.push(Interface {
                mesh: generate::flat(tile_nm, 0.0),
                mesh_path: PathBuf::from("[stack] coated interface (z = 0 nm)"),
                closed: false,
                front: ambient,
                back: substrate,
                coating: layers.clone(),
            });
        }
    }
    if let Some(stk) = &stack
        && interfaces.is_empty()
    {
        let (ambient, substrate, layers) = (stk.ambient, stk.substrate, stk.layers.clone());
        let total: f64 = layers.iter().map(|l| l.1).sum();
        let mut above = ambient;
        let mut z = total;
        for (i, &(m, t)) in layers.iter().enumerate() {
            interfaces.push(Interface {
                mesh: generate::flat(tile_nm, z),
                mesh_path: PathBuf::from(format!("[stack] interface {i} (z = {z} nm)")),
                closed: false,
                front: above,
                back: m,
                coating: Vec::new(),
            });
            above = m;
            z -= t;
        }
        interfaces.push(Interface {
            mesh: generate::flat(tile_nm, 0.0),
            mesh_path: PathBuf::from(format!("[stack] interface {} (z = 0 nm)", layers.len())),
            closed: false,
            front: above,
            back: substrate,
            coating: Vec::new(),
        });
    }

    // Loads a mesh or runs a generator for an [[interface]] or a [[body]].
    let source = |mesh: &Option<Spanned<String>>,
                  generator: &Option<Spanned<GeneratorSpec>>,
                  want_bodies: bool,
                  what: &str|
     -> Result<(Generated, String), SampleError> {
        match (mesh, generator) {
            (Some(m), None) => {
                let mesh_path = base.join(m.get_ref());
                let mesh = load_mesh(&mesh_path, scale, opts).map_err(|e| {
                    at(
                        m.span(),
                        SampleErrorKind::Mesh {
                            mesh: m.get_ref().clone(),
                            error: Box::new(e),
                        },
                    )
                })?;
                let desc = mesh_path.display().to_string();
                Ok((
                    if want_bodies {
                        Generated::Bodies(vec![(mesh, None)])
                    } else {
                        Generated::Sheet(mesh)
                    },
                    desc,
                ))
            }
            (None, Some(g)) => {
                let spec = g.get_ref();
                if spec.makes_bodies() != want_bodies {
                    return Err(at(
                        g.span(),
                        SampleErrorKind::Invalid(format!(
                            "generator '{}' makes {}, so it belongs in {}",
                            spec.kind(),
                            if spec.makes_bodies() {
                                "closed bodies"
                            } else {
                                "a sheet"
                            },
                            if spec.makes_bodies() {
                                "[[body]]"
                            } else {
                                "[[interface]]"
                            }
                        )),
                    ));
                }
                let out = spec.generate(tile_nm, scale).map_err(|e| {
                    at(
                        g.span(),
                        SampleErrorKind::Generator {
                            kind: spec.kind().to_string(),
                            message: e.to_string(),
                        },
                    )
                })?;
                Ok((out, format!("generator {}", spec.kind())))
            }
            _ => Err(SampleError::file(
                path,
                SampleErrorKind::Invalid(format!(
                    "every {what} needs exactly one of mesh = \"FILE.obj\" or generator = {{ kind = ... }}"
                )),
            )),
        }
    };

    for (ri, m) in raw.interface.iter().zip(measured) {
        let front = medium(&ri.front)?;
        let back = medium(&ri.back)?;
        let (mesh, desc) = match m {
            Some((mesh, _, desc)) => {
                if ri.mesh.is_some() || ri.generator.is_some() {
                    return Err(at(
                        ri.front.span(),
                        SampleErrorKind::Invalid(
                            "an [[interface]] takes one of mesh, generator or heightmap".into(),
                        ),
                    ));
                }
                (mesh, desc)
            }
            None => {
                let (g, desc) = source(&ri.mesh, &ri.generator, false, "[[interface]]")?;
                let Generated::Sheet(mesh) = g else {
                    unreachable!("sheet requested")
                };
                (mesh, desc)
            }
        };
        let coating = coating_of(&ri.coating)?;
        interfaces.push(Interface {
            mesh,
            mesh_path: PathBuf::from(desc),
            closed: false,
            front,
            back,
            coating,
        });
    }
    for rb in &raw.body {
        let inside = medium(&rb.inside)?;
        let outside = medium(&rb.outside)?;
        // `coating = "MEDIUM"`: a meshed shell (the generator's coated bodies);
        // `coating = [ { medium, thickness }, ... ]`: thin layers on the outside.
        let (coating, thin) = match &rb.coating {
            Some(RawCoating::Shell(m)) => {
                let m = Spanned::new(rb.inside.span(), m.clone());
                (Some(medium(&m)?), Vec::new())
            }
            Some(RawCoating::Layers(l)) => {
                let span = rb.inside.span();
                let spanned: Vec<RawLayer> = l
                    .iter()
                    .map(|x| RawLayer {
                        medium: Spanned::new(span.clone(), x.medium.clone()),
                        thickness: Spanned::new(span.clone(), x.thickness),
                    })
                    .collect();
                (None, coating_of(&Some(spanned))?)
            }
            None => (None, Vec::new()),
        };
        let (g, desc) = source(&rb.mesh, &rb.generator, true, "[[body]]")?;
        let Generated::Bodies(bodies) = g else {
            unreachable!("bodies requested")
        };
        for (i, (core, shell)) in bodies.into_iter().enumerate() {
            match (shell, coating) {
                (Some(shell), Some(c)) => {
                    interfaces.push(Interface {
                        mesh: shell,
                        mesh_path: PathBuf::from(format!("{desc} body {i} coating")),
                        closed: true,
                        front: outside,
                        back: c,
                        coating: Vec::new(),
                    });
                    interfaces.push(Interface {
                        mesh: core,
                        mesh_path: PathBuf::from(format!("{desc} body {i}")),
                        closed: true,
                        front: c,
                        back: inside,
                        coating: Vec::new(),
                    });
                }
                (Some(_), None) => {
                    return Err(SampleError::file(
                        path,
                        SampleErrorKind::Invalid(format!(
                            "{desc}: the bodies are coated, so the [[body]] needs coating = \"MEDIUM\""
                        )),
                    ));
                }
                (None, _) => interfaces.push(Interface {
                    mesh: core,
                    mesh_path: PathBuf::from(format!("{desc} body {i}")),
                    closed: true,
                    front: outside,
                    back: inside,
                    coating: thin.clone(),
                }),
            }
        }
    }
    if interfaces.is_empty() {
        return Err(SampleError::file(path, SampleErrorKind::NoInterfaces));
    }
    check_geometry(&interfaces, tile_nm).map_err(|m| SampleError::file(path, m))?;

    Ok(Sample {
        name: raw.sample.name,
        path: path.to_path_buf(),
        tile_nm,
        media,
        interfaces,
        stack,
        guard_nm,
        inputs,
    })
}

/// Every file a sample description names, resolved against its folder: the description
/// itself, meshes, height maps, and media tables and model files. Outputs must never be one
/// of them (`simulate --force` overwrote a sample's own `.x3p` or media `.csv`).
fn input_files(path: &Path, raw: &RawSample) -> Vec<PathBuf> {
    let base = path.parent().unwrap_or(Path::new(""));
    let mut files = vec![path.to_path_buf()];
    for m in raw.media.values() {
        let m = m.get_ref();
        files.extend(m.table.iter().chain(&m.model).map(|f| base.join(f)));
    }
    for i in &raw.interface {
        files.extend(
            i.mesh
                .iter()
                .chain(&i.heightmap)
                .map(|f| base.join(f.get_ref())),
        );
    }
    for b in &raw.body {
        files.extend(b.mesh.iter().map(|f| base.join(f.get_ref())));
    }
    files
}
