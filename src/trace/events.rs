//! What happens where a ray meets an interface: each lane's split into reflected and
//! transmitted waves (Fresnel, or a coating's transfer matrices), the energy checks, and
//! the children pushed for the walk to trace.

use super::film::{self, FilmBack};
use super::{
    ALL, C64, Field, Lane, LaneSplit, RayState, Scene, TraceLimits, TraceStack, Tree, drop_all,
};
use crate::optics::fresnel::{self, field_power};
use crate::optics::tmm;
use glam::DVec3;

impl Scene<'_> {
    /// Splits the ray `r` at an interface, lane by lane, and pushes its children.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn interface_event(
        &self,
        r: RayState,
        prim: u32,
        n: DVec3,
        lanes: &[Lane],
        limits: &TraceLimits,
        stack: &mut TraceStack,
        trees: &mut [Tree],
    ) {
        let itf = &self.sample.interfaces[self.owner[prim as usize] as usize];
        let cos = r.dir.dot(n);
        let (from, to, nf) = if cos < 0.0 {
            (itf.front, itf.back, n)
        } else {
            (itf.back, itf.front, -n)
        };
        let first = if r.lane == ALL { 0 } else { r.lane as usize };
        if from != r.medium {
            for (k, f) in stack.cur.iter().enumerate() {
                if f.is_some() {
                    trees[first + k].leaks += 1;
                }
            }
            drop_all(&stack.cur, first, r.opl, trees);
            return;
        }
        // Each lane's split: the children's directions, waves and fields (a ray of one
        // lane, the common case, needs no list).
        let TraceStack { splits, cur, .. } = stack;
        // Written in place (a split is a few hundred bytes); `splits[k]` is valid where
        // `cur[k]` holds a field.
        if splits.len() < cur.len() {
            splits.resize_with(cur.len(), LaneSplit::default);
        }
        // The event's recombination weight: the same in every lane (it depends on the
        // wave's index vector and the facet alone); 1 for a homogeneous wave.
        let (w, w0) = if r.n_im != DVec3::ZERO {
            // The facet that made the wave counts only inside an absorber, for a wave
            // bouncing between a film's faces; an evanescent wave in a lossless medium
            // (a paint's binder beside a flake's edge) meets the next flake by `w0` alone.
            let inside = lanes[first].indices[from].im > 0.0;
            let last = if inside { r.last_facet } else { DVec3::ZERO };
            event_weights(r.n_re, r.n_im, nf, last)
        } else {
            (1.0, 1.0)
        };
        // A thin absorbing film entered from a lossless medium: its far face, for the
        // local film's hand-off (`film`). One probe serves every lane, as deep as the
        // deepest lane that enters an absorber here needs (`film::reach_nm`).
        let mut reach = 0.0f64;
        let side = if cos < 0.0 { 1 } else { 2 };
        if self.film_faces[prim as usize] & side != 0
            && self.sample.media[to].scattering.is_none()
            && r.n_im == DVec3::ZERO
        {
            for (k, f) in cur.iter().enumerate() {
                let l = &lanes[first + k];
                if f.is_some() && l.indices[from].im == 0.0 && l.indices[to].im > 0.0 {
                    reach = reach.max(film::reach_nm(l.indices[to], l.lambda_nm));
                }
            }
        }
        let back = (reach > 0.0)
            .then(|| self.film_back(&r, nf, to, reach))
            .flatten();
        for (k, f) in cur.iter().enumerate() {
            if let Some(e) = f {
                let j = first + k;
                self.lane_split(
                    itf,
                    &r,
                    nf,
                    (from, to),
                    (w, w0),
                    back.as_ref(),
                    e,
                    &lanes[j],
                    &mut trees[j],
                    &mut splits[k],
                );
                if lanes[j].indices[from].im > 0.0 {
                    note_split(&r, e, &splits[k], lanes[j].lambda_nm, &mut trees[j]);
                }
            }
        }
        let coherent = r.coherent * w;
        self.push_children(
            &r,
            prim,
            nf,
            from,
            to,
            back.as_ref(),
            coherent,
            lanes,
            limits,
            stack,
            trees,
        );
    }

    /// One lane's split of ray `r` (field `e`) at interface `itf` (normal `nf` facing the
    /// ray, from medium `from` to `to`, the event's weights `(w, w0)` of [`event_weights`]):
    /// the coefficients (coated where the interface carries thin layers), the energy checks,
    /// and the children's fields; where `to` is a thin absorbing film with the far face
    /// `back`, the local film's share of them ([`super::film`]); notes absorption and
    /// faults in the lane's `tree`.
    #[allow(clippy::too_many_arguments)]
    fn lane_split(
        &self,
        itf: &crate::sample::Interface,
        r: &RayState,
        nf: DVec3,
        (from, to): (usize, usize),
        (w, w0): (f64, f64),
        back: Option<&FilmBack>,
        e: &[Field; 2],
        lane: &Lane,
        tree: &mut Tree,
        out: &mut LaneSplit,
    ) {
        let (indices, lambda_nm) = (lane.indices, lane.lambda_nm);
        let (n1, n2) = (indices[from], indices[to]);
        let mut g = fresnel::split_wave(r.dir, r.n_re, r.n_im, nf, n1, n2);
        let mut coating_absorbs = false;
        if !itf.coating.is_empty() {
            // The thin stack's transfer-matrix amplitudes in the direction of travel
            // (front to back: outermost layer first), at this event's tangential index.
            tree.n_buf.clear();
            tree.d_buf.clear();
            tree.n_buf.push(n1);
            coating_absorbs = push_layers(itf, from, indices, tree);
            tree.n_buf.push(n2);
            let amp = tmm::amplitudes(&tree.n_buf, &tree.d_buf, g.kappa, lambda_nm);
            g.c = fresnel::coated(&g.c, amp);
            if coating_absorbs {
                tree.absorbing = true;
            }
        }
        if g.k_im > 0.0 {
            // The wave's amplitude varies along this facet (it entered through a facet
            // not parallel to this one): its partial waves recombine only in part. The
            // amplitudes are limited with `w`; the power counted as limited is the part
            // `1 - w0` of what met a facet tilted against the wave's planes of constant
            // amplitude, where the plane-wave model is stretched even if `w` is 1.
            let stretched = w0 < 1.0 && fresnel::exceeds_unity(&g.c);
            fresnel::limit_excess(&mut g.c, w);
            if stretched {
                tree.limited += 1;
                // The incident power, attenuated along the path, that met such an event.
                let mut p = field_power(&e[0]).max(field_power(&e[1]));
                if r.opl.im != 0.0 {
                    p *= (-4.0 * std::f64::consts::PI / lambda_nm * r.opl.im).exp();
                }
                tree.limited_power += p * (1.0 - w0);
            }
        }
        if n1.im == 0.0 && r.n_im == DVec3::ZERO {
            // A homogeneous wave from a lossless medium: |r|^2 + T = 1 exactly
            // (optics::fresnel::balance_excess); an absorbing coating may only take power
            // away. From an absorbing medium, or for an inhomogeneous wave, the incident
            // and reflected fluxes do not separate and no single event balances on its
            // own: energy is checked on the run's coherent totals
            // (simulate::check_physical).
            let [es, ep] = fresnel::balance_excess(&g.c, n1, n2);
            let ok = if coating_absorbs {
                es <= 1e-9 && ep <= 1e-9
            } else {
                es.abs() <= 1e-9 && ep.abs() <= 1e-9
            };
            debug_assert!(ok, "energy fault at an interface: {n1} -> {n2}, {:?}", g.c);
            if !ok {
                tree.energy_faults += 1;
            }
        }
        if n2.im > 0.0 && (g.c.t_s != C64::new(0.0, 0.0) || g.c.t_p != C64::new(0.0, 0.0)) {
            tree.absorbing = true;
        }
        // Field by field: no temporary of the whole split.
        (out.er[0], out.et[0]) = fresnel::split_field(&e[0], &g);
        (out.er[1], out.et[1]) = fresnel::split_field(&e[1], &g);
        // An inhomogeneous wave in a lossless medium left an absorber through a face tilted
        // against the one it entered by (a flake's edge) and is evanescent across its
        // front; its Fresnel coefficients have a pole where `q1 + q2` vanishes (r_s = 1306
        // at a paint's binder under a clear coat, issue 46), and its complex s/p basis is
        // not unit in |E|^2, so no bound on the coefficients holds its power. Its events
        // conserve |E|^2 at most, whatever their tilt (`fresnel::limit_field_excess`):
        // a lossless medium adds no power.
        if n1.im == 0.0 && r.n_im != DVec3::ZERO {
            for ((ek, er), et) in e.iter().zip(&mut out.er).zip(&mut out.et) {
                fresnel::limit_field_excess(ek, er, et, 0.0);
            }
        }
        out.dir_r = g.dir_r;
        out.n_r = g.n_r;
        out.dir_t = g.dir_t;
        out.n_t = g.n_t;
        out.dir_t2 = None;
        if let Some(b) = back {
            self.hand_off(itf, r, nf, (from, to), b, e, lane, tree, out);
        }
    }

    /// The local film's share of a split ([`super::film`]): where the field `e` of a
    /// homogeneous wave enters a thin absorbing film (medium `to`) from a lossless medium
    /// and the probe found its far face `b`, the outer media's split with the stack's
    /// transfer-matrix amplitudes (the entry face's coating, the film at its local
    /// thickness, the far face's coating) is blended into `out`'s children by the
    /// hand-off's weight, and the transmitted wave handed on from the far face.
    #[allow(clippy::too_many_arguments)]
    fn hand_off(
        &self,
        itf: &crate::sample::Interface,
        r: &RayState,
        nf: DVec3,
        (from, to): (usize, usize),
        b: &FilmBack,
        e: &[Field; 2],
        lane: &Lane,
        tree: &mut Tree,
        out: &mut LaneSplit,
    ) {
        let (indices, lambda_nm) = (lane.indices, lane.lambda_nm);
        let (n1, n2) = (indices[from], indices[to]);
        // A homogeneous wave from a lossless medium into an absorber. (An evanescent wave
        // in a lossless medium, which left an absorber through a face steeply tilted
        // against the one it entered by, is bound to that face: its transfer-matrix
        // amplitudes, which no energy bound holds for, describe nothing at the next film,
        // and its events stay energy-limited, `fresnel::limit_excess`.)
        if n1.im != 0.0 || n2.im <= 0.0 || r.n_im != DVec3::ZERO {
            return;
        }
        let depth_weight = film::depth_weight(b.depth_nm, lambda_nm);
        let h = b.tilt_weight * depth_weight;
        if h <= 0.0 {
            return;
        }
        if b.tilt_weight < 1.0 {
            // A thin film too steep for the local film alone: the share its ray series
            // take (whose error is linear in it, as the blend is one of amplitudes) is
            // reported as limited, where the plane-wave model is stretched.
            tree.limited += 1;
            let mut p = field_power(&e[0]).max(field_power(&e[1]));
            if r.opl.im != 0.0 {
                p *= (-4.0 * std::f64::consts::PI / lambda_nm * r.opl.im).exp();
            }
            tree.limited_power += p * depth_weight * (1.0 - b.tilt_weight);
        }
        // The local film: the outer media's split with the stack's transfer-matrix
        // amplitudes (the entry face's coating, the film at its local thickness, the far
        // face's coating, in the order the light crosses them).
        let n3 = indices[b.beyond];
        let far = &self.sample.interfaces[self.owner[b.prim as usize] as usize];
        let mut g2 = fresnel::split_wave(r.dir, r.n_re, r.n_im, nf, n1, n3);
        tree.n_buf.clear();
        tree.d_buf.clear();
        tree.n_buf.push(n1);
        push_layers(itf, from, indices, tree);
        tree.n_buf.push(n2);
        tree.d_buf.push(b.depth_nm);
        push_layers(far, to, indices, tree);
        tree.n_buf.push(n3);
        let amp = tmm::amplitudes(&tree.n_buf, &tree.d_buf, g2.kappa, lambda_nm);
        g2.c = fresnel::coated(&g2.c, amp);
        // A homogeneous wave from a lossless medium: an absorbing film may only take power
        // away.
        let [es, ep] = fresnel::balance_excess(&g2.c, n1, n3);
        let ok = es <= 1e-9 && ep <= 1e-9;
        debug_assert!(ok, "energy fault in a film: {n1} | {n2} | {n3}, {:?}", g2.c);
        if !ok {
            tree.energy_faults += 1;
        }
        tree.absorbing = true;
        for (k, ek) in e.iter().enumerate() {
            let (er, et) = fresnel::split_field(ek, &g2);
            for c in 0..3 {
                out.er[k][c] = out.er[k][c] * (1.0 - h) + er[c] * h;
                out.et[k][c] *= 1.0 - h;
                out.et2[k][c] = et[c] * h;
            }
        }
        if h >= 1.0 {
            out.dir_t = None;
        }
        out.dir_t2 = g2.dir_t;
        out.n_t2 = g2.n_t;
    }
}

/// Appends the coating of interface `itf` to the tree's transfer-matrix buffers, in the
/// order light coming from medium `from` crosses its layers (front to back: outermost layer
/// first); returns whether a layer absorbs.
fn push_layers(
    itf: &crate::sample::Interface,
    from: usize,
    indices: &[C64],
    tree: &mut Tree,
) -> bool {
    let nc = itf.coating.len();
    let mut absorbs = false;
    for i in 0..nc {
        let (m, d) = itf.coating[if from == itf.front { i } else { nc - 1 - i }];
        tree.n_buf.push(indices[m]);
        tree.d_buf.push(d);
        absorbs |= indices[m].im > 0.0;
    }
    absorbs
}

/// How far this facet's tilt turns the reflected wave, against a facet parallel to the
/// incident wave's planes of constant amplitude (normal `m0 = N'' / |N''|`, the face the
/// wave entered by): the reflected index vector is `N - 2 (N . m) m`, so the tilt moves its
/// real part by `Delta = 2 [(N' . m) m - (N' . m0) m0]` (an index; zero for the parallel
/// facet); `|Delta|` is returned. The light leaving through any face later turns by at most
/// that much (the tangential index is conserved there): for a film whose faces meet at a
/// small angle `beta`, whose successive partial waves leave `2 beta Re(q)` apart (`q` the
/// normal index inside), it is `2 beta |N'|` to first order; at a ridge tip or a flake's
/// edge (`beta` tens of degrees) it is of order `|N'|`. (Only the part along the entry face,
/// `2 beta Re(q)`, turns a film's light; but where the wave has met several facets `m0` is
/// no longer that face, and that part alone left a metallic paint's flake edges
/// unlimited: 1.2 of the power per tree created.)
pub fn deflection(n_re: DVec3, n_im: DVec3, normal: DVec3) -> f64 {
    let m0 = n_im.normalize_or_zero();
    let delta = normal * (2.0 * n_re.dot(normal)) - m0 * (2.0 * n_re.dot(m0));
    delta.length()
}

/// How far, in index units, a facet's tilt may change the reflected wave before its
/// plane-wave amplitudes stop describing the light the facet meets (see
/// [`recombination_weight`]).
pub const PLANE_WAVE_TILT: f64 = 0.5;

/// The weight in [0, 1] with which an event keeps its exact (plane-wave) amplitudes, for
/// an inhomogeneous wave of complex index vector `N = n_re + i n_im` meeting a facet of
/// normal `normal`: `w = exp(-x^2)` with `x = e |Delta|^2 / (2 a^2)`, `a = PLANE_WAVE_TILT`,
/// where
///
/// - `Delta = 2 [(N . m) m - (N . m0) m0]` is the change the facet's tilt gives the
///   reflected index vector against a facet parallel to the wave's planes of constant
///   amplitude (`m0 = n_im / |n_im|`; its real part is [`deflection`], and `|Delta|^2`
///   sums the squares of the real and imaginary parts): how fast, per reduced wavelength
///   `lambda / 2 pi`, the tilt changes the reflected wave's phase and amplitude along its
///   front;
/// - `e = (|N'|^2 + |N''|^2) / |N . N|` is the wave's evanescence: 1 for a wave whose
///   real and imaginary parts are parallel, about 1 for any wave that entered an absorber
///   from a lossless medium (1.15 in gold at 60 degrees), and large for the evanescent
///   waves that leave a metal through a face steeply tilted against the one they entered
///   by (22 in a paint's binder beside an aluminium flake's edge, `|N''| = 4.9` against an
///   index of 1.49): such a wave's amplitude changes by `e` within a fraction of a
///   wavelength across its front, it is bound to the face it left, and its plane-wave
///   extension to a facet elsewhere describes nothing.
///
/// A film whose faces meet at `beta` has `|Delta| ~ 2 beta |N|` and `e ~ 1` (`|Delta| =
/// 0.12` at 1 degree in gold): its partial waves leave with amplitudes that vary across
/// the beamlet, and the estimator recombines them over the window in which they are known
/// ([`crate::accumulate`], `directional_exponent`), so the event keeps nearly all of its
/// exact amplitudes. At a ridge tip or a flake's edge (`|Delta|` of order `|N|`, 1-14 in
/// metals), or for an evanescent wave meeting another facet, a series of exact events
/// creates energy without bound (the metallic paint's flake edges): there the event
/// conserves power on its own (docs/physics.md, "Energy at interfaces").
///
/// The weight is flat for small `x` and steep past `x = 1` (a super-Gaussian in
/// `|Delta|`): a film's events, whose `|Delta|` stays well below `a`, keep their exact
/// amplitudes, while ridge tips and flake edges are limited as strongly as before. With
/// `exp(-x)`, the weight of the stop before, a gold film tilted by 1 degree kept 0.976
/// per event, and its series of tens of events lost enough to be 4e-2 off at normal
/// incidence and 650 nm.
///
/// Measured with `a = 0.5` and this weight alone on every event (before
/// [`event_weights`]; tests/tilted_absorbers.rs): the tilted gold roof was within
/// 5.7e-4 of the local transfer-matrix film at 0.1 degree, 1.0e-3 at 0.2, 4.3e-3 at 0.5
/// and 2.5e-2 at 1 (with `exp(-x)`: 9.4e-4, 2.6e-3, 1.4e-2 and 5.6e-2); wavy gold films
/// with slopes to 10 degrees are within 5.2e-4 of the facet-wise film (5.9e-3); the
/// shipped metallic paint and rough gold report the same created and limited power.
/// Without `e`, `a = 0.3` made the paint create 4.5e-3 of the power per tree, and `a =
/// 0.5` 0.13 (refused): its evanescent binder waves meeting the next flake 5-8 degrees off
/// their planes of constant amplitude (`|Delta|` 1.2-1.9) kept part of their amplitudes.
/// (Before, `w` was the homogeneous beamlets' directional overlap over the whole 5 um
/// beamlet, `exp(-(k0 rho deflection)^2 / 8)`, 0.22 for a gold film tilted by 1 degree.)
pub fn recombination_weight(n_re: DVec3, n_im: DVec3, normal: DVec3) -> f64 {
    weight_against(n_re, n_im, normal, n_im.normalize_or_zero())
}

/// The weights of an event of the wave `N = n_re + i n_im` at a facet of normal `normal`,
/// made at a facet of normal `last` (its last interface event; zero for a launched ray):
/// `(w, w0)`. `w0` is [`recombination_weight`], the facet against the wave's own planes of
/// constant amplitude; `w` is the larger of `w0` and the same weight taken against the
/// facet `last` (`Delta = 2 [(N . m) m - (N . m_last) m_last]`), the event's amplitudes'
/// weight.
///
/// A wave bouncing between a film's two faces meeting at `beta` turns its planes of
/// constant amplitude by `2 beta` per round trip, so against them the j-th round trip's
/// facets are tilted by about `2 j beta`: `w0` falls as `exp(-c j^4)` (0.47 at the sixth
/// event of a 20 nm gold film tilted by 1 degree at 650 nm), although each of those waves
/// is an exact plane wave of the wedge, which the facet meets as the last one did. Taken
/// against the facet that made the wave, the tilt stays `beta` (`|Delta| ~ 2 beta |N|`,
/// `w` 0.9994 at 1 degree). At a ridge tip or a flake's edge the facet is far from both the
/// planes of constant amplitude and the facet the wave came from, and `w = w0` is as
/// small as before. The run reports the power that met events with `w0 < 1` as limited
/// (`SimStats::limited`): there the plane-wave model is stretched even where `w` keeps the
/// amplitudes.
///
/// Measured (tests/tilted_absorbers.rs, 256 trees, 0/30/60 degrees, 450-650 nm, worst R or
/// T error against the local transfer-matrix film): a gold film whose faces meet at 0.5
/// degree 1.5e-3 (4.3e-3 with `w = w0` and the estimator before its midpoint amplitudes
/// and flux factor, [`crate::accumulate`]), at 1 degree 1.0e-2 (2.5e-2).
pub fn event_weights(n_re: DVec3, n_im: DVec3, normal: DVec3, last: DVec3) -> (f64, f64) {
    let w0 = recombination_weight(n_re, n_im, normal);
    if last == DVec3::ZERO || w0 == 1.0 {
        return (w0, w0);
    }
    (w0.max(weight_against(n_re, n_im, normal, last)), w0)
}

/// [`recombination_weight`] with `Delta` taken against the unit normal `m0`.
fn weight_against(n_re: DVec3, n_im: DVec3, normal: DVec3, m0: DVec3) -> f64 {
    let change = |v: DVec3| normal * (2.0 * v.dot(normal)) - m0 * (2.0 * v.dot(m0));
    let (re, im) = (change(n_re), change(n_im));
    let d2 = re.length_squared() + im.length_squared();
    if d2 == 0.0 {
        return 1.0;
    }
    let (r2, i2) = (n_re.length_squared(), n_im.length_squared());
    // |N . N| = |N'^2 - N''^2 + 2 i N' . N''| (the medium's n^2 in modulus).
    let evanescence = (r2 + i2) / (r2 - i2).hypot(2.0 * n_re.dot(n_im));
    let a2 = PLANE_WAVE_TILT * PLANE_WAVE_TILT;
    let x = evanescence * d2 / (2.0 * a2);
    (-x * x).exp()
}

/// Notes in `tree` what the split `g` of the field `e` (of ray `r`, at `lambda_nm`) added to
/// the power that entered the event: the children that are pushed (reflected; transmitted
/// where a wave propagates; handed on by a thin film), against the incident field, both
/// polarisations averaged ([`Tree::note_event`]). Called for events from inside an
/// absorber only, the one place where a single event may add power (the interference flux
/// of the incident and reflected waves, `optics::fresnel`, "Power"); every event from a
/// lossless medium conserves `|E|^2` or is limited to it, so power created there is not
/// excess but overflow ([`Tree::overflow`]).
fn note_split(r: &RayState, e: &[Field; 2], g: &LaneSplit, lambda_nm: f64, tree: &mut Tree) {
    let p = |f: &[Field; 2]| 0.5 * (field_power(&f[0]) + field_power(&f[1]));
    let mut p_out = p(&g.er);
    if g.dir_t.is_some() {
        p_out += p(&g.et);
    }
    if g.dir_t2.is_some() {
        p_out += p(&g.et2);
    }
    let att = if r.opl.im != 0.0 {
        (-4.0 * std::f64::consts::PI / lambda_nm * r.opl.im).exp()
    } else {
        1.0
    };
    tree.note_event(p(e), p_out, att);
}
