//! Where each method holds: the sample's feature scales against the wavelengths asked for
//! (docs/validity.md). Cheap (no tracing), so `check` and `simulate` both run it.
//!
//! Per sheet interface, from its triangles (area-weighted over the tile):
//! - RMS height `sigma` (about the mean) and RMS slope `s` (`|grad h|`, from each facet's
//!   normal), and the period-equivalent lateral scale `Lambda = 2 pi sigma / s` (the period
//!   of a sinusoid; 0.91 of a triangle wave's; 4.4 correlation lengths of a Gaussian
//!   surface);
//! - its strongest axis-aligned Fourier mode of the height: a surface whose one mode holds
//!   half the height variance or more is a grating of that period;
//! - RMS principal curvature from the turn of the normal between neighbouring facets,
//!   and its radius `r_c = 1 / kappa_rms`.
//!
//! The measured limits (tests/diffraction.rs, docs/validity.md):
//! - Rays miss what only interference makes: the coherent specular order of a smooth
//!   surface, `exp(-g)` of the power with Rayleigh's `g = (4 pi sigma cos theta /
//!   lambda)^2` (Beckmann & Spizzichino 1963, ch. 5), and the orders of a grating whose
//!   period is coherent across (`Lambda < 4 rho`) and resolved by the buckets.
//! - Physical optics (the diffraction method, and the tangent-plane model it reproduces)
//!   needs curvature radii and periods of a few wavelengths: `k r_c cos^3 theta >> 1`
//!   (Ogilvy, Theory of Wave Scattering from Random Rough Surfaces, 1991, §4.2).
//!   Below a period of 3 wavelengths, or a curvature radius of half a wavelength, nothing
//!   here holds and the rigorous solver (`--coherence rigorous`) is the tool.
//! - The total R, which both methods take from the rays, is off where a metal grating's
//!   order meets a surface plasmon (TM absorption) and where structure is smooth against
//!   the wavelength at grazing light (the wave sees the mean plane): measured on gold
//!   gratings against the Rayleigh-Fourier method, `tests/interop/grating_rayleigh.py`.
//! - Bodies: below a size parameter of 10, ray optics does not describe a particle
//!   (van de Hulst 1957, §§ 10-12); a particle medium (Mie) does.

mod coatings;
pub use coatings::{WEIGHT_LOSS_SAID, coatings_ignore_radius, partial_wave_offset_nm};
mod measure;

use super::Sample;

/// Which method the warnings are for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Rays with the beamlet, bucket or global estimator.
    Rays,
    /// `--coherence diffraction`.
    Diffraction,
    /// `--coherence auto`: the run takes each cell's method itself (`simulate::auto`),
    /// and says where it could not, so the advice to switch methods is not given here.
    Auto,
    /// `--coherence rigorous`: Maxwell's equations on the tile; no scale limits it (its
    /// convergence is checked per cell instead), so nothing here applies.
    Rigorous,
}

/// What the run asks of the sample.
#[derive(Clone, Debug)]
pub struct Context {
    /// Shortest and longest vacuum wavelength of the run, nm.
    pub lambda_min_nm: f64,
    pub lambda_max_nm: f64,
    /// The incidence polar angles, degrees (`[0]` when unknown).
    pub theta_i_deg: Vec<f64>,
    /// Transverse coherence radius, nm (`inf`: plane wave).
    pub rho_nm: f64,
    /// Polar width of one outgoing bucket, radians.
    pub bucket_rad: f64,
    pub method: Method,
}

impl Context {
    /// The most oblique incidence, degrees.
    pub fn theta_max_deg(&self) -> f64 {
        self.theta_i_deg.iter().copied().fold(0.0, f64::max)
    }
}

/// The illumination's transverse coherence radius a run assumes unless told (the beamlet
/// radius of `simulate --coherence-radius-nm` and `check`'s), nm.
pub const DEFAULT_COHERENCE_RADIUS_NM: f64 = 5000.0;

/// Below this Rayleigh parameter `g` the coherent specular order (`exp(-g)` of the power,
/// 1.8 % here) is one the ray method does not produce.
pub const RAYLEIGH_MIN_FOR_RAYS: f64 = 4.0;
/// Below this many wavelengths of period (or period-equivalent scale) neither rays nor
/// physical optics hold (against RCWA, docs/validity.md: 14 % R error at 1.8 wavelengths).
pub const MIN_PERIOD_WAVELENGTHS: f64 = 3.0;
/// Below this curvature radius, in wavelengths, the tangent plane fails (`k r_c = pi`).
pub const MIN_CURVATURE_WAVELENGTHS: f64 = 0.5;
/// Above this RMS height over curvature radius, the diffraction method's exit plane is far
/// from the surface against the scale over which its tubes bend (sinusoids of slope 17 deg
/// at 9 wavelengths: 0.05, power kept 0.97-0.99; the shipped rough gold: 0.34, kept 0.9-1.8).
pub const MAX_DEPTH_OVER_CURVATURE: f64 = 0.1;
/// `--coherence auto` takes the diffraction method only where the tangent plane it rests on
/// holds: Ogilvy's `k r_c cos^3 theta >> 1` (Theory of Wave Scattering from Random Rough
/// Surfaces, 1991, §4.2), with the margin measured on the seed's film (curvature radius
/// 12 um), where the transform's power against the rays' at 16,384 trees is 1.010 at 45 deg
/// (this figure 48 at the worst bin), 1.064 at 50 deg and 615 nm (32.8), 1.237 at 55 deg and
/// 625 nm (22.9) and 1.448 at 60 deg and 605 nm (15.7). It grows with the ray count there
/// (60 deg: within 1.25 at 4,096 trees), so it is the method, not the sampling, that fails:
/// 35 keeps the ratio within [0.95, 1.053], where no warning is given.
pub const PHYSICAL_OPTICS_MIN: f64 = 35.0;
/// The same margin for a grating's orders: the sinusoidal glass gratings of the measured
/// map (docs/validity.md, A / period 0.05, 1.8 to 36 wavelengths at 0 and 30 deg) keep their
/// orders within L1 0.08 of the Kirchhoff orders, and of RCWA, at every margin measured, the
/// smallest 5.5 (1.8 wavelengths at 30 deg, the mesh's RMS curvature), where rays are 1.7
/// off. The film's calibration above concerns a random surface at grazing light; a grating
/// below this margin takes rays, and one deep against its curvature
/// ([`MAX_DEPTH_OVER_CURVATURE`]) too.
pub const PHYSICAL_OPTICS_MIN_GRATING: f64 = 5.0;
/// A grating's orders are distinct in the result when fewer than this many fall into one
/// bucket.
pub const ORDERS_PER_BUCKET: f64 = 4.0;
/// A grating's facets interfere when the period is under this many coherence radii (the
/// mutual coherence at half a period is above `exp(-2)`).
pub const COHERENT_PERIODS: f64 = 4.0;

/// The feature scales of one sheet interface, nm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scales {
    pub rms_height_nm: f64,
    pub rms_slope: f64,
    /// `2 pi sigma / s` (infinite for a flat sheet).
    pub lateral_nm: f64,
    /// The strongest axis-aligned mode: its period, nm, and its share of the variance.
    pub period_nm: f64,
    pub period_share: f64,
    /// `1 / kappa_rms` (infinite for a flat or faceted-plane sheet).
    pub curvature_radius_nm: f64,
}

impl Scales {
    /// Whether the sheet has relief at all. A relief of horizontal faces and vertical
    /// walls (lamellae, pillars) has no finite slope, so an infinite lateral scale, but a
    /// period: it is structured (issue 70: such sheets were passed over as flat, and a
    /// binary grating at 400 nm took rays under auto).
    pub fn structured(&self) -> bool {
        self.rms_height_nm > 0.0
    }
}

/// Measures one sheet's scales over `tile_nm`.
pub fn scales(mesh: &crate::sample::Mesh, tile_nm: [f64; 2]) -> Scales {
    let p = &mesh.positions_nm;
    let (mut area, mut zsum) = (0.0, 0.0);
    let mut cents = Vec::with_capacity(mesh.triangles.len());
    for (k, t) in mesh.triangles.iter().enumerate() {
        let a = mesh.area_vector(k).z.abs();
        let c = (p[t[0] as usize] + p[t[1] as usize] + p[t[2] as usize]) / 3.0;
        area += a;
        zsum += a * c.z;
        cents.push((a, c));
    }
    let flat = Scales {
        rms_height_nm: 0.0,
        rms_slope: 0.0,
        lateral_nm: f64::INFINITY,
        period_nm: f64::INFINITY,
        period_share: 0.0,
        curvature_radius_nm: f64::INFINITY,
    };
    if area <= 0.0 {
        return flat;
    }
    let mean = zsum / area;
    // Exact mean of (z - mean)^2 over each triangle (a linear function: the average of
    // its corners' squares and pairwise products, over 6).
    let (mut var, mut slope2) = (0.0, 0.0);
    for (k, t) in mesh.triangles.iter().enumerate() {
        let a = mesh.area_vector(k);
        let w = a.z.abs();
        let z = t.map(|i| p[i as usize].z - mean);
        var += w
            * (z[0] * z[0] + z[1] * z[1] + z[2] * z[2] + z[0] * z[1] + z[1] * z[2] + z[2] * z[0])
            / 6.0;
        if a.z.abs() > 0.0 {
            slope2 += w * (a.x * a.x + a.y * a.y) / (a.z * a.z);
        }
    }
    let sigma = (var / area).max(0.0).sqrt();
    let s = (slope2 / area).sqrt();
    if sigma < 1e-9 * tile_nm[0].max(tile_nm[1]) {
        return flat;
    }
    let best = measure::strongest_axis_mode(mesh, tile_nm, mean, sigma);
    let kmax = measure::max_edge_curvature(mesh);
    let kappa = (cents
        .iter()
        .zip(&kmax)
        .map(|((a, _), k2)| a * k2)
        .sum::<f64>()
        / area)
        .sqrt();
    Scales {
        rms_height_nm: sigma,
        rms_slope: s,
        lateral_nm: if s > 0.0 {
            2.0 * std::f64::consts::PI * sigma / s
        } else {
            f64::INFINITY
        },
        period_nm: best.0,
        period_share: best.1,
        curvature_radius_nm: if kappa > 0.0 {
            1.0 / kappa
        } else {
            f64::INFINITY
        },
    }
}

/// Ogilvy's tangent-plane margin `k r_c cos^3 theta` of one sheet (Theory of Wave Scattering
/// from Random Rough Surfaces, 1991, §4.2) at incidence `theta_deg` and vacuum wavelength
/// `lambda_nm`, `k` in the sheet's front medium; infinite where the sheet is not curved.
pub fn tangent_plane_margin(
    sample: &Sample,
    itf: &super::Interface,
    sc: &Scales,
    theta_deg: f64,
    lambda_nm: f64,
) -> f64 {
    if !sc.curvature_radius_nm.is_finite() {
        return f64::INFINITY;
    }
    let n = sample.media[itf.front]
        .model
        .eval(lambda_nm)
        .map_or(1.0, |(n, _)| n);
    2.0 * std::f64::consts::PI * n / lambda_nm
        * sc.curvature_radius_nm
        * theta_deg.to_radians().cos().powi(3)
}

/// Under an explicit `--coherence diffraction`, the run's angles where the tangent plane the
/// method rests on fails at the longest wavelength (`k r_c cos^3 theta` below
/// [`PHYSICAL_OPTICS_MIN`], or [`PHYSICAL_OPTICS_MIN_GRATING`] for a grating; `k` in the
/// front medium), said before the run: there `--coherence auto` takes rays, and the
/// transform may leave the rays' power by more than the run accepts (the seed's film at 75
/// deg: 1.28 after 30 s of tracing, refused).
fn tangent_plane_fails(
    sample: &Sample,
    sheet: &Sheet,
    ctx: &Context,
    grating: bool,
) -> Option<Finding> {
    let lambda = ctx.lambda_max_nm;
    let min = if grating {
        PHYSICAL_OPTICS_MIN_GRATING
    } else {
        PHYSICAL_OPTICS_MIN
    };
    let margin = |theta: f64| tangent_plane_margin(sample, sheet.itf, sheet.sc, theta, lambda);
    let failing: Vec<f64> = ctx
        .theta_i_deg
        .iter()
        .copied()
        .filter(|&t| margin(t) < min)
        .collect();
    let first = failing.iter().copied().fold(f64::INFINITY, f64::min);
    (!failing.is_empty()).then(|| Finding {
        message: format!(
            "{} has {} and curvature radius {:.0} nm: at {} deg the tangent plane the diffraction method rests on fails at {lambda:.0} nm (k r_c cos^3 theta = {:.1} at {first} deg, below {min}; Ogilvy 1991, §4.2), so its angular distribution is uncertain there, and where its transform holds the rays' power outside [0.8, 1.25] the run raises its trees within --max-rays while that helps, then stops (it traces the most oblique direction first). --coherence auto takes rays in those cells (docs/validity.md)",
            sheet.name,
            sheet.what,
            sheet.sc.curvature_radius_nm,
            failing
                .iter()
                .map(|t| format!("{t}"))
                .collect::<Vec<_>>()
                .join(", "),
            margin(first)
        ),
    })
}

/// One finding: the feature, its scale, and what to use instead.
#[derive(Clone, Debug, PartialEq)]
pub struct Finding {
    pub message: String,
}

/// The sample's findings for a run (each at most once).
pub fn assess(sample: &Sample, ctx: &Context) -> Vec<Finding> {
    assess_scales(sample, &sheet_scales(sample), ctx)
}

/// [`scales`] of every interface of `sample` (`None` for closed bodies).
pub fn sheet_scales(sample: &Sample) -> Vec<Option<Scales>> {
    sample
        .interfaces
        .iter()
        .map(|itf| (!itf.closed).then(|| scales(&itf.mesh, sample.tile_nm)))
        .collect()
}

/// The wavelength (nm) in the denser of the two media an interface separates, for light of
/// vacuum wavelength `lambda_nm`.
fn denser_wavelength(sample: &Sample, itf: &crate::sample::Interface, lambda_nm: f64) -> f64 {
    let n = [itf.front, itf.back]
        .iter()
        .map(|&m| {
            sample.media[m]
                .model
                .eval(lambda_nm)
                .map_or(1.0, |(n, _)| n)
        })
        .fold(1.0, f64::max);
    lambda_nm / n
}

/// Whether a sheet's structure is near or below the wavelength `lam` (nm, in the denser
/// medium), where neither rays nor the diffraction method hold: a period (or lateral
/// scale) below `MIN_PERIOD_WAVELENGTHS` wavelengths or a curvature radius below
/// `MIN_CURVATURE_WAVELENGTHS`.
fn finer_than(sc: &Scales, lam: f64) -> bool {
    let scale = if sc.period_share >= 0.5 {
        sc.period_nm
    } else {
        sc.lateral_nm
    };
    scale < MIN_PERIOD_WAVELENGTHS * lam || sc.curvature_radius_nm < MIN_CURVATURE_WAVELENGTHS * lam
}

/// The first sheet of `sample` whose structure is near or below the wavelength at
/// `lambda_nm` ([`finer_than`]): its index and the wavelength in its denser medium, nm.
pub fn finer_than_wavelength(
    sample: &Sample,
    sheets: &[Option<Scales>],
    lambda_nm: f64,
) -> Option<(usize, f64)> {
    sample
        .interfaces
        .iter()
        .zip(sheets)
        .enumerate()
        .find_map(|(i, (itf, sc))| {
            let sc = sc.filter(Scales::structured)?;
            let lam = denser_wavelength(sample, itf, lambda_nm);
            finer_than(&sc, lam).then_some((i, lam))
        })
}

/// [`assess`] with the interfaces' scales already measured ([`sheet_scales`]).
pub fn assess_scales(sample: &Sample, sheets: &[Option<Scales>], ctx: &Context) -> Vec<Finding> {
    let mut out = Vec::new();
    if ctx.method == Method::Rigorous {
        return out;
    }
    let lambda = ctx.lambda_min_nm;
    let cos = ctx.theta_max_deg().to_radians().cos().max(0.05);
    for (i, (itf, sc)) in sample.interfaces.iter().zip(sheets).enumerate() {
        let Some(sc) = *sc else {
            continue;
        };
        if !sc.structured() {
            continue;
        }
        let lam = denser_wavelength(sample, itf, lambda);
        let name = format!("interface {i} ({})", itf.mesh_path.display());
        let grating = sc.period_share >= 0.5;
        let what = if grating {
            format!("a grating of period {:.0} nm", sc.period_nm)
        } else {
            format!(
                "roughness of lateral scale {:.0} nm (RMS height {:.1} nm, RMS slope {:.2})",
                sc.lateral_nm, sc.rms_height_nm, sc.rms_slope
            )
        };
        if finer_than(&sc, lam) {
            // An auto run gives these cells the rigorous solver, and says where it could
            // not (`simulate::auto`).
            if ctx.method == Method::Auto {
                continue;
            }
            out.push(Finding {
                message: format!(
                    "{name} has {what} and curvature radius {:.0} nm, near or below the wavelength ({lambda:.0} nm, {lam:.0} nm in the denser medium): neither rays nor physical optics (--coherence diffraction) hold below {MIN_PERIOD_WAVELENGTHS} wavelengths of period or {MIN_CURVATURE_WAVELENGTHS} of curvature radius; use --coherence rigorous (the Fourier modal method) or --coherence auto, which takes it (docs/validity.md)",
                    sc.curvature_radius_nm
                ),
            });
            continue;
        }
        // The total R, which both methods take from the rays.
        let sheet = Sheet {
            itf,
            sc: &sc,
            name: &name,
            what: &what,
        };
        out.extend(plasmon_coupling(sample, &sheet, ctx));
        out.extend(smooth_at_grazing(sample, &sheet, ctx));
        if ctx.method == Method::Auto {
            continue;
        }
        if ctx.method == Method::Diffraction {
            let depth = sc.rms_height_nm / sc.curvature_radius_nm;
            if depth > MAX_DEPTH_OVER_CURVATURE {
                out.push(Finding {
                    message: format!(
                        "{name} has {what} and curvature radius {:.0} nm: deep against its curvature (RMS height / curvature radius {depth:.2}, above {MAX_DEPTH_OVER_CURVATURE}). The diffraction method adds the ray tubes on the exit plane above the sample, where tubes from neighbouring facets of such a surface overlap or part as they do not at the surface; its angular distribution is uncertain (the run reports how much power the transform kept). Use rays (--coherence beamlet), which hold for such rough surfaces when the Rayleigh g is large (docs/validity.md)",
                        sc.curvature_radius_nm
                    ),
                });
            }
            out.extend(tangent_plane_fails(sample, &sheet, ctx, grating));
            continue;
        }
        let g = (4.0 * std::f64::consts::PI * sc.rms_height_nm * cos / ctx.lambda_max_nm).powi(2);
        if grating {
            let coherent = sc.period_nm < COHERENT_PERIODS * ctx.rho_nm;
            let resolved = ctx.lambda_max_nm / sc.period_nm > ctx.bucket_rad / ORDERS_PER_BUCKET;
            if coherent && resolved {
                out.push(Finding {
                    message: format!(
                        "{name} is {what}: its diffraction orders are {:.3} apart in sin(theta) at {:.0} nm, which the buckets resolve and the coherence radius ({}) spans, but rays give only their envelope (against a rigorous RCWA solver their angular distributions are nearly disjoint up to a period of ~18 wavelengths); use --coherence diffraction (docs/validity.md)",
                        ctx.lambda_max_nm / sc.period_nm,
                        ctx.lambda_max_nm,
                        if ctx.rho_nm.is_finite() {
                            format!("{:.0} nm", ctx.rho_nm)
                        } else {
                            "plane wave".into()
                        }
                    ),
                });
                continue;
            }
        }
        if g < RAYLEIGH_MIN_FOR_RAYS {
            out.push(Finding {
                message: format!(
                    "{name} has {what}: smooth against the wavelength (Rayleigh g = {g:.2} at {:.0} nm and {:.0} deg), so a coherent specular order holds about exp(-g) = {:.2} of the reflected power, which rays spread over the slope lobe instead; use --coherence diffraction (docs/validity.md)",
                    ctx.lambda_max_nm,
                    ctx.theta_max_deg(),
                    (-g).exp()
                ),
            });
        }
    }
    out
}

/// Within this many resonance half-widths (`Im k_sp`) of a surface plasmon's wavenumber, a
/// grating order couples to it. Gold gratings at 550 nm against the Rayleigh-Fourier method
/// (docs/validity.md): with 3, every case of the 144-case calibration set whose R the rays
/// miss by more than [`R_TOLERANCE`] is warned; the 2 um gratings at 45 deg, off by 4e-3 and
/// 9e-3, have their order 1 at 2.9 half-widths.
pub const PLASMON_HALF_WIDTHS: f64 = 3.0;
/// The total R the warnings on R guard, as an absolute difference from a rigorous solver.
pub const R_TOLERANCE: f64 = 2e-3;
/// Below this Rayleigh `g`, on a surface with `k sigma` below [`SMOOTH_K_SIGMA`], the wave
/// sees the mean plane (the total R the flat interface's to `O(g)`), where rays average the
/// Fresnel reflectance over the facets' tilts. Gold gratings against the Rayleigh-Fourier
/// method: the rays' R misses by 4e-3 to 0.1 at `g` of 0.002-0.18 (docs/validity.md).
pub const RAYLEIGH_SMOOTH: f64 = 0.25;
/// The small-height regime of Rice's perturbation theory, `k sigma < 1` (Rice 1951; Thorsos
/// & Jackson, JASA 86 (1989) 261, find it accurate well below 1); rougher surfaces are
/// not smooth at any angle in that sense, however small `g` becomes at grazing light.
pub const SMOOTH_K_SIGMA: f64 = 1.0;

/// The unpolarised Fresnel reflectance from lossless `n1` onto `n2` at `theta` (radians).
fn fresnel_r(n1: f64, n2: num_complex::Complex64, theta: f64) -> f64 {
    let c = crate::optics::fresnel::coefficients(
        num_complex::Complex64::new(n1, 0.0),
        n2,
        theta.cos().max(1e-9),
    );
    0.5 * (c.r_s.norm_sqr() + c.r_p.norm_sqr())
}

/// The vacuum wavelengths a check judges over the run's range: every nanometre (at most
/// 2,001 of them).
fn wavelengths(ctx: &Context) -> impl Iterator<Item = f64> + '_ {
    let span = ctx.lambda_max_nm - ctx.lambda_min_nm;
    let n = (span.ceil() as usize).clamp(0, 2000);
    (0..=n).map(move |i| {
        if n == 0 {
            ctx.lambda_min_nm
        } else {
            ctx.lambda_min_nm + span * i as f64 / n as f64
        }
    })
}

/// One sheet interface as the warnings on R see it: the interface, its scales, and how the
/// messages name it and its structure.
struct Sheet<'a> {
    itf: &'a super::Interface,
    sc: &'a Scales,
    name: &'a str,
    what: &'a str,
}

impl Sheet<'_> {
    /// `(n, k)` of the media in front of and behind the sheet at `lambda_nm` (vacuum), or
    /// `None` outside a medium's table.
    fn indices(&self, sample: &Sample, lambda_nm: f64) -> Option<[(f64, f64); 2]> {
        let idx = |m: usize| sample.media[m].model.eval(lambda_nm).ok();
        Some([idx(self.itf.front)?, idx(self.itf.back)?])
    }
}

/// A metal grating whose orders reach a surface plasmon. On a conductor with `Re eps_m <
/// -eps_d` a bound surface wave runs along the interface with `k_sp = k0 sqrt(eps_m eps_d /
/// (eps_m + eps_d))` (Raether, Surface Plasmons on Smooth and Rough Surfaces and on
/// Gratings, Springer 1988, ch. 2); a grating of period `Lambda` lifts the incident
/// tangential wavenumber `n_d k0 sin(theta)` by `m K`, and where an order lands within the
/// resonance (`|k_t + m K| ~ Re k_sp`, in the plane across the grooves or conically along
/// them) TM light is absorbed into the plasmon (Raether ch. 6; the deep dips of Hutley &
/// Maystre, Opt. Commun. 19 (1976) 431). Neither rays nor physical optics have it. A
/// sinusoid of amplitude `A` reaches orders up to about `k A (1 + cos theta)` (its
/// Bessel spectrum, `J_m(k A (cos theta + cos theta_m))`), so higher orders are not
/// counted. Measured on gold gratings against the Rayleigh-Fourier method: R too high by up
/// to 0.16 (docs/validity.md).
fn plasmon_coupling(sample: &Sample, sheet: &Sheet, ctx: &Context) -> Option<Finding> {
    use num_complex::Complex64 as C;
    let Sheet { sc, name, what, .. } = *sheet;
    if sc.period_share < 0.5 {
        return None;
    }
    let amp = (2.0 * sc.period_share).sqrt() * sc.rms_height_nm;
    for lambda in wavelengths(ctx) {
        let Some([f, b]) = sheet.indices(sample, lambda) else {
            continue;
        };
        // The conductor and its lossless neighbour.
        let (metal, nd) = match (f.1 > 0.0, b.1 > 0.0) {
            (false, true) => (b, f.0),
            (true, false) => (f, b.0),
            _ => continue,
        };
        let eps_m = C::new(metal.0, metal.1).powi(2);
        let eps_d = nd * nd;
        if eps_m.re >= -eps_d {
            continue;
        }
        let ksp = (eps_m * eps_d / (eps_m + eps_d)).sqrt();
        let order = lambda / sc.period_nm;
        for &theta in &ctx.theta_i_deg {
            let (st, ct) = theta.to_radians().sin_cos();
            let kt = nd * st;
            let reach = (2.0 * std::f64::consts::PI * nd / lambda * amp * (1.0 + ct)).ceil() as i32;
            for m in 1..=reach {
                let q = f64::from(m) * order;
                let near = [(kt + q).abs(), (kt - q).abs(), kt.hypot(q)]
                    .into_iter()
                    .find(|t| (t - ksp.re).abs() < PLASMON_HALF_WIDTHS * ksp.im);
                if let Some(t) = near {
                    return Some(Finding {
                        message: format!(
                            "{name} is {what} on a conductor: at {theta:.0} deg and {lambda:.0} nm its order {m} runs along the surface with tangential index {t:.3}, within the surface plasmon's resonance (k_sp / k0 = {:.3} + {:.3}i), which absorbs TM light that rays and physical optics reflect. The run's total R may be too high there (by up to 0.16 on gold gratings against a rigorous solver); for R near such resonances use a rigorous grating solver (the Rayleigh-Fourier or C-method, or RCWA with Li's factorisation) (docs/validity.md)",
                            ksp.re, ksp.im
                        ),
                    });
                }
            }
        }
    }
    None
}

/// Structure smooth against the wavelength at an oblique incidence the run asks for. Where
/// Rayleigh's `g = (4 pi sigma n cos theta / lambda)^2` is small, and the heights small
/// against the wavelength (`k sigma`), the wave reflects from the mean plane, its total R
/// the flat interface's to `O(g)` (Rice, Commun. Pure Appl. Math. 4 (1951) 351; Beckmann &
/// Spizzichino 1963, ch. 5), while rays average the Fresnel
/// reflectance over facet tilts (and shadow at grazing light). Judged at every nanometre of
/// the run's range and at each of its angles. Where the two differ by more
/// than [`R_TOLERANCE`], estimated as the Fresnel reflectance at `theta` against its mean
/// at `theta` plus and minus the RMS slope angle, the rays' R is off: on gold gratings at
/// 75-85 deg, by up to 0.1 against the Rayleigh-Fourier method (docs/validity.md).
fn smooth_at_grazing(sample: &Sample, sheet: &Sheet, ctx: &Context) -> Option<Finding> {
    let Sheet { sc, name, what, .. } = *sheet;
    let tilt = sc.rms_slope.atan();
    for lambda in wavelengths(ctx) {
        let Some([f, b]) = sheet.indices(sample, lambda) else {
            continue;
        };
        if f.1 != 0.0 {
            continue;
        }
        let n2 = num_complex::Complex64::new(b.0, b.1);
        for &theta in &ctx.theta_i_deg {
            let t = theta.to_radians();
            let g =
                (4.0 * std::f64::consts::PI * sc.rms_height_nm * f.0 * t.cos() / lambda).powi(2);
            let k_sigma = 2.0 * std::f64::consts::PI * f.0 * sc.rms_height_nm / lambda;
            if g >= RAYLEIGH_SMOOTH || k_sigma >= SMOOTH_K_SIGMA {
                continue;
            }
            let flat = fresnel_r(f.0, n2, t);
            let tilted = 0.5
                * (fresnel_r(f.0, n2, (t - tilt).abs())
                    + fresnel_r(f.0, n2, (t + tilt).min(std::f64::consts::FRAC_PI_2)));
            if (tilted - flat).abs() > R_TOLERANCE {
                return Some(Finding {
                    message: format!(
                        "{name} has {what}: at {theta:.0} deg and {lambda:.0} nm it is smooth against the wavelength (Rayleigh g = {g:.2}), so the wave reflects from its mean plane (R {flat:.3}, the flat interface's) while rays average over facet tilts of {:.1} deg (about {tilted:.3}); the run's total R is uncertain by about {:.3} there. The flat interface's R is the better estimate at this angle (docs/validity.md)",
                        tilt.to_degrees(),
                        (tilted - flat).abs()
                    ),
                });
            }
        }
    }
    None
}

/// Everything a run should be told before it starts: [`assess`] and [`small_bodies`] at
/// the run's shortest wavelength.
pub fn findings(sample: &Sample, ctx: &Context) -> Vec<Finding> {
    let mut out = assess(sample, ctx);
    out.extend(small_bodies(sample, ctx.lambda_min_nm));
    out.extend(coatings_ignore_radius(sample, ctx));
    // Particle media packed beyond what their scattering model holds.
    out.extend(sample.media.iter().filter_map(|m| {
        let message = m.scattering.as_ref()?.packing_warning(&m.name)?;
        Some(Finding { message })
    }));
    out
}

/// Bodies small against `lambda_nm` (vacuum): below a size parameter `x = 2 pi r n /
/// lambda` of [`RAY_OPTICS_MIN_SIZE_PARAMETER`] for their equivalent-volume
/// sphere in the medium around them, traced as geometric bodies they scatter wrongly; one
/// finding per (outside, inside) pair of media, naming the particle medium to use.
pub fn small_bodies(sample: &Sample, lambda_nm: f64) -> Vec<Finding> {
    use RAY_OPTICS_MIN_SIZE_PARAMETER as X_MIN;
    let two_pi = 2.0 * std::f64::consts::PI;
    // Per (outside, inside) media: bodies counted, radii of the small ones, outside index.
    let mut small = std::collections::BTreeMap::<(usize, usize), (usize, Vec<f64>, f64)>::new();
    for itf in sample.interfaces.iter().filter(|i| i.closed) {
        let n_out = sample.media[itf.front]
            .model
            .eval(lambda_nm)
            .map_or(1.0, |(n, _)| n);
        let sizes: Vec<f64> = piece_volumes(&itf.mesh)
            .into_iter()
            .filter(|v| *v > 0.0)
            .map(|v| (3.0 * v / (2.0 * two_pi)).cbrt())
            .collect();
        let e = small
            .entry((itf.front, itf.back))
            .or_insert((0, Vec::new(), n_out));
        e.0 += sizes.len();
        e.1.extend(
            sizes
                .iter()
                .copied()
                .filter(|r| two_pi * r * n_out / lambda_nm < X_MIN),
        );
    }
    let mut out = Vec::new();
    for ((outside, inside), (count, mut radii, n_out)) in small {
        if radii.is_empty() {
            continue;
        }
        radii.sort_by(f64::total_cmp);
        let median = radii[radii.len() / 2];
        let (inner, outer) = (&sample.media[inside].name, &sample.media[outside].name);
        out.push(Finding {
            message: format!(
                "{} of {count} bodies of '{inner}' in '{outer}' are small against the wavelength (equivalent-sphere radius {median:.0} nm in the median, size parameter {:.1} at {lambda_nm:.0} nm; ray optics needs well above {X_MIN}): traced as geometric bodies they scatter wrongly. Describe them as a particle medium instead: particles = {{ medium = \"{inner}\", radius_nm = {median:.0}, volume_fraction = ... }} on '{outer}' (docs/physics.md, \"Particle media\")",
                radii.len(),
                two_pi * median * n_out / lambda_nm,
            ),
        });
    }
    out
}

/// Below this size parameter `x = 2 pi r n / lambda` of a body's equivalent-volume sphere
/// (at 550 nm in the medium around it), ray optics does not describe its scattering: Mie
/// resonances and diffraction dominate (van de Hulst, Light Scattering by Small Particles,
/// 1957, §§ 10-12: the geometric limit needs x well above 10).
pub const RAY_OPTICS_MIN_SIZE_PARAMETER: f64 = 10.0;

/// The connected pieces of a mesh (triangles joined by shared vertices): each piece's
/// enclosed volume, nm^3.
pub(crate) fn piece_volumes(mesh: &super::Mesh) -> Vec<f64> {
    let n = mesh.positions_nm.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn find(p: &mut [usize], mut i: usize) -> usize {
        while p[i] != i {
            p[i] = p[p[i]];
            i = p[i];
        }
        i
    }
    for t in &mesh.triangles {
        let a = find(&mut parent, t[0] as usize);
        for &v in &t[1..] {
            let b = find(&mut parent, v as usize);
            parent[b] = a;
        }
    }
    let mut volume = std::collections::BTreeMap::<usize, f64>::new();
    for t in &mesh.triangles {
        let root = find(&mut parent, t[0] as usize);
        let [a, b, c] = t.map(|i| mesh.positions_nm[i as usize]);
        *volume.entry(root).or_default() += a.dot(b.cross(c)) / 6.0;
    }
    volume.into_values().collect()
}
