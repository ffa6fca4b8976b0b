//! A material's units assembled into the accumulator its whole run would have written.

use std::path::Path;

use super::{BatchError, Manifest, Unit};
use crate::accumulate::file::Accumulator;

impl Manifest {
    /// Assembles one material's units into its whole-run accumulator; refuses, naming
    /// them, units that are missing, corrupt or from another plan.
    pub fn merge_material(&self, dir: &Path, name: &str) -> Result<Accumulator, BatchError> {
        let units: Vec<&Unit> = self.units.iter().filter(|u| u.material == name).collect();
        // Each unit is read once: checked, then assembled.
        let mut parts = Vec::with_capacity(units.len());
        let mut problems = Vec::new();
        for u in &units {
            match self.read_unit(dir, u) {
                Ok(acc) => parts.push(acc),
                Err(why) => problems.push(format!("unit {} ({}): {why}", u.id, u.output.display())),
            }
        }
        if !problems.is_empty() {
            return Err(BatchError::NotDone {
                material: name.to_string(),
                total: units.len(),
                problems,
            });
        }
        let m = self.material(name);
        let first = &parts[0].header;
        if parts.iter().any(|p| p.header.backend != first.backend) {
            return Err(BatchError::from(format!(
                "material '{name}': its units were traced with different backends"
            )));
        }
        let mut header = first.clone();
        let (theta, phi, each) =
            crate::simulate::directions::expand(&m.settings.theta_i_deg, &m.settings.phi_i_deg);
        header.settings.theta_i_deg = theta;
        header.settings.phi_i_deg = phi;
        header.settings.phi_i_each_deg = each;
        header.settings.first_direction = 0;
        // An auto run's methods, direction by direction (each unit holds one).
        header.settings.methods = parts
            .iter()
            .flat_map(|p| p.header.settings.methods.clone())
            .collect();
        header.rays_per_direction = parts
            .iter()
            .flat_map(|p| p.header.rays_per_direction.clone())
            .collect();
        header.rays = header.rays_per_direction.iter().copied().max().unwrap_or(0);
        header.leaks = parts.iter().map(|p| p.header.leaks).sum();
        // Each unit's warnings, in direction order, each sentence once (as one run keeps
        // them: `simulate::stored_warnings`).
        header.warnings = Vec::new();
        for w in parts.iter().flat_map(|p| &p.header.warnings) {
            if !header.warnings.contains(w) {
                header.warnings.push(w.clone());
            }
        }
        let cells = parts.into_iter().flat_map(|p| p.cells).collect();
        Ok(Accumulator { header, cells })
    }
}
