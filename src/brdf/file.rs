//! The `.gsb` built-BRDF file: versioned, checksummed, written atomically.
//!
//! Layout (little endian): magic `GSPECBRD`, format version (u32), header length (u32),
//! header (UTF-8 TOML: [`Meta`] and the representation's parameters), then the arrays the
//! representation needs, each as a length (u64) and that many f64; finally an FNV-1a 64
//! checksum of everything before it. A truncated or corrupted file, or one with the wrong
//! magic, is refused.

use std::io::Write;
use std::path::Path;

use serde::{Deserialize, Serialize};

use super::kdtree::KdTreeBrdf;
use super::subdivided::{Cell, SubdividedBrdf};
use super::table::TableBrdf;
use super::{Meta, Representation};
use crate::accumulate::Buckets;
use crate::accumulate::file::fnv1a;

pub const MAGIC: &[u8; 8] = b"GSPECBRD";
pub const VERSION: u32 = 1;

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Params {
    k: Option<u64>,
    tolerance: Option<f64>,
    theta_bins: Option<u32>,
    phi_bins: Option<u32>,
    phi_i: Option<f64>,
    incident_angles: Option<u64>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Header {
    meta: Meta,
    params: Params,
}

/// Why a `.gsb` file was refused.
#[derive(Debug, thiserror::Error)]
pub enum GsbError {
    #[error("{path}: cannot read: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("{path}: not a goniospec BRDF (.gsb) file (wrong magic bytes)")]
    Magic { path: String },
    #[error(
        "{path}: .gsb format version {found} is not supported (this build reads version {VERSION})"
    )]
    Version { path: String, found: u32 },
    #[error("{path}: the file is truncated")]
    Truncated { path: String },
    #[error("{path}: checksum mismatch: the file is corrupted")]
    Checksum { path: String },
    #[error("{path}: bad content: {message}")]
    Content { path: String, message: String },
}

fn put(out: &mut Vec<u8>, a: &[f64]) {
    out.extend_from_slice(&(a.len() as u64).to_le_bytes());
    for v in a {
        out.extend_from_slice(&v.to_le_bytes());
    }
}

/// Serialises a representation (deterministic bytes).
pub fn to_bytes(r: &Representation) -> Vec<u8> {
    let mut arrays: Vec<Vec<f64>> = Vec::new();
    let (meta, params) = match r {
        Representation::KdTree(k) => {
            arrays.push(k.points.iter().flatten().copied().collect());
            arrays.push(k.values.clone());
            (
                &k.meta,
                Params {
                    k: Some(k.k as u64),
                    ..Default::default()
                },
            )
        }
        Representation::Table(t) => {
            arrays.push(t.theta_i.clone());
            arrays.push(t.values.clone());
            (
                &t.meta,
                Params {
                    theta_bins: Some(t.theta_bins as u32),
                    phi_bins: Some(t.phi_bins as u32),
                    phi_i: Some(t.phi_i),
                    ..Default::default()
                },
            )
        }
        Representation::Subdivided(s) => {
            arrays.push(s.theta_i.clone());
            for (cells, flux) in s.cells.iter().zip(&s.flux) {
                arrays.push(
                    cells
                        .iter()
                        .flat_map(|c| {
                            [
                                c.t0 as f64,
                                c.t1 as f64,
                                c.p0 as f64,
                                c.p1 as f64,
                                c.child as f64,
                                c.omega,
                            ]
                        })
                        .collect(),
                );
                arrays.push(flux.clone());
            }
            (
                &s.meta,
                Params {
                    tolerance: Some(s.tolerance),
                    theta_bins: Some(s.buckets.theta_bins),
                    phi_bins: Some(s.buckets.phi_bins),
                    phi_i: Some(s.phi_i),
                    incident_angles: Some(s.theta_i.len() as u64),
                    ..Default::default()
                },
            )
        }
    };
    let header = toml::to_string(&Header {
        meta: meta.clone(),
        params,
    })
    .expect("the header serialises");
    let mut out = Vec::new();
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.extend_from_slice(&(header.len() as u32).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for a in &arrays {
        put(&mut out, a);
    }
    let sum = fnv1a(&out);
    out.extend_from_slice(&sum.to_le_bytes());
    out
}

/// Writes a representation atomically.
pub fn write(r: &Representation, path: &Path) -> std::io::Result<()> {
    let bytes = to_bytes(r);
    crate::io::write_atomic(path, |w| w.write_all(&bytes))
}

/// Reads and validates a `.gsb` file.
pub fn read(path: &Path) -> Result<Representation, GsbError> {
    let p = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|source| GsbError::Io {
        path: p.clone(),
        source,
    })?;
    from_bytes(&bytes, &p)
}

/// Parses bytes read from `path` (named in errors).
pub fn from_bytes(bytes: &[u8], path: &str) -> Result<Representation, GsbError> {
    let p = || path.to_string();
    if bytes.len() < 8 || &bytes[..8] != MAGIC {
        return Err(GsbError::Magic { path: p() });
    }
    if bytes.len() < 24 {
        return Err(GsbError::Truncated { path: p() });
    }
    let version = u32::from_le_bytes(bytes[8..12].try_into().expect("4 bytes"));
    if version != VERSION {
        return Err(GsbError::Version {
            path: p(),
            found: version,
        });
    }
    // The checksum covers everything: check it before trusting any length.
    let n = bytes.len();
    let stored = u64::from_le_bytes(bytes[n - 8..].try_into().expect("8 bytes"));
    let hlen = u32::from_le_bytes(bytes[12..16].try_into().expect("4 bytes")) as usize;
    if 16 + hlen + 8 > n {
        return Err(GsbError::Truncated { path: p() });
    }
    if fnv1a(&bytes[..n - 8]) != stored {
        // A cut file fails the checksum too; say which it is when the lengths tell.
        return Err(if declared_len(bytes, hlen).is_some_and(|want| want > n) {
            GsbError::Truncated { path: p() }
        } else {
            GsbError::Checksum { path: p() }
        });
    }
    let content = |m: &str| GsbError::Content {
        path: p(),
        message: m.to_string(),
    };
    let header: Header = toml::from_str(
        std::str::from_utf8(&bytes[16..16 + hlen]).map_err(|_| content("header is not UTF-8"))?,
    )
    .map_err(|e| content(e.message().trim()))?;
    let mut pos = 16 + hlen;
    let mut arrays = Vec::new();
    while pos < n - 8 {
        if pos + 8 > n - 8 {
            return Err(GsbError::Truncated { path: p() });
        }
        let len = u64::from_le_bytes(bytes[pos..pos + 8].try_into().expect("8 bytes")) as usize;
        pos += 8;
        if len > (n - 8 - pos) / 8 {
            return Err(GsbError::Truncated { path: p() });
        }
        arrays.push(
            bytes[pos..pos + 8 * len]
                .chunks_exact(8)
                .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
                .collect::<Vec<f64>>(),
        );
        pos += 8 * len;
    }
    let nl = header.meta.wavelengths_nm.len();
    let pr = &header.params;
    let need = |k: usize| -> Result<(), GsbError> {
        if arrays.len() == k {
            Ok(())
        } else {
            Err(content(&format!(
                "expected {k} arrays, found {}",
                arrays.len()
            )))
        }
    };
    match header.meta.repr.as_str() {
        "kdtree" => {
            need(2)?;
            let points: Vec<[f64; 4]> = arrays[0]
                .chunks_exact(4)
                .map(|c| [c[0], c[1], c[2], c[3]])
                .collect();
            if arrays[1].len() != points.len() * nl {
                return Err(content("values do not match the points"));
            }
            let k = pr.k.ok_or_else(|| content("missing k"))? as usize;
            Ok(Representation::KdTree(KdTreeBrdf::from_parts(
                points,
                arrays.swap_remove(1),
                k,
                header.meta,
            )))
        }
        "table" => {
            need(2)?;
            let (tb, pb) = (
                pr.theta_bins.ok_or_else(|| content("missing theta_bins"))? as usize,
                pr.phi_bins.ok_or_else(|| content("missing phi_bins"))? as usize,
            );
            let theta_i = arrays[0].clone();
            if arrays[1].len() != theta_i.len() * tb * pb * nl
                || tb == 0
                || pb == 0
                || theta_i.is_empty()
            {
                return Err(content("table size does not match its axes"));
            }
            Ok(Representation::Table(TableBrdf {
                theta_i,
                theta_bins: tb,
                phi_bins: pb,
                phi_i: pr.phi_i.unwrap_or(0.0),
                values: arrays.swap_remove(1),
                meta: header.meta,
            }))
        }
        "subdivided" => {
            let ni = pr
                .incident_angles
                .ok_or_else(|| content("missing incident_angles"))? as usize;
            need(1 + 2 * ni)?;
            let mut cells = Vec::new();
            let mut flux = Vec::new();
            for i in 0..ni {
                let c: Vec<Cell> = arrays[1 + 2 * i]
                    .chunks_exact(6)
                    .map(|c| Cell {
                        t0: c[0] as u32,
                        t1: c[1] as u32,
                        p0: c[2] as u32,
                        p1: c[3] as u32,
                        child: c[4] as u32,
                        omega: c[5],
                    })
                    .collect();
                if arrays[2 + 2 * i].len() != c.len() * nl || c.is_empty() {
                    return Err(content("cells do not match their flux"));
                }
                cells.push(c);
                flux.push(arrays[2 + 2 * i].clone());
            }
            Ok(Representation::Subdivided(SubdividedBrdf {
                theta_i: arrays[0].clone(),
                phi_i: pr.phi_i.unwrap_or(0.0),
                buckets: Buckets {
                    theta_bins: pr.theta_bins.ok_or_else(|| content("missing theta_bins"))?,
                    phi_bins: pr.phi_bins.ok_or_else(|| content("missing phi_bins"))?,
                },
                cells,
                flux,
                tolerance: pr.tolerance.unwrap_or(0.0),
                meta: header.meta,
            }))
        }
        other => Err(content(&format!("unknown representation '{other}'"))),
    }
}

/// The file length the array headers promise, when they can be read.
fn declared_len(bytes: &[u8], hlen: usize) -> Option<usize> {
    let mut pos = 16 + hlen;
    while pos + 8 <= bytes.len().saturating_sub(8) {
        let len = u64::from_le_bytes(bytes[pos..pos + 8].try_into().ok()?) as usize;
        pos = pos.checked_add(8)?.checked_add(len.checked_mul(8)?)?;
    }
    Some(pos + 8)
}
