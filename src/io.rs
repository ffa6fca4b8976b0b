//! Atomic file writes: write a temporary file beside the target, flush it to disk, then
//! rename it over the target and flush the folder, so a crash never leaves a half-written
//! result that looks valid, and an existing output survives a failed run.
//!
//! Temporary names are short and fixed in length (`.gs-<hash of the name>-<pid>.tmp.<ext>`),
//! so a legal 255-byte output name still has a legal temporary; they name their owner's
//! process, so a later run removes what a killed one left ([`clean_stale`]). Outputs that
//! belong together (an EXR and its PNG) are staged first and renamed together
//! ([`commit_all`]): a failure while writing either leaves both old files in place.

use std::fs::{self, File};
use std::io::{self, BufWriter};
use std::path::{Path, PathBuf};

/// Writes `path` atomically through `fill`. On any error the temporary file is removed
/// and the target is left as it was.
pub fn write_atomic<F>(path: &Path, fill: F) -> io::Result<()>
where
    F: FnOnce(&mut BufWriter<File>) -> io::Result<()>,
{
    Staged::write(path, fill)?.commit()
}

/// Writes `path` atomically through `fill`, which writes the file at the path it is given
/// (for libraries that take a path: image and chart encoders). The temporary keeps the
/// target's extension, since some encoders choose the format by it.
pub fn write_atomic_path<F>(path: &Path, fill: F) -> io::Result<()>
where
    F: FnOnce(&Path) -> io::Result<()>,
{
    Staged::write_path(path, fill)?.commit()
}

/// A finished temporary file waiting to replace its target. Dropping it uncommitted
/// removes the temporary.
#[derive(Debug)]
pub struct Staged {
    tmp: PathBuf,
    target: PathBuf,
    committed: bool,
}

impl Staged {
    /// Writes and flushes to disk the temporary of `path` through a buffered writer.
    pub fn write<F>(path: &Path, fill: F) -> io::Result<Staged>
    where
        F: FnOnce(&mut BufWriter<File>) -> io::Result<()>,
    {
        Staged::write_path(path, |tmp| {
            let mut w = BufWriter::new(File::create(tmp)?);
            fill(&mut w)?;
            w.into_inner().map_err(|e| e.into_error())?;
            Ok(())
        })
    }

    /// Writes the temporary of `path` through `fill` (given the temporary's path), then
    /// flushes it to disk.
    pub fn write_path<F>(path: &Path, fill: F) -> io::Result<Staged>
    where
        F: FnOnce(&Path) -> io::Result<()>,
    {
        clean_stale(path);
        let staged = Staged {
            tmp: temp_path(path),
            target: path.to_path_buf(),
            committed: false,
        };
        fill(&staged.tmp)?;
        File::open(&staged.tmp)?.sync_all()?;
        Ok(staged)
    }

    /// Renames the temporary over the target and flushes the folder.
    pub fn commit(mut self) -> io::Result<()> {
        fs::rename(&self.tmp, &self.target)?;
        self.committed = true;
        sync_parent(&self.target);
        Ok(())
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        if !self.committed {
            let _ = fs::remove_file(&self.tmp);
        }
    }
}

/// Renames staged files over their targets, in order, once all of them were written.
pub fn commit_all(staged: Vec<Staged>) -> io::Result<()> {
    for s in staged {
        s.commit()?;
    }
    Ok(())
}

/// Flushes the folder holding `path`, so the rename itself survives a power loss. Best
/// effort: some file systems cannot flush a folder, and the data is already on disk.
fn sync_parent(path: &Path) {
    if let Ok(dir) = File::open(parent(path)) {
        let _ = dir.sync_all();
    }
}

fn parent(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// FNV-1a 64-bit hash (Fowler, Noll & Vo; offset basis 0xcbf29ce484222325, prime
/// 0x100000001b3): short stable names and the sample identity hash, never a checksum of
/// file content (that is [`crate::container::checksum`]).
pub fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// `.gs-<16 hex digits of FNV-1a of the file name>-` : the start of every temporary name
/// of `path`.
fn temp_prefix(path: &Path) -> String {
    let name = path
        .file_name()
        .map(|n| n.as_encoded_bytes())
        .unwrap_or(b"out");
    format!(".gs-{:016x}-", fnv1a(name))
}

/// `dir/.gs-<hash>-<pid>.tmp[.ext]` beside `path`: same file system, so the rename is
/// atomic; at most 48 bytes long whatever the target's name.
pub fn temp_path(path: &Path) -> PathBuf {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .filter(|e| e.len() <= 8 && e.chars().all(|c| c.is_ascii_alphanumeric()))
        .map_or(String::new(), |e| format!(".{e}"));
    parent(path).join(format!(
        "{}{}.tmp{ext}",
        temp_prefix(path),
        std::process::id()
    ))
}

/// Removes temporaries of `path` whose process no longer runs (left by `kill -9` or a
/// power loss). Only on systems with `/proc`; elsewhere nothing is removed.
pub fn clean_stale(path: &Path) {
    if !Path::new("/proc/self").exists() {
        return;
    }
    let prefix = temp_prefix(path);
    let Ok(entries) = fs::read_dir(parent(path)) else {
        return;
    };
    for e in entries.flatten() {
        let name = e.file_name();
        let Some(rest) = name.to_str().and_then(|n| n.strip_prefix(&prefix)) else {
            continue;
        };
        let Some((pid, _)) = rest.split_once(".tmp") else {
            continue;
        };
        if let Ok(pid) = pid.parse::<u32>()
            && pid != std::process::id()
            && !Path::new(&format!("/proc/{pid}")).exists()
        {
            let _ = fs::remove_file(e.path());
        }
    }
}

/// Checks, before any work, that an output can be written at `path`: its folder exists
/// and accepts a new file (a probe temporary is created and removed).
pub fn check_writable(path: &Path) -> io::Result<()> {
    let probe = temp_path(path);
    File::create(&probe)?;
    fs::remove_file(&probe)
}

/// The most bytes a text input (sample, medium table or model, study) may have: 256 MiB.
pub const MAX_TEXT_BYTES: u64 = 256 << 20;

/// Reads a whole input file of at most `max_bytes`. Devices (`/dev/urandom`, a terminal)
/// are refused rather than read forever; pipes and regular files are read up to the limit.
pub fn read_input(path: &Path, max_bytes: u64) -> io::Result<Vec<u8>> {
    use std::io::Read;
    let meta = fs::metadata(path)?;
    if meta.is_dir() {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            "is a directory",
        ));
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        let t = meta.file_type();
        if t.is_char_device() || t.is_block_device() || t.is_socket() {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                "is a device, not a file",
            ));
        }
    }
    let mut buf = Vec::new();
    File::open(path)?
        .take(max_bytes.saturating_add(1))
        .read_to_end(&mut buf)?;
    if buf.len() as u64 > max_bytes {
        return Err(io::Error::new(
            io::ErrorKind::InvalidData,
            format!("is larger than the {max_bytes} bytes this kind of file may have"),
        ));
    }
    Ok(buf)
}

/// [`read_input`] of UTF-8 text (at most [`MAX_TEXT_BYTES`]).
pub fn read_text(path: &Path) -> io::Result<String> {
    String::from_utf8(read_input(path, MAX_TEXT_BYTES)?).map_err(|e| {
        io::Error::new(
            io::ErrorKind::InvalidData,
            format!("is not UTF-8 text (byte {})", e.utf8_error().valid_up_to()),
        )
    })
}

/// Peak resident memory of this process so far, MB (Linux `VmHWM` from `/proc/self/status`;
/// `None` where that is not available).
pub fn peak_rss_mb() -> Option<f64> {
    let status = fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

/// Memory this machine can still give a process without swapping, bytes (Linux
/// `MemAvailable` from `/proc/meminfo`; `None` where that is not available).
pub fn available_memory_bytes() -> Option<u64> {
    let info = fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kb.checked_mul(1024)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("goniospec-io-{}-{tag}", std::process::id()));
        let _ = fs::remove_dir_all(&d);
        fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn long_names_stale_temporaries_and_failed_fills() {
        let d = dir("atomic");
        // A legal 254-byte name: its temporary is short.
        let long = d.join(format!("{}.gsa", "x".repeat(250)));
        write_atomic(&long, |w| io::Write::write_all(w, b"one")).unwrap();
        assert_eq!(fs::read(&long).unwrap(), b"one");
        assert!(temp_path(&long).file_name().unwrap().len() <= 48);
        // A temporary left by a process that no longer runs is removed by the next write;
        // pid 4294967295 cannot exist on Linux (pid_max is at most 2^22).
        let stale = d.join(format!("{}4294967295.tmp.gsa", temp_prefix(&long)));
        fs::write(&stale, b"half").unwrap();
        write_atomic(&long, |w| io::Write::write_all(w, b"two")).unwrap();
        assert!(!stale.exists());
        assert_eq!(fs::read(&long).unwrap(), b"two");
        // A failing fill leaves the old file and no temporary.
        let e = write_atomic(&long, |_| Err(io::Error::other("disk full")));
        assert!(e.is_err());
        assert_eq!(fs::read(&long).unwrap(), b"two");
        assert_eq!(fs::read_dir(&d).unwrap().count(), 1);
        // Staged pairs: a failure staging the second leaves the first target untouched.
        let (a, b) = (d.join("img.exr"), d.join("img.png"));
        fs::write(&a, b"old exr").unwrap();
        let first = Staged::write(&a, |w| io::Write::write_all(w, b"new exr")).unwrap();
        let second = Staged::write(&b, |_| Err(io::Error::other("encoder failed")));
        assert!(second.is_err());
        drop(first);
        assert_eq!(fs::read(&a).unwrap(), b"old exr");
        assert!(!b.exists());
        assert_eq!(fs::read_dir(&d).unwrap().count(), 2);
        // An unwritable location is found before any work.
        assert!(check_writable(&d.join("no-such-dir").join("x.exr")).is_err());
        assert!(check_writable(&a).is_ok());
    }
}
