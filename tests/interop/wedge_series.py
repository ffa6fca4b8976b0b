#!/usr/bin/env python3
"""The exact plane-wave series of an infinite absorbing wedge, independent of the tracer:
what the ray model computes inside one face of a tilted film, without its rays (issue 25,
docs/physics.md "Longer facets, and the TM light"). Run by hand (numpy only, about a
minute per line):

    python tests/interop/wedge_series.py [LAMBDA_NM THETA_DEG T1_NM T2_NM]

Air above a flat top at z = 0, gold below it (Johnson & Christy, the constants of
tests/interop/roof_rcwa.py), glass below a back face through the apex line x = 0 tilted
by `beta` (thickness `x tan(beta)`). Light arrives from air travelling along +x. Every
wave is referred to the apex, which lies on both faces, so each event multiplies the
amplitudes by its reflection and transmission alone, with no propagation factor. Each
event is solved from the boundary conditions by brute force: the reflected and
transmitted index vectors `K - q1 m` and `K + q2 m` (the tangential index `K` kept), two
transverse fields for each, and the continuity of `m x E` and `m x H`, `H = N x E`
(Maxwell's curl equation for a plane wave, in units of the vacuum admittance), solved by
least squares. The reflected field at a point x of the top face is the sum of the
partial waves there, `sum E_j exp(i k0 N_j . x)`, and R(x) its normal Poynting flux
`Re[(E x conj(H))_z] / 2` over the incident one; T(x) likewise through the back face.
Printed: R and T averaged over the stretch where the film is T1 to T2 nm thick, for each
tilt and polarisation, beside the local transfer-matrix film (roof_rcwa.film) over the same
thicknesses. At a tilt of 1e-4 degree the two agree to 1e-5 (a check of the solver and of
the flux normalisation); at larger tilts, each orientation carries energy along the film
and out of the stretch, so the two orientations differ from the local film at first
order in the tilt, and a roof (one face of each) at second.
"""
import sys

import numpy as np

from roof_rcwa import GLASS, GOLD, film


def bil(a, b):
    return np.sum(a * b)


def transverse(n):
    """Two independent fields v with v . N = 0 (bilinear), bilinear-normalised."""
    out = []
    for a in np.eye(3, dtype=complex)[[1, 0, 2]]:
        v = a - bil(a, n) / bil(n, n) * n
        for u in out:
            v = v - bil(v, u) / bil(u, u) * u
        if abs(bil(v, v)) > 1e-6:
            out.append(v / np.sqrt(bil(v, v)))
        if len(out) == 2:
            return out
    raise ValueError("no transverse basis")


def event(n_in, e_in, m, n2):
    """The wave (index vector n_in, field e_in) meets a plane of unit normal m pointing
    into the medium of index n2: returns the reflected and transmitted (N, E)."""
    q1 = bil(n_in, m)
    k = n_in - q1 * m
    n_r = k - q1 * m
    q2 = np.sqrt(n2 * n2 - bil(k, k) + 0j)
    # Into an absorber the root that decays; into a lossless medium the one that leaves.
    if (n2.imag > 0 and q2.imag < 0) or (n2.imag == 0 and q2.real < 0):
        q2 = -q2
    n_t = k + q2 * m
    v_r, v_t = transverse(n_r), transverse(n_t)
    cols = []
    for v, n, sign in ((v_r[0], n_r, 1), (v_r[1], n_r, 1), (v_t[0], n_t, -1), (v_t[1], n_t, -1)):
        cols.append(np.concatenate([sign * np.cross(m, v), sign * np.cross(m, np.cross(n, v))]))
    a = np.array(cols).T
    b = -np.concatenate([np.cross(m, e_in), np.cross(m, np.cross(n_in, e_in))])
    x, *_ = np.linalg.lstsq(a, b, rcond=None)
    assert np.linalg.norm(a @ x - b) < 1e-9 * (1 + np.linalg.norm(b)), "boundary conditions"
    return (n_r, x[0] * v_r[0] + x[1] * v_r[1]), (n_t, x[2] * v_t[0] + x[3] * v_t[1])


def series(lam, theta, beta, pol, rounds=40):
    """The partial waves leaving up into air and down into glass, referred to the apex."""
    th, b = np.radians(theta), np.radians(beta)
    n_gold = GOLD[lam]
    n0 = np.array([np.sin(th), 0, -np.cos(th)], complex)
    e0 = np.array([0, 1, 0], complex) if pol == "s" else np.array([np.cos(th), 0, np.sin(th)], complex)
    up = np.array([0, 0, 1.0], complex)
    back = np.array([np.tan(b), 0, 1.0])
    back = (back / np.linalg.norm(back)).astype(complex)  # normal into the gold
    (n_r, e_r), (n, e) = event(n0, e0, -up, n_gold)
    refl, trans = [(n_r, e_r)], []
    for _ in range(rounds):
        (n_r, e_r), (n_t, e_t) = event(n, e, -back, GLASS + 0j)
        trans.append((n_t, e_t))
        (n, e), (n_a, e_a) = event(n_r, e_r, up, 1.0 + 0j)
        refl.append((n_a, e_a))
    return refl, trans


def flux(waves, point, normal):
    """Normal Poynting flux of the summed waves at `point` (in units of 1 / k0)."""
    e = sum(w[1] * np.exp(1j * bil(w[0], point)) for w in waves)
    h = sum(np.cross(w[0], w[1]) * np.exp(1j * bil(w[0], point)) for w in waves)
    return 0.5 * np.real(bil(np.cross(e, np.conj(h)), normal))


def averaged(lam, theta, beta, pol, t1, t2, m=2000):
    """R and T averaged over the stretch of the top face where the film is t1 to t2 nm."""
    refl, trans = series(lam, theta, beta, pol)
    k0, b = 2 * np.pi / lam, np.radians(beta)
    xs = np.sign(b) * ((np.arange(m) + 0.5) / m * (t2 - t1) + t1) / np.tan(abs(b))
    incident = 0.5 * np.cos(np.radians(theta))
    r = np.mean([flux(refl, k0 * np.array([x, 0, 0]), np.array([0, 0, 1.0])) for x in xs])
    down = np.array([np.tan(b), 0, 1.0])
    down = -down / np.linalg.norm(down)
    # Through the back face, per unit of horizontal length: dA = dx / cos(beta).
    t = np.mean([flux(trans, k0 * np.array([x, 0, -x * np.tan(b)]), down) for x in xs]) / np.cos(b)
    return r / incident, t / incident


def main():
    args = [float(a) for a in sys.argv[1:5]] if len(sys.argv) > 4 else [650.0, 60.0, 20.0, 40.0]
    lam, theta, t1, t2 = args
    if lam not in GOLD or not 0.0 <= theta < 90.0 or not 0.0 < t1 < t2:
        sys.exit(f"need LAMBDA_NM in {sorted(GOLD)}, 0 <= THETA_DEG < 90 and 0 < T1_NM < T2_NM")
    thick = (np.arange(2000) + 0.5) / 2000 * (t2 - t1) + t1
    for pol in ("s", "p"):
        r_loc, t_loc = np.mean([film(lam, theta, t, pol) for t in thick], axis=0)
        for beta in (1e-4, 0.5, -0.5, 1.0, -1.0):
            r, t = averaged(lam, theta, beta, pol, t1, t2)
            print(
                f"{pol}, {lam:.0f} nm, {theta:.0f} deg, {t1:.0f}-{t2:.0f} nm, tilt {beta:+} deg: R {r:.5f} T {t:.5f}; "
                f"local TMM R {r_loc:.5f} T {t_loc:.5f}; off {r - r_loc:+.5f} {t - t_loc:+.5f}",
                flush=True,
            )
            if beta == 1e-4:
                assert abs(r - r_loc) < 1e-4 and abs(t - t_loc) < 1e-4, "the flat limit"


if __name__ == "__main__":
    main()
