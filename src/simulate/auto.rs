//! `--coherence auto`, the default: the method each (incident direction, wavelength) cell
//! takes, chosen before tracing from the sample's scales (`sample::validity`, measured limits
//! in docs/validity.md) and recorded in the `.gsa` (`Settings::methods`).
//!
//! A cell takes the diffraction method where its angular distribution holds interference
//! that rays do not give (a coherent specular order narrower than the rays' lobe, or a
//! grating's resolved orders: `cell_needs`) and the method can hold it: the
//! sample is periodic with deterministic trees (`diffraction_refused`), the tangent plane
//! holds (`physical_optics_margin` at least `Need::margin_min`, the sheets not deep against
//! their curvature), and its grid
//! and kept exits fit in memory. Every other cell takes rays with the beamlet estimator.
//! Where a cell needed the diffraction method and could not have it, the run says which
//! cells, what they miss, and why (`Choice::notes`); no such note advises another of the
//! run's methods, since the run already took the one that holds.
//!
//! The choice depends only on the sample, the cell's angle and wavelength and the settings,
//! so a batch unit (one direction) chooses as the whole run does.

use super::SimConfig;
use super::rigorous_fit::RigorousFit;
use crate::reference::rigorous::Rigorous;
use crate::sample::Sample;
use crate::sample::validity::{self, PHYSICAL_OPTICS_MIN, PHYSICAL_OPTICS_MIN_GRATING};

/// Each cell's method (direction-major; `true`: the diffraction method) and what the run
/// must say about cells that needed the diffraction method and took rays.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Choice {
    pub diffraction: Vec<bool>,
    /// Cells the rigorous solver takes (direction-major), and the sample sliced for it.
    pub rigorous: Vec<bool>,
    pub solver: Option<Rigorous>,
    pub notes: Vec<String>,
}

/// Why the diffraction method cannot take `sample` under `cfg` at all (`None` where it
/// can): the conditions `prepare::method_refusals` refuses an explicit
/// `--coherence diffraction` for.
pub fn diffraction_refused(sample: &Sample, cfg: &SimConfig) -> Option<&'static str> {
    if sample.media.iter().any(|m| m.scattering.is_some()) {
        Some("its particle media scatter with random phases")
    } else if sample.guard_nm.is_some() {
        Some(
            "its sides are open (a guard band), and the method takes the far field of a periodic tile",
        )
    } else if sample.interfaces.iter().any(|i| i.closed) {
        Some("its closed bodies end long trees by Russian roulette with random weights")
    } else if cfg.adaptive() {
        Some(
            "--tolerance and --target-stderr stop on the per-tree error, which a transform of all trees at once does not have",
        )
    } else {
        None
    }
}

/// The run's choice for every cell, from the sample's sheets' scales
/// (`validity::sheet_scales`). `grid_fits(lambda_nm)` says whether the diffraction
/// method's grid and kept exits fit at that wavelength (`Err` with the reason where not).
pub fn choose(
    sample: &Sample,
    cfg: &SimConfig,
    sheets: &[Option<validity::Scales>],
    grid_fits: &dyn Fn(f64) -> Result<(), String>,
) -> Choice {
    let nl = cfg.wavelengths.count();
    let centres = cfg.wavelengths.centres();
    let bucket_rad = std::f64::consts::FRAC_PI_2 / f64::from(cfg.buckets.theta_bins);
    let refused = diffraction_refused(sample, cfg);
    let mut out = Choice {
        diffraction: vec![false; cfg.theta_i_deg.len() * nl],
        rigorous: vec![false; cfg.theta_i_deg.len() * nl],
        solver: None,
        notes: Vec::new(),
    };
    // Cells that needed the method and took rays, per reason: (count, worst cell's need,
    // its angle and wavelength, the reason's figure).
    let mut missed: std::collections::BTreeMap<u8, Missed> = Default::default();
    let mut fits: Vec<Option<Result<(), String>>> = vec![None; nl];
    let mut rigorous = RigorousFit::new(sample, cfg);
    let mut rfits: Vec<Option<Option<String>>> = vec![None; nl];
    // Cells finer than the wavelength that the rigorous solver could not take: the count,
    // the first one's sheet, wavelength in its denser medium, angle, wavelength and reason.
    let mut fine: Option<(usize, usize, f64, f64, f64, String)> = None;
    for (di, &theta) in cfg.theta_i_deg.iter().enumerate() {
        for (j, &lambda) in centres.iter().enumerate() {
            // Ok where the rigorous solver takes the cell, else why not.
            let mut rfit = || {
                let refusal = rfits[j].get_or_insert_with(|| rigorous.refusal(lambda));
                refusal.clone().map_or(Ok(()), Err)
            };
            if let Some((iface, lam)) = validity::finer_than_wavelength(sample, sheets, lambda) {
                match rfit() {
                    Ok(()) => out.rigorous[di * nl + j] = true,
                    Err(r) => {
                        fine.get_or_insert((0, iface, lam, theta, lambda, r)).0 += 1;
                    }
                }
                continue;
            }
            let Some(need) = cell_needs(sample, sheets, theta, lambda, cfg.rho_nm, bucket_rad)
            else {
                continue;
            };
            let margin = physical_optics_margin(sample, sheets, theta, lambda);
            let fit = fits[j].get_or_insert_with(|| grid_fits(lambda)).clone();
            let why = if let Some(r) = refused {
                Some((0, r.to_string()))
            } else if cfg.rho_nm < 0.5 * cfg.wavelengths.max() {
                Some((
                    1,
                    format!(
                        "the coherence radius {} nm is below half the longest wavelength, which the method's spread of the orders cannot hold",
                        cfg.rho_nm
                    ),
                ))
            } else if margin < need.margin_min() {
                Some((
                    2,
                    format!(
                        "the tangent plane the method rests on fails there (k r_c cos^3 theta = {margin:.1}, below {} for {})",
                        need.margin_min(),
                        need.what()
                    ),
                ))
            } else if let Some(depth) = too_deep(sheets) {
                Some((
                    4,
                    format!(
                        "a sheet is deep against its curvature (RMS height / curvature radius {depth:.2}, above {}), where the method's tubes overlap on the exit plane as they do not at the surface",
                        validity::MAX_DEPTH_OVER_CURVATURE
                    ),
                ))
            } else if let Err(e) = fit {
                Some((3, e))
            } else {
                None
            };
            let Some((kind, reason)) = why else {
                out.diffraction[di * nl + j] = true;
                continue;
            };
            // Where the tangent plane fails, the rigorous solver holds if it fits; where it
            // does not, the note says why.
            let solver = match kind {
                2 | 4 => match rfit() {
                    Ok(()) => {
                        out.rigorous[di * nl + j] = true;
                        continue;
                    }
                    Err(r) => Some(r),
                },
                _ => None,
            };
            let m = missed.entry(kind).or_insert_with(|| Missed {
                cells: 0,
                need: need.clone(),
                theta,
                lambda,
                reason,
                solver,
                theta_min: theta,
            });
            m.cells += 1;
            m.theta_min = m.theta_min.min(theta);
        }
    }
    let total = out.diffraction.len();
    for m in missed.into_values() {
        out.notes.push(m.note(sample, total));
    }
    if let Some((cells, i, lam, theta, lambda, reason)) = fine {
        out.notes.push(format!(
            "interface {i} ({}) has structure near or below the wavelength at {lambda:.0} nm ({lam:.0} nm in its denser medium; below {} wavelengths of period or {} of curvature radius), where neither rays nor the diffraction method hold, and the rigorous solver cannot take this sample: {reason}; so {cells} cells of {total} (from {theta:.0} deg) took rays, whose R and angular distribution are uncertain there (docs/validity.md)",
            sample.interfaces[i].mesh_path.display(),
            validity::MIN_PERIOD_WAVELENGTHS,
            validity::MIN_CURVATURE_WAVELENGTHS,
        ));
    }
    if out.rigorous.contains(&true) {
        out.solver = rigorous.into_solver();
    }
    out
}

/// The cells of one reason that needed the diffraction method and took rays.
struct Missed {
    cells: usize,
    /// The first such cell's need, angle (deg) and wavelength (nm).
    need: Need,
    theta: f64,
    lambda: f64,
    reason: String,
    /// Why the rigorous solver could not take them, where it would hold (the tangent plane
    /// fails, or a sheet is too deep).
    solver: Option<String>,
    theta_min: f64,
}

impl Missed {
    fn note(&self, sample: &Sample, total: usize) -> String {
        let name = |i: usize| {
            format!(
                "interface {i} ({})",
                sample.interfaces[i].mesh_path.display()
            )
        };
        let what = match self.need {
            Need::Specular { interface, g } => format!(
                "{} is smooth against the wavelength (Rayleigh g = {g:.2} at {:.0} deg and {:.0} nm): a coherent specular order holds about exp(-g) = {:.2} of the reflected power, which rays spread over the slope lobe",
                name(interface),
                self.theta,
                self.lambda,
                (-g).exp()
            ),
            Need::Orders { interface, spacing } => format!(
                "{} is a grating whose orders are {spacing:.3} apart in direction sines at {:.0} deg and {:.0} nm, which rays give only as their envelope",
                name(interface),
                self.theta,
                self.lambda
            ),
        };
        // What would hold these cells, as a fact of this sample: the rigorous solver, where
        // it could not take them here. (Not advice to switch: an auto run already takes it
        // wherever it fits.)
        let beyond = self.solver.as_ref().map_or(String::new(), |why| {
            format!("; the rigorous solver cannot take them: {why}")
        });
        format!(
            "{} cells of {total} (from {:.0} deg) took rays, whose angular distribution misses what follows (their total R is right): {what}. The diffraction method holds that, but {}{beyond}",
            self.cells, self.theta_min, self.reason
        )
    }
}

/// What interference a cell's angular distribution holds that rays do not give.
#[derive(Clone, Debug, PartialEq)]
pub enum Need {
    /// A coherent specular order of `exp(-g)` of the reflected power, from the sheet
    /// `interface`, narrower than the rays' slope lobe at the coherence radius.
    Specular { interface: usize, g: f64 },
    /// The orders of a grating (sheet `interface`) that the coherence radius spans and the
    /// buckets resolve, `spacing` apart in direction sines.
    Orders { interface: usize, spacing: f64 },
}

impl Need {
    /// The smallest tangent-plane margin (`physical_optics_margin`) at which the
    /// diffraction method holds this need, as measured (`validity::PHYSICAL_OPTICS_MIN`,
    /// `validity::PHYSICAL_OPTICS_MIN_GRATING`).
    pub fn margin_min(&self) -> f64 {
        match self {
            Need::Specular { .. } => PHYSICAL_OPTICS_MIN,
            Need::Orders { .. } => PHYSICAL_OPTICS_MIN_GRATING,
        }
    }

    fn what(&self) -> &'static str {
        match self {
            Need::Specular { .. } => "a rough surface's coherent order",
            Need::Orders { .. } => "a grating's orders",
        }
    }
}

/// The largest RMS height over curvature radius among the sheets, where it is above
/// `validity::MAX_DEPTH_OVER_CURVATURE` (the diffraction method's limit there).
fn too_deep(sheets: &[Option<validity::Scales>]) -> Option<f64> {
    sheets
        .iter()
        .flatten()
        .filter(|s| s.curvature_radius_nm.is_finite())
        .map(|s| s.rms_height_nm / s.curvature_radius_nm)
        .filter(|&d| d > validity::MAX_DEPTH_OVER_CURVATURE)
        .reduce(f64::max)
}

/// What cell (`theta_deg`, vacuum `lambda_nm`) needs beyond rays, judged per sheet as the
/// warnings of [`validity::assess_scales`] judge the run: a grating whose orders are coherent across
/// (`Lambda < COHERENT_PERIODS rho`) and resolved (`lambda / Lambda > bucket / 4`), or a
/// surface smooth against the wavelength (Rayleigh `g = (4 pi sigma cos theta / lambda)^2 <
/// validity::RAYLEIGH_MIN_FOR_RAYS`, Beckmann & Spizzichino 1963, ch. 5) whose coherent order, spread
/// by the partial coherence over `1 / (k rho)` in direction sines (the Gaussian mutual
/// coherence's transform), is narrower than the rays' lobe (`2 s`, the reflected directions
/// of facets of RMS slope `s`). `None` where rays give the angular distribution.
pub fn cell_needs(
    sample: &Sample,
    sheets: &[Option<validity::Scales>],
    theta_deg: f64,
    lambda_nm: f64,
    rho_nm: f64,
    bucket_rad: f64,
) -> Option<Need> {
    let cos = theta_deg.to_radians().cos().max(0.05);
    let spread = lambda_nm / (2.0 * std::f64::consts::PI * rho_nm);
    for (i, (itf, sc)) in sample.interfaces.iter().zip(sheets).enumerate() {
        let Some(sc) = sc.filter(validity::Scales::structured) else {
            continue;
        };
        if itf.closed {
            continue;
        }
        if sc.period_share >= 0.5 {
            let coherent = sc.period_nm < validity::COHERENT_PERIODS * rho_nm;
            let spacing = lambda_nm / sc.period_nm;
            if coherent && spacing > bucket_rad / validity::ORDERS_PER_BUCKET {
                return Some(Need::Orders {
                    interface: i,
                    spacing,
                });
            }
        }
        let g = (4.0 * std::f64::consts::PI * sc.rms_height_nm * cos / lambda_nm).powi(2);
        if g < validity::RAYLEIGH_MIN_FOR_RAYS && spread < 2.0 * sc.rms_slope {
            return Some(Need::Specular { interface: i, g });
        }
    }
    None
}

/// The smallest `k r_c cos^3 theta` over the sample's sheets at (`theta_deg`, vacuum
/// `lambda_nm`), `k` in each sheet's front medium (infinite for flat sheets): the
/// tangent-plane condition [`PHYSICAL_OPTICS_MIN`] judges.
pub fn physical_optics_margin(
    sample: &Sample,
    sheets: &[Option<validity::Scales>],
    theta_deg: f64,
    lambda_nm: f64,
) -> f64 {
    sample
        .interfaces
        .iter()
        .zip(sheets)
        .filter_map(|(itf, sc)| {
            let sc = sc.as_ref()?;
            Some(validity::tangent_plane_margin(
                sample, itf, sc, theta_deg, lambda_nm,
            ))
        })
        .fold(f64::INFINITY, f64::min)
}

/// `goniospec check` as the default run would judge it: [`crate::check::check`], and where
/// the context's method is auto, the methods it takes at the context's wavelength per angle
/// as a fact, with its notes on cells that needed the diffraction method and could not have
/// it as warnings.
pub fn check(
    sample: &Sample,
    opts: &crate::check::CheckOptions,
) -> Result<crate::check::CheckReport, crate::accel::AccelError> {
    let mut r = crate::check::check(sample, opts)?;
    if let Some(ctx) = opts
        .validity
        .as_ref()
        .filter(|c| c.method == validity::Method::Auto)
    {
        let (fact, notes) = methods_fact(sample, &r.sheets, ctx);
        r.facts.push(fact);
        r.warnings.extend(notes);
    }
    Ok(r)
}

/// What `--coherence auto` (the default) takes at the context's wavelength and angles, as
/// a fact ("the diffraction method at 0-40 deg, rays at 41-60 deg"), with its notes on
/// cells that needed the diffraction method and could not have it. The memory the method's
/// grid needs is judged by the run itself (it depends on the trees asked for).
fn methods_fact(
    sample: &Sample,
    sheets: &[Option<crate::sample::validity::Scales>],
    ctx: &crate::sample::validity::Context,
) -> (String, Vec<String>) {
    use super::{Wavelengths, defaults};
    let cfg = SimConfig {
        rho_nm: ctx.rho_nm,
        ..SimConfig::new(
            ctx.theta_i_deg.clone(),
            Wavelengths::Monochromatic(vec![ctx.lambda_min_nm]),
            defaults::RAYS,
        )
    };
    let choice = choose(sample, &cfg, sheets, &|_| Ok(()));
    // Runs of consecutive angles with the same method.
    let mut runs: Vec<(&str, f64, f64)> = Vec::new();
    for (k, &t) in ctx.theta_i_deg.iter().enumerate() {
        let what = if choice.rigorous[k] {
            "the rigorous solver"
        } else if choice.diffraction[k] {
            "the diffraction method"
        } else {
            "rays"
        };
        match runs.last_mut() {
            Some(last) if last.0 == what => last.2 = t,
            _ => runs.push((what, t, t)),
        }
    }
    let parts: Vec<String> = runs
        .iter()
        .map(|&(what, a, b)| {
            if a == b {
                format!("{what} at {a} deg")
            } else {
                format!("{what} at {a}-{b} deg")
            }
        })
        .collect();
    (
        format!(
            "methods under --coherence auto (the default) at {} nm: {}",
            ctx.lambda_min_nm,
            parts.join(", ")
        ),
        choice.notes,
    )
}

/// `Settings::methods` of a `--coherence auto` run: per direction, one letter per
/// wavelength cell, `m` where the rigorous solver gave the buckets, `d` where the
/// diffraction method did and `r` where rays did (chosen so, or fallen back:
/// `DiffractionCell::fell_back`).
pub(super) fn method_strings(
    diffraction: &[bool],
    rigorous: &[bool],
    cells: &[super::DiffractionCell],
    nl: usize,
) -> Vec<String> {
    let nl = nl.max(1);
    (0..diffraction.len() / nl)
        .map(|di| {
            (di * nl..(di + 1) * nl)
                .map(|k| {
                    if rigorous[k] {
                        'm'
                    } else if diffraction[k] && !cells[k].fell_back {
                        'd'
                    } else {
                        'r'
                    }
                })
                .collect()
        })
        .collect()
}
