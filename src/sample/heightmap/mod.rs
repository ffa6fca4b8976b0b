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

use std::path::Path;

use exr::read_exr;
use npy::read_npy;
use png::read_png;
use tiff::read_tiff;

use super::mesh::Mesh;
use crate::sample::generate::MAX_GENERATED_TRIANGLES;
use glam::DVec3;

mod exr;
mod gsf;
mod npy;
mod png;
mod tiff;
mod x3p;

pub use gsf::read_gsf;
pub use x3p::read_x3p;

/// What stops a height map from becoming a surface. The messages are the sample's errors
/// (the caller names the file).
#[derive(Debug, thiserror::Error)]
pub enum HeightMapError {
    /// The file could not be read.
    #[error("{0}")]
    Io(#[from] std::io::Error),
    /// The file is not a valid file of its format, the sample's keys do not fit it, or its
    /// values cannot make a surface (the message says which and where).
    #[error("{0}")]
    Invalid(String),
}

message_error!(HeightMapError, HeightMapError::Invalid);

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
pub fn read(path: &Path, scale: Option<Scale>) -> Result<HeightMap, HeightMapError> {
    let format = Format::of(path).ok_or_else(|| {
        "unknown height-map format: use .x3p, .gsf, .npy, .exr, .png or .tif".to_string()
    })?;
    match (format.is_calibrated(), scale) {
        (true, Some(_)) => {
            return Err(HeightMapError::from(
                "this format states its own pixel size and height unit: remove pixel_size and height_scale",
            ));
        }
        (false, None) => {
            return Err(HeightMapError::from(
                "this format has no physical scale: give pixel_size (sample units, one number or [x, y]) and height_scale (sample units per stored value)",
            ));
        }
        _ => {}
    }
    let bytes = crate::io::read_input(path, 1 << 34).map_err(|e| e.to_string())?;
    from_bytes(format, &bytes, scale)
}

/// A height map from a file's bytes in `format`, with `scale` for the formats that carry
/// none (see [`read`], which checks the pairing first; here a missing scale is an error).
pub fn from_bytes(
    format: Format,
    bytes: &[u8],
    scale: Option<Scale>,
) -> Result<HeightMap, HeightMapError> {
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
pub(super) fn check_size(nx: u64, ny: u64) -> Result<(usize, usize), HeightMapError> {
    if nx < 2 || ny < 2 {
        return Err(HeightMapError::from(format!(
            "a height map needs at least 2 x 2 points, this one has {nx} x {ny}"
        )));
    }
    match nx.checked_mul(ny) {
        Some(n) if n <= MAX_POINTS => Ok((nx as usize, ny as usize)),
        _ => Err(HeightMapError::from(format!(
            "{nx} x {ny} points is more than the {MAX_POINTS} a height map may have; crop or resample the scan"
        ))),
    }
}

impl HeightMap {
    fn validate(&self) -> Result<(), HeightMapError> {
        check_size(self.nx as u64, self.ny as u64)?;
        if self.z_nm.len() != self.nx * self.ny {
            return Err(HeightMapError::from(format!(
                "{} heights for {} x {} points",
                self.z_nm.len(),
                self.nx,
                self.ny
            )));
        }
        for (what, d) in [("x", self.dx_nm), ("y", self.dy_nm)] {
            if !(d.is_finite() && d > 0.0) {
                return Err(HeightMapError::from(format!(
                    "the point spacing along {what} must be positive and finite, got {d} nm"
                )));
            }
        }
        let extent = (self.nx as f64 * self.dx_nm).max(self.ny as f64 * self.dy_nm);
        if extent > super::MAX_LENGTH_NM {
            return Err(HeightMapError::from(format!(
                "the scan is {extent:e} nm across, beyond the {:e} nm limit",
                super::MAX_LENGTH_NM
            )));
        }
        if let Some(z) = self.z_nm.iter().find(|z| z.is_infinite()) {
            return Err(HeightMapError::from(format!(
                "a height is {z}: not a measurement"
            )));
        }
        if let Some(z) = self.z_nm.iter().find(|z| z.abs() > super::MAX_LENGTH_NM) {
            return Err(HeightMapError::from(format!(
                "a height of {z:e} nm is beyond the {:e} nm limit (is height_scale right?)",
                super::MAX_LENGTH_NM
            )));
        }
        Ok(())
    }

    /// The number of missing (NaN) points.
    pub fn missing(&self) -> usize {
        self.z_nm.iter().filter(|z| z.is_nan()).count()
    }

    /// Refuses missing points (naming how many and the first), or fills them.
    pub fn resolve_missing(&mut self, how: Missing) -> Result<usize, HeightMapError> {
        let n = self.missing();
        if n == 0 {
            return Ok(0);
        }
        if how == Missing::Refuse || n == self.z_nm.len() {
            let first = self.z_nm.iter().position(|z| z.is_nan()).unwrap_or(0);
            return Err(HeightMapError::from(format!(
                "{n} of {} points are missing (NaN; the first at column {}, row {}){}",
                self.z_nm.len(),
                first % self.nx,
                first / self.nx,
                if n == self.z_nm.len() {
                    ": no height is known"
                } else {
                    ": set missing = \"fill\" to fill them from their neighbours, or fill them in the instrument's software"
                }
            )));
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
    pub fn mesh(&self, edges: Edges) -> Result<(Mesh, [f64; 2]), HeightMapError> {
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
            return Err(HeightMapError::from(format!(
                "meshed with edges = \"{}\", this map makes {triangles} triangles, more than {MAX_GENERATED_TRIANGLES}; crop or resample the scan",
                edges.name()
            )));
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
pub(super) fn metres_per(unit: &str) -> Option<f64> {
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
