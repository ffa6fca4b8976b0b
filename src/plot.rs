//! Pictures of a BRDF (`goniospec plot`) and the shared chart plumbing (plotters with the
//! embedded DejaVu font, atomic PNG/SVG files) that the study charts use too.
//!
//! A lobe plot has two panels for one incident direction:
//! - the lobe in the plane of incidence, `f(wi, wo, lambda) cos(theta_o)` (1/sr, the
//!   reflected radiance per unit incident irradiance) against the signed outgoing angle
//!   (positive: the forward, specular side), drawn in polar form, one curve per few
//!   wavelengths coloured by wavelength;
//! - the hemisphere of outgoing directions as a projected disc (`sin(theta_o)` from the
//!   centre, the specular side to the right), each point the sRGB colour of the reflected
//!   light under a unit D65 irradiance from `wi` (radiance factor `pi f cos(theta_i)`,
//!   CIE 1931 2-degree observer, IEC 61966-2-1), scaled so its brightest 1 % saturates;
//!   the scale is printed in the panel's title.

use std::path::Path;

use glam::DVec3;
use rayon::prelude::*;

use crate::brdf::Brdf;
use crate::geom::from_spherical;
use crate::render::colour;

/// What stops a picture: drawing it, or writing its file.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// The file could not be written (the drawing's own error included).
    #[error("{path}: {source}")]
    Write {
        path: String,
        #[source]
        source: std::io::Error,
    },
    /// Not a picture goniospec writes (the message says which are).
    #[error("{0}")]
    Format(String),
    /// The picture cannot be drawn (the BRDF or the plotting library says why).
    #[error("{0}")]
    Draw(String),
}

message_error!(PlotError, PlotError::Draw);

/// Draws a chart into `path` atomically (`draw` renders to the temporary path it is given;
/// its error, whatever its type, is reported with the path).
pub fn chart_file<E: std::fmt::Display>(
    path: &Path,
    draw: impl FnOnce(&Path) -> Result<(), E>,
) -> Result<(), PlotError> {
    crate::io::write_atomic_path(path, |tmp| {
        draw(tmp).map_err(|e| std::io::Error::other(e.to_string()))
    })
    .map_err(|source| PlotError::Write {
        path: path.display().to_string(),
        source,
    })
}

/// Registers the embedded DejaVu Sans (the `dejavu` crate) once: no system font library.
pub fn register_font() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let _ = plotters::style::register_font(
            "sans-serif",
            plotters::style::FontStyle::Normal,
            dejavu::sans::regular(),
        );
    });
}

/// The polar radius of a lobe value `v` (1/sr) on a plot whose peak is `rmax`: `v`
/// itself, or with `log_decades = Some(n)` a log scale on which `rmax` stays `rmax` and
/// `rmax 10^-n` and below fall to the centre. A negative estimate (cross terms:
/// docs/design.md §4) has no polar radius and is drawn at 0, which the plot's caption
/// counts; drawn as it is, it went below the horizon.
pub fn lobe_radius(v: f64, rmax: f64, log_decades: Option<u32>) -> f64 {
    match log_decades {
        _ if v <= 0.0 => 0.0,
        Some(n) => rmax * (1.0 + (v / rmax).log10() / f64::from(n)).max(0.0),
        None => v,
    }
}

/// The lobe in the plane of incidence.
#[derive(Clone, Debug, PartialEq)]
pub struct Lobe {
    /// Signed outgoing polar angles, degrees (positive: forward, `phi_o = phi_i + 180`).
    pub theta_o_deg: Vec<f64>,
    /// `(wavelength nm, f cos(theta_o) per angle)` for the plotted wavelengths.
    pub curves: Vec<(f64, Vec<f64>)>,
}

/// The lobe of `brdf` for incidence `(theta_i, phi_i)` (degrees) at every degree from -89
/// to 89, for `count` wavelength bins spread over the BRDF's range.
pub fn lobe(brdf: &(dyn Brdf + Sync), theta_i_deg: f64, phi_i_deg: f64, count: usize) -> Lobe {
    let lambdas = &brdf.meta().lambda_nm;
    let nl = lambdas.len();
    let picks: Vec<usize> = if nl <= count {
        (0..nl).collect()
    } else {
        (0..count)
            .map(|k| (k as f64 * (nl - 1) as f64 / (count - 1).max(1) as f64).round() as usize)
            .collect()
    };
    let wi = from_spherical(theta_i_deg.to_radians(), phi_i_deg.to_radians());
    let theta_o_deg: Vec<f64> = (-89..=89).map(f64::from).collect();
    let values: Vec<Vec<f64>> = theta_o_deg
        .par_iter()
        .map(|&t| {
            let phi = if t >= 0.0 {
                phi_i_deg + 180.0
            } else {
                phi_i_deg
            };
            let wo = from_spherical(t.abs().to_radians(), phi.to_radians());
            let mut out = vec![0.0; nl];
            brdf.eval(wi, wo, &mut out);
            out.iter().map(|v| v * wo.z).collect()
        })
        .collect();
    Lobe {
        theta_o_deg,
        curves: picks
            .iter()
            .map(|&j| (lambdas[j], values.iter().map(|v| v[j]).collect()))
            .collect(),
    }
}

/// Linear sRGB of the reflected light over the projected hemisphere, `n x n` points (row
/// 0 at the top, `+x` the specular side), `None` outside the disc.
pub fn hemisphere_colours(
    brdf: &(dyn Brdf + Sync),
    theta_i_deg: f64,
    phi_i_deg: f64,
    n: usize,
) -> Vec<Option<[f64; 3]>> {
    let lambdas = &brdf.meta().lambda_nm;
    let weights = colour::channel_weights(brdf.meta());
    let wi = from_spherical(theta_i_deg.to_radians(), phi_i_deg.to_radians());
    let forward = (phi_i_deg + 180.0).to_radians();
    (0..n * n)
        .into_par_iter()
        .map(|k| {
            let x = ((k % n) as f64 + 0.5) / n as f64 * 2.0 - 1.0;
            let y = 1.0 - ((k / n) as f64 + 0.5) / n as f64 * 2.0;
            let r = x.hypot(y);
            if r >= 1.0 {
                return None;
            }
            // x along the forward azimuth, y 90 degrees counter-clockwise from it.
            let phi = forward + y.atan2(x);
            let wo = DVec3::new(r * phi.cos(), r * phi.sin(), (1.0 - r * r).sqrt());
            let mut f = vec![0.0; lambdas.len()];
            brdf.eval(wi, wo, &mut f);
            let rho: Vec<f64> = f.iter().map(|v| std::f64::consts::PI * v * wi.z).collect();
            Some(colour::xyz_to_linear_srgb(colour::xyz(&rho, &weights)))
        })
        .collect()
}

/// The legend of a chart's labelled series, in its upper left corner (the lobe plots' and
/// `compare`'s picture's).
pub fn draw_legend<'a, DB: plotters::prelude::DrawingBackend + 'a>(
    chart: &mut plotters::prelude::ChartContext<
        'a,
        DB,
        plotters::prelude::Cartesian2d<
            plotters::coord::types::RangedCoordf64,
            plotters::coord::types::RangedCoordf64,
        >,
    >,
) -> Result<(), PlotError> {
    use plotters::prelude::*;
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font(("sans-serif", 12))
        .draw()
        .map_err(|e| PlotError::Draw(e.to_string()))
}

/// An approximate display colour of a wavelength (Bruton, "Approximate RGB values for
/// visible wavelengths", 1996), for telling curves apart.
pub fn wavelength_colour(l: f64) -> (u8, u8, u8) {
    let (r, g, b) = match l {
        l if l < 440.0 => (-(l - 440.0) / 60.0, 0.0, 1.0),
        l if l < 490.0 => (0.0, (l - 440.0) / 50.0, 1.0),
        l if l < 510.0 => (0.0, 1.0, -(l - 510.0) / 20.0),
        l if l < 580.0 => ((l - 510.0) / 70.0, 1.0, 0.0),
        l if l < 645.0 => (1.0, -(l - 645.0) / 65.0, 0.0),
        _ => (1.0, 0.0, 0.0),
    };
    // Fade towards the ends of the visible range, and darken for contrast on white.
    let fade = if l < 420.0 {
        0.3 + 0.7 * ((l - 380.0) / 40.0).clamp(0.0, 1.0)
    } else if l > 700.0 {
        0.3 + 0.7 * ((780.0 - l) / 80.0).clamp(0.0, 1.0)
    } else {
        1.0
    };
    let c = |v: f64| (200.0 * (v * fade).clamp(0.0, 1.0)) as u8;
    (c(r), c(g), c(b))
}

/// Everything a lobe plot shows.
pub struct LobePlot {
    pub title: String,
    /// The BRDF's channels are linear sRGB (an RGB measured file), not wavelengths: the
    /// curves are labelled R, G and B.
    pub rgb: bool,
    pub theta_i_deg: f64,
    pub lobe: Lobe,
    pub map: Vec<Option<[f64; 3]>>,
    pub map_n: usize,
    /// The lobe's radius on a log scale over this many decades below its peak (`None`:
    /// linear), so that one bright order does not flatten every other lobe.
    pub log_decades: Option<u32>,
}

impl LobePlot {
    /// Computes the plot of `brdf` at incidence `(theta_i, phi_i)` (degrees), its lobe on
    /// a linear scale ([`LobePlot::log_decades`] sets a log one).
    pub fn new(
        brdf: &(dyn Brdf + Sync),
        theta_i_deg: f64,
        phi_i_deg: f64,
        map_n: usize,
    ) -> Result<LobePlot, PlotError> {
        if !(theta_i_deg.is_finite() && (0.0..90.0).contains(&theta_i_deg)) {
            return Err(PlotError::from(format!(
                "--theta-i must lie in [0, 90) degrees, got {theta_i_deg}"
            )));
        }
        if !phi_i_deg.is_finite() {
            return Err("--phi-i must be finite".into());
        }
        let lobe = lobe(brdf, theta_i_deg, phi_i_deg, 7);
        if lobe
            .curves
            .iter()
            .flat_map(|c| &c.1)
            .any(|v| !v.is_finite())
        {
            return Err("the BRDF is not finite in the plane of incidence".into());
        }
        Ok(LobePlot {
            title: format!("{} at theta_i = {theta_i_deg} deg", brdf.meta().sample_name),
            rgb: brdf.meta().rgb,
            theta_i_deg,
            lobe,
            map: hemisphere_colours(brdf, theta_i_deg, phi_i_deg, map_n),
            map_n,
            log_decades: None,
        })
    }

    /// Writes the plot as PNG or SVG (by the extension), atomically.
    pub fn write(&self, path: &Path) -> Result<(), PlotError> {
        use plotters::prelude::*;
        register_font();
        let size = (1200, 600);
        match path.extension().and_then(|e| e.to_str()) {
            Some("png") => chart_file(path, |tmp| {
                self.draw(BitMapBackend::new(tmp, size).into_drawing_area())
            }),
            Some("svg") => chart_file(path, |tmp| {
                self.draw(SVGBackend::new(tmp, size).into_drawing_area())
            }),
            _ => Err(PlotError::Format(format!(
                "{}: the plot is written as .png or .svg",
                path.display()
            ))),
        }
    }

    fn draw<DB: plotters::prelude::DrawingBackend>(
        &self,
        root: plotters::prelude::DrawingArea<DB, plotters::coord::Shift>,
    ) -> Result<(), PlotError> {
        use plotters::prelude::*;
        let err = |e: &dyn std::fmt::Display| e.to_string();
        root.fill(&WHITE).map_err(|e| err(&e))?;
        let root = root
            .titled(&self.title, ("sans-serif", 22))
            .map_err(|e| err(&e))?;
        let (left, right) = root.split_horizontally(600);
        // Polar lobe: x = r sin(theta), y = r cos(theta), r = f cos(theta_o).
        let rmax = self
            .lobe
            .curves
            .iter()
            .flat_map(|c| c.1.iter().copied())
            .fold(0.0f64, f64::max)
            .max(1e-12);
        let radius = |v: f64| lobe_radius(v, rmax, self.log_decades);
        let negative = (self.lobe.curves.iter())
            .flat_map(|c| &c.1)
            .filter(|v| **v < 0.0)
            .count();
        let mut caption = match self.log_decades {
            Some(n) => format!(
                "lobe in the plane of incidence: f cos(theta_o), 1/sr, log over {n} decades"
            ),
            None => "lobe in the plane of incidence: f cos(theta_o), 1/sr".to_string(),
        };
        if negative > 0 {
            caption += &format!(" ({negative} negative estimates at 0)");
        }
        // Equal scales on both axes, so circles stay circles.
        let (w, h) = left.dim_in_pixel();
        let top =
            2.2 * rmax * f64::from(h.saturating_sub(60)) / f64::from(w.saturating_sub(24).max(1));
        let mut chart = ChartBuilder::on(&left)
            .caption(caption, ("sans-serif", 16))
            .margin(12)
            .build_cartesian_2d(-1.1 * rmax..1.1 * rmax, -0.05 * rmax..top - 0.05 * rmax)
            .map_err(|e| err(&e))?;
        let grey = RGBColor(200, 200, 200);
        for k in 1..=4 {
            let r = rmax * k as f64 / 4.0;
            // The value a ring stands for.
            let value = match self.log_decades {
                Some(n) => rmax * 10f64.powf(-f64::from(n) * (1.0 - k as f64 / 4.0)),
                None => r,
            };
            chart
                .draw_series(LineSeries::new(
                    (-90..=90).map(|t| {
                        let a = f64::from(t).to_radians();
                        (r * a.sin(), r * a.cos())
                    }),
                    grey,
                ))
                .map_err(|e| err(&e))?;
            chart
                .draw_series(std::iter::once(Text::new(
                    if self.log_decades.is_some() {
                        format!("{value:.1e}")
                    } else {
                        format!("{value:.3}")
                    },
                    (0.0, r),
                    ("sans-serif", 11)
                        .into_font()
                        .color(&RGBColor(120, 120, 120)),
                )))
                .map_err(|e| err(&e))?;
        }
        for t in [-60.0f64, -30.0, 0.0, 30.0, 60.0] {
            let a = t.to_radians();
            chart
                .draw_series(LineSeries::new(
                    vec![(0.0, 0.0), (1.05 * rmax * a.sin(), 1.05 * rmax * a.cos())],
                    grey,
                ))
                .map_err(|e| err(&e))?;
        }
        let mirror = self.theta_i_deg.to_radians();
        chart
            .draw_series(LineSeries::new(
                vec![
                    (0.0, 0.0),
                    (1.05 * rmax * mirror.sin(), 1.05 * rmax * mirror.cos()),
                ],
                ShapeStyle::from(&BLACK).stroke_width(1),
            ))
            .map_err(|e| err(&e))?
            .label("mirror direction")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], BLACK));
        for (k, (l, values)) in self.lobe.curves.iter().enumerate() {
            let (r, g, b) = wavelength_colour(*l);
            let label = if self.rgb {
                ["R (linear sRGB)", "G", "B"]
                    .get(k)
                    .unwrap_or(&"")
                    .to_string()
            } else {
                format!("{l:.0} nm")
            };
            let c = RGBColor(r, g, b);
            chart
                .draw_series(LineSeries::new(
                    self.lobe.theta_o_deg.iter().zip(values).map(|(t, v)| {
                        let (a, r) = (t.to_radians(), radius(*v));
                        (r * a.sin(), r * a.cos())
                    }),
                    ShapeStyle::from(&c).stroke_width(2),
                ))
                .map_err(|e| err(&e))?
                .label(label)
                .legend(move |(x, y)| {
                    PathElement::new(
                        vec![(x, y), (x + 16, y)],
                        ShapeStyle::from(&c).stroke_width(2),
                    )
                });
        }
        draw_legend(&mut chart)?;
        self.draw_map(&right)?;
        root.present().map_err(|e| err(&e))?;
        Ok(())
    }

    /// The hemisphere colour map panel.
    fn draw_map<DB: plotters::prelude::DrawingBackend>(
        &self,
        right: &plotters::prelude::DrawingArea<DB, plotters::coord::Shift>,
    ) -> Result<(), PlotError> {
        use plotters::prelude::*;
        let err = |e: &dyn std::fmt::Display| e.to_string();
        // Hemisphere colour map.
        let mut lum: Vec<f64> = self
            .map
            .iter()
            .flatten()
            .map(|c| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2])
            .collect();
        lum.sort_by(f64::total_cmp);
        let scale = lum
            .get(((lum.len() as f64) * 0.99) as usize)
            .copied()
            .filter(|v| *v > 0.0)
            .map_or(1.0, |v| 1.0 / v);
        let n = self.map_n;
        let mut map = ChartBuilder::on(right)
            .caption(
                format!("reflected colour under D65, projected hemisphere (x {scale:.3e}; specular side right)"),
                ("sans-serif", 14),
            )
            .margin(12)
            .build_cartesian_2d(0..n as i32, 0..n as i32)
            .map_err(|e| err(&e))?;
        map.draw_series(self.map.iter().enumerate().filter_map(|(k, c)| {
            let c = (*c)?;
            let enc =
                |v: f64| (255.0 * colour::srgb_encode((v * scale).clamp(0.0, 1.0))).round() as u8;
            let (x, y) = ((k % n) as i32, (n - 1 - k / n) as i32);
            Some(Rectangle::new(
                [(x, y), (x + 1, y + 1)],
                RGBColor(enc(c[0]), enc(c[1]), enc(c[2])).filled(),
            ))
        }))
        .map_err(|e| err(&e))?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lobe_radii_keep_the_peak_and_put_no_value_below_the_horizon() {
        // Linear: the value; negative estimates at the centre, never mirrored below.
        assert_eq!(lobe_radius(0.3, 2.0, None), 0.3);
        assert_eq!(lobe_radius(-0.3, 2.0, None), 0.0);
        // Log over 4 decades: the peak stays, each decade down is a quarter of the
        // radius, and 4 decades down is the centre.
        assert!((lobe_radius(2.0, 2.0, Some(4)) - 2.0).abs() < 1e-12);
        assert!((lobe_radius(0.2, 2.0, Some(4)) - 1.5).abs() < 1e-12);
        assert!((lobe_radius(2e-2, 2.0, Some(4)) - 1.0).abs() < 1e-12);
        assert_eq!(lobe_radius(2e-5, 2.0, Some(4)), 0.0);
        assert_eq!(lobe_radius(-1.0, 2.0, Some(4)), 0.0);
    }

    #[test]
    fn wavelength_colours_run_from_violet_to_red() {
        let (r, _, b) = wavelength_colour(420.0);
        assert!(b > r);
        let (r, g, b) = wavelength_colour(530.0);
        assert!(g > r && g > b);
        let (r, _, b) = wavelength_colour(650.0);
        assert!(r > b);
    }
}
