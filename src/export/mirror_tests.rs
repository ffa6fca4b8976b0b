//! The sharp mirror against closed forms: a Lambertian table with a known mirror power
//! added to the bucket a ray reflected by a flat surface reaches.

use super::*;
use crate::brdf::{Kind, hemispherical_reflectance};
use crate::geom::from_spherical;

const TB: usize = 45;
const PB: usize = 36;
/// Lambertian albedo of the background, per wavelength bin.
const RHO: [f64; 2] = [0.2, 0.5];

/// The mirror's power at `theta_i` (degrees): any smooth rise will do.
fn mirror_power(theta_deg: f64, j: usize) -> f64 {
    0.04 + 0.001 * theta_deg + 0.01 * j as f64
}

/// A table at `angles` (degrees) of a Lambertian surface of albedo `RHO`, plus, where
/// `with_mirror`, the mirror power in the one bucket the exact mirror direction falls in
/// (the upper one on an edge, as the float rounding of a ray may choose), or spread over
/// the first ring at normal incidence; `noise` adds a deterministic relative ripple.
fn table(angles: &[f64], with_mirror: bool, noise: f64) -> TableBrdf {
    let nl = RHO.len();
    let dt = FRAC_PI_2 / TB as f64;
    let dp = TAU / PB as f64;
    let proj = |t: usize| {
        let (a, b) = ((t as f64 * dt).sin(), ((t + 1) as f64 * dt).sin());
        0.5 * (b * b - a * a) * dp
    };
    let mut values = Vec::new();
    for &deg in angles {
        let mut slice = vec![0.0; TB * PB * nl];
        for (k, v) in slice.iter_mut().enumerate() {
            let ripple = 1.0 + noise * (((k * 7919) % 101) as f64 / 50.0 - 1.0);
            *v = RHO[k % nl] / PI * ripple;
        }
        if with_mirror {
            let cells: Vec<(usize, usize)> = if deg == 0.0 {
                (0..PB).map(|p| (0, p)).collect()
            } else {
                let t = (deg.to_radians() / dt + 1e-9).floor() as usize;
                vec![(t, (PB / 2) % PB)]
            };
            let omega: f64 = cells.iter().map(|&(t, _)| proj(t)).sum();
            for (t, p) in cells {
                for j in 0..nl {
                    slice[(t * PB + p) * nl + j] += mirror_power(deg, j) / omega;
                }
            }
        }
        values.extend(slice);
    }
    TableBrdf {
        theta_i_rad: angles.iter().map(|d| d.to_radians()).collect(),
        theta_bins: TB,
        phi_bins: PB,
        phi_i_rad: 0.0,
        values,
        meta: Meta {
            repr: Kind::Table,
            lambda_nm: vec![450.0, 650.0],
            spectrum: None,
            sample_name: "test".into(),
            sample_hash: String::new(),
            simulation: String::new(),
            isotropic: true,
            reciprocal: false,
            median_rel_stderr: None,
            trees_per_direction: None,
            incident_stokes: None,
            rgb: false,
        },
    }
}

/// The mirror direction of light arriving from `(theta_i, 0)`.
fn mirror(theta_deg: f64) -> DVec3 {
    from_spherical(theta_deg.to_radians(), PI)
}

#[test]
fn the_mirror_buckets_power_becomes_a_lobe_carrying_the_same_power() {
    let angles = [0.0, 30.0, 50.0];
    let t = table(&angles, true, 0.0);
    let width = SharpMirror::width_for(65);
    assert!((width.to_degrees() - 0.3516).abs() < 1e-3);
    let m = SharpMirror::from_table(&t, width).unwrap();
    for (i, &deg) in angles.iter().enumerate() {
        // The excess over a flat surround is the power put in, to rounding.
        for j in 0..2 {
            let want = mirror_power(deg, j);
            assert!(
                (m.power(i)[j] - want).abs() < 1e-12,
                "{deg} deg: {:?}",
                m.power(i)
            );
        }
        // The mirror's buckets now hold the background, and the lobe's albedo adds the
        // power back (a 2,880 x 2,880 midpoint rule resolves a 0.7-degree lobe).
        let wi = from_spherical(deg.to_radians(), 0.0);
        let a = hemispherical_reflectance(&m, wi, 2880, 2880);
        let b = hemispherical_reflectance(m.background(), wi, 360, 360);
        for j in 0..2 {
            assert!((b[j] - RHO[j]).abs() < 1e-4, "{deg} deg: background {b:?}");
            let want = RHO[j] + mirror_power(deg, j);
            assert!(
                (a[j] - want).abs() < 2e-3 * want,
                "{deg} deg: albedo {} against {want}",
                a[j]
            );
        }
    }
}

#[test]
fn between_simulated_angles_the_lobe_follows_the_mirror() {
    let t = table(&[30.0, 50.0], true, 0.0);
    let m = SharpMirror::from_table(&t, SharpMirror::width_for(65)).unwrap();
    let wi = from_spherical(40f64.to_radians(), 0.0);
    let mut f = [0.0; 2];
    let mut g = [0.0; 2];
    // The table shows two half-height copies at the neighbours' mirrors; the lobe one, at
    // 40 degrees, with the mean of their powers.
    for ghost in [30.0, 50.0] {
        t.eval(wi, mirror(ghost), &mut g);
        assert!(
            g[0] > 2.0 * RHO[0] / PI,
            "the table's copy at {ghost}: {g:?}"
        );
        m.eval(wi, mirror(ghost), &mut f);
        assert!((f[0] - RHO[0] / PI).abs() < 1e-9 * RHO[0], "{ghost}: {f:?}");
    }
    let a = hemispherical_reflectance(&m, wi, 2880, 2880);
    let want = RHO[0] + 0.5 * (mirror_power(30.0, 0) + mirror_power(50.0, 0));
    // The lobe's albedo, which `render` adds to the rest's, is the interpolated power.
    let mut e = [0.0; 2];
    m.power_at(40f64.to_radians(), &mut e);
    assert!((e[0] + RHO[0] - want).abs() < 1e-12, "{e:?}");
    assert!((a[0] - want).abs() < 2e-3 * want, "{a:?} against {want}");
    // Sharp: the peak is that of a lobe of solid angle 2 pi (2 s)(2 s cos theta_i) (a
    // Gaussian of half-vector spread s, reflected: Walter et al. 2007, eq. 14), 5.4 times
    // the bucket's 2 x 10 degree value at 40 degrees; 3 degrees off the mirror the lobe
    // has fallen below 1 % of it.
    m.eval(wi, mirror(40.0), &mut f);
    let peak = f[0] - RHO[0] / PI;
    let power = 0.5 * (mirror_power(30.0, 0) + mirror_power(50.0, 0));
    let (s, c) = (SharpMirror::width_for(65), 40f64.to_radians().cos());
    let lobe = power / (TAU * 4.0 * s * s * c * c);
    assert!(
        (peak - lobe).abs() < 0.01 * lobe,
        "peak {peak}, Gaussian {lobe}"
    );
    let bucket = power / (2f64.to_radians() * 10f64.to_radians() * 40f64.to_radians().sin() * c);
    assert!(peak > 5.0 * bucket, "peak {peak}, bucket {bucket}");
    let off = from_spherical(
        40f64.to_radians(),
        PI + 3f64.to_radians() / 40f64.to_radians().sin(),
    );
    m.eval(wi, off, &mut f);
    assert!(f[0] - RHO[0] / PI < 0.01 * peak, "{f:?}, peak {peak}");
}

#[test]
fn no_mirror_is_made_of_noise() {
    // A rippled Lambertian table holds no mirror: refused, naming the angle.
    let err = SharpMirror::from_table(&table(&[0.0, 30.0], false, 0.05), 0.01)
        .err()
        .unwrap();
    assert!(err.0.contains("within its noise"), "{}", err.0);
    // The same ripple under a mirror leaves it found.
    assert!(SharpMirror::from_table(&table(&[0.0, 30.0], true, 0.05), 0.01).is_ok());
}

#[test]
fn a_mirror_on_a_bucket_edge_is_found_on_either_side() {
    // 30 deg lies on the edge between rows 14 and 15, and 180 deg on the edge between
    // azimuth buckets 17 and 18: every bucket the rounding may choose is inside.
    let b = mirror_block(30f64.to_radians(), 0.0, TB, PB);
    for cell in [(14, 17), (14, 18), (15, 17), (15, 18)] {
        assert!(b.inside.contains(&cell), "{:?}", b.inside);
    }
    assert_eq!(b.around.len(), 12);
    // 31 deg lies inside row 15.
    let b = mirror_block(31f64.to_radians(), 0.0, TB, PB);
    assert!(b.inside.iter().all(|&(t, _)| t == 15));
}

#[test]
fn a_grid_with_no_bucket_beside_the_mirror_is_refused_not_a_panic() {
    // One bucket over the hemisphere: nothing to tell the mirror from (it panicked on an
    // empty median).
    let mut t = table(&[40.0], true, 0.0);
    t.theta_bins = 1;
    t.phi_bins = 1;
    t.values = vec![0.1; 2];
    let err = SharpMirror::from_table(&t, 0.01).err().unwrap();
    assert!(err.0.contains("no bucket beside the mirror's"), "{}", err.0);
}
