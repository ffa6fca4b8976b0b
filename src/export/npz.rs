//! NumPy export (`.npz`): the BRDF on a regular grid, its axes and the settings, for
//! Python users. Arrays are written by `npyz` (the `.npy` format) into an uncompressed zip
//! archive written by `zip` (what `numpy.savez` makes), with fixed timestamps, so the same
//! BRDF and grid give the same bytes.
//!
//! | array | dtype, shape | meaning |
//! |---|---|---|
//! | `brdf` | f64 `[theta_i, phi_i, theta_o, phi_o, lambda]` | BRDF, 1/sr |
//! | `theta_i_deg`, `phi_i_deg`, `theta_o_deg`, `phi_o_deg` | f64, 1-D | the axes, degrees |
//! | `lambda_nm` | f64, 1-D | wavelength of each bin (its centre), nm |
//! | `settings_json` | u8, 1-D | the BRDF's description as UTF-8 JSON (`bytes(a).decode()`) |
//!
//! From a `.gsa` simulated with `--mueller` ([`mueller_npz_bytes`]), the buckets as
//! simulated: `mueller` and `mueller_stderr`, f64 `[theta_i, phi_i, theta_o, phi_o,
//! lambda, 4, 4]` (1/sr, each direction's own s/p frame), `brdf` their m00, and the axes
//! at the simulated angles and the buckets' centres.

use super::ExportError;
use std::io::{Cursor, Write};

use npyz::WriterBuilder;
use rayon::prelude::*;

use crate::brdf::{Brdf, Representation};
use crate::geom::from_spherical;

/// The grid a `.npz` holds, degrees.
#[derive(Clone, Debug, PartialEq)]
pub struct Grid {
    pub theta_i_deg: Vec<f64>,
    pub phi_i_deg: Vec<f64>,
    pub theta_o_deg: Vec<f64>,
    pub phi_o_deg: Vec<f64>,
}

/// The most values a grid may hold (`brdf` array, f64): 2^28 (2 GiB).
pub const MAX_VALUES: u64 = 1 << 28;

impl Grid {
    /// The simulated incident angles at azimuth 0, and `theta_o_bins x phi_o_bins` bucket
    /// centres, uniform in `theta_o` over [0, 90) and `phi_o` over [0, 360).
    pub fn of(
        r: &Representation,
        theta_o_bins: usize,
        phi_o_bins: usize,
    ) -> Result<Grid, ExportError> {
        if theta_o_bins == 0 || phi_o_bins == 0 {
            return Err(ExportError::from(
                "the outgoing grid needs at least one bin per axis",
            ));
        }
        let centres = |n: usize, span: f64| (0..n).map(move |k| (k as f64 + 0.5) * span / n as f64);
        Ok(Grid {
            theta_i_deg: super::simulated_incidence(r)?
                .iter()
                .map(|t| t.to_degrees())
                .collect(),
            phi_i_deg: vec![0.0],
            theta_o_deg: centres(theta_o_bins, 90.0).collect(),
            phi_o_deg: centres(phi_o_bins, 360.0).collect(),
        })
    }

    fn check(&self) -> Result<(), ExportError> {
        let polar = |v: &[f64]| v.iter().all(|t| t.is_finite() && (0.0..90.0).contains(t));
        if self.theta_i_deg.is_empty() || self.phi_i_deg.is_empty() {
            return Err("the incident grid is empty".into());
        }
        if !polar(&self.theta_i_deg) || !polar(&self.theta_o_deg) {
            return Err("polar angles must lie in [0, 90) degrees".into());
        }
        if self
            .phi_i_deg
            .iter()
            .chain(&self.phi_o_deg)
            .any(|p| !p.is_finite())
        {
            return Err("azimuths must be finite".into());
        }
        Ok(())
    }
}

/// `[theta_i, phi_i, theta_o, phi_o, lambda]` values of `r` on `grid`, C order.
pub fn tabulate(r: &(dyn Brdf + Sync), grid: &Grid) -> Result<Vec<f64>, ExportError> {
    grid.check()?;
    let nl = r.meta().lambda_nm.len();
    let (ni, np, no, nq) = (
        grid.theta_i_deg.len(),
        grid.phi_i_deg.len(),
        grid.theta_o_deg.len(),
        grid.phi_o_deg.len(),
    );
    let total = [ni, np, no, nq, nl]
        .iter()
        .try_fold(1u64, |a, &n| a.checked_mul(n as u64))
        .filter(|&t| t <= MAX_VALUES)
        .ok_or_else(|| format!("the grid holds more than {MAX_VALUES} values"))?;
    let rows: Vec<Vec<f64>> = (0..ni * np * no)
        .into_par_iter()
        .map(|k| {
            let (i, p, o) = (k / (np * no), k / no % np, k % no);
            let wi = from_spherical(
                grid.theta_i_deg[i].to_radians(),
                grid.phi_i_deg[p].to_radians(),
            );
            let mut row = vec![0.0; nq * nl];
            for (q, out) in row.chunks_mut(nl).enumerate() {
                let wo = from_spherical(
                    grid.theta_o_deg[o].to_radians(),
                    grid.phi_o_deg[q].to_radians(),
                );
                r.eval(wi, wo, out);
            }
            row
        })
        .collect();
    let values: Vec<f64> = rows.into_iter().flatten().collect();
    debug_assert_eq!(values.len() as u64, total);
    if let Some(v) = values.iter().find(|v| !v.is_finite()) {
        return Err(ExportError::from(format!(
            "the BRDF evaluates to {v} on the grid"
        )));
    }
    Ok(values)
}

fn npy<T: npyz::AutoSerialize + Copy>(shape: &[u64], values: &[T]) -> std::io::Result<Vec<u8>> {
    let mut buf = Vec::new();
    {
        let mut w = npyz::WriteOptions::new()
            .default_dtype()
            .shape(shape)
            .writer(&mut buf)
            .begin_nd()?;
        w.extend(values.iter().copied())?;
        w.finish()?;
    }
    Ok(buf)
}

/// The `.npz` bytes of `r` on `grid`.
pub fn npz_bytes(r: &Representation, grid: &Grid) -> Result<Vec<u8>, ExportError> {
    let values = tabulate(r, grid)?;
    let m = r.meta();
    let settings = serde_json::json!({
        "representation": m.repr.name(),
        "sample_name": m.sample_name,
        "sample_hash": m.sample_hash,
        "isotropic": m.isotropic,
        "reciprocal": m.reciprocal,
        "median_rel_stderr": m.median_rel_stderr,
        "simulation_toml": m.simulation,
        "goniospec": env!("CARGO_PKG_VERSION"),
    })
    .to_string();
    let len = |v: &[f64]| v.len() as u64;
    let shape = [
        len(&grid.theta_i_deg),
        len(&grid.phi_i_deg),
        len(&grid.theta_o_deg),
        len(&grid.phi_o_deg),
        len(&m.lambda_nm),
    ];
    let io = |e: std::io::Error| e.to_string();
    let arrays: Vec<(&str, Vec<u8>)> = vec![
        ("brdf", npy(&shape, &values).map_err(io)?),
        (
            "theta_i_deg",
            npy(&[shape[0]], &grid.theta_i_deg).map_err(io)?,
        ),
        ("phi_i_deg", npy(&[shape[1]], &grid.phi_i_deg).map_err(io)?),
        (
            "theta_o_deg",
            npy(&[shape[2]], &grid.theta_o_deg).map_err(io)?,
        ),
        ("phi_o_deg", npy(&[shape[3]], &grid.phi_o_deg).map_err(io)?),
        ("lambda_nm", npy(&[shape[4]], &m.lambda_nm).map_err(io)?),
        (
            "settings_json",
            npy(&[settings.len() as u64], settings.as_bytes()).map_err(io)?,
        ),
    ];
    zip_arrays(arrays, values.len() * 8 > u32::MAX as usize / 2)
}

/// A stored zip of `.npy` arrays, as `numpy.savez` writes it, with the zip epoch as every
/// timestamp: deterministic bytes.
fn zip_arrays(arrays: Vec<(&str, Vec<u8>)>, large: bool) -> Result<Vec<u8>, ExportError> {
    let io = |e: std::io::Error| e.to_string();
    let mut zip = zip::ZipWriter::new(Cursor::new(Vec::new()));
    let opts = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Stored)
        .last_modified_time(zip::DateTime::default())
        .large_file(large);
    for (name, bytes) in arrays {
        zip.start_file(format!("{name}.npy"), opts)
            .map_err(|e| e.to_string())?;
        zip.write_all(&bytes).map_err(io)?;
    }
    Ok(zip.finish().map_err(|e| e.to_string())?.into_inner())
}

/// The `.npz` bytes of a `--mueller` accumulator's reflection buckets as simulated (no
/// representation in between): `mueller[theta_i, phi_i, theta_o, phi_o, lambda, 4, 4]`
/// and `mueller_stderr` (1/sr, row-major, each direction's own s/p frame: docs/physics.md,
/// "Polarisation"), `brdf` their m00, and the axes at the simulated angles and the
/// buckets' centres.
pub fn mueller_npz_bytes(
    acc: &crate::accumulate::file::Accumulator,
) -> Result<Vec<u8>, ExportError> {
    let s = &acc.header.settings;
    if !s.mueller {
        return Err(ExportError::from(
            "the accumulator holds no Mueller matrices (simulate with --mueller); for the unpolarised BRDF, build a .gsb and export that",
        ));
    }
    let b = s.buckets();
    let (ni, nl) = (s.theta_i_deg.len(), s.wavelength_count());
    let (nt, np) = (b.theta_bins as usize, b.phi_bins as usize);
    let total = [ni, nt, np, nl, 16]
        .iter()
        .try_fold(1u64, |a, &n| a.checked_mul(n as u64))
        .filter(|&t| t <= MAX_VALUES)
        .ok_or_else(|| format!("the Mueller grid holds more than {MAX_VALUES} values"))?;
    let (mut m, mut e, mut f) = (
        Vec::with_capacity(total as usize),
        Vec::with_capacity(total as usize),
        Vec::with_capacity(total as usize / 16),
    );
    for i in 0..ni {
        for k in 0..b.len() {
            let omega = b.projected_solid_angle(k);
            for j in 0..nl {
                let c = acc.cell(i, j);
                let v = c.mueller(2 * k).unwrap_or([0.0; 16]);
                let se = c.mueller_stderr(2 * k).unwrap_or([f64::NAN; 16]);
                m.extend(v.iter().map(|x| x / omega));
                e.extend(se.iter().map(|x| x / omega));
                f.push(v[0] / omega);
            }
        }
    }
    let centre = |n: usize, span: f64| -> Vec<f64> {
        (0..n).map(|k| (k as f64 + 0.5) * span / n as f64).collect()
    };
    let lambda: Vec<f64> = (0..nl).map(|j| s.wavelength(j)).collect();
    let settings = serde_json::json!({
        "representation": "buckets",
        "sample_name": s.sample_name,
        "sample_hash": s.sample_hash,
        "frames": "each direction's s/p frame: s = w x z / |w x z| (x along the normal), p = s x w; Stokes x = p, y = s, S3 = 2 Im(conj E_p E_s)",
        "trees_per_direction": acc.header.rays_per_direction,
        "simulation_toml": toml::to_string(s).unwrap_or_default(),
        "goniospec": env!("CARGO_PKG_VERSION"),
    })
    .to_string();
    let (ni, nt, np, nl) = (ni as u64, nt as u64, np as u64, nl as u64);
    let io = |e: std::io::Error| e.to_string();
    let arrays: Vec<(&str, Vec<u8>)> = vec![
        ("mueller", npy(&[ni, 1, nt, np, nl, 4, 4], &m).map_err(io)?),
        (
            "mueller_stderr",
            npy(&[ni, 1, nt, np, nl, 4, 4], &e).map_err(io)?,
        ),
        ("brdf", npy(&[ni, 1, nt, np, nl], &f).map_err(io)?),
        ("theta_i_deg", npy(&[ni], &s.theta_i_deg).map_err(io)?),
        ("phi_i_deg", npy(&[1], &[s.phi_i_deg]).map_err(io)?),
        (
            "theta_o_deg",
            npy(&[nt], &centre(nt as usize, 90.0)).map_err(io)?,
        ),
        (
            "phi_o_deg",
            npy(&[np], &centre(np as usize, 360.0)).map_err(io)?,
        ),
        ("lambda_nm", npy(&[nl], &lambda).map_err(io)?),
        (
            "settings_json",
            npy(&[settings.len() as u64], settings.as_bytes()).map_err(io)?,
        ),
    ];
    zip_arrays(arrays, total * 16 > u64::from(u32::MAX) / 2)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The .npy header numpy writes for a little-endian f64 array of shape (2, 3) (format
    /// 1.0, NEP 1: magic, version, header length, dict padded to 64 bytes).
    #[test]
    fn npy_layout() {
        let b = npy(&[2, 3], &[1.0f64, 2.0, 3.0, 4.0, 5.0, 6.0]).unwrap();
        assert_eq!(&b[..6], b"\x93NUMPY");
        let hlen = u16::from_le_bytes([b[8], b[9]]) as usize;
        let header = std::str::from_utf8(&b[10..10 + hlen]).unwrap();
        assert!(
            header.contains("'descr': '<f8'") && header.contains("'shape': (2, 3"),
            "{header}"
        );
        assert_eq!((10 + hlen) % 64, 0);
        assert_eq!(
            f64::from_le_bytes(b[10 + hlen + 40..10 + hlen + 48].try_into().unwrap()),
            6.0
        );
    }
}
