//! Coherent ray trees through a periodic sample (docs/design.md §3).
//!
//! A tree starts as one ray of a plane wave on the launch plane above the sample and splits
//! at every interface into a reflected and a transmitted child, each carrying the complex
//! electric field of two orthogonal incident polarisations, power-normalised so `|E|^2` is
//! the fraction of launched power where the wave is in a lossless medium, the complex
//! index vector `N` of its (possibly inhomogeneous) plane wave, and the complex optical
//! path length `sum N . dr` (nm) from the launch plane (`optics::fresnel` has the wave
//! model: inside an absorbing medium the attenuation follows the depth below the interface
//! the wave entered through, not the ray length). A child is dropped below a power cutoff or at a depth limit;
//! dropped power is recorded, never hidden. Rays wrap around the tile's sides with their
//! unwrapped offset kept for the phase; hits are refined in f64 against the triangle's
//! plane; the current medium is tracked and every mismatch (a leak) is counted.
//!
//! Propagation phases are kept out of the fields: a tree's exit amplitude at wavelength
//! `lambda` is `E * exp(i 2 pi OPL / lambda)`. When no medium is dispersive the Fresnel
//! coefficients do not depend on wavelength either, so one traced tree serves every
//! wavelength (spectral path sharing). Otherwise [`Scene::trace_lanes`] traces every
//! wavelength of a tree at once, sharing each ray until it refracts into a dispersive
//! medium and evaluating the coefficients per wavelength along it (wavelength sharing).

use crate::accel::{Accel, AccelError, Backend, Intersector, Ray};
use crate::optics::C64;
use crate::optics::fresnel::{self, Field, field_power};
use crate::optics::particles::ScatterModel;
use crate::optics::tmm;
use crate::rng::Rng;
use crate::sample::Sample;
use glam::DVec3;

mod random;
mod tree;

pub use random::{ROULETTE_AFTER_SEGMENTS, ROULETTE_BELOW};
use random::{Volume, roulette};
pub use tree::{Dropped, DroppedPower, Exit, Tree};

/// Limits of a tree.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TraceLimits {
    /// A child whose power falls below this fraction of the launched power is dropped.
    pub cutoff: f64,
    /// Interface events along one path before it is dropped.
    pub max_depth: u32,
    /// Tile-side crossings of one segment chain before it is dropped (rays running
    /// nearly parallel to the layers).
    pub max_wraps: u32,
    /// Traced segments of one tree before its remaining rays are dropped: a guard against
    /// the exponential growth of trees in multiply scattering samples (pigments, flakes).
    pub max_segments: u32,
}

impl TraceLimits {
    /// The default power cutoff: a dropped child's amplitude (the square root) enters the
    /// coherent sum, so 1e-10 keeps its effect on R near 1e-5.
    pub const CUTOFF: f64 = 1e-10;
    pub const MAX_DEPTH: u32 = 64;
    pub const MAX_WRAPS: u32 = 10_000;
    pub const MAX_SEGMENTS: u32 = 20_000;
}

impl Default for TraceLimits {
    fn default() -> Self {
        TraceLimits {
            cutoff: Self::CUTOFF,
            max_depth: Self::MAX_DEPTH,
            max_wraps: Self::MAX_WRAPS,
            max_segments: Self::MAX_SEGMENTS,
        }
    }
}

/// A sample prepared for tracing: its accelerator, per-triangle f64 geometry and the
/// media above and below it.
pub struct Scene<'a> {
    pub sample: &'a Sample,
    accel: Accel,
    /// Per triangle: owning interface.
    owner: Vec<u32>,
    /// Per triangle: a vertex and the unit normal, f64.
    plane: Vec<(DVec3, DVec3)>,
    /// Launch / top exit plane and bottom exit plane, nm.
    pub z_top: f64,
    pub z_bottom: f64,
    /// Offset that moves a new ray off its surface, nm.
    eps: f64,
    /// Medium above everything and below everything.
    pub ambient: usize,
    pub substrate: usize,
    /// The length over which the illumination is coherent, nm: the beamlet radius of a
    /// finite-radius estimator, else the tile's longer side (`set_coherence_length`).
    coherence_nm: f64,
    /// Per medium: its volume scattering, once [`Scene::prepare_scattering`] has
    /// tabulated it (`None` for a clear medium).
    scatter: Vec<Option<ScatterModel>>,
    /// Whether some medium scatters.
    scatters: bool,
    /// Whether long trees play Russian roulette: samples with bodies (flakes, pigments) or
    /// scattering media only. A meshed multilayer's long series is one coherent sum whose
    /// deep terms matter (its cross terms are not small): it keeps every branch and is
    /// refused when the limits cut it.
    roulette: bool,
}

/// Why a scene cannot be traced.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error(transparent)]
    Accel(#[from] AccelError),
    #[error("{0}")]
    Geometry(String),
}

impl<'a> Scene<'a> {
    pub fn new(sample: &'a Sample, backend: Backend) -> Result<Scene<'a>, SceneError> {
        let (soup, first) = sample.triangle_soup();
        let accel = Accel::build(backend, &soup)?;
        let mut owner = Vec::with_capacity(soup.triangles.len());
        let mut plane = Vec::with_capacity(soup.triangles.len());
        let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for (i, itf) in sample.interfaces.iter().enumerate() {
            let m = &itf.mesh;
            for k in 0..m.triangles.len() {
                let v0 = m.positions_nm[m.triangles[k][0] as usize];
                owner.push(i as u32);
                plane.push((v0, m.area_vector(k).normalize()));
            }
            if let Some((a, b)) = m.bounds() {
                lo = lo.min(a);
                hi = hi.max(b);
            }
        }
        debug_assert_eq!(
            owner.len(),
            first.last().map_or(0, |&f| f as usize)
                + sample
                    .interfaces
                    .last()
                    .map_or(0, |i| i.mesh.triangles.len())
        );
        let [lx, ly] = sample.tile_nm;
        let extent = lx.max(ly).max(hi[2] - lo[2]);
        let eps = (1e-7 * extent).max(1e-4);
        let margin = 1e-3 * extent + 1.0;
        let mut scene = Scene {
            sample,
            accel,
            owner,
            plane,
            z_top: hi[2] + margin,
            z_bottom: lo[2] - margin,
            eps,
            ambient: 0,
            substrate: 0,
            coherence_nm: lx.max(ly),
            scatter: Vec::new(),
            scatters: sample.media.iter().any(|m| m.scattering.is_some()),
            roulette: sample.media.iter().any(|m| m.scattering.is_some())
                || sample.interfaces.iter().any(|i| i.closed),
        };
        scene.ambient = scene.outer_medium(true)?;
        scene.substrate = scene.outer_medium(false)?;
        Ok(scene)
    }

    /// Sets the length over which the illumination is coherent (nm, finite and positive;
    /// anything else keeps the tile's longer side): the scale against which an event
    /// inside an absorber judges whether its partial waves recombine
    /// ([`recombination_weight`]).
    pub fn set_coherence_length(&mut self, nm: f64) {
        if nm.is_finite() && nm > 0.0 {
            self.coherence_nm = nm;
        }
    }

    /// The medium beyond the sample above (or below) it, from vertical probe rays; the
    /// probes must agree.
    fn outer_medium(&self, above: bool) -> Result<usize, SceneError> {
        let [lx, ly] = self.sample.tile_nm;
        let mut found: Option<usize> = None;
        for k in 0..9 {
            let (fx, fy) = (0.123 + 0.1 * k as f64, 0.317 + 0.071 * k as f64);
            let (z, dz) = if above {
                (self.z_top, -1.0)
            } else {
                (self.z_bottom, 1.0)
            };
            let ray = Ray::new(
                [(fx * lx) as f32, ((fy % 1.0) * ly) as f32, z as f32],
                [0.0, 0.0, dz as f32],
            );
            let h = self.accel.closest_hit(&ray);
            if !h.is_hit() {
                continue;
            }
            let itf = &self.sample.interfaces[self.owner[h.prim as usize] as usize];
            let facing_front = (f64::from(h.ng[2]) * dz) < 0.0;
            let m = if facing_front { itf.front } else { itf.back };
            if let Some(f) = found
                && f != m
            {
                return Err(SceneError::Geometry(format!(
                    "the sample's {} side is not one medium ('{}' and '{}'); run goniospec check",
                    if above { "upper" } else { "lower" },
                    self.sample.media[f].name,
                    self.sample.media[m].name
                )));
            }
            found = Some(m);
        }
        found.ok_or_else(|| {
            SceneError::Geometry(format!(
                "vertical rays from {} miss the sample: no sheet covers the tile",
                if above { "above" } else { "below" }
            ))
        })
    }

    pub fn backend(&self) -> Backend {
        self.accel.backend()
    }

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
        let [lx, ly] = self.sample.tile_nm;
        let mut traced = 0u64;
        while let Some(mut r) = stack.rays.pop() {
            // A shared ray's fields are the top of the field stack (pushed with it); a
            // single lane's ray carries its own.
            stack.cur.clear();
            if r.lane == ALL {
                stack.cur.extend(stack.fields.drain(r.at as usize..));
            } else if !r.killed {
                stack.cur.push(Some(r.e));
            }
            if r.killed {
                continue;
            }
            // `lane_of(k)`: the lane of the ray's k-th field.
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
            if stack.cur.iter().all(Option::is_none) {
                continue;
            }
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
                // Distances to the tile's sides and to the exit plane along dir.
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
                // Geometry lying exactly on a tile side is searched a little past it.
                let t_side_ext = t_side + self.eps / r.dir[axis].abs().max(1e-12);
                let t_lim = t_side_ext.min(t_plane);
                let ray = Ray {
                    origin: r.pos.as_vec3().to_array(),
                    tmin: 0.0,
                    dir: r.dir.as_vec3().to_array(),
                    tmax: t_lim.min(f64::from(f32::MAX)) as f32,
                };
                let hit = self.accel.closest_hit(&ray);
                let surface =
                    (hit.is_hit() && f64::from(hit.t) <= t_lim * (1.0 + 1e-6)).then(|| {
                        // Refine in f64 against the hit triangle's plane.
                        let (v0, n) = self.plane[hit.prim as usize];
                        let denom = n.dot(r.dir);
                        let mut t = if denom != 0.0 {
                            n.dot(v0 - r.pos) / denom
                        } else {
                            f64::from(hit.t)
                        };
                        if !(t.is_finite() && t >= 0.0) {
                            t = f64::from(hit.t);
                        }
                        (t, n)
                    });
                if self.scatters && self.sample.media[r.medium].scattering.is_some() {
                    let t_next = surface.map_or(t_plane.min(t_side), |s| s.0);
                    match self.volume_event(&mut r, t_next, n_med, lanes, limits, stack, trees) {
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
                    self.interface_event(r, hit.prim, n, lanes, limits, stack, trees);
                    // Any lane's tree past the threshold (a shared ray's first lane may
                    // have dropped out while the others grow on).
                    if self.roulette && trees.iter().any(|t| t.segments > ROULETTE_AFTER_SEGMENTS) {
                        roulette(before, lanes, stack, trees);
                    }
                    break;
                }
                if t_plane <= t_side {
                    self.advance(&mut r, t_plane, n_med, &stack.cur, first, trees);
                    let up = r.dir[2] > 0.0;
                    let absorbed = !up && n_med.im > 0.0;
                    let x = DVec3::new(r.pos.x + r.off[0], r.pos.y + r.off[1], r.pos.z);
                    for (k, f) in stack.cur.iter().enumerate() {
                        let Some(e) = f else { continue };
                        let t = &mut trees[first + k];
                        if absorbed {
                            // A semi-infinite absorbing substrate absorbs everything that
                            // enters it: nothing reaches infinity below (the exit plane is
                            // only where the tile ends).
                            t.absorbing = true;
                        } else {
                            t.exits.push(Exit {
                                e: *e,
                                opl: r.opl,
                                dir: r.dir,
                                x,
                                up,
                                group: r.group,
                                tube: r.tube,
                                path: r.path,
                            });
                        }
                    }
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
                // Wrap around the tile side; re-enter a little outside the opposite side.
                // The unwrapped position steps back by the re-entry margin: keep the plane
                // wave's phase exact there too.
                let l = [lx, ly][axis];
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
                wraps += 1;
                if wraps > limits.max_wraps {
                    drop_all(&stack.cur, first, r.opl, trees);
                    break;
                }
            }
        }
        traced
    }

    /// Moves the ray by `t` nm, adding `N . dr` to its optical path (the phase and the
    /// attenuation of its plane wave, docs/design.md §3); the lanes it carries (`cur`, the
    /// first being lane `first`) note power entering an absorbing medium.
    #[inline]
    fn advance(
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

    /// Splits the ray `r` at an interface, lane by lane, and pushes its children.
    #[allow(clippy::too_many_arguments)]
    fn interface_event(
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
        let TraceStack {
            rays,
            fields,
            splits,
            varies,
            cur,
            ..
        } = stack;
        // Written in place (a split is a few hundred bytes); `splits[k]` is valid where
        // `cur[k]` holds a field.
        if splits.len() < cur.len() {
            splits.resize_with(cur.len(), LaneSplit::default);
        }
        for (k, f) in cur.iter().enumerate() {
            if let Some(e) = f {
                let j = first + k;
                self.lane_split(
                    itf,
                    &r,
                    nf,
                    from,
                    to,
                    e,
                    &lanes[j],
                    &mut trees[j],
                    &mut splits[k],
                );
            }
        }
        // The lanes' splits, `None` where the lane dropped the ray.
        let lane_splits = || {
            cur.iter()
                .zip(splits.iter())
                .map(|(f, g)| f.is_some().then_some(g))
        };
        let depth = r.depth + 1;
        // Whether lane j keeps a child of field `e`: below the cutoff or past the depth
        // limit its power is dropped (recorded in its tree).
        let keep = |tree: &mut Tree, e: &[Field; 2], j: usize| -> bool {
            let mut power = field_power(&e[0]).max(field_power(&e[1]));
            // Attenuated along the path so far (exactly 1 on a lossless path: no call).
            if r.opl.im != 0.0 {
                power *= (-4.0 * std::f64::consts::PI / lanes[j].lambda_nm * r.opl.im).exp();
            }
            if power < limits.cutoff {
                tree.drop_field(e, r.opl, false);
                false
            } else if depth > limits.max_depth {
                tree.drop_field(e, r.opl, true);
                false
            } else {
                true
            }
        };
        // The child starts a little off the surface; its plane wave's phase there is `N .
        // offset` past the hit point, so the path stays exact however thin the layer (a 5
        // nm film would otherwise lose 2 eps of thickness per round trip).
        let child = |dir: DVec3,
                     wave: (DVec3, DVec3),
                     medium: usize,
                     side: f64,
                     lane,
                     at: usize,
                     e: [Field; 2]| {
            let offset = nf * (side * self.eps);
            let shift = C64::new(wave.0.dot(offset), wave.1.dot(offset));
            RayState {
                e,
                pos: (r.pos + offset),
                dir,
                n_re: wave.0,
                n_im: wave.1,
                off: r.off,
                medium,
                opl: r.opl + shift,
                depth,
                lane,
                at: at as u32,
                group: r.group,
                // A plane interface shares the footprint of the tube on either side, so a
                // refracted tube's cross-section scales by cos(theta_t) / cos(theta_i).
                tube: if side < 0.0 {
                    r.tube * dir.dot(nf).abs() / r.dir.dot(nf).abs().max(1e-300)
                } else {
                    r.tube
                },
                path: (r.path ^ (u64::from(prim) << 1 | u64::from(side < 0.0)))
                    .wrapping_mul(0x0000_0100_0000_01B3),
                killed: false,
            }
        };
        // Transmitted children first so the reflected one is traced first (stack order
        // does not change results; it keeps the stack shallow for films). Under total
        // internal reflection into a lossless medium no wave propagates and T = 0.
        if r.lane != ALL || varies[to] {
            // One ray per lane: its own direction into the dispersive medium.
            for (k, s) in lane_splits().enumerate() {
                let Some(g) = s else { continue };
                let Some(dt) = g.dir_t else { continue };
                let j = first + k;
                if keep(&mut trees[j], &g.et, j) {
                    rays.push(child(dt, g.n_t, to, -1.0, j as u32, 0, g.et));
                }
            }
        } else if let Some(g) = lane_splits().flatten().next()
            && let Some(dt) = g.dir_t
        {
            // Every lane refracts alike into a medium of the same index in each.
            let (wave, at) = (g.n_t, fields.len());
            let mut any = false;
            for (j, s) in lane_splits().enumerate() {
                let kept = s.and_then(|g| keep(&mut trees[j], &g.et, j).then_some(g.et));
                any |= kept.is_some();
                fields.push(kept);
            }
            if any {
                rays.push(child(dt, wave, to, -1.0, ALL, at, [[C64::ZERO; 3]; 2]));
            } else {
                fields.truncate(at);
            }
        }
        // The reflected wave stays in `from`, whose index is the same in every lane the
        // ray carries, and its direction does not depend on the far side's index.
        let Some(g) = lane_splits().flatten().next() else {
            return;
        };
        let (dir_r, wave, at) = (g.dir_r, g.n_r, fields.len());
        if r.lane != ALL {
            if keep(&mut trees[first], &g.er, first) {
                rays.push(child(dir_r, wave, from, 1.0, r.lane, 0, g.er));
            }
            return;
        }
        let mut any = false;
        for (k, s) in lane_splits().enumerate() {
            let kept =
                s.and_then(|g| keep(&mut trees[first + k], &g.er, first + k).then_some(g.er));
            any |= kept.is_some();
            fields.push(kept);
        }
        if any {
            rays.push(child(dir_r, wave, from, 1.0, ALL, at, [[C64::ZERO; 3]; 2]));
        } else {
            fields.truncate(at);
        }
    }

    /// One lane's split of ray `r` (field `e`) at interface `itf` (normal `nf` facing the
    /// ray, from medium `from` to `to`): the coefficients (coated where the interface
    /// carries thin layers), the energy checks, and the children's fields; notes absorption
    /// and faults in the lane's `tree`.
    #[allow(clippy::too_many_arguments)]
    fn lane_split(
        &self,
        itf: &crate::sample::Interface,
        r: &RayState,
        nf: DVec3,
        from: usize,
        to: usize,
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
            let nc = itf.coating.len();
            for i in 0..nc {
                let (m, d) = itf.coating[if from == itf.front { i } else { nc - 1 - i }];
                tree.n_buf.push(indices[m]);
                tree.d_buf.push(d);
                coating_absorbs |= indices[m].im > 0.0;
            }
            tree.n_buf.push(n2);
            let amp = tmm::amplitudes(&tree.n_buf, &tree.d_buf, g.kappa, lambda_nm);
            g.c = fresnel::coated(&g.c, amp);
            if coating_absorbs {
                tree.absorbing = true;
            }
        }
        if g.k_im > 0.0 {
            // The wave's amplitude varies along this facet (it entered through a facet
            // not parallel to this one): its partial waves recombine only in part.
            let w = recombination_weight(g.k_im, lambda_nm, self.coherence_nm);
            if fresnel::limit_excess(&mut g.c, w) {
                tree.limited += 1;
                // The incident power, attenuated along the path, that met an event whose
                // amplitudes are a model rather than the exact plane-wave ones.
                let mut p = field_power(&e[0]).max(field_power(&e[1]));
                if r.opl.im != 0.0 {
                    p *= (-4.0 * std::f64::consts::PI / lambda_nm * r.opl.im).exp();
                }
                tree.limited_power += p * (1.0 - w);
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
        out.dir_r = g.dir_r;
        out.n_r = g.n_r;
        out.dir_t = g.dir_t;
        out.n_t = g.n_t;
    }
}

/// The weight in [0, 1] with which the partial waves of an event recombine, for an
/// incident wave whose amplitude changes along the facet at the rate `k_im` (`|Im K|`,
/// in units of `k0 = 2 pi / lambda`), under illumination coherent over `coherence_nm`:
/// `exp(-x^2 / 2)` with `x = k0 k_im coherence_nm`, the number of e-foldings of the
/// wave's amplitude across the coherent area. A film whose faces are parallel has `x = 0`
/// and keeps the exact amplitudes (its series recombines into the transfer-matrix field);
/// a slightly tilted face keeps them to second order in the tilt; a ridge tip, where the
/// wave enters by one face and meets another at a large angle, has `x` in the hundreds,
/// its partial waves leave in directions that never interfere, and the event conserves
/// power on its own (docs/physics.md, "Energy at interfaces").
pub fn recombination_weight(k_im: f64, lambda_nm: f64, coherence_nm: f64) -> f64 {
    let x = 2.0 * std::f64::consts::PI / lambda_nm * k_im * coherence_nm;
    (-0.5 * x * x).exp()
}

/// Drops every field the ray carries (`cur`, lanes from `first`) by a limit or a leak.
fn drop_all(cur: &[Option<[Field; 2]>], first: usize, opl: C64, trees: &mut [Tree]) {
    for (k, f) in cur.iter().enumerate() {
        if let Some(e) = f {
            trees[first + k].drop_field(e, opl, true);
        }
    }
}

/// One wavelength of a spectral trace: every medium's complex index there and the
/// wavelength (nm).
#[derive(Clone, Copy, Debug)]
pub struct Lane<'a> {
    pub indices: &'a [C64],
    pub lambda_nm: f64,
}

/// One lane's split at an interface: the children's directions and complex index
/// vectors, and their fields of the two polarisations.
#[derive(Default)]
struct LaneSplit {
    dir_r: DVec3,
    n_r: (DVec3, DVec3),
    dir_t: Option<DVec3>,
    n_t: (DVec3, DVec3),
    er: [Field; 2],
    et: [Field; 2],
}

/// `RayState::lane` of a ray that carries every lane.
const ALL: u32 = u32::MAX;

/// A tracer's reusable state: rays in flight, the fields of shared rays (a stack parallel
/// to the rays': one field pair per lane, `None` where that lane dropped it), and
/// scratch.
#[derive(Default)]
pub struct TraceStack {
    rays: Vec<RayState>,
    fields: Vec<Option<[Field; 2]>>,
    cur: Vec<Option<[Field; 2]>>,
    splits: Vec<LaneSplit>,
    /// Per medium: whether its index differs between the lanes.
    varies: Vec<bool>,
    /// Free paths and scattering directions in particle media, and Russian roulette
    /// ([`TraceStack::set_stream`]).
    rng: Rng,
    /// Coherence groups handed out in this tree (random events start one each).
    groups: u32,
}

impl TraceStack {
    /// Seeds the random stream volume scattering draws from (the driver gives every tree
    /// and wavelength its own, so results do not depend on scheduling). Tracing without
    /// particle media draws nothing.
    pub fn set_stream(&mut self, seed: u64, stream: u64) {
        self.rng = Rng::new(seed, stream);
    }

    fn clear(&mut self) {
        self.rays.clear();
        self.fields.clear();
        self.cur.clear();
        self.varies.clear();
        self.groups = 0;
    }
}

/// [`Exit::path`] of a launched ray (the FNV-1a offset basis; each event is mixed in as
/// FNV-1a mixes a byte, `(h ^ x) * 0x100000001b3`).
const PATH_START: u64 = 0xCBF2_9CE4_8422_2325;

/// A ray in flight.
#[derive(Clone, Copy, Debug)]
struct RayState {
    pos: DVec3,
    /// Unit direction of travel: the real part of the index vector, normalised.
    dir: DVec3,
    /// Complex index vector of the ray's plane wave (`optics::fresnel`): real part and
    /// imaginary part (the latter normal to the interface the wave entered through).
    n_re: DVec3,
    n_im: DVec3,
    /// Unwrapped offset of the current tile copy, nm.
    off: [f64; 2],
    medium: usize,
    opl: C64,
    depth: u32,
    /// The lane it carries, or [`ALL`].
    lane: u32,
    /// A single lane's ray: its field of each polarisation.
    e: [Field; 2],
    /// A shared ray: where its fields (one pair per lane) start on the field stack.
    at: u32,
    /// Coherence group ([`Exit::group`]).
    group: u32,
    /// Cross-section of the ray's tube relative to the launched one ([`Exit::tube`]).
    tube: f64,
    /// The facets it met and how (reflected or transmitted), hashed ([`Exit::path`]).
    path: u64,
    /// Ended by Russian roulette: popped and discarded.
    killed: bool,
}

/// The two launched fields for a wave travelling along `d` (unit): s (perpendicular to the
/// plane of incidence) and p, each of unit power.
pub fn launch_fields(d: DVec3) -> [Field; 2] {
    let c = d.cross(DVec3::Z);
    let s = if c.length() > 1e-12 {
        c.normalize()
    } else {
        DVec3::X
    };
    let p = s.cross(d);
    let f = |v: DVec3| v.to_array().map(|x| C64::new(x, 0.0));
    [f(s), f(p)]
}
