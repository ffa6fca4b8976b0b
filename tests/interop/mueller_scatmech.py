"""Mueller-matrix BRDFs against NIST SCATMECH's facet models (issue 51): rough gold, and the
metallic paint against the flake-in-clear-coat model.

SCATMECH (PyPI pyscatmech, imports as pySCATMECH; a C++ build of a few minutes) is a
long-used metrology library of polarised scattering models. Its Facet_BRDF_Model reflects
light from each microfacet by the Fresnel equations, with the facet's own s and p turned
into the scattering frames: single scattering, no shadowing. Normalised by m00, its
Mueller matrix at a pair of directions does not depend on the slope distribution (every
facet that reflects one direction into the other has the half vector for its normal).

Its Subsurface_Facet_BRDF_Model puts the facets under a smooth overcoat (Germer & Marx,
"Ray model of light scattering by flake pigments or rough surfaces with smooth transparent
coatings", Appl. Opt. 43 (2004) 1266): refraction in, a flake's reflection, refraction
out.

goniospec simulates the shipped rough gold (GGX, alpha 0.2) and metallic paint (aluminium
flakes in a binder of n = 1.49) at two incident angles each on 1 x 5 degree buckets
centred on the plane of incidence, and each bucket holding the lobe is compared element by
element with SCATMECH at the bucket's centre. SCATMECH's "psps"
Stokes basis takes s first and the other sign of S3; of the two maps between the
conventions that a Fresnel reflection allows, the one that fits is reported, and every
bucket must fit it.

Not run by `make interop` (SCATMECH's build would add minutes to CI); run by hand:

    python tests/interop/mueller_scatmech.py GONIOSPEC_BINARY WORKDIR
"""

import csv
import io
import os
import subprocess
import sys

import numpy as np
import pySCATMECH.brdf as scat

BIN, WORK = sys.argv[1], sys.argv[2]
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
os.makedirs(WORK, exist_ok=True)
PHI_I = 2.5  # degrees: the plane of incidence through the middle of a 5-degree bucket


def run(*args):
    out = subprocess.run([BIN, *args], capture_output=True, text=True, cwd=ROOT)
    if out.returncode != 0:
        sys.exit(f"goniospec {' '.join(args)}: {out.stderr}")
    return out.stdout


def ours(gsa, theta_i, theta_o, phi_o):
    out = run("eval", gsa, "--mueller", "--theta-i", str(theta_i), "--phi-i", str(PHI_I),
              "--theta-o", str(theta_o), "--phi-o", str(phi_o))
    row = next(csv.DictReader(io.StringIO(out)))
    m = np.array([[float(row[f"m{a}{b}"]) for b in range(4)] for a in range(4)])
    e = np.array([[float(row[f"se_m{a}{b}"]) for b in range(4)] for a in range(4)])
    return m, e


# The conventions' map: D M_ours D = M_scatmech with D diagonal. At the specular direction
# (a Fresnel reflection) SCATMECH's m01 and m23 have the other signs: swapping the basis
# order flips S1 and S3 (diag(1, -1, 1, -1)); the other sign of one basis vector would flip
# S2 and S3 as well (diag(1, -1, -1, 1)). The off-specular buckets, whose m02, m12, m13 ...
# turn with the facets' planes, decide between them.
CANDIDATES = [np.diag([1.0, -1.0, 1.0, -1.0]), np.diag([1.0, -1.0, -1.0, 1.0])]


def compare(name, sample, lam, model, thetas, rays, skip_specular, least):
    """Simulates `sample` at `thetas` on 1 x 5 deg buckets and compares each bucket of the
    lobe with `model` at the bucket's centre (at least `least` of them); prints the figures
    and returns the worst normalised element's excess over 4 standard errors."""
    gsa = os.path.join(WORK, f"{name}.gsa")
    run("simulate", sample, "--theta-i", ",".join(str(t) for t in thetas), "--phi-i",
        str(PHI_I), "--wavelengths", str(lam), "--monochromatic", "--rays", str(rays),
        "--theta-o-bins", "90", "--phi-o-bins", "72", "--mueller", "--coherence", "beamlet",
        "-o", gsa)
    rows = []
    for theta_i in thetas:
        for dt in [-6.5, -3.5, -0.5, 2.5, 5.5]:
            for dphi in [-10.0, -5.0, 0.0, 5.0, 10.0]:
                if dphi == 0.0 and (skip_specular or dt != -0.5):
                    continue
                theta_o = theta_i + dt
                m, e = ours(gsa, theta_i, theta_o, 180 + PHI_I + dphi)
                rows.append((theta_i, theta_o, dphi, m, e))
    # The lobe: buckets holding at least 2 % of the brightest's BRDF, their m00 known to
    # 20 % (a paint's few flakes leave glints, and the buckets between them hold little
    # but edges and second bounces).
    peak = max(r[3][0, 0] for r in rows)
    excess = {id(d): [] for d in CANDIDATES}
    plain = {id(d): [] for d in CANDIDATES}
    compared = 0
    for theta_i, theta_o, dphi, m, e in rows:
        if m[0, 0] < 0.02 * peak or e[0, 0] > 0.2 * m[0, 0]:
            continue
        compared += 1
        w = np.array(model.MuellerBRDF(np.radians(theta_i), np.radians(theta_o),
                                       np.radians(dphi), 0.0, "psps"))
        for d in CANDIDATES:
            g = d @ m @ d / m[0, 0]
            sigma = np.abs(e) / m[0, 0]
            excess[id(d)].append((np.abs(g - w / w[0, 0]) - 4 * sigma).max())
            plain[id(d)].append(np.abs(g - w / w[0, 0]).max())
    best = min(CANDIDATES, key=lambda d: max(excess[id(d)]))
    other = max(max(excess[id(d)]) for d in CANDIDATES if d is not best)
    print(f"{name}_buckets_compared: {compared}")
    print(f"{name}_convention: D = diag{tuple(float(x) for x in best.diagonal())}")
    print(f"{name}_worst_normalised_element_difference: {max(plain[id(best)]):.4f}")
    print(f"{name}_worst_normalised_element_beyond_4_sigma: {max(max(excess[id(best)]), 0.0):.4f}")
    print(f"{name}_other_convention_worst_beyond_4_sigma: {other:.4f}")
    assert compared >= least, compared
    return max(excess[id(best)])


# Rough gold (GGX, alpha 0.2): Johnson & Christy's gold at a tabulated wavelength.
gold = scat.BRDF_Model("Facet_BRDF_Model", **{"lambda": 0.5486, "substrate": "(0.43,2.455)",
                                              "type": 0})
worst_gold = compare("scatmech_rough_gold", "meshes/rough-gold.toml", 548.6, gold, [30, 50],
                     262144, False, 20)
# The metallic paint: aluminium flakes (McPeak et al. at 550 nm) in a binder of n = 1.49,
# against the facet model under a smooth overcoat (Germer & Marx's flake-in-clear-coat
# ray model): the light refracted into the coat, reflected by a flake, refracted out. The
# specular bucket (the coat's and the black substrate's mirrors) is left out.
paint = scat.BRDF_Model("Subsurface_Facet_BRDF_Model",
                        **{"lambda": 0.55, "substrate": "(0.789405,5.85194)", "type": 0,
                           "overcoat": "(1.49,0)"})
worst_paint = compare("scatmech_metallic_paint", "meshes/metallic-paint.toml", 550.0, paint,
                      [30, 45], 131072, True, 4)
# What the facet models leave out, as in tests/polarimetric.rs: shadowing, masking and
# second bounces (between facets, or flakes and the coat's underside), a few per cent of
# the lobe's power, moving a normalised element by at most twice that share.
assert worst_gold < 0.06, worst_gold
assert worst_paint < 0.06, worst_paint
print("mueller_scatmech: ok")
