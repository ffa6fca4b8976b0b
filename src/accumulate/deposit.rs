//! The estimator's per-wavelength work: a prepared tree's deposits at one wavelength (each
//! exit's power, the plane-wave groups' coherent sums, and the pairs' cross terms through
//! the batched phase functions), or its amplitudes for the bucket and global modes
//! (docs/design.md §4).

use std::f64::consts::PI;

use glam::DVec3;

use super::inhomogeneous::directional_exponent;
use super::{Coherence, Estimator, PhasePrecision, Scratch, add_fields, dot32, phase};
use crate::optics::C64;
use crate::optics::fresnel::{Field, field_power};
use crate::optics::mueller::{self, Mueller};
use crate::trace::Tree;

impl Estimator {
    /// The incident wave's phase at a tree's launch point `x` (nm, world frame) for a
    /// wave travelling along `d` at wave number `k` (1/nm): `k n_up (d . x)`, in the
    /// estimator's precision.
    pub fn entry_phase(&self, k: f64, d: DVec3, x: DVec3) -> f64 {
        match self.precision {
            PhasePrecision::F64 => k * self.n_up * d.dot(x),
            PhasePrecision::F32 => f64::from(k as f32 * self.n_up as f32 * dot32(d, x)),
        }
    }

    /// Deposits of the prepared tree at `lambda_nm` into `out` as `(key, fraction of
    /// launched power)`, several entries per key possible. For `Global` mode, fills
    /// `global` with `(key, amplitude)` instead; `entry_phase` is the incident wave's phase
    /// at the tree's launch point, `k n0 (d . x_entry)`.
    pub fn deposit(
        &self,
        tree: &Tree,
        lambda_nm: f64,
        entry_phase: f64,
        s: &mut Scratch,
        out: &mut Vec<(u32, f64)>,
        global: &mut Vec<(u32, [Field; 2])>,
    ) {
        let k = 2.0 * PI / lambda_nm;
        let p = &s.prep;
        debug_assert_eq!(p.keys.len(), tree.exits.len(), "prepare() the tree first");
        s.corrected = 0.0;
        if self.mode == Coherence::Beamlet {
            // |a_j|^2 = P_j exp(-2 k Im OPL_j) (`Prepared::att`); c_jl = 2 Re(h e^{i k
            // delta}) K e^{-k (Im_j + Im_l)}. Each deposit's exit is kept beside it
            // (`out_exit`, `mdep_exit`) for the lossless groups' balance.
            s.mdeps.clear();
            s.out_exit.clear();
            s.mdep_exit.clear();
            let o0 = out.len();
            let mueller = self.mueller;
            for j in 0..p.keys.len() {
                let v = p.pow[j] * p.att(k, j);
                out.push((p.keys[j], v));
                s.out_exit.push(j as u32);
                if mueller {
                    let a = p.att(k, j);
                    let mut m = mueller::mueller(&p.jones[j]).map(|x| x * a);
                    m[0] = v;
                    s.mdeps.push((p.keys[j], m));
                    s.mdep_exit.push(j as u32);
                }
            }
            self.deposit_groups(tree, k, s, out);
            let theta_w2 = (lambda_nm / (PI * self.rho_nm)).powi(2);
            if self.reference {
                self.reference_pairs(k, theta_w2, s, out);
            } else {
                // The pair loop and its batches compiled for AVX2 where the CPU has it
                // (the same bits: `machine::with_avx2`).
                crate::machine::with_avx2(
                    #[inline(always)]
                    || self.deposit_pairs(k, theta_w2, s, out),
                );
            }
            if !tree.absorbing {
                s.corrected = super::conserve::conserve_groups(tree, s, &mut out[o0..]);
            }
            return;
        }
        // Each exit's amplitude with its phase relative to a plane through the global origin
        // perpendicular to its direction: `exp(i k (OPL - n0 w . x))` (a complex OPL
        // attenuates).
        s.amp.clear();
        for x in &tree.exits {
            let n0 = if x.up { self.n_up } else { self.n_down };
            let phase = match self.precision {
                PhasePrecision::F64 => k * (x.opl.re - n0 * x.dir.dot(x.x)),
                PhasePrecision::F32 => {
                    f64::from(k as f32 * (x.opl.re as f32 - n0 as f32 * dot32(x.dir, x.x)))
                }
            };
            let f = C64::from_polar((-k * x.opl.im).exp(), phase);
            s.amp.push([x.e[0].map(|c| c * f), x.e[1].map(|c| c * f)]);
        }
        match self.mode {
            Coherence::Auto | Coherence::Beamlet | Coherence::Diffraction => {
                unreachable!("the run gives the estimator beamlet for these")
            }
            Coherence::Rigorous => unreachable!("the rigorous solver traces no trees"),
            _ if self.mueller => unreachable!("--mueller is refused with {}", self.mode),
            Coherence::Bucket => {
                // Gondek et al. / the seed: phases relative to a plane through the global
                // origin perpendicular to each exit direction, `exp(-i k n0 w . x)` with
                // absolute exit points, summed per bucket.
                s.sums.clear();
                for (j, a) in s.amp.iter().enumerate() {
                    match s.sums.iter_mut().find(|(kk, _)| *kk == p.keys[j]) {
                        Some((_, acc)) => add_fields(acc, a),
                        None => s.sums.push((p.keys[j], *a)),
                    }
                }
                for (kk, a) in &s.sums {
                    out.push((*kk, 0.5 * (field_power(&a[0]) + field_power(&a[1]))));
                }
            }
            Coherence::Global => {
                let f = C64::from_polar(1.0, entry_phase);
                for (a, &kk) in s.amp.iter().zip(&p.keys) {
                    global.push((kk, [a[0].map(|c| c * f), a[1].map(|c| c * f)]));
                }
            }
        }
    }
    /// The pairs' cross terms at wave number `k` (1/nm), pair by pair with the standard
    /// library's functions: the reference the fast loop ([`Self::deposit_pairs`]) is
    /// tested against. Each pair's term is split between its two exits in proportion to
    /// their powers.
    fn reference_pairs(&self, k: f64, theta_w2: f64, s: &mut Scratch, out: &mut Vec<(u32, f64)>) {
        let p = &s.prep;
        let mueller = self.mueller;
        for (i, pr) in p.pairs.iter().enumerate() {
            let (j, l) = (pr.j as usize, pr.l as usize);
            let mut kernel = pr.k_pos;
            if pr.m2 > 0.0 {
                kernel *= directional_exponent(pr.dw2, pr.m2, k, self.rho_nm).exp();
            } else if pr.dw2 > 0.0 {
                kernel *= (-pr.dw2 / (2.0 * theta_w2)).exp();
            }
            let (sn, cs) = (k * pr.delta_nm).sin_cos();
            kernel *= (k * pr.grow_nm).exp();
            let mut c = 2.0 * (pr.h.re * cs - pr.h.im * sn) * kernel;
            let (mut pj, mut pl) = (p.pow[j], p.pow[l]);
            if p.absorbing {
                c *= (-k * (p.im[j] + p.im[l])).exp();
                pj *= p.att(k, j);
                pl *= p.att(k, l);
            }
            let tot = pj + pl;
            if tot > 0.0 {
                out.push((p.keys[j], c * pj / tot));
                out.push((p.keys[l], c * pl / tot));
                s.out_exit.extend([j as u32, l as u32]);
                if mueller {
                    let w = if p.absorbing {
                        kernel * (-k * (p.im[j] + p.im[l])).exp()
                    } else {
                        kernel
                    };
                    for (x, share) in [(j, pj / tot), (l, pl / tot)] {
                        let mut m = [0.0; 16];
                        mueller::add_cross(&mut m, &p.pair_m[i], sn, cs, w * share);
                        m[0] = c * share;
                        s.mdeps.push((p.keys[x], m));
                        s.mdep_exit.push(x as u32);
                    }
                }
            }
        }
    }

    /// Plane-wave limit: each group's coherent sum less its exits' own powers (its pairs'
    /// cross terms), split among its exits in proportion to their powers; with `--mueller`
    /// the same for the groups' Jones matrices.
    fn deposit_groups(&self, tree: &Tree, k: f64, s: &mut Scratch, out: &mut Vec<(u32, f64)>) {
        let p = &s.prep;
        let mueller = self.mueller;
        for &(g0, g1) in &p.groups {
            let (g0, g1) = (g0 as usize, g1 as usize);
            let mut sum = [[C64::new(0.0, 0.0); 3]; 2];
            let mut incoherent = 0.0;
            // With --mueller: the group's summed Jones matrix, and its exits' own
            // Mueller matrices summed.
            let mut jsum = [C64::new(0.0, 0.0); 4];
            let mut mown = [0.0; 16];
            for (m, &j) in p.members[g0..g1].iter().enumerate() {
                let j = j as usize;
                let mut f = C64::from_polar(1.0, k * p.member_delta_nm[g0 + m]);
                if p.absorbing {
                    f *= (-k * p.im[j]).exp();
                }
                for (acc, e) in sum.iter_mut().zip(&tree.exits[j].e) {
                    for (a, c) in acc.iter_mut().zip(e) {
                        *a += c * f;
                    }
                }
                incoherent += p.pow[j] * p.att(k, j);
                if mueller {
                    for (a, c) in jsum.iter_mut().zip(&p.jones[j]) {
                        *a += c * f;
                    }
                    let a = p.att(k, j);
                    for (o, x) in mown.iter_mut().zip(mueller::mueller(&p.jones[j])) {
                        *o += x * a;
                    }
                }
            }
            let cross = 0.5 * (field_power(&sum[0]) + field_power(&sum[1])) - incoherent;
            let mcross: Mueller = if mueller {
                let whole = mueller::mueller(&jsum);
                std::array::from_fn(|e| whole[e] - mown[e])
            } else {
                [0.0; 16]
            };
            if incoherent > 0.0 {
                for &j in &p.members[g0..g1] {
                    let j = j as usize;
                    let v = cross * p.pow[j] * p.att(k, j) / incoherent;
                    out.push((p.keys[j], v));
                    s.out_exit.push(j as u32);
                    if mueller {
                        let share = p.pow[j] * p.att(k, j) / incoherent;
                        let mut m = mcross.map(|x| x * share);
                        m[0] = v;
                        s.mdeps.push((p.keys[j], m));
                        s.mdep_exit.push(j as u32);
                    }
                }
            }
        }
    }

    /// The pairs' cross terms at wave number `k` (1/nm), the fast way: every pair's
    /// phase, and its directional overlap with the attenuation in one exponent, through
    /// the batched `phase` functions; each pair's term split between its two exits in
    /// proportion to their powers (as the reference does) and summed per exit, one deposit
    /// per exit rather than two per pair. The same sums as the reference to rounding
    /// (tests/estimator.rs).
    #[inline(always)]
    fn deposit_pairs(&self, k: f64, theta_w2: f64, s: &mut Scratch, out: &mut Vec<(u32, f64)>) {
        let Scratch {
            prep: p,
            phase: ph,
            sin,
            cos,
            arg,
            expv,
            att,
            exit_sum,
            mdeps,
            exit_msum,
            out_exit,
            mdep_exit,
            ..
        } = s;
        let mueller = self.mueller;
        let n = p.keys.len();
        ph.clear();
        ph.extend(p.pairs.iter().map(|pr| k * pr.delta_nm));
        phase::sin_cos_batch(ph, sin, cos);
        // Exponents: the directional kernel's, and the pair's attenuation.
        arg.clear();
        let two_theta_w2 = 2.0 * theta_w2;
        let rho = self.rho_nm;
        arg.extend(p.pairs.iter().map(|pr| {
            let mut a = if pr.m2 > 0.0 {
                directional_exponent(pr.dw2, pr.m2, k, rho)
            } else {
                -pr.dw2 / two_theta_w2
            };
            if p.absorbing {
                a -= k * (p.im[pr.j as usize] + p.im[pr.l as usize]);
            }
            // The amplitudes carried to the pair's midpoint ([`pair_terms`]).
            a + k * pr.grow_nm
        }));
        phase::exp_batch(arg, expv);
        // Each exit's attenuated power.
        att.clear();
        if p.absorbing {
            arg.clear();
            arg.extend(p.im.iter().map(|im| -2.0 * k * im));
            phase::exp_batch(arg, att);
            for (a, pw) in att.iter_mut().zip(&p.pow) {
                *a *= pw;
            }
        } else {
            att.extend_from_slice(&p.pow);
        }
        exit_sum.clear();
        exit_sum.resize(n, 0.0);
        exit_msum.clear();
        if mueller {
            exit_msum.resize(n, [0.0; 16]);
        }
        for (i, pr) in p.pairs.iter().enumerate() {
            let (j, l) = (pr.j as usize, pr.l as usize);
            let w = pr.k_pos * expv[i];
            let c = 2.0 * (pr.h.re * cos[i] - pr.h.im * sin[i]) * w;
            let (pj, pl) = (att[j], att[l]);
            let tot = pj + pl;
            if tot > 0.0 {
                exit_sum[j] += c * pj / tot;
                exit_sum[l] += c * pl / tot;
                if mueller {
                    let z = &p.pair_m[i];
                    mueller::add_cross(&mut exit_msum[j], z, sin[i], cos[i], w * pj / tot);
                    mueller::add_cross(&mut exit_msum[l], z, sin[i], cos[i], w * pl / tot);
                }
            }
        }
        for (j, &v) in exit_sum.iter().enumerate() {
            if v != 0.0 {
                out.push((p.keys[j], v));
                out_exit.push(j as u32);
            }
            if mueller && (v != 0.0 || exit_msum[j].iter().any(|&x| x != 0.0)) {
                let mut m = exit_msum[j];
                m[0] = v;
                mdeps.push((p.keys[j], m));
                mdep_exit.push(j as u32);
            }
        }
    }
}

impl super::Prepared {
    /// Exit `j`'s power attenuation at wave number `k` (1/nm): `exp(-2 k Im OPL_j)` (1
    /// where nothing absorbs).
    #[inline]
    fn att(&self, k: f64, j: usize) -> f64 {
        if self.absorbing {
            (-2.0 * k * self.im[j]).exp()
        } else {
            1.0
        }
    }
}
