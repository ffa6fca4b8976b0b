#!/usr/bin/env python3
"""A rigorous reference for gold V-grooves (issue 25): the TE reflectance (E along the
grooves) of a 60-degree gold V-groove grating of period 2 um at 550 nm, by RCWA (PyPI
grcwa), converged in orders and slices, written as JSON for tests/tilted_absorbers.rs
(`gold_v_grooves_against_rigorous_te_or_warn`).

    python tests/interop/vgroove_rcwa.py OUT.json

The profile is the tracer's `generate v-grooves` mesh (angle_deg = 60, 10 grooves per
20 um): ridges at x = 0 and 2000 nm, valley at 1000 nm, depth 1000 tan(60 deg) = 1732 nm,
air above, gold (n = 0.43 + 2.455i, constant) below, light in the plane across the grooves.
It is cut into a staircase of `slices` layers (the permittivity of each layer sampled at
its mid-height on 4,000 cells).

Only TE: for TE the staircase of a metal profile converges smoothly (E is tangential to
every step), while for TM the steps' corners carry field singularities and RCWA converges
slowly and erratically (Popov, Neviere, Gralak & Tayeb, JOSA A 19 (2002) 33; measured on
gold sinusoids in tests/interop/grating_rayleigh.py). Each figure is taken at 81 orders
and 200 slices, extrapolated in slices assuming an error falling as 1/slices (a staircase
of a slope; the more cautious of 1/slices and 1/slices^2) and corrected by the change from
81 to 121 orders at 100 slices; its stated uncertainty is the sum of both corrections.
Measured beside it: at 0 deg, 121 orders and 200 slices gave 0.63210 and 161 orders
0.63219; at 85 deg 0.91966 (the extrapolations: 0.6332 and 0.9201).
"""
import json
import sys

import numpy as np

LAMBDA = 550.0
N_GOLD = 0.43 + 2.455j
PERIOD = 2000.0
DEPTH = 0.5 * PERIOD * np.tan(np.radians(60.0))
THETAS = (0.0, 60.0, 85.0)


def r_te(theta_deg, n_g, slices, cells=4000):
    """TE (s, E along the grooves) reflectance of the staircase, by grcwa."""
    import grcwa

    grcwa.set_backend("numpy")
    eps = N_GOLD**2
    obj = grcwa.obj(n_g, [PERIOD, 0], [0, PERIOD * 1e-3], 1.0 / LAMBDA, np.radians(theta_deg), 0.0, verbose=0)
    obj.Add_LayerUniform(1.0, 1.0)
    for _ in range(slices):
        obj.Add_LayerGrid(DEPTH / slices, cells, 1)
    obj.Add_LayerUniform(1.0, eps)
    obj.Init_Setup(Gmethod=0)
    x = (np.arange(cells) + 0.5) / cells * PERIOD
    # Surface height: 0 at the ridges (x = 0, PERIOD), -DEPTH at the valley; gold below.
    surface = -DEPTH * (1.0 - np.abs(x - PERIOD / 2) / (PERIOD / 2))
    dz = DEPTH / slices
    layers = [np.where(surface > -(k + 0.5) * dz, eps, 1.0 + 0j) for k in range(slices)]
    obj.GridLayer_geteps(np.concatenate(layers))
    obj.MakeExcitationPlanewave(0, 0, 1, 0, order=0)
    r, t = obj.RT_Solve(normalize=1)
    # T is the power entering the gold below the staircase (absorbed there).
    r, t = float(np.real(r)), float(np.real(t))
    assert 0.0 <= r and 0.0 <= t and r + t <= 1.0 + 1e-9, f"R {r}, T {t}"
    return r


def main():
    cases = []
    for theta in THETAS:
        r81_100 = r_te(theta, 81, 100)
        r81_200 = r_te(theta, 81, 200)
        r121_100 = r_te(theta, 121, 100)
        d_slices = r81_200 - r81_100
        d_orders = r121_100 - r81_100
        extrapolated = r81_200 + d_slices + d_orders
        err = abs(d_slices) + abs(d_orders)
        print(
            f"gold V-grooves, TE, {theta:.0f} deg: R {r81_100:.5f} / {r81_200:.5f} (81 orders, 100 / 200 slices), "
            f"{r121_100:.5f} (121 orders, 100 slices); extrapolated {extrapolated:.5f} +- {err:.1e}"
        )
        assert err < 5e-3, f"not converged at {theta} deg: {err}"
        cases.append({"theta_deg": theta, "r_te": extrapolated, "uncertainty": err})
    out = {"lambda_nm": LAMBDA, "n": N_GOLD.real, "k": N_GOLD.imag, "period_nm": PERIOD, "angle_deg": 60.0, "cases": cases}
    with open(sys.argv[1], "w") as f:
        json.dump(out, f, indent=1)


main()
