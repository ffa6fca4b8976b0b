//! The house gate (`scripts/house-figures.py --check`, issue 45) on small made-up crates:
//! each defect it exists for fails it, naming the place, and a clean crate passes. The
//! real tree is held by `make lint`.

mod common;

use std::path::Path;
use std::process::Command;

/// The floors of a made-up crate: `base` above `mid` above `top`.
const DESIGN: &str = "# design\n\n## 9. Rooms and what each may import\n\nText.\n\n```\nbase  the bottom... the top floor\nmid   the middle\ntop   the last\n```\n";

/// Writes a crate of `files` (path under `src/`, text) beside the floors above, and runs
/// the gate on it: (passed, stdout + stderr).
fn gate(tag: &str, files: &[(&str, &str)]) -> (bool, String) {
    let d = common::scratch(tag);
    std::fs::create_dir_all(d.join("docs")).unwrap();
    std::fs::write(d.join("docs/design.md"), DESIGN).unwrap();
    for (path, text) in files {
        let p = d.join("src").join(path);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, text).unwrap();
    }
    let script = common::root().join("scripts/house-figures.py");
    let out = Command::new("python3")
        .arg(&script)
        .arg("--check")
        .arg(d.join("src"))
        .output()
        .expect("python3 runs the gate");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let _ = std::fs::remove_dir_all(&d);
    (out.status.success(), text)
}

/// A clean made-up crate: three rooms, each using only the floors above it.
fn clean() -> Vec<(&'static str, String)> {
    vec![
        ("lib.rs", "pub mod base;\npub mod mid;\npub mod top;\n".into()),
        ("base.rs", "pub fn one() -> u32 {\n    1\n}\n".into()),
        (
            "mid/mod.rs",
            "mod a;\nmod b;\npub use a::two;\npub fn three() -> u32 {\n    b::x() + crate::base::one()\n}\n".into(),
        ),
        ("mid/a.rs", "pub fn two() -> u32 {\n    super::b::x() * 2\n}\n".into()),
        ("mid/b.rs", "pub(super) fn x() -> u32 {\n    1\n}\n".into()),
        ("top.rs", "pub fn four() -> u32 {\n    crate::mid::three() + 1\n}\n".into()),
    ]
}

fn with(
    mut files: Vec<(&'static str, String)>,
    path: &'static str,
    text: String,
) -> Vec<(&'static str, String)> {
    files.retain(|(p, _)| *p != path);
    files.push((path, text));
    files
}

fn run(tag: &str, files: &[(&'static str, String)]) -> (bool, String) {
    let refs: Vec<(&str, &str)> = files.iter().map(|(p, t)| (*p, t.as_str())).collect();
    gate(tag, &refs)
}

#[test]
fn a_clean_crate_passes() {
    let (ok, out) = run("clean", &clean());
    assert!(ok, "{out}");
    assert!(out.contains("house gate: passed"), "{out}");
    assert!(out.contains("import_cycles: 0"), "{out}");
}

#[test]
fn a_long_function_fails_and_is_named() {
    let body: String = (0..160)
        .map(|i| format!("    let _v{i} = {i};\n"))
        .collect();
    let files = with(
        clean(),
        "base.rs",
        format!("pub fn one() -> u32 {{\n{body}    1\n}}\n"),
    );
    let (ok, out) = run("long-fn", &files);
    assert!(!ok, "{out}");
    assert!(out.contains("base.rs:1 one: 163 lines"), "{out}");
    assert!(out.contains("max_function_lines"), "{out}");
}

#[test]
fn a_long_file_fails_and_is_named() {
    // 3 + 4 n lines: 483 passes, 803 does not.
    let file = |n: usize| {
        let fns: String = (0..n)
            .map(|i| format!("pub fn f{i}() -> u32 {{\n    {i}\n}}\n\n"))
            .collect();
        format!("pub fn one() -> u32 {{\n    1\n}}\n{fns}")
    };
    let (ok, out) = run("file-483", &with(clean(), "base.rs", file(120)));
    assert!(ok, "{out}");
    let (ok, out) = run("file-803", &with(clean(), "base.rs", file(200)));
    assert!(!ok, "{out}");
    assert!(out.contains("base.rs: 803 lines"), "{out}");
    assert!(out.contains("max_file_lines"), "{out}");
}

#[test]
fn a_string_error_fails_but_not_in_the_cli_or_tests() {
    let files = with(
        clean(),
        "base.rs",
        "pub fn one() -> Result<u32, String> {\n    Ok(1)\n}\n".into(),
    );
    let (ok, out) = run("string-error", &files);
    assert!(!ok, "{out}");
    assert!(out.contains("base.rs:1 one"), "{out}");
    let files = with(
        clean(),
        "cli/mod.rs",
        "pub fn parse() -> Result<u32, String> {\n    Ok(1)\n}\n".into(),
    );
    let files = with(
        files,
        "base.rs",
        "pub fn one() -> u32 {\n    1\n}\n#[cfg(test)]\nmod tests {\n    fn t() -> Result<(), String> {\n        Ok(())\n    }\n}\n".into(),
    );
    let (ok, out) = run("string-error-allowed", &files);
    assert!(ok, "{out}");
}

#[test]
fn a_cycle_between_sibling_modules_fails_and_names_both_edges() {
    // `b` now calls back into `a`, which calls `b`: the circle issue 45 found in simulate.
    let files = with(
        clean(),
        "mid/b.rs",
        "use super::{a::two};\npub(super) fn x() -> u32 {\n    1\n}\npub(super) fn y() -> u32 {\n    two()\n}\n".into(),
    );
    let (ok, out) = run("module-cycle", &files);
    assert!(!ok, "{out}");
    assert!(out.contains("modules mid::a <-> mid::b"), "{out}");
    assert!(
        out.contains("mid::a -> mid::b (") && out.contains("mid::b -> mid::a ("),
        "{out}"
    );
    assert!(out.contains("mid/b.rs:1"), "{out}");
}

#[test]
fn a_reference_against_the_floors_fails_and_a_missing_room_too() {
    // `base` reaching down to `top` runs against the floors and closes a cycle of rooms.
    let files = with(
        clean(),
        "base.rs",
        "pub fn one() -> u32 {\n    1\n}\npub fn five() -> u32 {\n    crate::top::four() + 1\n}\n"
            .into(),
    );
    let (ok, out) = run("against", &files);
    assert!(!ok, "{out}");
    assert!(
        out.contains("base -> top (") && out.contains("base.rs:5"),
        "{out}"
    );
    assert!(out.contains("rooms base <-> mid <-> top"), "{out}");
    let files = with(
        clean(),
        "extra.rs",
        "pub fn six() -> u32 {\n    6\n}\n".into(),
    );
    let (ok, out) = run("unlisted", &files);
    assert!(!ok, "{out}");
    assert!(
        out.contains("rooms_missing_from_the_floors: 1\n  extra"),
        "{out}"
    );
}

#[test]
fn the_limits_file_gives_each_limit_a_reason() {
    let text = std::fs::read_to_string(common::root().join("scripts/house-limits.toml")).unwrap();
    for key in [
        "max_function_lines = 150",
        "max_file_lines = 700",
        "max_string_errors = 0",
        "max_import_cycles = 0",
    ] {
        let at = text.find(key).unwrap_or_else(|| panic!("{key} missing"));
        // The line before the limit is its reason, a comment.
        let before = text[..at].trim_end().rsplit('\n').next().unwrap();
        assert!(before.starts_with('#'), "{key} has no reason above it");
    }
    assert!(Path::new(&common::root().join("docs/design.md")).exists());
}
