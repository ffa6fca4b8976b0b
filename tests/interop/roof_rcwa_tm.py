#!/usr/bin/env python3
"""The 1 degree gold roof of tests/tilted_absorbers.rs in TM, by RCWA with Li's
factorisation: PyPI nannos (2.6.5), a Fourier modal method whose "tangent" formulation
applies Li's inverse rule across the grating's period and whose "original" one does not.
Not part of `make interop` (about 15 minutes on two cores); run by hand:

    python -m venv /tmp/rcwa && /tmp/rcwa/bin/pip install nannos==2.6.5 grcwa
    /tmp/rcwa/bin/python tests/interop/roof_rcwa_tm.py [TILT_DEG [T_MAX_NM RISE_NM]]

The film is the one tests/interop/roof_rcwa.py checks in TE with grcwa: air above a flat
top at z = 0, gold (Johnson & Christy at 450, 550 and 650 nm, as constants), a back face
that is a periodic roof with thickness `T_MAX - tan(tilt) |x - L/2|` nm over the tile `L = 2
RISE / tan(tilt)` (by default `T_MAX` 25 and `RISE` 10 nm, tests/tilted_absorbers.rs's
`Roof::thin`; its longer roofs take other values), glass (1.5) below; the roof as a staircase of slices, the permittivity of
each sampled on 2,048 cells. For each case it prints R and T in TM (E in the plane of
incidence, across the roof's ridges) at 81 orders and 40 slices and at 121 orders and 60
slices (orders and cells multiplied by the period over 1146 nm, rounded, for longer
roofs), with both formulations: their spread is the figure's uncertainty (up to 3e-3 at
650 nm, where gold's permittivity is largest), the local transfer-matrix film's TM
R and T (the Airy sum at each local thickness, averaged over 2,000 points) beside them,
and TE by grcwa (tests/interop/roof_rcwa.py's solver, 81 orders and 40 slices, scaled
likewise) for the unpolarised figures.

Measured at 1 degree (docs/physics.md, "Where the ray model stops"): the local TMM's TM
R is within 3e-3 of RCWA at all nine angles and wavelengths, and so is its T except at
30 degrees and 650 nm, where it is 5e-3 to 8e-3 above (0.498 against 0.491-0.493).
"""
import sys

import numpy as np

import roof_rcwa
from roof_rcwa import GLASS, GOLD, film

TILT = float(sys.argv[1]) if len(sys.argv) > 1 else 1.0
T_MAX = float(sys.argv[2]) if len(sys.argv) > 2 else 25.0
RISE = float(sys.argv[3]) if len(sys.argv) > 3 else 10.0
if not (0.0 < TILT < 45.0 and 0.0 < RISE < T_MAX):
    sys.exit(f"need 0 < TILT_DEG < 45 and 0 < RISE_NM < T_MAX_NM, got {TILT}, {T_MAX}, {RISE}")
L = 2.0 * RISE / np.tan(np.radians(TILT))
# Orders and cells grow with the period, from 81 and 121 orders on 2,048 cells at the
# default roof's 1146 nm: the same resolution across it.
SCALE = max(1, round(L / 1146.0))
# roof_rcwa's TE solver reads its module's roof.
roof_rcwa.T0, roof_rcwa.TILT, roof_rcwa.L = T_MAX, TILT, L


def thickness(x):
    return T_MAX - np.tan(np.radians(TILT)) * np.abs(x - L / 2)


def film_tm(lam, theta, d):
    """TM (p) R and T of the flat film at thickness d (roof_rcwa.film)."""
    return film(lam, theta, d, "p")


def rcwa_tm(lam, theta, nh, slices, formulation, cells=2048 * SCALE, flat=None):
    """TM R and T of the roof by RCWA; with `flat` (nm), of a flat film that thick."""
    import nannos as nn

    eps = GOLD[lam] ** 2
    lattice = nn.Lattice(L, discretization=cells)
    if flat is not None:
        layers = [lattice.Layer("air", epsilon=1.0), lattice.Layer("gold", thickness=flat, epsilon=eps)]
        layers.append(lattice.Layer("glass", epsilon=GLASS**2))
        wave = nn.PlaneWave(wavelength=lam, angles=(theta, 0, 0))
        r, t = nn.Simulation(layers, wave, nh=nh, formulation=formulation).diffraction_efficiencies()
        return float(np.real(r)), float(np.real(t))
    t = thickness((np.arange(cells) + 0.5) / cells * L)
    t_min = thickness(0.0)
    layers = [lattice.Layer("air", epsilon=1.0), lattice.Layer("gold", thickness=t_min, epsilon=eps)]
    dz = (T_MAX - t_min) / slices
    for k in range(slices):
        layer = lattice.Layer(f"roof{k}", thickness=dz)
        e = lattice.ones() * (GLASS**2 + 0j)
        e[t > t_min + (k + 0.5) * dz] = eps
        layer.epsilon = e
        layers.append(layer)
    layers.append(lattice.Layer("glass", epsilon=GLASS**2))
    # psi = 0: E in the plane of incidence (TM); main() checks it on a flat film.
    wave = nn.PlaneWave(wavelength=lam, angles=(theta, 0, 0))
    r, t = nn.Simulation(layers, wave, nh=nh, formulation=formulation).diffraction_efficiencies()
    return float(np.real(r)), float(np.real(t))


def main():
    # The polarisation and the reference's formulas: a flat 20 nm film, RCWA against Airy.
    for lam in GOLD:
        got, want = rcwa_tm(lam, 60.0, 11, 1, "original", flat=20.0), film_tm(lam, 60.0, 20.0)
        assert max(abs(got[0] - want[0]), abs(got[1] - want[1])) < 1e-9, f"flat film, {lam} nm: {got} {want}"
    xs = (np.arange(2000) + 0.5) / 2000 * L
    for theta in (60.0, 30.0, 0.0):
        for lam in GOLD:
            row = []
            for nh, slices in ((80 * SCALE + 1, 40), (120 * SCALE + 1, 60)):
                for form in ("original", "tangent"):
                    row.append(rcwa_tm(lam, theta, nh, slices, form))
            rs, ts = [x[0] for x in row], [x[1] for x in row]
            r_loc, t_loc = np.mean([film_tm(lam, theta, thickness(x)) for x in xs], axis=0)
            r_te, t_te = roof_rcwa.rcwa_te(lam, theta, 80 * SCALE + 1, 40, cells=2000 * SCALE)
            print(
                f"gold roof {TILT} deg, {T_MAX - RISE:.0f}-{T_MAX:.0f} nm, {lam:.0f} nm, {theta:.0f} deg, TM: RCWA R {min(rs):.4f}-{max(rs):.4f} "
                f"T {min(ts):.4f}-{max(ts):.4f}; local TMM R {r_loc:.4f} T {t_loc:.4f}; TE: RCWA R {r_te:.4f} T {t_te:.4f}",
                flush=True,
            )


main()
