//! Refractive-index models of media: constant, Cauchy, Sellmeier and tabulated `n, k`.
//!
//! Every model has a stated wavelength range; a wavelength outside it is an error, never an
//! extrapolation. Wavelengths are in nanometres; indices are dimensionless with `k >= 0`
//! absorbing (field `~ exp(i 2 pi (n + i k) l / lambda)`, docs/design.md §3).

use std::path::{Path, PathBuf};

use serde::Deserialize;

/// The range of refractive indices accepted as physical: real parts from 1e-9 (a
/// near-perfect conductor, `n -> 0`, as furnace tests use; metals' smallest real parts are
/// about 0.01) to a margin above the largest known in the infrared, and extinction
/// coefficients up to far-infrared metals'. Values
/// outside (1e300, 1e-300) make the optics overflow to NaN; they are refused on loading.
pub const N_MIN: f64 = 1e-9;
pub const N_MAX: f64 = 100.0;
pub const K_MAX: f64 = 1000.0;

/// Range assumed for a Cauchy or Sellmeier formula whose TOML gives no `range_nm`: the
/// visible and near infrared, where such fits are normally made.
pub const DEFAULT_FORMULA_RANGE_NM: [f64; 2] = [300.0, 2000.0];

/// How a medium's complex index depends on wavelength.
#[derive(Clone, Debug, PartialEq)]
pub enum IndexModel {
    /// The same `n + i k` at every wavelength.
    Constant { n: f64, k: f64 },
    /// `n(lambda) = a + b / lambda^2 + c / lambda^4` with lambda in nm
    /// (Cauchy 1836; e.g. Born & Wolf, Principles of Optics, §2.3.4), `k = 0`.
    Cauchy {
        a: f64,
        b_nm2: f64,
        c_nm4: f64,
        range_nm: [f64; 2],
    },
    /// `n^2 = 1 + sum_i b_i L^2 / (L^2 - c_i)` with L in µm and c_i in µm²
    /// (Sellmeier 1871; the form used by Malitson 1965), `k = 0`.
    Sellmeier {
        b: Vec<f64>,
        c_um2: Vec<f64>,
        range_nm: [f64; 2],
    },
    /// Tabulated `(lambda_nm, n, k)` rows, strictly increasing in wavelength, interpolated
    /// linearly in `n` and `k`.
    Table {
        source: PathBuf,
        lambda_nm: Vec<f64>,
        n: Vec<f64>,
        k: Vec<f64>,
    },
}

/// A wavelength the model cannot answer for.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("wavelength {lambda_nm} nm is outside the range {lo}..{hi} nm of {what}")]
pub struct OutOfRange {
    pub lambda_nm: f64,
    pub lo: f64,
    pub hi: f64,
    pub what: String,
}

impl IndexModel {
    /// Appends a canonical encoding of the physics this model describes (for the sample
    /// hash): a tag, then every number as little-endian f64 with lists prefixed by their
    /// length. Where a table came from does not enter, only its rows.
    pub fn canonical_bytes(&self, out: &mut Vec<u8>) {
        let mut put = |v: &[f64]| {
            out.extend_from_slice(&(v.len() as u64).to_le_bytes());
            for x in v {
                out.extend_from_slice(&x.to_le_bytes());
            }
        };
        match self {
            IndexModel::Constant { n, k } => {
                put(&[0.0]);
                put(&[*n, *k]);
            }
            IndexModel::Cauchy {
                a,
                b_nm2,
                c_nm4,
                range_nm,
            } => {
                put(&[1.0]);
                put(&[*a, *b_nm2, *c_nm4, range_nm[0], range_nm[1]]);
            }
            IndexModel::Sellmeier { b, c_um2, range_nm } => {
                put(&[2.0]);
                put(b);
                put(c_um2);
                put(range_nm);
            }
            IndexModel::Table {
                lambda_nm, n, k, ..
            } => {
                put(&[3.0]);
                put(lambda_nm);
                put(n);
                put(k);
            }
        }
    }

    /// `(n, k)` at `lambda_nm`.
    pub fn eval(&self, lambda_nm: f64) -> Result<(f64, f64), OutOfRange> {
        if let Some([lo, hi]) = self.range_nm()
            && !(lambda_nm >= lo && lambda_nm <= hi)
        {
            return Err(OutOfRange {
                lambda_nm,
                lo,
                hi,
                what: self.describe(),
            });
        }
        Ok(match self {
            IndexModel::Constant { n, k } => (*n, *k),
            IndexModel::Cauchy {
                a, b_nm2, c_nm4, ..
            } => {
                let l2 = lambda_nm * lambda_nm;
                (a + b_nm2 / l2 + c_nm4 / (l2 * l2), 0.0)
            }
            IndexModel::Sellmeier { b, c_um2, .. } => {
                let l2 = (lambda_nm * 1e-3).powi(2);
                let n2 = 1.0
                    + b.iter()
                        .zip(c_um2)
                        .map(|(b, c)| b * l2 / (l2 - c))
                        .sum::<f64>();
                (n2.sqrt(), 0.0)
            }
            IndexModel::Table {
                lambda_nm: l, n, k, ..
            } => {
                // Range checked above, so a bracketing interval exists.
                let i = l.partition_point(|&x| x <= lambda_nm).clamp(1, l.len() - 1);
                let t = (lambda_nm - l[i - 1]) / (l[i] - l[i - 1]);
                (
                    n[i - 1] + t * (n[i] - n[i - 1]),
                    k[i - 1] + t * (k[i] - k[i - 1]),
                )
            }
        })
    }

    /// The wavelengths (nm) the model is valid for; `None` for a constant.
    pub fn range_nm(&self) -> Option<[f64; 2]> {
        match self {
            IndexModel::Constant { .. } => None,
            IndexModel::Cauchy { range_nm, .. } | IndexModel::Sellmeier { range_nm, .. } => {
                Some(*range_nm)
            }
            IndexModel::Table { lambda_nm, .. } => {
                Some([lambda_nm[0], lambda_nm[lambda_nm.len() - 1]])
            }
        }
    }

    /// Whether the index changes with wavelength (then geometry does too, and spectral
    /// path sharing is off: docs/design.md §3).
    pub fn is_dispersive(&self) -> bool {
        !matches!(self, IndexModel::Constant { .. })
    }

    /// One line for reports.
    pub fn describe(&self) -> String {
        match self {
            IndexModel::Constant { n, k } => format!("constant n = {n}, k = {k}"),
            IndexModel::Cauchy { a, b_nm2, .. } => format!("Cauchy a = {a}, b = {b_nm2} nm²"),
            IndexModel::Sellmeier { b, .. } => format!("Sellmeier, {} terms", b.len()),
            IndexModel::Table {
                source, lambda_nm, ..
            } => {
                format!("table {} ({} rows)", source.display(), lambda_nm.len())
            }
        }
    }
}

/// A medium: a name, its index model, and the volume scattering inside it, if any.
#[derive(Clone, Debug, PartialEq)]
pub struct Medium {
    pub name: String,
    /// The index of the medium itself (a particle medium's host).
    pub model: IndexModel,
    pub scattering: Option<Scattering>,
}

/// Volume scattering inside a medium (`optics::particles` has the physics).
#[derive(Clone, Debug, PartialEq)]
pub enum Scattering {
    /// Mie spheres of another medium (an index into `Sample::media`) suspended in this one.
    Particles {
        medium: usize,
        radius: crate::optics::particles::Radius,
        volume_fraction: f64,
        /// Dependent scattering of the packed spheres (the Percus-Yevick structure factor,
        /// `optics::particles::structure`): on by default from `PY_FROM` by volume.
        dependent: bool,
    },
    /// A prescribed Henyey-Greenstein phase function and coefficients (1/um), the same at
    /// every wavelength.
    HenyeyGreenstein {
        g: f64,
        scattering_per_um: f64,
        absorption_per_um: f64,
    },
}

impl Scattering {
    /// Where a particle medium's scattering model is stretched: packed beyond where the
    /// Percus-Yevick structure factor is trusted, or dense and told to scatter independently.
    pub fn packing_warning(&self, name: &str) -> Option<String> {
        use crate::optics::particles::structure::{PY_TRUSTED_MAX, percus_yevick};
        let Scattering::Particles {
            volume_fraction: f,
            dependent,
            ..
        } = self
        else {
            return None;
        };
        if *dependent && *f > PY_TRUSTED_MAX {
            Some(format!(
                "medium '{name}' packs its particles at {} % by volume, above the {} % to which the Percus-Yevick structure factor is trusted (Hansen & McDonald 2006, §4.4): its scattering is uncertain there; a many-particle solver (T-matrix) settles it",
                100.0 * f,
                100.0 * PY_TRUSTED_MAX
            ))
        } else if !*dependent && *f >= 0.1 {
            Some(format!(
                "medium '{name}' holds {} % of particles by volume with dependent = \"none\": independent scattering overstates it there (by up to 1 / S(0) = {:.2} for spheres small against the wavelength); the default, \"percus-yevick\", takes the packing",
                100.0 * f,
                1.0 / percus_yevick(*f, 0.0)
            ))
        } else {
            None
        }
    }

    /// Appends a canonical encoding (for the sample hash), like
    /// [`IndexModel::canonical_bytes`].
    pub fn canonical_bytes(&self, out: &mut Vec<u8>) {
        use crate::optics::particles::Radius;
        let v: Vec<f64> = match self {
            Scattering::Particles {
                medium,
                radius,
                volume_fraction,
                dependent,
            } => {
                let mut v = match radius {
                    Radius::Fixed { radius_nm } => {
                        vec![10.0, *medium as f64, *volume_fraction, *radius_nm]
                    }
                    Radius::LogNormal { median_nm, sigma } => {
                        vec![11.0, *medium as f64, *volume_fraction, *median_nm, *sigma]
                    }
                };
                if *dependent {
                    v.push(1.0);
                }
                v
            }
            Scattering::HenyeyGreenstein {
                g,
                scattering_per_um,
                absorption_per_um,
            } => vec![12.0, *g, *scattering_per_um, *absorption_per_um],
        };
        out.extend_from_slice(&(v.len() as u64).to_le_bytes());
        for x in v {
            out.extend_from_slice(&x.to_le_bytes());
        }
    }
}

impl Medium {
    /// A non-dispersive medium.
    pub fn constant(name: &str, n: f64, k: f64) -> Medium {
        Medium {
            name: name.to_string(),
            model: IndexModel::Constant { n, k },
            scattering: None,
        }
    }
}

/// The TOML shape of a medium (in a sample's `[media.NAME]`, or a `data/*.toml` model
/// file). Exactly one model key is allowed.
#[derive(Deserialize, Debug, Default)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawMedium {
    pub n: Option<f64>,
    pub k: Option<f64>,
    pub cauchy: Option<RawCauchy>,
    pub sellmeier: Option<RawSellmeier>,
    pub table: Option<String>,
    pub model: Option<String>,
    pub range_nm: Option<[f64; 2]>,
    /// Mie particles suspended in the medium (a sample's media only).
    pub particles: Option<RawParticles>,
    /// A Henyey-Greenstein scattering medium (a sample's media only).
    pub henyey_greenstein: Option<RawHenyeyGreenstein>,
}

/// `particles = { medium = "tio2", radius_nm = 120, volume_fraction = 0.1 }`, or with
/// `log_normal = { median_radius_nm = 120, sigma = 0.3 }` instead of `radius_nm`.
#[derive(Deserialize, Debug, Clone)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawParticles {
    pub medium: String,
    pub radius_nm: Option<f64>,
    pub log_normal: Option<RawLogNormal>,
    pub volume_fraction: f64,
    /// "percus-yevick" or "none" (default: percus-yevick from 0.5 % by volume).
    pub dependent: Option<String>,
}

#[derive(Deserialize, Debug, Clone)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawLogNormal {
    pub median_radius_nm: f64,
    pub sigma: f64,
}

/// `henyey_greenstein = { g = 0.5, scattering_per_um = 2.0, absorption_per_um = 0.01 }`.
#[derive(Deserialize, Debug, Clone)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawHenyeyGreenstein {
    pub g: f64,
    pub scattering_per_um: f64,
    #[serde(default)]
    pub absorption_per_um: f64,
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawCauchy {
    pub a: f64,
    #[serde(default)]
    pub b_nm2: f64,
    #[serde(default)]
    pub c_nm4: f64,
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawSellmeier {
    pub b: Vec<f64>,
    pub c_um2: Vec<f64>,
}

/// Why a medium definition or a table was refused: the message, and the file and line
/// of a table defect when it lies in a table.
#[derive(Debug, Clone, PartialEq)]
pub struct MediumDefError {
    pub message: String,
    pub file: Option<(PathBuf, Option<usize>)>,
}

impl MediumDefError {
    fn msg(m: impl Into<String>) -> Self {
        MediumDefError {
            message: m.into(),
            file: None,
        }
    }
}

/// Turns a raw medium into a model; `base` resolves `table` and `model` paths.
pub(crate) fn build_model(
    raw: &RawMedium,
    base: &Path,
    allow_model_file: bool,
) -> Result<IndexModel, MediumDefError> {
    let given: Vec<&str> = [
        raw.n.map(|_| "n"),
        raw.cauchy.as_ref().map(|_| "cauchy"),
        raw.sellmeier.as_ref().map(|_| "sellmeier"),
        raw.table.as_ref().map(|_| "table"),
        raw.model.as_ref().map(|_| "model"),
    ]
    .into_iter()
    .flatten()
    .collect();
    if given.len() != 1 {
        return Err(MediumDefError::msg(if given.is_empty() {
            "needs one index model: n (and k), cauchy, sellmeier, table or model".to_string()
        } else {
            format!(
                "has several index models ({}); give exactly one",
                given.join(", ")
            )
        }));
    }
    if raw.k.is_some() && raw.n.is_none() {
        return Err(MediumDefError::msg(
            "k is only allowed together with a constant n",
        ));
    }
    let range = |default: [f64; 2]| -> Result<[f64; 2], MediumDefError> {
        let r = raw.range_nm.unwrap_or(default);
        if !(r[0].is_finite() && r[1].is_finite() && r[0] > 0.0 && r[0] < r[1]) {
            return Err(MediumDefError::msg(format!(
                "range_nm must be two increasing positive wavelengths, got {r:?}"
            )));
        }
        Ok(r)
    };
    if raw.range_nm.is_some() && (raw.n.is_some() || raw.table.is_some()) {
        return Err(MediumDefError::msg(
            "range_nm applies to cauchy and sellmeier formulas only (a table's range is its rows)",
        ));
    }
    let model = if let Some(n) = raw.n {
        let k = raw.k.unwrap_or(0.0);
        if !(n.is_finite() && n > 0.0) {
            return Err(MediumDefError::msg(format!(
                "n must be positive and finite, got {n}"
            )));
        }
        if !(N_MIN..=N_MAX).contains(&n) {
            return Err(MediumDefError::msg(format!(
                "n must be between {N_MIN:e} and {N_MAX} (a real material's index), got {n:?}"
            )));
        }
        if !(k.is_finite() && k >= 0.0) {
            return Err(MediumDefError::msg(format!(
                "k must be finite and >= 0, got {k}"
            )));
        }
        if k > K_MAX {
            return Err(MediumDefError::msg(format!(
                "k must be between 0 and {K_MAX}, got {k:?}"
            )));
        }
        IndexModel::Constant { n, k }
    } else if let Some(c) = &raw.cauchy {
        IndexModel::Cauchy {
            a: c.a,
            b_nm2: c.b_nm2,
            c_nm4: c.c_nm4,
            range_nm: range(DEFAULT_FORMULA_RANGE_NM)?,
        }
    } else if let Some(s) = &raw.sellmeier {
        if s.b.len() != s.c_um2.len() || s.b.is_empty() {
            return Err(MediumDefError::msg(format!(
                "sellmeier needs as many b as c_um2 coefficients (got {} and {})",
                s.b.len(),
                s.c_um2.len()
            )));
        }
        IndexModel::Sellmeier {
            b: s.b.clone(),
            c_um2: s.c_um2.clone(),
            range_nm: range(DEFAULT_FORMULA_RANGE_NM)?,
        }
    } else if let Some(t) = &raw.table {
        load_table(&base.join(t))?
    } else {
        let file = base.join(raw.model.as_deref().unwrap_or_default());
        if !allow_model_file {
            return Err(MediumDefError::msg(
                "a model file cannot itself name a model file",
            ));
        }
        return load_model_file(&file);
    };
    check_model(&model)?;
    Ok(model)
}

/// A formula must give a physical index over its whole range: sample it densely.
fn check_model(model: &IndexModel) -> Result<(), MediumDefError> {
    if let Some([lo, hi]) = model.range_nm() {
        for i in 0..=256 {
            let l = lo + (hi - lo) * f64::from(i) / 256.0;
            let (n, k) = model
                .eval(l)
                .map_err(|e| MediumDefError::msg(e.to_string()))?;
            if !(n.is_finite()
                && (N_MIN..=N_MAX).contains(&n)
                && k.is_finite()
                && (0.0..=K_MAX).contains(&k))
            {
                return Err(MediumDefError::msg(format!(
                    "the formula gives n = {n}, k = {k} at {l:.1} nm, inside its range (a real material has {N_MIN:e} <= n <= {N_MAX}, 0 <= k <= {K_MAX}); check the coefficients or range_nm"
                )));
            }
        }
    }
    Ok(())
}

/// Loads a `data/*.toml` model file (one medium definition without a name).
pub fn load_model_file(path: &Path) -> Result<IndexModel, MediumDefError> {
    parse_model_file(path, &read_medium_file(path)?)
}

/// The text of a medium file, or an error naming it.
fn read_medium_file(path: &Path) -> Result<String, MediumDefError> {
    crate::io::read_text(path).map_err(|e| in_file(path, None, format!("cannot read file: {e}")))
}

/// An error located in `path` (at `line`, where known).
fn in_file(path: &Path, line: Option<usize>, message: String) -> MediumDefError {
    MediumDefError {
        message,
        file: Some((path.to_path_buf(), line)),
    }
}

/// Parses the text of a `data/*.toml` model file read from `path` (named in errors; files
/// it refers to are resolved beside it).
pub fn parse_model_file(path: &Path, text: &str) -> Result<IndexModel, MediumDefError> {
    let at = |line: Option<usize>, message: String| in_file(path, line, message);
    let raw: RawMedium = toml::from_str(text).map_err(|e| {
        let line = e.span().map(|s| super::line_of(text, s.start));
        at(line, e.message().trim().to_string())
    })?;
    if raw.particles.is_some() || raw.henyey_greenstein.is_some() {
        return Err(at(
            None,
            "a model file holds an index model only; declare particles or henyey_greenstein on the sample's medium".into(),
        ));
    }
    let base = path.parent().unwrap_or(Path::new(""));
    build_model(&raw, base, false).map_err(|e| match e.file {
        Some(_) => e,
        None => at(None, e.message),
    })
}

/// Loads a `lambda_nm,n,k` table. Lines starting with `#` are comments; the first other
/// line is the header. Rows must be strictly increasing in wavelength with `n > 0` and
/// `k >= 0`; at least two rows.
pub fn load_table(path: &Path) -> Result<IndexModel, MediumDefError> {
    parse_table(path, &read_medium_file(path)?)
}

/// Parses the text of a `lambda_nm,n,k` table read from `path` (named in errors).
pub fn parse_table(path: &Path, text: &str) -> Result<IndexModel, MediumDefError> {
    let err = |line: Option<usize>, message: String| in_file(path, line, message);
    let mut header: Option<[usize; 3]> = None;
    let (mut l, mut n, mut k) = (Vec::new(), Vec::new(), Vec::new());
    for (line, raw) in super::obj::numbered_lines(text) {
        let s = raw.trim();
        if s.is_empty() || s.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = s.split(',').map(str::trim).collect();
        let Some(cols) = header else {
            let find = |name: &str| fields.iter().position(|f| *f == name);
            match (find("lambda_nm"), find("n"), find("k")) {
                (Some(a), Some(b), Some(c)) => header = Some([a, b, c]),
                _ => {
                    let missing: Vec<&str> = ["lambda_nm", "n", "k"]
                        .into_iter()
                        .filter(|c| find(c).is_none())
                        .collect();
                    return Err(err(
                        Some(line),
                        format!(
                            "header must name the columns lambda_nm,n,k; missing column {} (the line has {} comma-separated fields)",
                            missing.join(", "),
                            fields.len()
                        ),
                    ));
                }
            }
            continue;
        };
        let get = |c: usize, name: &str| -> Result<f64, MediumDefError> {
            let f = fields.get(c).ok_or_else(|| {
                err(
                    Some(line),
                    format!("missing column {name} (row has {} fields)", fields.len()),
                )
            })?;
            f.parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| err(Some(line), format!("{name} is not a finite number")))
        };
        let (lv, nv, kv) = (
            get(cols[0], "lambda_nm")?,
            get(cols[1], "n")?,
            get(cols[2], "k")?,
        );
        if lv <= 0.0 {
            return Err(err(
                Some(line),
                format!("wavelength must be positive, got {lv}"),
            ));
        }
        if let Some(&prev) = l.last()
            && lv <= prev
        {
            return Err(err(
                Some(line),
                format!(
                    "wavelengths must be sorted strictly increasing: {lv} nm follows {prev} nm"
                ),
            ));
        }
        if !(N_MIN..=N_MAX).contains(&nv) {
            return Err(err(
                Some(line),
                format!(
                    "n must be between {N_MIN} and {N_MAX} (a real material's index), got {nv:?}"
                ),
            ));
        }
        if kv < 0.0 {
            return Err(err(
                Some(line),
                format!("k must be >= 0 (absorbing), got {kv}"),
            ));
        }
        if kv > K_MAX {
            return Err(err(
                Some(line),
                format!("k must be between 0 and {K_MAX}, got {kv:?}"),
            ));
        }
        l.push(lv);
        n.push(nv);
        k.push(kv);
    }
    if header.is_none() {
        return Err(err(None, "no header line lambda_nm,n,k".into()));
    }
    if l.len() < 2 {
        return Err(err(
            None,
            format!("a table needs at least 2 rows, found {}", l.len()),
        ));
    }
    Ok(IndexModel::Table {
        source: path.to_path_buf(),
        lambda_nm: l,
        n,
        k,
    })
}
