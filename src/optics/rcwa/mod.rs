//! The Fourier modal method (rigorous coupled-wave analysis) for a periodic tile sliced into
//! layers along z (docs/physics.md, "The rigorous solver").
//!
//! Within a slice the permittivity depends on x and y only; the tangential fields are
//! Floquet sums over the kept harmonics, `k_pq = k_in + 2π (p / Λx, q / Λy)`. With lengths
//! in units of `1 / k0`, `H` in units of `1 / Z0`, time `e^{-iωt}` and `ζ = -z` pointing into
//! the sample, Maxwell's curl equations for `e = (E_x, E_y)` and `h = (H_x, H_y)` are
//! `∂ζ e = -i P h`, `∂ζ h = -i Q e` (Moharam, Grann, Pommet & Gaylord 1995, JOSA A 12,
//! 1068, in the vector form of Lalanne 1997, JOSA A 14, 1592) with
//!
//! ```text
//! P = [ Kx εz⁻¹ Ky        I − Kx εz⁻¹ Kx ]     Q = [ −Kx Ky       Kx² − ε_yy ]
//!     [ Ky εz⁻¹ Ky − I    −Ky εz⁻¹ Kx    ]         [ ε_xx − Ky²   Ky Kx      ]
//! ```
//!
//! (the permittivity matrices by Li's rules, [`fourier`]). The slice's modes are the
//! eigenvectors `W` of `PQ` with `γ² ` its eigenvalues: down-going `e^{iγζ}` with `Im γ > 0`
//! (or `γ > 0` when real), magnetic fields `V = -Q W Γ⁻¹`, up-going ones the same with `-V`.
//! A homogeneous slice has `W = I` and `γ = sqrt(ε − kx² − ky²)` exactly, so flat layers and
//! coatings are exact.
//!
//! Slices are joined by scattering matrices and Redheffer's star product, which only ever
//! multiplies the decaying factors `e^{iγ k0 d}`: stable for thick and absorbing slices
//! (Li 1996, "Formulation and comparison of two recursive matrix algorithms for modeling
//! layered diffraction gratings", JOSA A 13, 1024).

// The solver proper needs faer; the `rigorous` feature (on by default) brings it. The fuzz
// harnesses, which exercise the parsers only, build without it.
#[cfg(feature = "rigorous")]
mod asr;
#[cfg(feature = "rigorous")]
mod cmethod;
#[cfg(feature = "rigorous")]
mod conical;
#[cfg(feature = "rigorous")]
mod flat;
#[cfg(feature = "rigorous")]
pub mod fourier;
#[cfg(feature = "rigorous")]
mod modal;

use glam::DVec3;

pub use super::C64;
use super::mueller::Jones;

/// A slice's permittivity on a pixel grid, `eps[iy * nx + ix]`.
#[derive(Clone, Debug, PartialEq)]
pub struct Grid {
    pub n: [usize; 2],
    pub eps: Vec<C64>,
}

/// The harmonics kept: `-m[0]..=m[0]` along x and `-m[1]..=m[1]` along y; harmonic
/// `(p, q)` is row `(q + m[1]) (2 m[0] + 1) + (p + m[0])`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Harmonics {
    pub m: [usize; 2],
}

impl Harmonics {
    pub fn count(self) -> usize {
        (2 * self.m[0] + 1) * (2 * self.m[1] + 1)
    }
    /// Harmonic `(p, q)` of row `i`.
    pub fn pq(self, i: usize) -> [i64; 2] {
        let w = 2 * self.m[0] + 1;
        [
            (i % w) as i64 - self.m[0] as i64,
            (i / w) as i64 - self.m[1] as i64,
        ]
    }
}

/// A slice's permittivity: one value, or a pixel grid.
#[derive(Clone, Debug, PartialEq)]
pub enum Slab {
    Uniform(C64),
    Grid(Grid),
}

/// One slice: thickness (nm) and permittivity.
#[derive(Clone, Debug, PartialEq)]
pub struct Layer {
    pub thickness_nm: f64,
    pub slab: Slab,
}

/// A periodic structure: the half-space above (lossless: real permittivity), the slices top
/// first, the half-space below.
#[derive(Clone, Debug, PartialEq)]
pub struct Structure {
    pub period_nm: [f64; 2],
    pub eps_above: f64,
    pub layers: Vec<Layer>,
    pub eps_below: C64,
}

/// One propagating order of the solution.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Order {
    /// Harmonic `(p, q)`.
    pub m: [i64; 2],
    /// Travels up (reflected) or down (transmitted).
    pub up: bool,
    /// Unit direction of travel.
    pub dir: DVec3,
    /// Jones matrix (rows: outgoing p, s in the frame of `dir`; columns: incident p, s in
    /// the frame of the incident direction; [`crate::optics::mueller`]) scaled so that
    /// `|J_ab|^2` is the efficiency from state `b` into state `a`.
    pub jones: Jones,
}

impl Order {
    /// Efficiency for incident s (`pol = 0`) or p (`pol = 1`) light.
    pub fn efficiency(&self, pol: usize) -> f64 {
        let c = if pol == 0 { 1 } else { 0 };
        self.jones[c].norm_sqr() + self.jones[2 + c].norm_sqr()
    }
    /// Efficiency for unpolarised light.
    pub fn efficiency_unpolarised(&self) -> f64 {
        0.5 * (self.efficiency(0) + self.efficiency(1))
    }
}

/// The propagating orders of one incidence, and the totals.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Solution {
    pub orders: Vec<Order>,
    /// Reflectance for s and p light.
    pub r: [f64; 2],
    /// Transmittance for s and p light (0 below an absorbing half-space).
    pub t: [f64; 2],
}

/// Why the solver cannot answer.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RcwaError {
    #[error("the rigorous solver's eigendecomposition failed to converge ({0} harmonics)")]
    Eigen(usize),
    #[error("the rigorous solver met a singular matrix: {0}")]
    Singular(&'static str),
    #[error("the half-space above must be lossless with a positive permittivity (got {0})")]
    AboveLossy(f64),
    #[error("the incident direction must travel down into the sample (d.z < 0)")]
    Direction,
    #[error(
        "this build of goniospec has no rigorous solver (built without the `rigorous` feature)"
    )]
    NotBuilt,
    #[error("{0}")]
    Unsupported(&'static str),
}

/// What both solvers require of the light: a lossless half-space above with a positive
/// permittivity `eps_above`, and `d` travelling down into the sample.
fn check_incidence(eps_above: f64, d: DVec3) -> Result<(), RcwaError> {
    if eps_above.is_nan() || eps_above <= 0.0 {
        return Err(RcwaError::AboveLossy(eps_above));
    }
    if d.z.is_nan() || d.z >= 0.0 {
        return Err(RcwaError::Direction);
    }
    Ok(())
}

/// Solves `s` for light of `lambda_nm` (nm, in vacuum) travelling along `d` (unit, `d.z < 0`)
/// in the half-space above, keeping the harmonics `h`.
pub fn solve(s: &Structure, lambda_nm: f64, d: DVec3, h: Harmonics) -> Result<Solution, RcwaError> {
    check_incidence(s.eps_above, d)?;
    #[cfg(feature = "rigorous")]
    return modal::solve(s, lambda_nm, d, h);
    #[cfg(not(feature = "rigorous"))]
    {
        let _ = (s, lambda_nm, d, h);
        Err(RcwaError::NotBuilt)
    }
}

/// A 1-D relief `z = a(x)` (nm), sampled at `x_i = i Λ / S` (`heights_nm[i]`), over the
/// half-space below and under the half-space above or flat layers, for the C-method
/// ([`solve_profile`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Profile {
    pub period_nm: f64,
    pub heights_nm: Vec<f64>,
    /// The half-space above (lossless) and below.
    pub eps_above: f64,
    pub eps_below: C64,
    /// Flat interfaces above the relief, top first (a lacquer over an embossed metal): the
    /// last one's medium below is the relief's cover, which must be lossless. Empty: the
    /// relief lies under the half-space above.
    pub planes: Vec<Plane>,
}

/// A flat interface over a relief: its height (nm, in the relief's heights' frame, above
/// the relief's highest point) and the permittivity of the medium below it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    pub z_nm: f64,
    pub eps_below: C64,
}

/// Whether the relief `heights_nm` (one period `period_nm`, samples at `i Λ / S`) has sharp
/// corners (its direction turning by more than 10 deg at a vertex: a trapezoid, a V-groove),
/// where [`solve_profile`] takes the harmonics in a stretched coordinate (adaptive spatial
/// resolution) and needs more of them than on a smooth relief.
pub fn has_corners(heights_nm: &[f64], period_nm: f64) -> bool {
    #[cfg(feature = "rigorous")]
    return !asr::polyline(heights_nm, period_nm).corners().is_empty();
    #[cfg(not(feature = "rigorous"))]
    {
        let _ = (heights_nm, period_nm);
        false
    }
}

/// Solves the relief `p` by the C-method (curvilinear coordinates: no staircase, so TM on
/// metals converges fast; on a relief with sharp corners in the stretched coordinate of
/// adaptive spatial resolution, `asr.rs`), joined to its flat layers above order by order, for light
/// of `lambda_nm` along `d` (unit, `d.z < 0`; in the plane across the grooves, `d.y = 0`, or
/// from any other azimuth: conical incidence) with harmonics `-m..=m`.
pub fn solve_profile(
    p: &Profile,
    lambda_nm: f64,
    d: DVec3,
    m: usize,
) -> Result<Solution, RcwaError> {
    check_incidence(p.eps_above, d)?;
    #[cfg(feature = "rigorous")]
    return if d.y == 0.0 {
        cmethod::solve(p, lambda_nm, d, m)
    } else {
        conical::solve(p, lambda_nm, d, m)
    };
    #[cfg(not(feature = "rigorous"))]
    {
        let _ = (p, lambda_nm, d, m);
        Err(RcwaError::NotBuilt)
    }
}
