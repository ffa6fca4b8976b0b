//! Complex Fresnel amplitude coefficients and the split of a ray's electric field and wave
//! vector at an interface into a reflected and a transmitted wave.
//!
//! **Waves.** A ray carries the complex index vector `N = N' + i N''` of its plane wave
//! (the wave vector in units of `k0 = 2 pi / lambda`, `N . N = n^2` with the
//! non-Hermitian dot). In a lossless medium the wave is homogeneous, `N = n d`. A wave that
//! enters an absorbing medium through an interface of unit normal `m` is inhomogeneous:
//! `N = kappa + q m`, with the tangential part `kappa` real and conserved (Snell) and the
//! normal part `q = sqrt(n^2 - kappa^2)` complex, on the root that decays along `m`
//! (Born & Wolf, Principles of Optics, 7th ed., §14.2; Chang, Walker & Hopcraft, "Ray
//! tracing in absorbing media", JQSRT 96 (2005) 327, eqs. 4-9). Its planes of constant
//! amplitude are parallel to the interface it entered through. The geometric ray follows
//! `N'` (the direction of constant phase); phase and attenuation from `a` to `b` are
//! `exp(i k0 N . (b - a))` (docs/design.md §3).
//!
//! **Coefficients.** With the conserved tangential index `kappa` and the normal indices
//! `q1`, `q2` on either side (`cos_j = q_j / n_j`), the amplitude coefficients are
//! (Born & Wolf §1.5.2 eqs. 20-21 with complex indices as in §14.2; Byrnes, "Multilayer
//! optical calculations", arXiv:1603.02720, eqs. 1-4):
//!
//! ```text
//! r_s = (q1 - q2) / (q1 + q2)                                   t_s = 2 q1 / (q1 + q2)
//! r_p = (n2 cos_1 - n1 cos_2) / (n2 cos_1 + n1 cos_2)           t_p = 2 n1 cos_1 / (n2 cos_1 + n1 cos_2)
//! ```
//!
//! They follow from the continuity of the tangential fields alone, so they hold for any
//! complex tangential index: [`split_wave`] takes the incident wave's exact normal index
//! `q1 = N . m` and its complex tangential index vector `K`, which is what a wave inside an
//! absorbing medium has at a facet not parallel to the one it entered through (Dupertuis,
//! Proctor & Acklin, JOSA A 11 (1994) 1159). The tests check the event against the boundary
//! conditions solved by brute force.
//!
//! **Carried amplitudes.** The tracer carries `E sqrt(F Re(q))`, `F` the ray tube's footprint
//! on the facet, for both polarisations: transmission amplitudes are `t sqrt(Re(q2) /
//! Re(q1))`. In a lossless medium `Re(q)` is the normal Poynting factor of s and p alike, so
//! `|E|^2` is the fraction of launched power (Byrnes eqs. 21-22). Inside an absorber the p
//! wave's Poynting factor is `Re(conj(n) q / n)`; the tube factor is kept there because it
//! cancels exactly along any path between lossless media, whatever the facets' tilts.
//!
//! **Power.** The normal Poynting flux of the incident and reflected waves together is
//! `Re(Y1) (1 - |r|^2) + 2 Im(Y1) Im(r)` (`Y = q` for s, `conj(n) q / n` for p; Born & Wolf
//! §14.2), and equals the transmitted flux ([`normal_fluxes`]). For a homogeneous wave from a
//! lossless medium `Im(Y1) = 0` and `|r|^2 + T = 1` exactly (the tracer counts any event that
//! breaks this). From inside an absorbing medium the interference term makes `|r|^2 + T`
//! exceed 1 at a single event; the coherent sum of the region's whole reflection series
//! cancels it (a flat absorbing stack sums to the transfer-matrix result), and where the
//! series cannot recombine the tracer limits the event's energy by a weight continuous in the
//! facet's tilt ([`limit_excess`], docs/physics.md "Energy at interfaces").

use super::C64;
use glam::DVec3;

/// Fresnel amplitude coefficients of one interface for one tangential index.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coefficients {
    pub r_s: C64,
    pub r_p: C64,
    /// Transmission amplitudes scaled for the tracer's carried amplitude: `t` times
    /// `sqrt(Re(q2) / Re(q1))` (see the module docs, "Carried amplitudes").
    pub t_s: C64,
    pub t_p: C64,
    /// Complex normal indices `n cos(theta)` of the incident (`q1`) and transmitted (`q2`)
    /// waves.
    pub q1: C64,
    pub q2: C64,
}

/// The complex normal index `n cos(theta) = sqrt(n^2 - kappa^2)` of a wave in a medium of
/// index `n` whose tangential index is `kappa`, on the branch that decays, or for a
/// lossless medium propagates, along the interface normal (Byrnes §2, "is_forward_angle").
pub fn n_cos(n: C64, kappa: C64) -> C64 {
    let v = (n * n - kappa * kappa).sqrt();
    let forward = if v.im.abs() > 1e-12 * v.norm().max(1e-300) {
        v.im > 0.0
    } else {
        v.re > 0.0
    };
    if forward { v } else { -v }
}

/// The normal index `q2` of the wave transmitted into a medium of index `n` by a wave
/// whose tangential index vector `K` has `K . K = kk` (complex in general). The two roots
/// of `q^2 = n^2 - kk` are told apart as the physics does: where `Re(q^2) >= 0` the wave
/// carries power away from the interface (`Re q > 0`), where `Re(q^2) < 0` it is
/// evanescent-like and decays away from it (`Im q > 0`). For a real `kk` this is
/// [`n_cos`]'s choice; for a complex one the two rules meet only at a grazing transmitted
/// wave, `Re(q^2) = 0` with `Im(q^2) < 0`, where the transmitted power is of order
/// `sqrt(|Im kk|)` and the branch point of the square root makes a jump unavoidable
/// (Dupertuis, Proctor & Acklin, JOSA A 11 (1994) 1159, §2 discuss the choice).
pub fn transmitted_root(n: C64, kk: C64) -> C64 {
    let w = n * n - kk;
    let v = w.sqrt(); // principal: Re v >= 0
    if w.re < 0.0 && v.im < 0.0 { -v } else { v }
}

/// The carried-amplitude ratio `sqrt(Re(q2) / Re(q1))`, zero where either wave carries no
/// normal flux (total internal reflection, a grazing or backward wave).
fn tube_ratio(q1: C64, q2: C64) -> f64 {
    if q1.re > 0.0 && q2.re > 0.0 {
        (q2.re / q1.re).sqrt()
    } else {
        0.0
    }
}

/// Coefficients of an interface from `n1` onto `n2` for a wave of normal index `q1`
/// (incident) and `q2` (transmitted): the Fresnel amplitudes in the module's convention
/// (Born & Wolf §1.5.2 eqs. 20-21; Byrnes eqs. 1-4), exact for any complex tangential
/// index, since they follow from the continuity of the tangential fields alone.
pub fn coefficients_q(n1: C64, n2: C64, q1: C64, q2: C64) -> Coefficients {
    let (c1, c2) = (q1 / n1, q2 / n2);
    let r_s = (q1 - q2) / (q1 + q2);
    let r_p = (n2 * c1 - n1 * c2) / (n2 * c1 + n1 * c2);
    let t_s = 2.0 * q1 / (q1 + q2);
    let t_p = 2.0 * n1 * c1 / (n2 * c1 + n1 * c2);
    let f = tube_ratio(q1, q2);
    Coefficients {
        r_s,
        r_p,
        t_s: t_s * f,
        t_p: t_p * f,
        q1,
        q2,
    }
}

/// Coefficients for a wave of real tangential index `kappa` (`n1 sin(theta_i)` for a
/// homogeneous incident wave, `0 <= kappa`) going from index `n1` onto `n2`.
pub fn coefficients_kappa(n1: C64, n2: C64, kappa: f64) -> Coefficients {
    let kx = C64::new(kappa, 0.0);
    coefficients_q(n1, n2, n_cos(n1, kx), n_cos(n2, kx))
}

/// Coefficients for a homogeneous wave meeting the interface at real geometric `cos_i`
/// (`0 < cos_i <= 1`) from a lossless index `n1` onto `n2`: `kappa = n1 sin_i`.
pub fn coefficients(n1: C64, n2: C64, cos_i: f64) -> Coefficients {
    let sin_i = (1.0 - cos_i * cos_i).max(0.0).sqrt();
    coefficients_kappa(n1, n2, n1.re * sin_i)
}

/// The un-scaled transmission amplitudes `[t_s, t_p]` (E-field ratios) of `c`.
fn raw_t(c: &Coefficients) -> [C64; 2] {
    let f = tube_ratio(c.q1, c.q2);
    if f > 0.0 {
        [c.t_s / f, c.t_p / f]
    } else {
        [C64::ZERO; 2]
    }
}

/// The normal time-averaged Poynting flux on either side of the interface, for each
/// polarisation, per unit incident amplitude: `[[incident + reflected, transmitted]; 2]`.
/// With the admittance `Y = q` for s and `Y = conj(n) q / n` for p, the net flux of the
/// incident and reflected waves is `Re(Y1) (1 - |r|^2) + 2 Im(Y1) Im(r)` and the
/// transmitted one `Re(Y2) |t|^2` (Born & Wolf §14.2; derived from `S . m = Re(E_t x
/// conj(H_t)) . m / 2` with the tangential fields of the s and p waves, where the common
/// factor `|s|^2` of a complex s vector cancels). The two are equal for every tangential
/// index, which is the energy check of an event; they also show why `|r|^2 + T` may exceed
/// 1 where the wave arrives from an absorbing medium (`Im Y1 != 0`).
pub fn normal_fluxes(c: &Coefficients, n1: C64, n2: C64) -> [[f64; 2]; 2] {
    let [ts, tp] = raw_t(c);
    let y = |n: C64, q: C64| n.conj() * q / n;
    let (y1, y2) = (y(n1, c.q1), y(n2, c.q2));
    let side = |y1: C64, r: C64| y1.re * (1.0 - r.norm_sqr()) + 2.0 * y1.im * r.im;
    let through = if tube_ratio(c.q1, c.q2) > 0.0 {
        [c.q2.re * ts.norm_sqr(), y2.re * tp.norm_sqr()]
    } else {
        [0.0; 2]
    };
    [
        [side(c.q1, c.r_s), through[0]],
        [side(y1, c.r_p), through[1]],
    ]
}

/// `|r|^2 + T - 1` for each polarisation of a wave arriving from a lossless medium, `T`
/// the normal Poynting flux transmitted ([`normal_fluxes`]): zero to rounding for a
/// homogeneous wave, whatever the second medium; the tracer counts any event that breaks
/// it as a fault.
pub fn balance_excess(c: &Coefficients, n1: C64, n2: C64) -> [f64; 2] {
    let f = normal_fluxes(c, n1, n2);
    let y1 = [c.q1.re, (n1.conj() * c.q1 / n1).re];
    std::array::from_fn(|k| {
        let r = if k == 0 { c.r_s } else { c.r_p };
        if y1[k] > 0.0 {
            r.norm_sqr() + f[k][1] / y1[k] - 1.0
        } else {
            r.norm_sqr() - 1.0
        }
    })
}

/// A complex field vector (3 components in the sample frame).
pub type Field = [C64; 3];

#[inline]
pub fn field_dot_real(e: &Field, v: DVec3) -> C64 {
    e[0] * v.x + e[1] * v.y + e[2] * v.z
}

/// Bilinear product `a . b` of two complex vectors (no conjugate).
#[inline]
pub fn bilinear(a: &Field, b: &Field) -> C64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
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

/// The field `e` of an inhomogeneous plane wave `N = n_re + i n_im` in a lossless medium of
/// index `n` (`N . N = n^2`, so `n_re . n_im = 0`; `e . N = 0`), rewritten on a real
/// basis so that `|e|^2` is its normal flux, as for a homogeneous wave.
///
/// Its TE part lies along the real `u = n_re x n_im / |n_re x n_im|`, its TM part along
/// `p = u x N / n` (bilinear norm 1, and `e = (e . u) u + (e . p) p`). With `H = N x E`
/// (Maxwell's curl equation for a plane wave, in units of the vacuum admittance), each part
/// of amplitude `a` carries the normal flux `|a|^2 Re(q)`, `q = N . z` (TM: `E x conj(H) =
/// |a|^2 N` since `(u x N) x u = N`), whereas `|p|^2 = (|n_re|^2 + |n_im|^2) / n^2`, above 1:
/// on the complex vector the TM part's `|e|^2` overstates its power by that factor (Born &
/// Wolf §1.4.3 for the Poynting vector; §14.2 for inhomogeneous waves). The rewritten field
/// is `(e . u) u + (e . p) (u x n_re / |n_re|)`; the estimator's pair products of such
/// fields take TM pairs like TE ones. Homogeneous waves are returned as they are.
pub fn on_power_basis(e: &Field, n_re: DVec3, n_im: DVec3, n: f64) -> Field {
    let u = n_re.cross(n_im);
    if u.length_squared() == 0.0 {
        return *e;
    }
    let u = u.normalize();
    let p = scale(
        &cross(&real(u), &complex(n_re, n_im)),
        C64::new(1.0 / n, 0.0),
    );
    let (a_s, a_p) = (field_dot_real(e, u), bilinear(e, &p));
    let p_real = u.cross(n_re.normalize());
    std::array::from_fn(|k| a_s * u[k] + a_p * p_real[k])
}

fn complex(re: DVec3, im: DVec3) -> Field {
    [
        C64::new(re.x, im.x),
        C64::new(re.y, im.y),
        C64::new(re.z, im.z),
    ]
}

fn real(v: DVec3) -> Field {
    complex(v, DVec3::ZERO)
}

fn cross(a: &Field, b: &Field) -> Field {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn scale(a: &Field, s: C64) -> Field {
    a.map(|x| x * s)
}

fn parts(a: &Field) -> (DVec3, DVec3) {
    (
        DVec3::new(a[0].re, a[1].re, a[2].re),
        DVec3::new(a[0].im, a[1].im, a[2].im),
    )
}

/// The s/p basis of an event: `s` perpendicular to the plane of incidence, and `p = s x N
/// / n` of the incident, reflected and transmitted waves. Real for a homogeneous wave
/// between lossless media (the common case, kept in real arithmetic); complex vectors,
/// orthonormal under the bilinear product, where a wave is inhomogeneous.
#[derive(Clone, Copy, Debug)]
pub enum Basis {
    Real {
        s: DVec3,
        p_i: DVec3,
        p_r: DVec3,
        p_t: DVec3,
    },
    Complex {
        s: Field,
        p_i: Field,
        p_r: Field,
        p_t: Field,
    },
}

/// Geometry and fields of one interface event.
#[derive(Clone, Copy, Debug)]
pub struct Split {
    /// Reflected direction (unit).
    pub dir_r: DVec3,
    /// Transmitted direction (unit), or `None` when no wave carries power into the second
    /// medium (total internal reflection).
    pub dir_t: Option<DVec3>,
    /// Complex index vectors (real and imaginary parts) of the reflected and transmitted
    /// waves.
    pub n_r: (DVec3, DVec3),
    pub n_t: (DVec3, DVec3),
    pub basis: Basis,
    /// The coefficients of this event.
    pub c: Coefficients,
    /// The tangential index `sqrt(K . K)` the coefficients were computed for (real for a
    /// wave that entered through a parallel facet; a coating's transfer matrix takes it).
    pub kappa: C64,
    /// `|Im K|`: how fast the incident wave's amplitude changes along the facet (zero where
    /// its planes of constant amplitude are parallel to the facet).
    pub k_im: f64,
}

/// Splits a wave of complex index vector `N = n_re + i n_im` (real direction `d = n_re /
/// |n_re|`) at a surface of unit normal `nf` facing the incoming side (`d . nf < 0`), from
/// index `n1` onto `n2`.
///
/// With `m = -nf`, the incident wave's normal index is `q1 = N . m` and its tangential
/// index vector `K = N - q1 m`, complex in general: inside an absorbing medium at a facet
/// not parallel to the one the wave entered through, the planes of constant amplitude are
/// tilted against the facet and `K` has an imaginary part. `K` is conserved (the phase
/// matching of the boundary conditions); the reflected wave is `K - q1 m`, the transmitted
/// one `K + q2 m` with `q2 = sqrt(n2^2 - K . K)` ([`transmitted_root`]), and the Fresnel
/// coefficients take `q1` and `q2` as they are (Dupertuis, Proctor & Acklin, JOSA A 11
/// (1994) 1159, eqs. 8-14; Chang, Walker & Hopcraft, JQSRT 96 (2005) 327, §2). The s vector
/// is `K x m / sqrt(K . K)` and `p = s x N / n` for each wave: complex vectors, orthonormal
/// under the bilinear product, which reduce to the usual real ones when `K` is real. No
/// threshold separates the cases: the event is continuous in the facet's tilt and equals
/// the parallel-facet event when the tilt is zero.
pub fn split_wave(d: DVec3, n_re: DVec3, n_im: DVec3, nf: DVec3, n1: C64, n2: C64) -> Split {
    debug_assert!(d.dot(nf) <= 1e-9, "normal must face the incoming ray");
    let m = -nf;
    // s: perpendicular to the plane of incidence; any perpendicular at normal incidence.
    let real_s = || {
        let cr = d.cross(nf);
        if cr.dot(cr) > 1e-24 {
            cr.normalize()
        } else {
            let a = if d.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
            d.cross(a).normalize()
        }
    };
    if n1.im == 0.0 && n2.im == 0.0 && n_im == DVec3::ZERO {
        // A homogeneous wave between lossless media: the mirror direction and Snell's law
        // in closed form (bit-for-bit the geometry of earlier versions, so lossless
        // samples keep their results).
        let cos_i = (-d.dot(nf)).clamp(0.0, 1.0);
        let sin_i = (1.0 - cos_i * cos_i).max(0.0).sqrt();
        let kappa = n1.re * sin_i;
        let c = coefficients_kappa(n1, n2, kappa);
        let dir_r = (d + nf * (2.0 * cos_i)).normalize();
        let eta = n1.re / n2.re;
        let k = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
        let dir_t = (k > 0.0).then(|| (d * eta + nf * (eta * cos_i - k.sqrt())).normalize());
        let s = real_s();
        return Split {
            dir_r,
            dir_t,
            n_r: (dir_r * n1.re, DVec3::ZERO),
            n_t: (dir_t.unwrap_or(DVec3::ZERO) * n2.re, DVec3::ZERO),
            basis: Basis::Real {
                s,
                p_i: s.cross(d),
                p_r: s.cross(dir_r),
                p_t: dir_t.map(|t| s.cross(t)).unwrap_or(DVec3::ZERO),
            },
            c,
            kappa: C64::new(kappa, 0.0),
            k_im: 0.0,
        };
    }
    let n_in = complex(n_re, n_im);
    let mc = real(m);
    let q1 = bilinear(&n_in, &mc);
    let kt: Field = std::array::from_fn(|i| n_in[i] - q1 * m[i]);
    let kk = bilinear(&kt, &kt);
    let q2 = transmitted_root(n2, kk);
    let c = coefficients_q(n1, n2, q1, q2);
    let wave = |q: C64| -> Field { std::array::from_fn(|i| kt[i] + q * m[i]) };
    let (w_r, w_t) = (wave(-q1), wave(q2));
    let n_r = parts(&w_r);
    let n_t = parts(&w_t);
    let dir_r = n_r.0.normalize();
    let dir_t = (tube_ratio(q1, q2) > 0.0).then(|| n_t.0.normalize());
    // The s vector K x m / sqrt(K . K); at normal incidence (K = 0, or K . K vanishing
    // against |K|^2) any real perpendicular serves, as for a homogeneous wave.
    let k2 = kt.iter().map(|x| x.norm_sqr()).sum::<f64>();
    let s: Field = if kk.norm() > 1e-20 * k2.max(1e-300) && k2 > 1e-30 {
        scale(&cross(&kt, &mc), C64::ONE / kk.sqrt())
    } else {
        real(real_s())
    };
    let p_of = |w: &Field, n: C64| scale(&cross(&s, w), C64::ONE / n);
    Split {
        dir_r,
        dir_t,
        n_r,
        n_t,
        basis: Basis::Complex {
            s,
            p_i: p_of(&n_in, n1),
            p_r: p_of(&w_r, n1),
            p_t: if dir_t.is_some() {
                p_of(&w_t, n2)
            } else {
                [C64::ZERO; 3]
            },
        },
        c,
        kappa: kk.sqrt(),
        k_im: parts(&kt).1.length(),
    }
}

/// Whether `|r|^2 + |t|^2` exceeds 1 in either polarisation: the event [`limit_excess`]
/// would scale at a weight below 1.
pub fn exceeds_unity(c: &Coefficients) -> bool {
    power_sums(c).iter().any(|&sum| sum > 1.0)
}

/// `|r|^2 + |t|^2` of each polarisation, `[s, p]`.
fn power_sums(c: &Coefficients) -> [f64; 2] {
    [
        c.r_s.norm_sqr() + c.t_s.norm_sqr(),
        c.r_p.norm_sqr() + c.t_p.norm_sqr(),
    ]
}

/// Limits the energy of an event whose incident wave is inhomogeneous along the facet
/// (`k_im > 0`) by the weight `w` in [0, 1] that its partial waves recombine: where
/// `|r|^2 + T` of a polarisation exceeds 1 (the interference flux of the incident and
/// reflected waves, see the module docs), both of its amplitudes are multiplied by `w +
/// (1 - w) / sqrt(|r|^2 + T)`. `w = 1` keeps the exact plane-wave amplitudes (a film's
/// series then recombines into the exact field); `w = 0` makes the event conserve power on
/// its own, keeping its phases and its split between reflection and transmission. The
/// scaling is continuous in `w`, and the tracer's `w` is continuous in the facet's tilt
/// (`trace::recombination_weight`). Returns whether anything was scaled.
pub fn limit_excess(c: &mut Coefficients, w: f64) -> bool {
    let excess = power_sums(c);
    let mut scaled = false;
    for (k, sum) in excess.into_iter().enumerate() {
        if sum > 1.0 && w < 1.0 {
            let f = w + (1.0 - w) / sum.sqrt();
            if k == 0 {
                c.r_s *= f;
                c.t_s *= f;
            } else {
                c.r_p *= f;
                c.t_p *= f;
            }
            scaled = true;
        }
    }
    scaled
}

/// Limits the children of an energy-limited event (`w < 1`, as in [`limit_excess`]) on
/// their fields: where the reflected and transmitted fields `r`, `t` of the incident field
/// `e` hold more `|E|^2` together than `e`, both are multiplied by `w + (1 - w) sqrt(|e|^2 /
/// (|r|^2 + |t|^2))`. Returns whether anything was scaled.
///
/// [`limit_excess`] bounds the coefficients, `|r|^2 + |t|^2 <= 1`, but an inhomogeneous
/// wave's s and p vectors are unit under the bilinear product only: their Hermitian norms
/// `|s|^2 = |K|^2 / |K . K|` and `|p|^2 = (|N'|^2 + |N''|^2) / |N . N|` grow without bound as
/// the wave becomes evanescent, so a field taken apart on the incident wave's basis and
/// rebuilt on the children's can come out several times stronger with bounded
/// coefficients. An evanescent wave that left an aluminium flake's edge into a paint's
/// binder gained a factor 2 to 15 at each such event; walked through tens of events between
/// the flakes and a clear coat it carried 10^8 of the launched power out (R = 144,763 at 60
/// degrees, issue 46). With the fields bounded at every energy-limited event, no chain of
/// them can carry out more `|E|^2` than entered it (the exits' power basis,
/// [`on_power_basis`], only lowers it). Exact events (`w = 1`) are left alone: inside an
/// absorber `|E|^2` is not the flux, and a film's series needs its exact amplitudes.
pub fn limit_field_excess(e: &Field, r: &mut Field, t: &mut Field, w: f64) -> bool {
    let (p_in, p_out) = (field_power(e), field_power(r) + field_power(t));
    if !(w < 1.0 && p_out > p_in && p_out > 0.0) {
        return false;
    }
    let f = w + (1.0 - w) * (p_in / p_out).sqrt();
    for c in r.iter_mut().chain(t.iter_mut()) {
        *c *= f;
    }
    true
}

/// The coefficients of a coated interface: the stack's amplitude coefficients `[(r_s,
/// t_s), (r_p, t_p)]` (from `tmm::amplitudes`, same convention as the bare interface) with
/// the transmission scaled between the outer media exactly as for a bare interface (`c`
/// holds the outer media's normal indices). Layers between the outer media change the
/// amplitudes, never the directions (Snell's invariant is conserved through a flat stack).
pub fn coated(c: &Coefficients, amp: [(C64, C64); 2]) -> Coefficients {
    let f = tube_ratio(c.q1, c.q2);
    Coefficients {
        r_s: amp[0].0,
        r_p: amp[1].0,
        t_s: amp[0].1 * f,
        t_p: amp[1].1 * f,
        q1: c.q1,
        q2: c.q2,
    }
}

/// Applies the coefficients to a field: returns the reflected and transmitted fields.
pub fn split_field(e: &Field, g: &Split) -> (Field, Field) {
    let c = &g.c;
    match &g.basis {
        Basis::Real { s, p_i, p_r, p_t } => {
            let es = field_dot_real(e, *s);
            let ep = field_dot_real(e, *p_i);
            let (rs, rp) = (es * c.r_s, ep * c.r_p);
            let (ts, tp) = (es * c.t_s, ep * c.t_p);
            let r = std::array::from_fn(|k| rs * s[k] + rp * p_r[k]);
            let t = std::array::from_fn(|k| ts * s[k] + tp * p_t[k]);
            (r, t)
        }
        Basis::Complex { s, p_i, p_r, p_t } => {
            // Components by the bilinear product: {s, p, N / n} is orthonormal under it.
            let es = bilinear(e, s);
            let ep = bilinear(e, p_i);
            let (rs, rp) = (es * c.r_s, ep * c.r_p);
            let (ts, tp) = (es * c.t_s, ep * c.t_p);
            let r = std::array::from_fn(|k| rs * s[k] + rp * p_r[k]);
            let t = std::array::from_fn(|k| ts * s[k] + tp * p_t[k]);
            (r, t)
        }
    }
}

#[cfg(test)]
mod tests;
