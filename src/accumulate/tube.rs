//! The ray tubes the diffraction method transforms ([`super::diffraction`]): each exit's
//! contribution at a wavelength, and each tube's shape on the exit plane (the Jacobian of
//! its map from the launch plane, from the neighbouring trees' exits).

use crate::optics::C64;
use crate::optics::fresnel::Field;
use crate::trace::Exit;

/// Where the tubes were launched (the tile, nm, and the launch lattice, `[nx, ny]` trees:
/// tree `i` at cell `(i mod nx, i div nx)`), the incident direction's cosine, and whether
/// the tubes looked at leave downwards.
#[derive(Clone, Copy, Debug)]
pub struct Launches {
    pub tile_nm: [f64; 2],
    pub lattice: [u64; 2],
    pub cos_i: f64,
    pub down: bool,
}

/// One exit's contribution at one wavelength: its tree, point, direction, and the field of
/// both incident polarisations with its phase.
#[derive(Clone, Copy, Debug)]
pub struct Contribution {
    /// The tree (its index on the launch lattice) and the exit's place in the tree's list:
    /// the same exit of the neighbouring trees gives the tube's shape.
    pub tree: u32,
    pub slot: u32,
    /// Exit point on the exit plane, nm (world frame, not wrapped).
    pub x: [f64; 2],
    /// Transverse components of the unit direction of travel.
    pub w: [f64; 2],
    /// `e_j exp(i (psi_j - k_in . x_j)) exp(-k Im OPL_j)`: the power-normalised field with
    /// its phase at the exit point, less the incident wave's transverse phase.
    pub a: [Field; 2],
    /// The tube's cross-section relative to the launched one, tracked through its
    /// refractions ([`Exit::tube`]); used where no neighbouring tree has the same exit.
    pub tube: f64,
    /// The facets the ray met ([`Exit::path`]).
    pub path: u64,
    /// Left through the bottom plane (transmission).
    pub down: bool,
}

/// The contribution of exit `slot` of tree `tree` at wave number `k` (1/nm, vacuum), for an
/// incident wave whose phase at the tree's launch point is `entry_phase` and whose
/// transverse wave vector is `k_in` (1/nm).
pub fn contribution(
    exit: &Exit,
    tree: u32,
    slot: u32,
    k: f64,
    entry_phase: f64,
    k_in: [f64; 2],
) -> Contribution {
    let psi = exit_phase(exit, k, entry_phase, k_in);
    contribution_at(exit, tree, slot, k, crate::accumulate::phase::sin_cos(psi))
}

/// The phase `psi_j - k_in . x_j` (rad) of an exit's [`Contribution`] at wave number `k`
/// (1/nm): the incident wave's phase at the launch point, `entry_phase`, plus `k Re OPL`,
/// less the incident wave's transverse phase at the exit point.
pub fn exit_phase(exit: &Exit, k: f64, entry_phase: f64, k_in: [f64; 2]) -> f64 {
    entry_phase + k * exit.opl.re - (k_in[0] * exit.x.x + k_in[1] * exit.x.y)
}

/// An exit's [`Contribution`] at wave number `k` (1/nm) from the sine and cosine of its
/// [`exit_phase`] (`phase::sin_cos`'s bits, however they were evaluated): the field times
/// `exp(i psi) exp(-k Im OPL)`.
pub fn contribution_at(
    exit: &Exit,
    tree: u32,
    slot: u32,
    k: f64,
    (sin, cos): (f64, f64),
) -> Contribution {
    // exp(-0) is 1 exactly: a lossless path skips the call.
    let decay = if exit.opl.im == 0.0 {
        1.0
    } else {
        (-k * exit.opl.im).exp()
    };
    let f = C64::new(decay * cos, decay * sin);
    Contribution {
        tree,
        slot,
        x: [exit.x.x, exit.x.y],
        w: [exit.dir.x, exit.dir.y],
        a: [exit.e[0].map(|c| c * f), exit.e[1].map(|c| c * f)],
        tube: exit.tube,
        path: exit.path,
        down: !exit.up,
    }
}

/// One exit kept once for every wavelength where one traced tree serves them all (path
/// sharing: fixed indices, so the exit's point, direction, fields and optical path are the
/// same at each). Its [`Contribution`] at a wavelength is formed where that wavelength is
/// transformed, from `origin`, the tree's launch point in the world (nm), for the incident
/// wave's phase there. (Kept per wavelength, the contributions of 16,384 trees at 40 bins
/// took 1 GB, copied in one thread.)
#[derive(Clone, Copy, Debug)]
pub struct SharedExit {
    pub tree: u32,
    pub slot: u32,
    pub origin: glam::DVec3,
    pub exit: Exit,
}

/// A tube's map from the launch plane to the exit plane: its Jacobian `d(exit point) /
/// d(launch point)` (columns along the lattice's axes), and whether it came from the
/// tube's own tracked cross-section because no neighbouring tree had the same exit.
#[derive(Clone, Copy, Debug)]
pub struct TubeShape {
    pub(super) jac: [[f64; 2]; 2],
    pub(super) fallback: bool,
}

/// The shape of every tube of `contribs` leaving into hemisphere `h` (`c.down == h.down`),
/// in order: from the neighbouring trees' exits ([`tube_column`]), or else the tube as
/// tracked through plane facets. Geometry only: the same at every wavelength where the
/// contributions' points, directions and paths are.
pub fn tube_shapes(h: &Launches, contribs: &[Contribution]) -> Vec<TubeShape> {
    let [nx, ny] = h.lattice;
    let n_trees = (nx * ny) as usize;
    let step = [h.tile_nm[0] / nx as f64, h.tile_nm[1] / ny as f64];
    // Where each tree's exits start in `contribs` (which is in tree order, slot order).
    let mut first = vec![0usize; n_trees + 1];
    for c in contribs {
        first[c.tree as usize + 1] += 1;
    }
    for i in 0..n_trees {
        first[i + 1] += first[i];
    }
    let exit_of = |tree: u64, slot: u32| -> Option<&Contribution> {
        let (a, b) = (first[tree as usize], first[tree as usize + 1]);
        contribs[a..b].get(slot as usize).filter(|c| c.slot == slot)
    };
    let family = |tree: u64, path: u64| -> Option<&Contribution> {
        let (a, b) = (first[tree as usize], first[tree as usize + 1]);
        contribs[a..b].iter().find(|c| c.path == path)
    };
    contribs
        .iter()
        .filter(|c| c.down == h.down)
        .map(|c| {
            let cos_j = cos_of(c);
            match (
                tube_column(c, 0, h, step, cos_j, &exit_of, &family),
                tube_column(c, 1, h, step, cos_j, &exit_of, &family),
            ) {
                (Some(a), Some(b)) => TubeShape {
                    jac: [[a[0], b[0]], [a[1], b[1]]],
                    fallback: false,
                },
                _ => {
                    // No neighbour with this exit: the tube as tracked through plane facets.
                    let f = (c.tube * h.cos_i / cos_j).sqrt();
                    TubeShape {
                        jac: [[f, 0.0], [0.0, f]],
                        fallback: true,
                    }
                }
            }
        })
        .collect()
}

/// The cosine of a contribution's direction with the normal (at least 1e-6).
pub(super) fn cos_of(c: &Contribution) -> f64 {
    (1.0 - c.w[0] * c.w[0] - c.w[1] * c.w[1]).max(1e-12).sqrt()
}

/// One column of a tube's Jacobian `d(exit point) / d(launch point)` along lattice axis
/// `axis`, from the neighbouring trees' exit on the same path (the same facets met alike:
/// the same affine map, so their points give the tube's exact shape), or else their exit
/// in the same place of the tree with nearly the same direction (a curved surface sampled
/// by about one ray per facet, mapped smoothly): central differences, or one-sided where
/// one neighbour is missing or only the other is on the same path.
#[allow(clippy::too_many_arguments)]
fn tube_column<'c>(
    c: &Contribution,
    axis: usize,
    h: &Launches,
    step: [f64; 2],
    cos_j: f64,
    exit_of: &dyn Fn(u64, u32) -> Option<&'c Contribution>,
    family: &dyn Fn(u64, u64) -> Option<&'c Contribution>,
) -> Option<[f64; 2]> {
    let [nx, ny] = h.lattice;
    if (axis == 0 && nx == 1) || (axis == 1 && ny == 1) {
        return None;
    }
    let (ix, iy) = (u64::from(c.tree) % nx, u64::from(c.tree) / nx);
    let along = |dir: i64| -> Option<([f64; 2], bool)> {
        let (mut jx, mut jy) = (ix as i64, iy as i64);
        let mut wrap = [0.0; 2];
        if axis == 0 {
            jx += dir;
            if jx < 0 || jx >= nx as i64 {
                wrap[0] = -dir as f64 * h.tile_nm[0];
                jx = jx.rem_euclid(nx as i64);
            }
        } else {
            jy += dir;
            if jy < 0 || jy >= ny as i64 {
                wrap[1] = -dir as f64 * h.tile_nm[1];
                jy = jy.rem_euclid(ny as i64);
            }
        }
        let tree = jy as u64 * nx + jx as u64;
        let reach = 16.0 * step[axis] / cos_j;
        let column = |o: &Contribution| {
            let d = [o.x[0] - wrap[0] - c.x[0], o.x[1] - wrap[1] - c.x[1]];
            // Squared lengths: `hypot`'s care for overflow costs 5 % of the run here.
            (d[0] * d[0] + d[1] * d[1] < reach * reach).then(|| {
                [
                    dir as f64 * d[0] / step[axis],
                    dir as f64 * d[1] / step[axis],
                ]
            })
        };
        // The same path: the same affine map from launch to exit, exactly.
        if let Some(v) = family(tree, c.path).and_then(column) {
            return Some((v, true));
        }
        // Otherwise the same place in the tree, nearly the same direction: a curved
        // surface sampled by about one ray per facet, mapped smoothly.
        let o = exit_of(tree, c.slot)?;
        let dw2 = (o.w[0] - c.w[0]).powi(2) + (o.w[1] - c.w[1]).powi(2);
        if o.down != c.down || dw2 >= 0.0625 {
            return None;
        }
        column(o).map(|v| (v, false))
    };
    match (along(1), along(-1)) {
        (Some((a, sa)), Some((b, sb))) => {
            let len = |v: [f64; 2]| (v[0] * v[0] + v[1] * v[1]).sqrt();
            let diff = len([a[0] - b[0], a[1] - b[1]]);
            if diff <= 0.25 * (len(a) + len(b)) {
                // The two sides agree: a smooth map, sampled either side.
                Some([0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])])
            } else if sa != sb {
                // An edge on one side: the side on the same path.
                Some(if sa { a } else { b })
            } else {
                // An edge the paths do not tell apart: the side without the jump.
                Some(if len(a) <= len(b) { a } else { b })
            }
        }
        (a, b) => a.or(b).map(|x| x.0),
    }
}
