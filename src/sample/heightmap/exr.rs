//! OpenEXR height maps (one channel: Z, Y, or the only one).

use super::{HeightMapError, check_size};

/// The first channel of an OpenEXR image: (nx, ny, values).
pub(super) fn read_exr(bytes: &[u8]) -> Result<(usize, usize, Vec<f64>), HeightMapError> {
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
        return Err(HeightMapError::from(
            "the OpenEXR channel's size does not match the image",
        ));
    }
    Ok((nx, ny, v))
}

/// Which OpenEXR channel holds the heights: `Z` (the depth / height convention), else `Y`
/// (a luminance image), else the only channel. Several channels and neither name is
/// ambiguous and refused: an RGBA image would otherwise give whichever channel sorts
/// first (its alpha, a flat surface).
fn exr_height_channel(names: &[String]) -> Result<usize, HeightMapError> {
    for want in ["Z", "Y"] {
        if let Some(i) = names.iter().position(|n| n == want) {
            return Ok(i);
        }
    }
    match names.len() {
        0 => Err(HeightMapError::from("the OpenEXR image has no channel")),
        1 => Ok(0),
        _ => Err(HeightMapError::from(format!(
            "the OpenEXR image has channels {} and none named Z or Y: store the heights in a channel named Z",
            names.join(", ")
        ))),
    }
}
