//! From the TOML model ([`super::raw`]) to a [`Sample`], in named stages, each refusing
//! what it cannot resolve with the file and line:
//!
//! 1. [`read_raw`]: the TOML text into the raw model;
//! 2. [`Ctx::new`]: the unit, and the folder names are resolved against;
//! 3. [`measured_surfaces`]: height maps, read first because they can set the tile;
//! 4. [`tile`]: the tile, and every height map spanning it;
//! 5. [`media()`]: every medium's index model, then its scattering
//!    ([`media::scattering_of`]: particles name other media, so all of them exist first);
//! 6. [`guard`]: open sides and their guard band;
//! 7. [`stack`]: a `[stack]` as one coated interface or meshed layer planes;
//! 8. [`sheets`] and [`bodies`]: `[[interface]]` and `[[body]]` meshes, generators and
//!    height maps with their media and coatings ([`interfaces`]);
//! 9. the limits of [`super::limits`] on the whole geometry.
//!
//! The stages run in this order, so the first error a file has is the one reported.

use std::ops::Range;
use std::path::{Path, PathBuf};

use toml::Spanned;

mod interfaces;
mod media;

use interfaces::{bodies, sheets, stack};
use media::{Names, media};

use super::limits::{check_geometry, check_length};
use super::raw::{RawInterface, RawPixelSize, RawSample};
use super::{
    DEFAULT_GUARD_FRACTION, Mesh, MeshOptions, Sample, SampleError, SampleErrorKind, heightmap,
    line_of, nm_per_unit,
};

/// Parses a sample description whose text was read from `path` (meshes are resolved
/// relative to `path`'s folder).
pub fn parse(path: &Path, text: &str, opts: MeshOptions) -> Result<Sample, SampleError> {
    let raw = read_raw(path, text)?;
    let inputs = input_files(path, &raw);
    let cx = Ctx::new(path, text, &raw, opts)?;
    // Open sides: asked for in [sample], or by a height map's edges.
    let open = raw.sample.guard.is_some()
        || raw
            .interface
            .iter()
            .any(|ri| ri.edges == Some(heightmap::Edges::Guard));
    let measured = measured_surfaces(&cx, &raw, open)?;
    let [tx, ty] = tile(&cx, &raw, &measured)?;
    let media = media(&cx, &raw)?;
    let tile_span = raw.sample.tile.as_ref().map_or(0..0, |t| t.span());
    let tile_nm = [tx * cx.scale, ty * cx.scale];
    for (axis, v, nm) in [("x", tx, tile_nm[0]), ("y", ty, tile_nm[1])] {
        check_length(&format!("tile side {axis}"), v, cx.unit, nm)
            .map_err(|m| cx.at(tile_span.clone(), m))?;
        if nm < crate::sample::limits::MIN_TILE_NM {
            return Err(cx.at(
                tile_span.clone(),
                SampleErrorKind::from(format!(
                    "tile side {axis} is {} {} ({} nm), below the {} nm a tile needs: rays start 1e-4 nm off the surfaces they leave, which must stay a small fraction of the period (and nothing is periodic on a shorter scale than an atom)",
                    crate::sample::limits::show(v),
                    cx.unit,
                    crate::sample::limits::show(nm),
                    crate::sample::limits::MIN_TILE_NM
                )),
            ));
        }
    }
    let guard_nm = guard(&cx, &raw, [tx, ty], open)?;
    let names = Names {
        cx: &cx,
        media: &media,
    };
    let (stack, mut interfaces) = stack(&names, &raw, tile_nm)?;
    interfaces.extend(sheets(&names, &raw, measured, tile_nm)?);
    interfaces.extend(bodies(&names, &raw, tile_nm, stack.as_ref())?);
    if interfaces.is_empty() {
        return Err(cx.file(SampleErrorKind::NoInterfaces));
    }
    check_geometry(&interfaces, tile_nm).map_err(|m| cx.file(m))?;
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

/// What every stage needs to resolve names and place errors.
struct Ctx<'a> {
    path: &'a Path,
    text: &'a str,
    /// The description's folder: meshes, height maps and tables are relative to it.
    base: &'a Path,
    /// The declared unit, as written, and nanometres per unit.
    unit: &'a str,
    scale: f64,
    opts: MeshOptions,
}

impl<'a> Ctx<'a> {
    fn new(
        path: &'a Path,
        text: &'a str,
        raw: &'a RawSample,
        opts: MeshOptions,
    ) -> Result<Ctx<'a>, SampleError> {
        let unit = raw.sample.unit.get_ref();
        let cx = Ctx {
            path,
            text,
            base: path.parent().unwrap_or(Path::new("")),
            unit,
            scale: 0.0,
            opts,
        };
        let scale = nm_per_unit(unit).ok_or_else(|| {
            cx.at(
                raw.sample.unit.span(),
                SampleErrorKind::BadUnit(unit.clone()),
            )
        })?;
        Ok(Ctx { scale, ..cx })
    }

    /// An error at the line of `span`.
    fn at(&self, span: Range<usize>, kind: SampleErrorKind) -> SampleError {
        SampleError::at(self.path, line_of(self.text, span.start), kind)
    }

    /// An error of the whole file.
    fn file(&self, kind: SampleErrorKind) -> SampleError {
        SampleError::file(self.path, kind)
    }
}

/// Stage 1: the TOML text into the raw model.
fn read_raw(path: &Path, text: &str) -> Result<RawSample, SampleError> {
    toml::from_str(text).map_err(|e| {
        let kind = SampleErrorKind::Toml(e.message().trim().to_string());
        match e.span() {
            Some(s) => SampleError::at(path, line_of(text, s.start), kind),
            None => SampleError::file(path, kind),
        }
    })
}

/// A height map read and meshed: the mesh, its tile (nm) and a description.
type Measured = (Mesh, [f64; 2], String);

/// Stage 3: every interface's height map, in order (`None` where it has none).
fn measured_surfaces(
    cx: &Ctx,
    raw: &RawSample,
    open: bool,
) -> Result<Vec<Option<Measured>>, SampleError> {
    let mut measured = Vec::new();
    for ri in &raw.interface {
        measured.push(match &ri.heightmap {
            None => {
                if ri.pixel_size.is_some()
                    || ri.height_scale.is_some()
                    || ri.edges.is_some()
                    || ri.missing.is_some()
                {
                    return Err(cx.at(
                        ri.front.span(),
                        SampleErrorKind::Invalid(
                            "pixel_size, height_scale, edges and missing belong to an interface with a heightmap".into(),
                        ),
                    ));
                }
                None
            }
            Some(h) => Some(
                load_heightmap(ri, h, cx.base, cx.scale, open)
                    .map_err(|kind| cx.at(h.span(), kind))?,
            ),
        });
    }
    Ok(measured)
}

/// Reads an interface's height map and meshes it: (mesh, tile in nm, description).
fn load_heightmap(
    ri: &RawInterface,
    h: &Spanned<String>,
    base: &Path,
    nm_per_unit: f64,
    open: bool,
) -> Result<Measured, SampleErrorKind> {
    let file = base.join(h.get_ref());
    let bad = |m: String| SampleErrorKind::Invalid(format!("height map {}: {m}", file.display()));
    let scale = match (ri.pixel_size.as_ref(), ri.height_scale.as_ref()) {
        (None, None) => None,
        (Some(p), Some(z)) => {
            let [dx, dy] = match *p.get_ref() {
                RawPixelSize::Both(d) => [d, d],
                RawPixelSize::Each(d) => d,
            };
            let z = *z.get_ref();
            if !(dx.is_finite() && dy.is_finite() && dx > 0.0 && dy > 0.0) {
                return Err(bad(format!(
                    "pixel_size must be positive and finite, got [{dx}, {dy}]"
                )));
            }
            if !(z.is_finite() && z != 0.0) {
                return Err(bad(format!(
                    "height_scale must be finite and non-zero, got {z}"
                )));
            }
            Some(heightmap::Scale {
                dx_nm: dx * nm_per_unit,
                dy_nm: dy * nm_per_unit,
                dz_nm: z * nm_per_unit,
            })
        }
        _ => {
            return Err(bad(
                "give both pixel_size and height_scale, or neither".into()
            ));
        }
    };
    let mut map = heightmap::read(&file, scale).map_err(|e| bad(e.to_string()))?;
    let filled = map
        .resolve_missing(ri.missing.unwrap_or_default())
        .map_err(|e| bad(e.to_string()))?;
    let edges = match (ri.edges, open) {
        (None, true) => heightmap::Edges::Guard,
        (None, false) => heightmap::Edges::default(),
        (Some(e @ (heightmap::Edges::Mirror | heightmap::Edges::Periodic)), true) => {
            return Err(bad(format!(
                "edges = \"{}\" makes the patch periodic, but [sample] guard opens the sample's sides: use edges = \"guard\" (the default with a guard band) or remove guard",
                e.name()
            )));
        }
        (Some(e), _) => e,
    };
    let (mesh, tile) = map.mesh(edges).map_err(|e| bad(e.to_string()))?;
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

/// Stage 4: the tile `[Lx, Ly]` in sample units, as written or set by the first height
/// map; every height map must span it.
fn tile(cx: &Ctx, raw: &RawSample, measured: &[Option<Measured>]) -> Result<[f64; 2], SampleError> {
    let (scale, unit) = (cx.scale, cx.unit);
    let measured_tile = measured.iter().flatten().next().map(|m| m.1);
    let [tx, ty] = match (&raw.sample.tile, measured_tile) {
        (Some(tile), _) => match tile.get_ref()[..] {
            [x, y] => [x, y],
            ref other => {
                return Err(cx.at(
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
            return Err(cx.file(SampleErrorKind::Invalid(
                "[sample] needs tile = [Lx, Ly] (only a heightmap interface sets the tile itself)"
                    .into(),
            )));
        }
    };
    let tile_span = raw.sample.tile.as_ref().map_or(0..0, |t| t.span());
    if !(tx.is_finite() && ty.is_finite() && tx > 0.0 && ty > 0.0) {
        return Err(cx.at(tile_span, SampleErrorKind::BadTile(tx, ty)));
    }
    for (ri, m) in raw.interface.iter().zip(measured) {
        if let (Some((_, t, _)), Some(h)) = (m, &ri.heightmap) {
            let (ex, ey) = (t[0] / scale, t[1] / scale);
            if (ex - tx).abs() > 1e-9 * tx || (ey - ty).abs() > 1e-9 * ty {
                return Err(cx.at(
                    h.span(),
                    SampleErrorKind::Invalid(format!(
                        "height map {} spans [{ex}, {ey}] {unit} (with its edges made periodic), but the tile is [{tx}, {ty}] {unit}: remove tile from [sample] or make it match",
                        h.get_ref()
                    )),
                ));
            }
        }
    }
    Ok([tx, ty])
}

/// Stage 6: the guard band of an open sample (nm): as given, or a tenth of the shorter
/// side; it must leave an interior to launch trees in. `None` for periodic sides.
fn guard(
    cx: &Ctx,
    raw: &RawSample,
    [tx, ty]: [f64; 2],
    open: bool,
) -> Result<Option<f64>, SampleError> {
    let (short, unit) = (tx.min(ty), cx.unit);
    Ok(match (&raw.sample.guard, open) {
        (Some(g), _) => {
            let v = *g.get_ref();
            if !(v.is_finite() && v > 0.0 && v < 0.5 * short) {
                return Err(cx.at(
                    g.span(),
                    SampleErrorKind::Invalid(format!(
                        "guard must leave an interior to launch trees in: 0 < guard < {} {unit} (half the shorter tile side), got {v} {unit}",
                        0.5 * short
                    )),
                ));
            }
            Some(v * cx.scale)
        }
        (None, true) => Some(DEFAULT_GUARD_FRACTION * short * cx.scale),
        (None, false) => None,
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
