//! A binary cache beside large mesh files: `MESH.obj` is parsed once and its triangles
//! written to `MESH.obj.gsmesh` (the goniospec container: magic, version, header, payload,
//! CRC-32; written atomically), which later loads read instead of parsing text.
//!
//! The cache is used only when it matches its source exactly: the source's size, its
//! modification time (ns) and the CRC-32 of its bytes (read once, streamed), the unit
//! scale and the loading options, and the cache format version; anything else (a stale, cut,
//! corrupted or foreign cache) is ignored and rewritten. A cache that cannot be written (a
//! read-only folder) only costs the parse next time. Meshes below [`MIN_BYTES`] are not
//! cached: they parse in well under a second.

use std::io::Read;
use std::path::{Path, PathBuf};

use super::SampleError;
use super::mesh::Mesh;
use crate::container::{self, Format};
use glam::DVec3;

/// Source files at least this large are cached (by default).
pub const MIN_BYTES: u64 = 16 << 20;

/// The cache file's container format (public for tests that forge caches).
pub const FORMAT: Format = Format {
    magic: b"GSMESH\x00\x01",
    what: "mesh cache (.gsmesh)",
    version: 1,
    legacy_version: None,
};

/// Whether to use the cache.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CachePolicy {
    /// For sources of at least [`MIN_BYTES`].
    #[default]
    Large,
    /// For every source (tests).
    Always,
    /// Never read or write a cache.
    Off,
}

/// How a mesh was obtained.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Loaded {
    Parsed,
    /// Parsed, and the cache written.
    ParsedAndCached,
    FromCache,
}

/// The cache file of `source`.
pub fn cache_path(source: &Path) -> PathBuf {
    let mut s = source.as_os_str().to_owned();
    s.push(".gsmesh");
    PathBuf::from(s)
}

/// What identifies a source and how it was loaded.
fn key(source: &Path, nm_per_unit: f64, drop_degenerate: bool) -> std::io::Result<String> {
    let meta = std::fs::metadata(source)?;
    let mtime = meta
        .modified()?
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or(0);
    let mut hasher = crc32fast::Hasher::new();
    let mut f = std::fs::File::open(source)?;
    let mut buf = vec![0u8; 8 << 20];
    let mut len = 0u64;
    loop {
        let n = f.read(&mut buf)?;
        if n == 0 {
            break;
        }
        hasher.update(&buf[..n]);
        len += n as u64;
    }
    Ok(format!(
        "source_bytes = {len}\nsource_mtime_ns = {mtime}\nsource_crc32 = {}\nnm_per_unit_bits = {}\ndrop_degenerate = {drop_degenerate}\n",
        hasher.finalize(),
        nm_per_unit.to_bits()
    ))
}

fn encode(key: &str, mesh: &Mesh) -> Vec<u8> {
    let mut payload =
        Vec::with_capacity(16 + 24 * mesh.positions_nm.len() + 12 * mesh.triangles.len());
    payload.extend((mesh.positions_nm.len() as u64).to_le_bytes());
    payload.extend((mesh.triangles.len() as u64).to_le_bytes());
    for p in &mesh.positions_nm {
        for c in p.to_array() {
            payload.extend(c.to_le_bytes());
        }
    }
    for t in &mesh.triangles {
        for i in t {
            payload.extend(i.to_le_bytes());
        }
    }
    container::encode(&FORMAT, key, &payload)
}

/// The cached mesh, if `bytes` are a valid cache for `key` (public for the fuzzer).
pub fn decode(bytes: &[u8], key: &str) -> Option<Mesh> {
    let frame = container::decode(&FORMAT, bytes, "").ok()?;
    if frame.header != key {
        return None;
    }
    let p = frame.payload;
    let u64_at = |at: usize| -> Option<u64> {
        Some(u64::from_le_bytes(p.get(at..at + 8)?.try_into().ok()?))
    };
    let (nv, nt) = (u64_at(0)?, u64_at(8)?);
    // Checked: counts near 2^61 wrapped the unchecked sum into a plausible length.
    let want = nv
        .checked_mul(24)
        .and_then(|v| nt.checked_mul(12)?.checked_add(v))
        .and_then(|v| v.checked_add(16))?;
    if p.len() as u64 != want || nt == 0 {
        return None;
    }
    let (nv, nt) = (usize::try_from(nv).ok()?, usize::try_from(nt).ok()?);
    let f = |at: usize| f64::from_le_bytes(p[at..at + 8].try_into().expect("8 bytes"));
    let positions_nm = (0..nv)
        .map(|k| {
            let at = 16 + 24 * k;
            DVec3::new(f(at), f(at + 8), f(at + 16))
        })
        .collect();
    let base = 16 + 24 * nv;
    let u = |at: usize| u32::from_le_bytes(p[at..at + 4].try_into().expect("4 bytes"));
    let mut triangles = Vec::with_capacity(nt);
    for k in 0..nt {
        let at = base + 12 * k;
        let t = [u(at), u(at + 4), u(at + 8)];
        if t.iter().any(|&i| i as usize >= nv) {
            return None;
        }
        triangles.push(t);
    }
    let mesh = Mesh {
        positions_nm,
        triangles,
    };
    // A file from outside, checksum or not: the cache holds only what the parsers accept
    // (finite coordinates within the length limit, no degenerate triangle); anything else
    // is treated as no cache, and the source is parsed again.
    let sane = mesh
        .positions_nm
        .iter()
        .all(|v| v.is_finite() && v.abs().max_element() <= super::MAX_LENGTH_NM)
        && mesh.degenerate_triangles().is_empty();
    sane.then_some(mesh)
}

/// Whether `cache` exists and is not a goniospec mesh cache (its magic), or is not a file.
fn is_foreign(cache: &Path) -> bool {
    use std::io::Read;
    match std::fs::symlink_metadata(cache) {
        Err(_) => false,
        Ok(m) if !m.is_file() => true,
        Ok(_) => {
            let mut head = Vec::new();
            std::fs::File::open(cache)
                .and_then(|f| f.take(FORMAT.magic.len() as u64).read_to_end(&mut head))
                .map_or(true, |_| head != FORMAT.magic)
        }
    }
}

/// Loads `source` through its cache: the cached mesh when it matches, otherwise
/// `parse()`'s, then written to the cache.
pub fn load(
    source: &Path,
    nm_per_unit: f64,
    drop_degenerate: bool,
    policy: CachePolicy,
    parse: impl FnOnce() -> Result<Mesh, SampleError>,
) -> Result<(Mesh, Loaded), SampleError> {
    let size = std::fs::metadata(source).map(|m| m.len()).unwrap_or(0);
    let wanted = match policy {
        CachePolicy::Off => false,
        CachePolicy::Always => true,
        CachePolicy::Large => size >= MIN_BYTES,
    };
    if !wanted {
        return Ok((parse()?, Loaded::Parsed));
    }
    // A source that cannot be read is the parser's error to report.
    let Ok(key) = key(source, nm_per_unit, drop_degenerate) else {
        return Ok((parse()?, Loaded::Parsed));
    };
    let cache = cache_path(source);
    if let Ok(bytes) = std::fs::read(&cache)
        && let Some(mesh) = decode(&bytes, &key)
    {
        return Ok((mesh, Loaded::FromCache));
    }
    let mesh = parse()?;
    // A file of the cache's name that is not a goniospec mesh cache is the user's: it is
    // kept, and the mesh is not cached (issue 47: a user's own MESH.obj.gsmesh was
    // replaced).
    if is_foreign(&cache) {
        return Ok((mesh, Loaded::Parsed));
    }
    let bytes = encode(&key, &mesh);
    let written = crate::io::write_atomic(&cache, |w| std::io::Write::write_all(w, &bytes));
    Ok((
        mesh,
        if written.is_ok() {
            Loaded::ParsedAndCached
        } else {
            Loaded::Parsed
        },
    ))
}
