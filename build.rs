//! Build script: find Embree's C headers on the system and generate raw bindings with
//! bindgen.
//!
//! Search order: `EMBREE_INCLUDE_DIR` (and `EMBREE_LIB_DIR` for the linker), then the usual
//! system include folders. `embree4/rtcore.h` is preferred over `embree3/rtcore.h`: Debian
//! 12 ships Embree 3.13.5, Debian 13 and newer ship Embree 4. The major version found is
//! passed to the crate as `cfg(embree_major = "3")` / `"4"`, and `cfg(embree)` is set when
//! any Embree is usable. Without Embree (or without libclang for bindgen) the crate still
//! builds, with a cargo warning, and only the obvhs backend is available.
//!
//! The bindings are generated from the installed header on purpose: the layout of
//! `RTCRayHit` differs between Embree releases (4.2 against 4.3), so bundled bindings
//! (such as the `embree4-sys` crate's) would corrupt memory on a mismatched system.

use std::env;
use std::path::{Path, PathBuf};

const CANDIDATE_INCLUDE_DIRS: &[&str] = &[
    "/usr/include",
    "/usr/local/include",
    "/opt/homebrew/include",
    "/opt/local/include",
];

fn main() {
    println!("cargo::rustc-check-cfg=cfg(embree)");
    println!("cargo::rustc-check-cfg=cfg(embree_major, values(\"3\", \"4\"))");
    println!("cargo::rerun-if-env-changed=EMBREE_INCLUDE_DIR");
    println!("cargo::rerun-if-env-changed=EMBREE_LIB_DIR");
    println!("cargo::rerun-if-env-changed=GONIOSPEC_NO_EMBREE");
    println!("cargo::rerun-if-changed=build.rs");

    if env::var_os("GONIOSPEC_NO_EMBREE").is_some_and(|v| v != "0") {
        println!(
            "cargo::warning=GONIOSPEC_NO_EMBREE is set: building without Embree; only the obvhs backend is available"
        );
        return;
    }

    let Some((include_dir, major)) = find_embree_header() else {
        // Installing Embree later must rebuild with it: watch the folders it would appear
        // in (an existing folder's time changes when an entry is added).
        for dir in env::var_os("EMBREE_INCLUDE_DIR")
            .map(PathBuf::from)
            .into_iter()
            .chain(CANDIDATE_INCLUDE_DIRS.iter().map(PathBuf::from))
            .filter(|d| d.is_dir())
        {
            println!("cargo::rerun-if-changed={}", dir.display());
        }
        println!(
            "cargo::warning=Embree headers not found (looked for embree4/rtcore.h and embree3/rtcore.h in EMBREE_INCLUDE_DIR and {}): building without Embree; only the obvhs backend is available. On Debian: apt-get install -y libembree-dev libclang-dev pkg-config",
            CANDIDATE_INCLUDE_DIRS.join(", ")
        );
        return;
    };

    let header = include_dir.join(format!("embree{major}/rtcore.h"));
    println!("cargo::rerun-if-changed={}", header.display());

    // bindgen loads libclang at run time and panics when it cannot; turn that into a
    // warning and an Embree-less build rather than a failed one.
    let header_str = header.to_string_lossy().into_owned();
    let include_arg = format!("-I{}", include_dir.display());
    let generated = std::panic::catch_unwind(move || {
        bindgen::Builder::default()
            .header(header_str)
            .clang_arg(include_arg)
            .allowlist_function("rtc.*")
            .allowlist_type("RTC.*")
            .allowlist_var("RTC_.*")
            .prepend_enum_name(false)
            .default_enum_style(bindgen::EnumVariation::Consts)
            .derive_default(true)
            .layout_tests(true)
            .generate()
    });
    let bindings = match generated {
        Ok(Ok(b)) => b,
        Ok(Err(e)) => {
            println!(
                "cargo::warning=bindgen failed on {} ({e}): building without Embree",
                header.display()
            );
            return;
        }
        Err(_) => {
            println!(
                "cargo::warning=bindgen could not run (is libclang installed? apt-get install -y libclang-dev): building without Embree"
            );
            return;
        }
    };
    let out = PathBuf::from(env::var("OUT_DIR").expect("cargo sets OUT_DIR"));
    bindings
        .write_to_file(out.join("embree_bindings.rs"))
        .expect("write embree_bindings.rs into OUT_DIR");

    if let Some(lib_dir) = env::var_os("EMBREE_LIB_DIR") {
        println!(
            "cargo::rustc-link-search=native={}",
            Path::new(&lib_dir).display()
        );
    }
    println!("cargo::rustc-link-lib=dylib=embree{major}");
    println!("cargo::rustc-cfg=embree");
    println!("cargo::rustc-cfg=embree_major=\"{major}\"");
    println!(
        "cargo::rustc-env=GONIOSPEC_EMBREE_HEADER={}",
        header.display()
    );
}

/// The include folder holding `embree4/rtcore.h` or `embree3/rtcore.h`, and which major.
fn find_embree_header() -> Option<(PathBuf, u32)> {
    let mut dirs: Vec<PathBuf> = Vec::new();
    if let Some(d) = env::var_os("EMBREE_INCLUDE_DIR") {
        dirs.push(PathBuf::from(d));
    }
    dirs.extend(CANDIDATE_INCLUDE_DIRS.iter().map(PathBuf::from));
    for dir in &dirs {
        for major in [4u32, 3] {
            if dir.join(format!("embree{major}/rtcore.h")).is_file() {
                return Some((dir.clone(), major));
            }
        }
    }
    None
}
