//! Synthetic measured files in the RGL form, built in closed form for the tests.

use goniospec::export::tensor::Field;
use std::f64::consts::PI;

/// A synthetic measured file of a Lambertian material of albedo `rho` (per RGB channel),
/// built in closed form: a uniform VNDF makes the warp the identity (sample = `u_m`), so
/// node `(x, y)` is the half vector `theta_m = (x / (n - 1))^2 pi / 2`, `phi_m = 2 pi y /
/// (n - 1) - pi` from `phi_i`; with `jacobian = 0` the file stores `f cos(theta_o) =
/// rho cos(theta_o) / pi` there.
pub fn lambertian_file(rho: [f64; 3], theta_i: &[f64], n: usize) -> Vec<Field> {
    let nt = theta_i.len();
    let mut rgb = vec![0f32; nt * 3 * n * n];
    for (t, &ti) in theta_i.iter().enumerate() {
        let wi = goniospec::geom::from_spherical(ti, 0.0);
        for y in 0..n {
            for x in 0..n {
                let u = [x as f64 / (n - 1) as f64, y as f64 / (n - 1) as f64];
                let m = goniospec::geom::from_spherical(
                    u[0] * u[0] * PI / 2.0,
                    (2.0 * u[1] - 1.0) * PI,
                );
                let wo = m * (2.0 * m.dot(wi)) - wi;
                for c in 0..3 {
                    rgb[((t * 3 + c) * n + y) * n + x] = (rho[c] * wo.z.max(0.0) / PI) as f32;
                }
            }
        }
    }
    let f32s = |v: &[f64]| v.iter().map(|&x| x as f32).collect::<Vec<f32>>();
    vec![
        Field::u8("description", b"synthetic Lambertian"),
        Field::f32("theta_i", &[nt], &f32s(theta_i)),
        Field::f32("phi_i", &[1], &[0.0]),
        Field::f32("ndf", &[2, 2], &[1.0; 4]),
        Field::f32("sigma", &[2, 2], &[1.0; 4]),
        Field::f32("vndf", &[1, nt, n, n], &vec![1.0; nt * n * n]),
        Field::f32("luminance", &[1, nt, n, n], &vec![1.0; nt * n * n]),
        Field::f32("rgb", &[1, nt, 3, n, n], &rgb),
        Field::u8("jacobian", &[0]),
    ]
}
