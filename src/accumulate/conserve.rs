//! Lossless coherence groups carry out the power that entered them (issue 71).
//!
//! In a tree that met no absorption (no absorbing medium, metal or coating, no albedo
//! below 1) every Fresnel event splits its power exactly (`|r|^2 + T = 1`), so a
//! coherence group's exits hold, as own powers `P = sum_j |a_j|^2`, all the power that
//! entered the group less what the depth cut dropped (reported apart). Interference only
//! moves power between the exits (Poynting's theorem over a lossless volume; Born & Wolf,
//! *Principles of Optics*, 7th ed., §1.1.4), so the group's cross terms must sum to zero:
//! the flat film's do for any overlap that depends on the path offset alone (Stokes'
//! relations `r' = -r`, `t t' = 1 - r^2`, lag by lag; docs/design.md §4, "Energy of lossless
//! groups").
//!
//! The beamlet estimator's overlaps `K_jl` are those of beamlets whose central rays left
//! in the exits' directions. On a curved film the reflected and transmitted partial waves
//! fan out differently (they leave through different faces), so the reflected pairs'
//! overlaps and the transmitted pairs' no longer match lag by lag and the cross terms sum
//! to `C != 0`: the seed's wavy film gained up to 1.4 % at 70-85 deg. That is an error of
//! the estimator's partial-coherence model, not power a lossless film makes. The group's
//! deposits, own and cross, are therefore scaled by `P / (P + C)`: the group's angular
//! and R/T distribution is kept as the estimator formed it, and its total is the power
//! the physics says it holds. `P + C` is the beamlet superposition's power, positive for
//! the Gaussian overlaps (a positive semi-definite kernel); a group whose sum is not
//! positive is left as formed, for the run's checks to judge. The relative size of the
//! correction, `|C| / P`, is tallied per cell and reported by the run.

use super::Scratch;
use crate::trace::Tree;

/// Corrections below this relative size are rounding (a flat film's groups: about 1e-16)
/// and are not applied, so that exact cases keep their bits.
const ROUNDING: f64 = 1e-12;

/// Scales the deposits `out` (and the Mueller deposits `s.mdeps`) of the lossless `tree`
/// at one wavelength so that each coherence group's total is its exits' own power;
/// `s.out_exit` and `s.mdep_exit` name each deposit's exit. Returns the tree's corrected
/// power, `sum_g |C_g|` as a fraction of the launched power.
pub(super) fn conserve_groups(tree: &Tree, s: &mut Scratch, out: &mut [(u32, f64)]) -> f64 {
    debug_assert_eq!(out.len(), s.out_exit.len());
    let groups = &mut s.group_power;
    groups.clear();
    let n_groups = tree.exits.iter().map(|x| x.group as usize + 1).max();
    groups.resize(n_groups.unwrap_or(0), (0.0, 0.0));
    for (j, &pw) in s.prep.pow.iter().enumerate() {
        groups[tree.exits[j].group as usize].0 += pw;
    }
    for (&(_, v), &j) in out.iter().zip(&s.out_exit) {
        groups[tree.exits[j as usize].group as usize].1 += v;
    }
    let mut corrected = 0.0;
    let mut any = false;
    for g in groups.iter_mut() {
        let (own, total) = *g;
        let cross = total - own;
        // The factor, or 1 where there is nothing to correct or the sum is not positive.
        let f = if own > 0.0 && total > 0.0 && cross.abs() > ROUNDING * own {
            corrected += cross.abs();
            any = true;
            own / total
        } else {
            1.0
        };
        g.1 = f;
    }
    if !any {
        return 0.0;
    }
    for ((_, v), &j) in out.iter_mut().zip(&s.out_exit) {
        *v *= groups[tree.exits[j as usize].group as usize].1;
    }
    for ((_, m), &j) in s.mdeps.iter_mut().zip(&s.mdep_exit) {
        let f = groups[tree.exits[j as usize].group as usize].1;
        if f != 1.0 {
            for x in m.iter_mut() {
                *x *= f;
            }
        }
    }
    corrected
}
