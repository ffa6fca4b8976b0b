#!/usr/bin/env python3
"""References for the rigorous solver (issue 52, `optics::rcwa`) from independent Fourier
modal methods, written as JSON for `against_references` in tests/rcwa.rs: PyPI nannos
2.6.5, its "tangent" formulation (Li's inverse rule across the grating's boundaries), for
the gold and crossed gratings, and PyPI meent 0.13.2 (with the eigenvalue patch of
tests/interop/grating_meent.py) for the glass sinusoids, where nannos 2.6.5 does not
conserve energy at 5 um (R + T = 1.33).

    python tests/interop/rcwa_nannos.py OUT.json

Each case is a staircase given exactly (the slices' permittivities on `cells` pixels, the
same formula the Rust test evaluates), solved at `orders` harmonics per patterned axis;
for each polarisation (s: psi = 90, E along the grooves of a classical mount; p: psi = 0)
the reflected and transmitted efficiency of every propagating order. Each case is also
solved at 1.5 times the harmonics (`converged_*`), the spread that states how far the
figures are from their limit.

Cases: glass sinusoids z = A cos(2 pi x / period) with A / period = 0.05 at 1, 2 and 5 um
(550 nm, 30 deg, 24 slices); a lamellar gold grating (1200 nm, 80 nm deep, half filled,
600 nm, 20 deg) and a gold sinusoid (1200 nm, A = 80 nm), TE and TM; and a crossed
grating of glass cylinders (800 x 800 nm, radius 250 nm, 200 nm tall, on glass; 600 nm,
20 deg incidence at 30 deg azimuth). Checked here: every lossless 1-D case conserves
energy to 1e-6 in its solver, the crossed one to 1e-3 (nannos' tangent-field formulation
for crossed gratings conserves it only to its truncation: 0.99988 here).
"""
import json
import sys

import numpy as np
import nannos as nn

import grating_meent  # noqa: F401  (patches meent's eigenvalue branch on import)
import meent

GOLD = (0.25 + 3.0j) ** 2
GLASS = 2.25


def sinusoid(period, amp, eps, slices, cells):
    x = (np.arange(cells) + 0.5) / cells * period
    h = amp * np.cos(2 * np.pi * x / period)
    dz = 2 * amp / slices
    return [(dz, np.where(h > amp - (k + 0.5) * dz, eps, 1.0 + 0j)) for k in range(slices)]


def lamellar(depth, fill, eps, cells):
    x = (np.arange(cells) + 0.5) / cells
    return [(depth, np.where(x < fill, eps, 1.0 + 0j))]


def cylinders(height, radius, period, eps, cells):
    c = (np.arange(cells) + 0.5) / cells * period - period / 2
    xx, yy = np.meshgrid(c, c, indexing="ij")
    return [(height, np.where(xx**2 + yy**2 < radius**2, eps, 1.0 + 0j))]


def solve_meent(case, orders, psi):
    """A 1-D case by meent (pol 0: TE, s; 1: TM, p), its index the permittivity's root."""
    ucell = np.stack([np.sqrt(e).reshape(1, -1) for _, e in case["slices"]])
    below = np.sqrt(complex(*case["eps_below"]))
    mee = meent.call_mee(backend=0, pol=0 if psi == 90.0 else 1, n_top=1.0, n_bot=below,
                         theta=np.radians(case["theta_deg"]), phi=None, fto=[orders, 0],
                         period=[case["period_nm"], 1.0], wavelength=case["lambda_nm"],
                         thickness=[d for d, _ in case["slices"]], type_complex=np.complex128,
                         ucell=ucell, fourier_type=1, enhanced_dfs=False)
    res = mee.conv_solve().res
    out = {"r": {}, "t": {}}
    for m, rv, tv in zip(range(-orders, orders + 1), np.ravel(res.de_ri), np.ravel(res.de_ti)):
        if abs(rv) > 1e-14:
            out["r"][f"{m},0"] = float(rv)
        if abs(tv) > 1e-14:
            out["t"][f"{m},0"] = float(tv)
    total = sum(out["r"].values()) + sum(out["t"].values())
    assert abs(total - 1) < 1e-6, f"meent does not conserve energy: {total}"
    return out


def solve(case, orders, psi):
    if case["solver"] == "meent":
        return solve_meent(case, orders, psi)
    period = case["period_nm"]
    two_d = case["kind"] == "cylinders"
    if two_d:
        lattice = nn.Lattice(((period, 0), (0, period)), discretization=(case["cells"], case["cells"]))
        nh = (2 * orders + 1) ** 2
    else:
        lattice = nn.Lattice(period, discretization=case["cells"])
        nh = 2 * orders + 1
    layers = [lattice.Layer("above", epsilon=1.0)]
    for k, (d, e) in enumerate(case["slices"]):
        layer = lattice.Layer(f"s{k}", thickness=d)
        layer.epsilon = lattice.ones() * (1.0 + 0j)
        layer.epsilon[...] = e.reshape(layer.epsilon.shape)
        layers.append(layer)
    below = complex(*case["eps_below"])
    layers.append(lattice.Layer("below", epsilon=below))
    wave = nn.PlaneWave(wavelength=case["lambda_nm"], angles=(case["theta_deg"], case["phi_deg"], psi))
    sim = nn.Simulation(layers, wave, nh=nh, formulation="tangent")
    r, t = sim.diffraction_efficiencies(orders=True)
    harm = np.asarray(sim.harmonics).T
    out = {"r": {}, "t": {}}
    for (m, n), rv, tv in zip(harm, np.real(r), np.real(t)):
        key = f"{int(m)},{int(n)}"
        if abs(rv) > 1e-14:
            out["r"][key] = float(rv)
        if abs(tv) > 1e-14 and below.imag == 0:
            out["t"][key] = float(tv)
    if below.imag == 0:
        # Its crossed (tangent-field) formulation conserves energy only to the truncation.
        total = sum(out["r"].values()) + sum(out["t"].values())
        tol = 1e-3 if two_d else 1e-6
        assert abs(total - 1) < tol, f"nannos does not conserve energy: {total}"
        out["energy"] = total
    return out


def main():
    cases = []
    for period in (1000.0, 2000.0, 5000.0):
        cases.append({"name": f"glass sinusoid {period / 1000:g} um", "kind": "sinusoid", "period_nm": period,
                      "amplitude_nm": 0.05 * period, "eps": [GLASS, 0.0], "eps_below": [GLASS, 0.0],
                      "lambda_nm": 550.0, "theta_deg": 30.0, "phi_deg": 0.0, "slices_n": 24,
                      "cells": int(720 * period / 1000), "orders": int(np.ceil(3 * period / 550)) + 12,
                      "solver": "meent"})
    cases.append({"name": "gold lamellar", "kind": "lamellar", "period_nm": 1200.0, "depth_nm": 80.0, "fill": 0.5,
                  "eps": [GOLD.real, GOLD.imag], "eps_below": [GOLD.real, GOLD.imag], "lambda_nm": 600.0,
                  "theta_deg": 20.0, "phi_deg": 0.0, "cells": 2400, "orders": 32, "solver": "nannos"})
    cases.append({"name": "gold sinusoid", "kind": "sinusoid", "period_nm": 1200.0, "amplitude_nm": 80.0,
                  "eps": [GOLD.real, GOLD.imag], "eps_below": [GOLD.real, GOLD.imag], "lambda_nm": 600.0,
                  "theta_deg": 20.0, "phi_deg": 0.0, "slices_n": 24, "cells": 2400, "orders": 32,
                  "solver": "nannos"})
    cases.append({"name": "glass cylinders (crossed)", "kind": "cylinders", "period_nm": 800.0, "radius_nm": 250.0,
                  "height_nm": 200.0, "eps": [GLASS, 0.0], "eps_below": [GLASS, 0.0], "lambda_nm": 600.0,
                  "theta_deg": 20.0, "phi_deg": 30.0, "cells": 64, "orders": 5, "solver": "nannos"})
    for case in cases:
        eps = complex(*case["eps"])
        if case["kind"] == "sinusoid":
            case["slices"] = sinusoid(case["period_nm"], case["amplitude_nm"], eps, case["slices_n"], case["cells"])
        elif case["kind"] == "lamellar":
            case["slices"] = lamellar(case["depth_nm"], case["fill"], eps, case["cells"])
        else:
            case["slices"] = cylinders(case["height_nm"], case["radius_nm"], case["period_nm"], eps, case["cells"])
        for pol, psi in (("s", 90.0), ("p", 0.0)):
            case[pol] = solve(case, case["orders"], psi)
            case["converged_" + pol] = solve(case, int(np.ceil(1.5 * case["orders"])), psi)
            r = sum(case[pol]["r"].values())
            r2 = sum(case["converged_" + pol]["r"].values())
            print(f"{case['name']} {pol}: R {r:.6f} at {case['orders']} harmonics, {r2:.6f} at 1.5 times", flush=True)
        del case["slices"]
    with open(sys.argv[1], "w") as f:
        json.dump({"solvers": "meent 0.13.2 (patched), nannos 2.6.5 (tangent)", "cases": cases}, f, indent=1)


main()
