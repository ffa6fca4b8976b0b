//! Complex Fresnel amplitude coefficients and the split of a ray's electric field at an
//! interface into a reflected and a transmitted field.
//!
//! Basis: for a wave travelling along `k`, `s = normalize(k_i x n)` is perpendicular to the
//! plane of incidence (shared by all three waves) and `p = s x k` lies in it. In this basis
//! the coefficients are (Born & Wolf, Principles of Optics, 7th ed., §1.5.2, eqs. 20–21, with
//! complex indices as in §14.2; also Byrnes, "Multilayer optical calculations",
//! arXiv:1603.02720, eqs. 1–4):
//!
//! ```text
//! r_s = (n1 cos_i - n2 cos_t) / (n1 cos_i + n2 cos_t)     t_s = 2 n1 cos_i / (n1 cos_i + n2 cos_t)
//! r_p = (n2 cos_i - n1 cos_t) / (n2 cos_i + n1 cos_t)     t_p = 2 n1 cos_i / (n2 cos_i + n1 cos_t)
//! ```
//!
//! with `n1 sin_i = n2 sin_t` and the complex `cos_t = sqrt(1 - sin_t^2)` on the branch
//! whose wave decays or propagates away from the interface (`Im(n2 cos_t) >= 0`, and
//! `Re(n2 cos_t) >= 0` for a propagating wave). Total internal reflection follows
//! (|r| = 1, no transmitted power).
//!
//! Transmitted power fractions (Byrnes eqs. 21–22): `T_s = Re(n2 cos_t) / Re(n1 cos_i) |t_s|^2`
//! and `T_p = Re(n2 conj(cos_t)) / Re(n1 conj(cos_i)) |t_p|^2`; the tracer carries
//! power-normalised amplitudes, `t` times the square root of that ratio, so `|E|^2` is always
//! a fraction of launched power (DESIGN.md §3).

use super::C64;
use super::vec3::{V3, add, cross, dot, normalize, scale};

/// Fresnel amplitude coefficients of one interface for one angle of incidence.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coefficients {
    pub r_s: C64,
    pub r_p: C64,
    /// Power-normalised transmission amplitudes (`t` times `sqrt(T / |t|^2)`).
    pub t_s: C64,
    pub t_p: C64,
    /// Complex cosine of the transmitted angle.
    pub cos_t: C64,
}

/// The complex `n cos(theta)` of a wave in a medium of index `n` whose tangential wave
/// number is fixed by `n1 sin_i` (Snell), on the decaying / outgoing branch.
pub fn n_cos(n: C64, n1_sin_i: C64) -> C64 {
    let v = (n * n - n1_sin_i * n1_sin_i).sqrt();
    // Choose the root whose wave decays into the medium, or for a (nearly) lossless medium
    // propagates forward (Byrnes §2, "is_forward_angle").
    let forward = if v.im.abs() > 1e-12 * v.norm().max(1e-300) {
        v.im > 0.0
    } else {
        v.re > 0.0
    };
    if forward { v } else { -v }
}

/// Coefficients for a ray meeting the interface at real geometric `cos_i` (0 < cos_i <= 1)
/// from index `n1` onto `n2`.
///
/// The tangential wave number `Re(n1) sin_i` is real and conserved, as in the
/// transfer-matrix method where `n_j sin(theta_j) = n_0 sin(theta_0)` for a real ambient
/// (Byrnes §3): rays travel geometrically with `Re n`, so a ray inside an absorbing layer
/// carries the same real tangential component it entered with, and the complex cosines on
/// both sides follow from it.
pub fn coefficients(n1: C64, n2: C64, cos_i: f64) -> Coefficients {
    let sin_i = (1.0 - cos_i * cos_i).max(0.0).sqrt();
    let kx = C64::new(n1.re * sin_i, 0.0);
    let n1ci = n_cos(n1, kx);
    let n2ct = n_cos(n2, kx);
    let cos_t = n2ct / n2;
    let ci = n1ci / n1;
    let r_s = (n1ci - n2ct) / (n1ci + n2ct);
    let r_p = (n2 * ci - n1 * cos_t) / (n2 * ci + n1 * cos_t);
    let t_s = 2.0 * n1ci / (n1ci + n2ct);
    let t_p = 2.0 * n1ci / (n2 * ci + n1 * cos_t);
    // Power ratios; zero under total internal reflection (Re(n2 cos_t) = 0).
    let ratio_s = ((n2ct).re / n1ci.re).max(0.0);
    let ratio_p = ((n2 * cos_t.conj()).re / (n1 * ci.conj()).re).max(0.0);
    Coefficients {
        r_s,
        r_p,
        t_s: t_s * ratio_s.sqrt(),
        t_p: t_p * ratio_p.sqrt(),
        cos_t,
    }
}

/// A complex field vector (3 components in the sample frame).
pub type Field = [C64; 3];

#[inline]
pub fn field_dot_real(e: &Field, v: V3) -> C64 {
    e[0] * v[0] + e[1] * v[1] + e[2] * v[2]
}

/// Hermitian product `a . conj(b)`.
#[inline]
pub fn hermitian(a: &Field, b: &Field) -> C64 {
    a[0] * b[0].conj() + a[1] * b[1].conj() + a[2] * b[2].conj()
}

#[inline]
pub fn field_power(e: &Field) -> f64 {
    e[0].norm_sqr() + e[1].norm_sqr() + e[2].norm_sqr()
}

/// Geometry and fields of one interface event.
#[derive(Clone, Copy, Debug)]
pub struct Split {
    /// Reflected direction (unit).
    pub dir_r: V3,
    /// Transmitted direction (unit), or `None` under total internal reflection in the
    /// geometric sense (`Re n`).
    pub dir_t: Option<V3>,
    pub s: V3,
    pub p_i: V3,
    pub p_r: V3,
    pub p_t: V3,
}

/// Reflected and refracted directions for a ray along unit `d` meeting a surface with
/// unit normal `n` facing the incoming side (`d . n < 0`), from real index `eta1` into
/// `eta2` (Snell's law with the real parts: DESIGN.md §3). Also the s/p basis vectors.
pub fn split_geometry(d: V3, n: V3, eta1: f64, eta2: f64) -> Split {
    let cos_i = -dot(d, n);
    debug_assert!(cos_i >= 0.0, "normal must face the incoming ray");
    let dir_r = add(d, scale(n, 2.0 * cos_i));
    let eta = eta1 / eta2;
    let k = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
    let dir_t = (k > 0.0).then(|| normalize(add(scale(d, eta), scale(n, eta * cos_i - k.sqrt()))));
    // s: perpendicular to the plane of incidence; any perpendicular at normal incidence.
    let c = cross(d, n);
    let s = if dot(c, c) > 1e-24 {
        normalize(c)
    } else {
        let a = if d[0].abs() < 0.9 {
            [1.0, 0.0, 0.0]
        } else {
            [0.0, 1.0, 0.0]
        };
        normalize(cross(d, a))
    };
    let p_of = |k: V3| cross(s, k);
    Split {
        dir_r: normalize(dir_r),
        dir_t,
        s,
        p_i: p_of(d),
        p_r: p_of(normalize(dir_r)),
        p_t: dir_t.map(p_of).unwrap_or([0.0; 3]),
    }
}

/// Applies the coefficients to a field: returns the reflected and transmitted fields.
pub fn split_field(e: &Field, g: &Split, c: &Coefficients) -> (Field, Field) {
    let es = field_dot_real(e, g.s);
    let ep = field_dot_real(e, g.p_i);
    let (rs, rp) = (es * c.r_s, ep * c.r_p);
    let (ts, tp) = (es * c.t_s, ep * c.t_p);
    let r = std::array::from_fn(|k| rs * g.s[k] + rp * g.p_r[k]);
    let t = std::array::from_fn(|k| ts * g.s[k] + tp * g.p_t[k]);
    (r, t)
}

/// Power carried by the transmitted wave (fraction of launched power), from the s and p
/// components of `e`: `|E_s t_s|^2 + |E_p t_p|^2` with power-normalised `t`.
pub fn transmitted_power(e: &Field, g: &Split, c: &Coefficients) -> f64 {
    let es = field_dot_real(e, g.s);
    let ep = field_dot_real(e, g.p_i);
    (es * c.t_s).norm_sqr() + (ep * c.t_p).norm_sqr()
}
