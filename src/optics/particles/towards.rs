//! Next-event estimation's view of a scattering event: the fields the sampler would give
//! a chosen direction, weighted by the density of drawing it.

use glam::DVec3;

use super::{LambdaEntry, ScatterModel, SizeEntry, combine, hg_density};
use crate::geom::frame;
use crate::optics::C64;
use crate::optics::fresnel::{Field, field_dot_real};
use crate::rng::Rng;

impl ScatterModel {
    /// Next-event estimation (docs/physics.md, "Next-event estimation"): the fields that
    /// [`ScatterModel::scatter`] gives a wave along `d` with fields `e` when it draws the
    /// direction `w` (unit), each multiplied by `sqrt(q(w))`, `q` the sampler's probability
    /// density of `w` per steradian. Their power summed over the two polarisations is then
    /// `albedo P_in q(w)`: the expected power scattered towards `w` per steradian.
    ///
    /// For Mie particles, `q(w) = sum_pol |S e_pol|^2 F(theta) / (P_in 2 pi N_k)` for the
    /// size `k` drawn as `scatter` draws it (one uniform from `rng`; the mixture over sizes
    /// is then unbiased), `S` the amplitude matrix (Bohren & Huffman 1983, eq. 3.12), `F`
    /// the structure factor the sampler uses and `N_k = int f S dtheta` (`SizeEntry::norm`):
    /// the sampler draws theta by `f S` and phi by `sum_pol |S e_pol|^2` at that theta, and
    /// scales the fields to `albedo P_in` in all. So the fields are `S e_pol sqrt(albedo F /
    /// (2 pi N_k))`. For Henyey-Greenstein, the rotated fields times `sqrt(albedo
    /// p_HG(cos theta) / (2 pi))`.
    pub fn scatter_towards(
        &self,
        lambda_nm: f64,
        d: DVec3,
        e: &[Field; 2],
        w: DVec3,
        rng: &mut Rng,
    ) -> [Field; 2] {
        let mu = d.dot(w).clamp(-1.0, 1.0);
        // The scattering plane's normal: e_perp = (w x d) / |w x d|, any normal to d when
        // w is along it.
        let c = w.cross(d);
        let e_perp = if c.length_squared() > 1e-24 {
            c.normalize()
        } else {
            frame(d).1
        };
        let (par_in, par_out) = (e_perp.cross(d), e_perp.cross(w));
        let (amp1, amp2, scale) = match self {
            ScatterModel::HenyeyGreenstein { g, .. } => {
                let (_, albedo) = self.coefficients(lambda_nm);
                let one = C64::new(1.0, 0.0);
                let q = hg_density(*g, mu) / std::f64::consts::TAU;
                (one, one, (albedo * q).sqrt())
            }
            ScatterModel::Mie { .. } => {
                let t = self.entry(lambda_nm).expect("a tabulated wavelength");
                let size = t.draw_size(rng.uniform());
                let (s1, s2) = size.mie.s1_s2(mu);
                (s2, s1, t.weight(size, mu).sqrt())
            }
        };
        e.map(|f| {
            let (ep, es) = (field_dot_real(&f, par_in), field_dot_real(&f, e_perp));
            combine(amp1 * ep * scale, par_out, amp2 * es * scale, e_perp)
        })
    }
}

/// Points of each half of the size-averaged coherency table ([`Coherency`]): the forward
/// half equally spaced in `sqrt(1 - cos theta)` over [0, 1] (theta 0-90 degrees), the
/// backward half in `sqrt(1 + cos theta)` (180-90 degrees), so that theta moves at most
/// `2 / (COHERENCY_POINTS - 1)` radians between neighbours anywhere, at the cost of one
/// square root per look-up. Linear interpolation between them is within 1e-4 of the
/// table's largest entry for the white paint's pigment at 380 nm (size parameters up to
/// about 9; tested in `particles::tests` against the sum over sizes at the midpoints).
pub const COHERENCY_POINTS: usize = 257;

/// The expected coherency of the light a scattering event sends towards one direction,
/// per steradian and per unit incident power, averaged over the sizes the sampler draws:
/// `[A, B, Re C, Im C]` with `A = E[w |S2|^2]`, `B = E[w |S1|^2]`, `C = E[w S2 conj(S1)]`
/// and `w = albedo F / (2 pi N_k)` the weight [`ScatterModel::scatter_towards`] gives size
/// `k`. An incident field with components `a` (in the scattering plane) and `b`
/// (perpendicular) sends the field `(S2 a, S1 b)`, so its expected power along a unit
/// vector with components `(alpha, beta)` in the plane and perpendicular to it is
/// `A |a|^2 alpha^2 + B |b|^2 beta^2 + 2 alpha beta Re(C a conj(b))` (Bohren & Huffman
/// 1983, eq. 3.12; the expectation of a product of amplitudes over the size draw).
pub enum Coherency<'a> {
    /// Mie particles: tabulated, forward half then backward half ([`COHERENCY_POINTS`]
    /// each).
    Table(&'a [[f64; 4]]),
    /// Henyey-Greenstein: no polarisation change, `A = B = C = albedo p_HG / (2 pi)`.
    HenyeyGreenstein { g: f64, albedo: f64 },
}

/// `cos theta` at node `i` of the coherency table (`COHERENCY_POINTS` per half).
fn coherency_node(i: usize) -> f64 {
    let n = COHERENCY_POINTS - 1;
    let (half, j) = (i / COHERENCY_POINTS, i % COHERENCY_POINTS);
    let s = (j as f64 / n as f64).powi(2);
    if half == 0 { 1.0 - s } else { s - 1.0 }
}

impl Coherency<'_> {
    /// `[A, B, Re C, Im C]` at `cos theta = mu`.
    #[inline]
    pub fn at(&self, mu: f64) -> [f64; 4] {
        match self {
            Coherency::Table(t) => table_at(t, mu),
            Coherency::HenyeyGreenstein { g, albedo } => {
                let q = albedo * hg_density(*g, mu) / std::f64::consts::TAU;
                [q, q, q, 0.0]
            }
        }
    }
}

/// The tabulated coherency at `cos theta = mu`, linear between the nodes
/// ([`COHERENCY_POINTS`] per half).
#[inline(always)]
fn table_at(t: &[[f64; 4]], mu: f64) -> [f64; 4] {
    let n = COHERENCY_POINTS - 1;
    let (half, s) = if mu >= 0.0 {
        (&t[..COHERENCY_POINTS], (1.0 - mu).max(0.0))
    } else {
        (&t[COHERENCY_POINTS..], (1.0 + mu).max(0.0))
    };
    let x = s.sqrt() * n as f64;
    let j = (x as usize).min(n - 1);
    let f = x - j as f64;
    let (a, b) = (half[j], half[j + 1]);
    [
        a[0] + f * (b[0] - a[0]),
        a[1] + f * (b[1] - a[1]),
        a[2] + f * (b[2] - a[2]),
        a[3] + f * (b[3] - a[3]),
    ]
}

impl Coherency<'_> {
    /// [`Coherency::at`] at each `mu`, into `a`, `b`, `c_re` and `c_im` (each as long as
    /// `mu`): the same values, with the kind of coherency decided once for the batch, so
    /// that the Henyey-Greenstein loop vectorises.
    #[inline(always)]
    pub fn at_each(
        &self,
        mu: &[f64],
        a: &mut [f64],
        b: &mut [f64],
        c_re: &mut [f64],
        c_im: &mut [f64],
    ) {
        let n = mu.len();
        let (a, b, c_re, c_im) = (&mut a[..n], &mut b[..n], &mut c_re[..n], &mut c_im[..n]);
        match self {
            Coherency::Table(t) => {
                for j in 0..n {
                    [a[j], b[j], c_re[j], c_im[j]] = table_at(t, mu[j]);
                }
            }
            Coherency::HenyeyGreenstein { g, albedo } => {
                for j in 0..n {
                    let q = albedo * hg_density(*g, mu[j]) / std::f64::consts::TAU;
                    (a[j], b[j], c_re[j], c_im[j]) = (q, q, q, 0.0);
                }
            }
        }
    }
}

impl ScatterModel {
    /// The size-averaged coherency at `lambda_nm` ([`Coherency`]); a Mie medium tabulates
    /// it on first use at each whole nanometre, the same bits whichever
    /// thread asks first.
    pub fn coherency(&self, lambda_nm: f64) -> Coherency<'_> {
        match self {
            ScatterModel::HenyeyGreenstein { g, .. } => Coherency::HenyeyGreenstein {
                g: *g,
                albedo: self.coefficients(lambda_nm).1,
            },
            ScatterModel::Mie { .. } => {
                let t = self.entry(lambda_nm).expect("a tabulated wavelength");
                Coherency::Table(t.coherency.get_or_init(|| {
                    (0..2 * COHERENCY_POINTS)
                        .map(|i| t.coherency_at(coherency_node(i)))
                        .collect()
                }))
            }
        }
    }
}

impl LambdaEntry {
    /// [`Coherency`]'s `[A, B, Re C, Im C]` at `cos theta = mu`, summed over the sizes
    /// with the probabilities the sampler draws them by.
    pub(super) fn coherency_at(&self, mu: f64) -> [f64; 4] {
        let mut out = [0.0; 4];
        let mut below = 0.0;
        for (k, size) in self.sizes.iter().enumerate() {
            let p = if k + 1 == self.sizes.len() {
                1.0 - below
            } else {
                self.size_cdf[k] - below
            };
            below = self.size_cdf[k];
            let w = p * self.weight(size, mu);
            if w == 0.0 {
                continue;
            }
            let (s1, s2) = size.mie.s1_s2(mu);
            let c = s2 * s1.conj();
            out[0] += w * s2.norm_sqr();
            out[1] += w * s1.norm_sqr();
            out[2] += w * c.re;
            out[3] += w * c.im;
        }
        out
    }

    /// `albedo F(theta) / (2 pi N_k)` for size `size` at `cos theta = mu`: the factor
    /// that makes `|S e|^2` the expected power per steradian (see
    /// [`ScatterModel::scatter_towards`]), with the structure factor `F` as the sampler
    /// takes it.
    fn weight(&self, size: &SizeEntry, mu: f64) -> f64 {
        let f = if let Some(s) = &size.factor {
            // As the sampler interpolates it: probes every pi / (n PROBE_STEPS).
            let x = mu.acos() / std::f64::consts::PI * (s.len() - 1) as f64;
            let j = (x as usize).min(s.len() - 2);
            s[j] + (x - j as f64) * (s[j + 1] - s[j])
        } else if let Some((py, kd)) = &self.structure {
            py.at(2.0 * kd * (0.5 * (1.0 - mu)).max(0.0).sqrt())
        } else {
            1.0
        };
        let norm = std::f64::consts::TAU * size.norm;
        if norm > 0.0 {
            self.albedo * f.max(0.0) / norm
        } else {
            0.0
        }
    }

    /// The radius a scattering event takes for the uniform draw `r` (by `size_cdf`), for
    /// the sampler and for next-event estimation alike.
    pub(super) fn draw_size(&self, r: f64) -> &SizeEntry {
        let k = self.size_cdf.partition_point(|&c| c < r);
        &self.sizes[k.min(self.sizes.len() - 1)]
    }
}
