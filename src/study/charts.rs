//! Study charts (plotters, with the embedded font), written atomically as PNG and SVG.

use super::*;

pub(super) use crate::plot::{chart_file, register_font};

/// One log-log chart of `y` against `x` with a line per method, drawn on any backend.
pub(super) fn draw_loglog<DB: plotters::prelude::DrawingBackend>(
    root: plotters::prelude::DrawingArea<DB, plotters::coord::Shift>,
    title: &str,
    xlabel: &str,
    series: &[(String, Vec<(f64, f64)>)],
    guide: Option<(&str, Vec<(f64, f64)>)>,
) -> Result<(), StudyError> {
    draw_chart(
        root,
        title,
        xlabel,
        "error (RMS of R - reference)",
        series,
        guide,
    )
}

/// A log-log chart with a line per series and an optional guide line.
pub(super) fn draw_chart<DB: plotters::prelude::DrawingBackend>(
    root: plotters::prelude::DrawingArea<DB, plotters::coord::Shift>,
    title: &str,
    xlabel: &str,
    ylabel: &str,
    series: &[(String, Vec<(f64, f64)>)],
    guide: Option<(&str, Vec<(f64, f64)>)>,
) -> Result<(), StudyError> {
    use plotters::prelude::*;
    let err = |e: &dyn std::fmt::Display| e.to_string();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let all: Vec<(f64, f64)> = series
        .iter()
        .flat_map(|s| s.1.iter().copied())
        .chain(guide.iter().flat_map(|g| g.1.iter().copied()))
        .filter(|p| p.0 > 0.0 && p.1 > 0.0)
        .collect();
    if all.is_empty() {
        return Err(StudyError::from("nothing to plot (no positive values)"));
    }
    let (x0, x1) = all
        .iter()
        .fold((f64::MAX, f64::MIN), |a, p| (a.0.min(p.0), a.1.max(p.0)));
    let (y0, y1) = all
        .iter()
        .fold((f64::MAX, f64::MIN), |a, p| (a.0.min(p.1), a.1.max(p.1)));
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(
            (x0 / 1.5..x1 * 1.5).log_scale(),
            (y0 / 2.0..y1 * 2.0).log_scale(),
        )
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .x_desc(xlabel)
        .y_desc(ylabel)
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(|e| err(&e))?;
    for (i, (name, pts)) in series.iter().enumerate() {
        let colour = Palette99::pick(i).to_rgba();
        let pts: Vec<(f64, f64)> = pts
            .iter()
            .copied()
            .filter(|p| p.0 > 0.0 && p.1 > 0.0)
            .collect();
        chart
            .draw_series(LineSeries::new(pts.clone(), colour.stroke_width(2)))
            .map_err(|e| err(&e))?
            .label(name.clone())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(2))
            });
        chart
            .draw_series(pts.iter().map(|&p| Circle::new(p, 3, colour.filled())))
            .map_err(|e| err(&e))?;
    }
    if let Some((name, pts)) = guide {
        chart
            .draw_series(LineSeries::new(pts, BLACK.stroke_width(1)))
            .map_err(|e| err(&e))?
            .label(name.to_string())
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], BLACK));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font(("sans-serif", 13))
        .draw()
        .map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

/// The file stems of the charts `charts` draws (the last only where points measured the
/// angular distribution).
pub(super) const STEMS: [&str; 4] = [
    "error-vs-time",
    "error-vs-rays",
    "eval-time-vs-accuracy",
    "distribution-vs-time",
];

/// Draws the charts as PNG and SVG into `dir`: error against time (the Pareto view) and
/// error against rays with the 1/sqrt(N) slope.
pub fn charts(points: &[Point], dir: &Path) -> Result<Vec<PathBuf>, StudyError> {
    use plotters::prelude::*;
    register_font();
    let mut methods: Vec<String> = points.iter().map(method).collect();
    methods.dedup();
    methods.sort();
    methods.dedup();
    let series = |x: &dyn Fn(&Point) -> f64| -> Vec<(String, Vec<(f64, f64)>)> {
        methods
            .iter()
            .map(|m| {
                let mut v: Vec<(f64, f64)> = points
                    .iter()
                    .filter(|p| &method(p) == m)
                    .map(|p| (x(p), p.error))
                    .collect();
                v.sort_by(|a, b| a.0.total_cmp(&b.0));
                (m.clone(), v)
            })
            .collect()
    };
    let by_time = series(&|p| p.wall_s.max(1e-4));
    // The angular distribution against the reference run's, where it has one.
    let by_spread: Vec<(String, Vec<(f64, f64)>)> = methods
        .iter()
        .map(|m| {
            let mut v: Vec<(f64, f64)> = points
                .iter()
                .filter(|p| &method(p) == m)
                .filter_map(|p| Some((p.wall_s.max(1e-4), p.distribution_l1?.max(1e-6))))
                .collect();
            v.sort_by(|a, b| a.0.total_cmp(&b.0));
            (m.clone(), v)
        })
        .filter(|(_, v)| !v.is_empty())
        .collect();
    // Representations: query time against the error of their hemispherical integral.
    let mut reprs: Vec<crate::brdf::Kind> = points.iter().map(|p| p.representation).collect();
    reprs.sort();
    reprs.dedup();
    let by_repr: Vec<(String, Vec<(f64, f64)>)> = reprs
        .iter()
        .map(|r| {
            let mut v: Vec<(f64, f64)> = points
                .iter()
                .filter(|p| p.representation == *r)
                .map(|p| (p.query_ns.max(1.0), p.repr_error.max(1e-12)))
                .collect();
            v.sort_by(|a, b| a.0.total_cmp(&b.0));
            (r.to_string(), v)
        })
        .collect();
    let by_rays = series(&|p| p.rays as f64);
    // The 1/sqrt(N) guide through the first method's first point.
    let guide = by_rays
        .first()
        .and_then(|s| s.1.first().copied())
        .map(|(n0, e0)| {
            let n1 = points.iter().map(|p| p.rays as f64).fold(n0, f64::max);
            ("1/sqrt(N)", vec![(n0, e0), (n1, e0 * (n0 / n1).sqrt())])
        });
    let mut written = Vec::new();
    let spread_chart = (
        STEMS[3],
        "Angular distribution against the reference's (L1) and wall time",
        "wall time (s)",
        &by_spread,
        None,
    );
    let charts = [
        (
            STEMS[0],
            "Error against wall time (lower left is better)",
            "wall time (s)",
            &by_time,
            None,
        ),
        (
            STEMS[1],
            "Error against rays per direction",
            "rays per direction",
            &by_rays,
            guide.clone(),
        ),
        (
            STEMS[2],
            "BRDF query time against the error of its hemispherical integral",
            "query time (ns)",
            &by_repr,
            None,
        ),
    ];
    let spread = (!by_spread.is_empty()).then_some(spread_chart);
    for (stem, title, xlabel, data, g) in charts.into_iter().chain(spread) {
        let png = dir.join(format!("{stem}.png"));
        let svg = dir.join(format!("{stem}.svg"));
        // The bitmap backend picks its format from the extension: the temporary keeps it.
        chart_file(&png, |tmp| {
            draw_loglog(
                BitMapBackend::new(tmp, (900, 600)).into_drawing_area(),
                title,
                xlabel,
                data,
                g.clone(),
            )
        })?;
        chart_file(&svg, |tmp| {
            draw_loglog(
                SVGBackend::new(tmp, (900, 600)).into_drawing_area(),
                title,
                xlabel,
                data,
                g.clone(),
            )
        })?;
        written.push(png);
        written.push(svg);
    }
    Ok(written)
}
