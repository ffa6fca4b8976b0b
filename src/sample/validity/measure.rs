//! The measurements behind [`super::scales`] that take more than a pass over the facets: the
//! strongest axis-aligned mode of the height, and each facet's curvature across its edges.

/// Axis-aligned modes of the height: H_m = (1/A) int (z - mean) exp(-i q_m x) dA, each
/// facet cut into n x n pieces (its extent along the axis times q_max under 2 rad) and
/// integrated by the centroid rule; a mode of a real surface holds 2 |H_m|^2 of the
/// variance. Periods down to 100 nm (at most 128 per tile side) are scanned, over at most
/// about 20,000 facets taken evenly through the list. Returns the strongest mode's period
/// (nm) and its share of the height variance `sigma^2` about the mean height `mean` (nm).
///
/// The pieces' weights `a (z - mean)` are first deposited on a profile of
/// [`PROFILE_BINS_PER_MODE`] bins per mode along the axis by linear (cloud-in-cell)
/// weighting, and the profile is transformed: the deposit multiplies mode `m`'s amplitude
/// by `sinc^2(q_m dx / 2)` (Hockney & Eastwood, Computer Simulation Using Particles, 1988,
/// §5-5), which is divided out. The pieces' own aliases lie beyond `PROFILE_BINS_PER_MODE -
/// 1` times the highest mode scanned, where the centroid rule has already smoothed the
/// surface away. Each piece costs a deposit instead of a sum over every mode: the seed
/// film's scales took 0.5-0.9 s of every run, for the auto choice and the warnings.
pub(super) fn strongest_axis_mode(
    mesh: &crate::sample::Mesh,
    tile_nm: [f64; 2],
    mean: f64,
    sigma: f64,
) -> (f64, f64) {
    let p = &mesh.positions_nm;
    let stride = (mesh.triangles.len() / 20_000).max(1);
    let mut best = (f64::INFINITY, 0.0);
    for (axis, &l) in tile_nm.iter().enumerate() {
        let mmax = ((l / 100.0).floor() as usize).clamp(1, 128);
        let q1 = 2.0 * std::f64::consts::PI / l;
        let bins = PROFILE_BINS_PER_MODE * mmax;
        let dx = l / bins as f64;
        let mut profile = vec![0.0f64; bins];
        let mut sampled = 0.0;
        let mut add = |a: f64, x: f64, z: f64| {
            sampled += a;
            let u = (x / dx).rem_euclid(bins as f64);
            let i = (u.floor() as usize).min(bins - 1);
            let f = u - i as f64;
            profile[i] += a * z * (1.0 - f);
            profile[(i + 1) % bins] += a * z * f;
        };
        for t in mesh.triangles.iter().step_by(stride) {
            let v = t.map(|i| p[i as usize]);
            let coord = |w: glam::DVec3| if axis == 0 { w.x } else { w.y };
            let lo = v.iter().map(|w| coord(*w)).fold(f64::INFINITY, f64::min);
            let hi = v
                .iter()
                .map(|w| coord(*w))
                .fold(f64::NEG_INFINITY, f64::max);
            let n = ((q1 * mmax as f64 * (hi - lo) / 2.0).ceil() as usize).clamp(1, 64);
            // The n^2 pieces of a regular subdivision: n(n+1)/2 upright, n(n-1)/2 inverted.
            let at = |i: f64, j: f64| {
                v[0] + (v[1] - v[0]) * (i / n as f64) + (v[2] - v[0]) * (j / n as f64)
            };
            let a_piece = 0.5 * (v[1] - v[0]).cross(v[2] - v[0]).z.abs() / (n * n) as f64;
            for i in 0..n {
                for j in 0..n - i {
                    let (fi, fj) = (i as f64, j as f64);
                    let c = (at(fi, fj) + at(fi + 1.0, fj) + at(fi, fj + 1.0)) / 3.0;
                    add(a_piece, coord(c), c.z - mean);
                    if i + j + 1 < n {
                        let c =
                            (at(fi + 1.0, fj) + at(fi, fj + 1.0) + at(fi + 1.0, fj + 1.0)) / 3.0;
                        add(a_piece, coord(c), c.z - mean);
                    }
                }
            }
        }
        // exp(-i q_m x_b) by recurrence over the bins, for each mode.
        for m in 1..=mmax {
            let (sn, cs) = (q1 * m as f64 * dx).sin_cos();
            let (mut c, mut s) = (1.0, 0.0);
            let (mut re, mut im) = (0.0, 0.0);
            for &h in &profile {
                re += h * c;
                im -= h * s;
                (c, s) = (c * cs - s * sn, s * cs + c * sn);
            }
            let half = 0.5 * q1 * m as f64 * dx;
            let cic = (half.sin() / half).powi(2);
            let share =
                2.0 * (re * re + im * im) / (cic * cic) / (sampled * sampled) / (sigma * sigma);
            if share > best.1 {
                best = (l / m as f64, share);
            }
        }
    }
    best
}

/// Profile bins per mode scanned in [`strongest_axis_mode`]: the highest mode's deposit
/// factor is `sinc^2(pi / 16) = 0.987` (divided out).
const PROFILE_BINS_PER_MODE: usize = 16;

/// The squared curvature of each facet (1/nm^2): across each interior edge, the turn of
/// the normal over the mean of the two facets' altitudes onto the edge; each facet keeps
/// the largest of its edges (the principal curvature, whatever the facets' orientation).
/// [`super::scales`] averages it over the area for the RMS curvature.
pub(super) fn max_edge_curvature(mesh: &crate::sample::Mesh) -> Vec<f64> {
    let p = &mesh.positions_nm;
    let mut edges = std::collections::HashMap::<(u32, u32), usize>::new();
    let mut kmax = vec![0.0f64; mesh.triangles.len()];
    for (k, t) in mesh.triangles.iter().enumerate() {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            let key = (a.min(b), a.max(b));
            let Some(&o) = edges.get(&key) else {
                edges.insert(key, k);
                continue;
            };
            let (n1, n2) = (mesh.area_vector(k), mesh.area_vector(o));
            if n1.length() == 0.0 || n2.length() == 0.0 {
                continue;
            }
            let turn = n1.normalize().angle_between(n2.normalize());
            // Half the sum of the two facets' altitudes onto the edge (a regular grid's
            // cell width, where the curvature is sampled).
            let len = (p[b as usize] - p[a as usize]).length();
            let d = if len > 0.0 {
                (n1.length() + n2.length()) / (2.0 * len)
            } else {
                0.0
            };
            if d > 0.0 {
                let kappa2 = (turn / d).powi(2);
                kmax[k] = kmax[k].max(kappa2);
                kmax[o] = kmax[o].max(kappa2);
            }
        }
    }
    kmax
}
