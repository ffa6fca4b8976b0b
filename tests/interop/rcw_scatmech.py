"""The rigorous solver against NIST SCATMECH's RCW_Model and CrossRCW_Model (issue 52).

SCATMECH (PyPI pyscatmech, imports as pySCATMECH; a C++ build of about six minutes on two
cores) is a long-used metrology library. Its RCW_Model is the Fourier modal method of
Moharam et al. (1995) with Li's factorisation rules (Li 1996), its CrossRCW_Model Li's
1997 formulation for crossed gratings: the same method as src/optics/rcwa/, written
independently.

Each case is a staircase SCATMECH builds itself (its grating models slice the profile
into levels), solved at one truncation and again at 1.5 times it. What is stored per case:
the staircase as SCATMECH defines it (each level's thickness, transitions and
permittivities, from getGratingDefinition), the incidence, the truncation, and every
propagating order's direction and efficiency for s and p light (Mueller m00 + m01 and
m00 - m01: SCATMECH's Stokes basis puts s first, checked here on a flat interface
against Fresnel's equations), reflected and, for lossless substrates, transmitted.
`tests/rcwa_scatmech.rs` rebuilds each staircase on a pixel grid whose pixel edges hold
every transition exactly and compares the orders.

The cases:
- glass sinusoids (n = 1.5) of period 1, 2 and 5 um, peak-to-peak 0.1 period, 550 nm, 30 deg,
  20 levels divided evenly across (SCATMECH's option 0, so the transitions are rational);
- the 1 um glass sinusoid in conical incidence (the grating rotated by 30 deg);
- a lamellar gold grating (n = 0.25 + 3i), period 1.2 um, half filled, 100 nm deep, 20 deg;
- 60-degree gold V-grooves (n = 0.43 + 2.455i), period 2 um, depth 1732 nm, at 0, 60 and
  85 deg (the grooves of tests/interop/vgroove_rcwa.py; 40 levels);
- a crossed grating: glass blocks 300 x 150 nm, 100 nm high, on glass, in a 600 nm square
  cell, at 20 deg and 30 deg azimuth, 11 x 11 harmonics in both solvers (a square
  truncation). Its Fourier coefficients are a 4096-point DFT of samples in SCATMECH
  (Gridded_CrossGrating), exact for the staircase in goniospec; the two differ by the
  factor sinc(pi p / 4096), 1 - 1e-5 at the highest harmonic used.

Lossless cases must conserve energy in SCATMECH to 1e-4, or the script stops; the defect is
stored (at most 5e-15, but 5.2e-5 for p light on the 5 um sinusoid).

Not run by `make interop` (the build would add minutes to CI); the JSON it writes is
committed (tests/reference/rcw-scatmech.json). Run by hand to refresh it:

    python tests/interop/rcw_scatmech.py tests/reference/rcw-scatmech.json
"""

import json
import math
import os
import sys

import numpy as np
import pySCATMECH.crossrcw as crossrcw
import pySCATMECH.rcw as rcw

OUT = sys.argv[1]
LAMBDA = 0.55  # um
GLASS = "(1.5,0)"


def quiet(f):
    """SCATMECH reports each step of a solve on its standard streams: keep them off ours."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    null = os.open(os.devnull, os.O_WRONLY)
    os.dup2(null, 1)
    os.dup2(null, 2)
    try:
        return f()
    finally:
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in (null, *saved):
            os.close(fd)


def cplx(z):
    return [float(np.real(z)), float(np.imag(z))]


def s_and_p(mueller):
    m = np.array(mueller)
    return float(m[0, 0] + m[0, 1]), float(m[0, 0] - m[0, 1])


def check_fresnel():
    """SCATMECH's s is the first Stokes state: a flat glass interface at 30 deg."""
    m = quiet(lambda: rcw.RCW_Model(**{
        "grating": "Single_Line_Grating", "grating.height": 0.0, "grating.nlevels": 1,
        "grating.material": GLASS, "grating.medium_t": GLASS, "lambda": LAMBDA,
        "thetai": 30, "order": 3}))
    s, p = quiet(lambda: s_and_p(m.DiffractionEfficiency(0)))
    t = math.radians(30)
    ci, ct = math.cos(t), math.sqrt(1 - (math.sin(t) / 1.5) ** 2)
    rs = ((ci - 1.5 * ct) / (ci + 1.5 * ct)) ** 2
    rp = ((1.5 * ci - ct) / (1.5 * ci + ct)) ** 2
    assert abs(s - rs) < 1e-12 and abs(p - rp) < 1e-12, (s, rs, p, rp)


def orders_1d(params, order, lossless):
    out = {"r": [], "t": []}
    for side, kind in (("r", 0), ("t", 1))[: 2 if lossless else 1]:
        m = quiet(lambda: rcw.RCW_Model(**params, order=order, type=kind))
        for i in range(-order, order + 1):
            d = quiet(lambda: m.Direction(i))
            if d[0] == 0 and d[1] == 0 and d[2] == 0:
                continue  # evanescent
            s, p = quiet(lambda: s_and_p(m.DiffractionEfficiency(i)))
            out[side].append({"i": i, "dir": list(d), "s": s, "p": p})
    return out, m


def orders_2d(params, order):
    out = {"r": [], "t": []}
    for side, kind in (("r", 0), ("t", 1)):
        m = quiet(lambda: crossrcw.CrossRCW_Model(**params, order1=order, order2=order, type=kind))
        for i in range(-order, order + 1):
            for j in range(-order, order + 1):
                d = quiet(lambda: m.Direction(i, j))
                if d[0] == 0 and d[1] == 0 and d[2] == 0:
                    continue
                s, p = quiet(lambda: s_and_p(m.DiffractionEfficiency(i, j)))
                out[side].append({"i": [i, j], "dir": list(d), "s": s, "p": p})
    return out


def totals(o):
    return {side: [sum(e[k] for e in o[side]) for k in ("s", "p")] for side in ("r", "t")}


def spread(a, b):
    """The largest change of any order's efficiency between two truncations."""
    worst = 0.0
    for side in ("r", "t"):
        fine = {json.dumps(e["i"]): e for e in b[side]}
        for e in a[side]:
            f = fine.get(json.dumps(e["i"]))
            for k in ("s", "p"):
                worst = max(worst, abs(e[k] - (f[k] if f else 0.0)))
    return worst


def case_1d(name, params, order, lossless, eps_below):
    o, m = orders_1d(params, order, lossless)
    finer, _ = orders_1d(params, (3 * order + 1) // 2, lossless)
    g = quiet(m.getGratingDefinition)
    levels = [{
        "thickness_um": float(t),
        "positions_um": [float(x) for x in pos],
        "eps": [cplx(e) for e in mat],
    } for t, pos, mat in zip(g["thickness"], g["position"], g["materialx"])]
    tot = totals(o)
    energy = 0.0
    if lossless:
        energy = max(abs(tot["r"][k] + tot["t"][k] - 1) for k in range(2))
        assert energy < 1e-4, f"{name}: SCATMECH loses {energy:.1e} of the power"
    print(f"{name}: R s {tot['r'][0]:.6f} p {tot['r'][1]:.6f}, {len(levels)} levels, "
          f"order {order}, spread at 1.5x {spread(o, finer):.1e}")
    return {
        "name": name, "kind": "1d", "period_um": float(g["period"]), "lambda_um": LAMBDA,
        "theta_deg": params["thetai"], "rotation_deg": params.get("rotation", 0.0),
        "eps_above": cplx(g["medium_i"]), "eps_below": cplx(eps_below),
        "levels": levels, "order": order, "orders": o, "spread": spread(o, finer),
        "energy_defect": energy,
    }


def main():
    check_fresnel()
    cases = []
    for period in (1.0, 2.0, 5.0):
        params = {
            "grating": "Sinusoidal_Relief_Grating", "grating.period": period,
            "grating.amplitude": 0.1 * period, "grating.nlevels": 20, "grating.option": 0,
            "grating.material": GLASS, "grating.medium_t": GLASS, "lambda": LAMBDA, "thetai": 30.0,
        }
        order = int(2 * 1.5 * period / LAMBDA) + 12
        cases.append(case_1d(f"glass sinusoid {period:g} um", params, order, True, 2.25))
        if period == 1.0:
            conical = dict(params, rotation=30.0)
            cases.append(case_1d("glass sinusoid 1 um, conical 30 deg", conical, order, True, 2.25))
    gold = (0.25 + 3.0j) ** 2
    params = {
        "grating": "Single_Line_Grating", "grating.period": 1.2, "grating.height": 0.1,
        "grating.topwidth": 0.6, "grating.bottomwidth": 0.6, "grating.nlevels": 1,
        "grating.material": "(0.25,3.0)", "grating.space": "(1,0)",
        "grating.medium_t": "(0.25,3.0)", "lambda": LAMBDA, "thetai": 20.0,
    }
    cases.append(case_1d("lamellar gold 1.2 um", params, 30, False, gold))
    vgold = (0.43 + 2.455j) ** 2
    for theta in (0.0, 60.0, 85.0):
        params = {
            "grating": "Triangular_Grating", "grating.period": 2.0,
            "grating.amplitude": 1.0 * math.tan(math.radians(60)), "grating.aspect": 0.5,
            "grating.nlevels": 40, "grating.material": "(0.43,2.455)",
            "grating.medium_t": "(0.43,2.455)", "lambda": LAMBDA, "thetai": theta,
        }
        cases.append(case_1d(f"gold V-grooves {theta:g} deg", params, 40, False, vgold))
    params = {
        "grating": "Rectangle_CrossGrating", "grating.d1": 0.6, "grating.d2": 0.6,
        "grating.grid1": 4096, "grating.grid2": 4096, "grating.length1": 0.3,
        "grating.length2": 0.15, "grating.thickness": 0.1, "grating.inside": GLASS,
        "grating.outside": "(1,0)", "grating.medium_t": GLASS, "lambda": LAMBDA,
        "thetai": 20.0, "rotation": 30.0,
    }
    o = orders_2d(params, 5)
    finer = orders_2d(params, 8)
    tot = totals(o)
    energy = max(abs(tot["r"][k] + tot["t"][k] - 1) for k in range(2))
    assert energy < 1e-4, f"crossed grating: SCATMECH loses {energy:.1e} of the power"
    print(f"crossed glass blocks: R s {tot['r'][0]:.6f} p {tot['r'][1]:.6f}, 11 x 11, "
          f"spread at 17 x 17 {spread(o, finer):.1e}")
    cases.append({
        "name": "crossed glass blocks", "kind": "blocks", "period_um": 0.6, "lambda_um": LAMBDA,
        "theta_deg": 20.0, "rotation_deg": 30.0, "eps_above": [1.0, 0.0],
        "eps_below": [2.25, 0.0], "eps_block": [2.25, 0.0], "block_um": [0.3, 0.15],
        "height_um": 0.1, "order": 5, "orders": o, "spread": spread(o, finer), "energy_defect": energy,
    })
    out = {
        "reference": "NIST SCATMECH (PyPI pyscatmech 0.1.10): RCW_Model, CrossRCW_Model",
        "cases": cases,
    }
    tmp = OUT + ".tmp"
    with open(tmp, "w") as f:
        json.dump(out, f, indent=1)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, OUT)


main()
