//! Next-event estimation spread over every outgoing bucket (issue 49; docs/physics.md,
//! "Next-event estimation"): a volume event that the roulette of `escape::next_event`
//! picks (with probability `exp(-mu_ext h) / SPREAD_ROULETTE`, weighted by the inverse)
//! has its straight escape estimated towards one direction in each bucket of the
//! reflected hemisphere at once, instead of one direction in all, and the power is added
//! to the tree's [`Tree::nee`] buckets directly.
//!
//! The buckets are rectangles in the cosine map `(u1, u2) = (sin^2 theta_o, phi_o / 2 pi)`,
//! where the density `cos theta_o / pi` per steradian is uniform
//! (`d omega = pi du1 du2 / cos theta_o`). Each bucket is one stratum: its direction is
//! drawn uniformly inside it (one jitter `(v1, v2)` per event, shared by the buckets) and
//! weighted by its area `du1 du2`, so the estimate of every bucket is unbiased and their
//! sum is a stratified estimate of the whole escape. Per bucket it is the single
//! direction's (`escape`):
//!
//! `du1 du2 pi n_0^2 / (n_1^2 cos theta_1) exp(-mu_ext h / cos theta_1)
//!  sum_{s, p} T_pol <|E_pol|^2>`,
//!
//! with `<|E_pol|^2>` the expected scattered power along the exit's s and p axes, taken
//! from the size-averaged coherency (`particles::Coherency`) and the incident fields' own
//! coherency matrix `W = (1/2) sum_pol f f^H` (the two polarisations averaged, as every
//! exit's power is): `<|a|^2> = p^T W p`, `<a conj(b)> = p^T W e_perp` for the
//! components `a`, `b` in and perpendicular to the scattering plane.

use std::f64::consts::{FRAC_PI_2, PI, TAU};

use glam::DVec3;

use super::escape::{Event, SpreadGrid};
use super::{C64, Scene, Tree};
use crate::geom::frame;
use crate::optics::fresnel::field_dot_real;
use crate::rng::Rng;

/// `sin^2` of the polar edges of `grid`'s bands, `theta_bins + 1` of them.
pub(super) fn polar_edges(grid: SpreadGrid) -> Vec<f64> {
    let dt = FRAC_PI_2 / f64::from(grid.theta_bins);
    (0..=grid.theta_bins)
        .map(|i| (f64::from(i) * dt).sin().powi(2))
        .collect()
}

impl Scene<'_> {
    /// The spread estimate of a volume event of ray `r` with fields `e` about to scatter,
    /// `h` nm below the top of its scattering layer: one direction in each bucket of
    /// `grid` (`edges` from [`polar_edges`]), added to `tree.nee`.
    pub(super) fn spread(
        &self,
        ev: &Event,
        grid: SpreadGrid,
        edges: &[f64],
        weight: f64,
        rng: &mut Rng,
        tree: &mut Tree,
    ) {
        let Event {
            r,
            e,
            lambda,
            model,
            indices,
            layer,
            h,
        } = *ev;
        let esc = self
            .escape
            .as_ref()
            .expect("spread only where escape applies");
        let d = r.dir;
        let (n0, n1) = (indices[esc.ambient].re, indices[layer.medium]);
        let (mu_ext, _) = model.coefficients(lambda);
        let coherency = model.coherency(lambda);
        // The incident fields' coherency W = (1/2) sum_pol f f^H in a right-handed frame
        // (e1, e2, d) across the ray (the fields are transverse): w11, w22 and w12.
        let e1 = frame(d).0;
        let e2 = d.cross(e1);
        let (mut w11, mut w22, mut w12) = (0.0, 0.0, C64::new(0.0, 0.0));
        for f in e {
            let (f1, f2) = (field_dot_real(f, e1), field_dot_real(f, e2));
            w11 += 0.5 * f1.norm_sqr();
            w22 += 0.5 * f2.norm_sqr();
            w12 += 0.5 * f1 * f2.conj();
        }
        let power = w11 + w22;
        let (v1, v2) = (rng.uniform(), rng.uniform());
        let np = grid.phi_bins as usize;
        if tree.nee.len() != grid.len() {
            tree.nee.resize(grid.len(), 0.0);
        }
        tree.random_events += 1;
        let du2 = 1.0 / np as f64;
        let mut azimuths = std::mem::take(&mut tree.spread_azimuths);
        azimuths.clear();
        azimuths.extend((0..np).map(|j| (TAU * (j as f64 + v2) * du2).sin_cos()));
        let absorb = 4.0 * PI / lambda;
        for (ti, band) in edges.windows(2).enumerate() {
            let du1 = band[1] - band[0];
            let u1 = band[0] + v1 * du1;
            let kt = n0 * u1.sqrt();
            let sin1 = kt / n1.re;
            if sin1 >= 1.0 {
                continue;
            }
            let cos1 = (1.0 - sin1 * sin1).sqrt();
            let Some(up) = layer.through(indices, n0, n1.re, cos1, kt) else {
                continue;
            };
            let att = (-mu_ext * h / cos1 - absorb * (r.opl.im + n1.im * h / cos1)).exp();
            let common = weight * du1 * du2 * att * PI * n0 * n0 / (n1.re * n1.re * cos1);
            if common == 0.0 {
                continue;
            }
            let row = &mut tree.nee[ti * np..(ti + 1) * np];
            for (slot, &(sp, cp)) in row.iter_mut().zip(&azimuths) {
                let w1 = DVec3::new(sin1 * cp, sin1 * sp, cos1);
                let mu = d.dot(w1).clamp(-1.0, 1.0);
                // The scattering plane's normal `u = w1 x d` in the frame, `(w1 . e2, -w1 .
                // e1)`, and the in-plane axis before scattering `v = u x d = (u2, -u1)`,
                // both left unnormalised (`|u|^2 = 1 - mu^2`): every term below is
                // quadratic in them and divided by `|u|^2` once.
                let (mut u1, mut u2) = (w1.dot(e2), -w1.dot(e1));
                let mut l2 = u1 * u1 + u2 * u2;
                if l2 <= 1e-24 {
                    (u1, u2, l2) = (1.0, 0.0, 1.0);
                }
                let inv = 1.0 / l2;
                let u = e1 * u1 + e2 * u2;
                let [a, b, c_re, c_im] = coherency.at(mu);
                // <|b|^2> = u^T W u, <a conj(b)> = v^T W u (over |u|^2).
                let bb = (w11 * u1 * u1 + w22 * u2 * u2 + 2.0 * u1 * u2 * w12.re) * inv;
                let aa = power - bb;
                let ab_re = (u1 * u2 * (w11 - w22) + (u2 * u2 - u1 * u1) * w12.re) * inv;
                let cab = c_re * ab_re - c_im * w12.im;
                // The exit's s axis against the outgoing plane's axes: `beta = e_perp . s`,
                // `alpha = par_out . s = -(u . p) / |u|` with `p = s x w1` (the exit's p axis);
                // its p axis is the same basis turned by 90 degrees.
                let beta = cp * u.y - sp * u.x;
                let alpha = sin1 * u.z - cos1 * (cp * u.x + sp * u.y);
                let (a2, b2) = (alpha * alpha * inv, beta * beta * inv);
                let ab = 2.0 * alpha * beta * inv * cab;
                let (aa, bb) = (a * aa, b * bb);
                let es = aa * a2 + bb * b2 + ab;
                let ep = aa * b2 + bb * a2 - ab;
                *slot += common * (up.t[0] * es + up.t[1] * ep);
            }
        }
        tree.spread_azimuths = azimuths;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::Backend;
    use crate::sample::{self, MeshOptions};
    use crate::trace::{Field, RayState};

    /// Each bucket of a spread event, over its area, is the one-direction estimate
    /// (`escape_towards`, which forms the scattered fields themselves) at the bucket's
    /// point: the coherency algebra, the frame and the azimuths against the fields, for
    /// elliptically polarised light under a clear coat. Henyey-Greenstein to rounding;
    /// spheres of one radius (so that both take the same one; absorbing, so that `C` has an
    /// imaginary part) within the coherency table's interpolation, 1e-4 of its largest
    /// entry (`COHERENCY_POINTS`), here 2e-4 of the largest bucket.
    #[test]
    fn a_spread_bucket_is_the_one_direction_estimate_at_its_point() {
        one_event(
            "henyey_greenstein = { g = 0.6, scattering_per_um = 2.0, absorption_per_um = 0.1 }",
            1e-12,
        );
        one_event(
            "particles = { medium = \"pigment\", radius_nm = 200.0, volume_fraction = 0.05 }",
            2e-4,
        );
    }

    fn one_event(scattering: &str, tolerance: f64) {
        let dir = std::env::temp_dir().join(format!(
            "goniospec-spread-{}-{}",
            std::process::id(),
            scattering.len()
        ));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("s.toml");
        std::fs::write(
            &path,
            format!(
                "[sample]\nname = \"spread\"\nunit = \"um\"\ntile = [5.0, 5.0]\n\
                 [media.air]\nn = 1.0\n[media.coat]\nn = 1.3\n\
                 [media.pigment]\nn = 2.2\nk = 0.3\n\
                 [media.paint]\nn = 1.5\n{scattering}\n\
                 [media.sub]\nn = 1.5\nk = 0.2\n\
                 [stack]\nambient = \"air\"\n\
                 layers = [{{ medium = \"coat\", thickness = 1.0 }}, \
                 {{ medium = \"paint\", thickness = 2.0 }}]\n\
                 substrate = \"sub\"\n"
            ),
        )
        .unwrap();
        let s = sample::load(&path, MeshOptions::default()).unwrap();
        let mut scene = Scene::new(&s, Backend::Obvhs).unwrap();
        let grid = SpreadGrid {
            theta_bins: 7,
            phi_bins: 5,
        };
        assert!(scene.enable_next_event(Some(grid)));
        scene.prepare_scattering(380.0, 780.0, &|| false).unwrap();
        let lambda = 550.0;
        let mut indices = Vec::new();
        s.indices_into(lambda, &mut indices);
        let esc = scene.escape.as_ref().unwrap();
        let paint = esc.layers[0].medium;
        let z = esc.layers[0].z_top - 300.0;
        let layer = esc.layer(paint, z).unwrap();
        let model = scene.scatter[paint].as_ref().unwrap();
        let d = DVec3::new(0.3, -0.2, 0.9).normalize();
        let (a, b) = (frame(d).0, d.cross(frame(d).0));
        let field = |x: C64, y: C64| -> Field { [0, 1, 2].map(|i| x * a[i] + y * b[i]) };
        let c = C64::new;
        let e = [
            field(c(0.7, 0.2), c(0.1, -0.5)),
            field(c(-0.2, 0.3), c(0.8, 0.1)),
        ];
        let r = RayState {
            pos: DVec3::new(1000.0, 2000.0, z),
            dir: d,
            n_re: d * 1.5,
            n_im: DVec3::ZERO,
            off: [0.0; 2],
            medium: paint,
            opl: C64::new(4000.0, 0.0),
            depth: 3,
            lane: 0,
            e,
            at: 0,
            group: 1,
            tube: 1.0,
            path: 7,
            killed: false,
            coherent: 1.0,
            last_facet: DVec3::ZERO,
            nee: false,
        };
        let mut rng = crate::rng::Rng::new(3, 4);
        let (v1, v2) = {
            let mut jitter = rng.clone();
            (jitter.uniform(), jitter.uniform())
        };
        let edges = polar_edges(grid);
        let mut tree = Tree::default();
        let ev = Event {
            r: &r,
            e: &e,
            lambda,
            model,
            indices: &indices,
            layer,
            h: 300.0,
        };
        scene.spread(&ev, grid, &edges, 1.0, &mut rng, &mut tree);
        let np = grid.phi_bins as usize;
        let expected: Vec<f64> = (0..tree.nee.len())
            .map(|k| {
                let (ti, pj) = (k / np, k % np);
                let du1 = edges[ti + 1] - edges[ti];
                let u = [edges[ti] + v1 * du1, (pj as f64 + v2) / np as f64];
                let mut one = Tree::default();
                scene.escape_towards(&ev, esc, u, &mut rng, &mut 0, &mut one);
                one.exit_power(lambda) * du1 / np as f64
            })
            .collect();
        let largest = expected.iter().copied().fold(0.0, f64::max);
        for (k, (got, x)) in tree.nee.iter().zip(&expected).enumerate() {
            assert!(
                (got - x).abs() <= tolerance * largest,
                "bucket {k}: spread {got} against {x}"
            );
        }
        let lit = expected.iter().filter(|x| **x > 0.0).count();
        assert!(lit >= 25, "{lit} buckets with light");
        std::fs::remove_dir_all(&dir).ok();
    }
}
