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
                let theta = mu.acos();
                let f = if let Some(s) = &size.factor {
                    // As the sampler interpolates it: probes every pi / (n PROBE_STEPS).
                    let x = theta / std::f64::consts::PI * (s.len() - 1) as f64;
                    let j = (x as usize).min(s.len() - 2);
                    s[j] + (x - j as f64) * (s[j + 1] - s[j])
                } else if let Some((py, kd)) = &t.structure {
                    py.at(2.0 * kd * (0.5 * (1.0 - mu)).max(0.0).sqrt())
                } else {
                    1.0
                };
                let norm = std::f64::consts::TAU * size.norm;
                let scale = if norm > 0.0 {
                    (t.albedo * f.max(0.0) / norm).sqrt()
                } else {
                    0.0
                };
                (s2, s1, scale)
            }
        };
        e.map(|f| {
            let (ep, es) = (field_dot_real(&f, par_in), field_dot_real(&f, e_perp));
            combine(amp1 * ep * scale, par_out, amp2 * es * scale, e_perp)
        })
    }
}

impl LambdaEntry {
    /// The radius a scattering event takes for the uniform draw `r` (by `size_cdf`), for
    /// the sampler and for next-event estimation alike.
    pub(super) fn draw_size(&self, r: f64) -> &SizeEntry {
        let k = self.size_cdf.partition_point(|&c| c < r);
        &self.sizes[k.min(self.sizes.len() - 1)]
    }
}
