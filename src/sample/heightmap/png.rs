//! 16-bit or 8-bit greyscale PNG height maps.

use super::{HeightMapError, check_size};

/// A 16-bit greyscale PNG: (nx, ny, values 0..65535).
pub(super) fn read_png(bytes: &[u8]) -> Result<(usize, usize, Vec<f64>), HeightMapError> {
    let mut dec = png::Decoder::new(std::io::Cursor::new(bytes));
    dec.set_transformations(png::Transformations::IDENTITY);
    let mut reader = dec
        .read_info()
        .map_err(|e| format!("not a readable PNG: {e}"))?;
    let info = reader.info();
    let (w, h) = (u64::from(info.width), u64::from(info.height));
    if info.color_type != png::ColorType::Grayscale || info.bit_depth != png::BitDepth::Sixteen {
        return Err(HeightMapError::from(format!(
            "the PNG is {:?} at {:?} bits: a height map must be 16-bit greyscale (8 bits resolve only 256 heights)",
            info.color_type, info.bit_depth
        )));
    }
    let (nx, ny) = check_size(w, h)?;
    let mut buf = vec![0u8; reader.output_buffer_size().ok_or("PNG too large")?];
    let frame = reader
        .next_frame(&mut buf)
        .map_err(|e| format!("PNG data: {e}"))?;
    let data = &buf[..frame.buffer_size()];
    if data.len() != nx * ny * 2 {
        return Err(HeightMapError::from("PNG data: wrong size"));
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
