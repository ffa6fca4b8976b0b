//! Where `--coherence auto` recorded each cell's method (`Settings::methods`): the method
//! of one cell, the counts, and one direction's methods as wavelength ranges.

use super::Coherence;
use super::file::{Settings, WavelengthMode};

impl Settings {
    /// The method that gave the buckets of cell (direction `i`, wavelength `j`):
    /// `Beamlet` or `Diffraction` for an auto run ([`Settings::methods`]), the run's mode
    /// otherwise.
    pub fn cell_mode(&self, i: usize, j: usize) -> Coherence {
        if self.coherence != Coherence::Auto {
            return self.coherence;
        }
        match self.methods.get(i).and_then(|m| m.as_bytes().get(j)) {
            Some(b'd') => Coherence::Diffraction,
            Some(b'm') => Coherence::Rigorous,
            _ => Coherence::Beamlet,
        }
    }
    /// Direction `i`'s methods as wavelength ranges ("rays 380-500 nm, diffraction
    /// 500-780 nm"), each range from its first cell's lower edge to its last cell's upper
    /// edge (bins) or its first to last wavelength (monochromatic).
    pub fn methods_of(&self, i: usize) -> String {
        let nl = self.wavelength_count();
        let name = |j: usize| match self.cell_mode(i, j) {
            Coherence::Diffraction => "diffraction",
            Coherence::Rigorous => "rigorous",
            _ => "rays",
        };
        let bins = self.wavelength_mode == WavelengthMode::Bins;
        let edges = |j: usize| -> (f64, f64) {
            if bins {
                (self.wavelengths_nm[j], self.wavelengths_nm[j + 1])
            } else {
                (self.wavelengths_nm[j], self.wavelengths_nm[j])
            }
        };
        let mut parts = Vec::new();
        let mut start = 0;
        for j in 1..=nl {
            if j == nl || name(j) != name(start) {
                parts.push(format!(
                    "{} {}-{} nm",
                    name(start),
                    edges(start).0,
                    edges(j - 1).1
                ));
                start = j;
            }
        }
        parts.join(", ")
    }
    /// How many cells the rigorous solver gave.
    pub fn rigorous_cells(&self) -> usize {
        match self.coherence {
            Coherence::Auto => self
                .methods
                .iter()
                .map(|m| m.bytes().filter(|&b| b == b'm').count())
                .sum(),
            Coherence::Rigorous => self.theta_i_deg.len() * self.wavelength_count(),
            _ => 0,
        }
    }
    /// How many cells rays and the diffraction method each gave, `(rays, diffraction)`
    /// (all of one kind for a run that is not auto; [`Settings::rigorous_cells`] apart).
    pub fn method_counts(&self) -> (usize, usize) {
        let cells = self.theta_i_deg.len() * self.wavelength_count();
        match self.coherence {
            Coherence::Auto => {
                let d: usize = self
                    .methods
                    .iter()
                    .map(|m| m.bytes().filter(|&b| b == b'd').count())
                    .sum();
                (cells - (d + self.rigorous_cells()).min(cells), d)
            }
            Coherence::Diffraction => (0, cells),
            Coherence::Rigorous => (0, 0),
            _ => (cells, 0),
        }
    }
}
