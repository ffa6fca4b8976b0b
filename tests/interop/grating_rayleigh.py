#!/usr/bin/env python3
"""A rigorous reference for metal gratings (issues 25 and 26): the order efficiencies of
sinusoidal gold gratings by the Rayleigh-Fourier method, written here, converged in orders,
checked for energy on a lossless grating and against PyPI's grcwa (RCWA) for TE; written as
JSON for tests/diffraction.rs (`metal_grating_against_rigorous`,
`metal_gratings_match_rigorous_r_or_warn`).

    python tests/interop/grating_rayleigh.py OUT.json

Why not RCWA alone: a smooth metal profile as a staircase converges slowly and erratically
for TM light (each step's corners carry field singularities; Popov, Neviere, Gralak &
Tayeb, JOSA A 19 (2002) 33). Measured here on gold, Lambda = 2 um, A = 97 nm, 0 deg: nannos
2.6.5 (Li's factorisation, 'tangent' formulation) gave TM R 0.674 / 0.725 / 0.763 / 0.757
over 41-161 harmonics and 20-80 slices, meent 0.13.2 gave R > 1. TE converges (below).

The Rayleigh-Fourier method (Lord Rayleigh, Proc. R. Soc. A 79 (1907) 399; Petit (ed.),
Electromagnetic Theory of Gratings, Springer 1980, ch. 1; the sinusoid's Fourier
coefficients by Jacobi-Anger, Abramowitz & Stegun 9.1.41). The field above the surface
z = A sin(K x) is the incident wave plus outgoing Rayleigh orders, the field below a sum of
downgoing (or decaying) orders; u (E_y for TE, H_y for TM) and (1/p) du/dn (p = 1 for TE,
eps for TM) are continuous on the surface. Projected on exp(i alpha_n x), a term
exp(i alpha_m x + i s z) evaluated on the surface gives J_{n-m}(s A) for u and
i J_{n-m}(s A) (k^2 - alpha_m alpha_n) / s for N . grad u with N = (-h', 1). The Rayleigh
hypothesis holds for a sinusoid when K A < 0.448 (Petit & Cadilhac, C. R. Acad. Sci. Paris
B 262 (1966) 468; Millar, Radio Sci. 6 (1971) 1017); the gratings here have K A <= 0.32.
Checked here: convergence in orders, energy (R + T = 1) on a lossless grating, and TE
against grcwa's RCWA (Richardson-extrapolated in slices).
"""
import json
import sys

import numpy as np
from scipy.special import jv

LAMBDA = 550.0
N_METAL = 0.43 + 2.455j  # gold near 550 nm, constant, as the tracer's sample below uses
# The calibration set of docs/validity.md: (period nm, amplitude nm, incidence angles deg),
# periods 2-8 um (3.6-15 wavelengths), A / period 0.01-0.05 (K A <= 0.32).
ANGLES = (0.0, 30.0, 45.0, 60.0, 75.0, 85.0)
GRATINGS = [(p, f * p, ANGLES) for p in (2000.0, 3000.0, 4000.0, 5000.0, 6000.0, 8000.0) for f in (0.01, 0.02, 0.035, 0.05)]


def rayleigh_fourier(period, amp, lam, n1, n2, theta_deg, pol, N):
    """Reflected order efficiencies {m: eta} (propagating orders), total R and total T
    (meaningful for a lossless lower medium) of z = amp sin(2 pi x / period) between n1
    above and n2 below, light from theta_deg in the plane across the grooves, orders
    -N..N."""
    k0 = 2 * np.pi / lam
    k1, k2 = n1 * k0, n2 * k0
    m = np.arange(-N, N + 1)
    a0 = k1 * np.sin(np.radians(theta_deg))
    al = a0 + m * 2 * np.pi / period
    b = np.sqrt(k1**2 - al**2 + 0j)
    b = np.where(b.imag < 0, -b, b)
    g = np.sqrt(k2**2 - al**2 + 0j)
    g = np.where(g.imag < 0, -g, g)
    b0 = np.sqrt(k1**2 - a0**2 + 0j)
    p1, p2 = (1.0, 1.0) if pol == "TE" else (n1**2, n2**2)
    P = m[:, None] - m[None, :]
    kk1 = k1**2 - al[None, :] * al[:, None]
    kk2 = k2**2 - al[None, :] * al[:, None]
    n = len(m)
    M = np.zeros((2 * n, 2 * n), complex)
    rhs = np.zeros(2 * n, complex)
    M[:n, :n] = jv(P, b[None, :] * amp)
    M[:n, n:] = -jv(P, -g[None, :] * amp)
    rhs[:n] = -jv(m, -b0 * amp)
    M[n:, :n] = 1j * jv(P, b[None, :] * amp) * kk1 / b[None, :] / p1
    M[n:, n:] = -1j * jv(P, -g[None, :] * amp) * kk2 / (-g[None, :]) / p2
    rhs[n:] = -1j * jv(m, -b0 * amp) * (k1**2 - a0 * al) / (-b0) / p1
    x = np.linalg.solve(M, rhs)
    r, t = x[:n], x[n:]
    eff_r = np.abs(r) ** 2 * b.real / b0.real
    eff_t = np.abs(t) ** 2 * (g / p2).real / (b0.real / p1)
    orders = {int(mm): float(e) for mm, e, bb in zip(m, eff_r, b) if bb.real > 0}
    return orders, float(eff_r.sum()), float(eff_t.sum())


def grcwa_te(period, amp, lam, eps, theta_deg, nG, slices, cells=2048):
    """TE reflectance of the same sinusoid as a staircase of `slices` layers, by grcwa."""
    import grcwa

    grcwa.set_backend("numpy")
    obj = grcwa.obj(nG, [period, 0], [0, period * 1e-3], 1.0 / lam, np.radians(theta_deg), 0.0, verbose=0)
    obj.Add_LayerUniform(1.0, 1.0)
    for _ in range(slices):
        obj.Add_LayerGrid(2 * amp / slices, cells, 1)
    obj.Add_LayerUniform(1.0, eps)
    obj.Init_Setup(Gmethod=0)
    x = (np.arange(cells) + 0.5) / cells * period
    h = amp * np.sin(2 * np.pi * x / period)
    dz = 2 * amp / slices
    obj.GridLayer_geteps(np.concatenate([np.where(h > amp - (k + 0.5) * dz, eps, 1.0 + 0j) for k in range(slices)]))
    obj.MakeExcitationPlanewave(0, 0, 1, 0, order=0)
    r, _ = obj.RT_Solve(normalize=1)
    return float(np.real(r))


def main():
    # 1. Energy on a lossless grating (glass, K A = 0.31) at both polarisations.
    for theta in (0.0, 30.0):
        for pol in ("TE", "TM"):
            _, r, t = rayleigh_fourier(10000.0, 500.0, LAMBDA, 1.0, 1.5, theta, pol, 60)
            assert abs(r + t - 1) < 1e-9, f"glass {pol} {theta}: R + T = {r + t}"
    # 2. Against RCWA (grcwa, PyPI) for TE on the gold grating the tests use most: nG = 121
    # (119 orders after grcwa's truncation; 239 moves R by 3e-5), staircases of 80 and 160 slices, Richardson-extrapolated (the slice error
    # falls as slices^-2: measured 1.1e-3 -> 3.3e-4 between 40, 80 and 160).
    eps = N_METAL**2
    for theta in (0.0, 30.0):
        r80 = grcwa_te(5000.0, 250.0, LAMBDA, eps, theta, 121, 80)
        r160 = grcwa_te(5000.0, 250.0, LAMBDA, eps, theta, 121, 160)
        rich = r160 + (r160 - r80) / 3
        ours = rayleigh_fourier(5000.0, 250.0, LAMBDA, 1.0, N_METAL, theta, "TE", 60)[1]
        print(f"TE gold 5 um, {theta} deg: Rayleigh {ours:.6f}, grcwa {r80:.6f} / {r160:.6f} (80 / 160 slices), extrapolated {rich:.6f}")
        assert abs(rich - ours) < 1e-4, (rich, ours)
    # 3. The references, converged in orders (60 against 90).
    out = {"lambda_nm": LAMBDA, "n": N_METAL.real, "k": N_METAL.imag, "gratings": []}
    for period, amp, thetas in GRATINGS:
        cases = []
        for theta in thetas:
            pols = {}
            for pol in ("TE", "TM"):
                o60, r60, _ = rayleigh_fourier(period, amp, LAMBDA, 1.0, N_METAL, theta, pol, 60)
                _, r90, _ = rayleigh_fourier(period, amp, LAMBDA, 1.0, N_METAL, theta, pol, 90)
                # Converged far below the 2e-3 the tests compare R to (measured 1e-15 to
                # 3e-7, the largest at 8 um, A = 400 nm).
                assert abs(r60 - r90) < 1e-6, f"not converged: {period} {amp} {theta} {pol}: {r60} {r90}"
                pols[pol] = (o60, r60)
            orders = {m: 0.5 * (pols["TE"][0][m] + pols["TM"][0][m]) for m in pols["TE"][0]}
            r = 0.5 * (pols["TE"][1] + pols["TM"][1])
            print(f"gold period {period:.0f} A {amp:.0f} theta {theta:.0f}: R {r:.5f} (TE {pols['TE'][1]:.5f}, TM {pols['TM'][1]:.5f})")
            cases.append({"theta_deg": theta, "r": r, "r_te": pols["TE"][1], "r_tm": pols["TM"][1], "orders": orders})
        out["gratings"].append({"period_nm": period, "amplitude_nm": amp, "cases": cases})
    with open(sys.argv[1], "w") as f:
        json.dump(out, f, indent=1)


main()
