//! The wavelength sampling of a run: bins (edges, each tree jittered inside) or exact
//! wavelengths. At the bottom of the house: the optics, the tracer, the run and the file
//! formats all use it, and it uses nothing of theirs.

/// The default sampling: the visible, 380 to 780 nm in 10 nm bins.
pub const DEFAULT_WAVELENGTHS: &str = "380:780:10";

/// Wavelength sampling.
#[derive(Clone, Debug, PartialEq)]
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
        if monochromatic {
            Ok(Wavelengths::Monochromatic(values))
        } else if values.len() < 2 {
            Err(E::TooFewEdges)
        } else if values.windows(2).any(|p| p[1] <= p[0]) {
            Err(E::NotIncreasing)
        } else {
            Ok(Wavelengths::Bins(values))
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
