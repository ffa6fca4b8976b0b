//! Mitsuba 3's `measured_polarized` tensor file (`.pbsdf`): an isotropic Mueller-matrix
//! BRDF on a grid of Rusinkiewicz angles at five wavelengths, the format of Baek et al.'s
//! measured pBRDFs ("Image-based acquisition and modeling of polarimetric reflectance",
//! SIGGRAPH 2020), read by Mitsuba's `measured_polarized` plugin in its
//! `*_spectral_polarized` variants.
//!
//! Fields, in the tensor file of [`super::tensor`]:
//!
//! | field | dtype, shape | meaning |
//! |---|---|---|
//! | `phi_d`, `theta_d`, `theta_h` | float32 `[1, n]` | the grid, radians (`phi_d` over `[-pi, pi]`) |
//! | `wvls` | uint16 `[5]` | 450, 500, 550, 600, 650 nm |
//! | `M` | float32 `[phi_d, theta_d, theta_h, 5, 4, 4]` | the Mueller BRDF, 1/sr, row-major; NaN below the horizon |
//!
//! The angles are those the plugin computes: with `h` the half vector of the light's
//! direction `i` and the viewer's `o`, `theta_h = acos(h . z)`, `theta_d = acos(h . i)`, and
//! `phi_d` the azimuth of `i` about `h` from `t = normalize((z × h) × h)` towards
//! `b = normalize(z × h)`. Each matrix maps Stokes vectors in the frame of the plane of
//! reflection on the incident side (`z = -i`, `y` along `((i - o) × z) × z`, `x = y × z`) to
//! those on the outgoing side (`z = o`, `y` along `((o - i) × z) × z`), as the plugin
//! rotates them to its own bases.
//!
//! From a `--mueller` accumulator: at each grid point and wavelength, the matrix of the
//! bucket the outgoing direction falls in, interpolated linearly between the simulated
//! incident angles (the nearest at either end) and the wavelength bins' centres, turned
//! from the directions' own s/p frames (docs/physics.md, "Polarisation") to the plugin's,
//! with S3 of Mitsuba's sign (the opposite of ours).

use glam::DVec3;

use super::ExportError;
use super::tensor::Field;
use crate::accumulate::file::Accumulator;
use crate::optics::mueller::{Mueller, frame};

/// The five wavelengths the plugin reads, nm.
pub const WAVELENGTHS_NM: [u16; 5] = [450, 500, 550, 600, 650];

/// Grid points along each Rusinkiewicz angle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PbsdfGrid {
    pub phi_d: usize,
    pub theta_d: usize,
    pub theta_h: usize,
}

impl Default for PbsdfGrid {
    /// 5 degrees in phi_d and theta_d, 1 degree in theta_h (the specular peak's axis).
    fn default() -> Self {
        PbsdfGrid {
            phi_d: 73,
            theta_d: 19,
            theta_h: 91,
        }
    }
}

/// The light's and the viewer's directions `(i, o)` of Rusinkiewicz angles (radians), with
/// the half vector at azimuth 0: the inverse of the plugin's `directions_to_rusinkiewicz`;
/// and the unit direction of `i - o` (across the half vector, at azimuth `phi_d` about it),
/// which stays defined where `theta_d = 0` and `i = o`.
pub fn rusinkiewicz_directions(theta_h: f64, theta_d: f64, phi_d: f64) -> (DVec3, DVec3, DVec3) {
    let h = DVec3::new(theta_h.sin(), 0.0, theta_h.cos());
    // b = z × h normalised is y for any theta_h > 0 (and its limit at 0); t = b × h.
    let b = DVec3::Y;
    let t = b.cross(h);
    let i_prj = t * phi_d.cos() + b * phi_d.sin();
    let i = h * theta_d.cos() + i_prj * theta_d.sin();
    let o = 2.0 * i.dot(h) * h - i;
    (i, o, i_prj)
}

/// The Stokes rotation taking a vector in the basis whose `x` is `from` to the basis whose
/// `x` is `to`, both across the direction of travel `w`: the basis turned by `a` about
/// `w` gives `S1' = cos 2a S1 + sin 2a S2`, `S2' = -sin 2a S1 + cos 2a S2`.
fn rotation(w: DVec3, from: DVec3, to: DVec3) -> Mueller {
    let a = w.dot(from.cross(to)).atan2(from.dot(to));
    let (s, c) = (2.0 * a).sin_cos();
    [
        1.0, 0.0, 0.0, 0.0, //
        0.0, c, s, 0.0, //
        0.0, -s, c, 0.0, //
        0.0, 0.0, 0.0, 1.0,
    ]
}

fn mul(a: &Mueller, b: &Mueller) -> Mueller {
    std::array::from_fn(|k| (0..4).map(|m| a[4 * (k / 4) + m] * b[4 * m + k % 4]).sum())
}

/// The plugin's Stokes `x` axes for light from `i` (the light's direction) seen from `o`:
/// on the incident side (travelling along `-i`) and on the outgoing side (along `o`).
/// `across` is the unit direction of `i - o` (the plane of reflection's; given, so that
/// the limit holds where `i = o`).
pub fn plugin_frames(i: DVec3, o: DVec3, across: DVec3) -> (DVec3, DVec3) {
    let x_axis = |z: DVec3, other: DVec3| {
        let t = other.cross(z).normalize();
        let y = t.cross(z).normalize();
        y.cross(z)
    };
    (x_axis(-i, across), x_axis(o, -across))
}

/// The Mueller BRDF (1/sr) of a `--mueller` accumulator for light from `i` seen from `o`
/// at `lambda_nm`, in the directions' own s/p frames (see the module's notes), or `None`
/// below the horizon.
fn brdf_at(acc: &Accumulator, i: DVec3, o: DVec3, lambda_nm: f64) -> Option<Mueller> {
    if i.z <= 0.0 || o.z <= 0.0 {
        return None;
    }
    let s = &acc.header.settings;
    // Isotropic: turned about the normal so that the light has the simulated azimuth.
    let turn = s.phi_i_deg.to_radians() - i.y.atan2(i.x);
    let q = glam::DQuat::from_rotation_z(turn);
    let o = q * o;
    let theta_i = i.z.clamp(-1.0, 1.0).acos().to_degrees();
    let b = s.buckets();
    let k = 2 * b.index(o);
    let omega = b.projected_solid_angle(k / 2);
    let nl = s.wavelength_count();
    // Linear weights between neighbouring samples of an ascending axis (the nearest beyond
    // its ends).
    let weights = |axis: &[f64], x: f64| -> [(usize, f64); 2] {
        let n = axis.len();
        if n == 1 || x <= axis[0] {
            return [(0, 1.0), (0, 0.0)];
        }
        if x >= axis[n - 1] {
            return [(n - 1, 1.0), (n - 1, 0.0)];
        }
        let j = axis.partition_point(|&a| a <= x) - 1;
        let f = (x - axis[j]) / (axis[j + 1] - axis[j]);
        [(j, 1.0 - f), (j + 1, f)]
    };
    let mut order: Vec<usize> = (0..s.theta_i_deg.len()).collect();
    order.sort_by(|&a, &b| s.theta_i_deg[a].total_cmp(&s.theta_i_deg[b]));
    let thetas: Vec<f64> = order.iter().map(|&d| s.theta_i_deg[d]).collect();
    let lambdas: Vec<f64> = (0..nl).map(|j| s.wavelength(j)).collect();
    let mut m = [0.0; 16];
    for (ti, wt) in weights(&thetas, theta_i) {
        for (lj, wl) in weights(&lambdas, lambda_nm) {
            let w = wt * wl;
            if w == 0.0 {
                continue;
            }
            let cell = acc.cell(order[ti], lj);
            let v = cell.mueller(k).unwrap_or([0.0; 16]);
            for (a, x) in m.iter_mut().zip(v) {
                *a += w * x / omega;
            }
        }
    }
    Some(m)
}

/// The matrix `brdf_at` gives, turned from the directions' s/p frames to the plugin's
/// (`across`: the unit direction of `i - o`, see [`plugin_frames`]).
pub fn plugin_matrix(
    acc: &Accumulator,
    i: DVec3,
    o: DVec3,
    across: DVec3,
    lambda_nm: f64,
) -> Option<Mueller> {
    let m = brdf_at(acc, i, o, lambda_nm)?;
    let (x_in, x_out) = plugin_frames(i, o, across);
    let (p_in, _) = frame(-i);
    let (p_out, _) = frame(o);
    let into_ours = rotation(-i, x_in, p_in);
    let into_plugin = rotation(o, p_out, x_out);
    let mut v = mul(&into_plugin, &mul(&m, &into_ours));
    // Mitsuba's S3 has the other sign: its smooth `conductor` gives gold's reflection at 45
    // deg with m23 = -Im(r_p conj r_s) in these frames (tests/interop/mueller_mitsuba.py),
    // the complex conjugate's matrix. Flipping S3 on both sides conjugates.
    for (k, x) in v.iter_mut().enumerate() {
        if (k / 4 == 3) != (k % 4 == 3) {
            *x = -*x;
        }
    }
    Some(v)
}

/// What a `.pbsdf` of `acc` stands in for (issue 74): the file covers every incident angle
/// from 0 to 90 degrees and the plugin's five wavelengths, 450 to 650 nm, and
/// [`pbsdf_fields`] interpolates linearly between the simulated incident angles and bin
/// centres and holds the nearest beyond them. The sentence says which angles and
/// wavelengths are simulated and which are held; `alone` is true where one simulated angle
/// or one wavelength stands in for all of them (the CLI refuses that without `--force`).
#[derive(Clone, Debug, PartialEq)]
pub struct StandsIn {
    pub sentence: String,
    pub alone: bool,
}

/// See [`StandsIn`].
pub fn stands_in(acc: &Accumulator) -> StandsIn {
    let s = &acc.header.settings;
    let angles = &s.theta_i_deg;
    let centres: Vec<f64> = (0..s.wavelength_count()).map(|j| s.wavelength(j)).collect();
    let list = |v: &[f64]| {
        v.iter()
            .map(|x| format!("{x}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let (lo, hi) = (
        angles.iter().copied().fold(f64::INFINITY, f64::min),
        angles.iter().copied().fold(f64::NEG_INFINITY, f64::max),
    );
    let (wlo, whi) = (
        centres.iter().copied().fold(f64::INFINITY, f64::min),
        centres.iter().copied().fold(f64::NEG_INFINITY, f64::max),
    );
    let held: Vec<u16> = WAVELENGTHS_NM
        .iter()
        .copied()
        .filter(|&l| f64::from(l) < wlo || f64::from(l) > whi)
        .collect();
    let angle_part = if angles.len() == 1 {
        format!(
            "the one simulated incident angle, {lo} deg, stands in for every incident angle from 0 to 90 deg"
        )
    } else {
        format!(
            "incident angles between the simulated {} deg are interpolated linearly{}",
            list(angles),
            match (lo > 0.0, hi < 90.0) {
                (true, true) => format!(", and {lo} deg stands in below them and {hi} deg above"),
                (true, false) => format!(", and {lo} deg stands in below them"),
                (false, true) => format!(", and {hi} deg stands in above them, to 90 deg"),
                (false, false) => String::new(),
            }
        )
    };
    let wl_part = if centres.len() == 1 {
        format!("the one simulated wavelength, {wlo} nm, stands in for all five of 450 to 650 nm")
    } else if held.is_empty() {
        format!(
            "the five wavelengths are interpolated between the bins centred at {} nm",
            list(&centres)
        )
    } else {
        format!(
            "the five wavelengths are interpolated between the bins centred at {} nm, and {} nm take the nearest bin's matrices",
            list(&centres),
            held.iter()
                .map(|l| l.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        )
    };
    StandsIn {
        sentence: format!("{angle_part}; {wl_part}"),
        alone: angles.len() == 1 || centres.len() == 1,
    }
}

/// The `.pbsdf` fields of a `--mueller` accumulator on `grid`.
pub fn pbsdf_fields(acc: &Accumulator, grid: PbsdfGrid) -> Result<Vec<Field>, ExportError> {
    let s = &acc.header.settings;
    if !s.mueller {
        return Err(ExportError::from(
            "the accumulator holds no Mueller matrices: simulate with --mueller (the measured_polarized format holds the full matrix)",
        ));
    }
    if grid.phi_d < 2 || grid.theta_d < 2 || grid.theta_h < 2 {
        return Err(ExportError::from(
            "the Rusinkiewicz grid needs at least 2 points per angle",
        ));
    }
    let lin = |n: usize, lo: f64, hi: f64| -> Vec<f64> {
        (0..n)
            .map(|k| lo + (hi - lo) * k as f64 / (n - 1) as f64)
            .collect()
    };
    let half = std::f64::consts::FRAC_PI_2;
    let pd = lin(grid.phi_d, -std::f64::consts::PI, std::f64::consts::PI);
    let td = lin(grid.theta_d, 0.0, half);
    let th = lin(grid.theta_h, 0.0, half);
    let mut m: Vec<f32> = Vec::with_capacity(pd.len() * td.len() * th.len() * 5 * 16);
    for &p in &pd {
        for &d in &td {
            for &h in &th {
                let (i, o, across) = rusinkiewicz_directions(h, d, p);
                for &l in &WAVELENGTHS_NM {
                    match plugin_matrix(acc, i, o, across, f64::from(l)) {
                        Some(v) => m.extend(v.iter().map(|&x| x as f32)),
                        None => m.extend([f32::NAN; 16]),
                    }
                }
            }
        }
    }
    let axis = |name: &str, v: &[f64]| {
        Field::f32(
            name,
            &[1, v.len()],
            &v.iter().map(|&x| x as f32).collect::<Vec<_>>(),
        )
    };
    Ok(vec![
        axis("phi_d", &pd),
        axis("theta_d", &td),
        axis("theta_h", &th),
        Field::u16("wvls", &WAVELENGTHS_NM),
        Field::f32("M", &[pd.len(), td.len(), th.len(), 5, 4, 4], &m),
    ])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The grid's directions give back its angles by the plugin's own construction
    /// (written here from its description), and their half vector is `h`.
    #[test]
    fn rusinkiewicz_directions_invert_the_plugins_angles() {
        for (h, d, p) in [(0.3, 0.5, 1.0), (0.8, 0.2, -2.5), (0.1, 1.2, 3.0)] {
            let (i, o, across) = rusinkiewicz_directions(h, d, p);
            assert!(((i - o).normalize() - across).length() < 1e-12);
            let hv = (i + o).normalize();
            let n = DVec3::Z;
            let b = n.cross(hv).normalize();
            let t = b.cross(hv).normalize();
            let ip = (i - i.dot(hv) * hv).normalize();
            assert!((hv.dot(i).acos() - d).abs() < 1e-12);
            assert!((n.dot(hv).acos() - h).abs() < 1e-12);
            assert!((b.dot(ip).atan2(t.dot(ip)) - p).abs() < 1e-12);
        }
    }

    /// A Stokes rotation by a and back is the identity; by 90 degrees it swaps the sign of
    /// S1 and S2 (x and y exchange).
    #[test]
    fn rotations_compose() {
        let w = DVec3::new(0.2, -0.3, 0.9).normalize();
        let (p, s) = frame(w);
        let x = (p * 0.6 + s * 0.8).normalize();
        let m = mul(&rotation(w, x, p), &rotation(w, p, x));
        for (k, v) in m.iter().enumerate() {
            let want = if k % 5 == 0 { 1.0 } else { 0.0 };
            assert!((v - want).abs() < 1e-12);
        }
        let r = rotation(w, p, s);
        assert!((r[5] + 1.0).abs() < 1e-12 && (r[10] + 1.0).abs() < 1e-12);
    }
}
