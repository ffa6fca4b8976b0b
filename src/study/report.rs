//! Writing a study: `points.csv`, `report.md` with verdicts, and the area sweep's CSV.

use super::*;

/// Writes `area.csv` and the chart of total reflectance against sampled area.
pub fn write_area(points: &[AreaPoint], dir: &Path) -> Result<Vec<PathBuf>, StudyError> {
    use plotters::prelude::*;
    if points.is_empty() {
        return Ok(Vec::new());
    }
    std::fs::create_dir_all(dir).map_err(|e| e.to_string())?;
    crate::io::write_atomic(&dir.join("area.csv"), |w| {
        writeln!(w, "coherence,tiles,area_um2,rays,R")?;
        for p in points {
            writeln!(
                w,
                "{},{}x{},{},{},{:.6e}",
                p.coherence.name(),
                p.tiles[0],
                p.tiles[1],
                p.area_um2,
                p.rays,
                p.r
            )?;
        }
        Ok(())
    })
    .map_err(|e| e.to_string())?;
    register_font();
    let mut names: Vec<&str> = points.iter().map(|p| p.coherence.name()).collect();
    names.dedup();
    let series: Vec<(String, Vec<(f64, f64)>)> = names
        .iter()
        .map(|n| {
            (
                n.to_string(),
                points
                    .iter()
                    .filter(|p| p.coherence.name() == *n)
                    .map(|p| (p.area_um2, p.r))
                    .collect(),
            )
        })
        .collect();
    let png = dir.join("reflectance-vs-area.png");
    let svg = dir.join("reflectance-vs-area.svg");
    let title = "Total reflectance against sampled area (rays in proportion)";
    chart_file(&png, |tmp| {
        draw_chart(
            BitMapBackend::new(tmp, (900, 600)).into_drawing_area(),
            title,
            "sampled area (um^2)",
            "total reflectance R",
            &series,
            None,
        )
    })?;
    chart_file(&svg, |tmp| {
        draw_chart(
            SVGBackend::new(tmp, (900, 600)).into_drawing_area(),
            title,
            "sampled area (um^2)",
            "total reflectance R",
            &series,
            None,
        )
    })?;
    Ok(vec![png, svg])
}

/// Writes `points.csv` and `report.md` into `dir` (atomically each).
pub fn write(st: &Study, points: &[Point], reference: &str, dir: &Path) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    write_points_csv(st, points, dir)?;
    crate::io::write_atomic(&dir.join("report.md"), |w| {
        writeln!(w, "# Study: {}\n", st.name)?;
        if !st.notes.trim().is_empty() {
            writeln!(w, "{}\n", st.notes.trim())?;
        }
        writeln!(
            w,
            "Sample `{}`, incident angles {:?} deg, {} wavelength bins {}..{} nm.",
            st.sample_path.display(),
            st.theta_i,
            st.edges.len() - 1,
            st.edges[0],
            st.edges[st.edges.len() - 1]
        )?;
        writeln!(
            w,
            "Error: RMS over incident angles and bins of the directional reflectance against the {reference}. \
             A point holds when its error is at most {} (the study's tolerance). \
             Distribution L1: the mean over incident angles and bins of the L1 distance between the point's \
             reflected distribution over the buckets and the reference run's, each normalised to 1 \
             (0 identical, 2 disjoint; `-` where the reference has none).\n",
            st.tolerance
        )?;
        writeln!(
            w,
            "| method | rays | wall s | error | error bars | distribution L1 | dropped | holds | query ns | representation error |"
        )?;
        writeln!(w, "|---|---|---|---|---|---|---|---|---|---|")?;
        for p in points {
            writeln!(
                w,
                "| {} | {} | {:.3} | {:.2e} | {:.1e} | {} | {:.1e} | {} | {:.0} | {:.2e} |",
                method(p),
                p.rays,
                p.wall_s,
                p.error,
                p.stderr,
                p.distribution_l1
                    .map_or("-".to_string(), |d| format!("{d:.3}")),
                p.dropped,
                if holds(p, st.tolerance) {
                    "yes"
                } else {
                    "**no**"
                },
                p.query_ns,
                p.repr_error
            )?;
        }
        // Where each method breaks: its verdict at the largest ray count.
        let mut methods: Vec<String> = points.iter().map(method).collect();
        methods.sort();
        methods.dedup();
        let (mut ok, mut broken) = (Vec::new(), Vec::new());
        for m in &methods {
            if let Some(p) = points
                .iter()
                .filter(|p| &method(p) == m)
                .max_by_key(|p| p.rays)
            {
                let mut line = format!(
                    "`{m}` (error {:.2e}, error bars {:.1e} at {} rays)",
                    p.error, p.stderr, p.rays
                );
                if p.unphysical.is_some() {
                    line.push_str(": impossible values (R > 1 or energy created)");
                }
                if holds(p, st.tolerance) {
                    ok.push(line);
                } else {
                    broken.push(line);
                }
            }
        }
        writeln!(
            w,
            "\nWhere methods break (verdict at each method's largest ray count):\n"
        )?;
        for l in &broken {
            writeln!(w, "- breaks: {l}")?;
        }
        for l in &ok {
            writeln!(w, "- holds: {l}")?;
        }
        // The Pareto front: points no faster point beats in error.
        let mut order: Vec<&Point> = points.iter().collect();
        order.sort_by(|a, b| {
            a.wall_s
                .total_cmp(&b.wall_s)
                .then(a.error.total_cmp(&b.error))
        });
        let mut best = f64::INFINITY;
        writeln!(
            w,
            "\nPareto front (each point is more accurate than every faster one):\n"
        )?;
        for p in order {
            if p.error < best {
                best = p.error;
                writeln!(
                    w,
                    "- {:.3} s: error {:.2e} with {} at {} rays",
                    p.wall_s,
                    p.error,
                    method(p),
                    p.rays
                )?;
            }
        }
        if methods.len() == 1
            && let Some(s) = convergence_slope(points)
        {
            writeln!(
                w,
                "\nLeast-squares slope of log(error) against log(rays): {s:.3} (Monte Carlo: -0.5)."
            )?;
        }
        Ok(())
    })
}

/// A method: everything in a point but the ray count (one line per method in the charts).
/// Settings at their defaults are left out of the name.
pub(super) fn method(p: &Point) -> String {
    let v = &p.variant;
    let rho = if v.radius.is_infinite() {
        "inf".to_string()
    } else {
        format!("{}", v.radius)
    };
    let mut s = format!(
        "{} rho={} bins={} {} {}",
        v.coherence.name(),
        rho,
        v.theta_o_bins,
        v.backend,
        p.representation
    );
    let d = TraceLimits::default();
    if v.cutoff != d.cutoff {
        s.push_str(&format!(" cutoff={:e}", v.cutoff));
    }
    if v.max_depth != d.max_depth {
        s.push_str(&format!(" depth={}", v.max_depth));
    }
    if v.precision != PhasePrecision::F64 {
        s.push_str(&format!(" {}", v.precision.name()));
    }
    if v.origin_nm != 0.0 {
        s.push_str(&format!(" origin={:e}nm", v.origin_nm));
    }
    s
}

/// Writes `points.csv` into `dir` (atomically): one row per point, every swept setting and
/// every measured figure.
fn write_points_csv(st: &Study, points: &[Point], dir: &Path) -> std::io::Result<()> {
    crate::io::write_atomic(&dir.join("points.csv"), |w| {
        writeln!(
            w,
            "backend,coherence,coherence_radius_nm,theta_o_bins,cutoff,max_depth,phase,origin_nm,rays,representation,wall_s,traced_rays,peak_mem_mb,error,error_stderr,dropped,holds,query_ns,repr_error,distribution_l1"
        )?;
        for p in points {
            let v = &p.variant;
            writeln!(
                w,
                "{},{},{},{},{:e},{},{},{:e},{},{},{:.4},{},{:.1},{:.6e},{:.6e},{:.3e},{},{:.0},{:.6e},{}",
                v.backend,
                v.coherence.name(),
                v.radius,
                v.theta_o_bins,
                v.cutoff,
                v.max_depth,
                v.precision.name(),
                v.origin_nm,
                p.rays,
                p.representation,
                p.wall_s,
                p.traced_rays,
                p.peak_mem_mb,
                p.error,
                p.stderr,
                p.dropped,
                holds(p, st.tolerance),
                p.query_ns,
                p.repr_error,
                p.distribution_l1
                    .map_or(String::new(), |d| format!("{d:.6e}"))
            )?;
        }
        Ok(())
    })
}
