"""goniospec's Mie series against the PyPI miepython package (Prahl), an independent
implementation of the same theory: Q_ext, Q_sca, g and S1, S2 at several angles, for size
parameters from 0.01 to 1000 and relative indices from 1.05 to 2.7, absorbing ones
included.

    python tests/interop/mie_miepython.py GONIOSPEC_BINARY

Tolerance: relative error 1e-9 on Q_ext, Q_sca and g, and on S1, S2 relative to the
forward amplitude |S(0)| (the scale of the series' terms; backward amplitudes of large
spheres are 1e-4 of it and inherit the rounding of the whole sum). miepython sums the same
number of orders (Wiscombe's criterion), so truncation is not part of the difference.
Where miepython switches to its small-sphere expansion (|m| x < 0.1) the expansion itself
is accurate to its neglected order x^4 (relative); those cases are checked to 1e-7.
Prints `name: value unit` figures; exits non-zero on the first failure.
"""

import json
import subprocess
import sys

import miepython
import numpy as np

BIN = sys.argv[1]
MU = [-1.0, -0.7, -0.2, 0.0, 0.3, 0.8, 0.99, 1.0]
INDICES = [1.05 + 0j, 1.33 + 0j, 1.5 + 0.1j, 2.0 + 0.001j, 2.7 + 0j, 2.7 + 0.5j, 0.2 + 3.0j,
           1.5 + 1e-4j]
SIZES = [0.01, 0.2, 1.0, 2.5, 10.0, 37.0, 100.0, 1000.0]

worst = {"q": 0.0, "g": 0.0, "s": 0.0}
cases = 0
for m in INDICES:
    for x in SIZES:
        out = subprocess.run([BIN, "mie", "--n", repr(m.real), "--k", repr(m.imag), "--x", repr(x),
                              "--mu=" + ",".join(map(repr, MU)), "--json"],
                             capture_output=True, text=True, check=True).stdout
        ours = json.loads(out)
        # miepython takes n - ik for absorbing spheres, and its amplitudes are in that
        # convention too: the complex conjugates of Bohren & Huffman's (for a small sphere
        # BH eq. 5.2 gives S1 = -i x^3 (m^2 - 1)/(m^2 + 2), negative imaginary for m > 1).
        qext, qsca, _qback, g = miepython.efficiencies_mx(m.real - 1j * m.imag, x)
        s1, s2 = miepython.S1_S2(m.real - 1j * m.imag, x, np.array(MU), norm="wiscombe")
        s1, s2 = np.conj(s1), np.conj(s2)
        small = abs(m) * x < 0.1
        tol_q = 1e-7 if small else 1e-9
        for name, a, b in [("q_ext", ours["q_ext"], qext), ("q_sca", ours["q_sca"], qsca)]:
            err = abs(a - b) / abs(b)
            worst["q"] = max(worst["q"], err)
            if err > tol_q:
                sys.exit(f"FAILED {name} m={m} x={x}: goniospec {a!r}, miepython {b!r}, rel {err:.2e}")
        # g of a tiny sphere is itself of order x^2: compare it to 1 (its scale).
        err = abs(ours["g"] - g) / max(abs(g), 1e-3 if small else 1e-300)
        worst["g"] = max(worst["g"], err)
        if err > tol_q:
            sys.exit(f"FAILED g m={m} x={x}: goniospec {ours['g']!r}, miepython {g!r}, rel {err:.2e}")
        o1 = np.array(ours["s1_re"]) + 1j * np.array(ours["s1_im"])
        o2 = np.array(ours["s2_re"]) + 1j * np.array(ours["s2_im"])
        scale = abs(s1[-1])  # mu = 1: the forward amplitude
        err = max(np.max(np.abs(o1 - s1)), np.max(np.abs(o2 - s2))) / scale
        worst["s"] = max(worst["s"], err)
        if err > 1e-9:
            sys.exit(f"FAILED S1/S2 m={m} x={x}: rel to |S(0)| {err:.2e}\n ours {o1}\n miepython {s1}")
        cases += 1
print(f"mie_cases: {cases} count")
print(f"mie_max_rel_error_q: {worst['q']:.2e} 1")
print(f"mie_max_rel_error_g: {worst['g']:.2e} 1")
print(f"mie_max_rel_error_s1_s2: {worst['s']:.2e} 1")
print("mie-miepython: ok")
