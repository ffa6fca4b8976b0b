//! Fits a parametric real-time material to a simulated one: GGX roughness, a base
//! (dielectric index, or a conductor's complex index per wavelength), an optional thin
//! film (thickness, index, weight) and an optional clear coat over them (index), and writes
//! them for glTF 2.0 (`KHR_materials_iridescence`, `KHR_materials_ior`,
//! `KHR_materials_clearcoat`), OpenPBR and Autodesk Standard Surface.
//!
//! Model: the single-scattering GGX microfacet BRDF with height-correlated Smith masking
//! (Walter, Marschner, Li & Torrance, EGSR 2007, eqs. 20, 33, 34; Heitz 2014, JCGT 3(2),
//! eq. 99),
//!
//! ```text
//! f(wi, wo, lambda) = F(theta_d, lambda) D(h) G2(wi, wo) / (4 cos(theta_i) cos(theta_o))
//! F = w F_film + (1 - w) F_base
//! ```
//!
//! where `F_film` is the Airy reflectance of a film of index `n_f` and thickness `d` on the
//! base (the transfer-matrix method; Belcour & Barla, SIGGRAPH 2017, evaluate the same
//! quantity for rendering) and `theta_d` the angle between `wi` and `h`.
//!
//! The fit runs in three stages on the accumulator's own buckets:
//! 1. roughness: the wavelength-averaged lobe's shape against `D G2 / (4 cos cos)` integrated
//!    over every bucket (4 x 4 points each), a free scale per incident angle, golden-section
//!    search on `log(alpha)`;
//! 2. base: directional reflectance `R(theta_i, lambda)` against `E(theta_i) F(theta_i,
//!    lambda)`, `E` the model's own directional albedo with `F = 1` (the specular lobe is
//!    narrow enough that `F` at `theta_i` stands for it; docs/fitting.md), plus the
//!    multiple-scattering albedo `(1 - E) F_avg^2 E_avg / (1 - F_avg (1 - E_avg))` (Kulla &
//!    Conty 2017; [`multiple_scattering`]);
//! 3. film: a grid over thickness (5 nm steps, 20-2000 nm) and index (1.2-2.6) for the
//!    multimodal start, then Nelder-Mead on (d, n_f, w, n_b), with the CIELAB colour
//!    difference of every incident angle's reflected spectrum under D65 added to the squared
//!    reflectance error so highlights and colour both count (1 unit of Delta E weighs as
//!    0.01 of reflectance).

mod coat;
mod export;
mod film;
mod model;

pub use coat::{Coat, CoatChoice};
use coat::{fit_coated, mirror_excess, represents};
pub use export::{to_gltf, to_json, write_json};
use film::{fit_film, implausible_film};
use model::{Albedo, BaseTerms, model_on, model_r, multiple_scattering, reflectance};

use crate::accumulate::file::Accumulator;
use crate::geom::from_spherical;
use crate::optics::C64;
use crate::render::colour;
use glam::DVec3;
use rayon::prelude::*;

/// The simulated data a fit uses.
pub struct Data {
    pub theta_i_rad: Vec<f64>,
    pub phi_i_rad: f64,
    pub lambda_nm: Vec<f64>,
    /// `r[i][j]`: directional reflectance at incident angle i, wavelength j.
    pub r: Vec<Vec<f64>>,
    /// `lobe[i][b]`: wavelength-averaged power fraction in reflection bucket b.
    pub lobe: Vec<Vec<f64>>,
    pub buckets: crate::accumulate::Buckets,
    /// `t[i][j]`: directional transmittance (a conductor transmits nothing).
    pub t: Vec<Vec<f64>>,
    /// `mirror[i][j]`: the power in the bucket of the mirror direction beyond what the
    /// lobe around it puts there ([`mirror_excess`]): a smooth coat's or film's reflection.
    pub mirror: Vec<Vec<f64>>,
    /// The bucket of the mirror direction at each incident angle.
    pub mirror_bucket: Vec<usize>,
}

impl Data {
    pub fn from_accumulator(acc: &Accumulator) -> Data {
        let s = &acc.header.settings;
        let mode = s.coherence_mode();
        let buckets = s.buckets();
        let nl = s.wavelength_count();
        let (mut r, mut t, mut lobe, mut mirror, mut mirror_bucket) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for (i, th) in s.theta_i_deg.iter().enumerate() {
            let wi = from_spherical(th.to_radians(), s.phi_i_deg.to_radians());
            // `+ 0.0` makes a negative zero positive: at normal incidence the tracer's
            // reflection is (0, 0, 1), whose azimuth is 0, not -pi.
            let wm = DVec3::new(-wi.x + 0.0, -wi.y + 0.0, wi.z);
            let b = buckets.index(wm);
            let (mut row, mut trow, mut mrow) = (Vec::new(), Vec::new(), Vec::new());
            let mut l = vec![0.0; buckets.len()];
            for j in 0..nl {
                let c = acc.cell(i, j);
                let (rr, tt) = c.totals(mode, &buckets);
                row.push(rr);
                trow.push(tt);
                mrow.push(mirror_excess(c, mode, &buckets, b, wm));
                for (k, v) in l.iter_mut().enumerate() {
                    *v += c.fraction(2 * k, mode) / nl as f64;
                }
            }
            r.push(row);
            t.push(trow);
            mirror.push(mrow);
            mirror_bucket.push(b);
            lobe.push(l);
        }
        Data {
            theta_i_rad: s.theta_i_deg.iter().map(|t| t.to_radians()).collect(),
            phi_i_rad: s.phi_i_deg.to_radians(),
            lambda_nm: (0..nl).map(|j| s.wavelength(j)).collect(),
            r,
            lobe,
            buckets,
            t,
            mirror,
            mirror_bucket,
        }
    }
}

/// The base under the film.
#[derive(Clone, Debug, PartialEq)]
pub enum Base {
    /// A dielectric of real index `n`.
    Dielectric { n: f64 },
    /// A conductor with a complex index per wavelength of the data.
    Conductor { n: Vec<C64> },
}

/// A thin film on the base.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Film {
    pub thickness_nm: f64,
    pub n: f64,
    /// Weight of the filmed Fresnel term (glTF `iridescenceFactor`), 0..1.
    pub weight: f64,
}

/// A fitted material with its errors against the simulation.
#[derive(Clone, Debug)]
pub struct Fit {
    pub alpha: f64,
    pub base: Base,
    pub film: Option<Film>,
    /// A clear coat over base and film, where the simulation shows one.
    pub coat: Option<Coat>,
    /// RMS of `R_model - R_sim` over incident angles and wavelengths.
    pub rms_residual: f64,
    /// CIEDE2000 between the model's and the simulation's reflected colour under D65, per
    /// incident angle.
    pub delta_e2000: Vec<f64>,
    /// Plain words on where the model falls short, if it does.
    pub warnings: Vec<String>,
}

/// Smith's Lambda for GGX (Heitz 2014 eq. 86).
fn ggx_lambda(alpha: f64, cos: f64) -> f64 {
    let c2 = (cos * cos).min(1.0);
    let tan2 = (1.0 - c2) / c2.max(1e-300);
    0.5 * (-1.0 + (1.0 + alpha * alpha * tan2).sqrt())
}

/// Per reflection bucket: the model lobe without Fresnel, `integral over the bucket of D G2
/// / (4 cos_i cos_o) dw_o cos_o`, for incidence at `(theta_i, phi_i)`. Computed in
/// half-vector space, where it is `integral D(h) cos(theta_h) [G2 |wi . h| / (cos_i
/// cos(theta_h))] dw_h` (`dw_o = 4 |wi . h| dw_h`; Walter et al. 2007 eqs. 13-14): half
/// vectors on a stratified `K x K` grid of the GGX sampling map (eqs. 35-36), each
/// reflected into its bucket. Exact in the limit and accurate for lobes far narrower than a
/// bucket, where a quadrature over the buckets would miss the peak.
fn lobe_model(data: &Data, alpha: f64, theta_i: f64) -> Vec<f64> {
    const K: usize = 128;
    let wi = from_spherical(theta_i, data.phi_i_rad);
    let ci = wi.z;
    let mut out = vec![0.0; data.buckets.len()];
    for a in 0..K {
        let u1 = (a as f64 + 0.5) / K as f64;
        let tan2 = alpha * alpha * u1 / (1.0 - u1);
        let ch = 1.0 / (1.0 + tan2).sqrt();
        let sh = (1.0 - ch * ch).max(0.0).sqrt();
        for c in 0..K {
            let phi = std::f64::consts::TAU * (c as f64 + 0.5) / K as f64;
            let h = DVec3::new(sh * phi.cos(), sh * phi.sin(), ch);
            let ih = wi.dot(h);
            if ih <= 0.0 {
                continue;
            }
            let wo = h * (2.0 * ih) - wi;
            if wo.z <= 0.0 {
                continue;
            }
            let g2 = 1.0 / (1.0 + ggx_lambda(alpha, ci) + ggx_lambda(alpha, wo.z));
            out[data.buckets.index(wo)] += g2 * ih / (ci * ch) / (K * K) as f64;
        }
    }
    out
}

/// Stage 1: `alpha` from the lobe shape.
pub fn fit_alpha(data: &Data) -> f64 {
    let cost = |log_a: f64| {
        let alpha = log_a.exp();
        let mut e = 0.0;
        for (i, &th) in data.theta_i_rad.iter().enumerate() {
            let mut m = lobe_model(data, alpha, th);
            let obs = &data.lobe[i];
            // Buckets marked NaN (a coat's mirror, [`fit_coated`]) take no part.
            for (x, y) in m.iter_mut().zip(obs) {
                if y.is_nan() {
                    *x = 0.0;
                }
            }
            let obs: Vec<f64> = obs
                .iter()
                .map(|y| if y.is_nan() { 0.0 } else { *y })
                .collect();
            let obs = &obs;
            // Best scale per incident angle (linear least squares).
            let (mo, mm) = m
                .iter()
                .zip(obs)
                .fold((0.0, 0.0), |(a, b), (x, y)| (a + x * y, b + x * x));
            let s = if mm > 0.0 { mo / mm } else { 0.0 };
            let norm: f64 = obs.iter().map(|y| y * y).sum::<f64>().max(1e-300);
            e += m
                .iter()
                .zip(obs)
                .map(|(x, y)| (s * x - y).powi(2))
                .sum::<f64>()
                / norm;
        }
        e
    };
    golden(cost, (0.01f64).ln(), (1.0f64).ln(), 40).exp()
}

/// Golden-section minimisation of `f` on `[a, b]`.
fn golden(f: impl Fn(f64) -> f64, mut a: f64, mut b: f64, iters: usize) -> f64 {
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..iters {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - g * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + g * (b - a);
            fd = f(d);
        }
    }
    0.5 * (a + b)
}

/// Nelder-Mead minimisation from `x0` with initial steps `step` (Nelder & Mead, Computer
/// Journal 7 (1965) 308; standard coefficients 1, 2, 0.5, 0.5).
fn nelder_mead(f: &dyn Fn(&[f64]) -> f64, x0: &[f64], step: &[f64], iters: usize) -> Vec<f64> {
    let n = x0.len();
    let mut pts: Vec<Vec<f64>> = vec![x0.to_vec()];
    for k in 0..n {
        let mut p = x0.to_vec();
        p[k] += step[k];
        pts.push(p);
    }
    let mut vals: Vec<f64> = pts.iter().map(|p| f(p)).collect();
    for _ in 0..iters {
        let mut idx: Vec<usize> = (0..=n).collect();
        idx.sort_by(|&a, &b| vals[a].total_cmp(&vals[b]));
        pts = idx.iter().map(|&i| pts[i].clone()).collect();
        vals = idx.iter().map(|&i| vals[i]).collect();
        let centroid: Vec<f64> = (0..n)
            .map(|k| pts[..n].iter().map(|p| p[k]).sum::<f64>() / n as f64)
            .collect();
        let along = |t: f64| -> Vec<f64> {
            (0..n)
                .map(|k| centroid[k] + t * (pts[n][k] - centroid[k]))
                .collect()
        };
        let xr = along(-1.0);
        let fr = f(&xr);
        if fr < vals[0] {
            let xe = along(-2.0);
            let fe = f(&xe);
            if fe < fr {
                pts[n] = xe;
                vals[n] = fe;
            } else {
                pts[n] = xr;
                vals[n] = fr;
            }
        } else if fr < vals[n - 1] {
            pts[n] = xr;
            vals[n] = fr;
        } else {
            let xc = along(0.5);
            let fc = f(&xc);
            if fc < vals[n] {
                pts[n] = xc;
                vals[n] = fc;
            } else {
                let best = pts[0].clone();
                for i in 1..=n {
                    for (x, b) in pts[i].iter_mut().zip(&best) {
                        *x = b + 0.5 * (*x - b);
                    }
                    vals[i] = f(&pts[i]);
                }
            }
        }
    }
    let best = (0..=n)
        .min_by(|&a, &b| vals[a].total_cmp(&vals[b]))
        .unwrap_or(0);
    pts[best].clone()
}

/// Sum of squared reflectance errors plus the colour term (see the module docs).
fn cost(data: &Data, m: &[Vec<f64>], weights: &[[f64; 3]], white: [f64; 3]) -> f64 {
    let mut e = 0.0;
    for (mr, dr) in m.iter().zip(&data.r) {
        for (a, b) in mr.iter().zip(dr) {
            e += (a - b).powi(2);
        }
        let (la, lb) = (
            colour::lab(colour::xyz(mr, weights), white),
            colour::lab(colour::xyz(dr, weights), white),
        );
        let de2 = (0..3).map(|k| (la[k] - lb[k]).powi(2)).sum::<f64>();
        e += 1e-4 * de2;
    }
    e
}

/// Which bases and films to try.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BaseKind {
    Dielectric,
    Conductor,
    Auto,
}

/// Runs the three stages on the whole material, and again on the base under a clear coat
/// where the simulation shows a mirror lobe a coat could make ([`fit_coated`]). The coated
/// fit is kept where it is closer to the simulation (reflectance and colour, the stages'
/// own cost), where the user gave the coat's index, or where a coat's Fresnel reflection
/// explains the mirror lobe and the coated fit represents the material (RMS at most 0.02,
/// CIEDE2000 at most 2) or the coatless one does not either (the base is then beyond the
/// model, said so, and the coat is what is plainly there): a conductor without a coat, its n and k free per wavelength, can
/// match a coated gold more closely by bending them (to k at its bound of 20 in the red)
/// than the coat over a plain base does, and is no material.
///
/// A conductor transmits nothing: where the sample transmits (mean T above 0.05), only a
/// dielectric base is tried.
pub fn fit(data: &Data, base_kind: BaseKind, try_film: bool, coat: CoatChoice) -> Fit {
    let transmits = mean(&data.t) > 0.05;
    let kind = if transmits && base_kind == BaseKind::Auto {
        BaseKind::Dielectric
    } else {
        base_kind
    };
    let (mut best, mut cost) = fit_layer(data, kind, try_film);
    if coat == CoatChoice::None {
        return finish_notes(best, data, base_kind, transmits);
    }
    let coated = fit_coated(data, kind, try_film, coat);
    if let Some((mut coated, c, fresnel_like)) = coated {
        // A coat's Fresnel mirror at every angle is plainly there: it is kept where the
        // coated fit represents the material, and also where the coatless one does not
        // either, which then reaches its cost only by bending its base into no material
        // (issue 71: the car paint's coatless 'conductor' of n 7-8 and k 0 came 17-38 %
        // closer than its coat of 1.49-1.51 over a base; OpenPBR got a grey near-mirror).
        // A coatless fit that represents the material (a soap film) keeps its place.
        let evident = fresnel_like && (represents(&coated) || !represents(&best));
        if c < cost || matches!(coat, CoatChoice::Ior(_)) || evident {
            if c > cost && !matches!(coat, CoatChoice::Ior(_)) {
                coated.warnings.push(format!(
                    "a clear coat of index {:.3} explains the mirror reflection at every angle and is kept, though the model fits the whole material {:.0} % worse with it than without: the base under it is beyond the model",
                    coated.coat.map_or(f64::NAN, |k| k.ior),
                    100.0 * (c / cost - 1.0)
                ));
            }
            (best, cost) = (coated, c);
        }
    }
    let _ = cost;
    best.warnings.extend(bound_warnings(&best));
    finish_notes(best, data, base_kind, transmits)
}

/// Parameters the search left at its bounds, said (issue 71): such a value is where the
/// search stopped, not what the material is.
fn bound_warnings(f: &Fit) -> Vec<String> {
    let mut out = Vec::new();
    match &f.base {
        Base::Conductor { n } => {
            let at = n
                .iter()
                .filter(|c| c.re >= 9.99 || c.re <= 0.0101 || c.im >= 19.99 || c.im < 0.01 * c.re)
                .count();
            if at > 0 {
                out.push(format!(
                    "the conductor base's n + ik sits at the search's bounds (n 0.01-10, k 0-20) or has no extinction (k under n / 100) at {at} of {} wavelengths: no metal is so; the base is beyond the model (flakes, pigment, several layers)",
                    n.len()
                ));
            }
        }
        Base::Dielectric { n } => {
            if *n <= 1.001 || *n >= 2.999 {
                out.push(format!(
                    "the dielectric base's index {n:.3} sits at the search's bound (1-3): it is where the search stopped, not the material's"
                ));
            }
        }
    }
    if let Some(c) = f.coat
        && (c.ior <= 1.301 || c.ior >= 1.799)
    {
        out.push(format!(
            "the coat's index {:.3} sits at the search's bound (1.3-1.8): it is where the search stopped, not the coat's",
            c.ior
        ));
    }
    out
}

/// The notes on transmission of [`fit`].
fn finish_notes(mut best: Fit, data: &Data, base_kind: BaseKind, transmits: bool) -> Fit {
    if transmits && base_kind == BaseKind::Auto {
        best.warnings.push(format!(
            "the sample transmits (mean T {:.2}): only a dielectric base was tried, a conductor transmitting nothing",
            mean(&data.t)
        ));
    }
    if transmits && base_kind == BaseKind::Conductor {
        best.warnings.push(format!(
            "the sample transmits (mean T {:.2}), which a conductor cannot: a dielectric base represents it",
            mean(&data.t)
        ));
    }
    best
}

/// The mean of a table.
fn mean(v: &[Vec<f64>]) -> f64 {
    let n: usize = v.iter().map(|r| r.len()).sum();
    v.iter().flatten().sum::<f64>() / n.max(1) as f64
}

/// The model's reflectance table of a fitted (coatless) layer on `data`'s angles.
fn model_table(data: &Data, fit: &Fit) -> Vec<Vec<f64>> {
    let e = Albedo::new(data, fit.alpha);
    model_r(data, &e, &fit.base, fit.film)
}

/// RMS reflectance error and CIEDE2000 per incident angle of the model `m` against `data`.
fn errors(data: &Data, m: &[Vec<f64>]) -> (f64, Vec<f64>) {
    let weights = colour::bin_weights(&data.lambda_nm);
    let white = colour::xyz(&vec![1.0; data.lambda_nm.len()], &weights);
    let (mut s2, mut n) = (0.0, 0.0);
    for (mr, dr) in m.iter().zip(&data.r) {
        for (a, b) in mr.iter().zip(dr) {
            s2 += (a - b).powi(2);
            n += 1.0;
        }
    }
    let de = m
        .iter()
        .zip(&data.r)
        .map(|(mr, dr)| {
            colour::delta_e2000(
                colour::lab(colour::xyz(mr, &weights), white),
                colour::lab(colour::xyz(dr, &weights), white),
            )
        })
        .collect();
    ((s2 / n).sqrt(), de)
}

/// What the fit says of its own quality: a poor match, a lobe at the roughness bound, a
/// film at the bounds of its parameters.
fn quality_warnings(rms: f64, delta_e2000: &[f64], alpha: f64, film: &Option<Film>) -> Vec<String> {
    let mut warnings = Vec::new();
    let worst = delta_e2000.iter().copied().fold(0.0, f64::max);
    if worst > 2.0 || rms > 0.02 {
        warnings.push(format!(
            "the model cannot represent this material well (RMS reflectance error {rms:.3}, worst Delta E2000 {worst:.1}): multilayers, flakes, pigments or strong multiple scattering are beyond one GGX lobe with one film and a clear coat"
        ));
    }
    if alpha <= 0.0105 {
        warnings.push(
            "the lobe is narrower than the buckets resolve: alpha is at its lower bound 0.01 (a smooth or flat sample)".into(),
        );
    }
    let _ = film;
    warnings
}

/// Runs the three stages on `data` as one layer (no coat); returns the fit and its cost.
fn fit_layer(data: &Data, base_kind: BaseKind, try_film: bool) -> (Fit, f64) {
    let alpha = fit_alpha(data);
    let e = Albedo::new(data, alpha);
    let weights = colour::bin_weights(&data.lambda_nm);
    let white = colour::xyz(&vec![1.0; data.lambda_nm.len()], &weights);
    let total = |base: &Base, film: Option<Film>| {
        cost(data, &model_r(data, &e, base, film), &weights, white)
    };
    // Stage 2: bases.
    let mut candidates: Vec<Base> = Vec::new();
    if base_kind != BaseKind::Conductor {
        let n = golden(|n| total(&Base::Dielectric { n }, None), 1.0, 3.0, 50);
        candidates.push(Base::Dielectric { n });
    }
    if base_kind != BaseKind::Dielectric {
        // Per wavelength, (n, k) from the reflectance at every incident angle.
        // Each wavelength's fit is independent: in parallel, collected in order.
        let n: Vec<C64> = (0..data.lambda_nm.len())
            .into_par_iter()
            .map(|j| {
                let l = data.lambda_nm[j];
                // Bounded to metals' range (n 0.01-10, k 0-20): where single scattering cannot
                // reach the simulated R (multiple scattering at grazing angles), k would run off.
                let clampn =
                    |p: &[f64]| C64::new(p[0].abs().clamp(0.01, 10.0), p[1].abs().min(20.0));
                let f = |p: &[f64]| {
                    let nb = clampn(p);
                    let base = Base::Conductor { n: vec![nb; j + 1] };
                    let ms = multiple_scattering(&base, l, j, e.avg);
                    data.theta_i_rad
                        .iter()
                        .enumerate()
                        .map(|(i, &th)| {
                            let model =
                                e.at[i] * reflectance(&base, None, th, l, j) + (1.0 - e.at[i]) * ms;
                            (model - data.r[i][j]).powi(2)
                        })
                        .sum::<f64>()
                };
                let mut best = (f64::INFINITY, vec![1.0, 1.0]);
                for start in [[0.2, 3.0], [1.0, 2.0], [1.5, 7.0], [0.5, 0.5]] {
                    let p = nelder_mead(&f, &start, &[0.3, 0.5], 200);
                    let v = f(&p);
                    if v < best.0 {
                        best = (v, p);
                    }
                }
                clampn(&best.1)
            })
            .collect();
        candidates.push(Base::Conductor { n });
    }
    // Stage 3: on each base, a film started on a grid and refined by Nelder-Mead; the film
    // is kept only where it explains clearly more than the bare base (half the cost).
    let mut best: Option<(f64, Base, Option<Film>)> = None;
    let mut rejected: Option<String> = None;
    for cand in candidates {
        let bare = total(&cand, None);
        let mut choice = (bare, cand.clone(), None);
        if try_film {
            // A dielectric base's index is also started at 1 (a free-standing film).
            let mut starts = vec![cand.clone()];
            if let Base::Dielectric { n } = cand
                && n > 1.0 + 1e-6
            {
                starts.push(Base::Dielectric { n: 1.0 });
            }
            for st in &starts {
                let terms = BaseTerms::new(data, &e, st);
                let on_start = |film: Option<Film>| {
                    cost(data, &model_on(data, &e, st, &terms, film), &weights, white)
                };
                let (c, b, f) = fit_film(st, &total, &on_start);
                if c < 0.5 * bare && c < choice.0 {
                    // A film the fit would keep, but one no material is: refused, and said.
                    if let Some(why) = implausible_film(&b, &f, mean(&data.t)) {
                        rejected = Some(why);
                        continue;
                    }
                    choice = (c, b, Some(f));
                }
            }
        }
        if best.as_ref().is_none_or(|b| choice.0 < b.0) {
            best = Some(choice);
        }
    }
    let (c, base, film) = best.expect("at least one base kind");
    let m = model_r(data, &e, &base, film);
    let (rms, delta_e2000) = errors(data, &m);
    let mut warnings = quality_warnings(rms, &delta_e2000, alpha, &film);
    if film.is_none()
        && let Some(why) = rejected
    {
        warnings.push(format!(
            "no thin film explains this material's colour: the closest one is {why}, at the bounds of the model, which is what flakes, pigments or several layers look like to it; the fit is the base alone"
        ));
    }
    (
        Fit {
            alpha,
            base,
            film,
            coat: None,
            rms_residual: rms,
            delta_e2000,
            warnings,
        },
        c,
    )
}
