//! `goniospec compare`: two materials side by side, a simulation beside a measurement (or
//! any two BRDFs), in numbers and pictures (docs/measured.md, "Comparing").
//!
//! Both are evaluated on one grid: a tabulated `.bsdf`'s own incident angles and the nodes
//! of its warped outgoing grid (the first `.bsdf` named), or, for two simulations, the
//! first one's incident angles and bucket centres. At each outgoing direction the colour
//! of the reflected light is the radiance factor `pi f` (relative to a perfect diffuser
//! under the same light) under D65, CIE 1931 2-degree observer, in CIELAB; spectra reach
//! it through XYZ, RGB files through linear sRGB (`render::colour::channel_weights`). The
//! differences are CIEDE2000 (Sharma, Wu & Dalal 2005), weighted over the lit directions
//! by their projected solid angles; [`shape`] adds the figures of appearance metrology.

pub mod picture;
pub mod shape;
mod write;

use std::path::Path;

use glam::DVec3;
use rayon::prelude::*;

use crate::accumulate::Buckets;
use crate::brdf::{Brdf, Representation};
use crate::export::measured::MeasuredBrdf;
use crate::render::colour;

pub use write::{output_names, write_outputs};

/// What a comparison refuses: a file it cannot read as a BRDF, or two it cannot compare.
#[derive(Debug, thiserror::Error)]
pub enum CompareError {
    /// The message says what and where.
    #[error("{0}")]
    Invalid(String),
    /// A picture could not be drawn or written.
    #[error(transparent)]
    Plot(#[from] crate::plot::PlotError),
    /// A table could not be written.
    #[error("{path}: {source}")]
    Write {
        path: String,
        #[source]
        source: std::io::Error,
    },
}

message_error!(CompareError, CompareError::Invalid);

/// A material as `compare` reads it.
pub enum Material {
    /// A simulation (a `.gsb`, or a `.gsa` built into a table, or a kd-tree where it has
    /// several azimuths): its simulated incident angles and azimuths (degrees; each angle
    /// at each azimuth) and its bucket grid.
    Simulated {
        brdf: Box<Representation>,
        theta_i_deg: Vec<f64>,
        phi_i_deg: Vec<f64>,
        /// A `.gsa` of several azimuths: one table per azimuth (`phi_i_deg`'s order);
        /// empty otherwise.
        per_azimuth: Vec<Representation>,
        buckets: Buckets,
    },
    /// An RGL `.bsdf`: measured, or exported by goniospec.
    Tabulated(Box<MeasuredBrdf>),
}

impl Material {
    /// Reads a `.gsb`, a `.gsa` (built into a table) or a `.bsdf`, by its magic bytes.
    pub fn read(path: &Path) -> Result<Material, CompareError> {
        let named =
            |e: &dyn std::fmt::Display| CompareError::from(format!("{}: {e}", path.display()));
        // The magic bytes decide the reader; each reads the file once.
        let mut head = [0u8; 12];
        {
            use std::io::Read;
            std::fs::File::open(path)
                .and_then(|mut f| f.read(&mut head))
                .map_err(|e| named(&e))?;
        }
        if crate::export::tensor::is_tensor_file(&head) {
            let m = MeasuredBrdf::read(path).map_err(|e| CompareError::from(e.to_string()))?;
            return Ok(Material::Tabulated(Box::new(m)));
        }
        let gsa = head[..8] == crate::accumulate::file::MAGIC[..];
        if gsa {
            // Held to the physics its run was (`simulate::check_file`).
            let (acc, warning) = crate::simulate::read_judged(path).map_err(|e| named(&e))?;
            if let Some(w) = warning {
                eprintln!("warning: {w}");
            }
            return Material::from_accumulator(&acc).map_err(|e| named(&e));
        }
        let brdf = crate::brdf::file::read(path).map_err(|e| {
            named(&format!(
                "not a .gsb, .gsa or .bsdf that goniospec reads ({e})"
            ))
        })?;
        Material::simulated(brdf, Vec::new(), None).map_err(|e| named(&e))
    }

    /// A simulation's accumulator, built into a table (one table per azimuth where it has
    /// several: a table holds one azimuth, and each incidence is read from its own).
    pub fn from_accumulator(
        acc: &crate::accumulate::file::Accumulator,
    ) -> Result<Material, CompareError> {
        let azimuths = acc.header.settings.azimuths();
        let table = |a: &crate::accumulate::file::Accumulator| {
            Representation::build(
                crate::brdf::Kind::Table,
                &crate::brdf::BucketData::from_accumulator(a),
                &crate::brdf::BuildOptions::default(),
            )
            .map_err(|e| CompareError::from(e.to_string()))
        };
        let per_azimuth = if azimuths.len() > 1 {
            azimuths
                .iter()
                .map(|&p| table(&acc.at_azimuth(p)))
                .collect::<Result<Vec<_>, _>>()?
        } else {
            Vec::new()
        };
        let brdf = table(&acc.at_azimuth(azimuths[0]))?;
        Material::simulated(brdf, per_azimuth, Some(azimuths))
    }

    /// A simulated BRDF with its incident angles and grid, read from its settings.
    fn simulated(
        brdf: Representation,
        per_azimuth: Vec<Representation>,
        run_azimuths: Option<Vec<f64>>,
    ) -> Result<Material, CompareError> {
        let settings: crate::accumulate::file::Settings = toml::from_str(&brdf.meta().simulation)
            .map_err(|e| {
            CompareError::from(format!("its simulation settings do not parse: {e}"))
        })?;
        let theta_i_deg = crate::export::simulated_incidence(&brdf)
            .map_err(|e| CompareError::from(e.to_string()))?
            .iter()
            .map(|t| t.to_degrees())
            .collect();
        Ok(Material::Simulated {
            brdf: Box::new(brdf),
            theta_i_deg,
            phi_i_deg: run_azimuths.unwrap_or_else(|| settings.azimuths()),
            per_azimuth,
            buckets: Buckets {
                theta_bins: settings.theta_o_bins,
                phi_bins: settings.phi_o_bins,
            },
        })
    }

    /// The material as a BRDF.
    pub fn brdf(&self) -> &(dyn Brdf + Sync) {
        match self {
            Material::Simulated { brdf, .. } => brdf.as_ref(),
            Material::Tabulated(m) => m.as_ref(),
        }
    }

    /// The material as a BRDF for light from azimuth `phi_deg`: a simulation of several
    /// azimuths read as that azimuth's table, anything else as itself.
    pub fn brdf_at(&self, phi_deg: f64) -> &(dyn Brdf + Sync) {
        match self {
            Material::Simulated {
                phi_i_deg,
                per_azimuth,
                ..
            } if !per_azimuth.is_empty() => phi_i_deg
                .iter()
                .position(|p| (p - phi_deg).abs() < 1e-9)
                .map_or(self.brdf(), |k| &per_azimuth[k]),
            _ => self.brdf(),
        }
    }

    /// The material's name: the sample's, or the file's description.
    pub fn name(&self) -> &str {
        &self.brdf().meta().sample_name
    }

    /// What the material is, in a few words.
    pub fn kind(&self) -> &'static str {
        match self {
            Material::Simulated { .. } => "simulated",
            Material::Tabulated(m) if m.is_goniospec_export() => "exported .bsdf",
            Material::Tabulated(_) => "measured",
        }
    }

    /// Why incidence `theta_i_deg` cannot be compared on this side, if it cannot.
    fn refuses(&self, theta_i_deg: f64) -> Option<String> {
        match self {
            Material::Simulated { theta_i_deg: t, .. } => {
                let (lo, hi) = (t[0], t[t.len() - 1]);
                (theta_i_deg < lo - 1e-6 || theta_i_deg > hi + 1e-6).then(|| {
                    format!(
                        "outside the simulated incidence {lo:.1}-{hi:.1} deg (the table would repeat its nearest angle)"
                    )
                })
            }
            Material::Tabulated(m) => {
                let t = &m.theta_i_rad;
                let (lo, hi) = (t[0].to_degrees(), t[t.len() - 1].to_degrees());
                (theta_i_deg < lo - 1e-6 || theta_i_deg > hi + 1e-6)
                    .then(|| format!("outside the file's incidence {lo:.1}-{hi:.1} deg"))
            }
        }
    }
}

/// One incident direction of the grid: its lit outgoing directions and their projected
/// solid angles (sr), or why it is left out.
#[derive(Clone, Debug)]
pub struct Incidence {
    pub theta_i_deg: f64,
    pub phi_i_deg: f64,
    pub nodes: Vec<(DVec3, f64)>,
    pub skipped: Option<String>,
}

/// The grid both materials are evaluated on (see the module's documentation), and which
/// side it came from.
pub fn grid(a: &Material, b: &Material) -> (Vec<Incidence>, &'static str) {
    let (on, from) = match (a, b) {
        (Material::Tabulated(_), _) => (a, "A"),
        (_, Material::Tabulated(_)) => (b, "B"),
        _ => (a, "A"),
    };
    let list = match on {
        Material::Tabulated(m) => tabulated_grid(m),
        Material::Simulated {
            theta_i_deg,
            phi_i_deg,
            buckets,
            ..
        } => phi_i_deg
            .iter()
            .flat_map(|&p| theta_i_deg.iter().map(move |&t| (t, p)))
            .map(|(t, p)| Incidence {
                theta_i_deg: t,
                phi_i_deg: p,
                nodes: (0..buckets.len())
                    .map(|k| {
                        let (theta, phi) = buckets.centre(k);
                        (
                            crate::geom::from_spherical(theta, phi),
                            buckets.projected_solid_angle(k),
                        )
                    })
                    .collect(),
                skipped: None,
            })
            .collect(),
    };
    let list = list
        .into_iter()
        .map(|mut inc| {
            if inc.skipped.is_none() {
                inc.skipped = a
                    .refuses(inc.theta_i_deg)
                    .map(|r| format!("A: {r}"))
                    .or_else(|| b.refuses(inc.theta_i_deg).map(|r| format!("B: {r}")));
            }
            inc
        })
        .collect();
    (list, from)
}

/// A `.bsdf`'s own grid: each `(phi_i, theta_i)` and its lit nodes.
fn tabulated_grid(m: &MeasuredBrdf) -> Vec<Incidence> {
    let (w, h) = m.grid;
    let mut out = Vec::new();
    for &p in &m.phi_i_rad {
        for &t in &m.theta_i_rad {
            let skipped = (t.to_degrees() > 89.999)
                .then(|| "grazing incidence: no light reaches the surface".to_string());
            let nodes = if skipped.is_some() {
                Vec::new()
            } else {
                (0..w * h)
                    .filter_map(|k| m.node_direction(t, p, k % w, k / w))
                    .collect()
            };
            out.push(Incidence {
                theta_i_deg: t.to_degrees(),
                phi_i_deg: p.to_degrees(),
                nodes,
                skipped,
            });
        }
    }
    out
}

/// The colour space of a comparison: the white of CIELAB, and whether it is the
/// measurement's RGB (linear sRGB, D65) or CIE XYZ.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ColourSpace {
    pub rgb: bool,
    pub white: [f64; 3],
}

impl ColourSpace {
    /// Linear sRGB where either side is an RGB file (the measurement's form, docs/measured.md
    /// §4), else XYZ from the spectra under D65.
    pub fn of(a: &Material, b: &Material) -> ColourSpace {
        let rgb = a.brdf().meta().rgb || b.brdf().meta().rgb;
        ColourSpace {
            rgb,
            white: if rgb {
                colour::linear_srgb_to_xyz([1.0, 1.0, 1.0])
            } else {
                colour::white_xyz()
            },
        }
    }

    pub fn describe(&self) -> &'static str {
        if self.rgb {
            "linear sRGB (the measurement's RGB form; spectra through the CIE 1931 2-degree observer under D65, IEC 61966-2-1), CIELAB of the D65 white"
        } else {
            "CIE 1931 2-degree XYZ under D65, CIELAB of the D65 white"
        }
    }
}

/// The CIELAB colour of the radiance factor `pi f` of `brdf` at `(wi, wo)`.
pub fn lab_at(
    brdf: &(dyn Brdf + Sync),
    weights: &[[f64; 3]],
    space: &ColourSpace,
    wi: DVec3,
    wo: DVec3,
    f: &mut [f64],
) -> [f64; 3] {
    brdf.eval(wi, wo, f);
    let rho: Vec<f64> = f.iter().map(|v| std::f64::consts::PI * v).collect();
    colour::lab(colour::xyz(&rho, weights), space.white)
}

/// One node of the grid: where, its weight, both colours and their differences.
#[derive(Clone, Debug)]
pub struct Node {
    pub theta_i_deg: f64,
    pub wo: DVec3,
    /// Projected solid angle, sr.
    pub weight: f64,
    pub lab_a: [f64; 3],
    pub lab_b: [f64; 3],
    /// CIEDE2000 of the colours, and of their lightness alone.
    pub de: f64,
    pub de_lightness: f64,
}

/// Weighted mean, median and 95th percentile.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Stats {
    pub mean: f64,
    pub median: f64,
    pub p95: f64,
}

impl Stats {
    /// Of `(value, weight)` pairs (weights positive): the weighted mean, and the values at
    /// which the cumulative weight first reaches half and 95 % of the total.
    pub fn weighted(mut v: Vec<(f64, f64)>) -> Stats {
        let total: f64 = v.iter().map(|x| x.1).sum();
        if v.is_empty() || total <= 0.0 {
            return Stats::default();
        }
        let mean = v.iter().map(|x| x.0 * x.1).sum::<f64>() / total;
        v.sort_by(|a, b| a.0.total_cmp(&b.0));
        let at = |q: f64| {
            let mut acc = 0.0;
            for &(x, w) in &v {
                acc += w;
                if acc >= q * total {
                    return x;
                }
            }
            v[v.len() - 1].0
        };
        Stats {
            mean,
            median: at(0.5),
            p95: at(0.95),
        }
    }
}

/// The figures of one incident direction.
#[derive(Clone, Debug, serde::Serialize)]
pub struct AngleFigures {
    pub theta_i_deg: f64,
    pub phi_i_deg: f64,
    pub nodes: usize,
    /// CIEDE2000 of the colour over the lit directions, weighted by projected solid angle.
    pub delta_e: Stats,
    /// The same of the lightness alone.
    pub delta_e_lightness: Stats,
    pub lobe_a: shape::LobeFigures,
    pub lobe_b: shape::LobeFigures,
}

/// Everything `compare` found.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Report {
    pub a: String,
    pub b: String,
    pub a_kind: String,
    pub b_kind: String,
    /// Which side's grid the comparison used ("A" or "B").
    pub grid_from: String,
    pub colour_space: String,
    pub angles: Vec<AngleFigures>,
    /// Incident angles left out, with the reason.
    pub skipped: Vec<(f64, String)>,
    /// Over every compared angle, weighted by projected solid angle.
    pub overall: Stats,
    pub flop: Option<shape::Flop>,
    pub travel: Vec<shape::TravelRow>,
    #[serde(skip)]
    pub nodes: Vec<Node>,
}

/// Compares `a` with `b` (labels name them in the report).
pub fn compare(a: &Material, b: &Material, labels: [&str; 2]) -> Result<Report, CompareError> {
    compare_only(a, b, labels, &|_| true)
}

/// Compares `a` with `b` at the grid's incident angles (degrees) that `keep` takes; the
/// others are left out of the report altogether (`goniospec match` fits some angles of a
/// measurement and holds the others out).
pub fn compare_only(
    a: &Material,
    b: &Material,
    labels: [&str; 2],
    keep: &(dyn Fn(f64) -> bool + Sync),
) -> Result<Report, CompareError> {
    let space = ColourSpace::of(a, b);
    let (wa, wb) = (
        colour::channel_weights(a.brdf().meta()),
        colour::channel_weights(b.brdf().meta()),
    );
    let (incidences, from) = grid(a, b);
    let mut angles = Vec::new();
    let mut skipped = Vec::new();
    let mut all_nodes = Vec::new();
    for inc in incidences.iter().filter(|i| keep(i.theta_i_deg)) {
        if let Some(why) = &inc.skipped {
            skipped.push((inc.theta_i_deg, why.clone()));
            continue;
        }
        let wi =
            crate::geom::from_spherical(inc.theta_i_deg.to_radians(), inc.phi_i_deg.to_radians());
        let nodes: Vec<Node> = inc
            .nodes
            .par_iter()
            .map_init(
                || (vec![0.0; wa.len()], vec![0.0; wb.len()]),
                |(fa, fb), &(wo, weight)| {
                    let lab_a = lab_at(a.brdf_at(inc.phi_i_deg), &wa, &space, wi, wo, fa);
                    let lab_b = lab_at(b.brdf_at(inc.phi_i_deg), &wb, &space, wi, wo, fb);
                    Node {
                        theta_i_deg: inc.theta_i_deg,
                        wo,
                        weight,
                        lab_a,
                        lab_b,
                        de: colour::delta_e2000(lab_a, lab_b),
                        de_lightness: colour::delta_e2000(
                            [lab_a[0], 0.0, 0.0],
                            [lab_b[0], 0.0, 0.0],
                        ),
                    }
                },
            )
            .collect();
        if let Some(n) = nodes
            .iter()
            .find(|n| !(n.de.is_finite() && n.de_lightness.is_finite()))
        {
            return Err(CompareError::from(format!(
                "the colours at theta_i {:.2} deg, wo {:?} are not finite (A {:?}, B {:?}): a BRDF value is not finite there",
                inc.theta_i_deg, n.wo, n.lab_a, n.lab_b
            )));
        }
        angles.push(AngleFigures {
            theta_i_deg: inc.theta_i_deg,
            phi_i_deg: inc.phi_i_deg,
            nodes: nodes.len(),
            delta_e: Stats::weighted(nodes.iter().map(|n| (n.de, n.weight)).collect()),
            delta_e_lightness: Stats::weighted(
                nodes.iter().map(|n| (n.de_lightness, n.weight)).collect(),
            ),
            lobe_a: shape::lobe_figures(
                a.brdf_at(inc.phi_i_deg),
                &wa,
                inc.theta_i_deg,
                inc.phi_i_deg,
            ),
            lobe_b: shape::lobe_figures(
                b.brdf_at(inc.phi_i_deg),
                &wb,
                inc.theta_i_deg,
                inc.phi_i_deg,
            ),
        });
        all_nodes.extend(nodes);
    }
    if angles.is_empty() {
        return Err(CompareError::from(format!(
            "no incident angle can be compared: {}",
            skipped
                .iter()
                .map(|(t, w)| format!("{t:.1} deg: {w}"))
                .collect::<Vec<_>>()
                .join("; ")
        )));
    }
    // Over all angles, each angle's weights normalised so that every angle counts alike.
    let mut overall = Vec::new();
    for a in &angles {
        let total: f64 = all_nodes
            .iter()
            .filter(|n| n.theta_i_deg == a.theta_i_deg)
            .map(|n| n.weight)
            .sum();
        overall.extend(
            all_nodes
                .iter()
                .filter(|n| n.theta_i_deg == a.theta_i_deg)
                .map(|n| (n.de, n.weight / total)),
        );
    }
    let flop_at = |m: &Material| -> Option<String> { m.refuses(45.0) };
    let (flop, travel) = if flop_at(a).is_none() && flop_at(b).is_none() {
        (
            Some(shape::flop(a.brdf(), &wa, b.brdf(), &wb, &space)),
            shape::travel(a.brdf(), &wa, b.brdf(), &wb, &space),
        )
    } else {
        (None, Vec::new())
    };
    Ok(Report {
        a: format!("{} ({})", labels[0], a.name()),
        b: format!("{} ({})", labels[1], b.name()),
        a_kind: a.kind().into(),
        b_kind: b.kind().into(),
        grid_from: from.into(),
        colour_space: space.describe().into(),
        angles,
        skipped,
        overall: Stats::weighted(overall),
        flop,
        travel,
        nodes: all_nodes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weighted_stats_follow_the_weights() {
        let s = Stats::weighted(vec![(1.0, 1.0), (2.0, 1.0), (3.0, 2.0)]);
        assert_eq!(s.mean, 2.25);
        assert_eq!(s.median, 2.0);
        assert_eq!(s.p95, 3.0);
        let s = Stats::weighted(vec![(5.0, 0.1), (1.0, 0.9)]);
        assert_eq!(s.median, 1.0);
        assert_eq!(s.p95, 5.0);
        assert_eq!(Stats::weighted(Vec::new()), Stats::default());
    }
}
