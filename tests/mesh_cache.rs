//! The binary mesh cache (`sample::cache`): a second load reads the cache and gives the
//! same mesh as parsing; a changed, touched, cut or corrupted source or cache is never
//! used; the cache depends on the unit scale and options; and the cache is not written
//! where it is off or for small files by default.

mod common;

use common::*;
use goniospec::sample::cache::{CachePolicy, Loaded, cache_path};
use goniospec::sample::{MeshOptions, load_mesh_with};

fn opts(cache: CachePolicy) -> MeshOptions {
    MeshOptions {
        cache,
        ..MeshOptions::default()
    }
}

#[test]
fn the_cache_gives_the_parsed_mesh_and_is_never_stale() {
    let d = scratch("mesh-cache");
    let obj = d.join("m.obj");
    std::fs::copy(root().join("meshes/rough-gold-ggx.obj"), &obj).unwrap();
    let always = opts(CachePolicy::Always);
    let (parsed, how) = load_mesh_with(&obj, 1000.0, always).unwrap();
    assert_eq!(how, Loaded::ParsedAndCached);
    assert!(cache_path(&obj).is_file());
    let (cached, how) = load_mesh_with(&obj, 1000.0, always).unwrap();
    assert_eq!(how, Loaded::FromCache);
    assert_eq!(cached, parsed, "the cache holds the parsed mesh exactly");
    // Another unit scale or other options are another cache key.
    let (other, how) = load_mesh_with(&obj, 1.0, always).unwrap();
    assert_eq!(how, Loaded::ParsedAndCached);
    assert_eq!(other.positions_nm[0] * 1000.0, parsed.positions_nm[0]);
    assert_eq!(
        load_mesh_with(&obj, 1.0, always).unwrap().1,
        Loaded::FromCache
    );
    // A changed source (same size: one digit edited) is parsed again.
    let text = std::fs::read_to_string(&obj).unwrap();
    let i = text.find("\nv ").unwrap() + 3;
    let digit = text.as_bytes()[i];
    let mut bytes = text.into_bytes();
    bytes[i] = if digit == b'1' { b'2' } else { b'1' };
    std::fs::write(&obj, &bytes).unwrap();
    let (changed, how) = load_mesh_with(&obj, 1.0, always).unwrap();
    assert_eq!(how, Loaded::ParsedAndCached);
    assert_ne!(changed, other);
    // A corrupted or cut cache is ignored and rewritten.
    let cache = cache_path(&obj);
    let mut c = std::fs::read(&cache).unwrap();
    let mid = c.len() / 2;
    c[mid] ^= 0x40;
    std::fs::write(&cache, &c).unwrap();
    let (again, how) = load_mesh_with(&obj, 1.0, always).unwrap();
    assert_eq!((how, &again), (Loaded::ParsedAndCached, &changed));
    let c = std::fs::read(&cache).unwrap();
    std::fs::write(&cache, &c[..c.len() - 9]).unwrap();
    assert_eq!(
        load_mesh_with(&obj, 1.0, always).unwrap().1,
        Loaded::ParsedAndCached
    );
    // A cache of another file copied over is refused (its source's size, time and CRC
    // differ).
    let other_obj = d.join("o.obj");
    std::fs::copy(root().join("meshes/v-grooves-90.obj"), &other_obj).unwrap();
    load_mesh_with(&other_obj, 1.0, always).unwrap();
    std::fs::copy(cache_path(&other_obj), &cache).unwrap();
    let (m, how) = load_mesh_with(&obj, 1.0, always).unwrap();
    assert_eq!((how, &m), (Loaded::ParsedAndCached, &changed));
}

/// A file of the cache's name that is not a mesh cache is the user's: it is never replaced,
/// and the mesh is parsed (issue 47).
#[test]
fn a_users_file_at_the_cache_path_is_kept() {
    let d = scratch("mesh-cache-foreign");
    let obj = d.join("m.obj");
    std::fs::copy(root().join("meshes/rough-gold-ggx.obj"), &obj).unwrap();
    let mine = b"my notes on this mesh\n";
    std::fs::write(cache_path(&obj), mine).unwrap();
    let always = opts(CachePolicy::Always);
    for _ in 0..2 {
        let (m, how) = load_mesh_with(&obj, 1000.0, always).unwrap();
        assert_eq!(how, Loaded::Parsed);
        assert!(!m.triangles.is_empty());
        assert_eq!(std::fs::read(cache_path(&obj)).unwrap(), mine);
    }
}

#[test]
fn the_cache_is_off_when_asked_and_for_small_files_by_default() {
    let d = scratch("mesh-cache-off");
    let obj = d.join("m.obj");
    std::fs::copy(root().join("meshes/v-grooves-90.obj"), &obj).unwrap();
    for policy in [CachePolicy::Off, CachePolicy::Large] {
        let (_, how) = load_mesh_with(&obj, 1000.0, opts(policy)).unwrap();
        assert_eq!(how, Loaded::Parsed);
        assert!(!cache_path(&obj).exists(), "{policy:?}");
    }
    // A cache that cannot be written (a read-only folder) costs nothing but the parse.
    if is_root() {
        return; // root writes anywhere; the permission case cannot be made here
    }
    let ro = d.join("ro");
    std::fs::create_dir(&ro).unwrap();
    std::fs::copy(&obj, ro.join("m.obj")).unwrap();
    let mut perm = std::fs::metadata(&ro).unwrap().permissions();
    perm.set_readonly(true);
    std::fs::set_permissions(&ro, perm).unwrap();
    let (_, how) = load_mesh_with(&ro.join("m.obj"), 1000.0, opts(CachePolicy::Always)).unwrap();
    assert_eq!(how, Loaded::Parsed);
}

/// Whether this process runs as root (file permissions do not bind it).
fn is_root() -> bool {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("Uid:"))
                .map(|l| l.split_whitespace().nth(1) == Some("0"))
        })
        .unwrap_or(false)
}

/// Issue 30: a cache with a valid checksum but senseless content is data from outside
/// like any other: an empty mesh (it panicked `check`), vertex counts whose byte length
/// wraps around 2^64 (a capacity overflow), a non-finite or out-of-range coordinate, or a
/// degenerate triangle are not used; the source is parsed again and the cache rewritten.
#[test]
fn a_cache_with_a_valid_checksum_and_senseless_content_is_not_used() {
    use goniospec::container;
    use goniospec::sample::cache::FORMAT;
    let d = scratch("mesh-cache-forged");
    let obj = d.join("m.obj");
    std::fs::copy(root().join("meshes/v-grooves-90.obj"), &obj).unwrap();
    let always = opts(CachePolicy::Always);
    let (parsed, _) = load_mesh_with(&obj, 1.0, always).unwrap();
    let cache = cache_path(&obj);
    let good = std::fs::read(&cache).unwrap();
    let frame = container::decode(&FORMAT, &good, "").unwrap();
    let (header, payload) = (frame.header.to_string(), frame.payload.to_vec());
    let counts = |nv: u64, nt: u64, rest: &[u8]| -> Vec<u8> {
        let mut p = Vec::new();
        p.extend(nv.to_le_bytes());
        p.extend(nt.to_le_bytes());
        p.extend(rest);
        p
    };
    let nv = u64::from_le_bytes(payload[0..8].try_into().unwrap());
    let vertex = |k: usize| 16 + 24 * k;
    let mut far = payload.clone();
    far[vertex(0)..vertex(0) + 8].copy_from_slice(&1e12f64.to_le_bytes());
    let mut nan = payload.clone();
    nan[vertex(1) + 8..vertex(1) + 16].copy_from_slice(&f64::NAN.to_le_bytes());
    // Every triangle's corners the same vertex: degenerate.
    let mut flat = payload.clone();
    for b in &mut flat[vertex(nv as usize)..] {
        *b = 0;
    }
    // 24 * 2^61 + 12 * 2^62 + 16 wraps to 16: an empty payload after the counts.
    let wrapped = counts(1 << 61, 1 << 62, &[]);
    for (tag, forged) in [
        ("empty", counts(0, 0, &[])),
        ("wrapped", wrapped),
        ("far", far),
        ("nan", nan),
        ("degenerate", flat),
    ] {
        std::fs::write(&cache, container::encode(&FORMAT, &header, &forged)).unwrap();
        let (m, how) = load_mesh_with(&obj, 1.0, always).unwrap_or_else(|e| panic!("{tag}: {e}"));
        assert_eq!(
            (how, &m),
            (Loaded::ParsedAndCached, &parsed),
            "{tag}: the forged cache was used"
        );
        assert_eq!(std::fs::read(&cache).unwrap(), good, "{tag}: not rewritten");
    }
}
