//! The estimator's wavelength-independent work on one traced tree (spectral path sharing,
//! docs/design.md §4): bucket keys and powers of the exits, the interfering pairs found
//! through a grid of exit directions (their Hermitian products, path differences and
//! overlaps), and in the plane-wave limit the groups of exits that share a direction.

use std::f64::consts::PI;

use glam::DVec3;

use super::inhomogeneous::{directional_exponent, inhomogeneity, pair_terms};
use super::{
    Coherence, Estimator, NEGLIGIBLE_CROSS, Pair, PhasePrecision, Prepared, Scratch, dot32, key,
};
use crate::optics::C64;
use crate::optics::fresnel::{field_power, hermitian};
use crate::optics::mueller;
use crate::trace::Tree;

/// Exits whose unit directions agree to this (radians) leave in one direction: the
/// plane-wave limit's groups, and the exits one bucket takes together. Without it, the
/// exits of a meshed flat film that leave exactly along a bucket edge (70 deg on the
/// default 2-degree grid) fell on both sides by rounding (1e-16), and their pairs' cross
/// terms, split between the two buckets, left Mueller matrices that no sample can have
/// (issue 74: a coherency eigenvalue of -1.75e-2 of m00): a pair's cross term added to one
/// exit's own matrix alone is indefinite unless their Jones matrices are proportional.
pub(super) const SAME_DIRECTION: f64 = 1e-9;

impl Estimator {
    /// Prepares the wavelength-independent part of `tree` (call once per traced tree).
    pub fn prepare(&self, tree: &Tree, s: &mut Scratch) {
        let p = &mut s.prep;
        p.keys.clear();
        p.pow.clear();
        p.im.clear();
        p.pairs.clear();
        p.groups.clear();
        p.members.clear();
        p.member_delta_nm.clear();
        p.group_of.clear();
        p.jones.clear();
        p.pair_m.clear();
        p.absorbing = false;
        if self.mueller {
            p.jones
                .extend(tree.exits.iter().map(|x| mueller::jones(&x.e, x.dir)));
        }
        for x in &tree.exits {
            p.keys.push(key(self.buckets.index(x.dir), !x.up));
            p.pow
                .push(0.5 * (field_power(&x.e[0]) + field_power(&x.e[1])));
            p.im.push(x.opl.im);
            p.absorbing |= x.opl.im != 0.0;
        }
        if self.mode != Coherence::Beamlet {
            return;
        }
        let ex = &tree.exits;
        let plane_wave = self.rho_nm.is_infinite();
        if plane_wave {
            self.prepare_groups(tree, p);
            self.prepare_inhomogeneous_pairs(tree, p);
            return;
        }
        // The directional kernel `exp(-|dw|^2 / (2 theta_w^2))`, `theta_w = lambda / (pi
        // rho)`, is largest at the longest wavelength.
        let two_theta_max2 = 2.0 * (self.lambda_max_nm / (PI * self.rho_nm)).powi(2);
        let k_min = 2.0 * PI / self.lambda_max_nm;
        let inhomogeneous = ex.iter().any(|x| x.n_im != DVec3::ZERO);
        let mut candidates = std::mem::take(&mut s.cand);
        candidates.clear();
        self.candidate_pairs(ex, &p.pow, two_theta_max2, &mut s.grid, &mut candidates);
        for &(j, l) in &candidates {
            let (j, l) = (j as usize, l as usize);
            let dw = ex[j].dir - ex[l].dir;
            let dw2 = dw.dot(dw);
            let dx = ex[j].x - ex[l].x;
            let wbar = (ex[j].dir + ex[l].dir).normalize();
            let k_pos = {
                let along = dx.dot(wbar);
                let perp = dx - wbar * along;
                (-perp.dot(perp) / (2.0 * self.rho_nm * self.rho_nm)).exp()
            };
            let m2 = if inhomogeneous {
                inhomogeneity(&ex[j], &ex[l], wbar)
            } else {
                0.0
            };
            let n0 = if ex[j].up { self.n_up } else { self.n_down };
            let (phase_nm, grow_nm, flux) = pair_terms(&ex[j], &ex[l], n0);
            let h = 0.5
                * (hermitian(&ex[j].e[0], &ex[l].e[0]) + hermitian(&ex[j].e[1], &ex[l].e[1]))
                * flux;
            // Pairs that cannot contribute at any wavelength are skipped: |c| <= 2|h| K,
            // and the directional overlap is largest at the longest wavelength.
            let bound = 2.0 * h.norm() * k_pos;
            let directional = || {
                if m2 > 0.0 {
                    directional_exponent(dw2, m2, k_min, self.rho_nm).exp()
                } else {
                    (-dw2 / two_theta_max2).exp()
                }
            };
            // Carried to their midpoint the amplitudes may grow ([`pair_terms`]): such
            // a pair is kept.
            if grow_nm <= 0.0
                && (bound < NEGLIGIBLE_CROSS
                    || (!self.reference && dw2 > 0.0 && bound * directional() < NEGLIGIBLE_CROSS))
            {
                continue;
            }
            // Exits in one direction are binned together (see `SAME_DIRECTION`): `j < l`
            // and the pairs come in order, so a chain of them takes its first exit's key.
            if dw2 <= SAME_DIRECTION * SAME_DIRECTION {
                p.keys[l] = p.keys[j];
            }
            let delta_nm = self.path_difference(&ex[j], &ex[l], wbar, n0) + phase_nm;
            p.push_pair_mueller(j, l, flux);
            p.pairs.push(Pair {
                j: j as u32,
                l: l as u32,
                h,
                delta_nm,
                k_pos,
                dw2,
                m2,
                grow_nm,
            });
        }
        s.cand = candidates;
    }

    /// The pairs `(j, l)`, `j < l`, of exits in one hemisphere and one coherence group
    /// ([`crate::trace::Exit::group`]: light scattered by particles is incoherent with
    /// every other path) that [`Estimator::prepare`]
    /// must look at, in the order of a double loop over `j` then `l`. The reference
    /// estimator and small trees take every pair. Otherwise only exits whose directions are
    /// close enough for the directional kernel to matter at the longest wavelength can pair:
    /// `|h| <= max P`, so a pair with `|w_j - w_l|^2 > 2 theta_max^2 ln(2 max P /
    /// NEGLIGIBLE_CROSS)` has a bound below `NEGLIGIBLE_CROSS` and would be culled anyway.
    /// They are found through a grid of the unit directions with cells that wide, looking
    /// at the 27 cells around each exit, so a tree of n exits costs about n, not n^2 (a
    /// steep height map's 10^4 exits took seconds per tree). The kept pairs, and so the
    /// sums, are the double loop's exactly.
    fn candidate_pairs(
        &self,
        ex: &[crate::trace::Exit],
        pow: &[f64],
        two_theta_max2: f64,
        grid: &mut Vec<([i64; 3], u32)>,
        out: &mut Vec<(u32, u32)>,
    ) {
        let n = ex.len();
        // Only exits that share their coherence group and hemisphere with another can pair:
        // the rest (each next-event estimate, most light scattered in a particle medium)
        // are left out of the search, which then costs nothing for them.
        let mut by_group: Vec<(u32, bool, u32)> = ex
            .iter()
            .enumerate()
            .map(|(i, x)| (x.group, x.up, i as u32))
            .collect();
        by_group.sort_unstable();
        let mut pairable = vec![false; n];
        for w in by_group.windows(2) {
            if (w[0].0, w[0].1) == (w[1].0, w[1].1) {
                pairable[w[0].2 as usize] = true;
                pairable[w[1].2 as usize] = true;
            }
        }
        let count = pairable.iter().filter(|&&p| p).count();
        if count < 2 {
            return;
        }
        let max_pow = pow.iter().copied().fold(0.0, f64::max);
        let reach2 = if max_pow > 0.0 {
            two_theta_max2 * (2.0 * max_pow / NEGLIGIBLE_CROSS).ln().max(0.0)
        } else {
            0.0
        };
        // Unit directions differ by at most 2; cells narrower than that pay off.
        let cell = reach2.sqrt() * (1.0 + 1e-9);
        if self.reference || count <= 32 || !(cell > 0.0 && cell < 0.5) {
            for j in (0..n).filter(|&j| pairable[j]) {
                for l in j + 1..n {
                    if pairable[l] && ex[j].up == ex[l].up && ex[j].group == ex[l].group {
                        out.push((j as u32, l as u32));
                    }
                }
            }
            return;
        }
        let key = |d: DVec3| (d / cell).floor().as_i64vec3().to_array();
        grid.clear();
        grid.extend(
            ex.iter()
                .enumerate()
                .filter(|&(i, _)| pairable[i])
                .map(|(i, x)| (key(x.dir), i as u32)),
        );
        grid.sort_unstable();
        let same =
            |a: &crate::trace::Exit, b: &crate::trace::Exit| a.up == b.up && a.group == b.group;
        // The inhomogeneous exits, in order (none in most trees).
        let inhomogeneous: Vec<u32> = (0..n as u32)
            .filter(|&i| ex[i as usize].n_im != DVec3::ZERO)
            .collect();
        for (j, x) in ex.iter().enumerate().filter(|&(j, _)| pairable[j]) {
            // An inhomogeneous exit's directional window can be far narrower than the
            // beamlet's ([`directional_exponent`]): it pairs with every exit of its
            // hemisphere and group (only films and absorbers' edges have such exits).
            if x.n_im != DVec3::ZERO {
                for (l, y) in ex.iter().enumerate().skip(j + 1) {
                    if same(x, y) {
                        out.push((j as u32, l as u32));
                    }
                }
                continue;
            }
            for &l in &inhomogeneous[inhomogeneous.partition_point(|&l| l as usize <= j)..] {
                if same(x, &ex[l as usize]) {
                    out.push((j as u32, l));
                }
            }
            let k = key(x.dir);
            for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        let c = [k[0] + dx, k[1] + dy, k[2] + dz];
                        let from = grid.partition_point(|e| e.0 < c);
                        for &(kc, l) in &grid[from..] {
                            if kc != c {
                                break;
                            }
                            let l = l as usize;
                            // Pairs with an inhomogeneous exit were all taken above.
                            if l > j && same(&ex[l], x) && ex[l].n_im == DVec3::ZERO {
                                let dw = x.dir - ex[l].dir;
                                if dw.dot(dw) <= reach2 * (1.0 + 1e-9) {
                                    out.push((j as u32, l as u32));
                                }
                            }
                        }
                    }
                }
            }
        }
        out.sort_unstable();
    }

    /// `Re(OPL_j - OPL_l) - n0 w . (x_j - x_l)`, nm, in the estimator's precision: the
    /// phase difference of two exits along `w` over `2 pi / lambda`.
    fn path_difference(
        &self,
        a: &crate::trace::Exit,
        b: &crate::trace::Exit,
        w: DVec3,
        n0: f64,
    ) -> f64 {
        match self.precision {
            PhasePrecision::F64 => (a.opl.re - b.opl.re) - n0 * w.dot(a.x - b.x),
            PhasePrecision::F32 => {
                let dx32 = (a.x.as_vec3() - b.x.as_vec3()).as_dvec3();
                f64::from((a.opl.re as f32 - b.opl.re as f32) - n0 as f32 * dot32(w, dx32))
            }
        }
    }

    /// Plane-wave limit (`rho = inf`): only exits whose directions agree to 1e-9
    /// interfere, fully. Such exits are grouped (sorted by hemisphere and direction,
    /// consecutive ones within 1e-9 of the group's first), and at each wavelength a group's
    /// amplitudes are summed coherently, `|sum_j a_j e^{i k delta_j}|^2`, which is the sum
    /// of its exits' powers and all its pairs' cross terms `c_jl` (docs/design.md §4) in O(n)
    /// rather than O(n^2): a flat stack's tree has all its exits in two groups.
    fn prepare_groups(&self, tree: &Tree, p: &mut Prepared) {
        let ex = &tree.exits;
        p.members.extend(0..ex.len() as u32);
        p.group_of.resize(ex.len(), 0);
        p.members.sort_unstable_by(|&a, &b| {
            let (a, b) = (&ex[a as usize], &ex[b as usize]);
            b.up.cmp(&a.up)
                .then(a.group.cmp(&b.group))
                .then(a.dir[0].total_cmp(&b.dir[0]))
                .then(a.dir[1].total_cmp(&b.dir[1]))
                .then(a.dir[2].total_cmp(&b.dir[2]))
        });
        let mut start = 0;
        while start < p.members.len() {
            let first = &ex[p.members[start] as usize];
            let mut end = start + 1;
            while end < p.members.len() {
                let e = &ex[p.members[end] as usize];
                if e.up != first.up
                    || e.group != first.group
                    || (e.dir - first.dir).dot(e.dir - first.dir).sqrt() > SAME_DIRECTION
                {
                    break;
                }
                end += 1;
            }
            let n0 = if first.up { self.n_up } else { self.n_down };
            // One direction, one bucket (see `SAME_DIRECTION`): the group's first exit's.
            let first_key = p.keys[p.members[start] as usize];
            for &m in &p.members[start..end] {
                let delta = self.path_difference(&ex[m as usize], first, first.dir, n0);
                p.member_delta_nm.push(delta);
                p.group_of[m as usize] = start as u32;
                p.keys[m as usize] = first_key;
            }
            if end - start > 1 {
                p.groups.push((start as u32, end as u32));
            }
            start = end;
        }
    }

    /// Plane-wave limit: the pairs of exits in different groups of which at least one is
    /// inhomogeneous. Their directional window is their amplitudes', not the beamlet's
    /// ([`directional_exponent`], finite however wide the beamlet), so they interfere in
    /// part, as they do at any finite radius; positions do not decorrelate (`k_pos = 1`).
    fn prepare_inhomogeneous_pairs(&self, tree: &Tree, p: &mut Prepared) {
        let ex = &tree.exits;
        if ex.iter().all(|x| x.n_im == DVec3::ZERO) {
            return;
        }
        for j in 0..ex.len() {
            for l in j + 1..ex.len() {
                let (a, b) = (&ex[j], &ex[l]);
                if (a.n_im == DVec3::ZERO && b.n_im == DVec3::ZERO)
                    || a.up != b.up
                    || a.group != b.group
                    || p.group_of[j] == p.group_of[l]
                {
                    continue;
                }
                let wbar = (a.dir + b.dir).normalize();
                let m2 = inhomogeneity(a, b, wbar);
                let n0 = if a.up { self.n_up } else { self.n_down };
                let (phase_nm, grow_nm, flux) = pair_terms(a, b, n0);
                let h = 0.5 * (hermitian(&a.e[0], &b.e[0]) + hermitian(&a.e[1], &b.e[1])) * flux;
                if (2.0 * h.norm() < NEGLIGIBLE_CROSS && grow_nm <= 0.0) || m2 == 0.0 {
                    continue;
                }
                p.push_pair_mueller(j, l, flux);
                p.pairs.push(Pair {
                    j: j as u32,
                    l: l as u32,
                    h,
                    delta_nm: self.path_difference(a, b, wbar, n0) + phase_nm,
                    k_pos: 1.0,
                    dw2: (a.dir - b.dir).length_squared(),
                    m2,
                    grow_nm,
                });
            }
        }
    }
}

impl Prepared {
    /// With `--mueller`: the pair's mixed Mueller matrix `M(J_j, J_l)` times its flux
    /// factor, beside the pair (the matrix form of its `h`; `optics::mueller`).
    fn push_pair_mueller(&mut self, j: usize, l: usize, flux: C64) {
        if !self.jones.is_empty() {
            let m = mueller::mixed(&self.jones[j], &self.jones[l]);
            self.pair_m.push(m.map(|z| z * flux));
        }
    }
}
