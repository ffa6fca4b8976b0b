//! Peak memory of `simulate` by rays does not grow with the ray count (the accumulation
//! reduces blocks as they finish; the diffraction method, which the default auto takes for
//! this film, keeps every exit of a direction for its transform, within
//! `simulate::DIFFRACTION_MAX_BYTES`). Each run is its own process, so each high-water mark (`VmHWM`,
//! written in the run's `--report-json`) is that run's own.

use std::path::Path;
use std::process::Command;

fn peak_mb(rays: u64, dir: &Path) -> f64 {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let report = dir.join(format!("m{rays}.json"));
    let out = Command::new(env!("CARGO_BIN_EXE_goniospec"))
        .arg("simulate")
        .arg(root.join("meshes/thin-film-600nm.toml"))
        .args([
            "--theta-i",
            "30",
            "--rays",
            &rays.to_string(),
            "--threads",
            "2",
            "--coherence",
            "beamlet",
        ])
        .arg("-o")
        .arg(dir.join(format!("m{rays}.gsa")))
        .arg("--report-json")
        .arg(&report)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(out.status.success(), "{err}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    json["peak_memory_mb"]
        .as_f64()
        .unwrap_or_else(|| panic!("no peak_memory_mb in {json}"))
}

/// Linux only: the figure comes from `/proc/self/status`.
#[cfg(target_os = "linux")]
#[test]
fn peak_memory_does_not_grow_with_the_ray_count() {
    let dir = std::env::temp_dir().join(format!("goniospec-mem-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // 40 wavelength bins (the default) on the seed's wavy film. The old accumulation kept
    // every block's sums until the end: about 2.5 KB per launched ray here, so +92 MB from
    // 4,096 to 40,960 rays. Now a run holds 4 blocks per thread (at least 16): the 10x run
    // may differ only by allocator noise. 8 MB is a tenth of the old growth.
    let small = peak_mb(4096, &dir);
    let large = peak_mb(40_960, &dir);
    let _ = std::fs::remove_dir_all(&dir);
    assert!(
        large - small < 8.0,
        "peak memory grew from {small:.1} MB at 4,096 rays to {large:.1} MB at 40,960"
    );
}
