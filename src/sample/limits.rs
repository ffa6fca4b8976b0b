//! The limits every sample meets: lengths within f32 geometry and f64 phase, vertices
//! scaled and checked, and meshed surfaces that f32 can still tell apart.

use super::{Interface, SampleErrorKind};

/// The largest tile side, layer thickness or coordinate a sample may have, nm (10 cm).
///
/// The accelerators hold vertices in f32 (a 24-bit significand): at 1e8 nm neighbouring
/// f32 values are 8 nm apart, already coarser than a thin film. Phases are formed in f64:
/// over 1e8 nm at 380 nm, `k L` is 1.7e6 rad with a rounding error near 4e-10 rad
/// (docs/design.md §1). Microgeometry tiles are micrometres to millimetres.
pub const MAX_LENGTH_NM: f64 = 1e8;

/// The smallest tile side, nm. Rays start 1e-4 nm or more off the surface they leave
/// (`trace::Scene`'s epsilon, above f32's rounding of the vertices), which must be a small
/// fraction of the tile: a flat air/glass interface on a 0.001 nm tile reflected 0.0363
/// for Fresnel's 0.0415 (issue 47). A side of 1 nm keeps it at 1e-4 of the tile, and no
/// microgeometry (nor any optics of matter) is periodic on a shorter scale than an atom's.
pub const MIN_TILE_NM: f64 = 1.0;

/// Why a vertex cannot be scaled to nanometres.
pub(crate) enum VertexFault {
    /// Not finite after scaling (the coordinate, nm).
    NonFinite(f64),
    /// Beyond [`MAX_LENGTH_NM`] (the coordinate, nm).
    TooFar(f64),
}

/// A vertex `p` in file units scaled to nanometres and checked: finite, and every
/// coordinate within [`MAX_LENGTH_NM`]. Shared by the OBJ, PLY and STL readers, which
/// place the fault in their own terms.
pub(crate) fn scale_vertex(p: [f64; 3], nm_per_unit: f64) -> Result<glam::DVec3, VertexFault> {
    let q = p.map(|c| c * nm_per_unit);
    if let Some(&c) = q.iter().find(|c| !c.is_finite()) {
        return Err(VertexFault::NonFinite(c));
    }
    if let Some(&c) = q.iter().find(|c| c.abs() > MAX_LENGTH_NM) {
        return Err(VertexFault::TooFar(c));
    }
    Ok(glam::DVec3::from(q))
}

/// The message for a coordinate `c` (nm) beyond [`MAX_LENGTH_NM`].
pub(crate) fn beyond_limit(c: f64) -> String {
    format!(
        "coordinate {c:e} nm is beyond the {MAX_LENGTH_NM:e} nm (10 cm) limit of f32 geometry and f64 phase"
    )
}

/// The separation f32 vertices can resolve in a scene whose coordinates reach `extent_nm`:
/// the f32 spacing there (`extent * 2^-23`), floored at the tracer's 1e-4 nm restart
/// offset. Interfaces closer than a few of these cannot be told apart by the accelerator.
pub fn f32_resolution_nm(extent_nm: f64) -> f64 {
    (extent_nm * f64::from(f32::EPSILON)).max(1e-4)
}

/// Interfaces meshed closer than this many [`f32_resolution_nm`] are refused.
pub(super) const MIN_SEPARATION_RESOLUTIONS: f64 = 16.0;

/// Checks a length after scaling to nanometres: finite, positive and at most
/// [`MAX_LENGTH_NM`]; `what` names it in the message.
/// `value` as a message shows it: very large or small values in scientific notation, not
/// hundreds of digits.
pub(crate) fn show(value: f64) -> String {
    if value == 0.0 || (1e-4..1e6).contains(&value.abs()) {
        format!("{value}")
    } else {
        format!("{value:e}")
    }
}

pub(super) fn check_length(
    what: &str,
    value: f64,
    unit: &str,
    nm: f64,
) -> Result<(), SampleErrorKind> {
    let value = show(value);
    if !(nm.is_finite() && nm > 0.0) {
        return Err(SampleErrorKind::from(format!(
            "{what} must be positive and finite, got {value} {unit}"
        )));
    }
    if nm > MAX_LENGTH_NM {
        return Err(SampleErrorKind::from(format!(
            "{what} {value} {unit} ({nm:e} nm) exceeds the {MAX_LENGTH_NM:e} nm (10 cm) limit of f32 geometry and f64 phase"
        )));
    }
    Ok(())
}

/// Every coordinate finite and within [`MAX_LENGTH_NM`], and no triangle that collapses
/// when the accelerator rounds its corners to f32 (it would be invisible, or hide its
/// neighbour). The message names the interface.
pub(super) fn check_geometry(
    interfaces: &[Interface],
    tile_nm: [f64; 2],
) -> Result<(), SampleErrorKind> {
    let mut extent = tile_nm[0].max(tile_nm[1]);
    for itf in interfaces {
        for p in &itf.mesh.positions_nm {
            for c in p.to_array() {
                if !(c.is_finite() && c.abs() <= MAX_LENGTH_NM) {
                    return Err(format!("{}: {}", itf.mesh_path.display(), beyond_limit(c)).into());
                }
                extent = extent.max(c.abs());
            }
        }
    }
    for itf in interfaces {
        let collapsed = itf.mesh.degenerate_triangles_f32();
        if !collapsed.is_empty() {
            return Err(format!(
                "{}: {} of {} triangles collapse when the accelerator rounds coordinates to f32 (spacing {:.2e} nm where the sample reaches {extent:e} nm): enlarge the features or shrink the sample",
                itf.mesh_path.display(),
                collapsed.len(),
                itf.mesh.triangles.len(),
                f32_resolution_nm(extent)
            )
            .into());
        }
    }
    Ok(())
}
