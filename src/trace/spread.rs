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
use crate::optics::particles::Coherency;
use crate::rng::Rng;

/// `sin^2` of the polar edges of `grid`'s bands, `theta_bins + 1` of them.
pub(super) fn polar_edges(grid: SpreadGrid) -> Vec<f64> {
    let dt = FRAC_PI_2 / f64::from(grid.theta_bins);
    (0..=grid.theta_bins)
        .map(|i| (f64::from(i) * dt).sin().powi(2))
        .collect()
}

/// Scratch of [`Scene::spread`], kept in the tree between events: per azimuth sector `j`
/// its direction's `(sin, cos)` and the projections of that horizontal direction on the
/// ray's direction and frame (`d.x cos + d.y sin`, and likewise for `e1` and `e2`); per
/// band, `cos theta` of the scattering angle and the coherency there, one array each so
/// that the loops over the sectors vectorise.
#[derive(Clone, Debug, Default)]
pub struct SpreadScratch {
    sin: Vec<f64>,
    cos: Vec<f64>,
    dxy: Vec<f64>,
    e1xy: Vec<f64>,
    e2xy: Vec<f64>,
    mu: Vec<f64>,
    coh: [Vec<f64>; 4],
}

/// One band's quantities shared by its sectors.
struct Band {
    sin1: f64,
    cos1: f64,
    /// `weight du1 du2 att pi n0^2 / (n1^2 cos theta_1)` ([`Scene::spread`]).
    common: f64,
    /// The exit's power transmittances for s and p.
    t: [f64; 2],
}

/// The incident fields' coherency in the frame `(e1, e2, d)`.
struct Incident {
    d: DVec3,
    e1: DVec3,
    e2: DVec3,
    w11: f64,
    w22: f64,
    w12: C64,
}

impl Scene<'_> {
    /// The spread estimate of a volume event of ray `r` with fields `e` about to scatter,
    /// `h` nm below the top of its scattering layer: one direction in each bucket of
    /// `grid` (`edges` from [`polar_edges`]), added to `tree.nee`. Its loops over the
    /// azimuth sectors run four lanes wide where the CPU has AVX2, with the same bits
    /// (`machine::with_avx2`; issue 75: this was 57 % of the white paint's time).
    pub(super) fn spread(
        &self,
        ev: &Event,
        grid: SpreadGrid,
        edges: &[f64],
        weight: f64,
        rng: &mut Rng,
        tree: &mut Tree,
    ) {
        crate::machine::with_avx2(
            #[inline(always)]
            || self.spread_body(ev, grid, edges, weight, rng, tree),
        );
    }

    /// [`Scene::spread`] as compiled for the caller's target features.
    #[inline(always)]
    pub(super) fn spread_body(
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
        let inc = Incident {
            d,
            e1,
            e2,
            w11,
            w22,
            w12,
        };
        let (v1, v2) = (rng.uniform(), rng.uniform());
        let np = grid.phi_bins as usize;
        if tree.nee.len() != grid.len() {
            tree.nee.resize(grid.len(), 0.0);
        }
        tree.random_events += 1;
        let du2 = 1.0 / np as f64;
        let mut s = std::mem::take(&mut tree.spread_scratch);
        s.sin.clear();
        s.cos.clear();
        // The sectors' azimuths TAU (j + v2) / np by turning the first by TAU / np at a
        // time (angle addition): two sines and cosines an event instead of np; the turns'
        // rounding moves the last sector by some 1e-15 rad, far inside its jitter.
        let (mut sp, mut cp) = (TAU * v2 * du2).sin_cos();
        let (sd, cd) = (TAU * du2).sin_cos();
        for _ in 0..np {
            s.sin.push(sp);
            s.cos.push(cp);
            (sp, cp) = (sp * cd + cp * sd, cp * cd - sp * sd);
        }
        let project = |v: DVec3, out: &mut Vec<f64>, s: &[f64], c: &[f64]| {
            out.clear();
            out.extend(c.iter().zip(s).map(|(&cp, &sp)| v.x * cp + v.y * sp));
        };
        project(d, &mut s.dxy, &s.sin, &s.cos);
        project(e1, &mut s.e1xy, &s.sin, &s.cos);
        project(e2, &mut s.e2xy, &s.sin, &s.cos);
        s.mu.resize(np, 0.0);
        for c in &mut s.coh {
            c.resize(np, 0.0);
        }
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
            let band = Band {
                sin1,
                cos1,
                common,
                t: up.t,
            };
            band_row(
                &mut s,
                &mut tree.nee[ti * np..(ti + 1) * np],
                &band,
                &inc,
                &coherency,
            );
        }
        tree.spread_scratch = s;
    }
}

/// One band's sectors: `cos theta` of each scattering angle, the coherency there, then each
/// bucket's power along the exit's s and p axes (the module's formula), added to `row`.
#[inline(always)]
fn band_row(s: &mut SpreadScratch, row: &mut [f64], b: &Band, inc: &Incident, coh: &Coherency) {
    let n = row.len();
    let (sin, cos) = (&s.sin[..n], &s.cos[..n]);
    let (dxy, e1xy, e2xy) = (&s.dxy[..n], &s.e1xy[..n], &s.e2xy[..n]);
    let Band {
        sin1,
        cos1,
        common,
        t,
    } = *b;
    let Incident {
        d,
        e1,
        e2,
        w11,
        w22,
        w12,
    } = *inc;
    // The outgoing direction w1 = (sin1 cos, sin1 sin, cos1): w1 . d.
    for (m, &p) in s.mu[..n].iter_mut().zip(dxy) {
        *m = (sin1 * p + cos1 * d.z).clamp(-1.0, 1.0);
    }
    let [ca, cb, cre, cim] = &mut s.coh;
    coh.at_each(
        &s.mu[..n],
        &mut ca[..n],
        &mut cb[..n],
        &mut cre[..n],
        &mut cim[..n],
    );
    let (ca, cb, cre, cim) = (&ca[..n], &cb[..n], &cre[..n], &cim[..n]);
    let power = w11 + w22;
    for j in 0..n {
        // The scattering plane's normal `u = w1 x d` in the frame, `(w1 . e2, -w1 . e1)`,
        // and the in-plane axis before scattering `v = u x d = (u2, -u1)`, both left
        // unnormalised (`|u|^2 = 1 - mu^2`): every term below is quadratic in them and
        // divided by `|u|^2` once.
        let mut u1 = sin1 * e2xy[j] + cos1 * e2.z;
        let mut u2 = -(sin1 * e1xy[j] + cos1 * e1.z);
        let mut l2 = u1 * u1 + u2 * u2;
        if l2 <= 1e-24 {
            (u1, u2, l2) = (1.0, 0.0, 1.0);
        }
        let inv = 1.0 / l2;
        let (ux, uy, uz) = (
            e1.x * u1 + e2.x * u2,
            e1.y * u1 + e2.y * u2,
            e1.z * u1 + e2.z * u2,
        );
        // <|b|^2> = u^T W u, <a conj(b)> = v^T W u (over |u|^2).
        let bb = (w11 * u1 * u1 + w22 * u2 * u2 + 2.0 * u1 * u2 * w12.re) * inv;
        let aa = power - bb;
        let ab_re = (u1 * u2 * (w11 - w22) + (u2 * u2 - u1 * u1) * w12.re) * inv;
        let cab = cre[j] * ab_re - cim[j] * w12.im;
        // The exit's s axis against the outgoing plane's axes: `beta = e_perp . s`,
        // `alpha = par_out . s = -(u . p) / |u|` with `p = s x w1` (the exit's p axis);
        // its p axis is the same basis turned by 90 degrees.
        let (cp, sp) = (cos[j], sin[j]);
        let beta = cp * uy - sp * ux;
        let alpha = sin1 * uz - cos1 * (cp * ux + sp * uy);
        let (a2, b2) = (alpha * alpha * inv, beta * beta * inv);
        let ab = 2.0 * alpha * beta * inv * cab;
        let (aa, bb) = (ca[j] * aa, cb[j] * bb);
        let es = aa * a2 + bb * b2 + ab;
        let ep = aa * b2 + bb * a2 - ab;
        row[j] += common * (t[0] * es + t[1] * ep);
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
    /// entry (`COHERENCY_POINTS`), here 2e-4 of the largest bucket. The dispatched path
    /// (AVX2 where the CPU has it) gives the baseline path's bits.
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
        let (mut rng_body, mut baseline) = (rng.clone(), Tree::default());
        scene.spread(&ev, grid, &edges, 1.0, &mut rng, &mut tree);
        // The AVX2 path (where the CPU has it) gives the baseline path's bits.
        scene.spread_body(&ev, grid, &edges, 1.0, &mut rng_body, &mut baseline);
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&tree.nee), bits(&baseline.nee));
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
