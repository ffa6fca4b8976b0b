//! ISO 25178-72 X3P height maps (a zip of main.xml and binary point data).

use std::io::Read;

use super::{HeightMap, HeightMapError, check_size};

/// Reads an ISO 25178-72 X3P container.
pub fn read_x3p(bytes: &[u8]) -> Result<HeightMap, HeightMapError> {
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
        return Err(HeightMapError::from(format!(
            "the X3P holds a {} (FeatureType), not an areal surface (SUR): profiles and point clouds cannot be meshed as a height map",
            feature_name(&feature)
        )));
    }
    for axis in ["CX", "CY"] {
        let t = need(&["Record1", "Axes", axis, "AxisType"])?;
        if t != "I" {
            return Err(HeightMapError::from(format!(
                "the X3P's {axis} axis is of type {t:?}: only incremental (I) x and y axes form a height map"
            )));
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
        return Err(HeightMapError::from(format!(
            "the X3P has {sz} layers (SizeZ): a height map has one"
        )));
    }
    let (nx, ny) = check_size(sx, sy)?;
    let n = nx * ny;
    let width = width_of(&z_type)?;
    let mut z: Vec<f64> = if let Some(link) = text(&["Record3", "DataLink", "PointDataLink"]) {
        let data = entry(&link, (n * width) as u64)?;
        if data.len() != n * width {
            return Err(HeightMapError::from(format!(
                "{link}: {nx} x {ny} values of type {z_type} need {} bytes, it has {}{}",
                n * width,
                data.len(),
                if data.len() < n * width {
                    " (truncated)"
                } else {
                    ""
                }
            )));
        }
        decode_points(&data, width, &z_type)
    } else if let Some(list) = find(&["Record3", "DataList"]) {
        inline_points(list, nx, ny)?
    } else {
        return Err(HeightMapError::from(
            "main.xml has neither Record3/DataLink/PointDataLink nor Record3/DataList",
        ));
    };
    // Integer data carry their validity in a bit mask (bit k of byte k/8: point k).
    if matches!(z_type.as_str(), "I" | "L")
        && let Some(link) = text(&["Record3", "DataLink", "ValidPointsLink"])
    {
        let mask = entry(&link, n.div_ceil(8) as u64)?;
        mask_invalid(&mut z, &mask, &link)?;
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

/// What an X3P `FeatureType` other than an areal surface holds, for messages.
fn feature_name(feature: &str) -> String {
    match feature {
        "PRF" => "profile".to_string(),
        "PCL" => "point cloud".to_string(),
        f => format!("'{f}'"),
    }
}

/// Bytes per value of an X3P data type (`CZ/DataType`): I (i16), L (i32), F (f32), D (f64).
fn width_of(z_type: &str) -> Result<usize, HeightMapError> {
    Ok(match z_type {
        "I" => 2,
        "L" => 4,
        "F" => 4,
        "D" => 8,
        t => {
            return Err(HeightMapError::from(format!(
                "unknown X3P data type {t:?} (CZ/DataType must be I, L, F or D)"
            )));
        }
    })
}

/// Binary point data (little-endian) of `width` bytes per value of type `z_type`.
fn decode_points(data: &[u8], width: usize, z_type: &str) -> Vec<f64> {
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
}

/// Inline point data of `main.xml`'s `Record3/DataList`: one Datum per point of the
/// `nx x ny` grid; an empty one is missing (NaN).
fn inline_points(list: roxmltree::Node, nx: usize, ny: usize) -> Result<Vec<f64>, HeightMapError> {
    let n = nx * ny;
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
        return Err(HeightMapError::from(format!(
            "main.xml DataList holds {} values for {nx} x {ny} points",
            v.len()
        )));
    }
    Ok(v)
}

/// Marks the points of integer data that the valid-point mask of `link` clears (bit k of
/// byte k/8: point k) as missing (NaN).
fn mask_invalid(z: &mut [f64], mask: &[u8], link: &str) -> Result<(), HeightMapError> {
    let n = z.len();
    if mask.len() < n.div_ceil(8) {
        return Err(HeightMapError::from(format!(
            "{link}: the valid-point mask needs {} bytes, it has {}",
            n.div_ceil(8),
            mask.len()
        )));
    }
    for (k, v) in z.iter_mut().enumerate() {
        if mask[k / 8] >> (k % 8) & 1 == 0 {
            *v = f64::NAN;
        }
    }
    Ok(())
}
