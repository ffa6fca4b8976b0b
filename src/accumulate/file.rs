//! The `.gsa` accumulator file: versioned, checksummed, written atomically.
//!
//! In the shared container ([`crate::container`], magic `GSPECACC`, version 3; version 2
//! files still read): the header is the TOML of [`Header`]; the payload holds, for each
//! (incident direction, wavelength) cell, direction-major, little endian: `trees` (u64),
//! `sum` and `sumsq` (f64) and `count` (u64) per bucket key, `r_sum, r_sumsq, t_sum,
//! t_sumsq, absorbed, dropped` (f64), in global mode the complex amplitude sums (12 f64
//! per key), and where the header's `error_groups` is set the replicate groups' variance
//! estimates: a flag (f64 1 or 0: whether the cell has them), `var` per key, `r_var`,
//! `t_var` (f64; zeros where the flag is 0), and where the settings' `mueller` is set the
//! number of keys that hold Mueller sums (u64), then for each, keys ascending, the key (u64),
//! its 16 sums and its 16 sums of squares (f64). A truncated, corrupted or senseless file is
//! refused.

use std::io::Write;
use std::path::Path;

use serde::{Deserialize, Serialize};

use super::{Buckets, Cell, Coherence, PhasePrecision};
use crate::optics::C64;
pub use crate::spectrum::WavelengthMode;
use crate::spectrum::Wavelengths;

pub const MAGIC: &[u8; 8] = b"GSPECACC";
pub const VERSION: u32 = 3;

/// Everything that defines what was simulated; two files merge only when these agree.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Settings {
    pub sample_name: String,
    /// FNV-1a 64 of the sample's geometry and media, hex.
    pub sample_hash: String,
    /// Each incident direction's polar angle, degrees.
    pub theta_i_deg: Vec<f64>,
    /// The azimuth of every direction, degrees, where `phi_i_each_deg` is empty (else the
    /// first direction's).
    pub phi_i_deg: f64,
    /// Each direction's azimuth, degrees, for a run over several (`--phi-i A,B,...`:
    /// `simulate::directions`); absent for one azimuth.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub phi_i_each_deg: Vec<f64>,
    /// Bins (values are the bin edges) or monochromatic (values are the wavelengths).
    pub wavelength_mode: WavelengthMode,
    /// The sampling's values, nm: bin edges, or exact wavelengths (not the bins' centres,
    /// which every output names `lambda_nm`).
    pub wavelengths_nm: Vec<f64>,
    pub coherence: Coherence,
    /// Beamlet radius, nm; `inf` for the plane-wave limit.
    pub coherence_radius_nm: f64,
    pub cutoff: f64,
    pub max_depth: u32,
    pub theta_o_bins: u32,
    pub phi_o_bins: u32,
    /// f64 (default; omitted from the file) or f32 (the precision experiment).
    #[serde(default, skip_serializing_if = "is_f64")]
    pub phase_precision: PhasePrecision,
    /// Tile-side crossings of one segment chain before it is dropped.
    pub max_wraps: u32,
    /// Traced segments of one tree before its remaining rays are dropped.
    pub max_segments: u32,
    /// Entry points: the R2 low-discrepancy sequence or uniform (plain Monte Carlo).
    pub entry_points: EntryPoints,
    /// Geometry traced once for all wavelengths (same expectation, other bits).
    pub path_sharing: bool,
    /// Adaptive budget: the target relative standard error, and the most trees per
    /// direction; absent for a fixed budget.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tolerance: Option<f64>,
    /// Adaptive budget by the BRDF's quality (`--target-stderr`): the target median
    /// relative standard error of the bright buckets; absent otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target_stderr: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_rays: Option<u64>,
    /// A batch unit's offset in its run's directions (`SimConfig::first_direction`);
    /// omitted when 0.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub first_direction: u64,
    /// `coherence = "auto"`: each cell's method, one string per incident direction with
    /// one letter per wavelength cell: `r` (rays, the beamlet estimator) or `d` (the
    /// diffraction method). Empty otherwise. Runs whose choices differ do not merge.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub methods: Vec<String>,
    /// Next-event estimation in particle media (`trace::escape`): the same expectation as
    /// the walk alone, other bits and less noise; absent (false) where it did not apply.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub next_event: bool,
    /// `--mueller`: each cell also holds every bucket's Mueller matrix (sums and sums of
    /// squares of its 16 elements); absent (false) otherwise.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub mueller: bool,
    /// The surface facing the light is flat (`sample::flat_fraction`): its mirror is a
    /// delta the buckets spread, which `render` and `export` put back sharp.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub flat_top: bool,
    /// The sample is not rotation-symmetric (`sample::symmetry`): its facets lean towards
    /// some azimuths, so its BRDF depends on the incident azimuth. `build` keeps it
    /// anisotropic. Absent where it is symmetric (and in files before it was recorded).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub anisotropy: Option<crate::sample::symmetry::Anisotropy>,
    /// What the rigorous solver spent where any cell took it; absent otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rigorous: Option<crate::reference::rigorous::Effort>,
}

fn is_zero(v: &u64) -> bool {
    *v == 0
}

fn is_f64(p: &PhasePrecision) -> bool {
    *p == PhasePrecision::F64
}

/// How entry points are drawn (written "r2" or "uniform").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum EntryPoints {
    /// The R2 low-discrepancy sequence (Roberts 2018).
    R2,
    /// Independent uniform points.
    Uniform,
}

impl std::fmt::Display for EntryPoints {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            EntryPoints::R2 => "r2",
            EntryPoints::Uniform => "uniform",
        })
    }
}

/// The file header: settings plus what the runs contributed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Header {
    pub settings: Settings,
    /// Seeds of the runs merged into this file.
    pub seeds: Vec<u64>,
    /// Launched trees per incident direction and wavelength, over all runs: the same for
    /// every direction with a fixed budget, the largest with an adaptive one.
    pub rays: u64,
    /// Launched trees of each incident direction, over all runs (adaptive runs differ).
    pub rays_per_direction: Vec<u64>,
    /// The trees per direction the runs asked for (`--rays`, summed over runs), where a
    /// direction of the diffraction method traced its lattice's count instead
    /// (`simulate::diffraction_lattice`); absent for the other methods, whose directions
    /// trace what was asked. `batch` checks a unit against its plan by it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rays_asked: Option<u64>,
    pub backend: String,
    /// Rays that met an interface from the wrong medium, over all runs.
    pub leaks: u64,
    /// What the runs had to say about their results (the validity findings and the run's
    /// own warnings, as `simulate` prints them, each direction's in direction order), each
    /// sentence once; `goniospec info` lists them.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
    /// Replicate groups of trees (independent shifts of the R2 entry points) whose spread
    /// gives the standard errors (docs/design.md §4, "Standard errors"); absent (0) where
    /// the per-tree spread does. Where set, each cell's payload ends with the variance
    /// estimates (a cell without them flags so). Not a setting: runs with and without
    /// groups estimate the same thing and merge (the larger is kept).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub error_groups: u64,
    /// The runs' lossless trees carried out exactly the power that entered each of their
    /// coherence groups (`accumulate::conserve`, issue 71), so that a rays cell without
    /// absorption balances `R + T + dropped = 1` to rounding, which the checks hold it to
    /// (`simulate::check_file`). Absent (false) in files of earlier versions, and in a
    /// merge with one.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub balanced: bool,
}

/// A `.gsa` header whose values no reader can rely on (the message names the field).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct InvalidHeader(pub String);

message_error!(InvalidHeader, InvalidHeader);

impl Header {
    /// What `goniospec info` prints about a run, one fact per line.
    pub fn describe(&self) -> String {
        let st = &self.settings;
        let mut s = format!("sample: '{}' (hash {})\n", st.sample_name, st.sample_hash);
        let azimuths = st.azimuths();
        s += &if azimuths.len() > 1 {
            let at = |p: f64| -> Vec<f64> {
                (0..st.theta_i_deg.len())
                    .filter(|&i| st.phi_of(i) == p)
                    .map(|i| st.theta_i_deg[i])
                    .collect()
            };
            let rows: Vec<String> = azimuths
                .iter()
                .map(|&p| format!("{:?} at phi_i {p}", at(p)))
                .collect();
            format!("incident angles (deg): {}\n", rows.join("; "))
        } else {
            format!(
                "incident angles (deg): {:?}, phi_i {} deg\n",
                st.theta_i_deg, st.phi_i_deg
            )
        };
        s += &format!(
            "wavelengths: {} {} ({}..{} nm)\n",
            st.wavelength_count(),
            st.wavelength_mode,
            st.wavelengths_nm.first().unwrap_or(&0.0),
            st.wavelengths_nm.last().unwrap_or(&0.0)
        );
        s += &format!(
            "estimator: {}, coherence radius {} nm, cutoff {:e}, max depth {}\n",
            st.coherence, st.coherence_radius_nm, st.cutoff, st.max_depth
        );
        if st.mueller {
            s += "polarisation: every bucket's Mueller matrix kept (--mueller; goniospec eval --mueller)\n";
        }
        if let Some(e) = st.rigorous.filter(|_| st.rigorous_cells() > 0) {
            s += &format!(
                "rigorous solver: harmonics {} per patterned axis, {} slices per structured region, converged to {:.0e} against a check with two thirds of the harmonics and half the slices\n",
                e.orders.map_or("by wavelength".into(), |m| m.to_string()),
                e.slices,
                e.tolerance
            );
        }
        if st.coherence == Coherence::Auto {
            let (r, d) = st.method_counts();
            s += &format!(
                "methods (auto): rays in {r} cells, the diffraction method in {d}, the rigorous solver in {}\n",
                st.rigorous_cells()
            );
            for (i, t) in st.theta_i_deg.iter().enumerate() {
                let phi = if azimuths.len() > 1 {
                    format!(", phi_i {} deg", st.phi_of(i))
                } else {
                    String::new()
                };
                s += &format!("  theta_i {t} deg{phi}: {}\n", st.methods_of(i));
            }
        }
        s += &format!(
            "buckets: {} x {} per hemisphere\n",
            st.theta_o_bins, st.phi_o_bins
        );
        s += &format!(
            "rays per direction: {:?} (seeds {:?}), backend {}, path sharing {}, leaks {}\n",
            self.rays_per_direction, self.seeds, self.backend, st.path_sharing, self.leaks
        );
        s += &format!(
            "limits: cutoff {:e}, max depth {}, max wraps {}, max segments {}; entry points {}{}\n",
            st.cutoff,
            st.max_depth,
            st.max_wraps,
            st.max_segments,
            st.entry_points,
            match (st.tolerance, st.target_stderr, st.max_rays) {
                (Some(t), _, Some(m)) =>
                    format!("; adaptive to {t} relative error, at most {m} rays"),
                (_, Some(t), Some(m)) => format!(
                    "; adaptive to a median relative error of {t} over the bright buckets, at most {m} rays"
                ),
                _ => String::new(),
            }
        );
        s += &crate::warning_codes::describe(&self.warnings);
        s
    }
}

impl Settings {
    pub fn coherence_mode(&self) -> Coherence {
        self.coherence
    }
    pub fn buckets(&self) -> Buckets {
        Buckets {
            theta_bins: self.theta_o_bins,
            phi_bins: self.phi_o_bins,
        }
    }
    /// The run's wavelength sampling (the header was validated when read, or written by
    /// a run whose sampling was).
    pub fn spectrum(&self) -> Wavelengths {
        match self.wavelength_mode {
            WavelengthMode::Bins => Wavelengths::Bins(self.wavelengths_nm.clone()),
            WavelengthMode::Monochromatic => {
                Wavelengths::Monochromatic(self.wavelengths_nm.clone())
            }
        }
    }
    /// Number of wavelength cells.
    pub fn wavelength_count(&self) -> usize {
        if self.wavelength_mode == WavelengthMode::Bins {
            self.wavelengths_nm.len().saturating_sub(1)
        } else {
            self.wavelengths_nm.len()
        }
    }
    /// Representative wavelength of cell `j` (bin centre, or the exact wavelength).
    pub fn wavelength(&self, j: usize) -> f64 {
        if self.wavelength_mode == WavelengthMode::Bins {
            0.5 * (self.wavelengths_nm[j] + self.wavelengths_nm[j + 1])
        } else {
            self.wavelengths_nm[j]
        }
    }
}

/// A simulation result: header and one cell per (incident direction, wavelength),
/// direction-major.
#[derive(Clone, Debug, PartialEq)]
pub struct Accumulator {
    pub header: Header,
    pub cells: Vec<Cell>,
}

pub use crate::container::FileError;

/// The `.gsa` format in the shared container.
pub const FORMAT: crate::container::Format = crate::container::Format {
    magic: MAGIC,
    what: "accumulator (.gsa)",
    version: VERSION,
    legacy_version: Some(2),
};

/// One wavelength's directional reflectance (`goniospec reflectance`, one CSV row).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReflectanceRow {
    /// Bin centre or exact wavelength, nm.
    pub lambda_nm: f64,
    pub r: f64,
    pub t: f64,
    /// Power absorbed per tree (`1 - R - T - dropped` where power entered an absorbing
    /// medium).
    pub absorbed: f64,
    /// Power dropped per tree (cutoff and limits).
    pub dropped: f64,
    /// Standard error of `r`; `None` in global mode (no per-tree estimate).
    pub r_stderr: Option<f64>,
}

/// An incident direction the accumulator was not simulated at (degrees).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NotSimulated {
    #[error("simulated at phi_i {simulated_deg:?} deg, not {asked_deg}")]
    Azimuth {
        asked_deg: f64,
        simulated_deg: Vec<f64>,
    },
    #[error("no incident angle {asked_deg} deg (it has {simulated_deg:?})")]
    Polar {
        asked_deg: f64,
        simulated_deg: Vec<f64>,
    },
}

/// The directional reflectance at one incident angle.
#[derive(Clone, Debug, PartialEq)]
pub struct Reflectance {
    pub rows: Vec<ReflectanceRow>,
    /// Buckets holding a negative estimate (beamlet cross terms; kept, not clamped).
    pub negative_buckets: usize,
}

impl Accumulator {
    /// The directional reflectance at `theta_i_deg` (one of the simulated angles; and
    /// `phi_i_deg`, when given, must be the simulated azimuth).
    pub fn reflectance(
        &self,
        theta_i_deg: f64,
        phi_i_deg: Option<f64>,
    ) -> Result<Reflectance, NotSimulated> {
        let i = self.direction_of(theta_i_deg, phi_i_deg)?;
        let s = &self.header.settings;
        let mode = s.coherence_mode();
        let buckets = s.buckets();
        let mut negative_buckets = 0;
        let rows = (0..s.wavelength_count())
            .map(|j| {
                let c = self.cell(i, j);
                let (r, t) = c.totals(mode, &buckets);
                let n = c.trees.max(1) as f64;
                negative_buckets += (0..2 * buckets.len())
                    .filter(|&k| c.fraction(k, mode) < 0.0)
                    .count();
                ReflectanceRow {
                    lambda_nm: s.wavelength(j),
                    r,
                    t,
                    absorbed: c.absorbed / n,
                    dropped: c.dropped / n,
                    r_stderr: c.r_stderr(mode),
                }
            })
            .collect();
        Ok(Reflectance {
            rows,
            negative_buckets,
        })
    }

    /// The f64 values of a cell's fixed part (after its tree count); a `--mueller` cell's
    /// matrices follow, as many as it holds.
    fn cell_f64s(&self) -> usize {
        let keys = 2 * self.header.settings.buckets().len();
        let global = if self.header.settings.coherence_mode() == Coherence::Global {
            12 * keys
        } else {
            0
        };
        let groups = if self.header.error_groups > 0 {
            keys + 3
        } else {
            0
        };
        3 * keys + 6 + global + groups
    }

    /// Serialises to bytes (deterministic).
    pub fn to_bytes(&self) -> Vec<u8> {
        let header = toml::to_string(&self.header).expect("the header serialises");
        let mut out = Vec::with_capacity(self.cells.len() * (8 + 8 * self.cell_f64s()));
        for c in &self.cells {
            out.extend_from_slice(&c.trees.to_le_bytes());
            let mut put = |v: f64| out.extend_from_slice(&v.to_le_bytes());
            c.sum.iter().for_each(|&v| put(v));
            c.sumsq.iter().for_each(|&v| put(v));
            c.count.iter().for_each(|&v| put(f64::from_bits(v)));
            for v in [
                c.r_sum, c.r_sumsq, c.t_sum, c.t_sumsq, c.absorbed, c.dropped,
            ] {
                put(v);
            }
            for a in &c.global {
                for p in a {
                    for z in p {
                        put(z.re);
                        put(z.im);
                    }
                }
            }
            if self.header.error_groups > 0 {
                c.group_values().into_iter().for_each(&mut put);
            }
            if self.header.settings.mueller {
                super::cell::write_mueller(c, &mut put);
            }
        }
        crate::container::encode(&FORMAT, &header, &out)
    }

    /// Writes the file atomically.
    pub fn write(&self, path: &Path) -> std::io::Result<()> {
        let bytes = self.to_bytes();
        crate::io::write_atomic(path, |w| w.write_all(&bytes))
    }

    /// Reads and validates a file.
    pub fn read(path: &Path) -> Result<Accumulator, FileError> {
        let bytes = crate::container::read(path)?;
        Self::from_bytes(&bytes, &path.display().to_string())
    }

    /// Parses bytes read from `path` (named in errors).
    pub fn from_bytes(bytes: &[u8], path: &str) -> Result<Accumulator, FileError> {
        let frame = crate::container::decode(&FORMAT, bytes, path)?;
        let header: Header = toml::from_str(frame.header)
            .map_err(|e| FileError::content(path, e.message().trim()))?;
        // A file is data from outside: its checksum proves it was not damaged, not that a
        // writer made sense. Every value the reader relies on is validated.
        header
            .validate()
            .map_err(|m| FileError::content(path, m.0))?;
        let mut acc = Accumulator {
            header,
            cells: Vec::new(),
        };
        let ncells = acc.header.settings.theta_i_deg.len() * acc.header.settings.wavelength_count();
        let per = 8 + 8 * acc.cell_f64s();
        let payload = frame.payload;
        let mueller = acc.header.settings.mueller;
        let fixed = ncells.checked_mul(per);
        if fixed.is_none_or(|f| {
            if mueller {
                f > payload.len()
            } else {
                f != payload.len()
            }
        }) {
            return Err(FileError::content(
                path,
                format!(
                    "the header declares {ncells} cells of {per} bytes{}; the payload holds {} bytes",
                    if mueller {
                        " and their Mueller matrices"
                    } else {
                        ""
                    },
                    payload.len()
                ),
            ));
        }
        let buckets = acc.header.settings.buckets();
        let global = acc.header.settings.coherence_mode() == Coherence::Global;
        let truncated = || {
            FileError::content(
                path,
                "a cell's Mueller matrices are cut short or name a senseless bucket key",
            )
        };
        let mut pos = 0;
        for _ in 0..ncells {
            // Every cell's fixed part fits: the payload holds at least the fixed parts of
            // the cells left, checked above and after each cell's matrices.
            let mut f = || {
                let v = f64::from_le_bytes(payload[pos..pos + 8].try_into().expect("8 bytes"));
                pos += 8;
                v
            };
            let mut c = Cell::new(&buckets, global);
            if mueller {
                c = c.with_mueller();
            }
            c.trees = f().to_bits();
            for v in c.sum.iter_mut() {
                *v = f();
            }
            for v in c.sumsq.iter_mut() {
                *v = f();
            }
            for v in c.count.iter_mut() {
                *v = f().to_bits();
            }
            c.r_sum = f();
            c.r_sumsq = f();
            c.t_sum = f();
            c.t_sumsq = f();
            c.absorbed = f();
            c.dropped = f();
            for a in c.global.iter_mut() {
                for pol in a.iter_mut() {
                    for z in pol.iter_mut() {
                        let re = f();
                        let im = f();
                        *z = C64::new(re, im);
                    }
                }
            }
            if acc.header.error_groups > 0 {
                let v: Vec<f64> = (0..c.sum.len() + 3).map(|_| f()).collect();
                c.set_group_values(&v)
                    .map_err(|m| FileError::content(path, m))?;
            }
            if mueller {
                pos = super::cell::read_mueller(payload, pos, &mut c).ok_or_else(truncated)?;
                let left = acc.cells.len() + 1;
                if (ncells - left) * per > payload.len() - pos {
                    return Err(truncated());
                }
            }
            let finite = c.sum.iter().chain(&c.sumsq).all(|v| v.is_finite())
                && c.mueller
                    .iter()
                    .chain(&c.mueller_sq)
                    .flatten()
                    .all(|v| v.is_finite())
                && [
                    c.r_sum, c.r_sumsq, c.t_sum, c.t_sumsq, c.absorbed, c.dropped,
                ]
                .iter()
                .all(|v| v.is_finite());
            if !finite {
                return Err(FileError::content(path, "a cell holds non-finite sums"));
            }
            acc.cells.push(c);
        }
        if pos != payload.len() {
            return Err(FileError::content(
                path,
                format!("{} bytes follow the last cell", payload.len() - pos),
            ));
        }
        Ok(acc)
    }

    /// The cell of incident direction `i` and wavelength `j`.
    pub fn cell(&self, i: usize, j: usize) -> &Cell {
        &self.cells[i * self.header.settings.wavelength_count() + j]
    }

    /// The cells of incident direction `i`, one per wavelength.
    pub fn direction_cells(&self, i: usize) -> &[Cell] {
        let nl = self.header.settings.wavelength_count();
        &self.cells[i * nl..(i + 1) * nl]
    }
}
