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
//! `exp(i k0 N . (b - a))` (DESIGN.md §3).
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
//! These are exact for plane waves whenever both waves share one real tangential index,
//! which holds through any stack of parallel interfaces at any angle. Where a wave inside an
//! absorbing medium meets a facet that is not parallel to the one it entered through, its
//! tangential index relative to the new facet is complex; the tracer keeps its real part
//! (the tangential component of the phase direction) and recomputes `q1` from the medium,
//! the usual approximation of ray optics in absorbing media (Chang et al. 2005, §3). The
//! attenuation up to the hit point is exact either way.
//!
//! **Power.** The power crossing an interface is the normal component of the time-averaged
//! Poynting vector (Byrnes eqs. 21-22): `T_s = |t_s|^2 Re(q2) / Re(q1)` and `T_p = |t_p|^2
//! Re(n2 conj(cos_2)) / Re(n1 conj(cos_1))`. The tracer carries power-normalised
//! amplitudes, `t` times the square root of that ratio. For a wave arriving from a lossless
//! medium `|r|^2 + T = 1` exactly, whether the second medium absorbs or not (the tracer
//! counts any event that breaks this). For a wave arriving from inside an absorbing medium
//! the incident and reflected waves' fluxes do not separate: the normal flux there is
//! `Re(q1) (1 - |r_s|^2) + 2 Im(q1) Im(r_s)` for s (Born & Wolf §14.2; Dupertuis, Proctor &
//! Acklin, JOSA A 11 (1994) 1159), so `|r|^2 + T` may exceed 1 at that single event. The
//! amplitudes are kept exact (a flat absorbing stack then sums to the transfer-matrix
//! result), and energy is checked where it is well defined: on the coherent totals of every
//! run (`simulate::check_physical`).

use super::C64;
use glam::DVec3;

/// Fresnel amplitude coefficients of one interface for one tangential index.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coefficients {
    pub r_s: C64,
    pub r_p: C64,
    /// Power-normalised transmission amplitudes (`t` times `sqrt(T / |t|^2)`).
    pub t_s: C64,
    pub t_p: C64,
    /// Complex normal indices `n cos(theta)` of the incident (`q1`) and transmitted (`q2`)
    /// waves, on the decaying / forward branch.
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

/// Coefficients for a wave of real tangential index `kappa` (`n1 sin(theta_i)` for a
/// homogeneous incident wave, `0 <= kappa`) going from index `n1` onto `n2`.
pub fn coefficients_kappa(n1: C64, n2: C64, kappa: f64) -> Coefficients {
    let kx = C64::new(kappa, 0.0);
    let q1 = n_cos(n1, kx);
    let q2 = n_cos(n2, kx);
    let (c1, c2) = (q1 / n1, q2 / n2);
    let r_s = (q1 - q2) / (q1 + q2);
    let r_p = (n2 * c1 - n1 * c2) / (n2 * c1 + n1 * c2);
    let t_s = 2.0 * q1 / (q1 + q2);
    let t_p = 2.0 * n1 * c1 / (n2 * c1 + n1 * c2);
    // Poynting ratios; zero under total internal reflection (Re(q2) = 0). A grazing wave
    // (Re(q1) = 0) carries no normal flux and transmits none.
    let ratio = |num: f64, den: f64| if den > 0.0 { (num / den).max(0.0) } else { 0.0 };
    let ratio_s = ratio(q2.re, q1.re);
    let ratio_p = ratio((n2 * c2.conj()).re, (n1 * c1.conj()).re);
    Coefficients {
        r_s,
        r_p,
        t_s: t_s * ratio_s.sqrt(),
        t_p: t_p * ratio_p.sqrt(),
        q1,
        q2,
    }
}

/// Coefficients for a homogeneous wave meeting the interface at real geometric `cos_i`
/// (`0 < cos_i <= 1`) from a lossless index `n1` onto `n2`: `kappa = n1 sin_i`.
pub fn coefficients(n1: C64, n2: C64, cos_i: f64) -> Coefficients {
    let sin_i = (1.0 - cos_i * cos_i).max(0.0).sqrt();
    coefficients_kappa(n1, n2, n1.re * sin_i)
}

/// Flux-normalises an event whose wave arrives from inside an absorbing medium through a
/// facet that is not parallel to the one it entered by. The exact plane-wave amplitudes
/// there can give `|r|^2 + T > 1` (the interference flux of the incident and reflected
/// waves, see the module docs), which only a coherent sum over the region's whole
/// reflection series cancels; a tilted facet sends those reflections elsewhere, so the
/// event must balance on its own. Where `|r|^2 + T > 1` for a polarisation, both of its
/// amplitudes are divided by `sqrt(|r|^2 + T)`: the event keeps its phases and its split
/// between reflection and transmission and conserves power; where the sum is below 1 the
/// rest is absorbed, as it is. Returns whether anything was scaled. For a thick absorbing
/// body (the geometric-optics regime) the rescaled waves are attenuated to nothing either
/// way; flat layers never take this path and stay exact.
pub fn flux_normalise(c: &mut Coefficients) -> bool {
    let [es, ep] = balance_excess(c);
    let mut scaled = false;
    // Excesses at rounding level (a lossless incidence) are left alone.
    if es > 1e-12 {
        let f = 1.0 / (1.0 + es).sqrt();
        c.r_s *= f;
        c.t_s *= f;
        scaled = true;
    }
    if ep > 1e-12 {
        let f = 1.0 / (1.0 + ep).sqrt();
        c.r_p *= f;
        c.t_p *= f;
        scaled = true;
    }
    scaled
}

/// `|r|^2 + T - 1` for each polarisation: zero (to rounding) for a wave arriving from a
/// lossless medium, the interference flux term for one arriving from an absorbing medium.
pub fn balance_excess(c: &Coefficients) -> [f64; 2] {
    [
        c.r_s.norm_sqr() + c.t_s.norm_sqr() - 1.0,
        c.r_p.norm_sqr() + c.t_p.norm_sqr() - 1.0,
    ]
}

/// A complex field vector (3 components in the sample frame).
pub type Field = [C64; 3];

#[inline]
pub fn field_dot_real(e: &Field, v: DVec3) -> C64 {
    e[0] * v.x + e[1] * v.y + e[2] * v.z
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
    pub dir_r: DVec3,
    /// Transmitted direction (unit), or `None` when no wave propagates into the second
    /// medium (total internal reflection into a lossless medium).
    pub dir_t: Option<DVec3>,
    /// Complex index vectors (real and imaginary parts) of the reflected and transmitted
    /// waves.
    pub n_r: (DVec3, DVec3),
    pub n_t: (DVec3, DVec3),
    pub s: DVec3,
    pub p_i: DVec3,
    pub p_r: DVec3,
    pub p_t: DVec3,
    /// The coefficients of this event.
    pub c: Coefficients,
    /// The real tangential index `kappa` the coefficients were computed for.
    pub kappa: f64,
}

/// The index vector `kappa + sign q m` (real and imaginary parts) of a wave with real
/// tangential index vector `kappa` and normal index `q` along `sign m`.
fn inhomogeneous(kt: DVec3, m: DVec3, q: C64, sign: f64) -> (DVec3, DVec3) {
    (kt + m * (sign * q.re), m * (sign * q.im))
}

/// Splits a wave of complex index vector `(n_re, n_im)` (real direction `d = n_re / |n_re|`)
/// at a surface of unit normal `nf` facing the incoming side (`d . nf < 0`), from index
/// `n1` onto `n2`: the conserved real tangential index `kappa` (the tangential part of
/// `n_re`), the normal indices and coefficients, the reflected and transmitted waves
/// `kappa - q1 m` and `kappa + q2 m` (`m = -nf`), and the s/p basis (`s = normalize(d x
/// nf)`, `p = s x k` for each wave).
pub fn split_wave(d: DVec3, n_re: DVec3, n_im: DVec3, nf: DVec3, n1: C64, n2: C64) -> Split {
    debug_assert!(d.dot(nf) <= 1e-9, "normal must face the incoming ray");
    let m = -nf;
    let homogeneous = n1.im == 0.0 && n_im == DVec3::ZERO;
    let (c, dir_r, n_r, dir_t, n_t, kappa);
    if homogeneous {
        // A homogeneous wave in a lossless medium: the mirror direction and, into a
        // lossless medium, Snell's law in closed form (bit-for-bit the geometry of
        // earlier versions, so lossless samples keep their results).
        let cos_i = (-d.dot(nf)).clamp(0.0, 1.0);
        let sin_i = (1.0 - cos_i * cos_i).max(0.0).sqrt();
        kappa = n1.re * sin_i;
        c = coefficients_kappa(n1, n2, kappa);
        dir_r = (d + nf * (2.0 * cos_i)).normalize();
        n_r = (dir_r * n1.re, DVec3::ZERO);
        if n2.im == 0.0 {
            let eta = n1.re / n2.re;
            let k = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
            dir_t = (k > 0.0).then(|| (d * eta + nf * (eta * cos_i - k.sqrt())).normalize());
            n_t = (dir_t.unwrap_or(DVec3::ZERO) * n2.re, DVec3::ZERO);
        } else {
            let kt = d - m * d.dot(m);
            let w = inhomogeneous(kt * n1.re, m, c.q2, 1.0);
            dir_t = Some(w.0.normalize());
            n_t = w;
        }
    } else {
        let kt = n_re - m * n_re.dot(m);
        kappa = kt.length();
        c = coefficients_kappa(n1, n2, kappa);
        n_r = inhomogeneous(kt, m, c.q1, -1.0);
        dir_r = n_r.0.normalize();
        n_t = inhomogeneous(kt, m, c.q2, 1.0);
        dir_t = (c.q2.re > 0.0).then(|| n_t.0.normalize());
    }
    // s: perpendicular to the plane of incidence; any perpendicular at normal incidence.
    let cr = d.cross(nf);
    let s = if cr.dot(cr) > 1e-24 {
        cr.normalize()
    } else {
        let a = if d.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
        d.cross(a).normalize()
    };
    let p_of = |k: DVec3| s.cross(k);
    Split {
        dir_r,
        dir_t,
        n_r,
        n_t,
        s,
        p_i: p_of(d),
        p_r: p_of(dir_r),
        p_t: dir_t.map(p_of).unwrap_or(DVec3::ZERO),
        c,
        kappa,
    }
}

/// The coefficients of a coated interface: the stack's amplitude coefficients `[(r_s,
/// t_s), (r_p, t_p)]` (from `tmm::amplitudes`, same convention as the bare interface) with
/// the transmission power-normalised between the outer media exactly as for a bare
/// interface (`c` holds the outer media's normal indices). Layers between the outer media
/// change the amplitudes, never the directions (Snell's invariant is conserved through a
/// flat stack).
pub fn coated(c: &Coefficients, n1: C64, n2: C64, amp: [(C64, C64); 2]) -> Coefficients {
    let bare = coefficients_from(n1, n2, c.q1, c.q2, amp);
    Coefficients {
        q1: c.q1,
        q2: c.q2,
        ..bare
    }
}

fn coefficients_from(n1: C64, n2: C64, q1: C64, q2: C64, amp: [(C64, C64); 2]) -> Coefficients {
    let (c1, c2) = (q1 / n1, q2 / n2);
    let ratio = |num: f64, den: f64| if den > 0.0 { (num / den).max(0.0) } else { 0.0 };
    let ratio_s = ratio(q2.re, q1.re);
    let ratio_p = ratio((n2 * c2.conj()).re, (n1 * c1.conj()).re);
    Coefficients {
        r_s: amp[0].0,
        r_p: amp[1].0,
        t_s: amp[0].1 * ratio_s.sqrt(),
        t_p: amp[1].1 * ratio_p.sqrt(),
        q1,
        q2,
    }
}

/// Applies the coefficients to a field: returns the reflected and transmitted fields.
pub fn split_field(e: &Field, g: &Split) -> (Field, Field) {
    let c = &g.c;
    let es = field_dot_real(e, g.s);
    let ep = field_dot_real(e, g.p_i);
    let (rs, rp) = (es * c.r_s, ep * c.r_p);
    let (ts, tp) = (es * c.t_s, ep * c.t_p);
    let r = std::array::from_fn(|k| rs * g.s[k] + rp * g.p_r[k]);
    let t = std::array::from_fn(|k| ts * g.s[k] + tp * g.p_t[k]);
    (r, t)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn indices() -> Vec<C64> {
        vec![
            C64::new(1.0, 0.0),
            C64::new(1.5, 0.0),
            C64::new(2.4, 0.0),
            C64::new(0.43, 2.455),
            C64::new(1.38, 1.92),
            C64::new(0.166, 3.15),
            C64::new(2.0, 0.3),
        ]
    }

    /// From a lossless medium, |r|^2 + T = 1 for both polarisations at every tangential
    /// index, onto lossless and absorbing media alike, total internal reflection included.
    #[test]
    fn power_balances_from_a_lossless_medium() {
        for n1 in [1.0, 1.33, 1.52, 2.4] {
            for &n2 in &indices() {
                for i in 0..=200 {
                    let kappa = n1 * i as f64 / 200.0 * 0.999_999;
                    let c = coefficients_kappa(C64::new(n1, 0.0), n2, kappa);
                    let [es, ep] = balance_excess(&c);
                    assert!(
                        es.abs() < 1e-12 && ep.abs() < 1e-12,
                        "{n1} -> {n2} at kappa {kappa}: {es:e} {ep:e}"
                    );
                }
            }
        }
    }

    /// From an absorbing medium the s flux is continuous across the interface: the net
    /// normal flux of incident plus reflected wave, `Re(q1) (1 - |r|^2) + 2 Im(q1) Im(r)`,
    /// equals the transmitted one, `Re(q2) |t|^2` (Born & Wolf §14.2; derived from
    /// `S_z ~ Re(E conj(H))` with `E = e^{i q z} + r e^{-i q z}`).
    #[test]
    fn s_flux_is_continuous_from_an_absorbing_medium() {
        for &n1 in &indices()[3..] {
            for n2 in [C64::new(1.0, 0.0), C64::new(1.5, 0.0), C64::new(2.0, 0.3)] {
                for i in 0..=50 {
                    let kappa = 1.2 * i as f64 / 50.0;
                    let c = coefficients_kappa(n1, n2, kappa);
                    let net = c.q1.re * (1.0 - c.r_s.norm_sqr()) + 2.0 * c.q1.im * c.r_s.im;
                    // c.t_s is power-normalised: |t_s|^2 = |t|^2 Re(q2) / Re(q1).
                    let trans = c.t_s.norm_sqr() * c.q1.re;
                    assert!(
                        (net - trans).abs() < 1e-12 * (1.0 + net.abs()),
                        "{n1} -> {n2} at {kappa}: {net} vs {trans}"
                    );
                }
            }
        }
    }

    /// Gold to air at normal incidence: |r|^2 + T > 1 (the interference flux); flux
    /// normalisation restores the balance and keeps the phases and the R : T split.
    #[test]
    fn flux_normalisation_balances_and_keeps_phases() {
        let gold = C64::new(0.166, 3.15);
        let mut c = coefficients_kappa(gold, C64::new(1.0, 0.0), 0.0);
        let before = c;
        let [es, _] = balance_excess(&c);
        assert!(
            es > 1.0,
            "expected a large excess from inside gold, got {es}"
        );
        assert!(flux_normalise(&mut c));
        let [es, ep] = balance_excess(&c);
        assert!(es.abs() < 1e-12 && ep.abs() < 1e-12);
        assert!((c.r_s.arg() - before.r_s.arg()).abs() < 1e-12);
        let ratio = |c: &Coefficients| c.r_s.norm_sqr() / c.t_s.norm_sqr();
        assert!((ratio(&c) / ratio(&before) - 1.0).abs() < 1e-12);
        // Nothing to do from a lossless medium.
        let mut air = coefficients_kappa(C64::new(1.0, 0.0), gold, 0.3);
        assert!(!flux_normalise(&mut air));
    }

    /// Reflection keeps the tangential index and mirrors the normal one; transmission into
    /// an absorbing medium beyond sin(theta) = Re(n) still propagates (no false TIR).
    #[test]
    fn split_wave_geometry() {
        let d = DVec3::new(0.8, 0.0, -0.6).normalize();
        let nf = DVec3::Z;
        let g = split_wave(
            d,
            d,
            DVec3::ZERO,
            nf,
            C64::new(1.0, 0.0),
            C64::new(0.43, 2.455),
        );
        assert!((g.dir_r[0] - 0.8).abs() < 1e-12 && (g.dir_r[2] - 0.6).abs() < 1e-12);
        let dt = g
            .dir_t
            .expect("transmission into gold at sin 0.8 > Re n = 0.43");
        assert!(dt[2] < 0.0);
        // The transmitted wave decays along -z and keeps the tangential index 0.8.
        assert!((g.n_t.0[0] - 0.8).abs() < 1e-12 && g.n_t.1[2] < 0.0);
        // Into glass beyond the critical angle from inside: no transmitted wave.
        let d = DVec3::new(0.9, 0.0, 0.436).normalize();
        let g = split_wave(
            d,
            d * 1.5,
            DVec3::ZERO,
            DVec3::NEG_Z,
            C64::new(1.5, 0.0),
            C64::new(1.0, 0.0),
        );
        assert!(g.dir_t.is_none());
        assert!((g.c.r_s.norm() - 1.0).abs() < 1e-12);
    }
}
