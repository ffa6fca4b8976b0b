//! RGL `.bsdf` export: a simulated BRDF in the adaptive parameterisation of Dupuy & Jakob,
//! "An Adaptive Parameterization for Efficient Material Acquisition and Rendering", ACM
//! TOG 37(6), 2018, as Mitsuba 3's `measured` plugin (`src/bsdfs/measured.cpp`) and
//! pbrt-v4's `measured` material read it.
//!
//! The reader evaluates, for incident `wi` and outgoing `wo` (both away from the surface)
//! with half vector `m`:
//!
//! ```text
//! u_m    = (sqrt(2 theta_m / pi), (phi_m [- phi_i if isotropic] + pi) / 2 pi)
//! s      = VNDF warp inverse(u_m; phi_i, theta_i)            (continuous Marginal2D)
//! eval   = spectra(s; phi_i, theta_i, lambda) * ndf(u_m) / (4 sigma(u_wi))   (jacobian = 1)
//! ```
//!
//! and `eval` is the BRDF times `cos(theta_o)` (Mitsuba's convention; pbrt-v4's
//! `MeasuredBxDF::f` (`src/pbrt/bxdfs.cpp`) divides the same product by `|cos theta|` of
//! the other direction and so reads the same stored quantity). So, at each node `s`
//! of the sample grid, this writer finds `u_m` by inverting the same warp, reflects `wi`
//! about `m`, and stores `spectra = f(wi, wo) cos(theta_o) 4 sigma(wi) / ndf(u_m)` with
//! `ndf` and `sigma` interpolated exactly as the reader interpolates them: at the nodes
//! the reader reproduces goniospec's BRDF, and between them it interpolates bilinearly in
//! the warped space.
//!
//! `ndf` is the sample's own microfacet distribution `D(m)`: an area-weighted histogram of
//! the facet normals that face the ambient medium, smoothed by a von Mises–Fisher kernel
//! (Fisher 1953) of 2 degrees, normalised so that `int D(m) cos(theta_m) dm = 1`, and mixed
//! with 10 % of the uniform distribution `1 / pi`, so that every half vector the simulated
//! BRDF reaches beyond the top surface's facets (a film's second surface, refraction,
//! multiple scattering, diffraction) has a positive density and enough nodes of the warped
//! grid (with 1 % the wavy film's .bsdf lost 8 % of its albedo at 60 degrees). `sigma(wi) =
//! int D(m) max(0, m . wi) dm` (the projected area, Heitz 2014 eq. 2) and the VNDF
//! `D(m) max(0, m . wi) / sigma(wi)` (Heitz & d'Eon 2014) follow from it; the VNDF is
//! tabulated per unit square of `u_m`, Jacobian `2 pi^2 u_theta sin(theta_m)`.

use super::ExportError;
use glam::DVec3;
use rayon::prelude::*;
use std::f64::consts::{FRAC_PI_2, PI, TAU};

use super::tensor::Field;
pub use super::warp::Warp;
use super::warp::bilinear;
use crate::brdf::Brdf;
use crate::sample::Sample;

/// `u = sqrt(2 theta / pi)` (measured.cpp `theta2u`).
pub fn theta2u(theta: f64) -> f64 {
    (theta * (2.0 / PI)).sqrt()
}
/// `theta = u^2 pi / 2` (`u2theta`).
pub fn u2theta(u: f64) -> f64 {
    u * u * FRAC_PI_2
}
/// `u = (phi + pi) / 2 pi` (`phi2u`).
pub fn phi2u(phi: f64) -> f64 {
    (phi + PI) / TAU
}
/// `phi = (2 u - 1) pi` (`u2phi`).
pub fn u2phi(u: f64) -> f64 {
    (2.0 * u - 1.0) * PI
}

/// A sample's microfacet distribution on the `ndf` grid of the `.bsdf` (`n` nodes in
/// `u_theta` by `n` in `u_phi`), in 1/sr.
#[derive(Clone, Debug)]
pub struct FacetDistribution {
    pub n: usize,
    /// `D(m)` at the nodes, row-major: `values[phi_node * n + theta_node]`.
    pub values: Vec<f64>,
    /// The fraction of the facets' projected area within 0.5 degrees of the normal
    /// ([`crate::sample::flat_fraction`]): near 1 for a flat (mirror) surface.
    pub flat_fraction: f64,
}

/// Smoothing of the facet-normal histogram, radians.
const KERNEL_RAD: f64 = 2.0 * PI / 180.0;
/// The uniform distribution's share in the exported `D`.
const UNIFORM_SHARE: f64 = 0.1;

impl FacetDistribution {
    /// The distribution of the facets that face the ambient medium (the medium above the
    /// sample), area-weighted; `isotropic` averages it over azimuth.
    pub fn from_sample(
        sample: &Sample,
        ambient: usize,
        n: usize,
        isotropic: bool,
    ) -> Result<FacetDistribution, ExportError> {
        check_resolution(n)?;
        // Facet normals binned on a fine grid of (u_theta, u_phi), with their mean normal.
        const G: usize = 256;
        let mut area = vec![0.0f64; G * G];
        let mut normal = vec![DVec3::ZERO; G * G];
        let mut projected = 0.0;
        for itf in &sample.interfaces {
            let sign = if itf.front == ambient {
                1.0
            } else if itf.back == ambient {
                -1.0
            } else {
                continue;
            };
            for k in 0..itf.mesh.triangles.len() {
                let a = itf.mesh.area_vector(k) * sign;
                let len = a.length();
                if len.is_nan() || len <= 0.0 {
                    continue;
                }
                let m = a / len;
                if m.z <= 0.0 {
                    continue;
                }
                let (theta, phi) = (m.z.clamp(-1.0, 1.0).acos(), m.y.atan2(m.x));
                let i = ((theta2u(theta) * G as f64) as usize).min(G - 1);
                let j = ((phi2u(phi) * G as f64) as usize).min(G - 1);
                area[j * G + i] += 0.5 * len;
                normal[j * G + i] += m * (0.5 * len);
                projected += 0.5 * len * m.z;
            }
        }
        if projected.is_nan() || projected <= 0.0 {
            return Err(ExportError::from(
                "the sample has no facet facing its ambient medium",
            ));
        }
        let cells: Vec<(f64, DVec3)> = area
            .iter()
            .zip(&normal)
            .filter(|(a, _)| **a > 0.0)
            .map(|(a, s)| (*a, s.normalize()))
            .collect();
        let kappa = 1.0 / (KERNEL_RAD * KERNEL_RAD);
        let norm = kappa / (TAU * (1.0 - (-2.0 * kappa).exp()));
        let node = |t: usize, p: usize| {
            let (theta, phi) = (
                u2theta(t as f64 / (n - 1) as f64),
                u2phi(p as f64 / (n - 1) as f64),
            );
            crate::geom::from_spherical(theta, phi)
        };
        let mut values: Vec<f64> = (0..n * n)
            .into_par_iter()
            .map(|k| {
                let m = node(k % n, k / n);
                let d: f64 = cells
                    .iter()
                    .map(|(a, c)| a * norm * (kappa * (m.dot(*c) - 1.0)).exp())
                    .sum();
                d / projected
            })
            .collect();
        if isotropic {
            for t in 0..n {
                let mean = (0..n).map(|p| values[p * n + t]).sum::<f64>() / n as f64;
                (0..n).for_each(|p| values[p * n + t] = mean);
            }
        }
        for v in &mut values {
            *v = (1.0 - UNIFORM_SHARE) * *v + UNIFORM_SHARE / PI;
        }
        Ok(FacetDistribution {
            n,
            values,
            flat_fraction: crate::sample::flat_fraction(sample, ambient),
        })
    }

    /// For a sample whose surface facing the light is flat (a clear coat over flakes or
    /// pigments), the facets say nothing of the lobe under it: half of the non-uniform
    /// share of `D` is taken instead from the BRDF's own lobe at normal incidence, the
    /// microfacet model read backwards, `D(m) ~ 4 cos(theta_i) cos(theta_o) f(z, wo) / (F
    /// G)` with `wo` the mirror of the normal about `m` (Walter et al. 2007, eq. 20; `F G`
    /// taken as constant), averaged over wavelength, clamped at 0 and normalised like the
    /// facets' (`int D cos(theta_m) dm = 1`). The warped grid then follows the flakes'
    /// lobe as well as the coat's mirror peak: with the facets alone, Mitsuba's render of
    /// the shipped car paint came out 20 % darker than goniospec's (the lobe fell where
    /// the grid had few nodes). `D` stays the reader's warp density only, so any positive
    /// choice leaves the tabulated BRDF exact at the nodes.
    pub fn add_brdf_lobe(&mut self, brdf: &(dyn Brdf + Sync), isotropic: bool) {
        let n = self.n;
        let nl = brdf.meta().lambda_nm.len();
        let grid = |k: usize| k as f64 / (n - 1) as f64;
        let lobe: Vec<f64> = (0..n * n)
            .into_par_iter()
            .map(|k| {
                let m = crate::geom::from_spherical(u2theta(grid(k % n)), u2phi(grid(k / n)));
                let wo = m * (2.0 * m.z) - DVec3::Z;
                if wo.z <= 0.0 {
                    return 0.0;
                }
                let (mut f, mut s) = (vec![0.0; nl], vec![0.0; nl]);
                symmetric_eval(brdf, DVec3::Z, wo, isotropic, &mut f, &mut s);
                let mean = f.iter().sum::<f64>() / nl.max(1) as f64;
                (4.0 * wo.z * mean).max(0.0)
            })
            .collect();
        // int D cos(theta_m) dm by the midpoint rule in u, on the bilinear interpolant.
        const Q: usize = 256;
        let mut integral = 0.0;
        for a in 0..Q {
            let ut = (a as f64 + 0.5) / Q as f64;
            let theta = u2theta(ut);
            for b in 0..Q {
                let up = (b as f64 + 0.5) / Q as f64;
                integral += bilinear(&lobe, n, n, [ut, up])
                    * theta.cos()
                    * 2.0
                    * PI
                    * PI
                    * ut
                    * theta.sin();
            }
        }
        integral /= (Q * Q) as f64;
        if !(integral > 0.0 && integral.is_finite()) {
            return;
        }
        for (v, l) in self.values.iter_mut().zip(&lobe) {
            let facets = (*v - UNIFORM_SHARE / PI) / (1.0 - UNIFORM_SHARE);
            let mixed = 0.5 * facets + 0.5 * l / integral;
            *v = (1.0 - UNIFORM_SHARE) * mixed + UNIFORM_SHARE / PI;
        }
    }

    /// A quarter of the non-uniform share of `D` taken from the sharp mirror's facet
    /// distribution `D_s` (normalised like the rest to `int D_s cos(theta_m) dm = 1 - 1 / kappa`, within
    /// 4e-5 of 1 at 65 nodes), so that the warped grid has nodes within the peak.
    pub fn add_peak(&mut self, m: &super::mirror::SharpMirror) {
        let n = self.n;
        for (k, v) in self.values.iter_mut().enumerate() {
            let theta = u2theta((k % n) as f64 / (n - 1) as f64);
            let rest = (*v - UNIFORM_SHARE / PI) / (1.0 - UNIFORM_SHARE);
            let mixed = 0.75 * rest + 0.25 * m.facet_density(theta);
            *v = (1.0 - UNIFORM_SHARE) * mixed + UNIFORM_SHARE / PI;
        }
    }

    /// `D` as the reader interpolates it at `u = (u_theta, u_phi)`.
    pub fn eval(&self, u: [f64; 2]) -> f64 {
        bilinear(&self.values, self.n, self.n, u)
    }

    /// `int D(m) max(0, m . wi) dm` by the midpoint rule in `u` (256 x 256 cells), with
    /// `phi_m` relative to `phi_i` when `relative`.
    pub fn sigma(&self, wi: DVec3, relative: bool) -> f64 {
        self.sigma_table().at(wi, relative)
    }

    /// The midpoint rule of [`FacetDistribution::sigma`] tabulated once, for the many
    /// incidences an export asks (4,225 at 65 nodes: evaluating each from scratch took
    /// 65,536 sines and cosines apiece, 80 % of the export).
    pub fn sigma_table(&self) -> SigmaTable {
        const Q: usize = 256;
        let mut points = Vec::with_capacity(Q * Q);
        for a in 0..Q {
            let ut = (a as f64 + 0.5) / Q as f64;
            let theta = u2theta(ut);
            for b in 0..Q {
                let up = (b as f64 + 0.5) / Q as f64;
                let m = crate::geom::from_spherical(theta, u2phi(up));
                let w = self.eval([ut, up]) * 2.0 * PI * PI * ut * theta.sin() / (Q * Q) as f64;
                points.push((m, w));
            }
        }
        SigmaTable { points }
    }
}

/// The facet normals and weights of [`FacetDistribution::sigma`]'s midpoint rule.
pub struct SigmaTable {
    points: Vec<(DVec3, f64)>,
}

impl SigmaTable {
    /// [`FacetDistribution::sigma`] at `wi`. Relative to `wi`'s azimuth, `m` at `phi +
    /// phi_i` against `wi` is `m` at `phi` against `wi` turned to azimuth 0.
    pub fn at(&self, wi: DVec3, relative: bool) -> f64 {
        let wi = if relative {
            DVec3::new(wi.x.hypot(wi.y), 0.0, wi.z)
        } else {
            wi
        };
        self.points
            .iter()
            .map(|(m, w)| w * m.dot(wi).max(0.0))
            .sum()
    }
}

/// The BRDF at `(wi, wo)`, for an isotropic sample averaged over the directions its
/// symmetry makes equivalent: `wo` mirrored in the plane of incidence (isotropy and
/// reciprocity make `f` even in `phi_o - phi_i`), and at normal incidence also turned by
/// pi about the normal. The simulated table holds Monte Carlo noise that breaks these
/// symmetries slightly, and the reader may assign an azimuth of 0 or pi to a normal `wi`
/// (the sign of a zero in its `atan2`), so the written file must not depend on them.
pub fn symmetric_eval(
    brdf: &(dyn Brdf + Sync),
    wi: DVec3,
    wo: DVec3,
    isotropic: bool,
    out: &mut [f64],
    scratch: &mut [f64],
) {
    if !isotropic {
        brdf.eval(wi, wo, out);
        return;
    }
    // The mirror of the plane through the normal and wi (the xz plane for wi at phi 0).
    let axis = if wi.x.abs() + wi.y.abs() > 0.0 {
        DVec3::new(-wi.y, wi.x, 0.0).normalize()
    } else {
        DVec3::Y
    };
    let mirror = |v: DVec3| v - axis * (2.0 * v.dot(axis));
    let turn = |v: DVec3| DVec3::new(-v.x, -v.y, v.z);
    let normal = wi.x == 0.0 && wi.y == 0.0;
    let variants: &[DVec3] = if normal {
        &[wo, mirror(wo), turn(wo), turn(mirror(wo))]
    } else {
        &[wo, mirror(wo)]
    };
    out.iter_mut().for_each(|v| *v = 0.0);
    for &w in variants {
        brdf.eval(wi, w, scratch);
        for (o, s) in out.iter_mut().zip(scratch.iter()) {
            *o += s / variants.len() as f64;
        }
    }
}

/// The outgoing bucket's size in `theta_o` and `phi_o`, degrees, from the BRDF's simulation
/// settings (the default 45 x 36 grid's where they are not known).
fn bucket_aperture_deg(brdf: &(dyn Brdf + Sync)) -> (f64, f64) {
    let settings: toml::Table = toml::from_str(&brdf.meta().simulation).unwrap_or_default();
    let bins = |k: &str, d: f64| {
        settings
            .get(k)
            .and_then(|v| v.as_integer())
            .map_or(d, |n| n.max(1) as f64)
    };
    (
        90.0 / bins("theta_o_bins", 45.0),
        360.0 / bins("phi_o_bins", 36.0),
    )
}

/// What the exporter reports besides the fields.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RglReport {
    /// Where the sample's surface facing the light is flat (above 99 % of it within 0.5
    /// degrees): its mirror lobe is written as simulated, at the bucket aperture `(theta_o,
    /// phi_o)` in degrees.
    pub mirror_aperture_deg: Option<(f64, f64)>,
    /// Where the mirror was written instead as a sharp lobe ([`super::mirror`]): its
    /// half-vector spread, degrees.
    pub sharp_mirror_deg: Option<f64>,
    /// The sharp mirror's power per simulated angle: `(theta_i degrees, mean over
    /// wavelength of the fraction of the incident power)`.
    pub mirror_power: Vec<(f64, f64)>,
    /// Where a flat surface's mirror stayed at the bucket aperture: why.
    pub no_sharp_mirror: Option<String>,
    /// Values of the BRDF that were negative (beamlet cross terms; kept in goniospec, but
    /// the format holds none), written as 0, and the most negative one (1/sr).
    pub negative: usize,
    pub most_negative: f64,
    pub values: usize,
}

/// Options of the RGL writer.
#[derive(Clone, Debug, PartialEq)]
pub struct RglOptions {
    /// Nodes per side of the warped grids (`ndf`, `sigma`, `vndf`, `luminance`, `spectra`),
    /// odd: at normal incidence the reader may look a half turn away (the azimuth of a
    /// normal `wi` is `atan2` of signed zeros), and an odd count puts that on the nodes.
    pub resolution: usize,
    /// Incident elevations of the tabulation, radians, ascending in [0, pi/2).
    pub theta_i: Vec<f64>,
    /// Free text stored as `description`.
    pub description: String,
    /// 1: each node stores the BRDF at its own direction, which the reader then
    /// reproduces exactly there. q > 1: the mean over a q x q grid filling the node's cell
    /// of the warped square, a one-cell box filter. A lobe made of glints finer than the
    /// grid (flakes under a flat coat or binder, one sample of a few tens of flakes) is
    /// sampled by the nodes at random: the shipped metallic paint's point-sampled `.bsdf`
    /// integrated to 10 % to 40 % off the simulated albedo at 20 to 80 degrees, and
    /// Mitsuba's render of it was 12 % darker than goniospec's (CIEDE2000 2.8); filtered,
    /// each node carries its cell's share of the lobe. `rgl_for` filters 7 x 7 where the
    /// sample's surface facing the light is flat: at 3 x 3 the car paint's slices between
    /// simulated angles (every 5 degrees) integrated to 0.51-1.23 where the simulated
    /// albedo runs 0.54-0.64, at 7 x 7 smoothly and within 1.3 % at the simulated angles
    /// (issue 71).
    pub prefilter: usize,
}

/// The largest grid side accepted (spectra hold `phi_i x theta_i x lambda x n x n` f32).
pub const MAX_RESOLUTION: usize = 255;

/// Refuses a grid resolution the writer cannot use: odd, 3..=[`MAX_RESOLUTION`] (odd:
/// half a turn about the normal then maps the azimuth grid onto itself, as the reader's
/// normal incidence needs).
pub fn check_resolution(n: usize) -> Result<(), ExportError> {
    if (3..=MAX_RESOLUTION).contains(&n) && n % 2 == 1 {
        Ok(())
    } else {
        Err(ExportError::from(format!(
            "the resolution must be odd, 3..={MAX_RESOLUTION}, got {n} (odd: half a turn about the normal then maps the azimuth grid onto itself, as the reader's normal incidence needs)"
        )))
    }
}

/// Builds the fields of a `.bsdf` for `brdf` with the microfacet distribution `d`.
pub fn rgl_fields(
    brdf: &(dyn Brdf + Sync),
    d: &FacetDistribution,
    opts: &RglOptions,
) -> Result<(Vec<Field>, RglReport), ExportError> {
    let n = opts.resolution;
    check_resolution(n)?;
    if d.n != n {
        return Err(ExportError::from(format!(
            "the facet distribution has {} nodes, the grid {n}",
            d.n
        )));
    }
    // A flat surface facing the light (a clear coat, a film) reflects a mirror (delta)
    // lobe; the simulation measured it spread over the outgoing bucket around the mirror
    // direction, as a goniospectrometer of that aperture does. `rgl_for` passes a table's
    // as a sharp lobe (`super::mirror`) and then clears this; otherwise it is written as
    // measured (`RglReport::mirror_aperture_deg`), the facets' 2-degree peak giving it nodes.
    let mirror_aperture_deg =
        (d.flat_fraction > crate::sample::FLAT_TOP_FRACTION).then(|| bucket_aperture_deg(brdf));
    let theta_i = &opts.theta_i;
    if theta_i.is_empty()
        || theta_i.windows(2).any(|w| w[1] <= w[0])
        || theta_i.iter().any(|t| !(*t >= 0.0 && *t < FRAC_PI_2))
    {
        return Err(ExportError::from(
            "incident angles must be ascending in [0, 90) degrees",
        ));
    }
    let meta = brdf.meta();
    let lambdas = &meta.lambda_nm;
    let nl = lambdas.len();
    let isotropic = meta.isotropic;
    let phi_i: Vec<f64> = if isotropic {
        vec![0.0]
    } else {
        (0..13).map(|k| -PI + TAU * k as f64 / 12.0).collect()
    };
    let ybar: Vec<f64> = crate::render::colour::bin_weights(lambdas)
        .iter()
        .map(|w| w[1])
        .collect();
    let grid = |k: usize| k as f64 / (n - 1) as f64;
    // sigma on its grid of u_wi, and at each tabulated incidence.
    let table = d.sigma_table();
    let sigma: Vec<f64> = (0..n * n)
        .into_par_iter()
        .map(|k| {
            let wi = crate::geom::from_spherical(u2theta(grid(k % n)), u2phi(grid(k / n)));
            table.at(wi, isotropic)
        })
        .collect();
    let slices: Vec<(f64, f64)> = phi_i
        .iter()
        .flat_map(|&p| theta_i.iter().map(move |&t| (p, t)))
        .collect();
    type Slice = (Vec<f64>, Vec<f64>, Vec<f64>, usize, f64);
    let per_slice: Vec<Slice> = slices
        .par_iter()
        .map(|&(p, t)| -> Result<Slice, String> {
            let wi = crate::geom::from_spherical(t, p);
            let s_wi = bilinear(&sigma, n, n, [theta2u(t), phi2u(p)]);
            let m_of = |u: [f64; 2]| {
                let phi = u2phi(u[1]) + if isotropic { p } else { 0.0 };
                crate::geom::from_spherical(u2theta(u[0]), phi)
            };
            // The VNDF per unit square of u_m (the reader normalises it).
            let vndf: Vec<f64> = (0..n * n)
                .map(|k| {
                    let u = [grid(k % n), grid(k / n)];
                    let m = m_of(u);
                    d.eval(u) * m.dot(wi).max(0.0) * 2.0 * PI * PI * u[0] * u2theta(u[0]).sin()
                })
                .collect();
            let warp = Warp::new(vndf.clone(), n, n).map_err(|e| e.to_string())?;
            let mut spectra = vec![0.0; nl * n * n];
            let mut lum = vec![0.0; n * n];
            let (negative, most_negative) = node_values(
                &Node {
                    brdf,
                    d,
                    warp: &warp,
                    m_of: &m_of,
                    wi,
                    s_wi,
                    isotropic,
                    q: opts.prefilter.max(1),
                    n,
                    ybar: &ybar,
                },
                &mut spectra,
                &mut lum,
            )
            .map_err(|what| format!("{what} at theta_i {:.1} deg", t.to_degrees()))?;
            Ok((vndf, spectra, lum, negative, most_negative))
        })
        .collect::<Result<_, _>>()?;
    let mut report = RglReport {
        values: slices.len() * n * n * nl,
        mirror_aperture_deg,
        ..Default::default()
    };
    let (mut vndf, mut spectra, mut lum) = (Vec::new(), Vec::new(), Vec::new());
    for (v, s, l, neg, most) in per_slice {
        vndf.extend(v.iter().map(|&x| x as f32));
        spectra.extend(s.iter().map(|&x| x as f32));
        // The luminance warp needs a positive total: a floor far below every lobe.
        let floor = 1e-6 * l.iter().cloned().fold(0.0, f64::max) + 1e-30;
        lum.extend(l.iter().map(|&x| (x + floor) as f32));
        report.negative += neg;
        report.most_negative = report.most_negative.min(most);
    }
    let f32s = |v: &[f64]| v.iter().map(|&x| x as f32).collect::<Vec<f32>>();
    let (np, nt) = (phi_i.len(), theta_i.len());
    let fields = vec![
        Field::u8("description", opts.description.as_bytes()),
        Field::f32("theta_i", &[nt], &f32s(theta_i)),
        Field::f32("phi_i", &[np], &f32s(&phi_i)),
        Field::f32("ndf", &[n, n], &f32s(&d.values)),
        Field::f32("sigma", &[n, n], &f32s(&sigma)),
        Field::f32("vndf", &[np, nt, n, n], &vndf),
        Field::f32("luminance", &[np, nt, n, n], &lum),
        Field::f32("spectra", &[np, nt, nl, n, n], &spectra),
        Field::f32("wavelengths", &[nl], &f32s(lambdas)),
        Field::u8("jacobian", &[1]),
    ];
    Ok((fields, report))
}

/// What [`node_values`] needs of one incidence: the BRDF and `D`, the incidence's warp and
/// its map from the unit square to half vectors, `wi` and `sigma(wi)`, and the filter.
struct Node<'a> {
    brdf: &'a (dyn Brdf + Sync),
    d: &'a FacetDistribution,
    warp: &'a Warp,
    m_of: &'a dyn Fn([f64; 2]) -> DVec3,
    wi: DVec3,
    s_wi: f64,
    isotropic: bool,
    /// The box filter's q x q positions per node (`RglOptions::prefilter`).
    q: usize,
    n: usize,
    ybar: &'a [f64],
}

/// The stored quantity `f(wi, wo) cos(theta_o) 4 sigma(wi) / D(u_m)` at every node of one
/// incidence's warped grid, into `spectra` (wavelength-major) and its luminance into `lum`:
/// the point value, or with `q > 1` the mean over a q x q grid of positions filling the
/// node's cell of the warped square (a box filter of one cell), so that lobes finer than
/// the grid keep their energy (`RglOptions::prefilter`). Returns the count of negative
/// BRDF values written as 0 and the most negative, or what was not finite.
fn node_values(
    c: &Node,
    spectra: &mut [f64],
    lum: &mut [f64],
) -> Result<(usize, f64), ExportError> {
    let (n, q) = (c.n, c.q);
    let nl = c.ybar.len();
    let grid = |k: usize| k as f64 / (n - 1) as f64;
    let h = 1.0 / (n - 1) as f64;
    let (mut negative, mut most_negative) = (0usize, 0.0f64);
    let (mut f, mut g) = (vec![0.0; nl], vec![0.0; nl]);
    for k in 0..n * n {
        let node = [grid(k % n), grid(k / n)];
        for a in 0..q * q {
            let off = |i: usize| {
                if q == 1 {
                    0.0
                } else {
                    ((i as f64 + 0.5) / q as f64 - 0.5) * h
                }
            };
            let s = [
                (node[0] + off(a % q)).clamp(0.0, 1.0),
                (node[1] + off(a / q)).clamp(0.0, 1.0),
            ];
            let u = c.warp.sample(s);
            let m = (c.m_of)(u);
            let cos = c.wi.dot(m);
            let wo = m * (2.0 * cos) - c.wi;
            if cos <= 0.0 || wo.z <= 0.0 {
                continue;
            }
            symmetric_eval(c.brdf, c.wi, wo, c.isotropic, &mut f, &mut g);
            let scale = wo.z * 4.0 * c.s_wi / c.d.eval(u) / (q * q) as f64;
            for (j, &v) in f.iter().enumerate() {
                if !v.is_finite() {
                    return Err(ExportError::from(format!(
                        "the BRDF is not finite at wo {wo:?}"
                    )));
                }
                if v < 0.0 {
                    negative += 1;
                    most_negative = most_negative.min(v);
                }
                let x = v.max(0.0) * scale;
                spectra[j * n * n + k] += x;
                lum[k] += x * c.ybar[j];
            }
        }
    }
    Ok((negative, most_negative))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parameter_maps_match_measured_cpp() {
        for t in [0.0, 0.3, 1.2, FRAC_PI_2] {
            assert!((u2theta(theta2u(t)) - t).abs() < 1e-15);
        }
        assert_eq!(phi2u(-PI), 0.0);
        assert_eq!(phi2u(0.0), 0.5);
        assert!((u2phi(phi2u(1.0)) - 1.0).abs() < 1e-15);
    }
}
