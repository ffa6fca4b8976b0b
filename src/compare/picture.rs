//! `compare`'s picture: for each compared incident angle, the two materials' reflected
//! colour over the projected hemisphere side by side (one exposure for both), the
//! CIEDE2000 between them there, and their lobes in the plane of incidence overlaid.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use super::shape::plane_lobe;
use super::{ColourSpace, Material, Report};
use crate::plot::{PlotError, chart_file, hemisphere_colours, register_font};
use crate::render::colour;

/// Points per side of each hemisphere map.
const MAP_N: usize = 72;
/// The least CIEDE2000 at the dark end of the difference map's scale (the scale is the
/// 95th percentile of the maps' differences where that is larger, rounded up).
const DE_SCALE_MIN: f64 = 5.0;

/// One row of the picture.
struct Row {
    theta_i_deg: f64,
    mean_de: f64,
    a: Vec<Option<[f64; 3]>>,
    b: Vec<Option<[f64; 3]>>,
    de: Vec<Option<f64>>,
    /// `(signed angle deg, Y of f cos(theta_o))` of each material.
    lobe_a: Vec<(f64, f64)>,
    lobe_b: Vec<(f64, f64)>,
}

/// Everything the picture shows.
pub struct Picture {
    title: String,
    names: [String; 2],
    rows: Vec<Row>,
    /// One exposure for every map: the brightest 1 % of all of them saturates.
    scale: f64,
    /// The CIEDE2000 drawn black.
    de_scale: f64,
}

impl Picture {
    /// Computes the picture of `report`'s angles for `a` and `b`.
    pub fn new(report: &Report, a: &Material, b: &Material) -> Picture {
        let space = ColourSpace::of(a, b);
        let (wa, wb) = (
            colour::channel_weights(a.brdf().meta()),
            colour::channel_weights(b.brdf().meta()),
        );
        let rows: Vec<Row> = report
            .angles
            .iter()
            .map(|ang| {
                let (t, p) = (ang.theta_i_deg, ang.phi_i_deg);
                let ma = hemisphere_colours(a.brdf_at(p), t, p, MAP_N);
                let mb = hemisphere_colours(b.brdf_at(p), t, p, MAP_N);
                // The maps hold pi f cos(theta_i) in linear sRGB; the difference is of the
                // radiance factors pi f, as everywhere in compare.
                let cos = t.to_radians().cos();
                let lab = |c: [f64; 3]| {
                    let x = colour::linear_srgb_to_xyz([c[0] / cos, c[1] / cos, c[2] / cos]);
                    colour::lab(x, space.white)
                };
                let de = ma
                    .iter()
                    .zip(&mb)
                    .map(|(x, y)| Some(colour::delta_e2000(lab((*x)?), lab((*y)?))))
                    .collect();
                let with_cos = |l: Vec<(f64, f64)>| {
                    l.into_iter()
                        .map(|(x, y)| (x, y * x.to_radians().cos()))
                        .collect()
                };
                Row {
                    theta_i_deg: t,
                    mean_de: ang.delta_e.mean,
                    a: ma,
                    b: mb,
                    de,
                    lobe_a: with_cos(plane_lobe(a.brdf_at(p), &wa, t, p)),
                    lobe_b: with_cos(plane_lobe(b.brdf_at(p), &wb, t, p)),
                }
            })
            .collect();
        let mut lum: Vec<f64> = rows
            .iter()
            .flat_map(|r| r.a.iter().chain(&r.b).flatten())
            .map(|c| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2])
            .collect();
        lum.sort_by(f64::total_cmp);
        let scale = lum
            .get((lum.len() as f64 * 0.99) as usize)
            .copied()
            .filter(|v| *v > 0.0)
            .map_or(1.0, |v| 1.0 / v);
        let mut de: Vec<f64> = rows
            .iter()
            .flat_map(|r| r.de.iter().flatten())
            .copied()
            .collect();
        de.sort_by(f64::total_cmp);
        let p95 = de
            .get((de.len() as f64 * 0.95) as usize)
            .copied()
            .unwrap_or(0.0);
        Picture {
            title: format!("A: {}   B: {}", report.a, report.b),
            names: ["A".into(), "B".into()],
            rows,
            scale,
            de_scale: p95.ceil().max(DE_SCALE_MIN),
        }
    }

    /// Writes the picture as PNG or SVG (by the extension), atomically. In the SVG each
    /// map is one embedded PNG image (a rectangle per point would make it megabytes).
    pub fn write(&self, path: &Path) -> Result<(), PlotError> {
        register_font();
        let size = (1400, 90 + 300 * self.rows.len() as u32);
        match path.extension().and_then(|e| e.to_str()) {
            Some("png") => chart_file(path, |tmp| {
                self.draw(BitMapBackend::new(tmp, size).into_drawing_area(), false)
                    .map(|_| ())
            }),
            Some("svg") => chart_file(path, |tmp| {
                let maps = self.draw(SVGBackend::new(tmp, size).into_drawing_area(), true)?;
                embed_maps(tmp, &maps)
            }),
            _ => Err(PlotError::Format(format!(
                "{}: the picture is written as .png or .svg",
                path.display()
            ))),
        }
    }

    /// Draws the picture; with `embed`, the maps are returned as images to embed instead
    /// of drawn.
    fn draw<DB: DrawingBackend>(
        &self,
        root: DrawingArea<DB, Shift>,
        embed: bool,
    ) -> Result<Vec<Embedded>, PlotError> {
        let err = |e: &dyn std::fmt::Display| PlotError::Draw(e.to_string());
        root.fill(&WHITE).map_err(|e| err(&e))?;
        let root = root
            .titled(&self.title, ("sans-serif", 18))
            .map_err(|e| err(&e))?;
        let (head, body) = root.split_vertically(40);
        head.draw(&Text::new(
            format!(
                "reflected colour under D65 over the projected hemisphere (radiance factor x cos theta_i, x {:.3e}; mirror side right); CIEDE2000 between them (white 0, black {} or more); in-plane lobes, Y of f cos theta_o (1/sr)",
                self.scale, self.de_scale
            ),
            (10, 10),
            ("sans-serif", 13).into_font(),
        ))
        .map_err(|e| err(&e))?;
        let rows = body.split_evenly((self.rows.len().max(1), 1));
        let mut maps = Vec::new();
        for (row, area) in self.rows.iter().zip(rows) {
            maps.extend(self.draw_row(row, &area, embed)?);
        }
        root.present().map_err(|e| err(&e))?;
        Ok(maps)
    }

    fn draw_row<DB: DrawingBackend>(
        &self,
        row: &Row,
        area: &DrawingArea<DB, Shift>,
        embed: bool,
    ) -> Result<Vec<Embedded>, PlotError> {
        let err = |e: &dyn std::fmt::Display| PlotError::Draw(e.to_string());
        let (maps, lobes) = area.split_horizontally(900);
        let panels = maps.split_evenly((1, 3));
        let enc = |v: f64| (255.0 * colour::srgb_encode(v * self.scale)).round() as u8;
        let captions = [
            format!("{} at theta_i {:.1} deg", self.names[0], row.theta_i_deg),
            format!("{} at theta_i {:.1} deg", self.names[1], row.theta_i_deg),
            format!("CIEDE2000 (mean {:.2})", row.mean_de),
        ];
        let mut embedded = Vec::new();
        for (k, (panel, caption)) in panels.iter().zip(&captions).enumerate() {
            let chart = ChartBuilder::on(panel)
                .caption(caption, ("sans-serif", 14))
                .margin(8)
                .build_cartesian_2d(0..MAP_N as i32, 0..MAP_N as i32)
                .map_err(|e| err(&e))?;
            // Each point's colour, row 0 at the top; None outside the disc.
            let colours: Vec<Option<[u8; 3]>> = match k {
                0 | 1 => {
                    let map = if k == 0 { &row.a } else { &row.b };
                    map.iter()
                        .map(|c| c.map(|c| [enc(c[0]), enc(c[1]), enc(c[2])]))
                        .collect()
                }
                _ => row
                    .de
                    .iter()
                    .map(|d| {
                        d.map(|d| {
                            let g = (255.0 * (1.0 - (d / self.de_scale).clamp(0.0, 1.0))) as u8;
                            [g, g, g]
                        })
                    })
                    .collect(),
            };
            if embed {
                let (xr, yr) = chart.plotting_area().get_pixel_range();
                embedded.push(Embedded {
                    at: (xr.start, yr.start),
                    size: (xr.end - xr.start, yr.end - yr.start),
                    png: map_png(&colours)?,
                });
                continue;
            }
            let mut chart = chart;
            chart
                .draw_series(colours.iter().enumerate().filter_map(|(i, c)| {
                    let c = (*c)?;
                    let (x, y) = ((i % MAP_N) as i32, (MAP_N - 1 - i / MAP_N) as i32);
                    Some(Rectangle::new(
                        [(x, y), (x + 1, y + 1)],
                        RGBColor(c[0], c[1], c[2]).filled(),
                    ))
                }))
                .map_err(|e| err(&e))?;
        }
        self.draw_lobes(row, &lobes)?;
        Ok(embedded)
    }

    fn draw_lobes<DB: DrawingBackend>(
        &self,
        row: &Row,
        area: &DrawingArea<DB, Shift>,
    ) -> Result<(), PlotError> {
        let err = |e: &dyn std::fmt::Display| PlotError::Draw(e.to_string());
        let rmax = row
            .lobe_a
            .iter()
            .chain(&row.lobe_b)
            .map(|p| p.1)
            .fold(0.0f64, f64::max)
            .max(1e-12);
        let mut chart = ChartBuilder::on(area)
            .caption(
                format!("in-plane lobes (max {rmax:.3e} 1/sr)"),
                ("sans-serif", 14),
            )
            .margin(8)
            .build_cartesian_2d(-1.1 * rmax..1.1 * rmax, -0.05 * rmax..1.1 * rmax)
            .map_err(|e| err(&e))?;
        let grey = RGBColor(200, 200, 200);
        let mirror = row.theta_i_deg.to_radians();
        chart
            .draw_series(LineSeries::new(
                vec![(0.0, 0.0), (rmax * mirror.sin(), rmax * mirror.cos())],
                grey,
            ))
            .map_err(|e| err(&e))?;
        for (lobe, name, c) in [
            (&row.lobe_a, &self.names[0], RGBColor(30, 90, 200)),
            (&row.lobe_b, &self.names[1], RGBColor(210, 60, 30)),
        ] {
            chart
                .draw_series(LineSeries::new(
                    lobe.iter().map(|&(t, v)| {
                        let a = t.to_radians();
                        (v * a.sin(), v * a.cos())
                    }),
                    ShapeStyle::from(&c).stroke_width(2),
                ))
                .map_err(|e| err(&e))?
                .label(name.as_str())
                .legend(move |(x, y)| {
                    PathElement::new(
                        vec![(x, y), (x + 16, y)],
                        ShapeStyle::from(&c).stroke_width(2),
                    )
                });
        }
        crate::plot::draw_legend(&mut chart)
    }
}

/// A map to embed in the SVG: its place and size in pixels, and the PNG of its points.
struct Embedded {
    at: (i32, i32),
    size: (i32, i32),
    png: Vec<u8>,
}

/// The PNG of a map (`MAP_N` x `MAP_N`, white outside the disc).
fn map_png(colours: &[Option<[u8; 3]>]) -> Result<Vec<u8>, PlotError> {
    let data: Vec<u8> = colours
        .iter()
        .flat_map(|c| c.unwrap_or([255, 255, 255]))
        .collect();
    let mut out = Vec::new();
    let mut enc = png::Encoder::new(&mut out, MAP_N as u32, MAP_N as u32);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut w = enc
        .write_header()
        .map_err(|e| PlotError::Draw(e.to_string()))?;
    w.write_image_data(&data)
        .map_err(|e| PlotError::Draw(e.to_string()))?;
    w.finish().map_err(|e| PlotError::Draw(e.to_string()))?;
    Ok(out)
}

/// Standard base64 (RFC 4648 §4, with padding).
fn base64(bytes: &[u8]) -> String {
    const ABC: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for c in bytes.chunks(3) {
        let n = (u32::from(c[0]) << 16)
            | (u32::from(*c.get(1).unwrap_or(&0)) << 8)
            | u32::from(*c.get(2).unwrap_or(&0));
        for k in 0..4 {
            if k <= c.len() {
                s.push(ABC[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

/// Inserts the maps into the SVG written at `path`, as `<image>` elements before its end.
fn embed_maps(path: &Path, maps: &[Embedded]) -> Result<(), PlotError> {
    let io = |e: std::io::Error| PlotError::Write {
        path: path.display().to_string(),
        source: e,
    };
    let mut text = std::fs::read_to_string(path).map_err(io)?;
    let end = text
        .rfind("</svg>")
        .ok_or_else(|| PlotError::Draw("the SVG has no end tag".into()))?;
    let images: String = maps
        .iter()
        .map(|m| {
            format!(
                "<image x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" preserveAspectRatio=\"none\" style=\"image-rendering:pixelated\" href=\"data:image/png;base64,{}\"/>\n",
                m.at.0,
                m.at.1,
                m.size.0,
                m.size.1,
                base64(&m.png)
            )
        })
        .collect();
    text.insert_str(end, &images);
    std::fs::write(path, text).map_err(io)
}

#[cfg(test)]
mod tests {
    /// RFC 4648 §10's test vectors.
    #[test]
    fn base64_of_the_rfc_vectors() {
        for (a, b) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(super::base64(a.as_bytes()), b);
        }
    }
}
