//! Gwyddion Simple Field (.gsf) height maps.

use super::{HeightMap, HeightMapError, check_size, metres_per};

/// Reads a Gwyddion Simple Field.
pub fn read_gsf(bytes: &[u8]) -> Result<HeightMap, HeightMapError> {
    const MAGIC: &[u8] = b"Gwyddion Simple Field 1.0\n";
    if !bytes.starts_with(MAGIC) {
        return Err(HeightMapError::from(
            "not a Gwyddion Simple Field (the file must start with \"Gwyddion Simple Field 1.0\")",
        ));
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
        return Err(HeightMapError::from(
            "the GSF header padding is not 1 to 4 NUL bytes to a multiple of 4",
        ));
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
        return Err(HeightMapError::from(format!(
            "GSF data: {nx} x {ny} float32 values need {want} bytes after the header, the file has {}{}",
            data.len(),
            if data.len() < want {
                " (truncated)"
            } else {
                ""
            }
        )));
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
