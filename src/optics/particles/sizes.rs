//! Size distributions of a particle medium: the integrals over radius that set its
//! extinction, albedo and asymmetry, to a stated accuracy, and the radii a scattering event
//! draws its phase function from (docs/physics.md, "Particle media", size integrals).

use super::C64;
use super::ParticleError;
use crate::optics::mie::Mie;

/// The size integrals' tails: a log-normal distribution is integrated over `z = ln(r /
/// median) / sigma` in `[2 sigma - TAIL_Z, 3 sigma + TAIL_Z]`. The integrands that set the
/// medium are the number density times a volume (`r^3`: a normal density of `z` centred on
/// `3 sigma`) or a cross-section (`r^2` for spheres larger than the wavelength: centred on
/// `2 sigma`; steeper for Rayleigh spheres, whose upper tail is extended as needed), so each
/// leaves at most the normal tail beyond `TAIL_Z`, 1.0e-5 of its integral.
pub const TAIL_Z: f64 = 4.26;
/// The size integrals (`<C_ext>`, `<C_sca>`, `<g C_sca>`) are refined, halving the step in
/// `z` from 1/2, until each changes by less than this, relative (about the truncated
/// tails' 1e-5; the trapezoidal rule on a smooth integrand under a normal density converges
/// geometrically, so the error left is far below the last change).
pub const SIZE_TOLERANCE: f64 = 1e-5;
/// The first step in `z` (about 1/2) is halved at most this often (to about 1/128): a
/// distribution whose size integrals have not converged by then is refused (none does
/// among the sizes the loader accepts, the Mie ripple being averaged over the spread).
const FINEST_HALVINGS: u32 = 9;
/// A scattering event draws its radius from one per cell of this width in `ln r` (radii
/// 5 % apart), the integration node of the cell whose asymmetry is nearest the cell's,
/// standing for the cell's scattering: the extinction and albedo are the converged
/// integrals', and only the phase function is the mixture of these radii, so that the
/// envelopes, which cost `x^2` each, are built for tens of radii, not hundreds. The
/// mixture's `g` is within 1e-3 of the integral's in the tests (2e-7 to 1e-5 at sigma 0.25).
const SAMPLING_CELL_LN_R: f64 = 0.05;
/// The largest radius a size integral's tail may reach, nm, and the loader's largest
/// radius (`sample::resolve::media::PARTICLE_RADIUS_NM`).
pub const MAX_RADIUS_NM: f64 = 1e4;

/// The spheres' radius.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Radius {
    Fixed {
        radius_nm: f64,
    },
    /// `ln r` normal with median `median_nm` and standard deviation `sigma`, by number.
    LogNormal {
        median_nm: f64,
        sigma: f64,
    },
}

impl Radius {
    /// The radii the size integrals sample, nm (`[r, r]` for one size): what must lie in
    /// the loader's range. A Rayleigh tail may extend above it at set-up, and is refused
    /// there if it would pass the largest radius.
    pub fn span_nm(&self) -> [f64; 2] {
        match *self {
            Radius::Fixed { radius_nm } => [radius_nm, radius_nm],
            Radius::LogNormal { median_nm, sigma } => {
                let [lo, hi] = z_range(sigma);
                [
                    median_nm * (sigma * lo).exp(),
                    median_nm * (sigma * hi).exp(),
                ]
            }
        }
    }

    /// The mean volume of a sphere, nm^3: `4/3 pi r^3`, or for the log-normal by number
    /// `4/3 pi median^3 exp(9 sigma^2 / 2)` (the moment `<r^3> = median^3 exp(9 sigma^2 /
    /// 2)` of a log-normal; Aitchison & Brown 1957, eq. 2.8), over the whole distribution.
    pub fn mean_volume_nm3(&self) -> f64 {
        let v = |r: f64| 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
        match *self {
            Radius::Fixed { radius_nm } => v(radius_nm),
            Radius::LogNormal { median_nm, sigma } => v(median_nm) * (4.5 * sigma * sigma).exp(),
        }
    }
}

/// The range of `z = ln(r / median) / sigma` the size integrals start on ([`TAIL_Z`]).
fn z_range(sigma: f64) -> [f64; 2] {
    [2.0 * sigma - TAIL_Z, 3.0 * sigma + TAIL_Z]
}

/// A size integral at one wavelength: `<C_ext>`, `<C_sca>` and `<g C_sca>` (nm^2, per
/// particle), the last refinement's largest relative change, and the radii a scattering
/// event draws from, each with its Mie series and the scattering `w C_sca` it stands for.
pub(super) struct SizeIntegral {
    pub sums: [f64; 3],
    pub change: f64,
    pub sampling: Vec<(Mie, f64)>,
}

/// One radius of a size integral: the radius (nm), its quadrature weight (the number
/// density's share, so that `sum w C` is `<C>`), and its Mie coefficients.
struct SizeNode {
    r: f64,
    w: f64,
    mie: Mie,
}

impl SizeNode {
    /// `(w C_ext, w C_sca, w g C_sca)`, nm^2.
    fn moments(&self) -> [f64; 3] {
        let area = std::f64::consts::PI * self.r * self.r;
        let (e, s) = (self.mie.q_ext() * area, self.mie.q_sca() * area);
        [self.w * e, self.w * s, self.w * s * self.mie.g()]
    }
}

/// The nodes of the size integral at one wavelength (`k_host` 1/nm, relative index `m`):
/// one for a fixed radius; for a log-normal, the trapezoidal rule over `z` on the range of
/// [`z_range`] (its upper end raised a step at a time while a Rayleigh tail still carries more than
/// [`SIZE_TOLERANCE`] of `<C_ext>` per unit of `z`), its step halved from 1/2 until
/// `<C_ext>`, `<C_sca>` and `<g C_sca>` change by less than [`SIZE_TOLERANCE`]. Nested
/// steps reuse every series already summed.
pub(super) fn size_integral(
    radius: Radius,
    k_host: f64,
    m: C64,
    max_radius_nm: f64,
) -> Result<SizeIntegral, ParticleError> {
    let mie = |r: f64| Mie::new(m, k_host * r).map_err(|e| ParticleError::Invalid(e.to_string()));
    let (median, sigma) = match radius {
        Radius::Fixed { radius_nm } => {
            let node = SizeNode {
                r: radius_nm,
                w: 1.0,
                mie: mie(radius_nm)?,
            };
            let sums = node.moments();
            return Ok(SizeIntegral {
                sums,
                change: 0.0,
                sampling: vec![(node.mie, sums[1])],
            });
        }
        Radius::LogNormal { median_nm, sigma } => (median_nm, sigma),
    };
    let density = |z: f64| (-0.5 * z * z).exp() / (2.0 * std::f64::consts::PI).sqrt();
    let [lo, mut hi] = z_range(sigma);
    // The first step: the range in whole steps of about 1/2, each halved up to
    // FINEST_HALVINGS times; nodes are kept by their index on the finest grid.
    let first = (hi - lo) / ((hi - lo) / 0.5).ceil();
    let fine = first / f64::from(1u32 << FINEST_HALVINGS);
    let mut series: std::collections::BTreeMap<i64, (f64, Mie)> = Default::default();
    let mut at = |i: i64| -> Result<(f64, Mie), ParticleError> {
        if let Some(v) = series.get(&i) {
            return Ok(v.clone());
        }
        let z = lo + i as f64 * fine;
        let r = median * (sigma * z).exp();
        if r > max_radius_nm {
            return Err(ParticleError::Invalid(format!(
                "its size integral reaches radii above {max_radius_nm} nm (median {median} nm, sigma {sigma}) before the cross-sections' tail falls below {SIZE_TOLERANCE:e} of their integral"
            )));
        }
        let v = (r, mie(r)?);
        series.insert(i, v.clone());
        Ok(v)
    };
    let integrate = |step: i64,
                     hi: f64,
                     at: &mut dyn FnMut(i64) -> Result<(f64, Mie), ParticleError>|
     -> Result<(Vec<SizeNode>, [f64; 3]), ParticleError> {
        let n = ((hi - lo) / fine).round() as i64 / step;
        let h = step as f64 * fine;
        let mut nodes = Vec::with_capacity(n as usize + 1);
        let mut sums = [0.0; 3];
        for j in 0..=n {
            let (r, mie) = at(j * step)?;
            let end = if j == 0 || j == n { 0.5 } else { 1.0 };
            let z = lo + (j * step) as f64 * fine;
            let node = SizeNode {
                r,
                w: end * h * density(z),
                mie,
            };
            for (s, v) in sums.iter_mut().zip(node.moments()) {
                *s += v;
            }
            nodes.push(node);
        }
        Ok((nodes, sums))
    };
    let mut step = 1i64 << FINEST_HALVINGS;
    // The upper end: raised a step at a time while the last node's share of <C_ext> per
    // unit z is above the tolerance (spheres still in the Rayleigh regime there).
    loop {
        let (nodes, sums) = integrate(step, hi, &mut at)?;
        let last = nodes.last().expect("a node");
        if last.moments()[0] / last.w * density(hi) <= SIZE_TOLERANCE * sums[0] {
            break;
        }
        hi += first;
    }
    let (_, mut sums) = integrate(step, hi, &mut at)?;
    let mut change = f64::INFINITY;
    let mut finest = Vec::new();
    while step > 1 {
        step /= 2;
        let (nodes, s) = integrate(step, hi, &mut at)?;
        change = sums
            .iter()
            .zip(&s)
            .map(|(a, b)| (a - b).abs() / b.abs().max(1e-300))
            .fold(0.0, f64::max);
        sums = s;
        finest = nodes;
        if change <= SIZE_TOLERANCE {
            break;
        }
    }
    // The sampling radii: one per cell of SAMPLING_CELL_LN_R, the integration node whose
    // asymmetry is nearest the cell's (its nodes' g weighted by their scattering),
    // carrying the cell's scattering: the mixture keeps each cell's g up to that
    // difference, where one radius at the cell's centre would carry the Mie ripple of g.
    let s_step = ((SAMPLING_CELL_LN_R / (sigma * fine)).round() as i64).max(1);
    let mut cells: Vec<Vec<(usize, f64, f64)>> = Vec::new();
    for (j, node) in finest.iter().enumerate() {
        let c = ((j as i64 * step + s_step / 2) / s_step) as usize;
        if cells.len() <= c {
            cells.resize(c + 1, Vec::new());
        }
        let [_, w, wg] = node.moments();
        cells[c].push((j, w, if w > 0.0 { wg / w } else { 0.0 }));
    }
    let mut sampling = Vec::with_capacity(cells.len());
    for cell in cells.iter().filter(|c| !c.is_empty()) {
        let w: f64 = cell.iter().map(|x| x.1).sum();
        if w <= 0.0 {
            continue;
        }
        let g = cell.iter().map(|x| x.1 * x.2).sum::<f64>() / w;
        let &(j, _, gj) = cell
            .iter()
            .min_by(|a, b| (a.2 - g).abs().total_cmp(&(b.2 - g).abs()))
            .expect("a node");
        let mut best = (finest[j].mie.clone(), (gj - g).abs());
        // Between two neighbours whose g brackets the cell's, the radius where g would
        // meet it on a straight line in ln r, where that is nearer (a smooth g: few nodes).
        for pair in cell.windows(2) {
            let ((a, _, ga), (b, _, gb)) = (pair[0], pair[1]);
            if (ga - g) * (gb - g) < 0.0 {
                let t = (g - ga) / (gb - ga);
                let r = (finest[a].r.ln() * (1.0 - t) + finest[b].r.ln() * t).exp();
                let m = mie(r)?;
                let d = (m.g() - g).abs();
                if d < best.1 {
                    best = (m, d);
                }
            }
        }
        sampling.push((best.0, w));
    }
    Ok(SizeIntegral {
        sums,
        change,
        sampling,
    })
}
