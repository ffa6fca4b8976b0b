//! The sample description as written: the TOML model, with the spans that error messages
//! point at. [`super::resolve`] turns it into a [`super::Sample`].

use std::collections::BTreeMap;

use serde::Deserialize;
use toml::Spanned;

use super::generate::GeneratorSpec;
use super::heightmap;
use super::media::RawMedium;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawSample {
    pub(super) sample: RawHeader,
    #[serde(default)]
    pub(super) media: BTreeMap<String, Spanned<RawMedium>>,
    pub(super) stack: Option<Spanned<RawStack>>,
    #[serde(default)]
    pub(super) interface: Vec<RawInterface>,
    #[serde(default)]
    pub(super) body: Vec<RawBody>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawStack {
    /// `"coating"` (default): one flat interface carrying the layers, exact by the
    /// transfer-matrix method; `"mesh"`: every layer boundary meshed and ray-traced.
    pub(super) mode: Option<Spanned<String>>,
    pub(super) ambient: Spanned<String>,
    #[serde(default)]
    pub(super) layers: Vec<RawLayer>,
    pub(super) substrate: Spanned<String>,
}

#[derive(Deserialize, Clone)]
#[serde(deny_unknown_fields)]
pub(super) struct RawLayer {
    pub(super) medium: Spanned<String>,
    pub(super) thickness: Spanned<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawBody {
    pub(super) mesh: Option<Spanned<String>>,
    pub(super) generator: Option<Spanned<GeneratorSpec>>,
    pub(super) inside: Spanned<String>,
    pub(super) outside: Spanned<String>,
    pub(super) coating: Option<RawCoating>,
}

/// A body's `coating`: a medium name for a meshed shell, or a list of thin layers. (Inside
/// an untagged enum serde buffers the value, which loses TOML spans, and a `Spanned` there
/// matches no variant at all: errors in either form point at the body's `inside` line.)
#[derive(Deserialize)]
#[serde(untagged)]
pub(super) enum RawCoating {
    Shell(String),
    Layers(Vec<RawPlainLayer>),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawPlainLayer {
    pub(super) medium: String,
    pub(super) thickness: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawHeader {
    pub(super) name: String,
    pub(super) unit: Spanned<String>,
    /// Optional where a height map sets the tile.
    pub(super) tile: Option<Spanned<Vec<f64>>>,
    /// Open sides with a guard band this wide (sample units).
    pub(super) guard: Option<Spanned<f64>>,
    #[serde(default)]
    #[allow(dead_code)]
    pub(super) description: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawInterface {
    pub(super) mesh: Option<Spanned<String>>,
    pub(super) generator: Option<Spanned<GeneratorSpec>>,
    /// A measured surface (`heightmap` module), with its scale where the format has none,
    /// how its edges are made periodic and what happens to missing points.
    pub(super) heightmap: Option<Spanned<String>>,
    pub(super) pixel_size: Option<Spanned<RawPixelSize>>,
    pub(super) height_scale: Option<Spanned<f64>>,
    pub(super) edges: Option<heightmap::Edges>,
    pub(super) missing: Option<heightmap::Missing>,
    pub(super) front: Spanned<String>,
    pub(super) back: Spanned<String>,
    /// Thin layers on the front side, outermost first.
    pub(super) coating: Option<Vec<RawLayer>>,
}

/// `pixel_size = 0.05` or `pixel_size = [0.05, 0.08]` (x, y), sample units.
#[derive(Deserialize, Clone, Copy)]
#[serde(untagged)]
pub(super) enum RawPixelSize {
    Both(f64),
    Each([f64; 2]),
}
