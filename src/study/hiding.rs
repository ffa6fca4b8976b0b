//! Hiding power of a paint: the film thickness at which it hides a black-and-white contrast
//! chart, and its reflectance at complete hiding (R-infinity), as paint makers measure
//! them (ISO 6504-3; ASTM D2805), by simulating the sample's scattering layer over two
//! backings.
//!
//! The chart is modelled by its two ideal halves, each a thick layer index-matched to the
//! paint's host (a copy of the host's own index model, so nothing reflects at the paint's
//! lower face and dispersion matches at every wavelength):
//! - black: a pure absorber ([`BLACK`]: no scattering, 10 per um, so nothing returns);
//! - white: an isotropic scatterer ([`WHITE`]) whose reflectance seen through the binder's
//!   top face is about 0.8 (ISO 6504-3 asks for a white of Y = 80 +- 2 %); the run
//!   measures it and reports it.
//!
//! Both runs use the same seed, so every tree is the same path in both until it first
//! enters the backing (the black ends it, the white sends it on): the two reflectances
//! share their noise and the contrast ratio is far steadier than two independent runs.
//! Its reported standard error treats them as independent, an upper bound.
//!
//! The contrast ratio `C(t) = Y_black / Y_white` (luminous reflectances, CIE 1931 Y under
//! D65 over the run's bins) rises towards 1 with thickness `t`; towards complete hiding
//! `1 - C` falls about exponentially (the diffusion regime of a thick slab), so the
//! thickness where `C` reaches the target is found by bracketing (doubling or halving) and
//! then interpolating `ln(1 - C)` linearly in `t` (regula falsi on that log).
//! R-infinity lies between `Y_black` and `Y_white` at any thickness (over black the film
//! reflects less than an infinitely thick one, over a white brighter than it, more); at
//! twice the hiding thickness the two are within about `(1 - C)^2` of each other, and the
//! bracket is reported as it is.

use std::path::Path;

use crate::render::colour;
use crate::sample::{self, MeshOptions};
use crate::simulate::{SimConfig, Wavelengths, simulate};

use super::StudyError;

/// The black half of the chart: `henyey_greenstein` coefficients (g, scattering and
/// absorption per um) of a pure absorber (1/e in 0.1 um).
pub const BLACK: [f64; 3] = [0.0, 0.0, 10.0];
/// The white half: an isotropic scatterer with single-scattering albedo 1 - 1.6e-3,
/// whose reflectance through a binder of index 1.49 at 8 degrees is about 0.8.
pub const WHITE: [f64; 3] = [0.0, 10.0, 0.016];
/// Thickness of either backing layer, um: the white's diffuse light falls by
/// `exp(-mu_eff t)`, `mu_eff = sqrt(3 mu_a (mu_a + mu_s (1 - g)))` = 0.22 per um (diffusion
/// theory, e.g. Ishimaru 1978, §9-3), so 1e-3 reaches the bottom of 30 um.
pub const BACKING_UM: f64 = 30.0;
/// R-infinity is bracketed at this multiple of the hiding thickness, where the two
/// backings differ by about `(1 - C)^2`, 4e-4 of Y at C = 0.98.
const THICK: f64 = 2.0;
/// The runs' `--max-segments`: enough for films a few hundred micrometres thick.
const MAX_SEGMENTS: u32 = 200_000;
/// Bracketing steps (doublings or halvings of the thickness) before the search gives up.
const MAX_BRACKET_STEPS: usize = 8;
/// Interpolation steps inside the bracket.
const REFINE_STEPS: usize = 3;

/// What the search asks for.
#[derive(Clone, Debug)]
pub struct HidingConfig {
    /// Incident polar angle, degrees (8: the d/8 instruments' specular-included geometry).
    pub theta_i_deg: f64,
    /// Trees per run.
    pub rays: u64,
    /// Wavelength bin edges, nm.
    pub edges: Vec<f64>,
    pub seed: u64,
    /// The contrast ratio that counts as hiding (0.98 in ISO 6504-3).
    pub contrast: f64,
    /// Replaces the scattering layer's particle volume fraction.
    pub volume_fraction: Option<f64>,
}

/// The film at one thickness over both backings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChartPoint {
    pub thickness_um: f64,
    /// Luminous reflectance over black and over white, with standard errors.
    pub y_black: (f64, f64),
    pub y_white: (f64, f64),
}

impl ChartPoint {
    /// The contrast ratio `Y_black / Y_white` and its standard error (the two treated as
    /// independent: an upper bound, since they share random numbers).
    pub fn contrast(&self) -> (f64, f64) {
        let ((b, sb), (w, sw)) = (self.y_black, self.y_white);
        let c = b / w;
        (c, c * ((sb / b).powi(2) + (sw / w).powi(2)).sqrt())
    }
}

/// The search's answer.
#[derive(Clone, Debug)]
pub struct Hiding {
    /// The scattering layer's medium and its volume fraction (None for a medium without
    /// particles).
    pub medium: String,
    pub volume_fraction: Option<f64>,
    /// Luminous reflectance of the white backing alone, under the binder's top face.
    pub white_backing: (f64, f64),
    /// Every thickness evaluated, in order.
    pub points: Vec<ChartPoint>,
    /// The hiding thickness, um, and its standard error from the contrast ratio's.
    pub thickness_um: (f64, f64),
    /// The film at twice the hiding thickness: R-infinity lies between its two
    /// reflectances.
    pub thick: ChartPoint,
}

impl Hiding {
    /// R-infinity's estimate (the middle of the bracket) and the bracket's half width
    /// plus two standard errors.
    pub fn r_infinity(&self) -> (f64, f64) {
        let ((b, sb), (w, sw)) = (self.thick.y_black, self.thick.y_white);
        (0.5 * (b + w), 0.5 * (w - b).abs() + 2.0 * sb.max(sw))
    }
}

/// The thickness at which `contrast(t)` reaches `target`, starting from `t0` um:
/// bracketing by doubling or halving, then interpolating `ln(1 - C)` linearly in `t` (at
/// most three steps, fewer once a point lies within its standard error of the target).
/// Returns the thickness, its standard error and every point evaluated.
pub fn search<F>(
    t0: f64,
    target: f64,
    mut eval: F,
) -> Result<((f64, f64), Vec<ChartPoint>), StudyError>
where
    F: FnMut(f64) -> Result<ChartPoint, StudyError>,
{
    let mut points = Vec::new();
    let mut at = |t: f64, points: &mut Vec<ChartPoint>| -> Result<f64, StudyError> {
        let p = eval(t)?;
        points.push(p);
        Ok(p.contrast().0)
    };
    let c0 = at(t0, &mut points)?;
    // (thickness, contrast) below and above the target.
    let (mut lo, mut hi) = ((t0, c0), (t0, c0));
    let mut t = t0;
    for step in 0..=MAX_BRACKET_STEPS {
        // The last thickness evaluated may be the one that crosses (issue 74: a paint
        // reaching 0.9984 at the last doubling was refused as not crossing 0.98).
        let crossed = if c0 < target {
            hi.1 >= target
        } else {
            lo.1 < target
        };
        if crossed {
            break;
        }
        if step == MAX_BRACKET_STEPS {
            // The range searched: doublings from t0 while below the target, halvings
            // while above.
            let span = 2f64.powi(MAX_BRACKET_STEPS as i32);
            let (from, to) = if c0 < target {
                (t0, t0 * span)
            } else {
                (t0 / span, t0)
            };
            return Err(StudyError::Invalid(format!(
                "the contrast ratio does not cross {target} between {from} and {to} um (it reached {:.4}); the film hides outside that range or not at all",
                if c0 < target { hi.1 } else { lo.1 }
            )));
        }
        if c0 < target {
            lo = hi;
            t *= 2.0;
            hi = (t, at(t, &mut points)?);
        } else {
            hi = lo;
            t *= 0.5;
            lo = (t, at(t, &mut points)?);
        }
    }
    let log = |c: f64| (1.0 - c).max(1e-9).ln();
    // The decay rate of 1 - C over the bracket the doubling or halving found (a factor of
    // two apart, so its noise is small against the change): dC/dt = (1 - C) rate.
    let rate = (log(lo.1) - log(hi.1)) / (hi.0 - lo.0).max(f64::MIN_POSITIVE);
    let interpolate = |lo: (f64, f64), hi: (f64, f64)| {
        let (a, b) = (log(lo.1), log(hi.1));
        if (a - b).abs() < 1e-12 {
            0.5 * (lo.0 + hi.0)
        } else {
            lo.0 + (log(target) - a) * (hi.0 - lo.0) / (b - a)
        }
    };
    for _ in 0..REFINE_STEPS {
        let t = interpolate(lo, hi).clamp(lo.0, hi.0);
        let c = at(t, &mut points)?;
        if c < target {
            lo = (t, c);
        } else {
            hi = (t, c);
        }
        // Within its own noise of the target: further steps would only wander in it.
        let se = points.last().map_or(0.0, |p| p.contrast().1);
        if (c - target).abs() <= se {
            break;
        }
    }
    let t = interpolate(lo, hi).clamp(lo.0, hi.0);
    // The standard error of C at the nearest point, carried over by dC/dt at the target
    // (a narrowed bracket's own slope is mostly noise).
    let slope = (1.0 - target) * rate;
    let nearest = points
        .iter()
        .min_by(|a, b| {
            (a.thickness_um - t)
                .abs()
                .total_cmp(&(b.thickness_um - t).abs())
        })
        .map_or(0.0, |p| p.contrast().1);
    let se = if slope > 0.0 {
        nearest / slope
    } else {
        f64::INFINITY
    };
    Ok(((t, se), points))
}

/// The hiding power of the sample at `path` (its text `text`): see the module's notes.
/// `progress` hears a line per run.
pub fn hiding(
    path: &Path,
    text: &str,
    cfg: &HidingConfig,
    progress: &dyn Fn(&str),
) -> Result<Hiding, StudyError> {
    let chart = Chart::new(path, text, cfg)?;
    let white_backing = chart.white_backing(cfg).map_err(|e| {
        StudyError::Invalid(format!(
            "the chart's white backing under the layers above the paint could not be simulated: {e}"
        ))
    })?;
    progress(&format!(
        "white backing alone: Y = {:.4} +- {:.4}",
        white_backing.0, white_backing.1
    ));
    // What the search saw, for a failure said in the paint's terms (`Chart::never_hides`).
    let seen = std::cell::RefCell::new(Vec::<ChartPoint>::new());
    let refused = std::cell::RefCell::new(None::<(f64, String)>);
    let eval = |t: f64| -> Result<ChartPoint, StudyError> {
        let p = chart.point(t, cfg).inspect_err(|e| {
            *refused.borrow_mut() = Some((t, e.to_string()));
        })?;
        seen.borrow_mut().push(p);
        let (c, se) = p.contrast();
        progress(&format!(
            "{t:.2} um: Y over black {:.4}, over white {:.4}, contrast {c:.4} +- {se:.4}",
            p.y_black.0, p.y_white.0
        ));
        Ok(p)
    };
    let (thickness_um, points) = search(chart.t0_um, cfg.contrast, eval)
        .map_err(|e| chart.never_hides(&e, &seen.borrow(), refused.borrow().as_ref()))?;
    let thick = chart.point(THICK * thickness_um.0, cfg)?;
    Ok(Hiding {
        medium: chart.medium.clone(),
        volume_fraction: chart.volume_fraction,
        white_backing,
        points,
        thickness_um,
        thick,
    })
}

/// The film `t_um` thick over both backings, on its own (for checks at one thickness).
pub fn chart_point(
    path: &Path,
    text: &str,
    cfg: &HidingConfig,
    t_um: f64,
) -> Result<ChartPoint, StudyError> {
    Chart::new(path, text, cfg)?.point(t_um, cfg)
}

/// A chart run's refusal in `hiding`'s terms: `simulate`'s sentences that advise flags
/// `hiding` does not have (--allow-unphysical, raising --max-depth) or that blame the
/// chart's own backings (opaque by design: [`BACKING_UM`] of [`WHITE`] is 300 mean free
/// paths, which every chart run traces) are left out (issue 74).
fn refusal(e: &crate::simulate::SimError) -> StudyError {
    let text = e.to_string();
    let kept: String = text
        .split_inclusive(". ")
        .filter(|s| {
            ![
                "--allow-unphysical",
                "raise --max-depth",
                "raise the limits",
                "'hiding-white'",
                "'hiding-black'",
            ]
            .iter()
            .any(|w| s.contains(w))
        })
        .collect();
    StudyError::Invalid(kept.trim_end().to_string())
}

/// The sample's description, parsed once, and what the chart changes in it.
struct Chart<'a> {
    path: &'a Path,
    doc: toml::Table,
    /// Index of the scattering layer in `[stack] layers`.
    layer: usize,
    medium: String,
    volume_fraction: Option<f64>,
    /// Micrometres per sample unit.
    um_per_unit: f64,
    /// The layer's own thickness, um: where the search starts.
    t0_um: f64,
    /// What scatters in the paint, as its description gives it.
    paint: Paint,
}

/// The paint's scattering as its description gives it, for errors in its own terms.
enum Paint {
    /// `henyey_greenstein`: scattering and absorption per um, and g.
    HenyeyGreenstein { s: f64, a: f64, g: f64 },
    /// `particles`, at the volume fraction run.
    Particles { volume_fraction: Option<f64> },
}

impl Paint {
    /// The paint's scattering at `t_um` thick: for a Henyey-Greenstein medium its
    /// coefficients and the depth in transport mean free paths, `t (s (1 - g) + a)`
    /// (diffusion theory's reduced extinction: Ishimaru 1978, §9-3).
    fn describe(&self, t_um: f64) -> String {
        match *self {
            Paint::HenyeyGreenstein { s, a, g } => format!(
                "it scatters {s} per um and absorbs {a} per um with g = {g}, so that film is {:.3} transport mean free paths deep",
                t_um * (s * (1.0 - g) + a)
            ),
            Paint::Particles {
                volume_fraction: Some(f),
            } => format!("its pigment fills a volume fraction {f}"),
            Paint::Particles {
                volume_fraction: None,
            } => "its particles give no volume fraction".to_string(),
        }
    }
}

impl<'a> Chart<'a> {
    fn new(path: &'a Path, text: &str, cfg: &HidingConfig) -> Result<Chart<'a>, StudyError> {
        let bad = |m: String| StudyError::Invalid(format!("{}: {m}", path.display()));
        let mut doc: toml::Table = text
            .parse()
            .map_err(|e: toml::de::Error| bad(e.to_string()))?;
        // Loads as it is first, so its own errors are named as the loader names them.
        sample::parse(path, text, MeshOptions::default())
            .map_err(|e| StudyError::Invalid(e.to_string()))?;
        let unit = doc
            .get("sample")
            .and_then(|s| s.get("unit"))
            .and_then(|u| u.as_str())
            .unwrap_or("nm");
        let um_per_unit = sample::nm_per_unit(unit).unwrap_or(1.0) * 1e-3;
        let media = doc.get("media").and_then(|m| m.as_table()).cloned();
        let scatters = |name: &str| {
            media.as_ref().and_then(|m| m.get(name)).is_some_and(|m| {
                m.get("particles").is_some() || m.get("henyey_greenstein").is_some()
            })
        };
        let layers = doc
            .get("stack")
            .and_then(|s| s.get("layers"))
            .and_then(|l| l.as_array())
            .ok_or_else(|| bad("hiding needs a [stack] whose layers hold the paint".into()))?;
        let scattering: Vec<(usize, String, f64)> = layers
            .iter()
            .enumerate()
            .filter_map(|(i, l)| {
                let name = l.get("medium")?.as_str()?;
                let t = l
                    .get("thickness")
                    .and_then(|t| t.as_float().or(t.as_integer().map(|v| v as f64)))?;
                scatters(name).then(|| (i, name.to_string(), t))
            })
            .collect();
        let [(layer, medium, t)] = scattering.as_slice() else {
            return Err(bad(format!(
                "hiding needs exactly one scattering layer (particles or henyey_greenstein) in [stack] layers, found {}",
                scattering.len()
            )));
        };
        let (layer, medium, t0_um) = (*layer, medium.clone(), t * um_per_unit);
        for name in ["hiding-black", "hiding-white"] {
            if media.as_ref().is_some_and(|m| m.contains_key(name)) {
                return Err(bad(format!(
                    "the sample names a medium '{name}', which hiding adds"
                )));
            }
        }
        let host = media
            .as_ref()
            .and_then(|m| m.get(&medium))
            .and_then(|m| m.as_table())
            .cloned()
            .unwrap_or_default();
        let particles = host.get("particles").and_then(|p| p.as_table()).cloned();
        let volume_fraction = match (cfg.volume_fraction, &particles) {
            (Some(_), None) => {
                return Err(bad(format!(
                    "--volume-fraction needs a medium of particles; '{medium}' scatters by henyey_greenstein"
                )));
            }
            (Some(f), Some(_)) => {
                // Named as the flag, before the chart's rewritten description would be
                // named with a line of its own.
                let rcp = crate::optics::particles::structure::RANDOM_CLOSE_PACKING;
                if !(f.is_finite() && f > 0.0 && f < rcp) {
                    return Err(bad(format!(
                        "--volume-fraction must lie in (0, {rcp}) ({rcp}: random close packing, the densest a suspension of spheres can be), got {f}"
                    )));
                }
                Some(f)
            }
            (None, Some(p)) => p.get("volume_fraction").and_then(|v| v.as_float()),
            (None, None) => None,
        };
        // The backings: the host's index model, without its particles, plus their own
        // scattering.
        let mut clear = host.clone();
        clear.remove("particles");
        clear.remove("henyey_greenstein");
        let media_doc = doc
            .get_mut("media")
            .and_then(|m| m.as_table_mut())
            .ok_or_else(|| bad("no [media]".into()))?;
        for (name, [g, s, a]) in [("hiding-black", BLACK), ("hiding-white", WHITE)] {
            let mut m = clear.clone();
            let mut hg = toml::Table::new();
            hg.insert("g".into(), g.into());
            hg.insert("scattering_per_um".into(), s.into());
            hg.insert("absorption_per_um".into(), a.into());
            m.insert("henyey_greenstein".into(), hg.into());
            media_doc.insert(name.into(), m.into());
        }
        if let (Some(f), Some(mut p)) = (cfg.volume_fraction, particles) {
            p.insert("volume_fraction".into(), f.into());
            if let Some(m) = media_doc.get_mut(&medium).and_then(|m| m.as_table_mut()) {
                m.insert("particles".into(), p.into());
            }
        }
        let num = |t: &toml::Table, k: &str| {
            t.get(k)
                .and_then(|v| v.as_float().or(v.as_integer().map(|i| i as f64)))
                .unwrap_or(0.0)
        };
        let paint = match host.get("henyey_greenstein").and_then(|h| h.as_table()) {
            Some(hg) => Paint::HenyeyGreenstein {
                s: num(hg, "scattering_per_um"),
                a: num(hg, "absorption_per_um"),
                g: num(hg, "g"),
            },
            None => Paint::Particles { volume_fraction },
        };
        Ok(Chart {
            path,
            doc,
            layer,
            medium,
            volume_fraction,
            um_per_unit,
            t0_um,
            paint,
        })
    }

    /// Why the search found no hiding thickness, in the paint's terms (issue 74: a paint
    /// that never hides was told to raise --max-depth or pass --allow-unphysical, which
    /// `hiding` does not have): how far the contrast ratio got at the thickest film
    /// simulated, what the paint's scattering is, and, where a film could not be simulated,
    /// at what thickness and why (the run's own advice about its flags left out).
    fn never_hides(
        &self,
        e: &StudyError,
        seen: &[ChartPoint],
        refused: Option<&(f64, String)>,
    ) -> StudyError {
        let first = match refused {
            Some((t, why)) => format!("the paint could not be simulated {t} um thick: {why}"),
            None => e.to_string(),
        };
        let reached = seen
            .iter()
            .max_by(|a, b| a.thickness_um.total_cmp(&b.thickness_um))
            .map_or_else(String::new, |p| {
                format!(
                    " At {} um, the thickest film simulated, its contrast ratio was {:.4} (Y {:.4} over black, {:.4} over white): {}.",
                    p.thickness_um,
                    p.contrast().0,
                    p.y_black.0,
                    p.y_white.0,
                    self.paint.describe(p.thickness_um)
                )
            });
        let first = first.trim_end_matches('.');
        StudyError::Invalid(match refused {
            Some(_) => format!(
                "no hiding thickness found for '{}': {first}.{reached}",
                self.medium
            ),
            None => format!(
                "'{}' does not hide: {first}.{reached} It hides, if at all, only thicker; more pigment, or a pigment that scatters more, hides in less.",
                self.medium
            ),
        })
    }

    /// The sample with the paint `t_um` thick (None: left out) over `backing`; layers
    /// below the paint are replaced by the backing.
    fn sample(&self, t_um: Option<f64>, backing: &str) -> Result<sample::Sample, StudyError> {
        let mut doc = self.doc.clone();
        let layers = doc
            .get_mut("stack")
            .and_then(|s| s.get_mut("layers"))
            .and_then(|l| l.as_array_mut())
            .expect("checked in Chart::new");
        layers.truncate(self.layer + 1);
        match t_um {
            Some(t) => {
                if let Some(l) = layers[self.layer].as_table_mut() {
                    l.insert("thickness".into(), (t / self.um_per_unit).into());
                }
            }
            None => {
                layers.pop();
            }
        }
        let mut b = toml::Table::new();
        b.insert("medium".into(), backing.into());
        b.insert("thickness".into(), (BACKING_UM / self.um_per_unit).into());
        layers.push(b.into());
        let text = toml::to_string(&doc).map_err(|e| StudyError::Invalid(e.to_string()))?;
        sample::parse(self.path, &text, MeshOptions::default())
            .map_err(|e| StudyError::Invalid(format!("the chart's sample: {e}")))
    }

    /// Luminous reflectance Y (CIE 1931 under D65, over the run's bins) and its standard
    /// error, of `s` at the configured angle.
    fn y(&self, s: &sample::Sample, cfg: &HidingConfig) -> Result<(f64, f64), StudyError> {
        let mut sim = SimConfig::new(
            vec![cfg.theta_i_deg],
            Wavelengths::Bins(cfg.edges.clone()),
            cfg.rays,
        );
        sim.seed = cfg.seed;
        // A thick film's deepest walks take many thousands of scattering events (the
        // square of the depth in mean free paths); the default limit cut 12 % of the
        // white paint's power at 385 um.
        sim.limits.max_segments = sim.limits.max_segments.max(MAX_SEGMENTS);
        let (acc, _) = simulate(s, &sim, &|_| {}).map_err(|e| refusal(&e))?;
        let refl = acc
            .reflectance(cfg.theta_i_deg, None)
            .map_err(|e| StudyError::Invalid(e.to_string()))?;
        let centres: Vec<f64> = refl.rows.iter().map(|r| r.lambda_nm).collect();
        let w: Vec<f64> = colour::bin_weights(&centres).iter().map(|w| w[1]).collect();
        let total: f64 = w.iter().sum();
        let y = refl.rows.iter().zip(&w).map(|(r, w)| r.r * w).sum::<f64>() / total;
        let var = refl
            .rows
            .iter()
            .zip(&w)
            .map(|(r, w)| (r.r_stderr.unwrap_or(0.0) * w).powi(2))
            .sum::<f64>();
        Ok((y, var.sqrt() / total))
    }

    fn point(&self, t_um: f64, cfg: &HidingConfig) -> Result<ChartPoint, StudyError> {
        Ok(ChartPoint {
            thickness_um: t_um,
            y_black: self.y(&self.sample(Some(t_um), "hiding-black")?, cfg)?,
            y_white: self.y(&self.sample(Some(t_um), "hiding-white")?, cfg)?,
        })
    }

    fn white_backing(&self, cfg: &HidingConfig) -> Result<(f64, f64), StudyError> {
        self.y(&self.sample(None, "hiding-white")?, cfg)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The search finds the closed-form crossing of a contrast ratio that approaches 1
    /// exponentially, `C(t) = 1 - a exp(-t / L)`: `t* = L ln(a / (1 - C*))`, from above
    /// and from below.
    #[test]
    fn search_finds_the_crossing_of_an_exponential_approach() {
        let (a, l) = (0.6, 7.0);
        for t0 in [1.0, 20.0, 400.0] {
            let eval = |t: f64| {
                let c: f64 = 1.0 - a * (-t / l).exp();
                Ok(ChartPoint {
                    thickness_um: t,
                    y_black: (0.9 * c, 0.0),
                    y_white: (0.9, 0.0),
                })
            };
            let ((t, se), points) = search(t0, 0.98, eval).unwrap();
            let exact = l * (a / 0.02f64).ln();
            assert!(
                (t - exact).abs() < 1e-9 * exact,
                "from {t0}: {t} vs {exact}"
            );
            assert_eq!(se, 0.0);
            assert!(points.len() <= 1 + MAX_BRACKET_STEPS + REFINE_STEPS);
        }
    }

    /// A crossing inside the last bracket the doubling reaches is found (issue 74: the
    /// search stopped one step early, so a paint that reaches 0.98 only at the last
    /// doubling was refused as never hiding): `C = 1 - 0.6 exp(-t / 50)` crosses 0.98 at
    /// 170 um, between 128 and 256 um, the last doubling of 1 um.
    #[test]
    fn search_finds_a_crossing_in_its_last_bracket() {
        let eval = |t: f64| {
            let c: f64 = 1.0 - 0.6 * (-t / 50.0).exp();
            Ok(ChartPoint {
                thickness_um: t,
                y_black: (0.9 * c, 0.0),
                y_white: (0.9, 0.0),
            })
        };
        assert_eq!(2f64.powi(MAX_BRACKET_STEPS as i32), 256.0);
        let ((t, _), _) = search(1.0, 0.98, eval).unwrap();
        let exact = 50.0 * (0.6f64 / 0.02).ln();
        assert!((t - exact).abs() < 1e-9 * exact, "{t} vs {exact}");
    }

    /// A film that never hides in range is an error naming the range, not a number.
    #[test]
    fn search_says_when_the_film_never_hides() {
        let eval = |t: f64| {
            Ok(ChartPoint {
                thickness_um: t,
                y_black: (0.5, 0.01),
                y_white: (0.8, 0.01),
            })
        };
        let e = search(10.0, 0.98, eval).unwrap_err().to_string();
        assert!(e.contains("does not cross 0.98"), "{e}");
    }
}
