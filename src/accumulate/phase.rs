//! Sine and cosine of a batch of phases (radians), and the exponential of a batch of
//! non-positive arguments, for the estimator's pair loop: one branch-free loop over the
//! batch, which the compiler keeps in vector registers, instead of one C library call per
//! value.
//!
//! The method is the classical one (Cody & Waite, *Software Manual for the Elementary
//! Functions*, 1980, ch. 8): reduce `x = n pi/2 + r` with `|r| <= pi/4`, `pi/2` split into
//! three parts so that `n pi/2` is exact to far below the rounding of `r`, evaluate the
//! Taylor series of `sin r` and `cos r` (truncated where the next term is below 5e-17 on
//! `|r| <= pi/4`), and rotate by the quadrant `n mod 4`. The error is a few units in the
//! last place for `|x| <= MAX_PHASE` (tested against the C library below); larger phases
//! go to the C library.

/// `pi/2 = PIO2_1 + PIO2_2 + PIO2_3`: the first two carry 30 significant bits, so `n
/// PIO2_1` and `n PIO2_2` are exact for `|n| < 2^23`; the third is the rest, rounded.
const PIO2_1: f64 = 1.570_796_325_802_803;
const PIO2_2: f64 = 9.920_935_791_635_221e-10;
const PIO2_3: f64 = 5.170_182_981_794_105e-19;
/// `1.5 * 2^52`: adding it rounds to the nearest integer and leaves the integer in the
/// low bits of the mantissa.
const ROUND: f64 = 6_755_399_441_055_744.0;
/// Phases up to this magnitude (rad) are reduced exactly enough (`|n| < 2^22`).
pub const MAX_PHASE: f64 = 6.0e6;

/// Taylor coefficients `(-1)^k / (2k+1)!` of `sin r / r` and `(-1)^k / (2k)!` of `cos r`,
/// in powers of `z = r^2`.
const S: [f64; 7] = [
    -1.0 / 6.0,
    1.0 / 120.0,
    -1.0 / 5040.0,
    1.0 / 362_880.0,
    -1.0 / 39_916_800.0,
    1.0 / 6_227_020_800.0,
    -1.0 / 1_307_674_368_000.0,
];
const C: [f64; 8] = [
    -1.0 / 2.0,
    1.0 / 24.0,
    -1.0 / 720.0,
    1.0 / 40_320.0,
    -1.0 / 3_628_800.0,
    1.0 / 479_001_600.0,
    -1.0 / 87_178_291_200.0,
    1.0 / 20_922_789_888_000.0,
];

/// `sin x` and `cos x` for every `x` of `phase`, into `sin` and `cos` (resized); AVX2
/// where the CPU has it, with the same bits (`machine::with_avx2`).
pub fn sin_cos_batch(phase: &[f64], sin: &mut Vec<f64>, cos: &mut Vec<f64>) {
    crate::machine::with_avx2(
        #[inline(always)]
        || sin_cos_body(phase, sin, cos),
    );
}

#[inline(always)]
fn sin_cos_body(phase: &[f64], sin: &mut Vec<f64>, cos: &mut Vec<f64>) {
    sin.resize(phase.len(), 0.0);
    cos.resize(phase.len(), 0.0);
    // NaN is not in range either.
    if phase.iter().any(|x| x.abs() > MAX_PHASE || x.is_nan()) {
        for ((x, s), c) in phase.iter().zip(sin.iter_mut()).zip(cos.iter_mut()) {
            (*s, *c) = x.sin_cos();
        }
        return;
    }
    for ((&x, s), c) in phase.iter().zip(sin.iter_mut()).zip(cos.iter_mut()) {
        (*s, *c) = sin_cos_kernel(x);
    }
}

/// `(sin x, cos x)` of one phase, the same bits as [`sin_cos_batch`] gives it (the C
/// library's beyond [`MAX_PHASE`], and for NaN).
pub fn sin_cos(x: f64) -> (f64, f64) {
    if x.abs() <= MAX_PHASE {
        sin_cos_kernel(x)
    } else {
        x.sin_cos()
    }
}

/// `sin x` and `cos x` for every `x` of `phase`, into `sin` and `cos` (resized), each the
/// same bits as [`sin_cos`] gives it, whatever else the batch holds (where
/// [`sin_cos_batch`] sends a whole batch to the C library for one phase out of range).
pub fn sin_cos_each(phase: &[f64], sin: &mut Vec<f64>, cos: &mut Vec<f64>) {
    if phase.iter().all(|x| x.abs() <= MAX_PHASE) {
        sin_cos_batch(phase, sin, cos);
    } else {
        sin.clear();
        cos.clear();
        for &x in phase {
            let (s, c) = sin_cos(x);
            sin.push(s);
            cos.push(c);
        }
    }
}

/// `sin x` and `cos x` for `|x| <= MAX_PHASE` (see the module's note on the method).
#[inline(always)]
fn sin_cos_kernel(x: f64) -> (f64, f64) {
    let t = x * std::f64::consts::FRAC_2_PI + ROUND;
    let q = t.to_bits() & 3;
    let n = t - ROUND;
    let r = ((x - n * PIO2_1) - n * PIO2_2) - n * PIO2_3;
    let z = r * r;
    let ps = S[0] + z * (S[1] + z * (S[2] + z * (S[3] + z * (S[4] + z * (S[5] + z * S[6])))));
    let sr = r + r * z * ps;
    let pc = C[0]
        + z * (C[1] + z * (C[2] + z * (C[3] + z * (C[4] + z * (C[5] + z * (C[6] + z * C[7]))))));
    let cr = 1.0 + z * pc;
    // x = n pi/2 + r: rotate by the quadrant.
    let (a, b) = if q & 1 == 1 { (cr, -sr) } else { (sr, cr) };
    let sign = if q & 2 == 2 { -1.0 } else { 1.0 };
    (sign * a, sign * b)
}

/// `ln 2 = LN2_1 + LN2_2`, the first with 32 significant bits so `n LN2_1` is exact for
/// `|n| < 2^21` (Cody & Waite, ch. 6).
const LN2_1: f64 = 0.693_147_180_369_123_8;
const LN2_2: f64 = 1.908_214_929_270_587_7e-10;
/// Below this argument `exp` is under the smallest normal double and is returned as 0.
pub const EXP_MIN: f64 = -708.0;

/// `exp x` for every `x <= 0` of `arg`, into `out` (resized): `x = n ln 2 + r` with `|r| <=
/// ln 2 / 2`, the Taylor series of `e^r` to degree 13 (the next term is below 5e-18), and
/// `2^n` built in the exponent bits. Arguments below [`EXP_MIN`] give 0 (the C library
/// would give a subnormal below 3e-308); positive or NaN arguments send the batch to the C
/// library. AVX2 where the CPU has it, with the same bits (`machine::with_avx2`).
pub fn exp_batch(arg: &[f64], out: &mut Vec<f64>) {
    crate::machine::with_avx2(
        #[inline(always)]
        || exp_body(arg, out),
    );
}

#[inline(always)]
fn exp_body(arg: &[f64], out: &mut Vec<f64>) {
    out.resize(arg.len(), 0.0);
    if arg.iter().any(|x| *x > 0.0 || x.is_nan()) {
        for (x, o) in arg.iter().zip(out.iter_mut()) {
            *o = x.exp();
        }
        return;
    }
    const E: [f64; 13] = {
        // 1 / k! for k = 1..=13.
        let mut e = [0.0; 13];
        let mut f = 1.0;
        let mut k = 0;
        while k < 13 {
            f /= (k + 1) as f64;
            e[k] = f;
            k += 1;
        }
        e
    };
    let round_bits = ROUND.to_bits() as i64;
    for (&x0, o) in arg.iter().zip(out.iter_mut()) {
        let x = x0.max(EXP_MIN);
        let t = x * std::f64::consts::LOG2_E + ROUND;
        // n, the integer nearest x / ln 2, from the mantissa bits (no float-to-integer
        // conversion, which would keep the loop scalar).
        let n_int = t.to_bits() as i64 - round_bits;
        let n = t - ROUND;
        let r = (x - n * LN2_1) - n * LN2_2;
        // Estrin's scheme (independent products, flat for rustfmt, which takes
        // exponential time on deeply nested brackets).
        let (r2, r4) = (r * r, r * r * r * r);
        let r8 = r4 * r4;
        let q0 = (E[0] + r * E[1]) + r2 * (E[2] + r * E[3]);
        let q1 = (E[4] + r * E[5]) + r2 * (E[6] + r * E[7]);
        let q2 = (E[8] + r * E[9]) + r2 * (E[10] + r * E[11]);
        let p = (q0 + r4 * q1) + r8 * (q2 + r4 * E[12]);
        let er = 1.0 + r * p;
        // 2^n for -1022 <= n <= 0: the biased exponent n + 1023.
        let two_n = f64::from_bits(((n_int + 1023) as u64) << 52);
        *o = if x0 < EXP_MIN { 0.0 } else { er * two_n };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `n` phases spread log-uniformly from 1e-9 to `max` rad (a fixed sequence), of
    /// alternating sign.
    fn phases(n: usize, max: f64) -> Vec<f64> {
        let mut u = 0.5f64;
        (0..n)
            .map(|i| {
                u = (u * 3.987_654_321 + 0.123_456_789).fract();
                let mag = 10f64.powf(-9.0 + u * (max.log10() + 9.0));
                if i % 2 == 0 { mag } else { -mag }
            })
            .collect()
    }

    #[test]
    fn agrees_with_the_c_library() {
        // Phases from 1e-9 to MAX_PHASE rad, both signs, and the quadrant boundaries.
        let mut x = phases(200_000, MAX_PHASE);
        for k in -20..=20 {
            let b = f64::from(k) * std::f64::consts::FRAC_PI_4;
            x.extend([b, b * (1.0 + f64::EPSILON), b * (1.0 - f64::EPSILON)]);
        }
        let (mut s, mut c) = (Vec::new(), Vec::new());
        sin_cos_batch(&x, &mut s, &mut c);
        for (i, &v) in x.iter().enumerate() {
            let (rs, rc) = v.sin_cos();
            // Absolute error of a few ulp of 1 (the C library is correctly rounded to
            // within an ulp; the reduction here is exact to ~1e-28 rad).
            let tol = 4.0 * f64::EPSILON;
            assert!(
                (s[i] - rs).abs() <= tol && (c[i] - rc).abs() <= tol,
                "x = {v:e}: sin {:e} vs {rs:e}, cos {:e} vs {rc:e}",
                s[i],
                c[i]
            );
        }
        // Beyond MAX_PHASE the batch goes to the C library, exactly.
        let big = [1e7, -3e9, f64::NAN];
        sin_cos_batch(&big, &mut s, &mut c);
        assert_eq!(s[0], 1e7f64.sin());
        assert_eq!(c[1], (-3e9f64).cos());
        assert!(s[2].is_nan() && c[2].is_nan());
    }

    /// The AVX2 path (where the CPU has it) and the baseline path give the same bits.
    #[test]
    fn the_avx2_path_gives_the_baseline_bits() {
        let x = phases(100_003, 1e6);
        let (mut s1, mut c1, mut s2, mut c2) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        sin_cos_body(&x, &mut s1, &mut c1);
        sin_cos_batch(&x, &mut s2, &mut c2);
        let bits = |v: &[f64]| v.iter().map(|f| f.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&s1), bits(&s2));
        assert_eq!(bits(&c1), bits(&c2));
        let neg: Vec<f64> = x.iter().map(|v| -v.abs().min(700.0)).collect();
        let (mut e1, mut e2) = (Vec::new(), Vec::new());
        exp_body(&neg, &mut e1);
        exp_batch(&neg, &mut e2);
        assert_eq!(bits(&e1), bits(&e2));
        eprintln!("AVX2 path taken: {}", crate::machine::avx2_enabled());
    }

    /// One phase at a time (`sin_cos`) and a batch with a phase out of range among them
    /// (`sin_cos_each`) give each phase the bits the batch gives it alone: the contribution
    /// of an exit is formed both ways (one per exit while tracing, a bin's at once under
    /// path sharing).
    #[test]
    fn one_at_a_time_and_mixed_batches_give_the_batch_bits() {
        let x = phases(10_001, 1e5);
        let (mut s, mut c) = (Vec::new(), Vec::new());
        sin_cos_batch(&x, &mut s, &mut c);
        for (i, &v) in x.iter().enumerate() {
            let (si, ci) = sin_cos(v);
            assert_eq!(
                (si.to_bits(), ci.to_bits()),
                (s[i].to_bits(), c[i].to_bits())
            );
        }
        let mut mixed = x.clone();
        mixed[17] = 1e9;
        mixed[4000] = f64::NAN;
        let (mut sm, mut cm) = (Vec::new(), Vec::new());
        sin_cos_each(&mixed, &mut sm, &mut cm);
        for i in 0..mixed.len() {
            if i == 17 || i == 4000 {
                continue;
            }
            assert_eq!(
                (sm[i].to_bits(), cm[i].to_bits()),
                (s[i].to_bits(), c[i].to_bits())
            );
        }
        assert_eq!((sm[17], cm[17]), 1e9f64.sin_cos());
        assert!(sm[4000].is_nan() && cm[4000].is_nan());
    }

    #[test]
    fn exp_agrees_with_the_c_library() {
        let mut x: Vec<f64> = vec![0.0, -0.0, -1e-300, EXP_MIN, -std::f64::consts::LN_2 / 2.0];
        let mut u = 0.25f64;
        for _ in 0..200_000 {
            u = (u * 3.987_654_321 + 0.123_456_789).fract();
            x.push(-(10f64.powf(-12.0 + u * 14.85)));
        }
        let mut e = Vec::new();
        exp_batch(&x, &mut e);
        for (v, got) in x.iter().zip(&e) {
            let want = v.exp();
            assert!(
                (got - want).abs() <= 4.0 * f64::EPSILON * want,
                "exp({v:e}) = {got:e}, the C library {want:e}"
            );
        }
        // Below EXP_MIN: 0 (the C library: below 3e-308); a positive argument: the C
        // library for the batch.
        exp_batch(&[-800.0, -1.0], &mut e);
        assert_eq!(e[0], 0.0);
        assert!((-800.0f64).exp() < 3e-308);
        exp_batch(&[1.0, -1.0], &mut e);
        assert_eq!(e, vec![1f64.exp(), (-1f64).exp()]);
    }
}
