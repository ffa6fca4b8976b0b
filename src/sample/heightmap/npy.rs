//! NumPy .npy height maps (2-D float or integer arrays, either byte order).

use super::{HeightMapError, MAX_POINTS, check_size};

/// Checks a `.npy` header before the `npyz` parser sees it (NEP 1: magic, version, header
/// length, then a Python dict literal). A plain array's header is one flat dict with one
/// shape tuple; anything nested is refused here, because the literal parser backtracks
/// exponentially on nested brackets (30 braces hung it), and every dimension must be a
/// count within the point limit (a dimension of 10^20 overflowed its product).
fn npy_header_guard(bytes: &[u8]) -> Result<(), HeightMapError> {
    const MAGIC: &[u8] = b"\x93NUMPY";
    if !bytes.starts_with(MAGIC) || bytes.len() < 10 {
        return Err(HeightMapError::from(
            "not a .npy array (no \\x93NUMPY magic)",
        ));
    }
    let (len, at) = match bytes[6] {
        1 => (usize::from(u16::from_le_bytes([bytes[8], bytes[9]])), 10),
        2 | 3 if bytes.len() >= 12 => (
            u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
            12,
        ),
        v => {
            return Err(HeightMapError::from(format!(
                "unknown .npy format version {v}"
            )));
        }
    };
    if len > 4096 {
        return Err(HeightMapError::from(format!(
            "the .npy header is {len} bytes: a plain array's is under 4096"
        )));
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
        return Err(HeightMapError::from(
            "the .npy header is not one flat dict with one shape tuple: only plain numeric arrays are height maps",
        ));
    }
    let open = header.iter().position(|&b| b == b'(').unwrap_or(0);
    let close = header.iter().position(|&b| b == b')').unwrap_or(0);
    if close < open {
        return Err(HeightMapError::from("the .npy header's shape is malformed"));
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
                return Err(HeightMapError::from(format!(
                    "the .npy array's dimension {t} is more than the {MAX_POINTS} points a height map may have"
                )));
            }
        }
    }
    Ok(())
}

/// A 2-D `.npy` array `[rows = y][columns = x]`, C order: (nx, ny, values).
pub(super) fn read_npy(bytes: &[u8]) -> Result<(usize, usize, Vec<f64>), HeightMapError> {
    use npyz::{DType, TypeChar};
    npy_header_guard(bytes)?;
    let npy = npyz::NpyFile::new(bytes).map_err(|e| format!("not a .npy array: {e}"))?;
    let shape = npy.shape().to_vec();
    let [ny, nx] = shape[..] else {
        return Err(HeightMapError::from(format!(
            "the .npy array has shape {shape:?}: a height map is 2-D (rows along y, columns along x)"
        )));
    };
    if npy.order() != npyz::Order::C {
        return Err(HeightMapError::from(
            "the .npy array is in Fortran order: save it in C order",
        ));
    }
    let (nx, ny) = check_size(nx, ny)?;
    let DType::Plain(t) = npy.dtype() else {
        return Err(HeightMapError::from(
            "the .npy array is not of a plain numeric type",
        ));
    };
    // The data as `T`, widened to f64 (exactly, for every type accepted).
    fn widen<T: npyz::Deserialize + Into<f64>>(
        npy: npyz::NpyFile<&[u8]>,
    ) -> Result<Vec<f64>, HeightMapError> {
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
            return Err(HeightMapError::from(format!(
                "the .npy array's type {t} is not supported: use float32, float64, int16, uint16 or int32"
            )));
        }
    };
    if v.len() != nx * ny {
        return Err(HeightMapError::from(format!(
            ".npy data: {} values for shape [{ny}, {nx}] (truncated?)",
            v.len()
        )));
    }
    Ok((nx, ny, v))
}
