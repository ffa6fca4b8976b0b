//! What a match writes besides the fitted sample: the search's trace as CSV and its chart
//! (error against evaluations), atomically.

use std::io::Write;
use std::path::{Path, PathBuf};

use super::{Outcome, RecipeError, Vary};

/// The files `match -o DIR` writes into DIR (the comparison goes into `DIR/compare`, the
/// candidates' records into `DIR/candidates`).
pub fn output_names() -> Vec<String> {
    [
        "fitted.toml",
        "fitted.gsa",
        "trace.csv",
        "trace.png",
        "trace.svg",
        "match.json",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect()
}

/// `trace.csv`: one row per evaluation, in order: its values, its objective, the best so
/// far, whether an earlier run's record gave it, and the seconds it took.
pub fn write_trace(path: &Path, vary: &[Vary], o: &Outcome) -> Result<(), RecipeError> {
    crate::io::write_atomic(path, |w| {
        write!(w, "evaluation")?;
        for v in vary {
            write!(w, ",{}", v.path)?;
        }
        writeln!(w, ",objective,best_so_far,from_record,seconds")?;
        let mut best = f64::INFINITY;
        for (k, e) in o.trace.iter().enumerate() {
            best = best.min(e.objective);
            write!(w, "{}", k + 1)?;
            for x in &e.values {
                write!(w, ",{x}")?;
            }
            writeln!(
                w,
                ",{},{best},{},{:.3}",
                e.objective,
                u8::from(e.cached),
                e.seconds
            )?;
        }
        Ok(())
    })
    .map_err(|e| RecipeError::from(format!("{}: {e}", path.display())))
}

/// `trace.png` and `trace.svg`: every evaluation's objective and the best so far against
/// the evaluation's number.
pub fn write_chart(dir: &Path, o: &Outcome, ylabel: &str) -> Result<Vec<PathBuf>, RecipeError> {
    use plotters::prelude::*;
    crate::plot::register_font();
    let points: Vec<(f64, f64)> = o
        .trace
        .iter()
        .enumerate()
        .map(|(k, e)| ((k + 1) as f64, e.objective))
        .collect();
    let mut best = f64::INFINITY;
    let best_line: Vec<(f64, f64)> = points
        .iter()
        .map(|&(x, y)| {
            best = best.min(y);
            (x, best)
        })
        .collect();
    let y1 = points.iter().map(|p| p.1).fold(0.0, f64::max) * 1.05 + 1e-9;
    let x1 = points.len() as f64 + 0.5;
    fn draw<DB: DrawingBackend>(
        root: DrawingArea<DB, plotters::coord::Shift>,
        points: &[(f64, f64)],
        best_line: &[(f64, f64)],
        (x1, y1): (f64, f64),
        ylabel: &str,
    ) -> Result<(), crate::plot::PlotError> {
        let err = |e: &dyn std::fmt::Display| crate::plot::PlotError::from(e.to_string());
        root.fill(&WHITE).map_err(|e| err(&e))?;
        let mut chart = ChartBuilder::on(&root)
            .caption("goniospec match: the search", ("sans-serif", 22))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(0.5..x1, 0.0..y1)
            .map_err(|e| err(&e))?;
        chart
            .configure_mesh()
            .x_desc("evaluation")
            .y_desc(ylabel)
            .draw()
            .map_err(|e| err(&e))?;
        chart
            .draw_series(
                points
                    .iter()
                    .map(|&p| Circle::new(p, 3, RGBColor(120, 120, 120).filled())),
            )
            .map_err(|e| err(&e))?
            .label("each candidate")
            .legend(|(x, y)| Circle::new((x + 10, y), 3, RGBColor(120, 120, 120).filled()));
        chart
            .draw_series(LineSeries::new(
                best_line.iter().copied(),
                BLUE.stroke_width(2),
            ))
            .map_err(|e| err(&e))?
            .label("best so far")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE));
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| err(&e))?;
        root.present().map_err(|e| err(&e))
    }
    let png = dir.join("trace.png");
    crate::plot::chart_file(&png, |p| {
        draw(
            BitMapBackend::new(p, (800, 500)).into_drawing_area(),
            &points,
            &best_line,
            (x1, y1),
            ylabel,
        )
    })?;
    let svg = dir.join("trace.svg");
    crate::plot::chart_file(&svg, |p| {
        draw(
            SVGBackend::new(p, (800, 500)).into_drawing_area(),
            &points,
            &best_line,
            (x1, y1),
            ylabel,
        )
    })?;
    Ok(vec![png, svg])
}
