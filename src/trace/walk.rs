//! The walk of a tree through the scene: launch, segments between the tile's sides and
//! exit planes, wrapping around the periodic tile, and hand-off to the interface and
//! volume events. One path serves one wavelength ([`Scene::trace`]) and many at once
//! ([`Scene::trace_lanes`]).

use super::random::{Volume, roulette};
use super::{
    ALL, Exit, Lane, PATH_START, ROULETTE_AFTER_SEGMENTS, RayState, Scene, TraceLimits, TraceStack,
    Tree, drop_all,
};
use crate::accel::{Intersector, Ray};
use crate::optics::C64;
use crate::optics::fresnel::{self, Field};
use glam::DVec3;

impl Scene<'_> {
    /// Traces one tree at one wavelength. `indices[m]` is medium m's complex index at the
    /// tracing wavelength `lambda_nm` (coated interfaces need it; with path sharing it is
    /// the longest wavelength evaluated, where absorption is weakest), also used to decide
    /// dropping. `e0` are the launched fields (unit power) of the two polarisations;
    /// `origin` lies on the launch plane.
    #[allow(clippy::too_many_arguments)]
    pub fn trace(
        &self,
        origin: DVec3,
        dir: DVec3,
        e0: [Field; 2],
        indices: &[C64],
        lambda_nm: f64,
        limits: &TraceLimits,
        stack: &mut TraceStack,
        out: &mut Tree,
    ) -> u64 {
        self.trace_lanes(
            origin,
            dir,
            e0,
            &[Lane { indices, lambda_nm }],
            limits,
            stack,
            std::slice::from_mut(out),
        )
    }

    /// Traces one tree at every wavelength of `lanes` at once, into `trees[j]` for lane
    /// `j`, and returns the number of segments traced.
    ///
    /// Wavelength sharing: directions change with the wavelength only where a wave
    /// refracts into a medium whose index differs between the lanes (a dispersive one);
    /// reflection keeps the tangential index and the incident medium's normal index
    /// (`fresnel::split_wave`), so a ray in a medium with the same index in every lane is
    /// traced once for all of them, carrying one field per lane, with Fresnel (and coating)
    /// coefficients, the cutoff, the depth and segment limits and the energy checks applied
    /// lane by lane. A refraction into a dispersive medium branches into one ray per lane;
    /// for a metal that is the light that enters it and is absorbed. Each `trees[j]` is
    /// exactly the tree that [`Scene::trace`] at lane `j` alone gives: the same exits and
    /// dropped entries in the same order (tests/wavelength_sharing.rs checks the bits).
    #[allow(clippy::too_many_arguments)]
    pub fn trace_lanes(
        &self,
        origin: DVec3,
        dir: DVec3,
        e0: [Field; 2],
        lanes: &[Lane],
        limits: &TraceLimits,
        stack: &mut TraceStack,
        trees: &mut [Tree],
    ) -> u64 {
        self.launch(origin, dir, e0, lanes, stack, trees);
        let mut traced = 0u64;
        while let Some(mut r) = stack.rays.pop() {
            let Some(first) = take_fields(&r, limits, stack, trees) else {
                continue;
            };
            // The ray's medium has the same index in every lane it carries.
            let n_med = lanes[first].indices[r.medium];
            let mut wraps = 0u32;
            loop {
                traced += 1;
                for (k, f) in stack.cur.iter().enumerate() {
                    if f.is_some() {
                        trees[first + k].segments += 1;
                    }
                }
                let (t_side, axis, t_plane) = self.bounds(&r);
                // Geometry lying exactly on a tile side is searched a little past it.
                let t_side_ext = t_side + self.eps / r.dir[axis].abs().max(1e-12);
                let (prim, surface) = self.surface(&r, t_side_ext.min(t_plane));
                if self.scatters && self.sample.media[r.medium].scattering.is_some() {
                    let t_next = surface.map_or(t_plane.min(t_side), |s| s.0);
                    let cos_ahead = surface.map_or(0.0, |s| r.dir.dot(s.1).abs());
                    match self.volume_event(
                        &mut r, t_next, cos_ahead, n_med, lanes, limits, stack, trees,
                    ) {
                        Volume::Passes => {}
                        Volume::Scattered => {
                            wraps = 0;
                            continue;
                        }
                        Volume::Ended => break,
                    }
                }
                if let Some((t, n)) = surface {
                    self.advance(&mut r, t, n_med, &stack.cur, first, trees);
                    let before = stack.rays.len();
                    self.interface_event(r, prim, n, lanes, limits, stack, trees);
                    if r.nee {
                        // Back in a scattering medium, the light is no longer on the
                        // straight way out that next-event estimation counted.
                        for c in &mut stack.rays[before..] {
                            c.nee &= self.sample.media[c.medium].scattering.is_none();
                        }
                    }
                    // Any lane's tree past the threshold (a shared ray's first lane may
                    // have dropped out while the others grow on).
                    if self.roulette && trees.iter().any(|t| t.segments > ROULETTE_AFTER_SEGMENTS) {
                        roulette(before, lanes, stack, trees);
                    }
                    break;
                }
                if t_plane <= t_side {
                    self.advance(&mut r, t_plane, n_med, &stack.cur, first, trees);
                    leave(&r, n_med, first, &stack.cur, trees);
                    break;
                }
                if !t_side.is_finite() {
                    // Horizontal ray with nowhere to go: cannot happen for finite t_side
                    // unless dir is vertical, which has a finite t_plane. Guard anyway.
                    drop_all(&stack.cur, first, r.opl, trees);
                    break;
                }
                self.advance(&mut r, t_side, n_med, &stack.cur, first, trees);
                if self.sample.guard_nm.is_some() {
                    // An open sample: the light leaves through the side.
                    for (k, f) in stack.cur.iter().enumerate() {
                        if let Some(e) = f {
                            trees[first + k].escape_field(e, r.opl);
                        }
                    }
                    break;
                }
                self.wrap(&mut r, axis);
                wraps += 1;
                if wraps > limits.max_wraps {
                    drop_all(&stack.cur, first, r.opl, trees);
                    break;
                }
            }
        }
        traced
    }

    /// Clears `trees` and `stack` and pushes the launched rays: one per lane, or one ray
    /// carrying every lane where the ambient medium has the same index in all of them.
    fn launch(
        &self,
        origin: DVec3,
        dir: DVec3,
        e0: [Field; 2],
        lanes: &[Lane],
        stack: &mut TraceStack,
        trees: &mut [Tree],
    ) {
        assert!(
            !lanes.is_empty() && lanes.len() == trees.len() && lanes.len() < ALL as usize,
            "one tree per lane"
        );
        for t in trees.iter_mut() {
            t.clear();
        }
        stack.clear();
        let nm = self.sample.media.len();
        stack
            .varies
            .extend((0..nm).map(|m| lanes.iter().any(|l| l.indices[m] != lanes[0].indices[m])));
        for l in lanes {
            debug_assert_eq!(
                l.indices[self.ambient].im, 0.0,
                "the ambient medium is lossless"
            );
        }
        let launch = |lane: u32, n: C64, at: usize| RayState {
            e: e0,
            pos: origin,
            dir,
            n_re: (dir * n.re),
            n_im: DVec3::ZERO,
            off: [0.0; 2],
            medium: self.ambient,
            opl: C64::new(0.0, 0.0),
            depth: 0,
            lane,
            at: at as u32,
            group: 0,
            tube: 1.0,
            path: PATH_START,
            killed: false,
            coherent: 1.0,
            last_facet: DVec3::ZERO,
            nee: false,
        };
        // One lane, or an ambient medium that differs between them: a ray per lane.
        if lanes.len() == 1 || stack.varies[self.ambient] {
            for (j, l) in lanes.iter().enumerate() {
                stack
                    .rays
                    .push(launch(j as u32, l.indices[self.ambient], 0));
            }
        } else {
            stack.fields.extend(lanes.iter().map(|_| Some(e0)));
            stack
                .rays
                .push(launch(ALL, lanes[0].indices[self.ambient], 0));
        }
    }

    /// Distances (nm) along the ray to the nearest tile side and to the exit plane it
    /// heads for: `(t_side, axis of that side, t_plane)`, infinite where it runs parallel.
    pub(super) fn bounds(&self, r: &RayState) -> (f64, usize, f64) {
        let [lx, ly] = self.sample.tile_nm;
        let (mut t_side, mut axis) = (f64::INFINITY, 0usize);
        for (a, l) in [(0usize, lx), (1, ly)] {
            let t = if r.dir[a] > 0.0 {
                (l - r.pos[a]) / r.dir[a]
            } else if r.dir[a] < 0.0 {
                -r.pos[a] / r.dir[a]
            } else {
                f64::INFINITY
            };
            if t < t_side {
                t_side = t;
                axis = a;
            }
        }
        let t_plane = if r.dir[2] > 0.0 {
            (self.z_top - r.pos[2]) / r.dir[2]
        } else if r.dir[2] < 0.0 {
            (self.z_bottom - r.pos[2]) / r.dir[2]
        } else {
            f64::INFINITY
        };
        (t_side, axis, t_plane)
    }

    /// The closest surface within `t_lim` nm: the triangle and, when hit, the distance
    /// refined in f64 against the triangle's plane (the accelerator finds in f32) and the
    /// plane's unit normal.
    ///
    /// A ray just wrapped starts `eps` outside the tile (`wrap`), where no triangle lies:
    /// the stretch of it outside the tile is searched over its periodic image, the
    /// opposite side's geometry (issue 71: a ray crossing a flat interface within that
    /// sliver passed it unseen and went on in the wrong medium, a leak, 4 in 7,680 trees
    /// of a hiding chart).
    pub(super) fn surface(&self, r: &RayState, t_lim: f64) -> (u32, Option<(f64, DVec3)>) {
        let mut best = self.surface_from(r.pos, r.dir, t_lim);
        for (a, l) in self.sample.tile_nm.into_iter().enumerate() {
            let (shift, t_in) = if r.pos[a] < 0.0 && r.dir[a] > 0.0 {
                (l, -r.pos[a] / r.dir[a])
            } else if r.pos[a] > l && r.dir[a] < 0.0 {
                (-l, (l - r.pos[a]) / r.dir[a])
            } else {
                continue;
            };
            let mut image = r.pos;
            image[a] += shift;
            let found = self.surface_from(image, r.dir, t_in.min(t_lim));
            if let Some((t, _)) = found.1
                && best.1.is_none_or(|(tb, _)| t < tb)
            {
                best = found;
            }
        }
        best
    }

    fn surface_from(&self, pos: DVec3, dir: DVec3, t_lim: f64) -> (u32, Option<(f64, DVec3)>) {
        let ray = Ray {
            origin: pos.as_vec3().to_array(),
            tmin: 0.0,
            dir: dir.as_vec3().to_array(),
            tmax: t_lim.min(f64::from(f32::MAX)) as f32,
        };
        let hit = self.accel.closest_hit(&ray);
        let surface = (hit.is_hit() && f64::from(hit.t) <= t_lim * (1.0 + 1e-6)).then(|| {
            let (v0, n) = self.plane[hit.prim as usize];
            let denom = n.dot(dir);
            let mut t = if denom != 0.0 {
                n.dot(v0 - pos) / denom
            } else {
                f64::from(hit.t)
            };
            if !(t.is_finite() && t >= 0.0) {
                t = f64::from(hit.t);
            }
            (t, n)
        });
        (hit.prim, surface)
    }

    /// Wraps the ray around the tile side it reached on `axis`, re-entering a little
    /// outside the opposite side. The unwrapped position steps back by the re-entry
    /// margin: the plane wave's phase stays exact there too.
    pub(super) fn wrap(&self, r: &mut RayState, axis: usize) {
        let l = self.sample.tile_nm[axis];
        let before = r.pos[axis] + r.off[axis];
        if r.dir[axis] > 0.0 {
            r.pos[axis] = -self.eps;
            r.off[axis] += l;
        } else {
            r.pos[axis] = l + self.eps;
            r.off[axis] -= l;
        }
        let jump = r.pos[axis] + r.off[axis] - before;
        r.opl += C64::new(r.n_re[axis] * jump, r.n_im[axis] * jump);
    }

    /// Moves the ray by `t` nm, adding `N . dr` to its optical path (the phase and the
    /// attenuation of its plane wave, docs/design.md §3); the lanes it carries (`cur`, the
    /// first being lane `first`) note power entering an absorbing medium.
    #[inline]
    pub(super) fn advance(
        &self,
        r: &mut RayState,
        t: f64,
        n: C64,
        cur: &[Option<[Field; 2]>],
        first: usize,
        trees: &mut [Tree],
    ) {
        let step = r.dir * t;
        if n.im == 0.0 {
            // A lossless medium carries homogeneous waves: `N . dr = n t`.
            r.opl += n * t;
        } else {
            let im = r.n_im.dot(step);
            r.opl += C64::new(r.n_re.dot(step), im);
            if im > 0.0 {
                for (k, f) in cur.iter().enumerate() {
                    if f.is_some() {
                        trees[first + k].absorbing = true;
                    }
                }
            }
        }
        r.pos += step;
    }
}

/// Takes the fields of the popped ray `r` into `stack.cur` (a shared ray's are the top of
/// the field stack, pushed with it; a single lane's ray carries its own) and drops those
/// of trees past the segment limit. Returns the lane of the first field, or `None` when
/// nothing is left to trace.
fn take_fields(
    r: &RayState,
    limits: &TraceLimits,
    stack: &mut TraceStack,
    trees: &mut [Tree],
) -> Option<usize> {
    stack.cur.clear();
    if r.lane == ALL {
        stack.cur.extend(stack.fields.drain(r.at as usize..));
    } else if !r.killed {
        stack.cur.push(Some(r.e));
    }
    if r.killed {
        return None;
    }
    // `first + k`: the lane of the ray's k-th field.
    let first = if r.lane == ALL { 0 } else { r.lane as usize };
    for (k, f) in stack.cur.iter_mut().enumerate() {
        let t = &mut trees[first + k];
        if let Some(e) = f
            && t.segments >= limits.max_segments
        {
            t.drop_field(e, r.opl, true);
            *f = None;
        }
    }
    (!stack.cur.iter().all(Option::is_none)).then_some(first)
}

/// The ray `r`, in a medium of index `n_med`, has reached an exit plane: its fields
/// (`cur`, lanes from `first`) leave the sample, upwards or downwards, except into a
/// semi-infinite absorbing substrate, which absorbs everything that enters it (nothing
/// reaches infinity below; the exit plane is only where the tile ends), and except light
/// that next-event estimation already counted (`RayState::nee`).
fn leave(r: &RayState, n_med: C64, first: usize, cur: &[Option<[Field; 2]>], trees: &mut [Tree]) {
    let up = r.dir[2] > 0.0;
    if up && r.nee {
        // Next-event estimation counted this light at its last volume event (`escape`).
        return;
    }
    let absorbed = !up && n_med.im > 0.0;
    let x = DVec3::new(r.pos.x + r.off[0], r.pos.y + r.off[1], r.pos.z);
    for (k, f) in cur.iter().enumerate() {
        let Some(e) = f else { continue };
        let t = &mut trees[first + k];
        if absorbed {
            t.absorbing = true;
        } else {
            let e = if r.n_im == DVec3::ZERO || n_med.im != 0.0 {
                *e
            } else {
                e.map(|f| fresnel::on_power_basis(&f, r.n_re, r.n_im, n_med.re))
            };
            t.exits.push(Exit {
                e,
                opl: r.opl,
                dir: r.dir,
                n_im: r.n_im * r.coherent,
                x,
                up,
                group: r.group,
                tube: r.tube,
                path: r.path,
            });
        }
    }
}
