//! Measured surfaces: height maps from profilometers, confocal microscopes and AFMs, read
//! into a regular grid of heights and meshed as an interface.
//!
//! Formats (chosen by the file's extension):
//! - `.x3p`: ISO 25178-72 / ISO 5436-2 XML 3D surface profile, the openGPS container: a
//!   zip holding `main.xml` (axes, increments and the matrix size, metres) and the point
//!   data (`bindata/data.bin`, little-endian `I` int16, `L` int32, `F` float32 or `D`
//!   float64, x fastest) or an inline `DataList`. Integer data are scaled by the z axis
//!   increment; missing points are NaN (floats) or cleared bits of the optional valid-point
//!   mask (`ValidPointsLink`). Only surfaces (`FeatureType` `SUR`) on incremental x and y
//!   axes are read.
//! - `.gsf`: Gwyddion Simple Field 1.0 (the format Gwyddion exports from every instrument
//!   format it reads): a `Key = Value` text header (`XRes`, `YRes`, `XReal`, `YReal`,
//!   `XYUnits`, `ZUnits`), NUL padding to a multiple of 4 bytes, then `XRes x YRes`
//!   little-endian float32 rows.
//! - `.npy` (2-D, float or integer), `.exr` (the first channel), 16-bit grey `.png` and
//!   16-bit or float grey `.tif`/`.tiff`: these carry no physical scale, so the sample
//!   states `pixel_size` (sample units) and `height_scale` (sample units per stored value).
//!
//! Rows run along +x, successive rows along +y (the first row at y = 0). Heights are
//! relative: their zero is the file's.
//!
//! **Edges.** A measured patch is not periodic, and the tracer wraps rays around the
//! tile. `edges = "mirror"` (the default) reflects the patch across its right and top edges
//! into a 2x2 tile that is periodic and continuous (no cliff at the seams; slopes flip
//! sign there, as they would at a mirror, which keeps the slope distribution of the
//! patch). `edges = "periodic"` takes the patch as one period (for maps of periodic
//! structures, or ones already made periodic); the wrap then joins the last row to the
//! first. `edges = "guard"` keeps the patch as it is and opens the sample's sides
//! (`[sample] guard`, a band 10 % of the shorter side wide unless given): trees launch only
//! in the interior, at least the band's width from every side, and light that reaches a
//! side leaves the sample as escaped power, reported with the results (no seams, at the
//! cost of the band's area and of what escapes).
//!
//! **Missing points** (NaN, common in AFM and optical scans where the signal dropped
//! out): refused by default, naming how many and where the first is; `missing = "fill"`
//! fills each from the mean of its known 4-neighbours, ring by ring inwards from the known
//! points (a deterministic, smooth fill), and the sample check reports how many were
//! filled.

use std::io::Read;
use std::path::Path;

use super::mesh::Mesh;
use crate::sample::generate::MAX_GENERATED_TRIANGLES;
use glam::DVec3;

/// The most points a height map may have (a 8192 x 8192 scan; mirrored and meshed it is
/// 2^29 triangles, beyond the mesh limit, so the mesh limit binds first for large maps).
pub const MAX_POINTS: u64 = 1 << 26;

/// A regular grid of heights, nm.
#[derive(Clone, Debug, PartialEq)]
pub struct HeightMap {
    /// Points along x and along y.
    pub nx: usize,
    pub ny: usize,
    /// Point spacing along x and y, nm.
    pub dx_nm: f64,
    pub dy_nm: f64,
    /// Heights, nm, row-major (x fastest); NaN where the point is missing.
    pub z_nm: Vec<f64>,
}

/// How the patch's edges are treated.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Edges {
    /// Reflected into a periodic, continuous 2x2 tile.
    #[default]
    Mirror,
    /// The patch is one period.
    Periodic,
    /// The patch as it is, in a sample with open sides and a guard band (`[sample]
    /// guard`).
    Guard,
}

impl Edges {
    /// The key's value.
    pub fn name(self) -> &'static str {
        match self {
            Edges::Mirror => "mirror",
            Edges::Periodic => "periodic",
            Edges::Guard => "guard",
        }
    }
}

/// What to do with missing points.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Missing {
    #[default]
    Refuse,
    Fill,
}

/// The physical scale of a format that has none: pixel spacing along x and y and height
/// per stored value, nm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scale {
    pub dx_nm: f64,
    pub dy_nm: f64,
    pub dz_nm: f64,
}

/// The formats, by extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    X3p,
    Gsf,
    Npy,
    Exr,
    Png,
    Tiff,
}

impl Format {
    pub fn of(path: &Path) -> Option<Format> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        Some(match ext.as_str() {
            "x3p" => Format::X3p,
            "gsf" => Format::Gsf,
            "npy" => Format::Npy,
            "exr" => Format::Exr,
            "png" => Format::Png,
            "tif" | "tiff" => Format::Tiff,
            _ => return None,
        })
    }

    /// Whether the file states its own pixel size and height unit.
    pub fn is_calibrated(self) -> bool {
        matches!(self, Format::X3p | Format::Gsf)
    }
}

/// Reads a height map. `scale` is required for the formats that carry no physical scale
/// and refused for those that do. Errors are messages for the sample's error (the caller
/// names the file).
pub fn read(path: &Path, scale: Option<Scale>) -> Result<HeightMap, String> {
    let format = Format::of(path).ok_or_else(|| {
        "unknown height-map format: use .x3p, .gsf, .npy, .exr, .png or .tif".to_string()
    })?;
    match (format.is_calibrated(), scale) {
        (true, Some(_)) => {
            return Err(
                "this format states its own pixel size and height unit: remove pixel_size and height_scale"
                    .into(),
            );
        }
        (false, None) => {
            return Err(
                "this format has no physical scale: give pixel_size (sample units, one number or [x, y]) and height_scale (sample units per stored value)"
                    .into(),
            );
        }
        _ => {}
    }
    let bytes = crate::io::read_input(path, 1 << 34).map_err(|e| e.to_string())?;
    from_bytes(format, &bytes, scale)
}

/// A height map from a file's bytes in `format`, with `scale` for the formats that carry
/// none (see [`read`], which checks the pairing first; here a missing scale is an error).
pub fn from_bytes(format: Format, bytes: &[u8], scale: Option<Scale>) -> Result<HeightMap, String> {
    let map = match format {
        Format::X3p => read_x3p(bytes)?,
        Format::Gsf => read_gsf(bytes)?,
        Format::Npy | Format::Exr | Format::Png | Format::Tiff => {
            let s = scale
                .ok_or("this format has no physical scale: give pixel_size and height_scale")?;
            let (nx, ny, values) = match format {
                Format::Npy => read_npy(bytes)?,
                Format::Exr => read_exr(bytes)?,
                Format::Png => read_png(bytes)?,
                _ => read_tiff(bytes)?,
            };
            HeightMap {
                nx,
                ny,
                dx_nm: s.dx_nm,
                dy_nm: s.dy_nm,
                z_nm: values.into_iter().map(|v| v * s.dz_nm).collect(),
            }
        }
    };
    map.validate()?;
    Ok(map)
}

/// Checks the size and the point count against the data before anything is allocated.
fn check_size(nx: u64, ny: u64) -> Result<(usize, usize), String> {
    if nx < 2 || ny < 2 {
        return Err(format!(
            "a height map needs at least 2 x 2 points, this one has {nx} x {ny}"
        ));
    }
    match nx.checked_mul(ny) {
        Some(n) if n <= MAX_POINTS => Ok((nx as usize, ny as usize)),
        _ => Err(format!(
            "{nx} x {ny} points is more than the {MAX_POINTS} a height map may have; crop or resample the scan"
        )),
    }
}

impl HeightMap {
    fn validate(&self) -> Result<(), String> {
        check_size(self.nx as u64, self.ny as u64)?;
        if self.z_nm.len() != self.nx * self.ny {
            return Err(format!(
                "{} heights for {} x {} points",
                self.z_nm.len(),
                self.nx,
                self.ny
            ));
        }
        for (what, d) in [("x", self.dx_nm), ("y", self.dy_nm)] {
            if !(d.is_finite() && d > 0.0) {
                return Err(format!(
                    "the point spacing along {what} must be positive and finite, got {d} nm"
                ));
            }
        }
        let extent = (self.nx as f64 * self.dx_nm).max(self.ny as f64 * self.dy_nm);
        if extent > super::MAX_LENGTH_NM {
            return Err(format!(
                "the scan is {extent:e} nm across, beyond the {:e} nm limit",
                super::MAX_LENGTH_NM
            ));
        }
        if let Some(z) = self.z_nm.iter().find(|z| z.is_infinite()) {
            return Err(format!("a height is {z}: not a measurement"));
        }
        if let Some(z) = self.z_nm.iter().find(|z| z.abs() > super::MAX_LENGTH_NM) {
            return Err(format!(
                "a height of {z:e} nm is beyond the {:e} nm limit (is height_scale right?)",
                super::MAX_LENGTH_NM
            ));
        }
        Ok(())
    }

    /// The number of missing (NaN) points.
    pub fn missing(&self) -> usize {
        self.z_nm.iter().filter(|z| z.is_nan()).count()
    }

    /// Refuses missing points (naming how many and the first), or fills them.
    pub fn resolve_missing(&mut self, how: Missing) -> Result<usize, String> {
        let n = self.missing();
        if n == 0 {
            return Ok(0);
        }
        if how == Missing::Refuse || n == self.z_nm.len() {
            let first = self.z_nm.iter().position(|z| z.is_nan()).unwrap_or(0);
            return Err(format!(
                "{n} of {} points are missing (NaN; the first at column {}, row {}){}",
                self.z_nm.len(),
                first % self.nx,
                first / self.nx,
                if n == self.z_nm.len() {
                    ": no height is known"
                } else {
                    ": set missing = \"fill\" to fill them from their neighbours, or fill them in the instrument's software"
                }
            ));
        }
        // Ring by ring: every missing point with known 4-neighbours takes their mean,
        // all of a ring from the previous ring's values (so the fill does not depend on
        // the scan order). Each ring's candidates are the missing neighbours of the ring
        // before, so the fill costs O(points), not O(points x rings) (a single known point
        // in a 2048^2 scan took 154 s).
        let (nx, ny) = (self.nx, self.ny);
        let neighbours = |i: usize| {
            let (x, y) = (i % nx, i / nx);
            [
                (x > 0, i.wrapping_sub(1)),
                (x + 1 < nx, i + 1),
                (y > 0, i.wrapping_sub(nx)),
                (y + 1 < ny, i + nx),
            ]
        };
        let mut queued = vec![false; self.z_nm.len()];
        let mut next: Vec<usize> = Vec::new();
        for (i, q) in queued.iter_mut().enumerate() {
            if self.z_nm[i].is_nan()
                && neighbours(i)
                    .iter()
                    .any(|&(ok, j)| ok && !self.z_nm[j].is_nan())
            {
                *q = true;
                next.push(i);
            }
        }
        let mut ring: Vec<(usize, f64)> = Vec::new();
        while !next.is_empty() {
            ring.clear();
            for &i in &next {
                let mut sum = 0.0;
                let mut count = 0;
                for (ok, j) in neighbours(i) {
                    if ok && !self.z_nm[j].is_nan() {
                        sum += self.z_nm[j];
                        count += 1;
                    }
                }
                ring.push((i, sum / f64::from(count)));
            }
            for &(i, v) in &ring {
                self.z_nm[i] = v;
            }
            next.clear();
            for &(i, _) in &ring {
                for (ok, j) in neighbours(i) {
                    if ok && self.z_nm[j].is_nan() && !queued[j] {
                        queued[j] = true;
                        next.push(j);
                    }
                }
            }
        }
        Ok(n)
    }

    /// The interface mesh (normals up, +z) and the tile it spans, nm.
    pub fn mesh(&self, edges: Edges) -> Result<(Mesh, [f64; 2]), String> {
        debug_assert_eq!(self.missing(), 0, "resolve missing points first");
        let (nx, ny) = (self.nx, self.ny);
        // Cells of the periodic grid, and the height at a grid point (any integers).
        let (cx, cy) = match edges {
            Edges::Mirror => (2 * (nx - 1), 2 * (ny - 1)),
            Edges::Periodic => (nx, ny),
            Edges::Guard => (nx - 1, ny - 1),
        };
        let triangles = 2 * cx as u64 * cy as u64;
        if triangles > MAX_GENERATED_TRIANGLES {
            return Err(format!(
                "meshed with edges = \"{}\", this map makes {triangles} triangles, more than {MAX_GENERATED_TRIANGLES}; crop or resample the scan",
                edges.name()
            ));
        }
        let fold = |i: usize, n: usize, c: usize| match edges {
            Edges::Periodic => i % n,
            Edges::Guard => i,
            // Mirror: 0, 1, ..., n-1, n-2, ..., 1, then again.
            Edges::Mirror => {
                let k = i % c;
                if k < n { k } else { c - k }
            }
        };
        let mut positions_nm = Vec::with_capacity((cx + 1) * (cy + 1));
        for j in 0..=cy {
            for i in 0..=cx {
                let z = self.z_nm[fold(j, ny, cy) * nx + fold(i, nx, cx)];
                positions_nm.push(DVec3::new(i as f64 * self.dx_nm, j as f64 * self.dy_nm, z));
            }
        }
        let tile = [cx as f64 * self.dx_nm, cy as f64 * self.dy_nm];
        Ok((
            super::generate::height::height_field_from_grid([cx, cy], positions_nm),
            tile,
        ))
    }
}

/// Metres per unit of a length unit as Gwyddion and X3P write them.
fn metres_per(unit: &str) -> Option<f64> {
    Some(match unit.trim() {
        "m" => 1.0,
        "mm" => 1e-3,
        "um" | "µm" | "μm" => 1e-6,
        "nm" => 1e-9,
        "pm" => 1e-12,
        "A" | "Å" => 1e-10,
        _ => return None,
    })
}

/// Reads a Gwyddion Simple Field.
pub fn read_gsf(bytes: &[u8]) -> Result<HeightMap, String> {
    const MAGIC: &[u8] = b"Gwyddion Simple Field 1.0\n";
    if !bytes.starts_with(MAGIC) {
        return Err(
            "not a Gwyddion Simple Field (the file must start with \"Gwyddion Simple Field 1.0\")"
                .into(),
        );
    }
    let end = bytes
        .iter()
        .position(|&b| b == 0)
        .ok_or("the GSF header is not terminated by NUL padding (truncated file?)")?;
    let header = std::str::from_utf8(&bytes[MAGIC.len()..end]).map_err(|_| {
        "the GSF header is not UTF-8 text ending in 1 to 4 NUL bytes of padding: a file written without the padding runs into its binary data"
    })?;
    // The header with its padding is a multiple of 4 bytes, padded by 1 to 4 NULs.
    let data_at = (end / 4 + 1) * 4;
    if bytes.len() < data_at || bytes[end..data_at].iter().any(|&b| b != 0) {
        return Err("the GSF header padding is not 1 to 4 NUL bytes to a multiple of 4".into());
    }
    let mut keys = std::collections::HashMap::new();
    for (k, line) in header.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let (key, value) = line.split_once('=').ok_or_else(|| {
            format!(
                "GSF header line {}: expected \"Key = Value\", got {line:?}",
                k + 2
            )
        })?;
        keys.insert(key.trim().to_string(), value.trim().to_string());
    }
    let int = |k: &str| -> Result<u64, String> {
        let v = keys
            .get(k)
            .ok_or_else(|| format!("the GSF header has no {k}"))?;
        v.parse()
            .map_err(|_| format!("GSF {k} = {v:?} is not a positive integer"))
    };
    let real = |k: &str, default: f64| -> Result<f64, String> {
        match keys.get(k) {
            None => Ok(default),
            Some(v) => v
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite() && *x > 0.0)
                .ok_or_else(|| format!("GSF {k} = {v:?} is not a positive number")),
        }
    };
    let (nx, ny) = check_size(int("XRes")?, int("YRes")?)?;
    let unit = |k: &str| -> Result<f64, String> {
        match keys.get(k) {
            None => Ok(1.0),
            Some(u) => metres_per(u)
                .ok_or_else(|| format!("GSF {k} = {u:?} is not a length unit (m, mm, um, nm)")),
        }
    };
    let (xy, zu) = (unit("XYUnits")? * 1e9, unit("ZUnits")? * 1e9);
    let want = nx * ny * 4;
    let data = &bytes[data_at..];
    if data.len() != want {
        return Err(format!(
            "GSF data: {nx} x {ny} float32 values need {want} bytes after the header, the file has {}{}",
            data.len(),
            if data.len() < want {
                " (truncated)"
            } else {
                ""
            }
        ));
    }
    // XReal is the width of the field: nx pixels of XReal / XRes each.
    let (xreal, yreal) = (real("XReal", 1.0)?, real("YReal", 1.0)?);
    Ok(HeightMap {
        nx,
        ny,
        dx_nm: xreal / nx as f64 * xy,
        dy_nm: yreal / ny as f64 * xy,
        z_nm: data
            .chunks_exact(4)
            .map(|c| f64::from(f32::from_le_bytes([c[0], c[1], c[2], c[3]])) * zu)
            .collect(),
    })
}

/// Reads an ISO 25178-72 X3P container.
pub fn read_x3p(bytes: &[u8]) -> Result<HeightMap, String> {
    let mut zip = zip::ZipArchive::new(std::io::Cursor::new(bytes))
        .map_err(|e| format!("not an X3P file (an X3P is a zip archive): {e}"))?;
    let mut entry = |name: &str, limit: u64| -> Result<Vec<u8>, String> {
        let f = zip
            .by_name(name)
            .map_err(|_| format!("the X3P archive has no {name}"))?;
        if f.size() > limit {
            return Err(format!("{name} is {} bytes, more than expected", f.size()));
        }
        let mut out = Vec::with_capacity(f.size() as usize);
        f.take(limit + 1)
            .read_to_end(&mut out)
            .map_err(|e| format!("reading {name} from the X3P archive: {e}"))?;
        Ok(out)
    };
    let xml = entry("main.xml", 64 << 20)?;
    let xml = std::str::from_utf8(&xml).map_err(|_| "main.xml is not UTF-8")?;
    let doc = roxmltree::Document::parse(xml).map_err(|e| format!("main.xml: {e}"))?;
    // Elements by path of local names below the root, namespaces ignored.
    let find = |path: &[&str]| -> Option<roxmltree::Node> {
        let mut node = doc.root_element();
        for name in path {
            node = node
                .children()
                .find(|c| c.is_element() && c.tag_name().name() == *name)?;
        }
        Some(node)
    };
    let text = |path: &[&str]| -> Option<String> {
        find(path)
            .and_then(|n| n.text())
            .map(|t| t.trim().to_string())
    };
    let need = |path: &[&str]| -> Result<String, String> {
        text(path).ok_or_else(|| format!("main.xml has no {}", path.join("/")))
    };
    let number = |path: &[&str]| -> Result<f64, String> {
        let t = need(path)?;
        t.parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| {
                let t: String = t.chars().take(40).collect();
                format!("main.xml {} = {t:?} is not a number", path.join("/"))
            })
    };
    let feature = need(&["Record1", "FeatureType"])?;
    if feature != "SUR" {
        return Err(format!(
            "the X3P holds a {} (FeatureType), not an areal surface (SUR): profiles and point clouds cannot be meshed as a height map",
            match feature.as_str() {
                "PRF" => "profile".to_string(),
                "PCL" => "point cloud".to_string(),
                f => format!("'{f}'"),
            }
        ));
    }
    for axis in ["CX", "CY"] {
        let t = need(&["Record1", "Axes", axis, "AxisType"])?;
        if t != "I" {
            return Err(format!(
                "the X3P's {axis} axis is of type {t:?}: only incremental (I) x and y axes form a height map"
            ));
        }
    }
    // An increment is a step in metres: positive and a normal number (0 flattened the
    // surface; a denormal one gave a kilobyte-long error further on).
    let increment = |axis: &str| -> Result<f64, String> {
        let path = ["Record1", "Axes", axis, "Increment"];
        let v = number(&path)?;
        if v > 0.0 && v.is_normal() {
            Ok(v)
        } else {
            let t: String = need(&path)?.chars().take(40).collect();
            Err(format!(
                "main.xml {} = {t} must be a positive step in metres",
                path.join("/")
            ))
        }
    };
    let dx = increment("CX")?;
    let dy = increment("CY")?;
    let z_type = need(&["Record1", "Axes", "CZ", "DataType"])?;
    let z_inc = match text(&["Record1", "Axes", "CZ", "Increment"]) {
        Some(_) => increment("CZ")?,
        None => 1.0,
    };
    let z_off = match text(&["Record1", "Axes", "CZ", "Offset"]) {
        Some(_) => number(&["Record1", "Axes", "CZ", "Offset"])?,
        None => 0.0,
    };
    let size = |k: &str| -> Result<u64, String> {
        let t = need(&["Record3", "MatrixDimension", k])?;
        t.parse()
            .map_err(|_| format!("main.xml Record3/MatrixDimension/{k} = {t:?} is not a count"))
    };
    let (sx, sy, sz) = (size("SizeX")?, size("SizeY")?, size("SizeZ")?);
    if sz != 1 {
        return Err(format!(
            "the X3P has {sz} layers (SizeZ): a height map has one"
        ));
    }
    let (nx, ny) = check_size(sx, sy)?;
    let n = nx * ny;
    let width = match z_type.as_str() {
        "I" => 2,
        "L" => 4,
        "F" => 4,
        "D" => 8,
        t => {
            return Err(format!(
                "unknown X3P data type {t:?} (CZ/DataType must be I, L, F or D)"
            ));
        }
    };
    let mut z: Vec<f64> = if let Some(link) = text(&["Record3", "DataLink", "PointDataLink"]) {
        let data = entry(&link, (n * width) as u64)?;
        if data.len() != n * width {
            return Err(format!(
                "{link}: {nx} x {ny} values of type {z_type} need {} bytes, it has {}{}",
                n * width,
                data.len(),
                if data.len() < n * width {
                    " (truncated)"
                } else {
                    ""
                }
            ));
        }
        let c = data.chunks_exact(width);
        match width {
            2 => c
                .map(|b| f64::from(i16::from_le_bytes([b[0], b[1]])))
                .collect(),
            8 => c
                .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
                .collect(),
            _ if z_type == "L" => c
                .map(|b| f64::from(i32::from_le_bytes(b.try_into().expect("4 bytes"))))
                .collect(),
            _ => c
                .map(|b| f64::from(f32::from_le_bytes(b.try_into().expect("4 bytes"))))
                .collect(),
        }
    } else if let Some(list) = find(&["Record3", "DataList"]) {
        // Inline data: one Datum per point; an empty one is missing.
        let mut v = Vec::with_capacity(n);
        for d in list.children().filter(|c| c.is_element()) {
            let t = d.text().unwrap_or("").trim();
            v.push(if t.is_empty() {
                f64::NAN
            } else {
                t.parse::<f64>().map_err(|_| {
                    format!(
                        "main.xml DataList: datum {} = {t:?} is not a number",
                        v.len() + 1
                    )
                })?
            });
            if v.len() > n {
                break;
            }
        }
        if v.len() != n {
            return Err(format!(
                "main.xml DataList holds {} values for {nx} x {ny} points",
                v.len()
            ));
        }
        v
    } else {
        return Err(
            "main.xml has neither Record3/DataLink/PointDataLink nor Record3/DataList".into(),
        );
    };
    // Integer data carry their validity in a bit mask (bit k of byte k/8: point k).
    if matches!(z_type.as_str(), "I" | "L")
        && let Some(link) = text(&["Record3", "DataLink", "ValidPointsLink"])
    {
        let mask = entry(&link, n.div_ceil(8) as u64)?;
        if mask.len() < n.div_ceil(8) {
            return Err(format!(
                "{link}: the valid-point mask needs {} bytes, it has {}",
                n.div_ceil(8),
                mask.len()
            ));
        }
        for (k, v) in z.iter_mut().enumerate() {
            if mask[k / 8] >> (k % 8) & 1 == 0 {
                *v = f64::NAN;
            }
        }
    }
    let scale = if matches!(z_type.as_str(), "I" | "L") {
        z_inc
    } else {
        1.0
    };
    for v in &mut z {
        *v = (*v * scale + z_off) * 1e9;
    }
    Ok(HeightMap {
        nx,
        ny,
        dx_nm: dx * 1e9,
        dy_nm: dy * 1e9,
        z_nm: z,
    })
}

/// Checks a `.npy` header before the `npyz` parser sees it (NEP 1: magic, version, header
/// length, then a Python dict literal). A plain array's header is one flat dict with one
/// shape tuple; anything nested is refused here, because the literal parser backtracks
/// exponentially on nested brackets (30 braces hung it), and every dimension must be a
/// count within the point limit (a dimension of 10^20 overflowed its product).
fn npy_header_guard(bytes: &[u8]) -> Result<(), String> {
    const MAGIC: &[u8] = b"\x93NUMPY";
    if !bytes.starts_with(MAGIC) || bytes.len() < 10 {
        return Err("not a .npy array (no \\x93NUMPY magic)".into());
    }
    let (len, at) = match bytes[6] {
        1 => (usize::from(u16::from_le_bytes([bytes[8], bytes[9]])), 10),
        2 | 3 if bytes.len() >= 12 => (
            u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
            12,
        ),
        v => return Err(format!("unknown .npy format version {v}")),
    };
    if len > 4096 {
        return Err(format!(
            "the .npy header is {len} bytes: a plain array's is under 4096"
        ));
    }
    let header = bytes
        .get(at..at + len)
        .ok_or("the .npy header is cut (truncated file?)")?;
    let count = |c: u8| header.iter().filter(|&&b| b == c).count();
    if count(b'{') != 1
        || count(b'}') != 1
        || count(b'(') != 1
        || count(b')') != 1
        || count(b'[') != 0
    {
        return Err(
            "the .npy header is not one flat dict with one shape tuple: only plain numeric arrays are height maps"
                .into(),
        );
    }
    let open = header.iter().position(|&b| b == b'(').unwrap_or(0);
    let close = header.iter().position(|&b| b == b')').unwrap_or(0);
    if close < open {
        return Err("the .npy header's shape is malformed".into());
    }
    for dim in header[open + 1..close].split(|&b| b == b',') {
        let t = std::str::from_utf8(dim).unwrap_or("?").trim();
        if t.is_empty() {
            continue;
        }
        match t.parse::<u64>() {
            Ok(n) if n <= MAX_POINTS => {}
            _ => {
                let t: String = t.chars().take(24).collect();
                return Err(format!(
                    "the .npy array's dimension {t} is more than the {MAX_POINTS} points a height map may have"
                ));
            }
        }
    }
    Ok(())
}

/// A 2-D `.npy` array `[rows = y][columns = x]`, C order: (nx, ny, values).
fn read_npy(bytes: &[u8]) -> Result<(usize, usize, Vec<f64>), String> {
    use npyz::{DType, TypeChar};
    npy_header_guard(bytes)?;
    let npy = npyz::NpyFile::new(bytes).map_err(|e| format!("not a .npy array: {e}"))?;
    let shape = npy.shape().to_vec();
    let [ny, nx] = shape[..] else {
        return Err(format!(
            "the .npy array has shape {shape:?}: a height map is 2-D (rows along y, columns along x)"
        ));
    };
    if npy.order() != npyz::Order::C {
        return Err("the .npy array is in Fortran order: save it in C order".into());
    }
    let (nx, ny) = check_size(nx, ny)?;
    let DType::Plain(t) = npy.dtype() else {
        return Err("the .npy array is not of a plain numeric type".into());
    };
    // The data as `T`, widened to f64 (exactly, for every type accepted).
    fn widen<T: npyz::Deserialize + Into<f64>>(
        npy: npyz::NpyFile<&[u8]>,
    ) -> Result<Vec<f64>, String> {
        let v = npy.into_vec::<T>().map_err(|e| format!(".npy data: {e}"))?;
        Ok(v.into_iter().map(Into::into).collect())
    }
    let v = match (t.type_char(), t.size_field()) {
        (TypeChar::Float, 8) => widen::<f64>(npy)?,
        (TypeChar::Float, 4) => widen::<f32>(npy)?,
        (TypeChar::Int, 2) => widen::<i16>(npy)?,
        (TypeChar::Uint, 2) => widen::<u16>(npy)?,
        (TypeChar::Int, 4) => widen::<i32>(npy)?,
        _ => {
            return Err(format!(
                "the .npy array's type {t} is not supported: use float32, float64, int16, uint16 or int32"
            ));
        }
    };
    if v.len() != nx * ny {
        return Err(format!(
            ".npy data: {} values for shape [{ny}, {nx}] (truncated?)",
            v.len()
        ));
    }
    Ok((nx, ny, v))
}

/// The first channel of an OpenEXR image: (nx, ny, values).
fn read_exr(bytes: &[u8]) -> Result<(usize, usize, Vec<f64>), String> {
    use exr::prelude::*;
    // The header first: a 300-byte file may declare a data window of 10^10 pixels, which
    // the decoder would allocate before any check of ours.
    let meta = exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(bytes), false)
        .map_err(|e| format!("not a readable OpenEXR image: {e}"))?;
    for h in &meta.headers {
        check_size(h.layer_size.width() as u64, h.layer_size.height() as u64)?;
    }
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_buffered(std::io::Cursor::new(bytes))
        .map_err(|e| format!("not a readable OpenEXR image: {e}"))?;
    let layer = &image.layer_data;
    let size = layer.size;
    let (nx, ny) = check_size(size.width() as u64, size.height() as u64)?;
    let list = &layer.channel_data.list;
    let names: Vec<String> = list.iter().map(|c| c.name.to_string()).collect();
    let channel = exr_height_channel(&names)?;
    let v: Vec<f64> = list[channel]
        .sample_data
        .values_as_f32()
        .map(f64::from)
        .collect();
    if v.len() != nx * ny {
        return Err("the OpenEXR channel's size does not match the image".into());
    }
    Ok((nx, ny, v))
}

/// Which OpenEXR channel holds the heights: `Z` (the depth / height convention), else `Y`
/// (a luminance image), else the only channel. Several channels and neither name is
/// ambiguous and refused: an RGBA image would otherwise give whichever channel sorts
/// first (its alpha, a flat surface).
fn exr_height_channel(names: &[String]) -> Result<usize, String> {
    for want in ["Z", "Y"] {
        if let Some(i) = names.iter().position(|n| n == want) {
            return Ok(i);
        }
    }
    match names.len() {
        0 => Err("the OpenEXR image has no channel".into()),
        1 => Ok(0),
        _ => Err(format!(
            "the OpenEXR image has channels {} and none named Z or Y: store the heights in a channel named Z",
            names.join(", ")
        )),
    }
}

/// A 16-bit greyscale PNG: (nx, ny, values 0..65535).
fn read_png(bytes: &[u8]) -> Result<(usize, usize, Vec<f64>), String> {
    let mut dec = png::Decoder::new(std::io::Cursor::new(bytes));
    dec.set_transformations(png::Transformations::IDENTITY);
    let mut reader = dec
        .read_info()
        .map_err(|e| format!("not a readable PNG: {e}"))?;
    let info = reader.info();
    let (w, h) = (u64::from(info.width), u64::from(info.height));
    if info.color_type != png::ColorType::Grayscale || info.bit_depth != png::BitDepth::Sixteen {
        return Err(format!(
            "the PNG is {:?} at {:?} bits: a height map must be 16-bit greyscale (8 bits resolve only 256 heights)",
            info.color_type, info.bit_depth
        ));
    }
    let (nx, ny) = check_size(w, h)?;
    let mut buf = vec![0u8; reader.output_buffer_size().ok_or("PNG too large")?];
    let frame = reader
        .next_frame(&mut buf)
        .map_err(|e| format!("PNG data: {e}"))?;
    let data = &buf[..frame.buffer_size()];
    if data.len() != nx * ny * 2 {
        return Err("PNG data: wrong size".into());
    }
    // PNG stores 16-bit samples big-endian.
    Ok((
        nx,
        ny,
        data.chunks_exact(2)
            .map(|c| f64::from(u16::from_be_bytes([c[0], c[1]])))
            .collect(),
    ))
}

/// A greyscale TIFF of 16-bit integers or 32-bit floats: (nx, ny, values).
fn read_tiff(bytes: &[u8]) -> Result<(usize, usize, Vec<f64>), String> {
    use tiff::decoder::{Decoder, DecodingResult};
    let mut dec = Decoder::new(std::io::Cursor::new(bytes))
        .map_err(|e| format!("not a readable TIFF: {e}"))?;
    let (w, h) = dec.dimensions().map_err(|e| format!("TIFF header: {e}"))?;
    let colour = dec.colortype().map_err(|e| format!("TIFF header: {e}"))?;
    let (nx, ny) = check_size(u64::from(w), u64::from(h))?;
    let v: Vec<f64> = match (
        colour,
        dec.read_image().map_err(|e| format!("TIFF data: {e}"))?,
    ) {
        (tiff::ColorType::Gray(16), DecodingResult::U16(v)) => {
            v.into_iter().map(f64::from).collect()
        }
        // Signed 16-bit heights (SampleFormat 2): counts either side of zero.
        (tiff::ColorType::Gray(16), DecodingResult::I16(v)) => {
            v.into_iter().map(f64::from).collect()
        }
        (tiff::ColorType::Gray(32), DecodingResult::F32(v)) => {
            v.into_iter().map(f64::from).collect()
        }
        (c, data) => {
            let samples = match data {
                DecodingResult::U8(_) => "unsigned 8-bit",
                DecodingResult::U16(_) => "unsigned 16-bit",
                DecodingResult::U32(_) => "unsigned 32-bit",
                DecodingResult::U64(_) => "unsigned 64-bit",
                DecodingResult::I8(_) => "signed 8-bit",
                DecodingResult::I16(_) => "signed 16-bit",
                DecodingResult::I32(_) => "signed 32-bit",
                DecodingResult::I64(_) => "signed 64-bit",
                DecodingResult::F32(_) => "float32",
                DecodingResult::F64(_) => "float64",
                _ => "other",
            };
            return Err(format!(
                "the TIFF holds {samples} samples as {c:?}: a height map must be one channel of 16-bit integers (signed or not) or float32"
            ));
        }
    };
    if v.len() != nx * ny {
        return Err("TIFF data: wrong size".into());
    }
    Ok((nx, ny, v))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The fill as first written, scanning every missing point each ring: the brute-force
    /// reference for the frontier version.
    fn fill_by_rescan(z: &mut [f64], nx: usize, ny: usize) {
        let mut todo: Vec<usize> = (0..z.len()).filter(|&i| z[i].is_nan()).collect();
        while !todo.is_empty() {
            let mut ring = Vec::new();
            for &i in &todo {
                let (x, y) = (i % nx, i / nx);
                let (mut sum, mut count) = (0.0, 0);
                for (ok, j) in [
                    (x > 0, i.wrapping_sub(1)),
                    (x + 1 < nx, i + 1),
                    (y > 0, i.wrapping_sub(nx)),
                    (y + 1 < ny, i + nx),
                ] {
                    if ok && !z[j].is_nan() {
                        sum += z[j];
                        count += 1;
                    }
                }
                if count > 0 {
                    ring.push((i, sum / f64::from(count)));
                }
            }
            for &(i, v) in &ring {
                z[i] = v;
            }
            todo.retain(|&i| z[i].is_nan());
        }
    }

    /// Issue 30: the ring-by-ring fill gives bit for bit what rescanning gives, on maps with
    /// random holes, and a 2048^2 map with one known point fills in linear time (it took
    /// 154 s; every point then equals the known height exactly).
    #[test]
    fn the_frontier_fill_equals_the_rescan_and_scales_linearly() {
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut rnd = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        for (nx, ny, holes) in [(37, 23, 0.3), (64, 64, 0.9), (5, 80, 0.99)] {
            let mut z: Vec<f64> = (0..nx * ny).map(|_| rnd() * 100.0).collect();
            for v in z.iter_mut() {
                if rnd() < holes {
                    *v = f64::NAN;
                }
            }
            z[nx * ny / 2] = 1.0;
            let mut want = z.clone();
            fill_by_rescan(&mut want, nx, ny);
            let mut m = HeightMap {
                nx,
                ny,
                dx_nm: 1.0,
                dy_nm: 1.0,
                z_nm: z,
            };
            m.resolve_missing(Missing::Fill).unwrap();
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&m.z_nm), bits(&want), "{nx} x {ny}, holes {holes}");
        }
        let n = 2048;
        let mut z = vec![f64::NAN; n * n];
        z[n * 700 + 1500] = 3.25;
        let mut m = HeightMap {
            nx: n,
            ny: n,
            dx_nm: 1.0,
            dy_nm: 1.0,
            z_nm: z,
        };
        let t0 = std::time::Instant::now();
        assert_eq!(m.resolve_missing(Missing::Fill).unwrap(), n * n - 1);
        assert!(m.z_nm.iter().all(|&v| v == 3.25));
        assert!(t0.elapsed().as_secs_f64() < 20.0, "{:?}", t0.elapsed());
    }
}
