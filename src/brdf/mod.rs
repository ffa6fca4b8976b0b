//! BRDF representations built from accumulated buckets, all behind one query interface
//! (docs/design.md §5): the seed's 4-D spherical kd-tree, Gondek et al.'s adaptively subdivided
//! hemisphere, and a dense table; plus the `.gsb` file that stores any of them.
//!
//! `eval(wi, wo)` returns the BRDF (1/sr) in every wavelength bin. Directions point away
//! from the surface (z up); only the reflection hemisphere is represented.

pub mod file;
pub mod kdtree;
pub mod subdivided;
pub mod symmetry;
pub mod table;

use crate::accumulate::file::Accumulator;
use crate::accumulate::{Buckets, Coherence};
use glam::DVec3;

/// What a BRDF representation refuses: an unknown kind, data it cannot be built from, a file whose content makes no sense.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BrdfError {
    /// The message says what and where.
    #[error("{0}")]
    Invalid(String),
}

message_error!(BrdfError, BrdfError::Invalid);

/// The kind of a representation, serialised by name; an unknown name is refused.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum Kind {
    /// Scattered buckets blended by their k nearest neighbours ([`kdtree`]).
    Kdtree,
    /// An adaptively subdivided hemisphere ([`subdivided`]).
    Subdivided,
    /// The bucket grid as a table ([`table`]).
    Table,
    /// A closed-form model (tests, benchmarks); never stored in a `.gsb`.
    Analytic,
    /// A measured material read from an RGL `.bsdf` (`export::measured`); never stored in
    /// a `.gsb`.
    Measured,
}

impl Kind {
    /// The kinds `goniospec build` makes and `.gsb` files store.
    pub const STORED: [Kind; 3] = [Kind::Kdtree, Kind::Subdivided, Kind::Table];

    pub fn name(self) -> &'static str {
        match self {
            Kind::Kdtree => "kdtree",
            Kind::Subdivided => "subdivided",
            Kind::Table => "table",
            Kind::Analytic => "analytic",
            Kind::Measured => "measured",
        }
    }

    /// A stored kind by name, or an error listing them.
    pub fn parse(s: &str) -> Result<Kind, BrdfError> {
        Kind::STORED
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| {
                BrdfError::Invalid(format!(
                    "unknown representation '{s}' (kdtree, subdivided or table)"
                ))
            })
    }
}

impl std::fmt::Display for Kind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// How to build a representation from buckets ([`Representation::build`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BuildOptions {
    /// kd-tree: neighbours blended per query, 1..=[`kdtree::MAX_K`].
    pub k: usize,
    /// Subdivided: relative RMS deviation above which a cell splits (positive).
    pub tolerance: f64,
    /// kd-tree: reduce to `phi_o - phi_i` (isotropic samples).
    pub isotropic: bool,
    /// kd-tree: also enter each bucket as its reciprocal pair `(wo, wi)`.
    pub reciprocal: bool,
}

impl Default for BuildOptions {
    fn default() -> Self {
        BuildOptions {
            k: 4,
            tolerance: 0.05,
            isotropic: true,
            reciprocal: false,
        }
    }
}

/// What every representation knows about itself.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Meta {
    /// Which representation this is.
    pub repr: Kind,
    /// Representative wavelength of each bin (its centre, or the exact wavelength), nm: the
    /// `lambda_nm` of every CSV, NPZ and Python output. Written `wavelengths_nm` before
    /// issue 45, which is still read.
    #[serde(alias = "wavelengths_nm")]
    pub lambda_nm: Vec<f64>,
    /// The whole sampling these are the cells of (bin edges, or exact wavelengths);
    /// absent in files written before it was stored.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spectrum: Option<crate::spectrum::Wavelengths>,
    pub sample_name: String,
    pub sample_hash: String,
    /// The simulation's settings, as TOML (from the `.gsa` header).
    pub simulation: String,
    /// The BRDF was reduced to `phi_o - phi_i` (isotropic sample).
    pub isotropic: bool,
    /// Each bucket was also entered as its reciprocal pair `(wo, wi)`.
    pub reciprocal: bool,
    /// Typical relative standard error of the buckets that went in (median over
    /// populated buckets), where known.
    pub median_rel_stderr: Option<f64>,
    /// Trees traced per incident direction (the `.gsa`'s, summed over merged runs);
    /// absent in files written before it was stored.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub trees_per_direction: Option<Vec<u64>>,
    /// The incident polarisation the BRDF is of, as a Stokes vector `S0 = 1` in the
    /// incident direction's s/p frame (`build --incident`, from a `--mueller` run's
    /// matrices); absent for unpolarised light.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub incident_stokes: Option<[f64; 4]>,
    /// The channels are linear sRGB (red, green, blue: IEC 61966-2-1 primaries, D65
    /// white), not wavelength bins: a measured file in the RGL database's RGB form.
    /// `lambda_nm` then holds the primaries' dominant wavelengths, for labels and curve
    /// colours only; colour is computed with [`crate::render::colour::channel_weights`].
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub rgb: bool,
}

impl Meta {
    /// The sampling the cells come from: as stored, or, for files written before it was
    /// (centres only), bins whose edges lie halfway between centres, the outer bins as
    /// wide as their neighbours (10 nm for a single centre).
    pub fn sampling(&self) -> crate::spectrum::Wavelengths {
        if let Some(w) = &self.spectrum {
            return w.clone();
        }
        let c = &self.lambda_nm;
        let nl = c.len();
        if nl == 0 {
            return crate::spectrum::Wavelengths::Bins(Vec::new());
        }
        let first_width = if nl > 1 { c[1] - c[0] } else { 10.0 };
        let last_width = if nl > 1 { c[nl - 1] - c[nl - 2] } else { 10.0 };
        let edges = (0..=nl)
            .map(|i| match i {
                0 => c[0] - 0.5 * first_width,
                i if i == nl => c[nl - 1] + 0.5 * last_width,
                i => 0.5 * (c[i - 1] + c[i]),
            })
            .collect();
        crate::spectrum::Wavelengths::Bins(edges)
    }
}

/// The query interface every representation implements.
pub trait Brdf {
    /// BRDF (1/sr) of the pair `(wi, wo)` in every wavelength bin, into `out`
    /// (`out.len()` = number of bins).
    fn eval(&self, wi: DVec3, wo: DVec3, out: &mut [f64]);

    /// Many pairs at once: `out` holds `pairs.len() * bins` values, pair-major.
    fn eval_batch(&self, pairs: &[(DVec3, DVec3)], out: &mut [f64]) {
        let n = self.meta().lambda_nm.len();
        for (i, &(wi, wo)) in pairs.iter().enumerate() {
            self.eval(wi, wo, &mut out[i * n..(i + 1) * n]);
        }
    }

    fn meta(&self) -> &Meta;
}

/// One accumulated bucket: incident direction, outgoing bucket centre, its BRDF spectrum.
#[derive(Clone, Debug)]
pub struct BucketSample {
    /// Radians.
    pub theta_i_rad: f64,
    /// Radians.
    pub phi_i_rad: f64,
    /// Radians.
    pub theta_o_rad: f64,
    /// Radians.
    pub phi_o_rad: f64,
    /// BRDF per wavelength bin, 1/sr.
    pub f: Vec<f64>,
    /// Fraction of launched power per bin (for flux bookkeeping).
    pub flux: Vec<f64>,
    /// Projected solid angle of the bucket, sr.
    pub omega: f64,
    /// Relative standard error (mean over bins), when defined.
    pub rel_stderr: Option<f64>,
}

/// The reflection buckets of a `.gsa`, grouped by incident direction.
#[derive(Clone, Debug)]
pub struct BucketData {
    /// Simulated incident angles, radians.
    pub theta_i_rad: Vec<f64>,
    /// Incident azimuth, radians (the first direction's; each sample holds its own).
    pub phi_i_rad: f64,
    pub buckets: Buckets,
    pub lambda_nm: Vec<f64>,
    /// `samples[i]` holds every reflection bucket of incident direction `i`, bucket order.
    pub samples: Vec<Vec<BucketSample>>,
    pub meta: Meta,
}

impl BucketData {
    /// Extracts the reflection buckets (radians) of an accumulator.
    pub fn from_accumulator(acc: &Accumulator) -> BucketData {
        let s = &acc.header.settings;
        let b = s.buckets();
        let mode = s.coherence_mode();
        let nl = s.wavelength_count();
        let mut samples = Vec::new();
        let mut rel = Vec::new();
        for i in 0..s.theta_i_deg.len() {
            let mut v = Vec::with_capacity(b.len());
            for k in 0..b.len() {
                let (t, p) = b.centre(k);
                let omega = b.projected_solid_angle(k);
                let flux: Vec<f64> = (0..nl)
                    .map(|j| acc.cell(i, j).fraction(2 * k, mode))
                    .collect();
                let se: Option<f64> = if mode == Coherence::Global {
                    None
                } else {
                    let (mut num, mut den) = (0.0, 0.0);
                    for (j, f) in flux.iter().enumerate() {
                        if let Some(e) = acc.cell(i, j).fraction_stderr(2 * k, mode) {
                            num += e;
                            den += f.abs();
                        }
                    }
                    (den > 0.0).then(|| num / den)
                };
                if let Some(r) = se {
                    rel.push(r);
                }
                v.push(BucketSample {
                    theta_i_rad: s.theta_i_deg[i].to_radians(),
                    phi_i_rad: s.phi_of(i).to_radians(),
                    theta_o_rad: t,
                    phi_o_rad: p,
                    f: flux.iter().map(|x| x / omega).collect(),
                    flux,
                    omega,
                    rel_stderr: se,
                });
            }
            samples.push(v);
        }
        rel.sort_by(f64::total_cmp);
        BucketData {
            theta_i_rad: s.theta_i_deg.iter().map(|t| t.to_radians()).collect(),
            phi_i_rad: s.phi_i_deg.to_radians(),
            buckets: b,
            lambda_nm: (0..nl).map(|j| s.wavelength(j)).collect(),
            samples,
            meta: Meta {
                repr: Kind::Table,
                lambda_nm: (0..nl).map(|j| s.wavelength(j)).collect(),
                spectrum: Some(s.spectrum()),
                sample_name: s.sample_name.clone(),
                sample_hash: s.sample_hash.clone(),
                simulation: toml::to_string(s).unwrap_or_default(),
                isotropic: false,
                reciprocal: false,
                median_rel_stderr: rel.get(rel.len() / 2).copied(),
                trees_per_direction: Some(acc.header.rays_per_direction.clone()),
                incident_stokes: None,
                rgb: false,
            },
        }
    }

    /// The reflection buckets for polarised light in, the Stokes vector `stokes` (`S0 =
    /// 1`, the incident direction's s/p frame), from a `--mueller` run: each bucket's first
    /// row of its Mueller matrix applied to it. Each bucket's relative error is its
    /// elements' standard errors added in quadrature with the state's weights.
    pub fn from_accumulator_polarised(
        acc: &Accumulator,
        stokes: &[f64; 4],
    ) -> Result<BucketData, BrdfError> {
        if !acc.header.settings.mueller {
            return Err(BrdfError::Invalid(
                "the accumulator holds no Mueller matrices: simulate with --mueller to build the BRDF of polarised light".into(),
            ));
        }
        let mut data = BucketData::from_accumulator(acc);
        let nl = data.lambda_nm.len();
        let mut rel = Vec::new();
        for (i, samples) in data.samples.iter_mut().enumerate() {
            for (k, v) in samples.iter_mut().enumerate() {
                let (mut num, mut den) = (0.0, 0.0);
                for j in 0..nl {
                    let c = acc.cell(i, j);
                    let m = c.mueller(2 * k).unwrap_or([0.0; 16]);
                    let flux: f64 = (0..4).map(|b| m[b] * stokes[b]).sum();
                    v.flux[j] = flux;
                    v.f[j] = flux / v.omega;
                    if let Some(e) = c.mueller_stderr(2 * k) {
                        num += (0..4)
                            .map(|b| (e[b] * stokes[b]).powi(2))
                            .sum::<f64>()
                            .sqrt();
                        den += flux.abs();
                    }
                }
                v.rel_stderr = (den > 0.0).then(|| num / den);
                if let Some(r) = v.rel_stderr {
                    rel.push(r);
                }
            }
        }
        rel.sort_by(f64::total_cmp);
        data.meta.median_rel_stderr = rel.get(rel.len() / 2).copied();
        data.meta.incident_stokes = Some(*stokes);
        Ok(data)
    }
}

/// Directional-hemispherical reflectance `integral f(wi, wo) cos(theta_o) dwo` of `b` for
/// light arriving from `wi`, per wavelength bin: midpoint rule on an `nt x np` grid of
/// outgoing polar and azimuth angles.
pub fn hemispherical_reflectance(
    b: &(impl Brdf + ?Sized),
    wi: DVec3,
    nt: usize,
    np: usize,
) -> Vec<f64> {
    let nl = b.meta().lambda_nm.len();
    let mut acc = vec![0.0; nl];
    let mut v = vec![0.0; nl];
    let (dt, dp) = (
        std::f64::consts::FRAC_PI_2 / nt as f64,
        std::f64::consts::TAU / np as f64,
    );
    for t in 0..nt {
        let th = (t as f64 + 0.5) * dt;
        let w = th.cos() * th.sin() * dt * dp;
        for p in 0..np {
            b.eval(
                wi,
                crate::geom::from_spherical(th, (p as f64 + 0.5) * dp),
                &mut v,
            );
            for (a, x) in acc.iter_mut().zip(&v) {
                *a += w * x;
            }
        }
    }
    acc
}

/// Great-circle distance between unit vectors (radians), robust near 0 and pi.
#[inline]
pub fn arc(a: DVec3, b: DVec3) -> f64 {
    a.cross(b).length().atan2(a.dot(b))
}

/// Any representation, dispatched by `match`.
pub enum Representation {
    KdTree(kdtree::KdTreeBrdf),
    Subdivided(subdivided::SubdividedBrdf),
    Table(table::TableBrdf),
}

impl Brdf for Representation {
    fn eval(&self, wi: DVec3, wo: DVec3, out: &mut [f64]) {
        match self {
            Representation::KdTree(r) => r.eval(wi, wo, out),
            Representation::Subdivided(r) => r.eval(wi, wo, out),
            Representation::Table(r) => r.eval(wi, wo, out),
        }
    }
    fn meta(&self) -> &Meta {
        match self {
            Representation::KdTree(r) => r.meta(),
            Representation::Subdivided(r) => r.meta(),
            Representation::Table(r) => r.meta(),
        }
    }
}

impl Representation {
    /// Builds a representation of `kind` from buckets. Refuses options out of range and
    /// the analytic kind (it is not built from data).
    pub fn build(kind: Kind, data: &BucketData, o: &BuildOptions) -> Result<Self, BrdfError> {
        symmetry::check_azimuths(kind, data)?;
        Ok(match kind {
            Kind::Kdtree => {
                if !(1..=kdtree::MAX_K).contains(&o.k) {
                    return Err(BrdfError::from(format!(
                        "k = {} is outside 1..={}",
                        o.k,
                        kdtree::MAX_K
                    )));
                }
                Representation::KdTree(kdtree::KdTreeBrdf::build(
                    data,
                    o.k,
                    o.isotropic,
                    o.reciprocal,
                ))
            }
            Kind::Subdivided => {
                if !(o.tolerance > 0.0 && o.tolerance.is_finite()) {
                    return Err(BrdfError::from(format!(
                        "the subdivision tolerance must be positive, got {}",
                        o.tolerance
                    )));
                }
                Representation::Subdivided(subdivided::SubdividedBrdf::build(data, o.tolerance))
            }
            Kind::Table => Representation::Table(table::TableBrdf::build(data)),
            Kind::Analytic | Kind::Measured => {
                return Err(BrdfError::from(format!(
                    "a representation of kind {} is not built from buckets",
                    kind.name()
                )));
            }
        })
    }

    /// What `goniospec info` prints about a BRDF, one fact per line.
    pub fn describe(&self) -> String {
        let m = self.meta();
        let mut s = format!("sample: '{}' (hash {})\n", m.sample_name, m.sample_hash);
        s += &format!(
            "wavelengths: {} ({}..{} nm)\n",
            m.lambda_nm.len(),
            m.lambda_nm.first().unwrap_or(&0.0),
            m.lambda_nm.last().unwrap_or(&0.0)
        );
        if let Some(st) = m.incident_stokes {
            s += &format!(
                "incident light polarised: Stokes ({}, {}, {}, {}) in the s/p frame\n",
                st[0], st[1], st[2], st[3]
            );
        }
        s += &format!(
            "isotropic {}, reciprocal {}, median relative stderr of the buckets {}\n",
            m.isotropic,
            m.reciprocal,
            m.median_rel_stderr
                .map_or("unknown".to_string(), |v| format!("{v:.3}"))
        );
        s += &match self {
            Representation::KdTree(k) => {
                format!("kd-tree: {} points, k = {}\n", k.points.len(), k.k)
            }
            Representation::Table(t) => format!(
                "table: {} incident angles x {} x {}\n",
                t.theta_i_rad.len(),
                t.theta_bins,
                t.phi_bins
            ),
            Representation::Subdivided(d) => format!(
                "subdivided: {} incident angles, {} leaves, tolerance {}\n",
                d.theta_i_rad.len(),
                (0..d.theta_i_rad.len())
                    .map(|i| d.leaves(i).count())
                    .sum::<usize>(),
                d.tolerance
            ),
        };
        s
    }
}
