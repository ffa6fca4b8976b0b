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
pub mod diffraction;
pub mod file;
pub mod phase;

use std::f64::consts::PI;

pub use buckets::Buckets;
pub use cell::{Cell, stderr};

use crate::optics::C64;
use crate::optics::fresnel::{Field, field_power, hermitian};
use crate::trace::Tree;
use glam::DVec3;

/// How contributions interfere (written by name in files: "beamlet", "bucket", "global";
/// an unknown name is refused).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Coherence {
    Beamlet,
    Bucket,
    Global,
    Diffraction,
}

impl Coherence {
    pub fn name(self) -> &'static str {
        match self {
            Coherence::Beamlet => "beamlet",
            Coherence::Bucket => "bucket",
            Coherence::Global => "global",
            Coherence::Diffraction => "diffraction",
        }
    }
    pub fn parse(s: &str) -> Option<Coherence> {
        match s {
            "beamlet" => Some(Coherence::Beamlet),
            "bucket" => Some(Coherence::Bucket),
            "global" => Some(Coherence::Global),
            "diffraction" => Some(Coherence::Diffraction),
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
    /// ([`directional_exponent`]).
    m2: f64,
    /// The pair's amplitudes carried from their exit points to their midpoint, where its
    /// phase is taken ([`pair_terms`]), as an exponent over `k`, nm (zero for
    /// homogeneous exits).
    grow_nm: f64,
}

/// What a pair of exits `a`, `b` of which at least one is an inhomogeneous wave (`N = N' +
/// i N''`, `N' . N'' = 0` and `|N'|^2 - |N''|^2 = n0^2` in the lossless exit medium, `N'`
/// along the exit's direction) needs beyond a homogeneous pair: the terms of carrying it
/// to its midpoint, `(phase_nm, grow_nm)`, and its interference flux factor `f`.
///
/// **Midpoint.**
///
/// A field `a exp(i k N . (x - x_a))` evaluated at the midpoint `x_c = (x_a + x_b) / 2`
/// has its amplitude multiplied by `exp(-k N''_a . (x_c - x_a))`, so the product of the
/// pair's amplitudes there gains `exp(k g)` with `g = -(N''_a - N''_b) . (x_b - x_a) / 2`
/// (`grow_nm`); and its phase difference is `k [OPL_a - OPL_b - (N'_a + N'_b) / 2 . (x_a -
/// x_b)]`, which differs from the homogeneous pairs' `n0 wbar . (x_a - x_b)`
/// ([`Estimator::path_difference`]) by `phase_nm`. Both vanish for homogeneous exits and
/// for exits at one point. Evaluated at any point common to the pair, the cross term
/// averages over launch points to the same value on a facet whose partial waves are plane
/// waves (a wedge); at the exit points, as before, the amplitudes of a film whose faces
/// are tilted were taken at different places: a gold film whose faces meet at 0.5 degree
/// was 4.3e-3 off the local transfer-matrix film, with 1.7e-3 of the power per tree
/// created at 60 degrees and 650 nm, and was 1.3e-3 off with none (1.7e-3 with the flux
/// factor too, 1.5e-3 with the exits on the power basis; tests/tilted_absorbers.rs).
/// (Carrying every exit of a tree to one common point instead makes the amplitudes of
/// partial waves that walked hundreds of nanometres grow without bound: 0.42 of the power
/// created at 0.5 degree.)
///
/// **Flux factor**, through the exit plane: `f = (q_a + conj(q_b)) / (Re q_a + Re q_b)`, with `q = N . z_out` the
/// complex normal index of each exit (`z_out` the exit plane's normal on the side the
/// light leaves by; `N' = |N'| d`, `|N'|^2 = n0^2 + |N''|^2` in the lossless exit medium).
///
/// The time-averaged normal Poynting flux of two plane waves `E_j`, `H_j = N_j x E_j` of one
/// polarisation through a plane is, up to a common factor,
///
/// ```text
/// |A_a|^2 Re q_a + |A_b|^2 Re q_b + Re[A_a conj(A_b) (q_a + conj(q_b))]
/// ```
///
/// (for s, `E = A y` and `H_x = -A q`; for p the same with the bilinear amplitude `A`,
/// `H_y = n A`: Born & Wolf §1.4.3, §14.2): the cross term's factor is `q_a + conj(q_b)`,
/// not `2 Re q`. The carried amplitudes hold `sqrt(Re q)` (optics::fresnel, "Carried
/// amplitudes"), so the pair's Hermitian product `h` is
/// multiplied by `f`, to second order in the difference of the exits' directions (the
/// homogeneous pairs' own approximation). For homogeneous exits `f = 1`; an inhomogeneous
/// pair's `f - 1 = i (q''_a - q''_b) / (q'_a + q'_b)` is first order in the tilt of a film's
/// faces. Measured on a gold film whose faces meet at 1 degree, against RCWA for TM (PyPI
/// nannos, Li's factorisation, 121 orders): R at 60 degrees and 650 nm 0.334 against
/// 0.325, was 0.358; at 550 nm 0.228 against 0.227, was 0.239 (docs/physics.md).
///
/// Returns `(phase_nm, grow_nm, f)`; a homogeneous pair `(0, 0, 1)`.
fn pair_terms(a: &crate::trace::Exit, b: &crate::trace::Exit, n0: f64) -> (f64, f64, C64) {
    if a.n_im == DVec3::ZERO && b.n_im == DVec3::ZERO {
        return (0.0, 0.0, C64::ONE);
    }
    let n_re = |x: &crate::trace::Exit| x.dir * (n0 * n0 + x.n_im.length_squared()).sqrt();
    let (na, nb) = (n_re(a), n_re(b));
    let wbar = (a.dir + b.dir).normalize();
    let phase = -((na + nb) * 0.5 - wbar * n0).dot(a.x - b.x);
    let grow = -0.5 * (a.n_im - b.n_im).dot(b.x - a.x);
    let z = if a.up { DVec3::Z } else { -DVec3::Z };
    let (qa, qb) = (
        C64::new(na.dot(z), a.n_im.dot(z)),
        C64::new(nb.dot(z), b.n_im.dot(z)),
    );
    (phase, grow, (qa + qb.conj()) / (qa.re + qb.re))
}

/// [`Pair::m2`] for exits `a` and `b` about their mean direction `wbar`: `|(N''_a +
/// N''_b)_perp|^2`.
fn inhomogeneity(a: &crate::trace::Exit, b: &crate::trace::Exit, wbar: DVec3) -> f64 {
    let m = a.n_im + b.n_im;
    let m = m - wbar * m.dot(wbar);
    m.dot(m)
}

/// A pair of inhomogeneous exits is evaluated over the window in which its amplitudes
/// change by at most this factor's logarithm (5 %): see [`directional_exponent`].
pub const AMPLITUDE_WINDOW: f64 = 0.05;

/// The exponent of a pair's directional overlap at wave number `k` (1/nm), for exits
/// `|w_j - w_l|^2 = dw2` apart in direction and with `m2` as in [`Pair::m2`], under a
/// beamlet of radius `rho_nm`:
///
/// - homogeneous exits (`m2 = 0`): the Gaussian beamlets' overlap `-|dw|^2 / (2
///   theta_w^2)`, `theta_w = lambda / (pi rho)` (docs/design.md §4), that is `-s^2 k^2
///   |dw|^2 / 2` over the window `s = rho / 2`;
/// - inhomogeneous exits (they left an absorber through a face not parallel to its planes
///   of constant amplitude, as each partial wave of a film whose faces are tilted does):
///   their fields `a exp(i k N . x)` change in amplitude by `exp(k |M| x)` across the
///   beamlet, `M = (N''_j + N''_l)_perp`, so their plane-wave extrapolation from the exit
///   points holds only within `s = AMPLITUDE_WINDOW / (k |M|)`. The overlap is taken over
///   that window where it is smaller than `rho / 2`: `-min(rho / 2, c / (k |M|))^2 k^2
///   |dw|^2 / 2`. The exact overlap of two inhomogeneous Gaussian beamlets over a window
///   `s` is `exp(-s^2 Q . Q / 2)` with `Q = k (dw + i M)` (docs/physics.md, "Energy at
///   interfaces"): within this window its other factors, `exp(s^2 k^2 |M|^2 / 2)` and a
///   phase `s^2 k^2 dw . M`, are within `c^2 / 2 = 1.25e-3` of 1 and are left out.
///
/// The window is continuous in `M` (it is the beamlet's until `k |M| rho / 2` reaches
/// `c`: a film tilted by about 1e-4 degree), so results are continuous in a facet's tilt.
#[inline(always)]
fn directional_exponent(dw2: f64, m2: f64, k: f64, rho_nm: f64) -> f64 {
    let beamlet = 0.25 * k * k * rho_nm * rho_nm;
    let window = if m2 > 0.0 {
        beamlet.min(AMPLITUDE_WINDOW * AMPLITUDE_WINDOW / m2)
    } else {
        beamlet
    };
    -0.5 * dw2 * window
}

impl Estimator {
    /// The incident wave's phase at a tree's launch point `x` (nm, world frame) for a
    /// wave travelling along `d` at wave number `k` (1/nm): `k n_up (d . x)`, in the
    /// estimator's precision.
    pub fn entry_phase(&self, k: f64, d: DVec3, x: DVec3) -> f64 {
        match self.precision {
            PhasePrecision::F64 => k * self.n_up * d.dot(x),
            PhasePrecision::F32 => f64::from(k as f32 * self.n_up as f32 * dot32(d, x)),
        }
    }

    /// Prepares the wavelength-independent part of `tree` (call once per traced tree).
    pub fn prepare(&self, tree: &Tree, s: &mut Scratch) {
        let p = &mut s.prep;
        p.keys.clear();
        p.pow.clear();
        p.im.clear();
        p.pairs.clear();
        p.groups.clear();
        p.members.clear();
        p.member_delta_nm.clear();
        p.group_of.clear();
        p.absorbing = false;
        for x in &tree.exits {
            p.keys.push(key(self.buckets.index(x.dir), !x.up));
            p.pow
                .push(0.5 * (field_power(&x.e[0]) + field_power(&x.e[1])));
            p.im.push(x.opl.im);
            p.absorbing |= x.opl.im != 0.0;
        }
        if self.mode != Coherence::Beamlet {
            return;
        }
        let ex = &tree.exits;
        let plane_wave = self.rho_nm.is_infinite();
        if plane_wave {
            self.prepare_groups(tree, p);
            self.prepare_inhomogeneous_pairs(tree, p);
            return;
        }
        // The directional kernel `exp(-|dw|^2 / (2 theta_w^2))`, `theta_w = lambda / (pi
        // rho)`, is largest at the longest wavelength.
        let two_theta_max2 = 2.0 * (self.lambda_max_nm / (PI * self.rho_nm)).powi(2);
        let k_min = 2.0 * PI / self.lambda_max_nm;
        let inhomogeneous = ex.iter().any(|x| x.n_im != DVec3::ZERO);
        let mut candidates = std::mem::take(&mut s.cand);
        candidates.clear();
        self.candidate_pairs(ex, &p.pow, two_theta_max2, &mut s.grid, &mut candidates);
        for &(j, l) in &candidates {
            let (j, l) = (j as usize, l as usize);
            let dw = ex[j].dir - ex[l].dir;
            let dw2 = dw.dot(dw);
            let dx = ex[j].x - ex[l].x;
            let wbar = (ex[j].dir + ex[l].dir).normalize();
            let k_pos = {
                let along = dx.dot(wbar);
                let perp = dx - wbar * along;
                (-perp.dot(perp) / (2.0 * self.rho_nm * self.rho_nm)).exp()
            };
            let m2 = if inhomogeneous {
                inhomogeneity(&ex[j], &ex[l], wbar)
            } else {
                0.0
            };
            let n0 = if ex[j].up { self.n_up } else { self.n_down };
            let (phase_nm, grow_nm, flux) = pair_terms(&ex[j], &ex[l], n0);
            let h = 0.5
                * (hermitian(&ex[j].e[0], &ex[l].e[0]) + hermitian(&ex[j].e[1], &ex[l].e[1]))
                * flux;
            // Pairs that cannot contribute at any wavelength are skipped: |c| <= 2|h| K,
            // and the directional overlap is largest at the longest wavelength.
            let bound = 2.0 * h.norm() * k_pos;
            let directional = || {
                if m2 > 0.0 {
                    directional_exponent(dw2, m2, k_min, self.rho_nm).exp()
                } else {
                    (-dw2 / two_theta_max2).exp()
                }
            };
            // Carried to their midpoint the amplitudes may grow ([`pair_terms`]): such
            // a pair is kept.
            if grow_nm <= 0.0
                && (bound < NEGLIGIBLE_CROSS
                    || (!self.reference && dw2 > 0.0 && bound * directional() < NEGLIGIBLE_CROSS))
            {
                continue;
            }
            let delta_nm = self.path_difference(&ex[j], &ex[l], wbar, n0) + phase_nm;
            p.pairs.push(Pair {
                j: j as u32,
                l: l as u32,
                h,
                delta_nm,
                k_pos,
                dw2,
                m2,
                grow_nm,
            });
        }
        s.cand = candidates;
    }

    /// The pairs `(j, l)`, `j < l`, of exits in one hemisphere and one coherence group
    /// ([`crate::trace::Exit::group`]: light scattered by particles is incoherent with
    /// every other path) that [`Estimator::prepare`]
    /// must look at, in the order of a double loop over `j` then `l`. The reference
    /// estimator and small trees take every pair. Otherwise only exits whose directions are
    /// close enough for the directional kernel to matter at the longest wavelength can pair:
    /// `|h| <= max P`, so a pair with `|w_j - w_l|^2 > 2 theta_max^2 ln(2 max P /
    /// NEGLIGIBLE_CROSS)` has a bound below `NEGLIGIBLE_CROSS` and would be culled anyway.
    /// They are found through a grid of the unit directions with cells that wide, looking
    /// at the 27 cells around each exit, so a tree of n exits costs about n, not n^2 (a
    /// steep height map's 10^4 exits took seconds per tree). The kept pairs, and so the
    /// sums, are the double loop's exactly.
    fn candidate_pairs(
        &self,
        ex: &[crate::trace::Exit],
        pow: &[f64],
        two_theta_max2: f64,
        grid: &mut Vec<([i64; 3], u32)>,
        out: &mut Vec<(u32, u32)>,
    ) {
        let n = ex.len();
        let max_pow = pow.iter().copied().fold(0.0, f64::max);
        let reach2 = if max_pow > 0.0 {
            two_theta_max2 * (2.0 * max_pow / NEGLIGIBLE_CROSS).ln().max(0.0)
        } else {
            0.0
        };
        // Unit directions differ by at most 2; cells narrower than that pay off.
        let cell = reach2.sqrt() * (1.0 + 1e-9);
        if self.reference || n <= 32 || !(cell > 0.0 && cell < 0.5) {
            for j in 0..n {
                for l in j + 1..n {
                    if ex[j].up == ex[l].up && ex[j].group == ex[l].group {
                        out.push((j as u32, l as u32));
                    }
                }
            }
            return;
        }
        let key = |d: DVec3| (d / cell).floor().as_i64vec3().to_array();
        grid.clear();
        grid.extend(ex.iter().enumerate().map(|(i, x)| (key(x.dir), i as u32)));
        grid.sort_unstable();
        let same =
            |a: &crate::trace::Exit, b: &crate::trace::Exit| a.up == b.up && a.group == b.group;
        // The inhomogeneous exits, in order (none in most trees).
        let inhomogeneous: Vec<u32> = (0..n as u32)
            .filter(|&i| ex[i as usize].n_im != DVec3::ZERO)
            .collect();
        for (j, x) in ex.iter().enumerate() {
            // An inhomogeneous exit's directional window can be far narrower than the
            // beamlet's ([`directional_exponent`]): it pairs with every exit of its
            // hemisphere and group (only films and absorbers' edges have such exits).
            if x.n_im != DVec3::ZERO {
                for (l, y) in ex.iter().enumerate().skip(j + 1) {
                    if same(x, y) {
                        out.push((j as u32, l as u32));
                    }
                }
                continue;
            }
            for &l in &inhomogeneous[inhomogeneous.partition_point(|&l| l as usize <= j)..] {
                if same(x, &ex[l as usize]) {
                    out.push((j as u32, l));
                }
            }
            let k = key(x.dir);
            for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        let c = [k[0] + dx, k[1] + dy, k[2] + dz];
                        let from = grid.partition_point(|e| e.0 < c);
                        for &(kc, l) in &grid[from..] {
                            if kc != c {
                                break;
                            }
                            let l = l as usize;
                            // Pairs with an inhomogeneous exit were all taken above.
                            if l > j && same(&ex[l], x) && ex[l].n_im == DVec3::ZERO {
                                let dw = x.dir - ex[l].dir;
                                if dw.dot(dw) <= reach2 * (1.0 + 1e-9) {
                                    out.push((j as u32, l as u32));
                                }
                            }
                        }
                    }
                }
            }
        }
        out.sort_unstable();
    }

    /// `Re(OPL_j - OPL_l) - n0 w . (x_j - x_l)`, nm, in the estimator's precision: the
    /// phase difference of two exits along `w` over `2 pi / lambda`.
    fn path_difference(
        &self,
        a: &crate::trace::Exit,
        b: &crate::trace::Exit,
        w: DVec3,
        n0: f64,
    ) -> f64 {
        match self.precision {
            PhasePrecision::F64 => (a.opl.re - b.opl.re) - n0 * w.dot(a.x - b.x),
            PhasePrecision::F32 => {
                let dx32 = (a.x.as_vec3() - b.x.as_vec3()).as_dvec3();
                f64::from((a.opl.re as f32 - b.opl.re as f32) - n0 as f32 * dot32(w, dx32))
            }
        }
    }

    /// Plane-wave limit (`rho = inf`): only exits whose directions agree to 1e-9
    /// interfere, fully. Such exits are grouped (sorted by hemisphere and direction,
    /// consecutive ones within 1e-9 of the group's first), and at each wavelength a group's
    /// amplitudes are summed coherently, `|sum_j a_j e^{i k delta_j}|^2`, which is the sum
    /// of its exits' powers and all its pairs' cross terms `c_jl` (docs/design.md §4) in O(n)
    /// rather than O(n^2): a flat stack's tree has all its exits in two groups.
    fn prepare_groups(&self, tree: &Tree, p: &mut Prepared) {
        let ex = &tree.exits;
        p.members.extend(0..ex.len() as u32);
        p.group_of.resize(ex.len(), 0);
        p.members.sort_unstable_by(|&a, &b| {
            let (a, b) = (&ex[a as usize], &ex[b as usize]);
            b.up.cmp(&a.up)
                .then(a.group.cmp(&b.group))
                .then(a.dir[0].total_cmp(&b.dir[0]))
                .then(a.dir[1].total_cmp(&b.dir[1]))
                .then(a.dir[2].total_cmp(&b.dir[2]))
        });
        let mut start = 0;
        while start < p.members.len() {
            let first = &ex[p.members[start] as usize];
            let mut end = start + 1;
            while end < p.members.len() {
                let e = &ex[p.members[end] as usize];
                if e.up != first.up
                    || e.group != first.group
                    || (e.dir - first.dir).dot(e.dir - first.dir).sqrt() > 1e-9
                {
                    break;
                }
                end += 1;
            }
            let n0 = if first.up { self.n_up } else { self.n_down };
            for &m in &p.members[start..end] {
                let delta = self.path_difference(&ex[m as usize], first, first.dir, n0);
                p.member_delta_nm.push(delta);
                p.group_of[m as usize] = start as u32;
            }
            if end - start > 1 {
                p.groups.push((start as u32, end as u32));
            }
            start = end;
        }
    }

    /// Plane-wave limit: the pairs of exits in different groups of which at least one is
    /// inhomogeneous. Their directional window is their amplitudes', not the beamlet's
    /// ([`directional_exponent`], finite however wide the beamlet), so they interfere in
    /// part, as they do at any finite radius; positions do not decorrelate (`k_pos = 1`).
    fn prepare_inhomogeneous_pairs(&self, tree: &Tree, p: &mut Prepared) {
        let ex = &tree.exits;
        if ex.iter().all(|x| x.n_im == DVec3::ZERO) {
            return;
        }
        let group = &p.group_of;
        for j in 0..ex.len() {
            for l in j + 1..ex.len() {
                let (a, b) = (&ex[j], &ex[l]);
                if (a.n_im == DVec3::ZERO && b.n_im == DVec3::ZERO)
                    || a.up != b.up
                    || a.group != b.group
                    || group[j] == group[l]
                {
                    continue;
                }
                let wbar = (a.dir + b.dir).normalize();
                let m2 = inhomogeneity(a, b, wbar);
                let n0 = if a.up { self.n_up } else { self.n_down };
                let (phase_nm, grow_nm, flux) = pair_terms(a, b, n0);
                let h = 0.5 * (hermitian(&a.e[0], &b.e[0]) + hermitian(&a.e[1], &b.e[1])) * flux;
                if (2.0 * h.norm() < NEGLIGIBLE_CROSS && grow_nm <= 0.0) || m2 == 0.0 {
                    continue;
                }
                p.pairs.push(Pair {
                    j: j as u32,
                    l: l as u32,
                    h,
                    delta_nm: self.path_difference(a, b, wbar, n0) + phase_nm,
                    k_pos: 1.0,
                    dw2: (a.dir - b.dir).length_squared(),
                    m2,
                    grow_nm,
                });
            }
        }
    }

    /// Deposits of the prepared tree at `lambda_nm` into `out` as `(key, fraction of
    /// launched power)`, several entries per key possible. For `Global` mode, fills
    /// `global` with `(key, amplitude)` instead; `entry_phase` is the incident wave's phase
    /// at the tree's launch point, `k n0 (d . x_entry)`.
    pub fn deposit(
        &self,
        tree: &Tree,
        lambda_nm: f64,
        entry_phase: f64,
        s: &mut Scratch,
        out: &mut Vec<(u32, f64)>,
        global: &mut Vec<(u32, [Field; 2])>,
    ) {
        let k = 2.0 * PI / lambda_nm;
        let p = &s.prep;
        debug_assert_eq!(p.keys.len(), tree.exits.len(), "prepare() the tree first");
        if self.mode == Coherence::Beamlet {
            // |a_j|^2 = P_j exp(-2 k Im OPL_j); c_jl = 2 Re(h e^{i k delta}) K e^{-k (Im_j + Im_l)}.
            let att = |j: usize| {
                if p.absorbing {
                    (-2.0 * k * p.im[j]).exp()
                } else {
                    1.0
                }
            };
            for j in 0..p.keys.len() {
                out.push((p.keys[j], p.pow[j] * att(j)));
            }
            for &(g0, g1) in &p.groups {
                let (g0, g1) = (g0 as usize, g1 as usize);
                let mut sum = [[C64::new(0.0, 0.0); 3]; 2];
                let mut incoherent = 0.0;
                for (m, &j) in p.members[g0..g1].iter().enumerate() {
                    let j = j as usize;
                    let mut f = C64::from_polar(1.0, k * p.member_delta_nm[g0 + m]);
                    if p.absorbing {
                        f *= (-k * p.im[j]).exp();
                    }
                    for (acc, e) in sum.iter_mut().zip(&tree.exits[j].e) {
                        for (a, c) in acc.iter_mut().zip(e) {
                            *a += c * f;
                        }
                    }
                    incoherent += p.pow[j] * att(j);
                }
                let cross = 0.5 * (field_power(&sum[0]) + field_power(&sum[1])) - incoherent;
                if incoherent > 0.0 {
                    for &j in &p.members[g0..g1] {
                        let j = j as usize;
                        out.push((p.keys[j], cross * p.pow[j] * att(j) / incoherent));
                    }
                }
            }
            let theta_w2 = (lambda_nm / (PI * self.rho_nm)).powi(2);
            if !self.reference {
                // The pair loop and its batches compiled for AVX2 where the CPU has it
                // (the same bits: `machine::with_avx2`).
                crate::machine::with_avx2(
                    #[inline(always)]
                    || self.deposit_pairs(k, theta_w2, s, out),
                );
                return;
            }
            for pr in &p.pairs {
                let (j, l) = (pr.j as usize, pr.l as usize);
                let mut kernel = pr.k_pos;
                if pr.m2 > 0.0 {
                    kernel *= directional_exponent(pr.dw2, pr.m2, k, self.rho_nm).exp();
                } else if pr.dw2 > 0.0 {
                    kernel *= (-pr.dw2 / (2.0 * theta_w2)).exp();
                }
                let (sn, cs) = (k * pr.delta_nm).sin_cos();
                kernel *= (k * pr.grow_nm).exp();
                let mut c = 2.0 * (pr.h.re * cs - pr.h.im * sn) * kernel;
                let (mut pj, mut pl) = (p.pow[j], p.pow[l]);
                if p.absorbing {
                    c *= (-k * (p.im[j] + p.im[l])).exp();
                    pj *= att(j);
                    pl *= att(l);
                }
                let tot = pj + pl;
                if tot > 0.0 {
                    out.push((p.keys[j], c * pj / tot));
                    out.push((p.keys[l], c * pl / tot));
                }
            }
            return;
        }
        // Each exit's amplitude with its phase relative to a plane through the global origin
        // perpendicular to its direction: `exp(i k (OPL - n0 w . x))` (a complex OPL
        // attenuates).
        s.amp.clear();
        for x in &tree.exits {
            let n0 = if x.up { self.n_up } else { self.n_down };
            let phase = match self.precision {
                PhasePrecision::F64 => k * (x.opl.re - n0 * x.dir.dot(x.x)),
                PhasePrecision::F32 => {
                    f64::from(k as f32 * (x.opl.re as f32 - n0 as f32 * dot32(x.dir, x.x)))
                }
            };
            let f = C64::from_polar((-k * x.opl.im).exp(), phase);
            s.amp.push([x.e[0].map(|c| c * f), x.e[1].map(|c| c * f)]);
        }
        match self.mode {
            Coherence::Beamlet | Coherence::Diffraction => unreachable!("handled above"),
            Coherence::Bucket => {
                // Gondek et al. / the seed: phases relative to a plane through the global
                // origin perpendicular to each exit direction, `exp(-i k n0 w . x)` with
                // absolute exit points, summed per bucket.
                s.sums.clear();
                for (j, a) in s.amp.iter().enumerate() {
                    match s.sums.iter_mut().find(|(kk, _)| *kk == p.keys[j]) {
                        Some((_, acc)) => add_fields(acc, a),
                        None => s.sums.push((p.keys[j], *a)),
                    }
                }
                for (kk, a) in &s.sums {
                    out.push((*kk, 0.5 * (field_power(&a[0]) + field_power(&a[1]))));
                }
            }
            Coherence::Global => {
                let f = C64::from_polar(1.0, entry_phase);
                for (a, &kk) in s.amp.iter().zip(&p.keys) {
                    global.push((kk, [a[0].map(|c| c * f), a[1].map(|c| c * f)]));
                }
            }
        }
    }
}

impl Estimator {
    /// The pairs' cross terms at wave number `k` (1/nm), the fast way: every pair's
    /// phase, and its directional overlap with the attenuation in one exponent, through
    /// the batched `phase` functions; each pair's term split between its two exits in
    /// proportion to their powers (as the reference does) and summed per exit, one deposit
    /// per exit rather than two per pair. The same sums as the reference to rounding
    /// (tests/estimator.rs).
    #[inline(always)]
    fn deposit_pairs(&self, k: f64, theta_w2: f64, s: &mut Scratch, out: &mut Vec<(u32, f64)>) {
        let Scratch {
            prep: p,
            phase: ph,
            sin,
            cos,
            arg,
            expv,
            att,
            exit_sum,
            ..
        } = s;
        let n = p.keys.len();
        ph.clear();
        ph.extend(p.pairs.iter().map(|pr| k * pr.delta_nm));
        phase::sin_cos_batch(ph, sin, cos);
        // Exponents: the directional kernel's, and the pair's attenuation.
        arg.clear();
        let two_theta_w2 = 2.0 * theta_w2;
        let rho = self.rho_nm;
        arg.extend(p.pairs.iter().map(|pr| {
            let mut a = if pr.m2 > 0.0 {
                directional_exponent(pr.dw2, pr.m2, k, rho)
            } else {
                -pr.dw2 / two_theta_w2
            };
            if p.absorbing {
                a -= k * (p.im[pr.j as usize] + p.im[pr.l as usize]);
            }
            // The amplitudes carried to the pair's midpoint ([`pair_terms`]).
            a + k * pr.grow_nm
        }));
        phase::exp_batch(arg, expv);
        // Each exit's attenuated power.
        att.clear();
        if p.absorbing {
            arg.clear();
            arg.extend(p.im.iter().map(|im| -2.0 * k * im));
            phase::exp_batch(arg, att);
            for (a, pw) in att.iter_mut().zip(&p.pow) {
                *a *= pw;
            }
        } else {
            att.extend_from_slice(&p.pow);
        }
        exit_sum.clear();
        exit_sum.resize(n, 0.0);
        for (i, pr) in p.pairs.iter().enumerate() {
            let (j, l) = (pr.j as usize, pr.l as usize);
            let c = 2.0 * (pr.h.re * cos[i] - pr.h.im * sin[i]) * (pr.k_pos * expv[i]);
            let (pj, pl) = (att[j], att[l]);
            let tot = pj + pl;
            if tot > 0.0 {
                exit_sum[j] += c * pj / tot;
                exit_sum[l] += c * pl / tot;
            }
        }
        for (j, &v) in exit_sum.iter().enumerate() {
            if v != 0.0 {
                out.push((p.keys[j], v));
            }
        }
    }
}

/// `acc += a` for the fields of both polarisations.
pub fn add_fields(acc: &mut [Field; 2], a: &[Field; 2]) {
    for (x, y) in acc.iter_mut().zip(a) {
        for (u, v) in x.iter_mut().zip(y) {
            *u += v;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The overlap of two Gaussian-windowed plane waves `exp(i k (dw + i M) x)` along one
    /// line, by brute-force quadrature over the window `exp(-x^2 / (2 s^2))` (trapezoids
    /// over +-12 s), normalised by the window's own integral: the exact overlap the
    /// estimator's directional kernel stands for.
    fn window_overlap(dw: f64, m: f64, k: f64, s: f64) -> C64 {
        let n = 40_001;
        let (mut num, mut den) = (C64::new(0.0, 0.0), 0.0);
        for i in 0..n {
            let x = (i as f64 / (n - 1) as f64 - 0.5) * 24.0 * s;
            let g = (-x * x / (2.0 * s * s)).exp();
            num += g * (C64::new(-k * m * x, k * dw * x)).exp();
            den += g;
        }
        num / den
    }

    /// Two inhomogeneous plane waves leaving into air (`N' . N'' = 0`, `|N'|^2 - |N''|^2 =
    /// 1`, directions 30 and 30.5 degrees, `|N''|` 0.1 and 0.2, both in the x-z plane):
    /// their normal Poynting flux by brute force, `Re[(E x conj(H))_z] / 2` with `E = sum
    /// E_j` and `H = sum N_j x E_j` (Maxwell's curl equation for a plane wave, in units of
    /// the vacuum impedance), normalised by a single wave's, against the estimator's pair
    /// sum of the exits' carried fields with [`pair_terms`]. s-polarised, `E_j = A_j y`;
    /// p-polarised, `E_j = A_j (y x N_j)` (transverse: `E . N = 0`), whose complex vector's
    /// `|E|^2` is `|A|^2 (|N'|^2 + |N''|^2)` while it carries `|A|^2 Re(q)`: the tracer
    /// writes such exits on the power basis (`fresnel::on_power_basis`). Without the flux
    /// factor, or for p without the power basis, the sum is off by more than 1e-2.
    #[test]
    fn the_pair_flux_factor_gives_the_poynting_flux_of_inhomogeneous_waves() {
        use crate::optics::fresnel::{Field, on_power_basis};
        let wave = |theta_deg: f64, g: f64| {
            let t = theta_deg.to_radians();
            let d = DVec3::new(t.sin(), 0.0, t.cos());
            let along = DVec3::new(t.cos(), 0.0, -t.sin());
            (d, d * (1.0 + g * g).sqrt(), along * g)
        };
        let cross = |a: [C64; 3], b: [C64; 3]| -> [C64; 3] {
            [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ]
        };
        let waves = [wave(30.0, 0.1), wave(30.5, 0.2)];
        let amps = [C64::new(1.0, 0.0), C64::from_polar(0.8, 0.7)];
        let nvec = |(_, re, im): (DVec3, DVec3, DVec3)| -> [C64; 3] {
            std::array::from_fn(|i| C64::new(re[i], im[i]))
        };
        let y = [C64::ZERO, C64::ONE, C64::ZERO];
        for p_polarised in [false, true] {
            let field = |j: usize| -> [C64; 3] {
                let unit = if p_polarised {
                    cross(y, nvec(waves[j]))
                } else {
                    y
                };
                unit.map(|c| c * amps[j])
            };
            let flux = |which: &[usize]| {
                let (mut e, mut h) = ([C64::ZERO; 3], [C64::ZERO; 3]);
                for &j in which {
                    let ej = field(j);
                    let hj = cross(nvec(waves[j]), ej);
                    for i in 0..3 {
                        e[i] += ej[i];
                        h[i] += hj[i];
                    }
                }
                let hc = h.map(|x| x.conj());
                0.5 * cross(e, hc)[2].re
            };
            // Each exit as the tracer leaves it: the field times `sqrt(Re q)`, then on the
            // power basis (or not).
            let exit = |j: usize, basis: bool| {
                let (d, re, im) = waves[j];
                let raw: Field = field(j).map(|c| c * re.z.sqrt());
                let e = if basis {
                    on_power_basis(&raw, re, im, 1.0)
                } else {
                    raw
                };
                crate::trace::Exit {
                    e: [e, e],
                    opl: C64::ZERO,
                    dir: d,
                    n_im: im,
                    x: DVec3::ZERO,
                    up: true,
                    group: 0,
                    tube: 1.0,
                    path: 0,
                }
            };
            // A single wave's flux per unit `|A|^2 Re(q)` (the common factor, 1/2).
            let unit = flux(&[0]) / (amps[0].norm_sqr() * waves[0].1.z);
            let brute = flux(&[0, 1]) / unit;
            let estimate = |basis: bool, with_factor: bool| {
                let (a, b) = (exit(0, basis), exit(1, basis));
                let h = hermitian(&a.e[0], &b.e[0]);
                let f = if with_factor {
                    pair_terms(&a, &b, 1.0).2
                } else {
                    C64::ONE
                };
                field_power(&a.e[0]) + field_power(&b.e[0]) + 2.0 * (h * f).re
            };
            let with = estimate(true, true);
            assert!(
                (with - brute).abs() < 1e-4 * brute,
                "p {p_polarised}: {with} against {brute}"
            );
            let without = estimate(true, false);
            assert!(
                (without - brute).abs() > 1e-2 * brute,
                "p {p_polarised}, no factor: {without} against {brute}"
            );
            let complex_p = estimate(false, true);
            if p_polarised {
                assert!(
                    (complex_p - brute).abs() > 1e-2 * brute,
                    "p on the complex vector: {complex_p} against {brute}"
                );
            } else {
                assert!(
                    (complex_p - with).abs() < 1e-12 * brute,
                    "s: the power basis changes nothing: {complex_p} against {with}"
                );
            }
        }
        // Homogeneous exits: the factor is 1.
        let bare = |dir: DVec3| crate::trace::Exit {
            e: [[C64::ZERO; 3]; 2],
            opl: C64::ZERO,
            dir,
            n_im: DVec3::ZERO,
            x: DVec3::ZERO,
            up: true,
            group: 0,
            tube: 1.0,
            path: 0,
        };
        let (c, d) = (bare(waves[0].0), bare(waves[1].0));
        assert_eq!(pair_terms(&c, &d, 1.0).2, C64::ONE);
    }

    /// Homogeneous exits: the beamlet's Gaussian overlap `exp(-|dw|^2 / (2 theta_w^2))`,
    /// `theta_w = lambda / (pi rho)` (docs/design.md §4), and the quadrature over `s = rho /
    /// 2`. Inhomogeneous exits: over the window `s = min(rho / 2, c / (k |M|))` the exact
    /// overlap's magnitude and phase are within `c^2 / 2` of the kernel (the factors the
    /// kernel leaves out), for gold-film-like pairs (`|M|` 1-10 times `|dw|`) and a ridge
    /// tip's (`|M| = 3`, `|dw| = 1`).
    #[test]
    fn the_directional_kernel_is_the_window_overlap_to_its_stated_order() {
        let (lambda, rho) = (550.0, 5000.0);
        let k = 2.0 * PI / lambda;
        for dw in [1e-4, 1e-3, 3e-3] {
            let kernel = directional_exponent(dw * dw, 0.0, k, rho).exp();
            let theta_w = lambda / (PI * rho);
            let closed = (-dw * dw / (2.0 * theta_w * theta_w)).exp();
            assert!((kernel - closed).abs() < 1e-12, "{kernel} {closed}");
            let exact = window_overlap(dw, 0.0, k, rho / 2.0);
            assert!((exact.norm() - kernel).abs() < 1e-9, "{exact} {kernel}");
        }
        let c = AMPLITUDE_WINDOW;
        for (dw, m) in [
            (0.01, 0.03),
            (0.05, 0.12),
            (0.02, 0.2),
            (1.0, 3.0),
            (1e-6, 1e-5),
        ] {
            let kernel = directional_exponent(dw * dw, m * m, k, rho).exp();
            let s = (rho / 2.0).min(c / (k * m));
            let exact = window_overlap(dw, m, k, s);
            assert!(
                (exact.norm() / kernel - 1.0).abs() <= c * c / 2.0 * 1.01
                    && exact.arg().abs() <= c * c,
                "dw {dw}, M {m}: window {s} nm, exact {exact}, kernel {kernel}"
            );
        }
    }
}
