//! Mueller calculus of the tracer's fields (docs/physics.md, "Polarisation").
//!
//! Every tree carries the complex field of two incident states, s and p
//! ([`crate::trace::launch_fields`]). Projected on the outgoing direction's own s/p frame
//! ([`frame`]) they are the columns of an exit's Jones matrix `J` (2 x 2, rows the outgoing
//! and columns the incident p and s components). In the Stokes convention used here
//! (`x` = p, `y` = s, `x × y` = the direction of travel; `S1 = |E_p|^2 - |E_s|^2`,
//! `S2 = 2 Re(E_p conj E_s)`, `S3 = 2 Im(conj E_p E_s)`), the Mueller matrix of a Jones
//! matrix is `M_ab = tr(σ_a J σ_b J†) / 2` with the Pauli matrices `σ_0 = I`,
//! `σ_1 = diag(1, -1)`, `σ_2 = [[0, 1], [1, 0]]`, `σ_3 = [[0, -i], [i, 0]]` (Azzam &
//! Bashara 1977, §2.8; Chipman, Lam & Young 2018, "Polarized Light and Optical Systems",
//! eq. 6.99). Its `m00` is `|J|_F^2 / 2`: the unpolarised power the estimator deposits.
//!
//! Coherent sums of exits need the cross terms of two Jones matrices: the mixed matrix
//! `M(A, B)_ab = tr(σ_a A σ_b B†) / 2` is linear in `A`, antilinear in `B`, and
//! `M(B, A) = conj M(A, B)` (the Pauli matrices are Hermitian), so a pair with phase
//! `φ` adds `2 Re(M(A, B) e^{iφ})`, the matrix form of the scalar `2 Re(a conj(b) e^{iφ})`.
//!
//! A Mueller matrix is physically realisable (a sum of non-depolarising systems) exactly
//! when its coherency matrix `H = Σ_ab m_ab (σ_a ⊗ conj σ_b) / 4` is positive
//! semi-definite (Cloude 1986, "Group theory and polarisation algebra", Optik 75, 26);
//! `tr H = m00`, and a pure Jones matrix's `H` has rank one.

use glam::DVec3;

use super::C64;
use super::fresnel::Field;

/// A Jones matrix, row-major: `[pp, ps, sp, ss]` (row: outgoing p, s; column: incident
/// p, s), dimensionless amplitudes.
pub type Jones = [C64; 4];

/// A Mueller matrix, row-major, `m[4 a + b]`.
pub type Mueller = [f64; 16];

const Z: C64 = C64::new(0.0, 0.0);
const ONE: C64 = C64::new(1.0, 0.0);
const I: C64 = C64::new(0.0, 1.0);

/// The Pauli matrices in the Stokes order, row-major 2 x 2.
const PAULI: [[C64; 4]; 4] = [
    [ONE, Z, Z, ONE],
    [ONE, Z, Z, C64::new(-1.0, 0.0)],
    [Z, ONE, ONE, Z],
    [Z, C64::new(0.0, -1.0), I, Z],
];

/// The s and p unit vectors of a wave travelling along `w` (unit): `s = w × z`
/// normalised (perpendicular to the plane through `w` and the sample's normal), `p = s ×
/// w`, so `p × s = w`. Along the normal itself, where that plane is undefined, `s = x`.
/// The launched fields and every outgoing frame use this one definition.
pub fn frame(w: DVec3) -> (DVec3, DVec3) {
    let c = w.cross(DVec3::Z);
    let s = if c.length() > 1e-12 {
        c.normalize()
    } else {
        DVec3::X
    };
    (s.cross(w), s)
}

fn project(e: &Field, v: DVec3) -> C64 {
    e[0] * v.x + e[1] * v.y + e[2] * v.z
}

/// The Jones matrix of an exit travelling along `w` whose fields for incident s and p
/// light are `e[0]` and `e[1]` (as the tracer carries them).
pub fn jones(e: &[Field; 2], w: DVec3) -> Jones {
    let (p, s) = frame(w);
    [
        project(&e[1], p),
        project(&e[0], p),
        project(&e[1], s),
        project(&e[0], s),
    ]
}

/// The mixed Mueller matrix `M(A, B)_ab = tr(σ_a A σ_b B†) / 2` (complex; real when
/// `A = B`): `sum (σ_a)_li (σ_b)_jk A_ij conj(B_lk) / 2` written out over the 16 products
/// `p[2i + j][2l + k] = A_ij conj(B_lk)`, the Pauli matrices' entries being 1, -1 and +-i
/// (a pair of exits' matrix is formed once per tree for every pair: this is its cost; the
/// test checks it against the definition).
pub fn mixed(a: &Jones, b: &Jones) -> [C64; 16] {
    let p: [[C64; 4]; 4] = std::array::from_fn(|x| std::array::from_fn(|y| a[x] * b[y].conj()));
    let i = |z: C64| C64::new(-z.im, z.re);
    let h = 0.5;
    [
        h * (p[0][0] + p[1][1] + p[2][2] + p[3][3]),
        h * (p[0][0] - p[1][1] + p[2][2] - p[3][3]),
        h * (p[0][1] + p[1][0] + p[2][3] + p[3][2]),
        h * i(-p[0][1] + p[1][0] - p[2][3] + p[3][2]),
        h * (p[0][0] + p[1][1] - p[2][2] - p[3][3]),
        h * (p[0][0] - p[1][1] - p[2][2] + p[3][3]),
        h * (p[0][1] + p[1][0] - p[2][3] - p[3][2]),
        h * i(-p[0][1] + p[1][0] + p[2][3] - p[3][2]),
        h * (p[2][0] + p[3][1] + p[0][2] + p[1][3]),
        h * (p[2][0] - p[3][1] + p[0][2] - p[1][3]),
        h * (p[2][1] + p[3][0] + p[0][3] + p[1][2]),
        h * i(-p[2][1] + p[3][0] - p[0][3] + p[1][2]),
        h * i(-p[2][0] - p[3][1] + p[0][2] + p[1][3]),
        h * i(-p[2][0] + p[3][1] + p[0][2] - p[1][3]),
        h * i(-p[2][1] - p[3][0] + p[0][3] + p[1][2]),
        h * (-p[2][1] + p[3][0] + p[0][3] - p[1][2]),
    ]
}

/// The Mueller matrix of one Jones matrix.
pub fn mueller(a: &Jones) -> Mueller {
    mixed(a, a).map(|z| z.re)
}

/// Cloude's coherency matrix `H = Σ_ab m_ab (σ_a ⊗ conj σ_b) / 4`, row-major 4 x 4.
pub fn coherency(m: &Mueller) -> [C64; 16] {
    let mut h = [Z; 16];
    for a in 0..4 {
        for b in 0..4 {
            let w = m[4 * a + b] * 0.25;
            if w == 0.0 {
                continue;
            }
            let (sa, sb) = (&PAULI[a], &PAULI[b]);
            for i in 0..2 {
                for j in 0..2 {
                    for k in 0..2 {
                        for l in 0..2 {
                            h[4 * (2 * i + k) + (2 * j + l)] +=
                                sa[2 * i + j] * sb[2 * k + l].conj() * w;
                        }
                    }
                }
            }
        }
    }
    h
}

/// The eigenvalues of a Mueller matrix's coherency matrix, ascending (Cloude 1986): all
/// non-negative for a realisable matrix, summing to `m00`. The Hermitian 4 x 4 is taken as
/// the real symmetric 8 x 8 `[[Re, -Im], [Im, Re]]`, whose eigenvalues are its own, each
/// twice, found by cyclic Jacobi rotations (Golub & Van Loan 2013, §8.5.3).
pub fn coherency_eigenvalues(m: &Mueller) -> [f64; 4] {
    let h = coherency(m);
    let mut a = [[0.0f64; 8]; 8];
    for i in 0..4 {
        for j in 0..4 {
            let z = h[4 * i + j];
            a[i][j] = z.re;
            a[i + 4][j + 4] = z.re;
            a[i][j + 4] = -z.im;
            a[i + 4][j] = z.im;
        }
    }
    let scale: f64 = a.iter().flatten().map(|x| x * x).sum::<f64>().sqrt();
    for _sweep in 0..50 {
        let off: f64 = (0..8)
            .flat_map(|i| (0..8).filter(move |&j| j != i).map(move |j| (i, j)))
            .map(|(i, j)| a[i][j] * a[i][j])
            .sum::<f64>()
            .sqrt();
        if off <= 1e-15 * scale || off == 0.0 {
            break;
        }
        for p in 0..8 {
            for q in p + 1..8 {
                if a[p][q] == 0.0 {
                    continue;
                }
                let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                for row in a.iter_mut() {
                    let (akp, akq) = (row[p], row[q]);
                    row[p] = c * akp - s * akq;
                    row[q] = s * akp + c * akq;
                }
                let (rp, rq) = (a[p], a[q]);
                for k in 0..8 {
                    a[p][k] = c * rp[k] - s * rq[k];
                    a[q][k] = s * rp[k] + c * rq[k];
                }
            }
        }
    }
    let mut d: [f64; 8] = std::array::from_fn(|i| a[i][i]);
    d.sort_by(f64::total_cmp);
    [d[0], d[2], d[4], d[6]]
}

/// The degree of polarisation of the light a Mueller matrix sends out for unpolarised
/// light in: `sqrt(m10^2 + m20^2 + m30^2) / m00` (0 where `m00 <= 0`).
pub fn degree_of_polarisation(m: &Mueller) -> f64 {
    if m[0] <= 0.0 {
        return 0.0;
    }
    (m[4] * m[4] + m[8] * m[8] + m[12] * m[12]).sqrt() / m[0]
}

/// A named incident polarisation state, or a Stokes vector `S0,S1,S2,S3`, that a state
/// is not.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error(
    "'{0}' is not a polarisation state: give unpolarised, s, p, +45, -45, circular+ (S3 = +1), circular- (S3 = -1), or a Stokes vector S0,S1,S2,S3 with S0 > 0 and S1^2 + S2^2 + S3^2 <= S0^2"
)]
pub struct BadState(pub String);

/// The Stokes vector of a named state (in the frame of [`frame`], `S3 = 2 Im(conj E_p
/// E_s)`), or of four comma-separated numbers, normalised to `S0 = 1`.
pub fn stokes_state(s: &str) -> Result<[f64; 4], BadState> {
    let v = match s.trim() {
        "unpolarised" | "unpolarized" => [1.0, 0.0, 0.0, 0.0],
        "p" => [1.0, 1.0, 0.0, 0.0],
        "s" => [1.0, -1.0, 0.0, 0.0],
        "+45" => [1.0, 0.0, 1.0, 0.0],
        "-45" => [1.0, 0.0, -1.0, 0.0],
        "circular+" => [1.0, 0.0, 0.0, 1.0],
        "circular-" => [1.0, 0.0, 0.0, -1.0],
        t => {
            let x: Vec<f64> = t
                .split(',')
                .map(|x| x.trim().parse::<f64>())
                .collect::<Result<_, _>>()
                .map_err(|_| BadState(s.into()))?;
            // Normalised before the degree of polarisation is checked, so that the check
            // neither overflows (1e200) nor underflows (1e-170): it is scale-free.
            if !(x.len() == 4 && x.iter().all(|v| v.is_finite()) && x[0] > 0.0) {
                return Err(BadState(s.into()));
            }
            let v = [1.0, x[1] / x[0], x[2] / x[0], x[3] / x[0]];
            if v[1] * v[1] + v[2] * v[2] + v[3] * v[3] > 1.0 + 1e-12 {
                return Err(BadState(s.into()));
            }
            v
        }
    };
    Ok(v)
}

/// `M S`: the Stokes vector a Mueller matrix sends out for `s` in.
pub fn apply(m: &Mueller, s: &[f64; 4]) -> [f64; 4] {
    std::array::from_fn(|a| (0..4).map(|b| m[4 * a + b] * s[b]).sum())
}

/// `acc += 2 Re(z e^{iφ}) w` for the 16 elements, with `(sin φ, cos φ)` given.
#[inline]
pub fn add_cross(acc: &mut Mueller, z: &[C64; 16], sin: f64, cos: f64, w: f64) {
    for (a, z) in acc.iter_mut().zip(z) {
        *a += 2.0 * (z.re * cos - z.im * sin) * w;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The degree of polarisation is checked on the normalised vector: a vector of any
    /// scale is judged as its direction (issue 74: 1e200 and 1e-170 entries, degrees of
    /// polarisation sqrt 2 and sqrt 3, passed because the squares overflowed or vanished).
    #[test]
    fn stokes_vectors_are_checked_whatever_their_scale() {
        for bad in [
            "1e200,1e200,1e200,0",
            "1e-170,1e-170,1e-170,1e-170",
            "-1,0,0,0",
            "0,0,0,0",
            "1,0.8,0.8,0",
        ] {
            assert!(stokes_state(bad).is_err(), "{bad}");
        }
        assert_eq!(
            stokes_state("1e200,1e200,0,0").unwrap(),
            [1.0, 1.0, 0.0, 0.0]
        );
        assert_eq!(
            stokes_state("2e-170,0,-1e-170,0").unwrap(),
            [1.0, 0.0, -0.5, 0.0]
        );
    }

    /// The 2 x 2 product, row-major.
    fn mul(a: &[C64; 4], b: &[C64; 4]) -> [C64; 4] {
        [
            a[0] * b[0] + a[1] * b[2],
            a[0] * b[1] + a[1] * b[3],
            a[2] * b[0] + a[3] * b[2],
            a[2] * b[1] + a[3] * b[3],
        ]
    }

    /// Two Jones matrices with every entry complex and no symmetry.
    fn two_jones() -> (Jones, Jones) {
        (
            [
                C64::new(0.3, -0.2),
                C64::new(0.05, 0.1),
                C64::new(-0.12, 0.04),
                C64::new(-0.6, 0.25),
            ],
            [
                C64::new(-0.1, 0.4),
                C64::new(0.2, 0.0),
                C64::new(0.0, -0.3),
                C64::new(0.5, 0.1),
            ],
        )
    }

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    /// A pure Jones matrix: rank-one coherency with eigenvalue m00, a degree of
    /// polarisation of 1 for any input state (checked for unpolarised light's only
    /// defined output), and `M(B, A) = conj M(A, B)`.
    #[test]
    fn a_pure_jones_matrix_has_a_rank_one_coherency() {
        let (a, b) = two_jones();
        let m = mueller(&a);
        let f2: f64 = a.iter().map(|z| z.norm_sqr()).sum();
        assert!(close(m[0], 0.5 * f2, 1e-15));
        let ev = coherency_eigenvalues(&m);
        assert!(close(ev[3], m[0], 1e-12), "{ev:?}");
        for e in &ev[..3] {
            assert!(e.abs() < 1e-12, "{ev:?}");
        }
        // A Stokes vector through a pure system stays fully polarised: S0^2 = S1^2+S2^2+S3^2
        // for fully polarised input (1, 0, 0, 1).
        let s: Vec<f64> = (0..4).map(|r| m[4 * r] + m[4 * r + 3]).collect();
        assert!(close(
            s[0] * s[0],
            s[1] * s[1] + s[2] * s[2] + s[3] * s[3],
            1e-12
        ));
        let (ab, ba) = (mixed(&a, &b), mixed(&b, &a));
        for (x, y) in ab.iter().zip(&ba) {
            assert!((x - y.conj()).norm() < 1e-15);
        }
    }

    /// Stokes vectors from the fields directly: a field E = (E_p, E_s) through J, its
    /// Stokes vector by the convention's definitions, against M times the input's.
    #[test]
    fn the_mueller_matrix_maps_stokes_vectors_as_the_fields_do() {
        let j: Jones = [
            C64::new(0.7, 0.1),
            C64::new(-0.2, 0.3),
            C64::new(0.1, -0.4),
            C64::new(0.5, 0.5),
        ];
        let stokes = |ep: C64, es: C64| {
            [
                ep.norm_sqr() + es.norm_sqr(),
                ep.norm_sqr() - es.norm_sqr(),
                2.0 * (ep * es.conj()).re,
                2.0 * (ep.conj() * es).im,
            ]
        };
        let m = mueller(&j);
        for (ep, es) in [
            (ONE, Z),
            (Z, ONE),
            (C64::new(0.6, 0.0), C64::new(0.0, 0.8)),
            (C64::new(0.3, 0.4), C64::new(-0.5, 0.1)),
        ] {
            let out = stokes(j[0] * ep + j[1] * es, j[2] * ep + j[3] * es);
            let s = stokes(ep, es);
            for r in 0..4 {
                let v: f64 = (0..4).map(|c| m[4 * r + c] * s[c]).sum();
                assert!(close(v, out[r], 1e-14), "row {r}: {v} against {}", out[r]);
            }
        }
    }

    /// An ideal depolariser diag(1, 0, 0, 0): four equal eigenvalues 1/4; a matrix with
    /// m11 > m00 is not realisable (a negative eigenvalue).
    #[test]
    fn depolarisers_and_impossible_matrices() {
        let mut m = [0.0; 16];
        m[0] = 1.0;
        for e in coherency_eigenvalues(&m) {
            assert!(close(e, 0.25, 1e-14));
        }
        m[5] = 1.5;
        assert!(coherency_eigenvalues(&m)[0] < -0.1);
    }

    /// `mixed` against the definition, `tr(σ_a A σ_b B†) / 2` by 2 x 2 products.
    #[test]
    fn the_mixed_matrix_is_its_definition() {
        let (a, b) = two_jones();
        let got = mixed(&a, &b);
        for (ai, sa) in PAULI.iter().enumerate() {
            for (bi, sb) in PAULI.iter().enumerate() {
                let y = mul(sa, &mul(&a, sb));
                let t = y[0] * b[0].conj()
                    + y[1] * b[1].conj()
                    + y[2] * b[2].conj()
                    + y[3] * b[3].conj();
                assert!((got[4 * ai + bi] - 0.5 * t).norm() < 1e-15);
            }
        }
    }

    #[test]
    fn frames_are_right_handed_about_the_direction() {
        for w in [
            DVec3::new(0.3, -0.2, 0.9).normalize(),
            DVec3::new(-0.5, 0.1, -0.7).normalize(),
            DVec3::Z,
            -DVec3::Z,
        ] {
            let (p, s) = frame(w);
            assert!((p.cross(s) - w).length() < 1e-14);
            assert!(p.dot(s).abs() < 1e-15);
        }
    }
}
