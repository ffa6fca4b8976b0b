//! Next-event estimation in particle media under flat layers (issue 49; docs/physics.md,
//! "Next-event estimation"): at each volume scattering event the expected power that
//! leaves the sample straight through the flat layers above, with no further event, is
//! sent out, and the walk's own light that does so is not counted again (`RayState::nee`),
//! so the estimate stays unbiased while every event contributes.
//!
//! Where the run gives a bucket grid (`Escape::spread`), the estimate is spread over every
//! bucket at once (`spread`), with probability `exp(-mu_ext h) / SPREAD_ROULETTE` and
//! weight its inverse. Otherwise (Mueller runs), one outgoing direction per event, as an
//! exit of a coherence group of its own, drawn by the cosine in the ambient (`w_o`, density
//! `cos theta_o / pi` per steradian). Inside the scattering layer it is `w_1`, with the
//! tangential index kept through every flat interface (`n_m sin theta_m = n_0 sin
//! theta_o`). The estimate of the power leaving towards `w_o` per event is
//!
//! `sum_pol |E_pol(w_1)|^2 T_pol exp(-mu_ext h / cos theta_1) J / p(w_o)`,
//!
//! with `|E_pol(w_1)|^2` the walk's scattered power per steradian towards `w_1`
//! (`ScatterModel::scatter_towards`), `T_s`, `T_p` the layers' incoherent transmission
//! (Fresnel power coefficients, multiple reflections in each clear layer summed as a
//! geometric series: e.g. Macleod, *Thin-Film Optical Filters*, 4th ed., §2.7.2), the
//! free-path survival over the depth `h` below the layer's top, and the radiance Jacobian
//! `J = d omega_1 / d omega_o = n_0^2 cos theta_o / (n_1^2 cos theta_1)` (Snell's law in
//! solid angle; e.g. Born & Wolf §1.5.2). With `p(w_o) = cos theta_o / pi`,
//! `J / p = pi n_0^2 / (n_1^2 cos theta_1)`, bounded because `theta_1` stays inside the
//! critical angle. Absorption by the layers' own media rides on the exit's optical path.
//!
//! Where an event lies many mean free paths deep, the estimate is made with probability
//! `exp(-mu_ext h) / NEE_ROULETTE` (below [`NEE_ROULETTE`]) and otherwise the walk keeps
//! its own direct escape: either way the expectation is the same.

use std::f64::consts::{PI, TAU};

use glam::DVec3;

use super::{C64, Exit, Field, RayState, Scene, Tree, field_power};
use crate::optics::fresnel::field_dot_real;
use crate::optics::particles::ScatterModel;
use crate::rng::Rng;
use crate::sample::Sample;

/// Best-case survival to the top below which an event's estimate is made only sometimes
/// (with probability `survival / NEE_ROULETTE`): deeper events would add almost nothing
/// at the cost of an evaluation each.
pub const NEE_ROULETTE: f64 = 1e-3;

/// An event `h` nm below the top of its layer is spread with probability `exp(-mu_ext h)
/// / SPREAD_ROULETTE` (the best-case survival to the top over this) and its estimate
/// weighted by the inverse; the others make none (`next_event`). A spread costs one evaluation
/// per bucket (1,620 on the default grid; the spread was 57 % of the white paint's
/// profile), so this trades the noise of the roulette against the number of spreads. Measured on the white paint
/// (`meshes/paint-pigments.toml`, 30 deg, 40 bins, 1,024 trees, `bench converge`'s
/// figure): 0.3 gave 0.034 in 80 s, 1 gave 0.035 in 49 s, 2 gave 0.041 in 18 s, 3 gave
/// 0.046 in 17.7 s, 5 gave 0.055 in 12.4 s (before the evaluation was made 1.6 times
/// cheaper: 3 then took 10.9 s).
pub const SPREAD_ROULETTE: f64 = 3.0;

/// A grid of outgoing buckets: `theta_bins` equal polar bands over [0, 90 deg] times
/// `phi_bins` equal azimuth sectors, numbered `band * phi_bins + sector` (the order of
/// `accumulate::Buckets::index`, which the run's tally keys them by).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SpreadGrid {
    pub theta_bins: u32,
    pub phi_bins: u32,
}

impl SpreadGrid {
    pub(super) fn len(self) -> usize {
        self.theta_bins as usize * self.phi_bins as usize
    }
}

/// A volume event that next-event estimation works from: the ray at it, the fields about to
/// scatter, the wavelength (nm), the medium's model and the sample's indices there, and the
/// scattering layer it lies in, `h` nm below that layer's top.
pub(super) struct Event<'a> {
    pub r: &'a RayState,
    pub e: &'a [Field; 2],
    pub lambda: f64,
    pub model: &'a ScatterModel,
    pub indices: &'a [C64],
    pub layer: &'a EscapeLayer,
    pub h: f64,
}

/// A scattering layer of a flat stack with only clear layers between it and the ambient.
#[derive(Clone, Debug)]
pub(super) struct EscapeLayer {
    pub(super) medium: usize,
    /// The layer's top and bottom faces, nm (sample frame).
    pub(super) z_top: f64,
    z_bottom: f64,
    /// The clear layers above it, top first: `(medium, thickness nm)`.
    above: Vec<(usize, f64)>,
}

/// Where next-event estimation applies in a scene.
#[derive(Clone, Debug)]
pub(super) struct Escape {
    pub(super) ambient: usize,
    /// z of the ambient's face (the stack's top), nm.
    z_face: f64,
    pub(super) layers: Vec<EscapeLayer>,
    /// The outgoing buckets where each shallow event's estimate is spread over all of
    /// them at once (`spread`), with `sin^2` of their polar edges; `None`: one direction.
    pub(super) spread: Option<(SpreadGrid, Vec<f64>)>,
}

impl Escape {
    /// The escape geometry of `sample`, or `None` where its structure is not a flat
    /// `[stack]` of sheets without coatings, periodic, with a scattering layer under clear
    /// ones only (bodies, rough or coated faces and open sides keep the walk alone).
    pub(super) fn of(sample: &Sample) -> Option<Escape> {
        let st = sample.stack.as_ref()?;
        if sample.guard_nm.is_some() || sample.interfaces.len() != st.layers.len() + 1 {
            return None;
        }
        // Each face flat, at one z, without coatings, top first.
        let mut faces: Vec<(f64, usize, usize)> = Vec::new();
        for i in &sample.interfaces {
            if i.closed || !i.coating.is_empty() || i.mesh.positions_nm.is_empty() {
                return None;
            }
            let z = i.mesh.positions_nm[0].z;
            let flat = i
                .mesh
                .positions_nm
                .iter()
                .all(|v| (v.z - z).abs() <= 1e-6 * (1.0 + z.abs()));
            if !flat {
                return None;
            }
            faces.push((z, i.front, i.back));
        }
        faces.sort_by(|a, b| b.0.total_cmp(&a.0));
        let media: Vec<usize> = std::iter::once(st.ambient)
            .chain(st.layers.iter().map(|l| l.0))
            .chain(std::iter::once(st.substrate))
            .collect();
        for (j, &(_, f, b)) in faces.iter().enumerate() {
            let (above, below) = (media[j], media[j + 1]);
            if !((f == above && b == below) || (f == below && b == above)) {
                return None;
            }
        }
        let scatters = |m: usize| sample.media[m].scattering.is_some();
        if scatters(st.ambient) {
            return None;
        }
        let mut layers = Vec::new();
        for (i, &(m, _)) in st.layers.iter().enumerate() {
            if !scatters(m) {
                continue;
            }
            if st.layers[..i].iter().any(|l| scatters(l.0)) {
                break;
            }
            layers.push(EscapeLayer {
                medium: m,
                z_top: faces[i].0,
                z_bottom: faces[i + 1].0,
                above: st.layers[..i].to_vec(),
            });
        }
        (!layers.is_empty()).then(|| Escape {
            ambient: st.ambient,
            z_face: faces[0].0,
            layers,
            spread: None,
        })
    }

    pub(super) fn layer(&self, medium: usize, z: f64) -> Option<&EscapeLayer> {
        self.layers
            .iter()
            .find(|l| l.medium == medium && z <= l.z_top && z >= l.z_bottom)
    }
}

/// What the clear layers above a scattering layer do to light leaving it
/// ([`EscapeLayer::through`]).
pub(super) struct Through {
    /// Incoherent transmission to the ambient, `[s, p]`.
    pub t: [f64; 2],
    /// Optical path across the clear layers, nm (lossless: real).
    pub opl_nm: f64,
    /// Lateral shift across them per unit of the in-plane direction, nm.
    pub lateral_nm: f64,
}

impl EscapeLayer {
    /// Light leaving the layer's top at `cos1` inside (index `n1`) with tangential index
    /// `kt` (`n sin theta`, kept through every face), up through the clear layers above
    /// into the ambient (`n0`): `None` where a face reflects it totally.
    ///
    /// Bottom face first, the incoherent transmission `T` and the reflectance seen from
    /// below of the part above `R`, per polarisation: adding a face of reflectance `r`
    /// above gives `T' = T (1 - r) / (1 - R r)` and `R' = r + (1 - r)^2 R / (1 - R r)`
    /// (multiple reflections in each clear layer summed as a geometric series: e.g.
    /// Macleod, *Thin-Film Optical Filters*, 4th ed., §2.7.2).
    pub(super) fn through(
        &self,
        indices: &[C64],
        n0: f64,
        n1: f64,
        cos1: f64,
        kt: f64,
    ) -> Option<Through> {
        let cos_in = |n: f64| {
            let s = kt / n;
            (s < 1.0).then(|| (1.0 - s * s).sqrt())
        };
        let (mut t, mut rb) = ([1.0, 1.0], [0.0, 0.0]);
        let (mut opl_nm, mut lateral_nm) = (0.0, 0.0);
        let (mut n_below, mut c_below) = (n1, cos1);
        for (m, d) in self
            .above
            .iter()
            .rev()
            .map(|&(m, d)| (Some(m), d))
            .chain(std::iter::once((None, 0.0)))
        {
            let n_above = m.map_or(n0, |m| indices[m].re);
            let c_above = cos_in(n_above)?;
            // The face between: reflectance the same from either side (lossless), T = 1 - R.
            let (rs, rp) = fresnel_r(n_below, c_below, n_above, c_above);
            for (k, rf) in [rs, rp].into_iter().enumerate() {
                let through = t[k] * (1.0 - rf) / (1.0 - rb[k] * rf);
                rb[k] = rf + (1.0 - rf) * (1.0 - rf) * rb[k] / (1.0 - rb[k] * rf);
                t[k] = through;
            }
            if m.is_some() {
                opl_nm += n_above * d / c_above;
                lateral_nm += kt / n_above * d / c_above;
            }
            (n_below, c_below) = (n_above, c_above);
        }
        Some(Through {
            t,
            opl_nm,
            lateral_nm,
        })
    }
}

/// Fresnel power reflectances `(R_s, R_p)` between real indices `n_a` (incidence, cosine
/// `c_a`) and `n_b` (cosine `c_b`); Born & Wolf §1.5.3.
fn fresnel_r(n_a: f64, c_a: f64, n_b: f64, c_b: f64) -> (f64, f64) {
    let rs = (n_a * c_a - n_b * c_b) / (n_a * c_a + n_b * c_b);
    let rp = (n_b * c_a - n_a * c_b) / (n_b * c_a + n_a * c_b);
    (rs * rs, rp * rp)
}

impl Scene<'_> {
    /// Next-event estimation at a volume event of ray `r` (in its medium, at its position)
    /// with fields `e` about to scatter: pushes the estimate as an exit of a coherence group
    /// of its own and returns whether it was made (the walk then leaves out its own
    /// straight escape: `RayState::nee`).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn next_event(
        &self,
        r: &RayState,
        e: &[Field; 2],
        lambda: f64,
        model: &ScatterModel,
        indices: &[C64],
        rng: &mut Rng,
        groups: &mut u32,
        tree: &mut Tree,
    ) -> bool {
        let Some(esc) = &self.escape else {
            return false;
        };
        let Some(layer) = esc.layer(r.medium, r.pos.z) else {
            return false;
        };
        let n0 = indices[esc.ambient];
        if n0.im != 0.0 || layer.above.iter().any(|&(m, _)| indices[m].im != 0.0) {
            return false;
        }
        let (mu_ext, _) = model.coefficients(lambda);
        let h = (layer.z_top - r.pos.z).max(0.0);
        let best = (-mu_ext * h).exp();
        if best < NEE_ROULETTE && rng.uniform() * NEE_ROULETTE >= best {
            return false;
        }
        let ev = Event {
            r,
            e,
            lambda,
            model,
            indices,
            layer,
            h,
        };
        if let Some((grid, edges)) = &esc.spread {
            // Spread over every bucket with probability `p = survival / SPREAD_ROULETTE`
            // and weight `1 / p` (Russian roulette: the expectation is kept, and a weighted
            // estimate stays within `SPREAD_ROULETTE` times the shallowest event's).
            let p = (best / SPREAD_ROULETTE).min(1.0);
            if p >= 1.0 || rng.uniform() < p {
                self.spread(&ev, *grid, edges, 1.0 / p, rng, tree);
            }
            return true;
        }
        let u = [rng.uniform(), rng.uniform()];
        self.escape_towards(&ev, esc, u, rng, groups, tree);
        true
    }

    /// One direction of [`Scene::next_event`]'s estimate: the exit towards the ambient
    /// direction that the cosine map takes `u` to (`sin^2 theta_o = u[0]`, `phi_o = 2 pi
    /// u[1]`: density `cos theta_o / pi` per steradian).
    pub(super) fn escape_towards(
        &self,
        ev: &Event,
        esc: &Escape,
        u: [f64; 2],
        rng: &mut Rng,
        groups: &mut u32,
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
        let (n0, n1) = (indices[esc.ambient], indices[layer.medium]);
        let (mu_ext, _) = model.coefficients(lambda);
        let (u1, u2) = (u[0], u[1]);
        let (sin_o, cos_o) = (u1.sqrt(), (1.0 - u1).sqrt());
        let (sp, cp) = (TAU * u2).sin_cos();
        // The tangential index, kept through every face.
        let kt = n0.re * sin_o;
        let cos_in = |n: f64| {
            let s = kt / n;
            (s < 1.0).then(|| (1.0 - s * s).sqrt())
        };
        let Some(cos1) = cos_in(n1.re) else {
            // No direction inside leaves this way: the estimate is 0.
            return;
        };
        let w1 = DVec3::new(kt / n1.re * cp, kt / n1.re * sp, cos1);
        let wo = DVec3::new(sin_o * cp, sin_o * sp, cos_o);
        let Some(up) = layer.through(indices, n0.re, n1.re, cos1, kt) else {
            return;
        };
        let t = up.t;
        let opl = r.opl + n1 * (h / cos1) + C64::new(up.opl_nm, 0.0);
        let lateral =
            w1.truncate() * (h / cos1) + DVec3::new(cp, sp, 0.0).truncate() * up.lateral_nm;
        let rise = self.z_top - esc.z_face;
        let opl = opl + n0 * (rise / cos_o);
        let lateral = lateral + wo.truncate() * (rise / cos_o);
        let out = model.scatter_towards(lambda, r.dir, e, w1, rng);
        let common =
            ((-mu_ext * h / cos1).exp() * PI * n0.re * n0.re / (n1.re * n1.re * cos1)).sqrt();
        let s_hat = DVec3::new(-sp, cp, 0.0);
        let (p_in, p_out) = (s_hat.cross(w1), s_hat.cross(wo));
        let (ts, tp) = (t[0].sqrt() * common, t[1].sqrt() * common);
        let fields = out.map(|f| {
            let (a, b) = (field_dot_real(&f, s_hat), field_dot_real(&f, p_in));
            [0, 1, 2].map(|i| a * ts * s_hat[i] + b * tp * p_out[i])
        });
        let att = (-4.0 * PI / lambda * opl.im).exp();
        tree.excess += 0.5 * (field_power(&fields[0]) + field_power(&fields[1])) * att;
        tree.random_events += 1;
        *groups += 1;
        tree.exits.push(Exit {
            e: fields,
            opl,
            dir: wo,
            n_im: DVec3::ZERO,
            x: DVec3::new(
                r.pos.x + r.off[0] + lateral.x,
                r.pos.y + r.off[1] + lateral.y,
                self.z_top,
            ),
            up: true,
            group: *groups,
            tube: 1.0,
            path: r.path ^ 0x4E45_4500_0000_0000,
        });
    }
}
