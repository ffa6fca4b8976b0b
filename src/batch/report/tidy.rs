//! What a report row says, made readable: repeated warnings grouped (issue 71: a foil's row
//! showed 11 warnings then "and 122 more", most of them one warning at other angles and
//! cells), the methods each angle used, and paths relative to the page (a report is
//! shared; the user's home folder is not part of it).

use std::path::{Component, Path};

pub use crate::warning_codes::{WarningGroup, group as group_warnings};

/// The methods a run used, per incident angle (`methods[i]` at `thetas[i]`, as
/// `Settings::methods_of` says them): once, where every angle used the same.
pub fn methods_line(thetas: &[f64], methods: &[String]) -> String {
    match methods.first() {
        Some(first) if methods.iter().all(|m| m == first) => {
            format!("methods: {first} at every angle")
        }
        _ => {
            let per: Vec<String> = thetas
                .iter()
                .zip(methods)
                .map(|(t, m)| format!("{t} deg: {m}"))
                .collect();
            format!("methods: {}", per.join("; "))
        }
    }
}

/// `text` with each absolute path in `paths` written relative to the page's folder
/// `folder` (each path matched as given and canonical, the longest first, in one pass):
/// the page names files as a reader of the page finds them, never by the machine's
/// absolute paths. A path more than two folders above the page's is named by its file
/// name alone (a relative path that climbs to the root says as much as an absolute one).
pub fn relative_paths(text: &str, folder: &Path, paths: &[&Path]) -> String {
    let base = std::fs::canonicalize(folder).unwrap_or_else(|_| folder.to_path_buf());
    let mut pairs: Vec<(String, String)> = Vec::new();
    for p in paths {
        let canonical = std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf());
        let rel = super::relative(&base, &canonical);
        let climbs = rel
            .components()
            .take_while(|c| matches!(c, Component::ParentDir))
            .count();
        let rel = if rel.as_os_str().is_empty() {
            ".".to_string()
        } else if climbs > 2 {
            p.file_name()
                .map_or_else(|| ".".to_string(), |n| n.to_string_lossy().into_owned())
        } else {
            rel.display().to_string()
        };
        for form in [p.to_path_buf(), canonical] {
            let abs = form.display().to_string();
            if form.is_absolute() && !pairs.iter().any(|(a, _)| *a == abs) {
                pairs.push((abs, rel.clone()));
            }
        }
    }
    pairs.sort_by_key(|p| std::cmp::Reverse(p.0.len()));
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    'scan: while let Some(c) = rest.chars().next() {
        for (abs, rel) in &pairs {
            if let Some(after) = rest.strip_prefix(abs.as_str()) {
                out.push_str(rel);
                rest = after;
                continue 'scan;
            }
        }
        out.push(c);
        rest = &rest[c.len_utf8()..];
    }
    out
}

/// Whether `text` holds an absolute path: a word starting at the root (`/home/...`).
pub fn holds_absolute_path(text: &str) -> bool {
    text.split(|c: char| c.is_whitespace() || matches!(c, '\'' | '"' | '(' | '>' | '='))
        .any(|w| {
            let p = Path::new(w);
            p.is_absolute()
                && p.components()
                    .filter(|c| matches!(c, Component::Normal(_)))
                    .count()
                    > 1
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn methods_are_said_once_where_every_angle_shares_them() {
        let same = vec!["rays 400-700 nm".to_string(); 3];
        assert_eq!(
            methods_line(&[0.0, 30.0, 60.0], &same),
            "methods: rays 400-700 nm at every angle"
        );
        let mixed = vec![
            "rigorous 400-700 nm".to_string(),
            "rays 400-500 nm, rigorous 500-700 nm".to_string(),
        ];
        assert_eq!(
            methods_line(&[0.0, 60.0], &mixed),
            "methods: 0 deg: rigorous 400-700 nm; 60 deg: rays 400-500 nm, rigorous 500-700 nm"
        );
    }

    /// Absolute paths become relative to the page's folder, and the check finds what is
    /// left.
    #[test]
    fn paths_are_written_relative_to_the_page() {
        let folder = Path::new("/work/lib/report");
        let out = Path::new("/work/lib/b/out");
        let t = relative_paths(
            "film-table.gsb is missing from /work/lib/b/out: run goniospec batch merge",
            folder,
            &[out],
        );
        assert_eq!(
            t,
            "film-table.gsb is missing from ../b/out: run goniospec batch merge"
        );
        assert!(!holds_absolute_path(&t));
        // Far above the page: the file name alone; and one pass, so a path whose relative
        // form holds it again is not rewritten twice.
        let t = relative_paths(
            "sample /srv/x/meshes/gold.toml",
            folder,
            &[Path::new("/srv/x/meshes/gold.toml")],
        );
        assert_eq!(t, "sample gold.toml");
        let t = relative_paths("in /work/lib/b", folder, &[Path::new("/work/lib/b")]);
        assert_eq!(t, "in ../b");
        assert!(holds_absolute_path("sample /home/ana/paint.toml"));
        assert!(!holds_absolute_path("ratio 1/2 at 380-780 nm"));
    }
}
