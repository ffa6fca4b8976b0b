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
