//! The wavelength sampling of a run: bins (edges, each tree jittered inside) or exact
//! wavelengths. At the bottom of the house: the optics, the tracer, the run and the file
//! formats all use it, and it uses nothing of theirs.

/// The default sampling: the visible, 380 to 780 nm in 10 nm bins.
pub const DEFAULT_WAVELENGTHS: &str = "380:780:10";

use serde::{Deserialize, Serialize};

/// Wavelength sampling. In files it is written whole, as its mode and its values
/// (`mode = "bins"`, `values_nm = [edges]`, or `mode = "monochromatic"` and the
/// wavelengths), so a reader never has to guess bin edges back from centres.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(into = "Record", try_from = "Record")]
pub enum Wavelengths {
    /// Bins given by their edges (nm); each tree draws a stratified jittered wavelength in
    /// each bin.
    Bins(Vec<f64>),
    /// Exact wavelengths (nm).
    Monochromatic(Vec<f64>),
}

/// Most wavelengths (or bins) one run may ask for: each is a cell of every incident
/// direction's accumulator, and 10,000 already resolve 0.04 nm over the visible.
pub const MAX_WAVELENGTHS: usize = 10_000;

/// What the values of a sampling are (written "bins" or "monochromatic").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum WavelengthMode {
    /// Bin edges; each tree draws a jittered wavelength in each bin.
    Bins,
    /// Exact wavelengths.
    Monochromatic,
}

impl std::fmt::Display for WavelengthMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            WavelengthMode::Bins => "bins",
            WavelengthMode::Monochromatic => "monochromatic",
        })
    }
}

/// The file form of a sampling: its mode and its values, nm.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Record {
    mode: WavelengthMode,
    values_nm: Vec<f64>,
}

impl From<Wavelengths> for Record {
    fn from(w: Wavelengths) -> Record {
        let mode = w.mode();
        let (Wavelengths::Bins(v) | Wavelengths::Monochromatic(v)) = w;
        Record { mode, values_nm: v }
    }
}

impl TryFrom<Record> for Wavelengths {
    type Error = SpectrumError;
    fn try_from(r: Record) -> Result<Wavelengths, SpectrumError> {
        Wavelengths::from_parts(r.mode, r.values_nm)
    }
}

/// A wavelength list that cannot be parsed (the setting it came from is the caller's to
/// name: `--wavelengths`, a plan's `wavelengths`, Python's keyword).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SpectrumError {
    #[error("'{0}' is not a number")]
    NotANumber(String),
    #[error("'{0}': expected A:B:STEP or a comma list")]
    NotARange(String),
    #[error("{0}: need finite A < B and STEP > 0")]
    BadRange(String),
    #[error("{0}: more than {MAX_WAVELENGTHS} wavelengths; choose a coarser STEP")]
    TooMany(String),
    #[error("{0}: (B - A) must be a whole number of STEPs")]
    NotWholeSteps(String),
    #[error("every wavelength must be positive and finite")]
    NotPositive,
    #[error("bins need at least two edges (or monochromatic wavelengths)")]
    TooFewEdges,
    #[error("bin edges must increase")]
    NotIncreasing,
    #[error("no wavelengths")]
    Empty,
}

impl Wavelengths {
    /// Parses `--wavelengths` (nm): `A:B:STEP` gives bins of width STEP from A to B (or,
    /// when `monochromatic`, the wavelengths A, A+STEP, ..., B); a comma list gives bin
    /// edges (or exact wavelengths). The error names no flag: the caller knows where the
    /// text came from.
    pub fn parse(spec: &str, monochromatic: bool) -> Result<Wavelengths, SpectrumError> {
        use SpectrumError as E;
        let w = spec.trim();
        let num = |v: &str| {
            v.trim()
                .parse::<f64>()
                .map_err(|_| E::NotANumber(v.trim().to_string()))
        };
        let values: Vec<f64> = if let Some((a, rest)) = w.split_once(':') {
            let (b, step) = rest
                .split_once(':')
                .ok_or_else(|| E::NotARange(w.to_string()))?;
            let (a, b, step) = (num(a)?, num(b)?, num(step)?);
            if !(a.is_finite() && b.is_finite() && step.is_finite() && step > 0.0 && b > a) {
                return Err(E::BadRange(w.to_string()));
            }
            if (b - a) / step > MAX_WAVELENGTHS as f64 {
                return Err(E::TooMany(w.to_string()));
            }
            let n = ((b - a) / step).round() as usize;
            if ((a + n as f64 * step) - b).abs() > 1e-9 * b {
                return Err(E::NotWholeSteps(w.to_string()));
            }
            (0..=n).map(|i| a + i as f64 * step).collect()
        } else {
            w.split(',').map(num).collect::<Result<_, _>>()?
        };
        if values.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
            return Err(E::NotPositive);
        }
        if values.len() > MAX_WAVELENGTHS + 1 {
            return Err(E::TooMany(w.to_string()));
        }
        let mode = if monochromatic {
            WavelengthMode::Monochromatic
        } else {
            WavelengthMode::Bins
        };
        Wavelengths::from_parts(mode, values)
    }

    /// A sampling from its mode and values (nm), as files store it: every value positive
    /// and finite; bins need at least two increasing edges, exact wavelengths at least one.
    /// The count limit is the caller's (a run allows [`MAX_WAVELENGTHS`], a file more).
    pub fn from_parts(
        mode: WavelengthMode,
        values: Vec<f64>,
    ) -> Result<Wavelengths, SpectrumError> {
        use SpectrumError as E;
        if values.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
            return Err(E::NotPositive);
        }
        match mode {
            WavelengthMode::Monochromatic if values.is_empty() => Err(E::Empty),
            WavelengthMode::Monochromatic => Ok(Wavelengths::Monochromatic(values)),
            WavelengthMode::Bins if values.len() < 2 => Err(E::TooFewEdges),
            WavelengthMode::Bins if values.windows(2).any(|p| p[1] <= p[0]) => {
                Err(E::NotIncreasing)
            }
            WavelengthMode::Bins => Ok(Wavelengths::Bins(values)),
        }
    }

    pub fn mode(&self) -> WavelengthMode {
        match self {
            Wavelengths::Bins(_) => WavelengthMode::Bins,
            Wavelengths::Monochromatic(_) => WavelengthMode::Monochromatic,
        }
    }

    /// The stored values, nm: the bin edges, or the exact wavelengths.
    pub fn values_nm(&self) -> &[f64] {
        match self {
            Wavelengths::Bins(v) | Wavelengths::Monochromatic(v) => v,
        }
    }

    /// The representative wavelength of cell `j`, nm: the bin's centre, or the exact
    /// wavelength.
    pub fn centre(&self, j: usize) -> f64 {
        match self {
            Wavelengths::Bins(e) => 0.5 * (e[j] + e[j + 1]),
            Wavelengths::Monochromatic(v) => v[j],
        }
    }

    /// Every cell's representative wavelength, nm.
    pub fn centres(&self) -> Vec<f64> {
        (0..self.count()).map(|j| self.centre(j)).collect()
    }

    /// The band cell `j` covers, nm: its bin's edges, or `(l, l)` for an exact wavelength.
    pub fn band(&self, j: usize) -> (f64, f64) {
        match self {
            Wavelengths::Bins(e) => (e[j], e[j + 1]),
            Wavelengths::Monochromatic(v) => (v[j], v[j]),
        }
    }

    pub fn count(&self) -> usize {
        match self {
            Wavelengths::Bins(e) => e.len().saturating_sub(1),
            Wavelengths::Monochromatic(v) => v.len(),
        }
    }
    /// The shortest wavelength sampled (the first edge of the first bin), nm.
    pub fn min(&self) -> f64 {
        match self {
            Wavelengths::Bins(e) | Wavelengths::Monochromatic(e) => {
                e.iter().copied().fold(f64::INFINITY, f64::min)
            }
        }
    }
    /// The longest wavelength sampled (the last edge of the last bin), nm.
    pub fn max(&self) -> f64 {
        match self {
            Wavelengths::Bins(e) | Wavelengths::Monochromatic(e) => {
                e.iter().copied().fold(0.0, f64::max)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The file form keeps the mode and every value: bins come back as the same edges
    /// (not rebuilt from centres), exact wavelengths as the same list.
    #[test]
    fn samplings_round_trip_through_toml_whole() {
        for w in [
            Wavelengths::Bins(vec![400.0, 420.0, 500.0, 780.0]),
            Wavelengths::Monochromatic(vec![633.0, 450.0]),
        ] {
            let text = toml::to_string(&w).unwrap();
            assert!(text.contains(&format!("mode = \"{}\"", w.mode())), "{text}");
            assert_eq!(toml::from_str::<Wavelengths>(&text).unwrap(), w);
        }
        let w = Wavelengths::Bins(vec![400.0, 420.0, 500.0]);
        assert_eq!(w.centres(), vec![410.0, 460.0]);
        assert_eq!(w.band(1), (420.0, 500.0));
        let m = Wavelengths::Monochromatic(vec![633.0]);
        assert_eq!((m.centres(), m.band(0)), (vec![633.0], (633.0, 633.0)));
    }

    /// A file's sampling meets the parser's rules: bad values are refused by name.
    #[test]
    fn senseless_stored_samplings_are_refused() {
        let bad = |mode: &str, values: &str| {
            toml::from_str::<Wavelengths>(&format!("mode = \"{mode}\"\nvalues_nm = [{values}]"))
                .unwrap_err()
                .to_string()
        };
        assert!(bad("bins", "500.0, 400.0").contains("must increase"));
        assert!(bad("bins", "500.0").contains("at least two edges"));
        assert!(bad("bins", "0.0, 400.0").contains("positive"));
        assert!(bad("monochromatic", "").contains("no wavelengths"));
        assert!(bad("sideways", "500.0").contains("unknown variant"));
    }
}
