//! Measured BRDFs in the RGL material database's `.bsdf` form (Dupuy & Jakob, "An Adaptive
//! Parameterization for Efficient Material Acquisition and Rendering", ACM TOG 37(6),
//! 2018), read and evaluated as the database's own loader (`rgl-epfl/brdf-loader`,
//! `powitacq_rgb.inl`) and Mitsuba 3's `measured` plugin (`src/bsdfs/measured.cpp`)
//! evaluate them; also the spectral files goniospec's own `export` writes
//! ([`super::rgl`]). The equations, and what the files hold, are in docs/measured.md.
//!
//! For incident `wi` and outgoing `wo` (both above the surface), half vector `m`:
//!
//! ```text
//! u_m   = (sqrt(2 theta_m / pi), (phi_m [- phi_i if isotropic] + pi) / 2 pi  mod 1)
//! s     = vndf.invert(u_m; phi_i, theta_i)                 (continuous Marginal2D)
//! value = values(s; phi_i, theta_i, channel)               (bilinear, slices blended)
//! f cos(theta_o) = value [* ndf(u_m) / (4 sigma(u_wi))  where jacobian = 1]
//! ```
//!
//! with each angle taken from the direction as the reader takes it (`theta` by
//! `2 asin(|w - z| / 2)`, `phi` by `atan2(y, x)`). The files hold `f cos(theta_o)`, the
//! renderers' BSDF value; [`MeasuredBrdf`] implements [`Brdf`] as every representation
//! does, as the BRDF `f` in 1/sr.

use std::f64::consts::{PI, TAU};
use std::path::Path;

use glam::DVec3;
use rayon::prelude::*;

use super::ExportError;
use super::marginal::Marginal2D;
use super::rgl::{phi2u, theta2u, u2phi, u2theta};
use super::tensor::{Dtype, Field};
use crate::brdf::{Brdf, Kind, Meta};

/// The dominant wavelengths of the sRGB primaries against D65 (nm), the labels of an RGB
/// file's channels (`Meta::lambda_nm` where `Meta::rgb`): red 611.3, green 549.1, blue
/// 464.3, from the primaries' chromaticities (IEC 61966-2-1) on the CIE 1931 spectrum locus.
pub const RGB_LABEL_NM: [f64; 3] = [611.3, 549.1, 464.3];

/// The largest measured file read (bytes): the database's spectral files are about 40 MB.
pub const MAX_FILE_BYTES: u64 = 1 << 30;

/// What a measured file's channels are.
#[derive(Clone, Debug, PartialEq)]
pub enum Form {
    /// `rgb`: linear sRGB (the database's RGB files; docs/measured.md gives why).
    Rgb,
    /// `spectra` at these wavelengths, nm.
    Spectral(Vec<f64>),
}

/// A measured (or exported) material in the RGL `.bsdf` form.
#[derive(Clone, Debug)]
pub struct MeasuredBrdf {
    meta: Meta,
    /// The file's `description`.
    pub description: String,
    pub form: Form,
    /// Incident elevations of the measurement, radians, ascending.
    pub theta_i_rad: Vec<f64>,
    /// Incident azimuths, radians (one for an isotropic material).
    pub phi_i_rad: Vec<f64>,
    /// Fewer than three azimuths: the outgoing half vector is taken relative to `phi_i`.
    pub isotropic: bool,
    /// The azimuthal symmetry of an anisotropic file (`2 pi` over the span of its `phi_i`:
    /// 2 or 4 fold the incident direction into a half or a quadrant), as the reader takes it.
    pub reduction: i32,
    /// The stored values are divided by `ndf / (4 sigma)` (`jacobian = 1`).
    pub jacobian: bool,
    /// `valid`: one bit per incident angle and node of the value grid, packed first bit
    /// highest, `theta_i`-major (docs/measured.md; neither reader uses it); absent in
    /// exported files.
    pub valid: Option<Vec<u8>>,
    ndf: Marginal2D,
    sigma: Marginal2D,
    vndf: Marginal2D,
    values: Marginal2D,
    /// The value grid's nodes per side `(w, h)`.
    pub grid: (usize, usize),
    /// The VNDF grid's `(w, h)`.
    pub vndf_grid: (usize, usize),
    channels: usize,
}

/// `field` as f64, after checking it is numeric of `ndim` dimensions, finite where `finite`.
fn numbers(f: &Field, ndim: usize, finite: bool) -> Result<Vec<f64>, ExportError> {
    if f.shape.len() != ndim {
        return Err(ExportError::from(format!(
            "field '{}' has {} dimensions, the format gives it {ndim}",
            f.name,
            f.shape.len()
        )));
    }
    if !f.dtype.is_float() && f.dtype != Dtype::UInt8 {
        return Err(ExportError::from(format!(
            "field '{}' is {}, where the format stores floats",
            f.name,
            f.dtype.name()
        )));
    }
    let v = f.values_f64();
    if finite && let Some(k) = v.iter().position(|x| !x.is_finite()) {
        return Err(ExportError::from(format!(
            "field '{}' holds {} at index {k}",
            f.name, v[k]
        )));
    }
    Ok(v)
}

/// The fields a measured file is read from, by name, with the shape checks of the readers.
struct Fields<'a>(&'a [Field]);

impl<'a> Fields<'a> {
    fn get(&self, name: &str) -> Result<&'a Field, ExportError> {
        self.0.iter().find(|f| f.name == name).ok_or_else(|| {
            ExportError::from(format!(
                "no field '{name}': not a BRDF in the RGL database's format (fields: {})",
                self.0
                    .iter()
                    .map(|f| f.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            ))
        })
    }
    fn dims(&self, name: &str) -> Result<Vec<usize>, ExportError> {
        Ok(self.get(name)?.shape.iter().map(|&s| s as usize).collect())
    }

    /// The description, the incident angles (radians) and the form, checked.
    fn axes(&self) -> Result<(String, Vec<f64>, Vec<f64>, Form), ExportError> {
        let description = self.get("description")?;
        if description.dtype != Dtype::UInt8 || description.shape.len() != 1 {
            return Err(ExportError::from(
                "field 'description' must be a 1-D uint8 string",
            ));
        }
        let description = String::from_utf8_lossy(&description.data).into_owned();
        let theta_i = numbers(self.get("theta_i")?, 1, true)?;
        let phi_i = numbers(self.get("phi_i")?, 1, true)?;
        let ascending = |v: &[f64]| !v.is_empty() && v.windows(2).all(|w| w[1] > w[0]);
        if !ascending(&theta_i) || theta_i.iter().any(|t| !(0.0..=PI / 2.0 + 1e-6).contains(t)) {
            return Err(ExportError::from(
                "theta_i must be ascending in [0, pi/2] radians",
            ));
        }
        if !ascending(&phi_i) || phi_i.iter().any(|p| !(-PI - 1e-6..=TAU + 1e-6).contains(p)) {
            return Err(ExportError::from(
                "phi_i must be ascending within [-pi, 2 pi] radians",
            ));
        }
        let form = if self.0.iter().any(|x| x.name == "wavelengths") {
            let l = numbers(self.get("wavelengths")?, 1, true)?;
            if !ascending(&l) || l[0] <= 0.0 {
                return Err(ExportError::from(
                    "wavelengths must be positive and ascending (nm)",
                ));
            }
            Form::Spectral(l)
        } else {
            Form::Rgb
        };
        Ok((description, theta_i, phi_i, form))
    }
}

impl MeasuredBrdf {
    /// Reads a `.bsdf` file (at most [`MAX_FILE_BYTES`]).
    pub fn read(path: &Path) -> Result<MeasuredBrdf, ExportError> {
        let bytes = crate::io::read_input(path, MAX_FILE_BYTES)
            .map_err(|e| ExportError::from(format!("{}: {e}", path.display())))?;
        let fields = super::tensor::from_bytes(&bytes)
            .map_err(|e| ExportError::from(format!("{}: {e}", path.display())))?;
        MeasuredBrdf::from_fields(&fields)
            .map_err(|e| ExportError::from(format!("{}: {e}", path.display())))
    }

    /// Builds the reader's interpolants from a tensor file's fields, refusing what the
    /// readers refuse (a field missing, of the wrong type or shape, a value not finite, a
    /// warp density negative or zero) with the reason.
    pub fn from_fields(fields: &[Field]) -> Result<MeasuredBrdf, ExportError> {
        let f = Fields(fields);
        let (description, theta_i, phi_i, form) = f.axes()?;
        let (np, nt) = (phi_i.len(), theta_i.len());
        let key = match form {
            Form::Spectral(_) => "spectra",
            Form::Rgb => "rgb",
        };
        let channels = match &form {
            Form::Spectral(l) => l.len(),
            Form::Rgb => 3,
        };
        let vd = f.dims("vndf")?;
        let sd = f.dims(key)?;
        let nd = f.dims("ndf")?;
        let gd = f.dims("sigma")?;
        if vd.len() != 4 || vd[0] != np || vd[1] != nt {
            return Err(ExportError::from(format!(
                "field 'vndf' is {vd:?}; the format gives it [phi_i {np}, theta_i {nt}, h, w]"
            )));
        }
        if sd.len() != 5 || sd[0] != np || sd[1] != nt || sd[2] != channels {
            return Err(ExportError::from(format!(
                "field '{key}' is {sd:?}; the format gives it [phi_i {np}, theta_i {nt}, {channels}, h, w]"
            )));
        }
        if nd.len() != 2 || gd.len() != 2 {
            return Err(ExportError::from(
                "fields 'ndf' and 'sigma' must be 2-D tables",
            ));
        }
        let jac = f.get("jacobian")?;
        if jac.dtype != Dtype::UInt8 || jac.shape != [1] {
            return Err(ExportError::from("field 'jacobian' must be one uint8"));
        }
        let jacobian = jac.data[0] != 0;
        let grid = (sd[4], sd[3]);
        // One bit per incident angle and node (an overflowing count matches no field).
        let bits = nt
            .checked_mul(grid.0)
            .and_then(|v| v.checked_mul(grid.1))
            .map_or(u64::MAX, |b| b.div_ceil(8) as u64);
        let valid = match fields.iter().find(|x| x.name == "valid") {
            Some(v) if v.dtype == Dtype::UInt8 && v.shape == [bits] => Some(v.data.clone()),
            Some(v) => {
                return Err(ExportError::from(format!(
                    "field 'valid' is {} {:?}; the format packs one bit per incident angle and node, {bits} uint8 for {nt} x {} x {}",
                    v.dtype.name(),
                    v.shape,
                    grid.1,
                    grid.0
                )));
            }
            None => None,
        };
        if let Some(l) = fields.iter().find(|x| x.name == "luminance") {
            let ld: Vec<usize> = l.shape.iter().map(|&s| s as usize).collect();
            if ld != [np, nt, grid.1, grid.0] {
                return Err(ExportError::from(format!(
                    "field 'luminance' is {ld:?}, the value grid [{np}, {nt}, {}, {}]",
                    grid.1, grid.0
                )));
            }
        }
        let table = |name: &str, dims: &[usize], params: Vec<Vec<f64>>, warp: bool| {
            let (w, h) = (dims[dims.len() - 1], dims[dims.len() - 2]);
            let v = numbers(f.get(name)?, dims.len(), true)?;
            Marginal2D::new(&v, w, h, params, warp)
                .map_err(|e| ExportError::from(format!("field '{name}': {e}")))
        };
        let ndf = table("ndf", &nd, vec![], false)?;
        let sigma = table("sigma", &gd, vec![], false)?;
        let vndf = table("vndf", &vd, vec![phi_i.clone(), theta_i.clone()], true)?;
        let channel_axis: Vec<f64> = match &form {
            Form::Spectral(l) => l.clone(),
            Form::Rgb => vec![0.0, 1.0, 2.0],
        };
        let values = table(
            key,
            &sd,
            vec![phi_i.clone(), theta_i.clone(), channel_axis],
            false,
        )?;
        let isotropic = np <= 2;
        let reduction = if isotropic {
            1
        } else {
            (TAU / (phi_i[np - 1] - phi_i[0])).round() as i32
        };
        let meta = Meta {
            repr: Kind::Measured,
            lambda_nm: match &form {
                Form::Spectral(l) => l.clone(),
                Form::Rgb => RGB_LABEL_NM.to_vec(),
            },
            spectrum: None,
            sample_name: description.clone(),
            sample_hash: String::new(),
            simulation: String::new(),
            isotropic,
            reciprocal: false,
            median_rel_stderr: None,
            trees_per_direction: None,
            incident_stokes: None,
            rgb: form == Form::Rgb,
        };
        Ok(MeasuredBrdf {
            meta,
            description,
            form,
            theta_i_rad: theta_i,
            phi_i_rad: phi_i,
            isotropic,
            reduction,
            jacobian,
            valid,
            ndf,
            sigma,
            vndf: vndf.clone(),
            values,
            grid,
            vndf_grid: vndf.size(),
            channels,
        })
    }

    /// Whether the file is one goniospec exported (its description says so,
    /// [`super::rgl_for`]).
    pub fn is_goniospec_export(&self) -> bool {
        self.description.starts_with("goniospec ")
    }

    /// The number of channels (3 for RGB, else the wavelengths).
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// `wi` and `wo` folded as the reader folds them for a 2- or 4-fold symmetric file.
    fn fold(&self, mut wi: DVec3, mut wo: DVec3) -> (DVec3, DVec3) {
        if self.reduction >= 2 {
            // mulsign_neg(v, s): v with the sign flipped where s is positive.
            let neg = |v: f64, s: f64| if s.is_sign_negative() { v } else { -v };
            let sy = wi.y;
            let sx = if self.reduction == 4 { wi.x } else { sy };
            wi.x = neg(wi.x, sx);
            wi.y = neg(wi.y, sy);
            wo.x = neg(wo.x, sx);
            wo.y = neg(wo.y, sy);
        }
        (wi, wo)
    }

    /// The file's value `f cos(theta_o)` per channel at `(wi, wo)` into `out`, as the
    /// readers return it (0 where either direction is not above the surface).
    pub fn eval_cos(&self, wi: DVec3, wo: DVec3, out: &mut [f64]) {
        out.fill(0.0);
        if !(wi.z > 0.0 && wo.z > 0.0) {
            return;
        }
        let (wi, wo) = self.fold(wi, wo);
        let m = (wi + wo).normalize();
        let (theta_i, phi_i) = (elevation(wi), wi.y.atan2(wi.x));
        let (theta_m, phi_m) = (elevation(m), m.y.atan2(m.x));
        let u_wi = [theta2u(theta_i), phi2u(phi_i)];
        let mut u_m = [
            theta2u(theta_m),
            phi2u(if self.isotropic { phi_m - phi_i } else { phi_m }),
        ];
        u_m[1] -= u_m[1].floor();
        let (s, _) = self.vndf.invert(u_m, &[phi_i, theta_i]);
        let scale = if self.jacobian {
            self.ndf.eval(u_m, &[]) / (4.0 * self.sigma.eval(u_wi, &[]))
        } else {
            1.0
        };
        let channel = |c: usize| match &self.form {
            Form::Spectral(l) => l[c],
            Form::Rgb => c as f64,
        };
        for (c, o) in out.iter_mut().enumerate().take(self.channels) {
            *o = self.values.eval(s, &[phi_i, theta_i, channel(c)]) * scale;
        }
    }

    /// The outgoing direction of position `s` of the warped square at incidence
    /// `(theta_i, phi_i)` (radians), and the solid angle per unit area of the square there
    /// (sr): the VNDF warp's forward map of `s`, the half vector it gives, `wi` reflected
    /// about it; the solid angle is the inverse of the reader's own density of `wo` (the
    /// `pdf` of `measured.cpp`: the warp's density over `2 pi^2 u_theta sin(theta_m) 4
    /// (wi . m)`, the Jacobians of `u` to `m` and of `m` to `wo`, Walter et al. 2007 eq.
    /// 14). `None` where the direction is not above the surface.
    pub fn sample_direction(&self, theta_i: f64, phi_i: f64, s: [f64; 2]) -> Option<(DVec3, f64)> {
        let wi = crate::geom::from_spherical(theta_i, phi_i);
        let (u, pdf_u) = self.vndf.sample(s, &[phi_i, theta_i]);
        let phi_m = u2phi(u[1]) + if self.isotropic { phi_i } else { 0.0 };
        let theta_m = u2theta(u[0]);
        let m = crate::geom::from_spherical(theta_m, phi_m);
        let cos = wi.dot(m);
        let wo = m * (2.0 * cos) - wi;
        if !(wo.z > 0.0 && cos > 0.0 && pdf_u > 0.0) {
            return None;
        }
        let jacobian = 2.0 * PI * PI * u[0] * theta_m.sin() * 4.0 * cos;
        Some((wo, jacobian / pdf_u))
    }

    /// The outgoing direction of node `(x, y)` of the value grid at incidence `(theta_i,
    /// phi_i)` (radians) and its share of the projected solid angle (sr): the node stands
    /// for the cell of the square around it (halves and quarters on the edges and corners,
    /// a trapezoidal rule), its solid angle from [`Self::sample_direction`], times
    /// `cos(theta_o)`. `None` where the direction is not above the surface.
    pub fn node_direction(
        &self,
        theta_i: f64,
        phi_i: f64,
        x: usize,
        y: usize,
    ) -> Option<(DVec3, f64)> {
        let (w, h) = self.grid;
        let s = [x as f64 / (w - 1) as f64, y as f64 / (h - 1) as f64];
        let (wo, sr) = self.sample_direction(theta_i, phi_i, s)?;
        let edge = |k: usize, n: usize| if k == 0 || k == n - 1 { 0.5 } else { 1.0 };
        let area = edge(x, w) * edge(y, h) / ((w - 1) * (h - 1)) as f64;
        Some((wo, area * sr * wo.z))
    }

    /// The `valid` bit of node `(x, y)` at incidence index `t`, where the file has one.
    pub fn valid_bit(&self, t: usize, x: usize, y: usize) -> Option<bool> {
        let (w, h) = self.grid;
        let bit = (t * h + y) * w + x;
        let v = self.valid.as_ref()?;
        Some(v.get(bit / 8)? >> (7 - bit % 8) & 1 == 1)
    }

    /// Per incident angle below 90 degrees, how many nodes' `valid` bit says the same as
    /// the geometry (the node's direction above the surface, [`Self::node_direction`]):
    /// `(nodes, agreeing where the bit marks nodes above, agreeing where it marks nodes
    /// below)`. The shipped files' bits agree node for node with one reading or the other
    /// (docs/measured.md).
    pub fn valid_agreement(&self) -> Option<Vec<(usize, usize, usize)>> {
        self.valid.as_ref()?;
        let (w, h) = self.grid;
        Some(
            self.theta_i_rad
                .iter()
                .enumerate()
                .filter(|(_, t)| **t < PI / 2.0 - 1e-6)
                .map(|(t, &ti)| {
                    let (mut above, mut below) = (0, 0);
                    for y in 0..h {
                        for x in 0..w {
                            let lit = self.node_direction(ti, 0.0, x, y).is_some();
                            let bit = self.valid_bit(t, x, y).unwrap_or(false);
                            above += usize::from(bit == lit);
                            below += usize::from(bit != lit);
                        }
                    }
                    (w * h, above, below)
                })
                .collect(),
        )
    }

    /// What `goniospec info` says of the material.
    pub fn describe(&self) -> String {
        let deg = |v: &[f64]| {
            v.iter()
                .map(|t| format!("{:.2}", t.to_degrees()))
                .collect::<Vec<_>>()
                .join(", ")
        };
        let mut s = format!("material: {}\n", self.description);
        s += &match &self.form {
            Form::Rgb => "form: RGB (linear sRGB channels; rendered and compared in RGB)\n".into(),
            Form::Spectral(l) => format!(
                "form: spectral, {} wavelengths {:.1}..{:.1} nm\n",
                l.len(),
                l[0],
                l[l.len() - 1]
            ),
        };
        s += &format!(
            "incident angles: theta_i {} deg ({}); phi_i {} deg ({})\n",
            deg(&self.theta_i_rad),
            self.theta_i_rad.len(),
            deg(&self.phi_i_rad),
            if self.isotropic {
                "isotropic".to_string()
            } else {
                format!("anisotropic, {}-fold", self.reduction)
            }
        );
        s += &format!(
            "outgoing grid: {} x {} nodes warped by a {} x {} VNDF; stored values {} (jacobian = {})\n",
            self.grid.0,
            self.grid.1,
            self.vndf_grid.0,
            self.vndf_grid.1,
            if self.jacobian {
                "divided by ndf / (4 sigma)"
            } else {
                "as f cos(theta_o)"
            },
            u8::from(self.jacobian)
        );
        if let Some(a) = self.valid_agreement() {
            let (n, above, below) = a
                .iter()
                .fold((0, 0, 0), |s, v| (s.0 + v.0, s.1 + v.1, s.2 + v.2));
            s += &format!(
                "valid: a bit per incident angle and node; below 90 deg it marks the nodes {} the horizon in {} of {n} (by the VNDF warp's own directions)\n",
                if above >= below { "above" } else { "below" },
                above.max(below)
            );
        }
        s
    }
}

/// The polar angle of a unit vector as the readers compute it, `2 asin(|w - z| / 2)`
/// (accurate near the pole, where `acos(z)` is not).
fn elevation(d: DVec3) -> f64 {
    let dist = (d.x * d.x + d.y * d.y + (d.z - 1.0) * (d.z - 1.0)).sqrt();
    2.0 * (0.5 * dist).clamp(-1.0, 1.0).asin()
}

/// `cos(theta_o)` below which a direction counts as the horizon itself, where the file's
/// `f cos(theta_o)` holds no BRDF (floating point puts `cos(90 deg)` at 6e-17, and the
/// quotient there would be 1e13 times the value).
pub const HORIZON_COS: f64 = 1e-9;

impl Brdf for MeasuredBrdf {
    /// The BRDF (1/sr): the file's `f cos(theta_o)` over `cos(theta_o)`; 0 at and below
    /// the horizon ([`HORIZON_COS`]), as the readers give no light below it.
    fn eval(&self, wi: DVec3, wo: DVec3, out: &mut [f64]) {
        if wo.z < HORIZON_COS {
            out.fill(0.0);
            return;
        }
        self.eval_cos(wi, wo, out);
        out.iter_mut().for_each(|v| *v /= wo.z);
    }

    fn eval_batch(&self, pairs: &[(DVec3, DVec3)], out: &mut [f64]) {
        let n = self.channels;
        out.par_chunks_mut(n)
            .zip(pairs.par_iter())
            .with_min_len(1024)
            .for_each(|(o, &(wi, wo))| self.eval(wi, wo, o));
    }

    fn meta(&self) -> &Meta {
        &self.meta
    }
}
