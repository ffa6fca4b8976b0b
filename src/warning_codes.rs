//! Each kind of warning a run keeps has a short code, and docs/warnings.md an anchor of
//! that name with the why and what to do (issue 71: a single warning ran to 900
//! characters with its citations inline, and `info` listed 20 where the summary showed
//! 3). The run's summary, `info` and `batch report` all list the `.gsa`'s warnings
//! grouped by kind ([`group`]): one line per kind, with its code and how many more like
//! it there were (the same warning at other angles, bins or cells).

/// Codes and the words that mark their warnings (the first that matches wins).
const CODES: &[(&str, &[&str])] = &[
    ("depth-cut", &["cut by --max-depth or --max-segments"]),
    ("cutoff", &["weaker than --cutoff"]),
    (
        "limited-events",
        &["met absorbing facets that change the wave"],
    ),
    (
        "partial-coherence",
        &["the beamlet overlaps of this lossless sample"],
    ),
    (
        "created-energy",
        &["came from ray series that created energy"],
    ),
    ("open-sides", &["escaped through the sides"]),
    ("mie-envelope", &["exceeded its tabulated envelope"]),
    ("leak", &["met an interface from the wrong medium"]),
    ("diffraction-held", &["the diffraction transform held"]),
    ("mean-plane", &["reflects from its mean plane"]),
    (
        "coherent-order",
        &[
            "coherent specular order",
            "tangent plane the diffraction method",
        ],
    ),
    (
        "grating-orders",
        &["orders are", "its order", "diffraction orders"],
    ),
    ("curvature", &["curvature radius"]),
    ("small-bodies", &["small against the wavelength"]),
    ("packing", &["packs its particles"]),
    (
        "coating-radius",
        &["interferes fully whatever --coherence-radius-nm"],
    ),
    ("unphysical", &["written with --allow-unphysical"]),
];

/// The code of warning `w`, or `other` where none is known.
pub fn code_of(w: &str) -> &'static str {
    CODES
        .iter()
        .find(|(_, marks)| marks.iter().any(|m| w.contains(m)))
        .map_or("other", |(c, _)| c)
}

/// Every code (for the documentation check).
pub fn codes() -> impl Iterator<Item = &'static str> {
    CODES.iter().map(|(c, _)| *c).chain(["other"])
}

/// One kind of warning: its code, the first of its kind, and how many there were.
#[derive(Clone, Debug, PartialEq)]
pub struct WarningGroup {
    pub code: &'static str,
    pub example: String,
    pub count: usize,
}

impl WarningGroup {
    /// The group as one line: the first warning, how many more like it, and its code
    /// with where its why is.
    pub fn line(&self) -> String {
        let more = match self.count {
            1 => String::new(),
            n => format!(" (and {} more like it)", n - 1),
        };
        format!(
            "{}{more} [{}: docs/warnings.md#{}]",
            self.example, self.code, self.code
        )
    }
}

/// The warning's kind: its code, and its text without the incident angle it was said at
/// (`theta_i N deg: `) and with every number replaced by `#`, so one warning at several
/// angles, cells or wavelengths is one kind.
fn kind(w: &str) -> String {
    let body = match w.strip_prefix("theta_i ") {
        Some(rest) => rest.split_once(" deg: ").map_or(w, |(_, b)| b),
        None => w,
    };
    let mut key = String::with_capacity(body.len());
    let mut in_number = false;
    for c in body.chars() {
        let numeric = c.is_ascii_digit() || (in_number && matches!(c, '.' | 'e' | '-' | '+'));
        if numeric {
            if !in_number {
                key.push('#');
            }
            in_number = true;
        } else {
            in_number = false;
            key.push(c);
        }
    }
    key
}

/// `warnings` grouped by kind, in the order each kind first appears.
pub fn group(warnings: &[String]) -> Vec<WarningGroup> {
    let mut groups: Vec<(String, WarningGroup)> = Vec::new();
    for w in warnings {
        let k = kind(w);
        match groups.iter_mut().find(|(key, _)| *key == k) {
            Some((_, g)) => g.count += 1,
            None => groups.push((
                k,
                WarningGroup {
                    code: code_of(w),
                    example: w.clone(),
                    count: 1,
                },
            )),
        }
    }
    groups.into_iter().map(|(_, g)| g).collect()
}

/// `warnings` as `info` lists them: a count, then one line per kind.
pub fn describe(warnings: &[String]) -> String {
    if warnings.is_empty() {
        return "warnings: none\n".to_string();
    }
    let groups = group(warnings);
    let mut s = format!(
        "warnings ({}, in {} kinds):\n",
        warnings.len(),
        groups.len()
    );
    for g in &groups {
        s += &format!("  - {}\n", g.line());
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One warning said at several angles, with different numbers, is one kind; a
    /// different warning is another; the order is that of first appearance.
    #[test]
    fn warnings_group_by_kind_whatever_their_angle_and_numbers() {
        let w: Vec<String> = [
            "theta_i 0 deg: 12 of 40 cells took rays (the rigorous solver did not converge to 2e-2)",
            "theta_i 0 deg: the tile is 3.5 um",
            "theta_i 30 deg: 17 of 40 cells took rays (the rigorous solver did not converge to 2e-2)",
            "theta_i 60 deg: 40 of 40 cells took rays (the rigorous solver did not converge to 1.5e-2)",
        ]
        .map(String::from)
        .to_vec();
        let g = group(&w);
        assert_eq!(g.len(), 2, "{g:?}");
        assert_eq!(g[0].count, 3);
        assert_eq!(g[0].example, w[0]);
        assert_eq!(g[1].count, 1);
        assert_eq!(g[1].example, w[1]);
        assert!(
            g[0].line()
                .ends_with("(and 2 more like it) [other: docs/warnings.md#other]"),
            "{}",
            g[0].line()
        );
    }

    /// Every code has its anchor in docs/warnings.md (a heading of that name), so the
    /// pointer each line ends with leads somewhere.
    #[test]
    fn every_code_is_documented() {
        let doc = include_str!("../docs/warnings.md");
        for c in codes() {
            assert!(
                doc.contains(&format!("## {c}\n")),
                "docs/warnings.md lacks '## {c}'"
            );
        }
    }

    #[test]
    fn codes_find_their_warnings() {
        assert_eq!(
            code_of(
                "up to 2.4e-2 of the launched power per tree was cut by --max-depth or --max-segments"
            ),
            "depth-cut"
        );
        assert_eq!(code_of("something new"), "other");
    }
}
