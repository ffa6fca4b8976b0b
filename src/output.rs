//! The output policy of every front end (CLI, Python, batch): an output is never a
//! directory, never the same file as an input of the run, always in a folder that takes a
//! new file, and replaces an existing file only when it is of its own kind, unless forced.
//! Writes are atomic (`io::write_atomic`), so a refused run changes nothing.

use std::io::Write;
use std::path::Path;

/// The first line of every page `batch report` writes; the output policy recognises it.
pub const HTML_MARK: &str = "<!DOCTYPE html>\n<!-- goniospec batch report -->";

/// What kind of file an output may replace without `force`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutputKind {
    Gsa,
    Gsb,
    Obj,
    /// RGL tensor files (.bsdf).
    Tensor,
    /// NumPy archives (.npz).
    Npz,
    /// MERL binaries (.binary).
    Merl,
    /// Images goniospec writes: PNG, OpenEXR or SVG.
    Image,
    /// The JSON or glTF `goniospec fit` writes (its `fit` key, or `asset.generator`).
    FitJson,
    /// The HTML page `goniospec batch report` writes (its first line).
    Report,
    /// The JSON figures of a run (`simulate --report-json`): an object with
    /// `traced_trees` and `segments_per_second`.
    RunReport,
    /// A Mitsuba 3 or pbrt-v4 scene `goniospec export --scene` writes (its mark in the
    /// first lines).
    Scene,
}

/// Why an output was refused.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("output {0} is a directory; give a file name")]
    Directory(String),
    #[error("output {out} is the input {input}: refusing to overwrite it")]
    IsInput { out: String, input: String },
    #[error("cannot write {out} (does its folder exist, and may you write there?): {source}")]
    NotWritable { out: String, source: std::io::Error },
    #[error("reading {out}: {source}")]
    Unreadable { out: String, source: std::io::Error },
    #[error(
        "refusing to overwrite {out}: it is not {what}; remove it, choose another name, or pass --force"
    )]
    Foreign { out: String, what: &'static str },
    #[error("output folder {0} is a file; give a folder (it is made when missing)")]
    NotAFolder(String),
    #[error(
        "refusing to write into {dir}: {files} would be replaced, and goniospec did not write them (they are not in {dir}/{WRITTEN_LIST}); move them, choose another folder, or pass --force"
    )]
    Unlisted { dir: String, files: String },
}

/// The list of the files goniospec wrote into a folder it writes several files into (a
/// study's folder, a report page's folder), one name per line. A file of one of those
/// names that the list does not hold is the user's (issue 47: `study -o FOLDER` replaced a
/// user's `report.md`, `batch report` a user's PNG named as a material's image).
pub const WRITTEN_LIST: &str = ".goniospec-written";

/// Checks, before any work, that writing the files `names` into folder `dir` replaces none
/// the user did not name: `dir` is a folder or does not exist yet (nor is its parent
/// missing), and each of `names` that exists there is in `dir`'s [`WRITTEN_LIST`], unless
/// `force`.
pub fn guard_folder(dir: &Path, names: &[String], force: bool) -> Result<(), OutputError> {
    let shown = || dir.display().to_string();
    if dir.exists() && !dir.is_dir() {
        return Err(OutputError::NotAFolder(shown()));
    }
    if !dir.exists() {
        let parent = dir.parent().filter(|p| !p.as_os_str().is_empty());
        if let Some(p) = parent.filter(|p| !p.is_dir()) {
            return Err(OutputError::NotWritable {
                out: shown(),
                source: std::io::Error::new(
                    std::io::ErrorKind::NotFound,
                    format!("its parent folder {} does not exist", p.display()),
                ),
            });
        }
        return Ok(());
    }
    crate::io::check_writable(&dir.join(WRITTEN_LIST)).map_err(|source| {
        OutputError::NotWritable {
            out: shown(),
            source,
        }
    })?;
    if force {
        return Ok(());
    }
    let listed = written_list(dir);
    let foreign: Vec<&str> = names
        .iter()
        .filter(|n| std::fs::symlink_metadata(dir.join(n)).is_ok() && !listed.contains(*n))
        .map(String::as_str)
        .collect();
    if foreign.is_empty() {
        Ok(())
    } else {
        Err(OutputError::Unlisted {
            dir: shown(),
            files: foreign.join(", "),
        })
    }
}

/// The names in `dir`'s [`WRITTEN_LIST`] (none when it is missing or unreadable).
fn written_list(dir: &Path) -> std::collections::BTreeSet<String> {
    crate::io::read_input(&dir.join(WRITTEN_LIST), 16 << 20)
        .ok()
        .map(|t| {
            String::from_utf8_lossy(&t)
                .lines()
                .filter(|l| !l.is_empty())
                .map(str::to_string)
                .collect()
        })
        .unwrap_or_default()
}

/// Adds `names` to `dir`'s [`WRITTEN_LIST`] (atomically), after they were written.
pub fn record_folder(dir: &Path, names: &[String]) -> std::io::Result<()> {
    let mut listed = written_list(dir);
    listed.extend(names.iter().cloned());
    crate::io::write_atomic(&dir.join(WRITTEN_LIST), |w| {
        for n in &listed {
            writeln!(w, "{n}")?;
        }
        Ok(())
    })
}

/// Checks `out` against the policy (see the module docs); `inputs` are every file the run
/// reads.
pub fn guard(
    out: &Path,
    inputs: &[&Path],
    kind: OutputKind,
    force: bool,
) -> Result<(), OutputError> {
    let name = || out.display().to_string();
    if out.is_dir() {
        return Err(OutputError::Directory(name()));
    }
    for i in inputs {
        if same_file(out, i) {
            return Err(OutputError::IsInput {
                out: name(),
                input: i.display().to_string(),
            });
        }
    }
    // Before any work: the folder exists and takes a new file.
    crate::io::check_writable(out).map_err(|source| OutputError::NotWritable {
        out: name(),
        source,
    })?;
    if force || !out.exists() {
        return Ok(());
    }
    let head = {
        use std::io::Read;
        let mut b = Vec::new();
        std::fs::File::open(out)
            .and_then(|f| f.take(4096).read_to_end(&mut b))
            .map_err(|source| OutputError::Unreadable {
                out: name(),
                source,
            })?;
        b
    };
    let (ok, what) = match kind {
        OutputKind::Gsa => (
            head.starts_with(crate::accumulate::file::MAGIC),
            "a goniospec accumulator (.gsa)",
        ),
        OutputKind::Gsb => (
            head.starts_with(crate::brdf::file::MAGIC),
            "a goniospec BRDF (.gsb)",
        ),
        OutputKind::Obj => (
            head.starts_with(b"# goniospec generate"),
            "an OBJ written by goniospec generate",
        ),
        OutputKind::Merl => (
            head.starts_with(&[90, 0, 0, 0, 90, 0, 0, 0, 180, 0, 0, 0]),
            "a MERL BRDF (.binary)",
        ),
        OutputKind::Npz => (head.starts_with(b"PK\x03\x04"), "a NumPy archive (.npz)"),
        OutputKind::Tensor => (
            crate::export::tensor::is_tensor_file(&head),
            "an RGL tensor file (.bsdf)",
        ),
        OutputKind::Image => (
            head.starts_with(b"\x89PNG\r\n\x1a\n")
                || head.starts_with(&[0x76, 0x2f, 0x31, 0x01])
                || head.starts_with(b"<svg")
                || head.starts_with(b"<?xml"),
            "an image (PNG, OpenEXR or SVG)",
        ),
        OutputKind::FitJson => (is_fit_output(out), "a material written by goniospec fit"),
        OutputKind::Report => (
            head.starts_with(HTML_MARK.as_bytes()),
            "a page written by goniospec batch report",
        ),
        OutputKind::RunReport => (
            json_object_with(out, &["traced_trees", "segments_per_second"]),
            "a run report written by goniospec simulate --report-json",
        ),
        OutputKind::Scene => (
            head.windows(crate::export::scene::MARK.len())
                .take(256)
                .any(|w| w == crate::export::scene::MARK.as_bytes()),
            "a scene written by goniospec export --scene",
        ),
    };
    if ok {
        Ok(())
    } else {
        Err(OutputError::Foreign { out: name(), what })
    }
}

/// Whether `path` is a JSON object holding every key of `keys` (files over 64 MiB are not
/// read).
fn json_object_with(path: &Path, keys: &[&str]) -> bool {
    let Ok(text) = crate::io::read_input(path, 64 << 20) else {
        return false;
    };
    serde_json::from_slice::<serde_json::Value>(&text)
        .is_ok_and(|v| keys.iter().all(|k| v.get(k).is_some()))
}

/// Whether `path` is a JSON or glTF file `goniospec fit` wrote: a JSON object with a `fit`
/// key, or with `asset.generator` "goniospec fit" (files over 64 MiB are not read).
fn is_fit_output(path: &Path) -> bool {
    let Ok(text) = crate::io::read_input(path, 64 << 20) else {
        return false;
    };
    let Ok(v) = serde_json::from_slice::<serde_json::Value>(&text) else {
        return false;
    };
    v.get("fit").is_some() || v["asset"]["generator"] == "goniospec fit"
}

/// Whether two paths name the same existing file.
pub fn same_file(a: &Path, b: &Path) -> bool {
    match (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
        (Ok(x), Ok(y)) => x == y,
        _ => false,
    }
}
