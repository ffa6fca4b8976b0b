//! `compare`'s files: every figure as CSV and JSON, and the picture (PNG and SVG).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::{CompareError, Material, Report};

/// The files `compare -o DIR` writes (the output policy guards the folder for them).
pub fn output_names() -> Vec<String> {
    [
        "angles.csv",
        "nodes.csv",
        "travel.csv",
        "compare.json",
        "compare.png",
        "compare.svg",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect()
}

fn opt(v: Option<f64>) -> String {
    v.map_or_else(String::new, |x| format!("{x:.4}"))
}

/// The per-angle figures as CSV.
fn angles_csv(r: &Report) -> String {
    let mut s = String::from(
        "theta_i_deg,phi_i_deg,nodes,delta_e_mean,delta_e_median,delta_e_p95,delta_l_mean,delta_l_median,delta_l_p95,a_peak_per_sr,a_peak_at_deg,a_fwhm_deg,b_peak_per_sr,b_peak_at_deg,b_fwhm_deg\n",
    );
    for a in &r.angles {
        let _ = writeln!(
            s,
            "{:.4},{:.4},{},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.6e},{:.2},{},{:.6e},{:.2},{}",
            a.theta_i_deg,
            a.phi_i_deg,
            a.nodes,
            a.delta_e.mean,
            a.delta_e.median,
            a.delta_e.p95,
            a.delta_e_lightness.mean,
            a.delta_e_lightness.median,
            a.delta_e_lightness.p95,
            a.lobe_a.peak_per_sr,
            a.lobe_a.peak_at_deg,
            opt(a.lobe_a.fwhm_deg),
            a.lobe_b.peak_per_sr,
            a.lobe_b.peak_at_deg,
            opt(a.lobe_b.fwhm_deg),
        );
    }
    s
}

/// Every node as CSV: where, its projected solid angle, both CIELAB colours, the
/// differences.
fn nodes_csv(r: &Report) -> String {
    let mut s = String::from(
        "theta_i_deg,theta_o_deg,phi_o_deg,weight_sr,a_l,a_a,a_b,b_l,b_a,b_b,delta_e,delta_l\n",
    );
    for n in &r.nodes {
        let (t, p) = crate::geom::angles(n.wo);
        let _ = writeln!(
            s,
            "{:.4},{:.4},{:.4},{:.6e},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.5},{:.5}",
            n.theta_i_deg,
            t.to_degrees(),
            p.to_degrees(),
            n.weight,
            n.lab_a[0],
            n.lab_a[1],
            n.lab_a[2],
            n.lab_b[0],
            n.lab_b[1],
            n.lab_b[2],
            n.de,
            n.de_lightness
        );
    }
    s
}

/// The colour travel under 45 deg light as CSV (empty where 45 deg cannot be compared).
fn travel_csv(r: &Report) -> String {
    let mut s = String::from("aspecular_deg,a_l,a_c,a_h_deg,b_l,b_c,b_h_deg,delta_e\n");
    for t in &r.travel {
        let _ = writeln!(
            s,
            "{:.0},{:.4},{:.4},{:.2},{:.4},{:.4},{:.2},{:.4}",
            t.aspecular_deg,
            t.a_lch[0],
            t.a_lch[1],
            t.a_lch[2],
            t.b_lch[0],
            t.b_lch[1],
            t.b_lch[2],
            t.delta_e
        );
    }
    s
}

/// Writes every file of [`output_names`] into `dir` (each atomically), drawing the
/// picture of `a` and `b`; returns the paths written.
pub fn write_outputs(
    r: &Report,
    a: &Material,
    b: &Material,
    dir: &Path,
) -> Result<Vec<PathBuf>, CompareError> {
    let text = |name: &str, body: String| -> Result<PathBuf, CompareError> {
        let p = dir.join(name);
        crate::io::write_atomic(&p, |w| w.write_all(body.as_bytes())).map_err(|source| {
            CompareError::Write {
                path: p.display().to_string(),
                source,
            }
        })?;
        Ok(p)
    };
    use std::io::Write as _;
    std::fs::create_dir_all(dir).map_err(|source| CompareError::Write {
        path: dir.display().to_string(),
        source,
    })?;
    let json = serde_json::to_string_pretty(r)
        .map_err(|e| CompareError::from(format!("the report does not serialise: {e}")))?;
    let mut written = vec![
        text("angles.csv", angles_csv(r))?,
        text("nodes.csv", nodes_csv(r))?,
        text("travel.csv", travel_csv(r))?,
        text("compare.json", json + "\n")?,
    ];
    let picture = super::picture::Picture::new(r, a, b);
    for name in ["compare.png", "compare.svg"] {
        let p = dir.join(name);
        picture.write(&p)?;
        written.push(p);
    }
    Ok(written)
}
