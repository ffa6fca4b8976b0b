//! Accumulation of ray trees into BRDF / BTDF buckets: the estimator of docs/design.md §4.
//!
//! - `Beamlet` (default): each launched ray stands for a Gaussian beamlet of radius rho.
//!   Within one tree every exit contribution j deposits `|a_j|^2` in the bucket of its
//!   direction, and every pair (j, l) in the same hemisphere adds
//!   `c_jl = 2 Re(a_j . conj(a_l) exp(-i k n0 wbar . (x_j - x_l))) K_jl`, with
//!   `K_jl = exp(-|w_j - w_l|^2 / (2 theta_w^2)) exp(-|dx_perp|^2 / (2 rho^2))`,
//!   `theta_w = lambda / (pi rho)`, split between the two buckets in proportion to
//!   `|a_j|^2` and `|a_l|^2`. Only phase differences inside one tree enter, formed from
//!   differences of exit points, so the result is free of any origin and of the grid.
//!   `rho = inf` is the plane-wave limit: only directions agreeing to 1e-9 interfere.
//! - `Bucket` (Gondek et al. 1994 and the seed): contributions of one tree that land in the
//!   same bucket add as amplitudes, each with its phase relative to the global origin
//!   (`exp(-i k n0 w . x)` with the absolute exit point); others do not interfere. Its
//!   answer depends on the bucket grid and on where the origin sits.
//! - `Global` (the seed's final method): all contributions of all trees in a bucket are
//!   averaged as amplitudes relative to the whole incident beam, and the average squared.
//! - `Diffraction`: every tree's exits into a lossless half-space add as fields over the
//!   whole tile (physical optics on the ray field, `diffraction.rs`): Floquet orders of the
//!   periodic tile, spread by the illumination's partial coherence (radius rho). The
//!   beamlet estimator still runs on the same trees: its totals are the ray method's, which
//!   the diffracted totals are checked against (energy, Parseval).
//!
//! Trees add incoherently, each carrying 1/N of the flux through the tile; the two incident
//! polarisations are averaged.

pub(crate) mod block;
pub mod buckets;
mod cell;
mod conserve;
mod deposit;
pub mod diffraction;
mod directions;
pub mod file;
mod inhomogeneous;
mod methods;
mod patch;
pub mod phase;
pub mod polarimetric;
mod prepare;
mod tube;
mod validate;

pub use buckets::Buckets;
pub use cell::{Cell, stderr};
pub use inhomogeneous::AMPLITUDE_WINDOW;

use crate::optics::C64;
use crate::optics::fresnel::Field;
use crate::optics::mueller::{Jones, Mueller};
use glam::DVec3;

/// How contributions interfere (written by name in files: "auto", "beamlet", "bucket",
/// "global", "diffraction", "rigorous"; an unknown name is refused).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Coherence {
    /// Each (incident direction, wavelength) cell takes the method its scales call for:
    /// the beamlet estimator's rays, or the diffraction method (`simulate::auto`). The
    /// estimator itself never runs in this mode; a `.gsa` records each cell's choice
    /// (`Settings::methods`).
    Auto,
    Beamlet,
    Bucket,
    Global,
    Diffraction,
    /// The Fourier modal method on the sample's tile (`optics::rcwa`,
    /// `reference::rigorous`): no rays; each cell's orders from Maxwell's equations.
    Rigorous,
}

impl Coherence {
    pub fn name(self) -> &'static str {
        match self {
            Coherence::Auto => "auto",
            Coherence::Beamlet => "beamlet",
            Coherence::Bucket => "bucket",
            Coherence::Global => "global",
            Coherence::Diffraction => "diffraction",
            Coherence::Rigorous => "rigorous",
        }
    }
    pub fn parse(s: &str) -> Option<Coherence> {
        match s {
            "auto" => Some(Coherence::Auto),
            "beamlet" => Some(Coherence::Beamlet),
            "bucket" => Some(Coherence::Bucket),
            "global" => Some(Coherence::Global),
            "diffraction" => Some(Coherence::Diffraction),
            "rigorous" => Some(Coherence::Rigorous),
            _ => None,
        }
    }
}

impl std::fmt::Display for Coherence {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Key of a bucket in either hemisphere: `bucket * 2 + (1 if down)`.
#[inline]
pub fn key(bucket: usize, down: bool) -> u32 {
    (bucket as u32) << 1 | u32::from(down)
}

/// Settings of the estimator for one simulation.
#[derive(Clone, Copy, Debug)]
pub struct Estimator {
    pub mode: Coherence,
    /// Beamlet radius, nm (`f64::INFINITY` for the plane-wave limit).
    pub rho_nm: f64,
    pub buckets: Buckets,
    /// Real index above (reflection side) and below (transmission side).
    pub n_up: f64,
    pub n_down: f64,
    /// Phase precision: with `F32`, optical path lengths and exit points are rounded to
    /// single precision and phases formed in single-precision arithmetic, as a tracer that
    /// stores them in `f32` would (the study's f32-against-f64 experiment). `F64` is the
    /// default and the only precision for production runs.
    pub precision: PhasePrecision,
    /// The longest wavelength any tree is evaluated at, nm: a pair's Gaussian overlap
    /// kernel is largest there, which bounds its cross term at every wavelength (pairs
    /// whose bound is below [`NEGLIGIBLE_CROSS`] are culled before the wavelength loop).
    pub lambda_max_nm: f64,
    /// The reference estimator: culls pairs by the positional overlap only and forms
    /// every phase with the C library's `sincos` (slower; the fast estimator is tested
    /// against it to 1e-12 relative, tests/estimator.rs).
    pub reference: bool,
    /// Deposit each exit's and pair's Mueller matrix too (`--mueller`, the beamlet
    /// estimator only): [`Scratch::mueller_deposits`].
    pub mueller: bool,
}

/// A pair of exits whose cross term `|c_jl| <= 2 |h| K` is below this fraction of the
/// launched power at every wavelength is left out (its contribution is below the
/// rounding of the cell sums it would be added to).
pub const NEGLIGIBLE_CROSS: f64 = 1e-15;

/// The floating-point precision phases are formed in (see [`Estimator::precision`]);
/// written by name ("f64", "f32").
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum PhasePrecision {
    #[default]
    F64,
    F32,
}

impl PhasePrecision {
    pub fn name(self) -> &'static str {
        match self {
            PhasePrecision::F64 => "f64",
            PhasePrecision::F32 => "f32",
        }
    }
    pub fn parse(s: &str) -> Option<PhasePrecision> {
        match s {
            "f64" => Some(PhasePrecision::F64),
            "f32" => Some(PhasePrecision::F32),
            _ => None,
        }
    }
}

/// `a . b` in single precision, from single-precision copies of the operands.
fn dot32(a: DVec3, b: DVec3) -> f32 {
    a.as_vec3().dot(b.as_vec3())
}

/// Reusable per-thread buffers.
#[derive(Default)]
pub struct Scratch {
    amp: Vec<[Field; 2]>,
    sums: Vec<(u32, [Field; 2])>,
    /// Pair phases at the current wavelength and their sines and cosines; exponents and
    /// their exponentials; exits' attenuated powers and summed cross terms.
    phase: Vec<f64>,
    sin: Vec<f64>,
    cos: Vec<f64>,
    arg: Vec<f64>,
    expv: Vec<f64>,
    att: Vec<f64>,
    exit_sum: Vec<f64>,
    /// The wavelength-independent part of the current tree (see [`Estimator::prepare`]).
    prep: Prepared,
    /// Candidate pairs and the direction grid that finds them
    /// ([`Estimator::candidate_pairs`]).
    cand: Vec<(u32, u32)>,
    grid: Vec<([i64; 3], u32)>,
    /// With [`Estimator::mueller`]: the deposits' Mueller matrices at the current
    /// wavelength, `(key, matrix)`, whose `m00` are the scalar deposits' very values; and
    /// each exit's summed pair terms.
    mdeps: Vec<(u32, Mueller)>,
    exit_msum: Vec<Mueller>,
    /// The exit each deposit of the last [`Estimator::deposit`] belongs to (beside its
    /// scalar and its Mueller deposits), each coherence group's own and total power, and
    /// the power the last deposit's lossless groups were corrected by
    /// ([`conserve::conserve_groups`]).
    out_exit: Vec<u32>,
    mdep_exit: Vec<u32>,
    group_power: Vec<(f64, f64)>,
    corrected: f64,
}

impl Scratch {
    /// The Mueller deposits of the last [`Estimator::deposit`] (empty without
    /// [`Estimator::mueller`]).
    pub fn mueller_deposits(&self) -> &[(u32, Mueller)] {
        &self.mdeps
    }

    /// The power, as a fraction of the launched power, by which the last
    /// [`Estimator::deposit`] corrected the cross terms of the tree's lossless coherence
    /// groups so that they carry out what entered them (`conserve`; 0 for trees that met
    /// absorption and for modes other than beamlet).
    pub fn corrected(&self) -> f64 {
        self.corrected
    }
}

/// What the estimator needs of one tree, computed once and reused for every wavelength
/// (spectral path sharing): bucket keys, powers, and for each interfering pair the
/// Hermitian product of the fields and the geometric phase and overlap terms.
#[derive(Default)]
struct Prepared {
    keys: Vec<u32>,
    /// `(|E_0|^2 + |E_1|^2) / 2` without attenuation, and `Im(OPL)` (nm).
    pow: Vec<f64>,
    im: Vec<f64>,
    pairs: Vec<Pair>,
    /// Plane-wave limit: groups of exits whose directions agree to 1e-9, as ranges of
    /// `members`; each member's phase offset from the group's first exit, nm.
    groups: Vec<(u32, u32)>,
    members: Vec<u32>,
    member_delta_nm: Vec<f64>,
    /// Each exit's group, as the index of the group's first member in `members`.
    group_of: Vec<u32>,
    absorbing: bool,
    /// With [`Estimator::mueller`]: each exit's Jones matrix (`optics::mueller::jones`)
    /// and, beside `pairs`, each pair's mixed Mueller matrix times its flux factor.
    jones: Vec<Jones>,
    pair_m: Vec<[C64; 16]>,
}

struct Pair {
    j: u32,
    l: u32,
    /// `(E_j . conj E_l)` averaged over the two polarisations.
    h: C64,
    /// Optical path difference minus the exit-point term: `Re(OPL_j - OPL_l) - n0 wbar .
    /// (x_j - x_l)`, nm; the pair's phase at wavelength lambda is `2 pi / lambda` times it.
    delta_nm: f64,
    /// Positional overlap `exp(-|dx_perp|^2 / (2 rho^2))`.
    k_pos: f64,
    /// `|w_j - w_l|^2`, for the directional overlap at each wavelength.
    dw2: f64,
    /// `|(N''_j + N''_l)_perp|^2`: how fast the pair's amplitudes change across the
    /// beamlet (the exits' imaginary index vectors, across `wbar`; zero for homogeneous
    /// exits), which narrows the window their directional overlap is taken over
    /// ([`inhomogeneous::directional_exponent`]).
    m2: f64,
    /// The pair's amplitudes carried from their exit points to their midpoint, where its
    /// phase is taken ([`inhomogeneous::pair_terms`]), as an exponent over `k`, nm (zero for
    /// homogeneous exits).
    grow_nm: f64,
}

/// `acc += a` for the fields of both polarisations.
pub fn add_fields(acc: &mut [Field; 2], a: &[Field; 2]) {
    for (x, y) in acc.iter_mut().zip(a) {
        for (u, v) in x.iter_mut().zip(y) {
            *u += v;
        }
    }
}
