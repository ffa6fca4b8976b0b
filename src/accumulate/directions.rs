//! A `.gsa`'s incident directions: each one's polar angle and azimuth, finding one, taking
//! one out, and putting runs together, either more trees at the same directions (other
//! seeds: [`Accumulator::merge`] adds them) or other directions of the same material
//! (other angles or azimuths: it joins them, so that runs at `--phi-i 0` and `--phi-i 90`
//! make one anisotropic material).

use super::file::{Accumulator, FileError, NotSimulated, Settings};

/// Two azimuths or polar angles, degrees, closer than this name the same direction.
const SAME_DEG: f64 = 1e-9;

impl Settings {
    /// Direction `i`'s azimuth, degrees.
    pub fn phi_of(&self, i: usize) -> f64 {
        self.phi_i_each_deg
            .get(i)
            .copied()
            .unwrap_or(self.phi_i_deg)
    }

    /// The distinct azimuths, degrees, in the order the directions first take them.
    pub fn azimuths(&self) -> Vec<f64> {
        let mut out: Vec<f64> = Vec::new();
        for i in 0..self.theta_i_deg.len() {
            let p = self.phi_of(i);
            if !out.iter().any(|q| (q - p).abs() < SAME_DEG) {
                out.push(p);
            }
        }
        out
    }

    /// The settings with the fields that say which directions were run (polar angles,
    /// azimuths, auto's methods, a batch unit's offset, what the rigorous solver spent)
    /// cleared: two runs whose cleared settings agree are the same material at other
    /// directions.
    fn material(&self) -> Settings {
        Settings {
            theta_i_deg: Vec::new(),
            phi_i_deg: 0.0,
            phi_i_each_deg: Vec::new(),
            methods: Vec::new(),
            first_direction: 0,
            rigorous: None,
            ..self.clone()
        }
    }
}

impl Accumulator {
    /// The index of the simulated incident direction (`theta_i_deg`, `phi_i_deg`); without
    /// an azimuth, the first simulated azimuth's.
    pub fn direction_of(
        &self,
        theta_i_deg: f64,
        phi_i_deg: Option<f64>,
    ) -> Result<usize, NotSimulated> {
        let s = &self.header.settings;
        let phi = phi_i_deg.unwrap_or(s.phi_i_deg);
        let azimuths = s.azimuths();
        if !azimuths.iter().any(|p| (p - phi).abs() < SAME_DEG) {
            return Err(NotSimulated::Azimuth {
                asked_deg: phi,
                simulated_deg: azimuths,
            });
        }
        (0..s.theta_i_deg.len())
            .find(|&i| {
                (s.theta_i_deg[i] - theta_i_deg).abs() < SAME_DEG
                    && (s.phi_of(i) - phi).abs() < SAME_DEG
            })
            .ok_or_else(|| NotSimulated::Polar {
                asked_deg: theta_i_deg,
                simulated_deg: (0..s.theta_i_deg.len())
                    .filter(|&i| (s.phi_of(i) - phi).abs() < SAME_DEG)
                    .map(|i| s.theta_i_deg[i])
                    .collect(),
            })
    }

    /// Direction `i` alone, as a run of that one direction would have it (its angles,
    /// trees, methods and cells; the rest of the header as it is).
    pub fn direction(&self, i: usize) -> Accumulator {
        let nl = self.header.settings.wavelength_count();
        let mut header = self.header.clone();
        let s = &mut header.settings;
        s.phi_i_deg = self.header.settings.phi_of(i);
        s.phi_i_each_deg = Vec::new();
        s.theta_i_deg = s.theta_i_deg.get(i).copied().into_iter().collect();
        s.methods = s.methods.get(i).cloned().into_iter().collect();
        header.rays_per_direction = self
            .header
            .rays_per_direction
            .get(i)
            .copied()
            .into_iter()
            .collect();
        header.rays = header.rays_per_direction.first().copied().unwrap_or(0);
        Accumulator {
            header,
            cells: self.cells.get(i * nl..(i + 1) * nl).unwrap_or(&[]).to_vec(),
        }
    }

    /// The directions lit from azimuth `phi_deg` (one of the run's), as a run of that
    /// azimuth alone would hold them (their angles, trees, methods and cells).
    pub fn at_azimuth(&self, phi_deg: f64) -> Accumulator {
        let s = &self.header.settings;
        let nl = s.wavelength_count();
        let keep: Vec<usize> = (0..s.theta_i_deg.len())
            .filter(|&i| (s.phi_of(i) - phi_deg).abs() < SAME_DEG)
            .collect();
        let mut header = self.header.clone();
        let h = &mut header.settings;
        h.theta_i_deg = keep.iter().map(|&i| s.theta_i_deg[i]).collect();
        h.methods = keep
            .iter()
            .filter_map(|&i| s.methods.get(i).cloned())
            .collect();
        h.phi_i_deg = phi_deg;
        h.phi_i_each_deg = Vec::new();
        header.rays_per_direction = keep
            .iter()
            .filter_map(|&i| self.header.rays_per_direction.get(i).copied())
            .collect();
        header.rays = header.rays_per_direction.iter().copied().max().unwrap_or(0);
        Accumulator {
            header,
            cells: keep
                .iter()
                .flat_map(|&i| self.cells[i * nl..(i + 1) * nl].iter().cloned())
                .collect(),
        }
    }

    /// Puts another run of the same sample together with this one: at the same directions
    /// and settings with other seeds, its trees are added; at other directions (polar
    /// angles or azimuths) with the same settings and seeds, its directions are appended
    /// after these. Anything else is refused, naming what differs.
    pub fn merge(&mut self, other: &Accumulator) -> Result<(), FileError> {
        let (a, b) = (&self.header.settings, &other.header.settings);
        if a.sample_hash != b.sample_hash {
            return Err(FileError::Merge(format!(
                "different samples ('{}' {} and '{}' {})",
                a.sample_name, a.sample_hash, b.sample_name, b.sample_hash
            )));
        }
        if a == b {
            return self.add(other);
        }
        let same_directions = a.theta_i_deg == b.theta_i_deg
            && (0..a.theta_i_deg.len()).all(|i| a.phi_of(i) == b.phi_of(i));
        if same_directions || a.material() != b.material() {
            let (x, y) = if same_directions {
                (a.clone(), b.clone())
            } else {
                (a.material(), b.material())
            };
            return Err(FileError::Merge(format!(
                "the runs differ in settings that change results:\n{}",
                differences(&x, &y)
            )));
        }
        self.join(other)
    }

    /// Adds the trees of another run at the same directions and settings (other seeds).
    fn add(&mut self, other: &Accumulator) -> Result<(), FileError> {
        if let Some(s) = other
            .header
            .seeds
            .iter()
            .find(|s| self.header.seeds.contains(s))
        {
            return Err(FileError::Merge(format!(
                "both runs used seed {s}: merging them would count the same trees twice"
            )));
        }
        for (x, y) in self.cells.iter_mut().zip(&other.cells) {
            x.merge(y);
        }
        self.header.seeds.extend_from_slice(&other.header.seeds);
        for (x, y) in self
            .header
            .rays_per_direction
            .iter_mut()
            .zip(&other.header.rays_per_direction)
        {
            *x = x
                .checked_add(*y)
                .ok_or_else(|| FileError::Merge("ray counts overflow".into()))?;
        }
        self.header.rays_asked = match (self.header.rays_asked, other.header.rays_asked) {
            (Some(a), Some(b)) => Some(
                a.checked_add(b)
                    .ok_or_else(|| FileError::Merge("ray counts overflow".into()))?,
            ),
            _ => None,
        };
        self.absorb_header(other);
        Ok(())
    }

    /// Appends the directions of another run of the same material, settings and seeds.
    fn join(&mut self, other: &Accumulator) -> Result<(), FileError> {
        let (a, b) = (&self.header.settings, &other.header.settings);
        if self.header.seeds != other.header.seeds {
            return Err(FileError::Merge(format!(
                "the runs are at different directions but from different seeds ({:?} and {:?}): directions are joined only from runs of the same seeds, so that the joined file is one set of runs (merge each direction's seeds first)",
                self.header.seeds, other.header.seeds
            )));
        }
        for j in 0..b.theta_i_deg.len() {
            let (t, p) = (b.theta_i_deg[j], b.phi_of(j));
            let twice = (0..a.theta_i_deg.len()).any(|i| {
                (a.theta_i_deg[i] - t).abs() < SAME_DEG
                    && ((a.phi_of(i) - p).rem_euclid(360.0) < SAME_DEG
                        || (a.phi_of(i) - p).rem_euclid(360.0) > 360.0 - SAME_DEG)
            });
            if twice {
                return Err(FileError::Merge(format!(
                    "both runs hold the direction theta_i {t} deg, phi_i {p} deg with the same seeds {:?}: the same trees would be counted twice",
                    self.header.seeds
                )));
            }
        }
        if let (Some(x), Some(y)) = (&a.rigorous, &b.rigorous)
            && x != y
        {
            return Err(FileError::Merge(
                "the runs' rigorous solver took different efforts (orders, slices or tolerance)"
                    .into(),
            ));
        }
        let n = a.theta_i_deg.len() + b.theta_i_deg.len();
        let phis: Vec<f64> = (0..a.theta_i_deg.len())
            .map(|i| a.phi_of(i))
            .chain((0..b.theta_i_deg.len()).map(|j| b.phi_of(j)))
            .collect();
        let s = &mut self.header.settings;
        let rigorous = s.rigorous.or(b.rigorous);
        s.rigorous = rigorous;
        s.theta_i_deg.extend_from_slice(&b.theta_i_deg);
        s.methods.extend(b.methods.iter().cloned());
        s.first_direction = s.first_direction.min(b.first_direction);
        s.phi_i_each_deg = if phis.iter().all(|p| (p - phis[0]).abs() < SAME_DEG) {
            Vec::new()
        } else {
            phis
        };
        debug_assert!(s.phi_i_each_deg.is_empty() || s.phi_i_each_deg.len() == n);
        self.cells.extend(other.cells.iter().cloned());
        self.header
            .rays_per_direction
            .extend_from_slice(&other.header.rays_per_direction);
        if self.header.rays_asked != other.header.rays_asked {
            self.header.rays_asked = None;
        }
        self.absorb_header(other);
        Ok(())
    }

    /// What any put-together run takes from both: the largest tree count, leaks, replicate
    /// groups, balance, warnings (each once) and the backends.
    fn absorb_header(&mut self, other: &Accumulator) {
        let h = &mut self.header;
        h.rays = h.rays_per_direction.iter().copied().max().unwrap_or(0);
        h.error_groups = h.error_groups.max(other.header.error_groups);
        h.balanced &= other.header.balanced;
        h.leaks += other.header.leaks;
        for w in &other.header.warnings {
            if !h.warnings.contains(w) {
                h.warnings.push(w.clone());
            }
        }
        if h.backend != other.header.backend {
            h.backend = format!("{}+{}", h.backend, other.header.backend);
        }
    }
}

/// The settings that differ, one per line, as the files record them.
fn differences(a: &Settings, b: &Settings) -> String {
    let (ta, tb) = (
        toml::Table::try_from(a).unwrap_or_default(),
        toml::Table::try_from(b).unwrap_or_default(),
    );
    let mut keys: Vec<&String> = ta.keys().chain(tb.keys()).collect();
    keys.sort();
    keys.dedup();
    let show =
        |t: &toml::Table, k: &str| t.get(k).map_or("(absent)".to_string(), |v| v.to_string());
    keys.into_iter()
        .filter(|k| ta.get(*k) != tb.get(*k))
        .map(|k| format!("  {k}: {} against {}", show(&ta, k), show(&tb, k)))
        .collect::<Vec<_>>()
        .join("\n")
}
