//! Small f64 vector helpers for the tracer's phase-critical arithmetic (glam's DVec3 would
//! do, but plain arrays keep the ray records `#[repr(C)]`-friendly and copyable).

pub type V3 = [f64; 3];

#[inline]
pub fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
#[inline]
pub fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
#[inline]
pub fn scale(a: V3, s: f64) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}
#[inline]
pub fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
#[inline]
pub fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
#[inline]
pub fn norm(a: V3) -> f64 {
    dot(a, a).sqrt()
}
#[inline]
pub fn normalize(a: V3) -> V3 {
    scale(a, 1.0 / norm(a))
}

/// The unit vector of spherical angles (theta from +z, phi from +x), radians.
pub fn from_spherical(theta_rad: f64, phi_rad: f64) -> V3 {
    let s = theta_rad.sin();
    [s * phi_rad.cos(), s * phi_rad.sin(), theta_rad.cos()]
}
