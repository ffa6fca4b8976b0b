//! Batch BRDF generation: a plan of many materials split into deterministic work units
//! (one material at one incident direction), run in shards by Slurm job arrays or GNU
//! parallel, resumable, and merged bit for bit.
//!
//! A unit simulates one incident direction with the random streams that direction has in
//! the material's whole run (`SimConfig::first_direction`), so the merged accumulator —
//! the units' cells side by side, the header rebuilt from the plan — is byte-identical to
//! `goniospec simulate` of the whole direction list, whatever the shard count and the
//! order the shards finished in.
//!
//! Layout of a batch folder:
//!
//! ```text
//! DIR/manifest.toml              the resolved plan, its hash and the units
//! DIR/units/MATERIAL/NNN.gsa     one accumulator per unit, written atomically
//! DIR/out/MATERIAL.gsa           merged accumulators
//! DIR/out/MATERIAL-REPR.gsb      the representations the plan asks for
//! DIR/report/index.html          `batch report`: a page to choose materials by ([`report`])
//! ```

mod assemble;
pub mod report;

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::accumulate::file::Accumulator;
use crate::sample::{self, MeshOptions};
use crate::simulate::{SimConfig, SimSettings, sample_hash};

/// What stops a batch: a plan that cannot run, a manifest edited after `batch plan`, a
/// unit that is not done or failed, files that cannot be read or written. Front ends turn
/// it into a message and exit status 1.
#[derive(Debug, thiserror::Error)]
pub enum BatchError {
    /// The plan (or a launcher's settings) cannot run: the message names the file and the
    /// material at fault.
    #[error("{0}")]
    Plan(String),
    /// The manifest is not as `goniospec batch plan` wrote it.
    #[error(
        "{path}: {why}; the manifest was edited after `goniospec batch plan` wrote it: plan again"
    )]
    Edited { path: PathBuf, why: String },
    /// A shard outside `1 <= I <= N`.
    #[error("shard {i}/{n}: need 1 <= I <= N")]
    Shard { i: usize, n: usize },
    /// A unit's output is not a finished unit of this plan.
    #[error(transparent)]
    Unit(#[from] UnitProblem),
    /// A unit's simulation failed.
    #[error("unit {id} ({material} at {theta_i_deg} deg): {source}")]
    Simulation {
        id: usize,
        material: String,
        theta_i_deg: f64,
        #[source]
        source: crate::simulate::SimError,
    },
    /// Units of a material are not done, each named with why.
    #[error("material '{material}': {} of {total} units are not done:\n  {}", problems.len(), problems.join("\n  "))]
    NotDone {
        material: String,
        total: usize,
        problems: Vec<String>,
    },
    /// A batch file or folder could not be read or written.
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
}

impl From<String> for BatchError {
    fn from(message: String) -> Self {
        BatchError::Plan(message)
    }
}

/// Why a unit's output is not a finished unit of its plan (`batch status` lists these).
#[derive(Debug, thiserror::Error)]
pub enum UnitProblem {
    #[error("missing")]
    Missing,
    /// `batch run` ran it and the simulation refused it (the reason, as `simulate` gave it,
    /// is kept beside the unit: [`Unit::failure_path`]).
    #[error("refused by the simulation: {0}")]
    Refused(String),
    #[error("unreadable: {0}")]
    Unreadable(crate::container::FileError),
    #[error("from another plan or sample (its header does not match the unit)")]
    Foreign,
}

/// A plan as written: `[defaults]` and a list of `[[material]]` tables. Each material's
/// keys override the defaults'; besides `sample`, `name` and `representations` they are
/// the settings of `goniospec simulate` ([`SimSettings`], keys of the flags' names), with
/// its defaults where neither gives them.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPlan {
    #[serde(default)]
    defaults: toml::Table,
    #[serde(rename = "material")]
    materials: Vec<toml::Table>,
}

/// The representations a material gets when the plan names none.
const DEFAULT_REPRESENTATIONS: &[&str] = &["table"];

/// One material of a resolved plan.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Material {
    pub name: String,
    /// Absolute path of the sample TOML.
    pub sample: PathBuf,
    pub sample_hash: String,
    pub representations: Vec<crate::brdf::Kind>,
    /// Every setting of the material's simulation, resolved (defaults filled in).
    pub settings: SimSettings,
}

/// One work unit: a material at one incident direction.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Unit {
    pub id: usize,
    pub material: String,
    /// The direction's index in the material's list.
    pub direction: usize,
    pub theta_i_deg: f64,
    /// The direction's azimuth, degrees, where the material has several.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub phi_i_deg: Option<f64>,
    /// Output, relative to the batch folder.
    pub output: PathBuf,
}

impl Unit {
    /// Where `batch run` keeps a copy of the unit's warnings for reading (one a line;
    /// absent where it had none), relative to the batch folder. The commands read them from
    /// the unit's accumulator ([`Manifest::unit_warnings`]).
    pub fn log_path(&self) -> PathBuf {
        self.output.with_extension("warnings")
    }

    /// Where `batch run` keeps why the simulation refused the unit, relative to the batch
    /// folder (absent where it ran).
    pub fn failure_path(&self) -> PathBuf {
        self.output.with_extension("refused")
    }
}

/// The manifest `plan` writes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    /// FNV-1a of the resolved materials: units of another plan are refused at merge.
    pub plan_hash: String,
    #[serde(rename = "material")]
    pub materials: Vec<Material>,
    #[serde(rename = "unit")]
    pub units: Vec<Unit>,
}

/// The most units a plan may hold.
pub const MAX_UNITS: usize = 1_000_000;

/// The longest material name: it names files (`NAME-subdivided.gsb`, `NAME-sphere.png`,
/// `NAME.warnings`) that most file systems limit to 255 bytes.
pub const MAX_NAME: usize = 200;

/// A material's name names files and folders: letters, digits, '-', '_' or '.', not
/// starting with '.' or '-', at most [`MAX_NAME`] characters.
fn check_name(name: &str) -> Result<(), BatchError> {
    if name.len() > MAX_NAME {
        return Err(BatchError::from(format!(
            "name '{}...' is {} characters: at most {MAX_NAME}, as it names files ('NAME-kdtree.gsb', 'NAME-sphere.png') that most file systems limit to 255 bytes",
            &name[..name.char_indices().nth(40).map_or(name.len(), |(i, _)| i)],
            name.len()
        )));
    }
    if name.is_empty()
        || !name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c))
    {
        return Err(BatchError::from(format!(
            "name '{name}' must be letters, digits, '-', '_' or '.' (it names files)"
        )));
    }
    if let Some(c) = name.chars().next().filter(|c| ".-".contains(*c)) {
        return Err(BatchError::from(format!(
            "name '{name}' must not start with '{c}' (it names files: a leading '.' hides them, a leading '-' makes commands read them as options)"
        )));
    }
    Ok(())
}

/// FNV-1a of the resolved materials, as the manifest records it.
fn plan_hash(materials: &[Material]) -> Result<String, BatchError> {
    let canonical = serde_json::to_string(materials).map_err(|e| e.to_string())?;
    Ok(format!("{:016x}", crate::io::fnv1a(canonical.as_bytes())))
}

/// The units the materials expand to: each material at each of its directions, in order,
/// each writing `units/MATERIAL/NNNN.gsa` inside the batch folder.
fn units_of(materials: &[Material]) -> Result<Vec<Unit>, BatchError> {
    let mut units = Vec::new();
    for m in materials {
        if m.settings.theta_i_deg.is_empty() {
            return Err(BatchError::from(format!(
                "material '{}' has no incident angle",
                m.name
            )));
        }
        let (theta, _, each) =
            crate::simulate::directions::expand(&m.settings.theta_i_deg, &m.settings.phi_i_deg);
        for (k, &t) in theta.iter().enumerate() {
            units.push(Unit {
                id: units.len(),
                material: m.name.clone(),
                direction: k,
                theta_i_deg: t,
                phi_i_deg: each.get(k).copied(),
                output: PathBuf::from("units")
                    .join(&m.name)
                    .join(format!("{k:04}.gsa")),
            });
            if units.len() > MAX_UNITS {
                return Err(BatchError::from(format!(
                    "the plan expands to more than {MAX_UNITS} units"
                )));
            }
        }
    }
    Ok(units)
}

impl Manifest {
    /// Reads and resolves a plan: every sample is loaded now (a bad sample fails here, not
    /// hours later on a node), every setting checked as `simulate` checks it.
    pub fn plan(plan_path: &Path) -> Result<Manifest, BatchError> {
        let text =
            crate::io::read_text(plan_path).map_err(|e| format!("{}: {e}", plan_path.display()))?;
        Self::plan_text(plan_path, &text)
    }

    /// [`Manifest::plan`] of a plan's text (`plan_path` resolves its samples and names it
    /// in errors).
    pub fn plan_text(plan_path: &Path, text: &str) -> Result<Manifest, BatchError> {
        let raw: RawPlan = toml::from_str(text)
            .map_err(|e| format!("{}: {}", plan_path.display(), e.message().trim()))?;
        if raw.materials.is_empty() {
            return Err(BatchError::from(format!(
                "{}: the plan lists no [[material]]",
                plan_path.display()
            )));
        }
        let base = plan_path.parent().unwrap_or(Path::new("."));
        let mut materials = Vec::new();
        for (i, own) in raw.materials.iter().enumerate() {
            let shown = own
                .get("sample")
                .and_then(|v| v.as_str())
                .unwrap_or("no sample");
            let at = |msg: String| {
                format!(
                    "{}: material {} ({shown}): {msg}",
                    plan_path.display(),
                    i + 1,
                )
            };
            // The material's keys over the defaults'.
            let mut merged = raw.defaults.clone();
            merged.extend(own.clone());
            let take_str = |t: &mut toml::Table, key: &str| -> Result<Option<String>, String> {
                match t.remove(key) {
                    None => Ok(None),
                    Some(toml::Value::String(s)) => Ok(Some(s)),
                    Some(v) => Err(at(format!("{key} must be a string, got {v}"))),
                }
            };
            if raw.defaults.contains_key("sample") || raw.defaults.contains_key("name") {
                return Err(BatchError::from(at(
                    "sample and name belong to a [[material]], not to [defaults]".into(),
                )));
            }
            let sample_key = take_str(&mut merged, "sample")?
                .ok_or_else(|| at("no sample (give its TOML path)".into()))?;
            let name = take_str(&mut merged, "name")?;
            let representations = match merged.remove("representations") {
                None => DEFAULT_REPRESENTATIONS
                    .iter()
                    .map(|s| s.to_string())
                    .collect(),
                Some(v) => Vec::<String>::deserialize(v)
                    .map_err(|e| at(format!("representations: {}", e.message())))?,
            }
            .iter()
            .map(|r| crate::brdf::Kind::parse(r))
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| at(e.to_string()))?;
            let settings = SimSettings::deserialize(toml::Value::Table(merged))
                .map_err(|e| at(e.message().trim().to_string()))?;
            // Checked as `simulate` checks them.
            settings.resolve().map_err(|e| at(e.to_string()))?;
            let path = base.join(&sample_key);
            let path = std::fs::canonicalize(&path).map_err(|e| at(format!("{e}")))?;
            if path.to_str().is_none() {
                return Err(BatchError::from(at(format!(
                    "{}: the sample's path is not valid UTF-8, which the manifest (TOML) cannot hold; rename its folder",
                    path.to_string_lossy()
                ))));
            }
            let sample =
                sample::load(&path, MeshOptions::default()).map_err(|e| at(e.to_string()))?;
            // Refused now what every unit would refuse on a node (issue 47), in simulate's
            // words; and what only a batch cannot hold.
            if let Some(key) = [
                ("tolerance", settings.tolerance),
                ("target_stderr", settings.target_stderr),
            ]
            .into_iter()
            .find_map(|(k, v)| v.map(|_| k))
            {
                return Err(BatchError::from(at(format!(
                    "{key} makes each direction's number of trees adaptive, which a batch's units cannot be checked and merged by: give a fixed rays (and split the spectrum or angles into more units for more trees; goniospec bench converge says how many trees a sample needs for a target)"
                ))));
            }
            let whole = settings.resolve().map_err(|e| at(e.to_string()))?;
            crate::simulate::preflight(&sample, &whole).map_err(|e| at(e.to_string()))?;
            let name = match name {
                Some(n) => n,
                None => path
                    .file_stem()
                    .unwrap_or_default()
                    .to_string_lossy()
                    .into_owned(),
            };
            check_name(&name).map_err(|e| at(e.to_string()))?;
            if materials.iter().any(|x: &Material| x.name == name) {
                return Err(BatchError::from(at(format!(
                    "two materials are named '{name}'; give them distinct names"
                ))));
            }
            materials.push(Material {
                name,
                sample: path,
                sample_hash: sample_hash(&sample),
                representations,
                settings,
            });
        }
        let units = units_of(&materials)?;
        Ok(Manifest {
            plan_hash: plan_hash(&materials)?,
            materials,
            units,
        })
    }

    /// Reads `DIR/manifest.toml` and checks that it is as `plan` wrote it: its materials
    /// hash to its plan hash, their names are file-safe, and its units are exactly the ones
    /// its materials expand to (so every unit names a material of the manifest, at the
    /// angle of its direction, with its output inside the batch folder). An edited manifest
    /// would otherwise file a unit's data under another angle, write an empty accumulator,
    /// or send a unit's output over the manifest itself.
    pub fn read(dir: &Path) -> Result<Manifest, BatchError> {
        let p = dir.join("manifest.toml");
        let text = crate::io::read_text(&p)
            .map_err(|e| format!("{}: {e} (run `goniospec batch plan` first)", p.display()))?;
        Self::from_text(&p, &text)
    }

    /// [`Manifest::read`] of a manifest's text (`p` names it in errors).
    pub fn from_text(p: &Path, text: &str) -> Result<Manifest, BatchError> {
        let m: Manifest =
            toml::from_str(text).map_err(|e| format!("{}: {}", p.display(), e.message().trim()))?;
        let edited = |why: String| BatchError::Edited {
            path: p.to_path_buf(),
            why,
        };
        for mat in &m.materials {
            check_name(&mat.name).map_err(|e| edited(e.to_string()))?;
        }
        if plan_hash(&m.materials)? != m.plan_hash {
            return Err(edited(
                "its materials do not match its plan hash".to_string(),
            ));
        }
        if units_of(&m.materials)? != m.units {
            return Err(edited(
                "its units are not the ones its materials expand to".to_string(),
            ));
        }
        Ok(m)
    }

    /// Writes `DIR/manifest.toml` atomically (making DIR).
    pub fn write(&self, dir: &Path) -> Result<(), BatchError> {
        let io = |source| BatchError::Io {
            path: dir.to_path_buf(),
            source,
        };
        std::fs::create_dir_all(dir).map_err(io)?;
        let text = toml::to_string(self).map_err(|e| BatchError::Plan(e.to_string()))?;
        crate::io::write_atomic(&dir.join("manifest.toml"), |w| w.write_all(text.as_bytes()))
            .map_err(io)
    }

    pub fn material(&self, name: &str) -> &Material {
        self.materials
            .iter()
            .find(|m| m.name == name)
            .expect("units name materials of the manifest")
    }

    /// The units of shard `i` of `n` (1-based): every `n`-th unit from the `i`-th.
    pub fn shard(&self, i: usize, n: usize) -> Result<Vec<&Unit>, BatchError> {
        if n == 0 || i == 0 || i > n {
            return Err(BatchError::Shard { i, n });
        }
        Ok(self.units.iter().filter(|u| u.id % n == i - 1).collect())
    }

    /// The simulation of a unit.
    pub fn unit_config(&self, u: &Unit) -> Result<SimConfig, BatchError> {
        let m = self.material(&u.material);
        let whole = m.settings.resolve().map_err(|e| e.to_string())?;
        Ok(SimConfig {
            theta_i_deg: vec![u.theta_i_deg],
            phi_i_deg: u.phi_i_deg.unwrap_or(whole.phi_i_deg),
            phi_each_deg: Vec::new(),
            first_direction: u.direction as u64,
            // A raise is the whole run's, which its units could not merge into.
            raise_trees: false,
            ..whole
        })
    }

    /// Why a unit's output is not a finished unit of this plan, or `None` when it is.
    pub fn verify(&self, dir: &Path, u: &Unit) -> Option<UnitProblem> {
        self.read_unit(dir, u).err()
    }

    /// A unit's accumulator, read once and checked to be this unit's ("missing" when
    /// absent; otherwise why it is not).
    pub fn read_unit(&self, dir: &Path, u: &Unit) -> Result<Accumulator, UnitProblem> {
        let p = dir.join(&u.output);
        if !p.exists() {
            let refused = dir.join(u.failure_path());
            if let Ok(why) = std::fs::read_to_string(&refused) {
                return Err(UnitProblem::Refused(why.trim().to_string()));
            }
            return Err(UnitProblem::Missing);
        }
        let acc = Accumulator::read(&p).map_err(UnitProblem::Unreadable)?;
        let m = self.material(&u.material);
        let s = &acc.header.settings;
        if s.sample_hash != m.sample_hash
            || s.theta_i_deg != [u.theta_i_deg]
            || u.phi_i_deg.is_some_and(|p| s.phi_of(0) != p)
            || s.first_direction != u.direction as u64
            || acc.header.seeds != [m.settings.seed]
            || !match acc.header.rays_asked {
                // The diffraction method traced its lattice's count.
                Some(asked) => asked == m.settings.rays,
                None => acc.header.rays_per_direction == [m.settings.rays],
            }
        {
            return Err(UnitProblem::Foreign);
        }
        Ok(acc)
    }

    /// Runs one unit and writes its output atomically, with its warnings (the sample's
    /// validity findings for the unit's settings and the run's own, as `simulate` prints
    /// them) beside it ([`Unit::log_path`]), which it also returns. A simulation that
    /// refuses the unit leaves its reason beside it ([`Unit::failure_path`]), so `status`,
    /// `merge` and `report` can name it, and is returned as the error.
    pub fn run_unit(
        &self,
        dir: &Path,
        u: &Unit,
        sample: &crate::sample::Sample,
    ) -> Result<Vec<String>, BatchError> {
        let cfg = self.unit_config(u)?;
        let p = dir.join(&u.output);
        if let Some(parent) = p.parent() {
            std::fs::create_dir_all(parent).map_err(|source| BatchError::Io {
                path: parent.to_path_buf(),
                source,
            })?;
        }
        let write = |rel: PathBuf, text: String| {
            let q = dir.join(rel);
            crate::io::write_atomic(&q, |w| w.write_all(text.as_bytes()))
                .map_err(|source| BatchError::Io { path: q, source })
        };
        let remove = |rel: PathBuf| {
            let q = dir.join(rel);
            match std::fs::remove_file(&q) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                    Err(BatchError::Io { path: q, source: e })
                }
                _ => Ok(()),
            }
        };
        let (acc, _) = match crate::simulate::simulate(sample, &cfg, &|_| {}) {
            Ok(r) => r,
            Err(source) => {
                write(u.failure_path(), format!("{source}\n"))?;
                return Err(BatchError::Simulation {
                    id: u.id,
                    material: u.material.clone(),
                    theta_i_deg: u.theta_i_deg,
                    source,
                });
            }
        };
        // The warnings are the ones the run stored in its checksummed accumulator (the
        // validity findings and the run's own: `simulate::stored_warnings`), which
        // `status`, `merge` and `report` read from it ([`Manifest::unit_warnings`]); the
        // text file beside it is a copy for reading, which no command trusts.
        let warnings = acc.header.warnings.clone();
        if warnings.is_empty() {
            remove(u.log_path())?;
        } else {
            write(u.log_path(), warnings.join("\n") + "\n")?;
        }
        remove(u.failure_path())?;
        acc.write(&p)
            .map_err(|e| BatchError::Plan(format!("{}: {e}", p.display())))?;
        Ok(warnings)
    }

    /// A unit's warnings, from its verified accumulator ([`Manifest::read_unit`]: the
    /// checksummed `.gsa` of this plan's unit), not from the text copy beside it, which a
    /// hand can change or delete (none where the unit had none or is not done).
    pub fn unit_warnings(&self, dir: &Path, u: &Unit) -> Vec<String> {
        self.read_unit(dir, u)
            .map(|acc| acc.header.warnings)
            .unwrap_or_default()
    }

    /// `(done, missing, failed)` unit ids, the failed with their reason.
    pub fn status(&self, dir: &Path) -> (Vec<usize>, Vec<usize>, Vec<(usize, String)>) {
        let (mut done, mut missing, mut failed) = (Vec::new(), Vec::new(), Vec::new());
        for u in &self.units {
            match self.verify(dir, u) {
                None => done.push(u.id),
                Some(UnitProblem::Missing) => missing.push(u.id),
                Some(why) => failed.push((u.id, why.to_string())),
            }
        }
        (done, missing, failed)
    }
}

use std::io::Write as _;

/// The shard `(I, N)` from Slurm's array variables, when set (`SLURM_ARRAY_TASK_ID` of an
/// array `1-N`, and `SLURM_ARRAY_TASK_COUNT`).
pub fn shard_from_env() -> Option<Result<(usize, usize), BatchError>> {
    let id = std::env::var("SLURM_ARRAY_TASK_ID").ok()?;
    let count = std::env::var("SLURM_ARRAY_TASK_COUNT").ok();
    let parse = |v: &str, what: &str| {
        v.trim()
            .parse::<usize>()
            .map_err(|_| format!("{what} is not a number: '{v}'"))
    };
    Some(
        (|| {
            let i = parse(&id, "SLURM_ARRAY_TASK_ID")?;
            let n = parse(
                count
                    .as_deref()
                    .ok_or("SLURM_ARRAY_TASK_ID is set but SLURM_ARRAY_TASK_COUNT is not")?,
                "SLURM_ARRAY_TASK_COUNT",
            )?;
            Ok((i, n))
        })()
        .map_err(BatchError::Plan),
    )
}

/// `s` as one POSIX shell word: single-quoted, each `'` written as `'\''`. Everything
/// user-controlled that reaches a shell goes through it (a batch folder named
/// `inj$(touch INJECTED)x` ran `touch` when the Slurm script ran).
pub fn shell_quote(s: &str) -> String {
    format!("'{}'", s.replace('\'', "'\\''"))
}

/// A path as text for a script, or why it cannot be one.
fn script_path(p: &Path) -> Result<&str, BatchError> {
    p.to_str().ok_or_else(|| {
        BatchError::Plan(format!(
            "{}: the path is not valid UTF-8, which the Slurm and GNU parallel scripts cannot carry; rename the folder",
            p.to_string_lossy()
        ))
    })
}

/// The Slurm scripts of a batch: an array with one task per shard (at most `limit`
/// running), a merge job, and `submit.sh` chaining them with `--dependency=afterok`. The
/// folder and binary reach the shell quoted ([`shell_quote`]); the `#SBATCH` lines, which
/// Slurm reads without a shell, name only paths relative to the folder `submit.sh`
/// submits from.
pub fn slurm_scripts(
    dir: &Path,
    goniospec: &Path,
    shards: usize,
    limit: usize,
) -> Result<Vec<(PathBuf, String)>, BatchError> {
    let d = shell_quote(script_path(dir)?);
    let g = shell_quote(script_path(goniospec)?);
    let array = format!(
        "#!/bin/bash\n# goniospec batch: one array task per shard; each resumes where a previous run stopped.\n#SBATCH --job-name=goniospec-units\n#SBATCH --array=1-{shards}%{limit}\n#SBATCH --output=logs/units-%A_%a.out\nset -euo pipefail\nexec {g} batch run {d}\n"
    );
    let merge = format!(
        "#!/bin/bash\n# goniospec batch: merge the units and build the representations once every shard succeeded.\n#SBATCH --job-name=goniospec-merge\n#SBATCH --output=logs/merge-%j.out\nset -euo pipefail\nexec {g} batch merge {d}\n"
    );
    let submit = String::from(
        "#!/bin/bash\n# Submits the unit array, then the merge job to run after it succeeds (from this\n# folder, where the jobs' logs/ go).\nset -euo pipefail\ncd \"$(dirname \"$0\")\"\nmkdir -p logs\njid=$(sbatch --parsable units.sbatch)\nsbatch --parsable --dependency=afterok:${jid%%;*} merge.sbatch\n",
    );
    Ok(vec![
        (dir.join("units.sbatch"), array),
        (dir.join("merge.sbatch"), merge),
        (dir.join("submit.sh"), submit),
    ])
}

/// The GNU parallel command that runs every shard (`--joblog` and `--resume-failed`, so a
/// rerun repeats only the shards that failed). The paths are quoted for the shell the
/// command is typed into, and `-q` makes parallel quote them again for the shell it runs
/// each job in.
pub fn parallel_command(
    dir: &Path,
    goniospec: &Path,
    shards: usize,
    jobs: usize,
) -> Result<String, BatchError> {
    let log = shell_quote(script_path(&dir.join("parallel.log"))?);
    let (d, g) = (
        shell_quote(script_path(dir)?),
        shell_quote(script_path(goniospec)?),
    );
    Ok(format!(
        "parallel --joblog {log} --resume-failed -j {jobs} -q {g} batch run {d} --shard {{}}/{shards} ::: $(seq 1 {shards})"
    ))
}
