//! The shape figures of appearance metrology for `compare`: the lobe in the plane of
//! incidence (its peak and width at half maximum), the lightness at the aspecular angles of
//! multi-angle instruments and the flop index, and the colour travel of effect pigments.
//!
//! An aspecular angle `a` is measured from the mirror direction towards the light, in the
//! plane of incidence: at incidence `theta_i` it looks from the signed outgoing angle
//! `theta_i - a` (positive on the mirror side). Multi-angle instruments light at 45 deg
//! and look at 15, 45 and 110 deg aspecular (ASTM E2194, metal-flake pigments), and also at
//! -15, 25 and 75 deg for interference pigments (ASTM E2539).

use glam::DVec3;

use super::{ColourSpace, lab_at};
use crate::brdf::Brdf;
use crate::geom::from_spherical;

/// The lobe in the plane of incidence, of the luminance of the BRDF (`Y` of `f`, 1/sr).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct LobeFigures {
    /// The largest value, 1/sr.
    pub peak_per_sr: f64,
    /// Where: the signed outgoing angle, degrees (positive on the mirror side).
    pub peak_at_deg: f64,
    /// The width of the region around the peak above half of it, degrees; `None` where it
    /// reaches the horizon on either side (a lobe as wide as the plane).
    pub fwhm_deg: Option<f64>,
}

/// Signed outgoing angles of the in-plane lobe, degrees: every half degree within 89.5.
fn plane_angles() -> Vec<f64> {
    (-179..=179).map(|k| f64::from(k) * 0.5).collect()
}

/// The outgoing direction at signed angle `t` (degrees) in the plane of incidence of
/// azimuth `phi_i` (degrees): positive towards the mirror side.
pub fn in_plane(t: f64, phi_i_deg: f64) -> DVec3 {
    let phi = if t >= 0.0 {
        phi_i_deg + 180.0
    } else {
        phi_i_deg
    };
    from_spherical(t.abs().to_radians(), phi.to_radians())
}

/// The in-plane luminance lobe of `brdf` at `(theta_i, phi_i)` (degrees): `(angle, Y)`.
pub fn plane_lobe(
    brdf: &(dyn Brdf + Sync),
    weights: &[[f64; 3]],
    theta_i_deg: f64,
    phi_i_deg: f64,
) -> Vec<(f64, f64)> {
    let wi = from_spherical(theta_i_deg.to_radians(), phi_i_deg.to_radians());
    let mut f = vec![0.0; weights.len()];
    plane_angles()
        .into_iter()
        .map(|t| {
            brdf.eval(wi, in_plane(t, phi_i_deg), &mut f);
            let y: f64 = f.iter().zip(weights).map(|(v, w)| v * w[1]).sum();
            (t, y)
        })
        .collect()
}

/// The peak and full width at half maximum of the in-plane luminance lobe.
pub fn lobe_figures(
    brdf: &(dyn Brdf + Sync),
    weights: &[[f64; 3]],
    theta_i_deg: f64,
    phi_i_deg: f64,
) -> LobeFigures {
    figures_of(&plane_lobe(brdf, weights, theta_i_deg, phi_i_deg))
}

/// [`LobeFigures`] of a sampled curve: the half-maximum crossings found by linear
/// interpolation between the samples on either side of the peak.
pub fn figures_of(lobe: &[(f64, f64)]) -> LobeFigures {
    let Some((k, &(at, peak))) = lobe
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.1.total_cmp(&b.1.1))
    else {
        return LobeFigures::default();
    };
    if peak.is_nan() || peak <= 0.0 {
        return LobeFigures {
            peak_per_sr: peak,
            peak_at_deg: at,
            fwhm_deg: None,
        };
    }
    let half = 0.5 * peak;
    let crossing = |range: &mut dyn Iterator<Item = usize>, step: isize| -> Option<f64> {
        for i in range {
            let j = (i as isize - step) as usize;
            if lobe[i].1 < half {
                let (x0, y0) = lobe[j];
                let (x1, y1) = lobe[i];
                return Some(x0 + (half - y0) / (y1 - y0) * (x1 - x0));
            }
        }
        None
    };
    let right = crossing(&mut (k + 1..lobe.len()), 1);
    let left = crossing(&mut (0..k).rev(), -1);
    LobeFigures {
        peak_per_sr: peak,
        peak_at_deg: at,
        fwhm_deg: left.zip(right).map(|(l, r)| r - l),
    }
}

/// The lightness at 15, 45 and 110 deg aspecular under 45 deg light, and the flop index
/// `FI = 2.69 (L*15 - L*110)^1.11 / (L*45)^0.86` (the DuPont flop index, as X-Rite's
/// "Color iQC and Color iMatch Color Calculations Guide", v8.0, 2012, gives it): 0 for a
/// solid colour, 15-17 for a strongly flopping metallic. `None` where `L*15 <= L*110` or
/// `L*45 = 0`, where the formula has no value.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct FlopSide {
    pub l15: f64,
    pub l45: f64,
    pub l110: f64,
    pub flop_index: Option<f64>,
}

/// Both sides' [`FlopSide`].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Flop {
    pub a: FlopSide,
    pub b: FlopSide,
}

/// The lightness of `brdf` at aspecular angle `asp` (degrees) under 45 deg light.
fn aspecular_lab(
    brdf: &(dyn Brdf + Sync),
    weights: &[[f64; 3]],
    space: &ColourSpace,
    asp: f64,
) -> [f64; 3] {
    let wi = from_spherical(45f64.to_radians(), 0.0);
    let mut f = vec![0.0; weights.len()];
    lab_at(brdf, weights, space, wi, in_plane(45.0 - asp, 0.0), &mut f)
}

fn flop_side(brdf: &(dyn Brdf + Sync), weights: &[[f64; 3]], space: &ColourSpace) -> FlopSide {
    let l = |a: f64| aspecular_lab(brdf, weights, space, a)[0];
    let (l15, l45, l110) = (l(15.0), l(45.0), l(110.0));
    FlopSide {
        l15,
        l45,
        l110,
        flop_index: (l15 > l110 && l45 > 0.0)
            .then(|| 2.69 * (l15 - l110).powf(1.11) / l45.powf(0.86)),
    }
}

/// The flop figures of both materials.
pub fn flop(
    a: &(dyn Brdf + Sync),
    wa: &[[f64; 3]],
    b: &(dyn Brdf + Sync),
    wb: &[[f64; 3]],
    space: &ColourSpace,
) -> Flop {
    Flop {
        a: flop_side(a, wa, space),
        b: flop_side(b, wb, space),
    }
}

/// The aspecular angles of the colour travel, degrees.
pub const TRAVEL_ASPECULAR_DEG: [f64; 6] = [-15.0, 15.0, 25.0, 45.0, 75.0, 110.0];

/// One aspecular angle of the colour travel: lightness, chroma `C*ab` and hue angle
/// `h_ab` (degrees) of each material, and their CIEDE2000.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct TravelRow {
    pub aspecular_deg: f64,
    pub a_lch: [f64; 3],
    pub b_lch: [f64; 3],
    pub delta_e: f64,
}

/// `(L*, C*ab, h_ab in degrees [0, 360))` of a CIELAB colour (CIE 15:2004 §8.2.1).
pub fn lch(lab: [f64; 3]) -> [f64; 3] {
    [
        lab[0],
        lab[1].hypot(lab[2]),
        lab[2].atan2(lab[1]).to_degrees().rem_euclid(360.0),
    ]
}

/// The colour travel of both materials under 45 deg light.
pub fn travel(
    a: &(dyn Brdf + Sync),
    wa: &[[f64; 3]],
    b: &(dyn Brdf + Sync),
    wb: &[[f64; 3]],
    space: &ColourSpace,
) -> Vec<TravelRow> {
    TRAVEL_ASPECULAR_DEG
        .iter()
        .map(|&asp| {
            let (la, lb) = (
                aspecular_lab(a, wa, space, asp),
                aspecular_lab(b, wb, space, asp),
            );
            TravelRow {
                aspecular_deg: asp,
                a_lch: lch(la),
                b_lch: lch(lb),
                delta_e: crate::render::colour::delta_e2000(la, lb),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A Gaussian of standard deviation s has a full width at half maximum of
    /// `2 sqrt(2 ln 2) s`; the interpolated crossings find it to the sampling's accuracy.
    #[test]
    fn a_gaussian_lobe_has_its_closed_form_width() {
        let s = 7.0;
        let lobe: Vec<(f64, f64)> = plane_angles()
            .into_iter()
            .map(|t| (t, 3.0 * (-(t - 20.0) * (t - 20.0) / (2.0 * s * s)).exp()))
            .collect();
        let f = figures_of(&lobe);
        assert_eq!(f.peak_per_sr, 3.0);
        assert_eq!(f.peak_at_deg, 20.0);
        let want = 2.0 * (2.0 * 2f64.ln()).sqrt() * s;
        assert!((f.fwhm_deg.unwrap() - want).abs() < 0.02, "{f:?} vs {want}");
        // A flat lobe never falls to half: as wide as the plane.
        let flat: Vec<(f64, f64)> = plane_angles().into_iter().map(|t| (t, 1.0)).collect();
        assert_eq!(figures_of(&flat).fwhm_deg, None);
    }

    #[test]
    fn lch_of_the_axes() {
        assert_eq!(lch([50.0, 0.0, 10.0]), [50.0, 10.0, 90.0]);
        let c = lch([50.0, -3.0, -4.0]);
        assert!((c[1] - 5.0).abs() < 1e-12 && (c[2] - 233.130_102_354_155_98).abs() < 1e-9);
    }
}
