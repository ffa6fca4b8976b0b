//! The diffraction method: physical optics on the ray field (docs/physics.md,
//! "Diffraction: physical optics on the ray field").
//!
//! The rays of every tree of one incident direction that leave into a lossless half-space
//! add as fields, not intensities. Each exit `j` stands for a ray tube whose field on the
//! exit plane is a local plane wave `a_j exp(i (psi_j + k_j . (x - x_j)))` over its
//! footprint, `psi_j` its phase at the exit point (incident phase at the launch point plus
//! `k Re OPL`). Under plane-wave illumination the field of a periodic tile is
//! pseudo-periodic, `u(x + L) = u(x) exp(i k_in . L)`, so the far field is a set of Floquet
//! orders `kappa_m = k_in + G_m`, `G_m = 2 pi (m_x / L_x, m_y / L_y)`, with amplitudes
//! `U_m = (1 / A) integral u(x) exp(-i kappa_m . x) dx` over the tile (the angular spectrum of
//! the exit-plane field: Goodman, Introduction to Fourier Optics, 3rd ed., §3.10; as in the
//! shooting-and-bouncing-rays method of Ling, Chou & Lee, IEEE TAP 37 (1989) 194, which
//! integrates physical-optics currents over each ray tube's footprint).
//!
//! Normalisation (derived in docs/physics.md): with power-normalised exit fields
//! (`|e_j|^2` is the tree's power fraction) and `N` trees spread uniformly over the tile,
//! a tube whose cross-section is `s_j` times the launched one has the footprint
//! `(A / N) s_j cos(theta_i) / cos(theta_j)` on the exit plane, so
//! `U_m = (1 / N) sum_j e_j sqrt(s_j) (cos theta_i / cos theta_j) exp(i (psi_j - kappa_m .
//! x_j)) S(kappa_m - k_j)` and the order carries the fraction `|U_m,perp|^2 cos(theta_m) /
//! cos(theta_i)` of the incident power. `S` is the footprint's transform: each tube is a
//! Gaussian patch (0.8 launch steps mapped by the tube's Jacobian, so neighbouring
//! patches sum to a uniform field to 6e-6). The sum is evaluated on a grid over the tile (the
//! patches splatted, then one FFT per field component): a non-uniform FFT of type 1 by
//! Gaussian gridding (Greengard & Lee, SIAM Review 46 (2004) 443), on a grid just fine enough
//! that no patch's spectrum folds onto a propagating order ([`period`]).
//!
//! Partial coherence: the illumination's transverse coherence is Gaussian with the coherence
//! radius `rho` (`|mu(dx)| = exp(-|dx|^2 / (2 rho^2))`), which is an incoherent spread of
//! plane waves whose transverse wave vectors have standard deviation `1 / rho` (Mandel &
//! Wolf, Optical Coherence and Quantum Optics, 1995, §5.6.4). Every order moves with the
//! incident wave vector (the grating equation), so the pattern is the coherent one
//! convolved with that spread; it is deposited through a 5 x 5 Gauss-Hermite rule over the
//! spread. `rho = inf` deposits each order in the bucket of its direction.

use super::buckets::SineIndex;
use super::patch::{CHUNK, POINT_MASS, Patches, Spec};
use super::tube::cos_of;
pub use super::tube::{
    Contribution, Launches, SharedExit, TubeShape, contribution, contribution_at, exit_phase,
    tube_shapes,
};
use super::{Buckets, key};
use crate::optics::C64;
use crate::optics::fresnel::field_power;
use crate::optics::mueller::{self, Jones, Mueller};
use rustfft::FftPlanner;
use std::f64::consts::PI;

/// The largest grid (cells) one hemisphere's field may use at one wavelength: 2^24 cells
/// of 16 bytes, 256 MiB, per field component.
pub const MAX_GRID_CELLS: usize = 1 << 24;

/// Grid cells `[x, y]` over the tile for one hemisphere at `lambda_nm`, for trees on the
/// launch lattice `lattice`, whatever directions the tubes take: the most [`diffract`] can
/// use (its grid is sized by the tubes' own directions, [`period`]), so a run's memory is
/// checked against it before any tracing.
pub fn grid_cells(tile_nm: [f64; 2], lambda_nm: f64, n_out: f64, lattice: [u64; 2]) -> [usize; 2] {
    let kn = 2.0 * PI / lambda_nm * n_out;
    let p = 2.0 * kn + ALIAS_MARGIN / patch_sigma_nm(tile_nm, lattice);
    cells_for(tile_nm, kn, [p, p])
}

/// Cells `[x, y]` for the grid periods `p` (1/nm, in `G`, per axis): `p L / (2 pi)` cells
/// over a tile side `L`, and at least the disk of propagating orders' width plus three, so
/// the window [`far_field`] reads (centred on `-k_in`, rounded to an order) holds every
/// propagating order.
fn cells_for(tile_nm: [f64; 2], kn: f64, p: [f64; 2]) -> [usize; 2] {
    let axis = |a: usize| {
        let per_order = 2.0 * PI / tile_nm[a];
        let need = (p[a] / per_order).ceil();
        let disk = (2.0 * kn / per_order).ceil() + 3.0;
        need.max(disk).max(1.0) as usize
    };
    [axis(0), axis(1)]
}

/// A tube's patch at launch, as a standard deviation in launch steps: a lattice of such
/// Gaussians is uniform to `2 exp(-2 pi^2 0.8^2) = 6e-6` (Poisson summation), so a flat
/// sample's spurious orders carry 4e-11 of its power.
const PATCH_SIGMA_STEPS: f64 = 0.8;

/// How far, in standard deviations of a patch's spectrum, its aliases stay from every
/// propagating order ([`period`]): there the spectrum is down to `exp(-8) = 3.4e-4` in
/// amplitude, `1.1e-7` in power, and only at the horizon.
const ALIAS_MARGIN: f64 = 4.0;

/// The smallest standard deviation of an unmapped patch, nm.
fn patch_sigma_nm(tile_nm: [f64; 2], lattice: [u64; 2]) -> f64 {
    PATCH_SIGMA_STEPS * (tile_nm[0] / lattice[0] as f64).min(tile_nm[1] / lattice[1] as f64)
}

/// The grid's period in `G` per axis, 1/nm, for these tubes. The gridded field carries the
/// incident wave's transverse phase removed, so a tube leaving along `w` is a patch whose
/// spectrum is a Gaussian of standard deviation `1 / sigma` about `G = k n_out w_t - k_in`,
/// and the propagating orders are the disk `|k_in + G| < k n_out`. Sampling on a grid of
/// spacing `dx` folds the spectrum by the period `P = 2 pi / dx` (Goodman, Introduction to
/// Fourier Optics, 3rd ed., §2.4), so along an axis a tube's folded copy lies at least `P -
/// k n_out (1 + |w_t|)` from the disk. That distance is made `M_t / sigma`, with `M_t` the
/// margin for the tube's strength ([`alias_margin`]) and `sigma` the unmapped patch's
/// ([`patch_sigma_nm`]): `P = max over tubes of k n_out (1 + |w_t|) + M_t / sigma`, and at
/// least `2 k n_out`, the disk's width, which the window of orders read must hold.
///
/// (Until 2026-12-06 every tube was taken to leave at the horizon, `P = 2 k n_out + 4 /
/// sigma` on both axes; a sample whose light leaves near the normal needs about two thirds
/// of the cells a patch took then. Before issue 31 the spacing was `lambda / (4 (n_out +
/// n_in))` whatever the patch: 1.2 to 2.6 times as many cells per patch at 16,384 trees on
/// 20 um, 380-780 nm.)
fn period(h: &Hemisphere, tubes: impl Iterator<Item = ([f64; 2], f64)>) -> [f64; 2] {
    let kn = 2.0 * PI / h.lambda_nm * h.n_out;
    let inv_sigma = 1.0 / patch_sigma_nm(h.tile_nm, h.lattice);
    let mut p = [2.0 * kn; 2];
    for (w, mass) in tubes {
        let margin = alias_margin(mass) * inv_sigma;
        for (a, pa) in p.iter_mut().enumerate() {
            *pa = pa.max(kn * (1.0 + w[a].abs()) + margin);
        }
    }
    p
}

/// The margin, in standard deviations of a patch's spectrum, by which the folded copy of a
/// tube of mass `m` (`patch::radius`) stays off the propagating orders: [`ALIAS_MARGIN`] for
/// a tube as strong as the incident wave or stronger, and for a weaker one where its copy
/// falls to the same absolute level, `m exp(-M^2 / 2) = exp(-ALIAS_MARGIN^2 / 2)` (0 for a
/// tube already weaker than that level: its copy's peak is below it), as its patch is cut.
fn alias_margin(m: f64) -> f64 {
    if m >= 1.0 || m.is_nan() {
        return ALIAS_MARGIN;
    }
    (ALIAS_MARGIN * ALIAS_MARGIN + 2.0 * m.ln()).max(0.0).sqrt()
}

/// What one hemisphere of one wavelength diffracted into.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Pattern {
    /// Power fraction per bucket key of this hemisphere (`key(b, down)`), every bucket.
    pub per_key: Vec<(u32, f64)>,
    /// Sum over propagating orders: the hemisphere's diffracted reflectance or
    /// transmittance.
    pub total: f64,
    /// Propagating orders with any power.
    pub orders: usize,
    /// Tubes whose shape came from the tracked cross-section because no neighbouring tree
    /// had the same exit, and tubes that passed a line focus.
    pub fallback_tubes: usize,
    pub flipped_tubes: usize,
    /// With [`Hemisphere::mueller`]: each bucket key's Mueller matrix as a power fraction,
    /// its `m00` the very value of `per_key`, in the same order (empty otherwise).
    pub per_key_mueller: Vec<Mueller>,
}

/// The settings of one hemisphere's transform.
#[derive(Clone, Copy, Debug)]
pub struct Hemisphere {
    pub tile_nm: [f64; 2],
    pub lambda_nm: f64,
    /// Real index of the half-space the light leaves into.
    pub n_out: f64,
    /// Transverse incident wave vector, 1/nm.
    pub k_in: [f64; 2],
    pub cos_i: f64,
    /// The launch lattice, `[nx, ny]` trees (`simulate::diffraction_lattice`); tree `i` sits
    /// at cell `(i mod nx, i div nx)`.
    pub lattice: [u64; 2],
    /// Transverse coherence radius, nm (`inf`: plane-wave illumination).
    pub rho_nm: f64,
    pub down: bool,
    /// Also each order's Mueller matrix (`--mueller`): its Jones matrix from the two
    /// incident polarisations' order amplitudes in the order's s/p frame
    /// (`optics::mueller`), spread as its power is.
    pub mueller: bool,
}

impl Hemisphere {
    /// Where its tubes were launched, and which way they leave ([`tube_shapes`]).
    pub fn launches(&self) -> Launches {
        Launches {
            tile_nm: self.tile_nm,
            lattice: self.lattice,
            cos_i: self.cos_i,
            down: self.down,
        }
    }
}

/// Probabilists' Gauss-Hermite rule of 5 points for a standard normal variable (nodes
/// `0, +-sqrt(5 - sqrt 10), +-sqrt(5 + sqrt 10)`; Abramowitz & Stegun 25.4.46 rescaled).
const GH5: [(f64, f64); 5] = [
    (-2.856_970_013_872_805_6, 0.011_257_411_327_720_69),
    (-1.355_626_179_974_266, 0.222_075_922_005_612_6),
    (0.0, 0.533_333_333_333_333_3),
    (1.355_626_179_974_266, 0.222_075_922_005_612_6),
    (2.856_970_013_872_805_6, 0.011_257_411_327_720_69),
];

/// The orders of one hemisphere from its contributions (in tree order: the sums are the
/// same bits whatever produced them), deposited into `buckets`. `shapes`, where given, are
/// [`tube_shapes`] of these contributions' geometry (the same at every wavelength under
/// path sharing, so found once); otherwise they are found here.
pub fn diffract(
    h: &Hemisphere,
    contribs: &[Contribution],
    shapes: Option<&[TubeShape]>,
    buckets: &Buckets,
    scratch: &mut Scratch,
) -> Result<Pattern, DiffractionError> {
    let found;
    let shapes = match shapes {
        Some(s) => s,
        None => {
            found = tube_shapes(&h.launches(), contribs);
            &found[..]
        }
    };
    let tubes = contribs.iter().filter(|c| c.down == h.down);
    debug_assert_eq!(tubes.clone().count(), shapes.len(), "one shape per tube");
    // Each tube's amplitude and mass, found once for the grid and the splat, with its
    // direction: the grid's period is found from these, not from another pass over the
    // contributions (160 bytes a tube; each pass over a wavelength's 137,000 was 22 MB).
    let mut foot = std::mem::take(&mut scratch.foot);
    foot.clear();
    foot.extend(tubes.clone().zip(shapes).map(|(c, s)| {
        let (amp, mass) = footprint(h, c, s);
        (amp, mass, c.w)
    }));
    assert_eq!(foot.len(), shapes.len(), "one shape per tube");
    let p = period(h, foot.iter().map(|f| (f.2, f.1)));
    let kn = 2.0 * PI / h.lambda_nm * h.n_out;
    let [mx, my] = cells_for(h.tile_nm, kn, p);
    if mx.saturating_mul(my) > MAX_GRID_CELLS {
        return Err(DiffractionError::GridTooLarge {
            cells: [mx, my],
            tile_nm: h.tile_nm,
            lambda_nm: h.lambda_nm,
        });
    }
    let flagged = exit_plane_field(
        h,
        tubes.zip(shapes).zip(foot.iter().map(|f| (f.0, f.1))),
        [mx, my],
        scratch,
    );
    scratch.foot = foot;
    let (fallback, flipped) = flagged;
    let grids = &mut scratch.grids;
    fft2(grids, [mx, my], &mut scratch.fft);
    let (per_bucket, per_bucket_m, total, orders) = far_field(h, grids, [mx, my], buckets);
    Ok(Pattern {
        fallback_tubes: fallback,
        flipped_tubes: flipped,
        ..pattern(&per_bucket, &per_bucket_m, h.down, total, orders)
    })
}

/// A tube's patch amplitude on the exit plane, `sqrt(f cos theta_i / cos theta_j)` with `f
/// = |det J|` its footprint's area per launch area, and its mass: that times its stronger
/// polarisation's field, against the incident wave's share of one tree (which sets where
/// its patch is cut, `patch::radius`, and how far its folded copy must stay off the
/// orders, [`alias_margin`]).
fn footprint(h: &Hemisphere, c: &Contribution, shape: &TubeShape) -> (f64, f64) {
    let jac = shape.jac;
    let det = jac[0][0] * jac[1][1] - jac[0][1] * jac[1][0];
    let amp = (det.abs().max(1e-12) * h.cos_i / cos_of(c)).sqrt();
    let mass = amp * field_power(&c.a[0]).max(field_power(&c.a[1])).sqrt();
    (amp, mass)
}

/// A hemisphere's pattern from its per-bucket powers (and Mueller matrices, where kept):
/// the buckets that hold any.
fn pattern(
    per_bucket: &[f64],
    per_bucket_m: &[Mueller],
    down: bool,
    total: f64,
    orders: usize,
) -> Pattern {
    let kept: Vec<usize> = (0..per_bucket.len())
        .filter(|&b| per_bucket[b] != 0.0)
        .collect();
    Pattern {
        per_key: kept
            .iter()
            .map(|&b| (key(b, down), per_bucket[b]))
            .collect(),
        per_key_mueller: if per_bucket_m.is_empty() {
            Vec::new()
        } else {
            kept.iter().map(|&b| per_bucket_m[b]).collect()
        },
        total,
        orders,
        fallback_tubes: 0,
        flipped_tubes: 0,
    }
}

/// The pattern of plane-wave orders given directly (the rigorous solver's): each order's
/// travel direction (unit; its transverse part the direction sines) and Jones matrix
/// scaled to efficiencies (`optics::rcwa::Order::jones`), spread by the illumination's
/// partial coherence as the diffraction method spreads its orders (`spread`, with `kn` the
/// wave number in the half-space the orders travel in, 1/nm). Each order's unpolarised
/// power is its Mueller matrix's `m00`, so the matrices' `m00` are the powers' bits.
pub fn pattern_of_orders(
    orders: impl Iterator<Item = (glam::DVec3, Jones)>,
    buckets: &Buckets,
    kn: f64,
    rho_nm: f64,
    down: bool,
    with_mueller: bool,
) -> Pattern {
    let sigma_s = if rho_nm.is_finite() {
        1.0 / (kn * rho_nm)
    } else {
        0.0
    };
    let finder = SineIndex::new(buckets);
    // Each spread node's last bucket: the next order's node is near it.
    let mut near = [[0u32; 2]; 25];
    let mut per_bucket = vec![0.0; buckets.len()];
    let mut per_bucket_m = if with_mueller {
        vec![[0.0; 16]; buckets.len()]
    } else {
        Vec::new()
    };
    let (mut total, mut count) = (0.0, 0);
    for (dir, j) in orders {
        let m = mueller::mueller(&j);
        let p = m[0];
        if p <= 0.0 {
            continue;
        }
        count += 1;
        total += p;
        let s = [dir.x, dir.y];
        spread(&finder, s, sigma_s, &mut near, |b, w, wsum| {
            per_bucket[b] += p * w / wsum;
        });
        if with_mueller {
            spread(&finder, s, sigma_s, &mut near, |b, w, wsum| {
                for (a, x) in per_bucket_m[b].iter_mut().zip(&m) {
                    *a += x * w / wsum;
                }
            });
        }
    }
    pattern(&per_bucket, &per_bucket_m, down, total, count)
}

/// Why the transform cannot run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DiffractionError {
    #[error(
        "the diffraction method needs a {} x {} grid over the {:.0} x {:.0} nm tile at {lambda_nm} nm (more than {MAX_GRID_CELLS} cells): use a smaller tile (a period or a few correlation lengths; features this large against the wavelength are where rays alone hold)",
        cells[0], cells[1], tile_nm[0], tile_nm[1]
    )]
    GridTooLarge {
        cells: [usize; 2],
        tile_nm: [f64; 2],
        lambda_nm: f64,
    },
}

/// The exit-plane field of every tube leaving into hemisphere `h`, gridded on `mx x my`
/// cells: six grids (two polarisations x three components), each tube a Gaussian patch
/// carrying its field and the plane wave's phase (each tube with its [`footprint`]). Also the tubes whose shape came from
/// their own tracked cross-section (no neighbour on the same exit) and the mirrored ones.
fn exit_plane_field<'a>(
    h: &Hemisphere,
    tubes: impl Iterator<Item = ((&'a Contribution, &'a TubeShape), (f64, f64))>,
    [mx, my]: [usize; 2],
    scratch: &mut Scratch,
) -> (usize, usize) {
    let (dx, dy) = (h.tile_nm[0] / mx as f64, h.tile_nm[1] / my as f64);
    let k = 2.0 * PI / h.lambda_nm;
    let kn = k * h.n_out;
    let [nx, ny] = h.lattice;
    let n_trees = (nx * ny) as usize;
    // Launch steps, nm; each tube starts as a Gaussian of `PATCH_SIGMA_STEPS` steps and is
    // mapped to the exit plane by its Jacobian.
    let step = [h.tile_nm[0] / nx as f64, h.tile_nm[1] / ny as f64];
    let sig0 = [PATCH_SIGMA_STEPS * step[0], PATCH_SIGMA_STEPS * step[1]];
    // The six components of a cell side by side (re, im of each), so a patch cell is one
    // contiguous update; split into six grids for the transforms at the end.
    let Scratch {
        cells,
        grids,
        patches,
        ..
    } = scratch;
    cells.clear();
    cells.resize(mx * my, [0.0; 12]);
    let (mut fallback, mut flipped) = (0usize, 0usize);
    // Tubes a chunk at a time: laid out, their first cells evaluated in one batch, then
    // splatted (`patch::Patches`).
    let mut tubes = tubes.peekable();
    let mut chunk = Vec::with_capacity(CHUNK);
    while tubes.peek().is_some() {
        patches.start([dx, dy], [mx, my]);
        chunk.clear();
        for ((c, shape), (amp, mass)) in tubes.by_ref().take(CHUNK) {
            let jac = shape.jac;
            fallback += usize::from(shape.fallback);
            // A tube reflected an even number of times by crossed facets comes out
            // mirrored, det < 0: counted, not a focus.
            if jac[0][0] * jac[1][1] - jac[0][1] * jac[1][0] < 0.0 {
                flipped += 1;
            }
            // Covariance of the mapped patch, J diag(sig0^2) J^T, at least half a cell.
            let floor = 0.25 * dx.max(dy).powi(2);
            let (s0, s1) = (sig0[0].powi(2), sig0[1].powi(2));
            let cxx = jac[0][0].powi(2) * s0 + jac[0][1].powi(2) * s1 + floor;
            let cyy = jac[1][0].powi(2) * s0 + jac[1][1].powi(2) * s1 + floor;
            let cxy = jac[0][0] * jac[1][0] * s0 + jac[0][1] * jac[1][1] * s1;
            let cdet = cxx * cyy - cxy * cxy;
            let spec = Spec {
                inv: [cyy / cdet, cxx / cdet, -cxy / cdet],
                sx: cxx.sqrt(),
                radius: super::patch::radius(mass),
                q: [kn * c.w[0] - h.k_in[0], kn * c.w[1] - h.k_in[1]],
                xw: [
                    c.x[0].rem_euclid(h.tile_nm[0]),
                    c.x[1].rem_euclid(h.tile_nm[1]),
                ],
            };
            if mass < POINT_MASS {
                patches.push_point(spec);
            } else {
                patches.push(spec);
            }
            chunk.push((c, amp));
        }
        debug_assert_eq!(patches.len(), chunk.len());
        patches.evaluate();
        for (i, &(c, amp)) in chunk.iter().enumerate() {
            if let Some((at, w)) = patches.point(i) {
                let scale = amp / n_trees as f64;
                for (&cell, w) in at.iter().zip(w) {
                    let w = w * scale;
                    let cell = &mut cells[cell];
                    for (comp, v) in c.a.iter().flatten().enumerate() {
                        let z = v * w;
                        cell[2 * comp] += z.re;
                        cell[2 * comp + 1] += z.im;
                    }
                }
                continue;
            }
            let rows = patches.patch(i);
            let sum = rows.sum();
            // Normalised by its discrete sum, so the tube's own direction gets exactly its
            // field (neither truncation nor the grid's sampling of the Gaussian enters).
            let scale = amp / (n_trees as f64 * sum);
            let a = [c.a[0].map(|v| v * scale), c.a[1].map(|v| v * scale)];
            rows.splat(cells, a);
        }
    }
    grids.resize_with(6, Vec::new);
    for (comp, g) in grids.iter_mut().enumerate() {
        g.clear();
        g.extend(cells.iter().map(|v| C64::new(v[2 * comp], v[2 * comp + 1])));
    }
    (fallback, flipped)
}

/// The buffers one thread's transforms reuse from wavelength to wavelength: the gridded
/// field in both layouts and a patch's rows. (Allocated afresh for every transform, the
/// grids' pages were faulted in each time: 5 % of a diffraction run.)
#[derive(Default)]
pub struct Scratch {
    cells: Vec<[f64; 12]>,
    grids: Vec<Vec<C64>>,
    patches: Patches,
    /// Each tube's [`footprint`].
    foot: Vec<(f64, f64, [f64; 2])>,
    /// The FFTs' plans (kept: planning a prime length, as Rader's algorithm, was about 1 %
    /// of a run made anew for every transform) and their buffers.
    fft: Ffts,
}

/// [`fft2`]'s plans, kept from transform to transform, and its buffers.
#[derive(Default)]
pub(super) struct Ffts {
    planner: Option<FftPlanner<f64>>,
    columns: Vec<C64>,
    work: Vec<C64>,
}

/// One 2-D forward FFT per grid, in place: `V_m = sum_g v(x_g) exp(-i G_m . x_g)`. The
/// rows are transformed in one call, then the columns, gathered side by side.
fn fft2(grids: &mut [Vec<C64>], [mx, my]: [usize; 2], ffts: &mut Ffts) {
    let planner = ffts.planner.get_or_insert_with(FftPlanner::new);
    let fx = planner.plan_fft_forward(mx);
    let fy = planner.plan_fft_forward(my);
    let zero = C64::new(0.0, 0.0);
    let scratch = fx
        .get_inplace_scratch_len()
        .max(fy.get_inplace_scratch_len());
    ffts.work.resize(scratch, zero);
    ffts.columns.resize(mx * my, zero);
    for g in grids.iter_mut() {
        let g = &mut g[..mx * my];
        fx.process_with_scratch(g, &mut ffts.work);
        for (iy, row) in g.chunks_exact(mx).enumerate() {
            for (ix, v) in row.iter().enumerate() {
                ffts.columns[ix * my + iy] = *v;
            }
        }
        fy.process_with_scratch(&mut ffts.columns, &mut ffts.work);
        for (iy, row) in g.chunks_exact_mut(mx).enumerate() {
            for (ix, v) in row.iter_mut().enumerate() {
                *v = ffts.columns[ix * my + iy];
            }
        }
    }
}

/// The propagating Floquet orders of the transformed grids: each order's power (the
/// field's part transverse to its direction, per unit incident power), spread over the
/// buckets by the illumination's angular spread. Returns the power per bucket, with
/// [`Hemisphere::mueller`] each bucket's Mueller matrix (empty otherwise), the total and
/// the number of orders that carry power.
fn far_field(
    h: &Hemisphere,
    grids: &[Vec<C64>],
    [mx, my]: [usize; 2],
    buckets: &Buckets,
) -> (Vec<f64>, Vec<Mueller>, f64, usize) {
    let kn = 2.0 * PI / h.lambda_nm * h.n_out;
    // FFT bin `i` holds every order `m = i (mod cells)`; the one read is the `m` in the
    // window of `cells` orders centred on `-k_in`, which holds the disk of propagating
    // orders (see `period`).
    let window = |axis: usize, cells: usize| -> i64 {
        let centre = (-h.k_in[axis] * h.tile_nm[axis] / (2.0 * PI)).round() as i64;
        centre - (cells / 2) as i64
    };
    let (lo_x, lo_y) = (window(0, mx), window(1, my));
    let order = |i: usize, lo: i64, cells: usize| -> f64 {
        (lo + (i as i64 - lo).rem_euclid(cells as i64)) as f64
    };
    let sigma_s = if h.rho_nm.is_finite() {
        1.0 / (kn * h.rho_nm)
    } else {
        0.0
    };
    let finder = SineIndex::new(buckets);
    // Each spread node's last bucket: the next order's node is near it.
    let mut near = [[0u32; 2]; 25];
    let mut per_bucket = vec![0.0; buckets.len()];
    let mut per_bucket_m = if h.mueller {
        vec![[0.0; 16]; buckets.len()]
    } else {
        Vec::new()
    };
    let mut total = 0.0;
    let mut orders = 0;
    for iy in 0..my {
        let ky = h.k_in[1] + 2.0 * PI * order(iy, lo_y, my) / h.tile_nm[1];
        for ix in 0..mx {
            let kx = h.k_in[0] + 2.0 * PI * order(ix, lo_x, mx) / h.tile_nm[0];
            let s = [kx / kn, ky / kn];
            let s2 = s[0] * s[0] + s[1] * s[1];
            if s2 >= 1.0 {
                continue; // evanescent: no power leaves
            }
            let cz = (1.0 - s2).sqrt();
            let w = [s[0], s[1], if h.down { -cz } else { cz }];
            let cell = iy * mx + ix;
            let mut p = 0.0;
            let mut perps = [[C64::new(0.0, 0.0); 3]; 2];
            for (pol, perp) in perps.iter_mut().enumerate() {
                let u = [
                    grids[pol * 3][cell],
                    grids[pol * 3 + 1][cell],
                    grids[pol * 3 + 2][cell],
                ];
                let along = u[0] * w[0] + u[1] * w[1] + u[2] * w[2];
                *perp = [
                    u[0] - along * w[0],
                    u[1] - along * w[1],
                    u[2] - along * w[2],
                ];
                p += 0.5 * field_power(perp);
            }
            let p = p * cz / h.cos_i;
            if p <= 0.0 {
                continue;
            }
            orders += 1;
            total += p;
            spread(&finder, s, sigma_s, &mut near, |b, w, wsum| {
                per_bucket[b] += p * w / wsum;
            });
            if h.mueller {
                // The order's Jones matrix in its own s/p frame, scaled to power fractions;
                // its m00 set to the order's power itself, so the spread matrices' m00 are
                // the per-bucket powers' very bits.
                let wv = glam::DVec3::from_array(w);
                let mut m = mueller::mueller(&mueller::jones(&perps, wv)).map(|x| x * cz / h.cos_i);
                m[0] = p;
                spread(&finder, s, sigma_s, &mut near, |b, w, wsum| {
                    for (a, x) in per_bucket_m[b].iter_mut().zip(&m) {
                        *a += x * w / wsum;
                    }
                });
            }
        }
    }
    (per_bucket, per_bucket_m, total, orders)
}

/// Spreads the order at transverse direction `s` by the illumination's angular spread
/// `sigma_s` (standard deviation of each transverse component), through the 5 x 5
/// Gauss-Hermite rule: `add(bucket, w, wsum)` for each node's bucket, its share `w / wsum`
/// of the nodes within the horizon (`(1, 1)` for a single direction). `near` holds each
/// node's bucket for the order before, where its search starts (`SineIndex::index_near`).
fn spread(
    finder: &SineIndex,
    s: [f64; 2],
    sigma_s: f64,
    near: &mut [[u32; 2]; 25],
    mut add: impl FnMut(usize, f64, f64),
) {
    if sigma_s == 0.0 {
        add(finder.index_near(s, &mut near[12]), 1.0, 1.0);
        return;
    }
    let mut nodes = [(0usize, 0.0f64); 25];
    let mut n = 0;
    let mut wsum = 0.0;
    for (i, &(a, wa)) in GH5.iter().enumerate() {
        for (j, &(b, wb)) in GH5.iter().enumerate() {
            let t = [s[0] + sigma_s * a, s[1] + sigma_s * b];
            if t[0] * t[0] + t[1] * t[1] < 1.0 {
                nodes[n] = (finder.index_near(t, &mut near[5 * i + j]), wa * wb);
                wsum += wa * wb;
                n += 1;
            }
        }
    }
    if n == 0 {
        add(finder.index(s), 1.0, 1.0);
        return;
    }
    for &(b, w) in &nodes[..n] {
        add(b, w, wsum);
    }
}

#[cfg(test)]
mod tests;
