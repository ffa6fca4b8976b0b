//! The children of an interface event onto the trace stack: the transmitted, handed-on
//! and reflected waves of each lane's split, as one ray per lane or one ray shared by
//! every lane, with the power of those below the cutoff or past the depth limit recorded
//! as dropped.

use super::film::FilmBack;
use super::{ALL, C64, Field, Lane, LaneSplit, RayState, Scene, TraceLimits, TraceStack, Tree};
use crate::optics::fresnel::field_power;
use glam::DVec3;

impl Scene<'_> {
    /// Pushes the children of ray `r` split at facet `prim` (normal `nf` facing the ray,
    /// from medium `from` to `to`), from the lanes' splits in `stack.splits`: the
    /// transmitted ones first (one per lane into a medium whose index varies between the
    /// lanes, else one shared ray), then those a thin film hands on from its far face
    /// `back` ([`super::film`]), then the reflected one; each carries `coherent`, the
    /// product of the recombination weights on its path ([`recombination_weight`]). A
    /// child below the power cutoff or past the depth limit is dropped and recorded in its
    /// lane's tree ([`Litter::keep`]). Transmitted children go first so that the reflected
    /// one is traced first: stack order does not change results, and it keeps the stack
    /// shallow for films.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn push_children(
        &self,
        r: &RayState,
        prim: u32,
        nf: DVec3,
        from: usize,
        to: usize,
        back: Option<&FilmBack>,
        coherent: f64,
        lanes: &[Lane],
        limits: &TraceLimits,
        stack: &mut TraceStack,
        trees: &mut [Tree],
    ) {
        let TraceStack {
            rays,
            fields,
            splits,
            varies,
            cur,
            ..
        } = stack;
        let birth = Birth {
            r,
            prim,
            nf,
            depth: r.depth + 1,
            coherent,
            eps: self.eps,
        };
        let mut litter = Litter {
            first: if r.lane == ALL { 0 } else { r.lane as usize },
            per_lane: r.lane != ALL,
            cur,
            splits,
            rays,
            fields,
            trees,
            lanes,
            limits,
            r,
            depth: birth.depth,
        };
        // Transmitted: under total internal reflection into a lossless medium no wave
        // propagates and T = 0. Every lane refracts alike into a medium of the same index
        // in each; into a dispersive one each lane takes its own direction.
        let lead = litter
            .splits()
            .flatten()
            .next()
            .and_then(|g| g.dir_t.map(|d| (d, g.n_t)));
        litter.push(
            varies[to],
            lead,
            |g| g.dir_t.map(|d| (d, g.n_t, g.et)),
            |g| Some(g.et),
            |dir, wave, lane, at, e| birth.at_facet(dir, wave, to, -1.0, lane, at, e),
        );
        // The light a thin film hands on (`super::film`): it leaves the film's far face,
        // into the medium beyond, at the point the probe found. Every lane that hands on
        // leaves in the same direction unless the medium beyond is dispersive.
        if let Some(b) = back {
            let lead = litter
                .splits()
                .flatten()
                .find_map(|g| g.dir_t2.map(|d| (d, g.n_t2)));
            litter.push(
                varies[b.beyond],
                lead,
                |g| g.dir_t2.map(|d| (d, g.n_t2, g.et2)),
                |g| g.dir_t2.map(|_| g.et2),
                |dir, wave, lane, at, e| birth.at_far_face(b, dir, wave, lane, at, e),
            );
        }
        // The reflected wave stays in `from`, whose index is the same in every lane the
        // ray carries, and its direction does not depend on the far side's index.
        let lead = litter.splits().flatten().next().map(|g| (g.dir_r, g.n_r));
        litter.push(
            false,
            lead,
            |g| Some((g.dir_r, g.n_r, g.er)),
            |g| Some(g.er),
            |dir, wave, lane, at, e| birth.at_facet(dir, wave, from, 1.0, lane, at, e),
        );
    }
}

/// What every child of one interface event shares: its parent, the facet it is born at
/// (`prim`, normal `nf` facing the parent), its depth, and the product of the
/// recombination weights on its path.
struct Birth<'r> {
    r: &'r RayState,
    prim: u32,
    nf: DVec3,
    depth: u32,
    coherent: f64,
    /// How far off the surface a child starts, nm ([`Scene`]'s epsilon).
    eps: f64,
}

impl Birth<'_> {
    /// A child leaving the facet into `medium` along `dir` with plane wave `wave` (real and
    /// imaginary index vectors): reflected (`side` 1) or transmitted (`side` -1). It starts
    /// a little off the surface, and its plane wave's phase there is `N . offset` past the
    /// hit point, so the path stays exact however thin the layer (a 5 nm film would
    /// otherwise lose 2 eps of thickness per round trip). A plane interface shares the
    /// footprint of the tube on either side, so a refracted tube's cross-section scales by
    /// `cos(theta_t) / cos(theta_i)`.
    #[allow(clippy::too_many_arguments)]
    fn at_facet(
        &self,
        dir: DVec3,
        wave: (DVec3, DVec3),
        medium: usize,
        side: f64,
        lane: u32,
        at: usize,
        e: [Field; 2],
    ) -> RayState {
        let (r, nf) = (self.r, self.nf);
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
            depth: self.depth,
            lane,
            at: at as u32,
            group: r.group,
            tube: if side < 0.0 {
                r.tube * dir.dot(nf).abs() / r.dir.dot(nf).abs().max(1e-300)
            } else {
                r.tube
            },
            path: (r.path ^ (u64::from(self.prim) << 1 | u64::from(side < 0.0)))
                .wrapping_mul(0x0000_0100_0000_01B3),
            killed: false,
            coherent: self.coherent,
            last_facet: nf,
            nee: r.nee,
        }
    }

    /// A child a thin film hands on from its far face `b` ([`super::film`]) into the
    /// medium beyond, at the point the probe found. Its phase there is the incident wave's
    /// at the entry point: the transfer matrix's transmitted amplitude is referred to the
    /// far face, and the probe ran along the entry face's normal, so no tangential phase is
    /// gained. Its path mixes in both faces.
    fn at_far_face(
        &self,
        b: &FilmBack,
        dir: DVec3,
        wave: (DVec3, DVec3),
        lane: u32,
        at: usize,
        e: [Field; 2],
    ) -> RayState {
        let (r, nf) = (self.r, self.nf);
        let offset = nf * -self.eps;
        let shift = C64::new(wave.0.dot(offset), wave.1.dot(offset));
        let mix = |h: u64, x: u64| (h ^ x).wrapping_mul(0x0000_0100_0000_01B3);
        RayState {
            e,
            pos: b.pos + offset,
            dir,
            n_re: wave.0,
            n_im: wave.1,
            off: b.off,
            medium: b.beyond,
            opl: r.opl + shift,
            depth: self.depth,
            lane,
            at: at as u32,
            group: r.group,
            tube: r.tube * dir.dot(nf).abs() / r.dir.dot(nf).abs().max(1e-300),
            path: mix(
                mix(r.path, u64::from(self.prim) << 1 | 1),
                u64::from(b.prim) << 1 | 1,
            ),
            killed: false,
            coherent: self.coherent,
            last_facet: b.normal,
            nee: r.nee,
        }
    }
}

/// The children of one event on their way onto the stack: the lanes' splits, and where
/// rays, shared fields and dropped power go.
struct Litter<'s, 'l> {
    /// The parent's first lane, and whether it carries one lane alone.
    first: usize,
    per_lane: bool,
    cur: &'s [Option<[Field; 2]>],
    splits: &'s [LaneSplit],
    rays: &'s mut Vec<RayState>,
    fields: &'s mut Vec<Option<[Field; 2]>>,
    trees: &'s mut [Tree],
    lanes: &'s [Lane<'l>],
    limits: &'s TraceLimits,
    r: &'s RayState,
    depth: u32,
}

impl Litter<'_, '_> {
    /// The lanes' splits, `None` where the lane dropped the ray.
    fn splits(&self) -> impl Iterator<Item = Option<&LaneSplit>> + '_ {
        self.cur
            .iter()
            .zip(self.splits.iter())
            .map(|(f, g)| f.is_some().then_some(g))
    }

    /// Whether lane `j` keeps a child of field `e`: below the power cutoff (the field's
    /// power attenuated along the path so far, exactly 1 on a lossless path) or past the
    /// depth limit, its power is dropped and recorded in its tree.
    fn keep(&mut self, e: &[Field; 2], j: usize) -> bool {
        let r = self.r;
        let tree = &mut self.trees[j];
        let mut power = field_power(&e[0]).max(field_power(&e[1]));
        if r.opl.im != 0.0 {
            power *= (-4.0 * std::f64::consts::PI / self.lanes[j].lambda_nm * r.opl.im).exp();
        }
        if power < self.limits.cutoff {
            tree.drop_field(e, r.opl, false);
            false
        } else if self.depth > self.limits.max_depth {
            tree.drop_field(e, r.opl, true);
            false
        } else {
            true
        }
    }

    /// Pushes one kind of child (transmitted, handed on, or reflected). A parent of one
    /// lane, or a child into a medium whose index varies between the lanes (`varies`),
    /// makes one ray per lane, each along its own direction and wave (`own`: direction,
    /// wave and field, `None` where the lane makes no such child). Otherwise one shared
    /// ray goes along `lead` and carries every lane's field (`shared`) on the field stack;
    /// it is not pushed when no lane kept one. `make(dir, wave, lane, at, e)` builds the
    /// ray.
    fn push(
        &mut self,
        varies: bool,
        lead: Option<(DVec3, (DVec3, DVec3))>,
        own: impl Fn(&LaneSplit) -> Option<(DVec3, (DVec3, DVec3), [Field; 2])>,
        shared: impl Fn(&LaneSplit) -> Option<[Field; 2]>,
        make: impl Fn(DVec3, (DVec3, DVec3), u32, usize, [Field; 2]) -> RayState,
    ) {
        if self.per_lane || varies {
            for k in 0..self.cur.len() {
                if self.cur[k].is_none() {
                    continue;
                }
                let Some((dir, wave, e)) = own(&self.splits[k]) else {
                    continue;
                };
                let j = self.first + k;
                if self.keep(&e, j) {
                    self.rays.push(make(dir, wave, j as u32, 0, e));
                }
            }
            return;
        }
        let Some((dir, wave)) = lead else {
            return;
        };
        let at = self.fields.len();
        let mut any = false;
        for k in 0..self.cur.len() {
            let kept = if self.cur[k].is_some() {
                shared(&self.splits[k]).filter(|e| self.keep(e, self.first + k))
            } else {
                None
            };
            any |= kept.is_some();
            self.fields.push(kept);
        }
        if any {
            self.rays
                .push(make(dir, wave, ALL, at, [[C64::ZERO; 3]; 2]));
        } else {
            self.fields.truncate(at);
        }
    }
}
