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
//! Each thickness is run on [`REPLICATES`] seeds, each over both backings: a tree is the
//! same path over either until it first enters the backing (the black ends it, the white
//! sends it on), so each seed's pair shares its noise, and the contrast ratio's error
//! comes from the pairs' spread (`search`'s notes), several times smaller than two
//! independent runs'.
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
//!
//! Budgets follow the error (issue 71: a fixed 2,048 trees per run took 9 min 36 s for
//! +-32 % on the white paint): the search runs at `rays` trees per backing, then the
//! found thickness takes as many more as its standard error needs to reach `goal`
//! (`search::settle`), and the film at twice that thickness as many as the last run.
//! A result that cannot be true is an error: R-infinity above 1, or a thickness whose
//! standard error is larger than itself.

use std::path::Path;

use crate::render::colour;
use crate::sample::{self, MeshOptions};
use crate::simulate::{SimConfig, Wavelengths, simulate};

use super::StudyError;

mod search;
pub use search::{ChartPoint, Found, REPLICATES, search, settle};

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
/// The runs' `--max-depth` (events along one path, each meeting of a face included).
const MAX_DEPTH: u32 = 4096;

/// What the search asks for.
#[derive(Clone, Debug)]
pub struct HidingConfig {
    /// Incident polar angle, degrees (8: the d/8 instruments' specular-included geometry).
    pub theta_i_deg: f64,
    /// Trees per backing at each thickness of the search (split over [`REPLICATES`]
    /// seeds).
    pub rays: u64,
    /// The relative standard error of the hiding thickness the found thickness is run to
    /// (None: the search's own, at `rays`).
    pub goal: Option<f64>,
    /// The most trees per backing a thickness may take while reaching `goal`.
    pub max_rays: u64,
    /// Wavelength bin edges, nm.
    pub edges: Vec<f64>,
    pub seed: u64,
    /// The contrast ratio that counts as hiding (0.98 in ISO 6504-3).
    pub contrast: f64,
    /// Replaces the scattering layer's particle volume fraction.
    pub volume_fraction: Option<f64>,
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
    /// Trees per backing of the last run at the hiding thickness.
    pub trees: u64,
    /// Every tree traced, over both backings and every run.
    pub total_trees: u64,
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
    let eval = |t: f64, trees: u64| -> Result<ChartPoint, StudyError> {
        let p = chart.point(t, trees, cfg).inspect_err(|e| {
            *refused.borrow_mut() = Some((t, e.to_string()));
        })?;
        seen.borrow_mut().push(p);
        let (c, se) = p.contrast();
        progress(&format!(
            "{t:.2} um, {trees} trees per backing: Y over black {:.4}, over white {:.4}, contrast {c:.4} +- {se:.4}",
            p.y_black.0, p.y_white.0
        ));
        Ok(p)
    };
    let found = search(chart.t0_um, cfg.contrast, |t| eval(t, cfg.rays))
        .map_err(|e| chart.never_hides(&e, &seen.borrow(), refused.borrow().as_ref()))?;
    let found = match cfg.goal {
        Some(goal) => settle(found, cfg.contrast, goal, cfg.rays, cfg.max_rays, eval)?,
        None => found,
    };
    let Found {
        thickness_um,
        points,
        ..
    } = found;
    let (t, se) = thickness_um;
    let trees = points.last().map_or(cfg.rays, |p| p.trees);
    resolved(t, se, trees)?;
    if let Some(goal) = cfg.goal
        && se > goal * t
    {
        progress(&format!(
            "the hiding thickness's standard error is {:.1} % at {trees} trees per backing, --max-rays, above the goal of {:.1} %",
            100.0 * se / t,
            100.0 * goal
        ));
    }
    let thick = chart.point(THICK * t, trees, cfg)?;
    let total_trees = 2 * (points.iter().map(|p| p.trees).sum::<u64>() + thick.trees + cfg.rays);
    let h = Hiding {
        medium: chart.medium.clone(),
        volume_fraction: chart.volume_fraction,
        white_backing,
        points,
        thickness_um,
        trees,
        total_trees,
        thick,
    };
    possible(&h)?;
    Ok(h)
}
/// A thickness whose standard error `se` is not below itself is no result.
fn resolved(t: f64, se: f64, trees: u64) -> Result<(), StudyError> {
    if se < t {
        return Ok(());
    }
    Err(StudyError::Invalid(format!(
        "the hiding thickness is not resolved: {t:.1} +- {se:.1} um at {trees} trees per backing; raise --rays or --max-rays (or lower --target-stderr)"
    )))
}

/// R-infinity above 1 is no result: refused, saying whether its uncertainty covers it.
fn possible(h: &Hiding) -> Result<(), StudyError> {
    let (r_inf, half) = h.r_infinity();
    if r_inf <= 1.0 {
        return Ok(());
    }
    let why = if r_inf - half > 1.0 {
        "beyond its uncertainty: energy was created, which is a bug to report"
    } else {
        "within its uncertainty, which is too large: raise --max-rays or lower --target-stderr"
    };
    Err(StudyError::Invalid(format!(
        "R-infinity came out {r_inf:.4} +- {half:.4} (over black {:.4}, over white {:.4} at {:.1} um), above 1, {why}",
        h.thick.y_black.0, h.thick.y_white.0, h.thick.thickness_um
    )))
}

/// The film `t_um` thick over both backings, on its own (for checks at one thickness).
pub fn chart_point(
    path: &Path,
    text: &str,
    cfg: &HidingConfig,
    t_um: f64,
) -> Result<ChartPoint, StudyError> {
    Chart::new(path, text, cfg)?.point(t_um, cfg.rays, cfg)
}

/// Replicate `r`'s seed: `s K + r` for the user's seed `s`, so the replicates of
/// different seeds never meet.
fn replicate_seed(seed: u64, r: u64) -> u64 {
    seed.wrapping_mul(REPLICATES as u64).wrapping_add(r)
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
    fn y(
        &self,
        s: &sample::Sample,
        seed: u64,
        trees: u64,
        cfg: &HidingConfig,
    ) -> Result<f64, StudyError> {
        let mut sim = SimConfig::new(
            vec![cfg.theta_i_deg],
            Wavelengths::Bins(cfg.edges.clone()),
            trees,
        );
        sim.seed = seed;
        // Only the hemispherical totals are read: next-event estimation, which spreads
        // each scattering event over the bucket grid, would only cost time (a third of a
        // run's on the white paint).
        sim.next_event = false;
        // A thick film's deepest walks take many thousands of scattering events (the
        // square of the depth in mean free paths); the default limit cut 12 % of the
        // white paint's power at 385 um.
        sim.limits.max_segments = sim.limits.max_segments.max(MAX_SEGMENTS);
        // Each time a walk meets the film's top face it splits there, one event deeper;
        // a walk in a film a hundred micrometres thick meets it many times, and the
        // default 64 cut 11 % of a replicate's power (8 trees) at 80 um.
        sim.limits.max_depth = sim.limits.max_depth.max(MAX_DEPTH);
        let (acc, _) = simulate(s, &sim, &|_| {}).map_err(|e| refusal(&e))?;
        let refl = acc
            .reflectance(cfg.theta_i_deg, None)
            .map_err(|e| StudyError::Invalid(e.to_string()))?;
        let centres: Vec<f64> = refl.rows.iter().map(|r| r.lambda_nm).collect();
        let w: Vec<f64> = colour::bin_weights(&centres).iter().map(|w| w[1]).collect();
        let total: f64 = w.iter().sum();
        Ok(refl.rows.iter().zip(&w).map(|(r, w)| r.r * w).sum::<f64>() / total)
    }

    /// `y` over each backing on every replicate seed (in parallel, collected in seed
    /// order), `trees` per backing in all.
    fn pairs(
        &self,
        backings: [&sample::Sample; 2],
        trees: u64,
        cfg: &HidingConfig,
    ) -> Result<Vec<(f64, f64)>, StudyError> {
        use rayon::prelude::*;
        let k = REPLICATES as u64;
        let each = trees.div_ceil(k).max(1);
        (0..k)
            .into_par_iter()
            .map(|r| {
                let seed = replicate_seed(cfg.seed, r);
                Ok((
                    self.y(backings[0], seed, each, cfg)?,
                    self.y(backings[1], seed, each, cfg)?,
                ))
            })
            .collect()
    }

    fn point(&self, t_um: f64, trees: u64, cfg: &HidingConfig) -> Result<ChartPoint, StudyError> {
        let black = self.sample(Some(t_um), "hiding-black")?;
        let white = self.sample(Some(t_um), "hiding-white")?;
        let pairs = self.pairs([&black, &white], trees, cfg)?;
        let each = trees.div_ceil(REPLICATES as u64).max(1);
        Ok(ChartPoint::from_pairs(
            t_um,
            &pairs,
            each * REPLICATES as u64,
        ))
    }

    fn white_backing(&self, cfg: &HidingConfig) -> Result<(f64, f64), StudyError> {
        use rayon::prelude::*;
        let white = self.sample(None, "hiding-white")?;
        let each = cfg.rays.div_ceil(REPLICATES as u64).max(1);
        let ys = (0..REPLICATES as u64)
            .into_par_iter()
            .map(|r| Ok((0.0, self.y(&white, replicate_seed(cfg.seed, r), each, cfg)?)))
            .collect::<Result<Vec<_>, StudyError>>()?;
        Ok(ChartPoint::from_pairs(0.0, &ys, 0).y_white)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn answer(black: f64, white: f64, se: f64) -> Hiding {
        let p = |t| ChartPoint {
            thickness_um: t,
            y_black: (black, se),
            y_white: (white, se),
            contrast: (black / white, se),
            trees: 256,
        };
        Hiding {
            medium: "paint".into(),
            volume_fraction: None,
            white_backing: (0.8, 0.01),
            points: vec![p(100.0)],
            thickness_um: (100.0, 5.0),
            trees: 256,
            total_trees: 1024,
            thick: p(200.0),
        }
    }

    /// R-infinity above 1 is refused, and the message says whether noise could explain
    /// it (issue 71: `--rays 128` printed 1.0132 with no warning); at or below 1 it passes.
    #[test]
    fn r_infinity_above_one_is_refused() {
        assert!(possible(&answer(0.95, 0.96, 0.005)).is_ok());
        let e = possible(&answer(1.005, 1.02, 0.01))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("above 1") && e.contains("within its uncertainty"),
            "{e}"
        );
        let e = possible(&answer(1.05, 1.06, 0.001))
            .unwrap_err()
            .to_string();
        assert!(e.contains("beyond its uncertainty"), "{e}");
    }

    /// A thickness no better known than its own size is refused (issue 71: 118 +- 273 um
    /// was printed).
    #[test]
    fn an_unresolved_thickness_is_refused() {
        assert!(resolved(118.0, 20.0, 256).is_ok());
        let e = resolved(118.0, 273.0, 128).unwrap_err().to_string();
        assert!(
            e.contains("not resolved") && e.contains("118.0 +- 273.0"),
            "{e}"
        );
        assert!(resolved(118.0, f64::INFINITY, 128).is_err());
        assert!(resolved(118.0, f64::NAN, 128).is_err());
    }
}
