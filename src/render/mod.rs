//! Renders objects made of a simulated material: a spectral renderer over any BRDF
//! representation, with a directional or point light and a constant or sky environment,
//! written as a linear-sRGB EXR and an sRGB PNG preview.
//!
//! Radiometry is in radiance factors relative to the illuminant (D65): a white Lambertian
//! surface facing a light of unit strength has radiance factor 1. Per wavelength bin the
//! pixel spectrum is `pi E f(wi, wo) cos(theta_i)` for the light, plus the environment:
//! for a constant environment `integral f(wi, wo) cos(theta_i) dwi`, precomputed per
//! outgoing angle (exact, no noise; isotropic BRDFs), for the sky a cosine-weighted Monte
//! Carlo estimate. Spectra become XYZ with the CIE 1931 2-degree observer, then linear sRGB.
//! Rows render in parallel; every pixel has its own random stream, so images do not depend
//! on the thread count.

pub mod analytic;
pub mod colour;
pub mod plan;

use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};

use rayon::prelude::*;

use crate::accel::{Accel, Backend, Intersector, Ray};
use crate::brdf::Brdf;
use crate::rng::Rng;
use crate::sample::Mesh;
use glam::DVec3;

/// What the renderer refuses: a light or environment it cannot parse, a scene it cannot draw.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RenderError {
    /// The message says what and where.
    #[error("{0}")]
    Invalid(String),
}

message_error!(RenderError, RenderError::Invalid);

/// The light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Light {
    None,
    /// Direction towards the light (unit), world frame.
    Directional(DVec3),
    /// Position; its strength is 1 at the distance of the origin.
    Point(DVec3),
}

impl Light {
    /// Parses `--light`: `dir:THETA,PHI` (degrees), `point:X,Y,Z` or `none`. The message
    /// names the flag.
    pub fn parse(s: &str) -> Result<Light, RenderError> {
        // `n` comma-separated finite numbers, or the usage message.
        let numbers = |v: &str, n: usize, usage: &str| -> Result<Vec<f64>, String> {
            let p: Vec<f64> = v
                .split(',')
                .map(|x| x.trim().parse::<f64>())
                .collect::<Result<_, _>>()
                .map_err(|_| usage.to_string())?;
            if p.len() != n || p.iter().any(|v| !v.is_finite()) {
                return Err(format!("{usage} (finite numbers)"));
            }
            Ok(p)
        };
        if s == "none" {
            Ok(Light::None)
        } else if let Some(v) = s.strip_prefix("dir:") {
            let p = numbers(v, 2, "--light dir:THETA,PHI needs two angles in degrees")?;
            Ok(Light::Directional(crate::geom::from_spherical(
                p[0].to_radians(),
                p[1].to_radians(),
            )))
        } else if let Some(v) = s.strip_prefix("point:") {
            let p = numbers(v, 3, "--light point:X,Y,Z needs three numbers")?;
            Ok(Light::Point(DVec3::new(p[0], p[1], p[2])))
        } else {
            Err(RenderError::from(format!(
                "--light must be dir:THETA,PHI, point:X,Y,Z or none (got '{s}')"
            )))
        }
    }
}

/// The environment.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Env {
    None,
    Constant,
    /// Brighter towards the zenith: `0.25 + 0.75 max(0, z)`.
    Sky,
}

impl Env {
    /// Parses `--env`: `constant`, `sky` or `none`.
    pub fn parse(s: &str) -> Result<Env, RenderError> {
        match s {
            "constant" => Ok(Env::Constant),
            "sky" => Ok(Env::Sky),
            "none" => Ok(Env::None),
            other => Err(RenderError::from(format!(
                "--env must be constant, sky or none (got '{other}')"
            ))),
        }
    }
}

/// What to render.
pub enum Shape {
    /// The unit sphere at the origin.
    Sphere,
    /// The square `[-1, 1]^2` in the plane z = 0, facing up: a flat panel, whose every
    /// pixel sees the light at the same incident angle.
    Plane,
    /// A triangle mesh with smooth vertex normals.
    Mesh {
        mesh: Mesh,
        normals: Vec<DVec3>,
        accel: Box<Accel>,
    },
}

impl Shape {
    /// A mesh shape with area-weighted vertex normals.
    pub fn mesh(mesh: Mesh, backend: Backend) -> Result<Shape, crate::accel::AccelError> {
        let mut normals = vec![DVec3::ZERO; mesh.positions_nm.len()];
        for (k, t) in mesh.triangles.iter().enumerate() {
            let a = mesh.area_vector(k);
            for &v in t {
                normals[v as usize] += a;
            }
        }
        for n in &mut normals {
            let l = (*n).length();
            if l > 0.0 {
                *n *= 1.0 / l;
            }
        }
        let accel = Box::new(Accel::build(backend, &mesh.to_soup())?);
        Ok(Shape::Mesh {
            mesh,
            normals,
            accel,
        })
    }

    /// Bounding sphere (centre, radius).
    pub fn bounds(&self) -> (DVec3, f64) {
        match self {
            Shape::Sphere => (DVec3::ZERO, 1.0),
            Shape::Plane => (DVec3::ZERO, std::f64::consts::SQRT_2),
            Shape::Mesh { mesh, .. } => {
                let (lo, hi) = mesh.bounds().unwrap_or((DVec3::ZERO, DVec3::ONE));
                let c = (lo + hi) * 0.5;
                (c, 0.5 * (hi - lo).length())
            }
        }
    }

    /// Closest hit: distance and shading normal.
    fn hit(&self, o: DVec3, d: DVec3) -> Option<(f64, DVec3)> {
        match self {
            Shape::Sphere => {
                let b = o.dot(d);
                let c = o.dot(o) - 1.0;
                let disc = b * b - c;
                if disc < 0.0 {
                    return None;
                }
                let t = -b - disc.sqrt();
                let t = if t > 1e-9 { t } else { -b + disc.sqrt() };
                (t > 1e-9).then(|| (t, (o + (d * t)).normalize()))
            }
            Shape::Plane => {
                if d[2] == 0.0 {
                    return None;
                }
                let t = -o[2] / d[2];
                let p = o + (d * t);
                // Seen from below, the visible side faces down.
                let n = if o.z >= 0.0 { DVec3::Z } else { DVec3::NEG_Z };
                (t > 1e-9 && p[0].abs() <= 1.0 && p[1].abs() <= 1.0).then_some((t, n))
            }
            Shape::Mesh {
                mesh,
                normals,
                accel,
            } => {
                let h = accel.closest_hit(&Ray {
                    origin: o.as_vec3().to_array(),
                    tmin: 1e-4,
                    dir: d.as_vec3().to_array(),
                    tmax: f32::INFINITY,
                });
                if !h.is_hit() {
                    return None;
                }
                let [a, b, c] = mesh.triangles[h.prim as usize];
                let (u, v) = (f64::from(h.u), f64::from(h.v));
                let n = ((normals[a as usize] * (1.0 - u - v)) + (normals[b as usize] * u))
                    + (normals[c as usize] * v);
                let mut n = n.normalize();
                if n.dot(d) > 0.0 {
                    n = -n; // seen from behind: shade the visible side
                }
                Some((f64::from(h.t), n))
            }
        }
    }

    fn occluded(&self, o: DVec3, d: DVec3) -> bool {
        match self {
            Shape::Sphere | Shape::Plane => false, // convex
            Shape::Mesh { .. } => self.hit(o, d).is_some(),
        }
    }
}

/// Render settings.
#[derive(Clone, Debug)]
pub struct RenderConfig {
    pub width: usize,
    pub height: usize,
    pub spp: usize,
    pub light: Light,
    pub light_strength: f64,
    pub env: Env,
    pub env_strength: f64,
    /// Camera position; it looks at the shape's centre.
    pub camera: DVec3,
    /// Vertical field of view, degrees.
    pub fov_deg: f64,
    pub seed: u64,
}

/// A linear-sRGB image, rows from the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: usize,
    pub height: usize,
    pub rgb: Vec<[f32; 3]>,
    /// The per-pixel spectra (radiance factors per wavelength bin), row-major.
    pub spectra: Vec<f32>,
    pub bins: usize,
}

/// The pinhole camera: it looks from `cfg.camera` at the shape's centre, z up.
pub(crate) struct CameraFrame {
    fwd: DVec3,
    right: DVec3,
    up: DVec3,
    /// `tan(fov / 2)`.
    half_h: f64,
    aspect: f64,
}

pub(crate) fn camera_frame(shape: &Shape, cfg: &RenderConfig) -> CameraFrame {
    let (centre, _) = shape.bounds();
    let fwd = (centre - cfg.camera).normalize();
    let up0 = if fwd.z.abs() > 0.99 {
        DVec3::Y
    } else {
        DVec3::Z
    };
    let right = fwd.cross(up0).normalize();
    CameraFrame {
        fwd,
        right,
        up: right.cross(fwd),
        half_h: (cfg.fov_deg.to_radians() / 2.0).tan(),
        aspect: cfg.width as f64 / cfg.height as f64,
    }
}

impl CameraFrame {
    /// Unit direction through the image point `(px, py)` in pixels from the top left.
    pub(crate) fn ray(&self, cfg: &RenderConfig, px: f64, py: f64) -> DVec3 {
        let sx = (2.0 * px / cfg.width as f64 - 1.0) * self.half_h * self.aspect;
        let sy = (1.0 - 2.0 * py / cfg.height as f64) * self.half_h;
        (self.fwd + ((self.right * sx) + (self.up * sy))).normalize()
    }
}

/// Hemispherical albedo `integral f(wi, wo) cos(theta_i) dwi` of an isotropic BRDF as a
/// function of the outgoing polar angle: `n` samples of theta_o over [0, 90) deg.
///
/// By reciprocity (`f(wi, wo) = f(wo, wi)`) this is the directional-hemispherical
/// reflectance for light arriving from `wo`, `integral f(wo, w) cos(theta) dw`, which is
/// how it is integrated: the simulated incident angles are where the data are resolved,
/// and that reflectance varies smoothly between them even for a specular film.
pub fn albedo_table(brdf: &(dyn Brdf + Sync), n: usize) -> Vec<Vec<f64>> {
    (0..n)
        .into_par_iter()
        .map(|k| {
            let to = (k as f64 + 0.5) / n as f64 * std::f64::consts::FRAC_PI_2;
            crate::brdf::hemispherical_reflectance(
                brdf,
                crate::geom::from_spherical(to, 0.0),
                48,
                96,
            )
        })
        .collect()
}

/// The shading tangent of a surface of normal `n` (unit) for an anisotropic BRDF: the
/// direction of increasing azimuth about the world's z axis, `z x n` normalised, which is
/// a sphere's `dp/du` in Mitsuba 3 and pbrt-v4 (both parametrise by the azimuth about z),
/// and x where `n` is along z (the plane, whose `dp/du` is x in both, and the poles).
pub fn shading_tangent(n: DVec3) -> DVec3 {
    let t = DVec3::new(-n.y, n.x, 0.0);
    if t.length_squared() > 1e-12 {
        t.normalize()
    } else {
        DVec3::X
    }
}

/// Renders `shape` made of `brdf`. `albedo` is [`albedo_table`] (needed for a constant
/// environment); `progress` receives finished rows.
pub fn render(
    brdf: &(dyn Brdf + Sync),
    shape: &Shape,
    cfg: &RenderConfig,
    albedo: Option<&[Vec<f64>]>,
    progress: &(dyn Fn(u64) + Sync),
) -> Image {
    let nl = brdf.meta().lambda_nm.len();
    let isotropic = brdf.meta().isotropic;
    let weights = colour::channel_weights(brdf.meta());
    let (_, radius) = shape.bounds();
    let cam = camera_frame(shape, cfg);
    let rows = AtomicU64::new(0);
    let pixels: Vec<(Vec<f32>, [f32; 3])> = (0..cfg.height)
        .into_par_iter()
        .flat_map_iter(|y| {
            let mut spec = vec![0.0; nl];
            let mut f = vec![0.0; nl];
            let row: Vec<(Vec<f32>, [f32; 3])> = (0..cfg.width)
                .map(|x| {
                    let mut rng = Rng::new(cfg.seed, (y * cfg.width + x) as u64);
                    spec.iter_mut().for_each(|s| *s = 0.0);
                    for _ in 0..cfg.spp {
                        let (jx, jy) = (rng.uniform(), rng.uniform());
                        let d = cam.ray(cfg, x as f64 + jx, y as f64 + jy);
                        let Some((t, n)) = shape.hit(cfg.camera, d) else {
                            continue;
                        };
                        let p = cfg.camera + (d * t);
                        // Local frame around the shading normal: any tangent for an
                        // isotropic BRDF; for an anisotropic one the sample's x axis (its
                        // phi = 0) along `shading_tangent`, as Mitsuba 3 and pbrt-v4 take it.
                        let tx = if isotropic {
                            let a = if n.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
                            a.cross(n).normalize()
                        } else {
                            shading_tangent(n)
                        };
                        let ty = n.cross(tx);
                        let local = |w: DVec3| DVec3::new(w.dot(tx), w.dot(ty), w.dot(n));
                        let wo = local(-d);
                        if wo[2] <= 0.0 {
                            continue;
                        }
                        let lit = |wi_world: DVec3,
                                   strength: f64,
                                   spec: &mut Vec<f64>,
                                   f: &mut Vec<f64>| {
                            let wi = local(wi_world);
                            if wi[2] <= 0.0
                                || shape.occluded(p + n * (1e-6 * radius.max(1.0)), wi_world)
                            {
                                return;
                            }
                            brdf.eval(wi, wo, f);
                            for (s, v) in spec.iter_mut().zip(f.iter()) {
                                *s += strength * std::f64::consts::PI * v * wi[2];
                            }
                        };
                        match cfg.light {
                            Light::None => {}
                            Light::Directional(l) => lit(l, cfg.light_strength, &mut spec, &mut f),
                            Light::Point(q) => {
                                let v = q - p;
                                let r2 = v.dot(v);
                                lit(
                                    v.normalize(),
                                    cfg.light_strength * q.dot(q) / r2,
                                    &mut spec,
                                    &mut f,
                                )
                            }
                        }
                        match cfg.env {
                            Env::None => {}
                            Env::Constant => {
                                let table =
                                    albedo.expect("a constant environment needs the albedo table");
                                let k = ((wo[2].clamp(0.0, 1.0).acos()
                                    / std::f64::consts::FRAC_PI_2)
                                    * table.len() as f64)
                                    as usize;
                                for (s, v) in spec.iter_mut().zip(&table[k.min(table.len() - 1)]) {
                                    *s += cfg.env_strength * v;
                                }
                            }
                            Env::Sky => {
                                // Cosine-weighted direction about n: pdf cos/pi, so the
                                // estimate is pi f L.
                                let (u1, u2) = (rng.uniform(), rng.uniform());
                                let r = u1.sqrt();
                                let phi = std::f64::consts::TAU * u2;
                                let wi = DVec3::new(
                                    r * phi.cos(),
                                    r * phi.sin(),
                                    (1.0 - u1).max(0.0).sqrt(),
                                );
                                let world = ((tx * wi[0]) + (ty * wi[1])) + (n * wi[2]);
                                if !shape.occluded(p + (n * (1e-6 * radius.max(1.0))), world) {
                                    let sky = 0.25 + 0.75 * world[2].max(0.0);
                                    brdf.eval(wi, wo, &mut f);
                                    for (s, v) in spec.iter_mut().zip(f.iter()) {
                                        *s += cfg.env_strength * std::f64::consts::PI * v * sky;
                                    }
                                }
                            }
                        }
                    }
                    let inv = 1.0 / cfg.spp as f64;
                    let s: Vec<f64> = spec.iter().map(|v| v * inv).collect();
                    let rgb = colour::xyz_to_linear_srgb(colour::xyz(&s, &weights));
                    (s.iter().map(|&v| v as f32).collect(), rgb.map(|c| c as f32))
                })
                .collect();
            progress(rows.fetch_add(1, Ordering::Relaxed) + 1);
            row.into_iter()
        })
        .collect();
    let mut img = Image {
        width: cfg.width,
        height: cfg.height,
        rgb: Vec::with_capacity(pixels.len()),
        spectra: Vec::with_capacity(pixels.len() * nl),
        bins: nl,
    };
    for (s, c) in pixels {
        img.spectra.extend(s);
        img.rgb.push(c);
    }
    img
}

/// Stages the image as a linear-sRGB EXR (written and flushed; [`crate::io::Staged::commit`]
/// puts it in place).
pub fn stage_exr(img: &Image, path: &Path) -> std::io::Result<crate::io::Staged> {
    crate::io::Staged::write_path(path, |tmp| {
        exr::prelude::write_rgb_file(tmp, img.width, img.height, |x, y| {
            let c = img.rgb[y * img.width + x];
            (c[0], c[1], c[2])
        })
        .map_err(|e| std::io::Error::other(e.to_string()))
    })
}

/// Stages an 8-bit sRGB-encoded PNG preview (values clamped to [0, 1]).
pub fn stage_png(img: &Image, path: &Path) -> std::io::Result<crate::io::Staged> {
    let data: Vec<u8> = img
        .rgb
        .iter()
        .flat_map(|c| c.map(|v| (colour::srgb_encode(f64::from(v)) * 255.0).round() as u8))
        .collect();
    crate::io::Staged::write(path, |w| {
        let mut enc = png::Encoder::new(w, img.width as u32, img.height as u32);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
        let mut wr = enc.write_header().map_err(std::io::Error::other)?;
        wr.write_image_data(&data).map_err(std::io::Error::other)?;
        wr.finish().map_err(std::io::Error::other)
    })
}

/// Writes the image as a linear-sRGB EXR, atomically.
pub fn write_exr(img: &Image, path: &Path) -> std::io::Result<()> {
    stage_exr(img, path)?.commit()
}

/// Writes an 8-bit sRGB-encoded PNG preview, atomically.
pub fn write_png(img: &Image, path: &Path) -> std::io::Result<()> {
    stage_png(img, path)?.commit()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The tangent is the unit sphere's `dp/du` for `p(u, v) = (sin v cos 2 pi u, sin v
    /// sin 2 pi u, cos v)`, Mitsuba 3's and pbrt-v4's parametrisation: `dp/du = 2 pi (-sin
    /// v sin 2 pi u, sin v cos 2 pi u, 0)`, normalised, written here from the derivative.
    #[test]
    fn the_tangent_is_the_spheres_dp_du_and_x_on_the_axis() {
        for (u, v) in [(0.1f64, 0.3f64), (0.37, 1.2), (0.8, 2.9), (0.55, 1.4)] {
            let phi = std::f64::consts::TAU * u;
            let n = DVec3::new(v.sin() * phi.cos(), v.sin() * phi.sin(), v.cos());
            let dpdu = DVec3::new(-v.sin() * phi.sin(), v.sin() * phi.cos(), 0.0).normalize();
            let t = shading_tangent(n);
            assert!((t - dpdu).length() < 1e-12, "{t} against {dpdu}");
            assert!(t.dot(n).abs() < 1e-12);
        }
        assert_eq!(shading_tangent(DVec3::Z), DVec3::X);
        assert_eq!(shading_tangent(DVec3::NEG_Z), DVec3::X);
    }
}
