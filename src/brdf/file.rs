//! The `.gsb` built-BRDF file: versioned, checksummed, written atomically.
//!
//! In the shared container ([`crate::container`], magic `GSPECBRD`, version 2; version 1
//! files still read): the header is TOML of [`Meta`] and the representation's parameters;
//! the payload holds the arrays the representation needs, each as a length (u64) and that
//! many f64, little endian. A truncated, corrupted or senseless file is refused.

use super::BrdfError;
use std::io::Write;
use std::path::Path;

use serde::{Deserialize, Serialize};

use super::kdtree::{KdTreeBrdf, MAX_K};
use super::subdivided::{Cell, SubdividedBrdf};
use super::table::TableBrdf;
use super::{Kind, Meta, Representation};
use crate::accumulate::Buckets;
pub use crate::container::FileError;

pub const MAGIC: &[u8; 8] = b"GSPECBRD";
pub const VERSION: u32 = 2;

/// The `.gsb` format in the shared container.
pub const FORMAT: crate::container::Format = crate::container::Format {
    magic: MAGIC,
    what: "BRDF (.gsb)",
    version: VERSION,
    legacy_version: Some(1),
};

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
            arrays.push(t.theta_i_rad.clone());
            arrays.push(t.values.clone());
            (
                &t.meta,
                Params {
                    theta_bins: Some(t.theta_bins as u32),
                    phi_bins: Some(t.phi_bins as u32),
                    phi_i: Some(t.phi_i_rad),
                    ..Default::default()
                },
            )
        }
        Representation::Subdivided(s) => {
            arrays.push(s.theta_i_rad.clone());
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
                    phi_i: Some(s.phi_i_rad),
                    incident_angles: Some(s.theta_i_rad.len() as u64),
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
    for a in &arrays {
        put(&mut out, a);
    }
    crate::container::encode(&FORMAT, &header, &out)
}

/// Writes a representation atomically.
pub fn write(r: &Representation, path: &Path) -> std::io::Result<()> {
    let bytes = to_bytes(r);
    crate::io::write_atomic(path, |w| w.write_all(&bytes))
}

/// Reads and validates a `.gsb` file.
pub fn read(path: &Path) -> Result<Representation, FileError> {
    let bytes = crate::container::read(path)?;
    from_bytes(&bytes, &path.display().to_string())
}

/// Parses bytes read from `path` (named in errors).
pub fn from_bytes(bytes: &[u8], path: &str) -> Result<Representation, FileError> {
    let frame = crate::container::decode(&FORMAT, bytes, path)?;
    let content = |m: &str| FileError::content(path, m);
    let header: Header = toml::from_str(frame.header).map_err(|e| content(e.message().trim()))?;
    let payload = frame.payload;
    let mut pos = 0;
    let mut arrays = Vec::new();
    while pos < payload.len() {
        let rest = payload.len() - pos;
        if rest < 8 {
            return Err(content("the payload ends inside an array length"));
        }
        let len = u64::from_le_bytes(payload[pos..pos + 8].try_into().expect("8 bytes"));
        pos += 8;
        if len > (rest as u64 - 8) / 8 {
            return Err(content(&format!(
                "an array declares {len} values but the payload is truncated after {} bytes",
                rest - 8
            )));
        }
        let len = len as usize;
        arrays.push(
            payload[pos..pos + 8 * len]
                .chunks_exact(8)
                .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
                .collect::<Vec<f64>>(),
        );
        pos += 8 * len;
    }
    let r = decode(header, arrays).map_err(|m| content(&m.to_string()))?;
    validate(&r).map_err(|m| content(&m.to_string()))?;
    Ok(r)
}

/// Builds the representation the arrays describe; sizes are checked with checked
/// arithmetic, and grid values are converted only when they are exact integers.
fn decode(header: Header, mut arrays: Vec<Vec<f64>>) -> Result<Representation, BrdfError> {
    let nl = header.meta.lambda_nm.len();
    let pr = &header.params;
    let need = |k: usize| -> Result<(), String> {
        if arrays.len() == k {
            Ok(())
        } else {
            Err(format!("expected {k} arrays, found {}", arrays.len()))
        }
    };
    let times = |a: usize, b: usize| a.checked_mul(b).ok_or("array sizes overflow");
    match header.meta.repr {
        Kind::Kdtree => {
            need(2)?;
            if arrays[0].len() % 4 != 0 {
                return Err(BrdfError::from("kd-tree points are not 4-vectors"));
            }
            let points: Vec<[f64; 4]> = arrays[0]
                .chunks_exact(4)
                .map(|c| [c[0], c[1], c[2], c[3]])
                .collect();
            if arrays[1].len() != times(points.len(), nl)? {
                return Err(BrdfError::from("values do not match the points"));
            }
            let k = pr.k.ok_or("missing k")?;
            if !(1..=MAX_K as u64).contains(&k) || points.is_empty() {
                return Err(BrdfError::from(format!(
                    "k = {k} neighbours (1 to {MAX_K}) over {} points",
                    points.len()
                )));
            }
            if let Some(p) = points.iter().find(|p| p.iter().any(|c| !c.is_finite())) {
                return Err(BrdfError::from(format!(
                    "kd-tree point {p:?} is not finite"
                )));
            }
            Ok(Representation::KdTree(KdTreeBrdf::from_parts(
                points,
                arrays.swap_remove(1),
                k as usize,
                header.meta,
            )))
        }
        Kind::Table => {
            need(2)?;
            let (tb, pb) = (
                pr.theta_bins.ok_or("missing theta_bins")? as usize,
                pr.phi_bins.ok_or("missing phi_bins")? as usize,
            );
            let theta_i = arrays[0].clone();
            if tb == 0
                || pb == 0
                || theta_i.is_empty()
                || arrays[1].len() != times(times(times(theta_i.len(), tb)?, pb)?, nl)?
            {
                return Err(BrdfError::from("table size does not match its axes"));
            }
            Ok(Representation::Table(TableBrdf {
                theta_i_rad: theta_i,
                theta_bins: tb,
                phi_bins: pb,
                phi_i_rad: pr.phi_i.unwrap_or(0.0),
                values: arrays.swap_remove(1),
                meta: header.meta,
            }))
        }
        Kind::Subdivided => {
            let ni = pr.incident_angles.ok_or("missing incident_angles")?;
            if ni == 0 || ni != arrays.len().saturating_sub(1) as u64 / 2 {
                return Err(BrdfError::from(format!(
                    "incident_angles = {ni} does not match the {} arrays",
                    arrays.len()
                )));
            }
            need(1 + 2 * ni as usize)?;
            // A stored grid index: an exact integer that fits a u32.
            let index = |v: f64| -> Result<u32, String> {
                if v.fract() == 0.0 && (0.0..=f64::from(u32::MAX)).contains(&v) {
                    Ok(v as u32)
                } else {
                    Err(format!("cell index {v} is not an integer in the u32 range"))
                }
            };
            let mut cells = Vec::new();
            let mut flux = Vec::new();
            for i in 0..ni as usize {
                let raw = &arrays[1 + 2 * i];
                if raw.len() % 6 != 0 {
                    return Err(BrdfError::from("subdivided cells are not 6-vectors"));
                }
                let c: Vec<Cell> = raw
                    .chunks_exact(6)
                    .map(|c| {
                        Ok(Cell {
                            t0: index(c[0])?,
                            t1: index(c[1])?,
                            p0: index(c[2])?,
                            p1: index(c[3])?,
                            child: index(c[4])?,
                            omega: c[5],
                        })
                    })
                    .collect::<Result<_, String>>()?;
                if c.is_empty() || arrays[2 + 2 * i].len() != times(c.len(), nl)? {
                    return Err(BrdfError::from("cells do not match their flux"));
                }
                cells.push(c);
                flux.push(arrays[2 + 2 * i].clone());
            }
            Ok(Representation::Subdivided(SubdividedBrdf {
                theta_i_rad: arrays[0].clone(),
                phi_i_rad: pr.phi_i.unwrap_or(0.0),
                buckets: Buckets {
                    theta_bins: pr.theta_bins.ok_or("missing theta_bins")?,
                    phi_bins: pr.phi_bins.ok_or("missing phi_bins")?,
                },
                cells,
                flux,
                tolerance: pr.tolerance.unwrap_or(0.0),
                meta: header.meta,
            }))
        }
        Kind::Analytic | Kind::Measured => Err(BrdfError::from(format!(
            "a BRDF of kind {} cannot be stored in a .gsb",
            header.meta.repr
        ))),
    }
}

/// Incident angles: at least one, finite, in [0, pi/2) radians, strictly increasing.
fn check_theta_i(theta_i: &[f64]) -> Result<(), BrdfError> {
    if theta_i.is_empty()
        || theta_i
            .iter()
            .any(|t| !(0.0..std::f64::consts::FRAC_PI_2).contains(t))
        || theta_i.windows(2).any(|w| w[1] <= w[0])
    {
        return Err(BrdfError::from(format!(
            "incident angles must be increasing radians in [0, pi/2), got {theta_i:?}"
        )));
    }
    Ok(())
}

/// Checks everything the evaluators rely on: a file is data from outside, and its
/// checksum proves only that it was not damaged.
fn validate(r: &Representation) -> Result<(), BrdfError> {
    let meta = match r {
        Representation::KdTree(k) => &k.meta,
        Representation::Table(t) => &t.meta,
        Representation::Subdivided(s) => &s.meta,
    };
    let w = &meta.lambda_nm;
    if w.is_empty() || w.len() > 100_001 || w.iter().any(|l| !(l.is_finite() && *l > 0.0)) {
        return Err(BrdfError::from(format!(
            "{} wavelengths: need 1 to 100001 positive finite values",
            w.len()
        )));
    }
    // The stored sampling (validated as it was read) must be the one the centres come from.
    if let Some(sp) = &meta.spectrum
        && (sp.count() != w.len() || (0..w.len()).any(|j| sp.centre(j) != w[j]))
    {
        return Err(BrdfError::from(format!(
            "the spectrum's {} cells do not give the {} stored centres",
            sp.count(),
            w.len()
        )));
    }
    let finite = |what: &str, v: &[f64]| -> Result<(), String> {
        match v.iter().position(|x| !x.is_finite()) {
            Some(i) => Err(format!("{what} value {i} is {}", v[i])),
            None => Ok(()),
        }
    };
    let grid = |tb: u64, pb: u64| -> Result<(), String> {
        if tb == 0 || pb == 0 || tb * pb > 1 << 22 {
            return Err(format!("bucket grid {tb} x {pb} is empty or too large"));
        }
        Ok(())
    };
    match r {
        Representation::KdTree(k) => finite("kd-tree", &k.values).map_err(BrdfError::from),
        Representation::Table(t) => {
            check_theta_i(&t.theta_i_rad)?;
            grid(t.theta_bins as u64, t.phi_bins as u64)?;
            if !t.phi_i_rad.is_finite() {
                return Err(BrdfError::from(format!(
                    "phi_i = {} is not finite",
                    t.phi_i_rad
                )));
            }
            finite("table", &t.values).map_err(BrdfError::from)
        }
        Representation::Subdivided(s) => {
            check_theta_i(&s.theta_i_rad)?;
            let (tb, pb) = (s.buckets.theta_bins, s.buckets.phi_bins);
            grid(u64::from(tb), u64::from(pb))?;
            if !s.phi_i_rad.is_finite() || s.cells.len() != s.theta_i_rad.len() {
                return Err(BrdfError::from(
                    "phi_i is not finite, or the cells do not match the angles",
                ));
            }
            for (cells, flux) in s.cells.iter().zip(&s.flux) {
                finite("flux", flux)?;
                check_cells(cells, tb, pb)?;
            }
            Ok(())
        }
    }
}

/// The cell tree of one incident angle: the root covers the bucket grid, every cell lies
/// in it with a finite, non-negative solid angle, and every split cell has four children
/// after it in the list that partition it (disjoint, inside, areas adding up), so a
/// descent always ends and always finds its cell.
fn check_cells(cells: &[Cell], tb: u32, pb: u32) -> Result<(), BrdfError> {
    let root = &cells[0];
    if (root.t0, root.t1, root.p0, root.p1) != (0, tb, 0, pb) {
        return Err(BrdfError::from(
            "the root cell does not cover the bucket grid",
        ));
    }
    let area = |c: &Cell| u64::from(c.t1 - c.t0) * u64::from(c.p1 - c.p0);
    for (k, c) in cells.iter().enumerate() {
        if c.t0 > c.t1 || c.t1 > tb || c.p0 > c.p1 || c.p1 > pb {
            return Err(BrdfError::from(format!(
                "cell {k} lies outside the bucket grid"
            )));
        }
        if !(c.omega.is_finite() && c.omega >= 0.0) {
            return Err(BrdfError::from(format!(
                "cell {k} has solid angle {}",
                c.omega
            )));
        }
    }
    for (k, c) in cells.iter().enumerate() {
        if c.child == u32::MAX {
            continue;
        }
        let first = c.child as usize;
        if first <= k || first.checked_add(4).is_none_or(|end| end > cells.len()) {
            return Err(BrdfError::from(format!(
                "cell {k} points at children outside the list"
            )));
        }
        let kids = &cells[first..first + 4];
        let inside = kids
            .iter()
            .all(|d| d.t0 >= c.t0 && d.t1 <= c.t1 && d.p0 >= c.p0 && d.p1 <= c.p1);
        let disjoint = (0..4).all(|a| {
            (a + 1..4).all(|b| {
                let (x, y) = (&kids[a], &kids[b]);
                area(x) == 0
                    || area(y) == 0
                    || x.t1 <= y.t0
                    || y.t1 <= x.t0
                    || x.p1 <= y.p0
                    || y.p1 <= x.p0
            })
        });
        if !inside || !disjoint || kids.iter().map(area).sum::<u64>() != area(c) {
            return Err(BrdfError::from(format!(
                "the children of cell {k} do not partition it"
            )));
        }
    }
    Ok(())
}
