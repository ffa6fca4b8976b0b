//! Random events of a tree: volume scattering in particle media and Russian roulette in
//! long multiply scattering trees (docs/physics.md, "Particle media"). Each starts a
//! coherence group of its own; both draw from the stream `TraceStack::set_stream` seeds.

use super::{ALL, C64, Field, Lane, RayState, Scene, SceneError, TraceLimits, TraceStack, Tree};
use super::{drop_all, field_power};
use crate::optics::particles::ScatterModel;
use glam::DVec3;

/// What a stretch of scattering medium did to a ray.
pub(super) enum Volume {
    /// No particle before the next surface or plane.
    Passes,
    /// Scattered: trace on from the event in the new direction.
    Scattered,
    /// Dropped (below the cutoff, a limit, or an untabulated medium).
    Ended,
}

impl<'a> Scene<'a> {
    /// Tabulates every scattering medium for wavelengths in `[lo_nm, hi_nm]` (Mie
    /// particles) or checks it (Henyey-Greenstein), asking `cancelled()` between
    /// wavelengths (a cancelled tabulation is an error naming it). Until then a ray inside a scattering
    /// medium is dropped as cut by a limit, never traced as if the medium were clear.
    pub fn prepare_scattering(
        &mut self,
        lo_nm: f64,
        hi_nm: f64,
        cancelled: &(dyn Fn() -> bool + Sync),
    ) -> Result<(), SceneError> {
        use crate::sample::Scattering;
        let media = &self.sample.media;
        let index = |m: usize, l: f64| -> C64 {
            let (n, k) = media[m].model.eval(l).unwrap_or((f64::NAN, f64::NAN));
            C64::new(n, k)
        };
        let mut out = Vec::with_capacity(media.len());
        for (i, m) in media.iter().enumerate() {
            let model = match &m.scattering {
                None => None,
                Some(Scattering::HenyeyGreenstein {
                    g,
                    scattering_per_um,
                    absorption_per_um,
                }) => Some(ScatterModel::henyey_greenstein(
                    *g,
                    *scattering_per_um,
                    *absorption_per_um,
                )),
                Some(Scattering::Particles {
                    medium,
                    radius,
                    volume_fraction,
                    dependent,
                }) => Some(ScatterModel::mie(
                    *radius,
                    *volume_fraction,
                    *dependent,
                    lo_nm,
                    hi_nm,
                    &|l| index(i, l),
                    &|l| index(*medium, l),
                    cancelled,
                )),
            };
            out.push(
                model
                    .transpose()
                    .map_err(|e| SceneError::Geometry(format!("medium '{}': {e}", m.name)))?,
            );
        }
        self.scatter = out;
        Ok(())
    }

    /// Scattering angles drawn above their envelope so far, over every particle medium
    /// ([`ScatterModel::violations`]).
    pub fn scatter_violations(&self) -> u64 {
        self.scatter.iter().flatten().map(|m| m.violations()).sum()
    }

    /// The medium that scatters most at `lambda_nm`, and its optical depth over the
    /// sample's height (extinction coefficient times the height of the scene's box), or
    /// `None` where nothing scatters in volume.
    pub fn densest_scatterer(&self, lambda_nm: f64) -> Option<(usize, f64)> {
        let height = self.z_top - self.z_bottom;
        self.scatter
            .iter()
            .enumerate()
            .filter_map(|(i, m)| {
                m.as_ref()
                    .map(|m| (i, m.coefficients(lambda_nm).0 * height))
            })
            .max_by(|a, b| a.1.total_cmp(&b.1))
    }

    /// Whether some medium of the sample scatters light in its volume.
    pub fn scatters(&self) -> bool {
        self.scatters
    }

    /// Volume scattering along the next `t_next` nm of ray `r` in a scattering medium:
    /// an exponential free path with the medium's extinction coefficient at the lane's
    /// wavelength (`optics::particles`); if it ends first, the ray moves there, its power
    /// is multiplied by the albedo (the rest is absorbed) and the event's weight, it turns
    /// into the sampled direction and starts a coherence group of its own. The ray carries
    /// one lane: the driver traces scattering samples a wavelength at a time. `cos_ahead`:
    /// `|cos|` between the ray and the surface `t_next` ahead (0 where the next stop is
    /// an exit plane or a tile side, not a surface).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn volume_event(
        &self,
        r: &mut RayState,
        t_next: f64,
        cos_ahead: f64,
        n_med: C64,
        lanes: &[Lane],
        limits: &TraceLimits,
        stack: &mut TraceStack,
        trees: &mut [Tree],
    ) -> Volume {
        let first = if r.lane == ALL { 0 } else { r.lane as usize };
        let Some(model) = self.scatter.get(r.medium).and_then(|m| m.as_ref()) else {
            // Not tabulated (prepare_scattering was not called): dropped, and said so.
            drop_all(&stack.cur, first, r.opl, trees);
            return Volume::Ended;
        };
        if r.lane == ALL || stack.cur.len() != 1 {
            drop_all(&stack.cur, first, r.opl, trees);
            return Volume::Ended;
        }
        let lambda = lanes[first].lambda_nm;
        let (mu_ext, albedo) = model.coefficients(lambda);
        let s = -(1.0 - stack.rng.uniform()).ln() / mu_ext;
        // A free path ending within `eps` (perpendicular) of the surface ahead reaches it:
        // a ray scattered from nearer could miss that surface within the accelerator's
        // precision and cross into the next medium unseen, a leak (issue 71: a hiding
        // chart's 80 um film lost 0.9 of one tree's power so). The medium lost is at most
        // `eps` thick (1e-6 of the scene's extent in a scattering scene), a scattering
        // probability of `mu_ext eps / cos` per crossing.
        if s >= t_next || (cos_ahead > 0.0 && (t_next - s) * cos_ahead < self.eps) {
            return Volume::Passes;
        }
        self.advance(r, s, n_med, &stack.cur, first, trees);
        let tree = &mut trees[first];
        let Some(mut e) = stack.cur[0] else {
            return Volume::Ended;
        };
        if albedo < 1.0 {
            tree.absorbing = true;
        }
        let power = |e: &[Field; 2]| 0.5 * (field_power(&e[0]) + field_power(&e[1]));
        let p_in = power(&e);
        let estimated = self.next_event(
            r,
            &e,
            lambda,
            model,
            lanes[first].indices,
            &mut stack.rng,
            &mut stack.groups,
            tree,
        );
        let d2 = model.scatter(lambda, r.dir, &mut e, &mut stack.rng);
        let att = if r.opl.im != 0.0 {
            (-4.0 * std::f64::consts::PI / lambda * r.opl.im).exp()
        } else {
            1.0
        };
        tree.note_event(p_in, power(&e), att);
        tree.random_events += 1;
        stack.groups += 1;
        r.group = stack.groups;
        r.dir = d2;
        r.n_re = d2 * n_med.re;
        r.n_im = DVec3::ZERO;
        r.nee = estimated;
        let mut power = field_power(&e[0]).max(field_power(&e[1]));
        if r.opl.im != 0.0 {
            power *= (-4.0 * std::f64::consts::PI / lambda * r.opl.im).exp();
        }
        if power < limits.cutoff || power.is_nan() {
            tree.drop_field(&e, r.opl, false);
            stack.cur[0] = None;
            return Volume::Ended;
        }
        if tree.segments >= limits.max_segments {
            tree.drop_field(&e, r.opl, true);
            stack.cur[0] = None;
            return Volume::Ended;
        }
        stack.cur[0] = Some(e);
        Volume::Scattered
    }
}

/// In a sample with bodies or scattering media (`Scene::roulette`), a tree past this many
/// segments has stopped being a short coherent series (films,
/// rough surfaces and coatings stay below: their series end at the power cutoff within
/// tens of segments, and every shipped sample of that kind gives the same bytes with and
/// without roulette) and has become a multiply scattering one (flakes in a binder, light
/// walking through a particle medium), where every interface event doubling the rays makes
/// it grow exponentially until `--max-segments` cuts it.
pub const ROULETTE_AFTER_SEGMENTS: u32 = 256;
/// In such a tree, a child carrying less than this fraction of the launched power goes on
/// with probability `q = P / ROULETTE_BELOW` and its fields scaled by `1 / sqrt(q)`
/// (Russian roulette: Arvo & Kirk, SIGGRAPH 1990), so the power it carries is right on
/// average and the tree's rays number about `1 / ROULETTE_BELOW` per generation at most.
/// A survivor starts a coherence group of its own: its cross terms with the rest of the
/// tree (at most `2 sqrt(P_a P_b)`, with `P` below 1e-2 here) are left out, as the
/// estimator leaves out those of particle-scattered light.
pub const ROULETTE_BELOW: f64 = 1e-2;

/// Russian roulette on the rays `stack.rays[from..]` just pushed (see
/// [`ROULETTE_AFTER_SEGMENTS`]): decided once per ray (for a ray carrying several lanes, on
/// its strongest lane, and applied to all of them, which keeps every lane unbiased).
pub(super) fn roulette(from: usize, lanes: &[Lane], stack: &mut TraceStack, trees: &mut [Tree]) {
    let TraceStack {
        rays,
        fields,
        rng,
        groups,
        ..
    } = stack;
    for r in rays[from..].iter_mut() {
        let att = |lane: usize| {
            if r.opl.im != 0.0 {
                (-4.0 * std::f64::consts::PI / lanes[lane].lambda_nm * r.opl.im).exp()
            } else {
                1.0
            }
        };
        let power = |e: &[Field; 2]| 0.5 * (field_power(&e[0]) + field_power(&e[1]));
        let p = if r.lane == ALL {
            fields[r.at as usize..]
                .iter()
                .take(lanes.len())
                .enumerate()
                .filter_map(|(j, f)| f.as_ref().map(|e| power(e) * att(j)))
                .fold(0.0, f64::max)
        } else {
            power(&r.e) * att(r.lane as usize)
        };
        if p >= ROULETTE_BELOW || p.is_nan() {
            continue;
        }
        let q = p / ROULETTE_BELOW;
        if rng.uniform() >= q {
            // A killed ray's power is gone, not dropped: the tree balances only on average
            // from here on, a random event as a survivor's is (issue 71: lossless trees
            // whose only roulette killed were taken for exactly balanced ones).
            r.killed = true;
            if r.lane == ALL {
                for (j, f) in fields[r.at as usize..]
                    .iter_mut()
                    .take(lanes.len())
                    .enumerate()
                {
                    if f.take().is_some() {
                        trees[j].random_events += 1;
                    }
                }
            } else {
                trees[r.lane as usize].random_events += 1;
            }
            continue;
        }
        let scale = 1.0 / q.sqrt();
        let grow = |e: &mut [Field; 2]| {
            for f in e.iter_mut() {
                for c in f.iter_mut() {
                    *c *= scale;
                }
            }
        };
        // A survivor's added weight counts as the tree's excess (`Tree::note_event`).
        let gain = 1.0 / q - 1.0;
        if r.lane == ALL {
            for (j, f) in fields[r.at as usize..]
                .iter_mut()
                .take(lanes.len())
                .enumerate()
            {
                if let Some(e) = f {
                    let before = power(e);
                    grow(e);
                    trees[j].random_events += 1;
                    trees[j].note_event(before, before * (1.0 + gain), att(j));
                }
            }
        } else {
            let before = power(&r.e);
            grow(&mut r.e);
            let lane = r.lane as usize;
            trees[lane].random_events += 1;
            trees[lane].note_event(before, before * (1.0 + gain), att(lane));
        }
        *groups += 1;
        r.group = *groups;
    }
}
