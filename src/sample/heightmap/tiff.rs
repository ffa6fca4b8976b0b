//! TIFF height maps (one greyscale or float channel).

use super::{HeightMapError, check_size};

/// A greyscale TIFF of 16-bit integers or 32-bit floats: (nx, ny, values).
pub(super) fn read_tiff(bytes: &[u8]) -> Result<(usize, usize, Vec<f64>), HeightMapError> {
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
            return Err(HeightMapError::from(format!(
                "the TIFF holds {samples} samples as {c:?}: a height map must be one channel of 16-bit integers (signed or not) or float32"
            )));
        }
    };
    if v.len() != nx * ny {
        return Err(HeightMapError::from("TIFF data: wrong size"));
    }
    Ok((nx, ny, v))
}
