"""A tour of goniospec from Python (`make python` first, then run with .venv-python):

1. simulate the seed's wavy 600 nm soap film and plot its lobe with matplotlib;
2. compare the flat soap film with the PyPI `tmm` package;
3. export the film as an RGL .bsdf and render a sphere of it with Mitsuba 3.

    .venv-python/bin/pip install matplotlib tmm mitsuba
    .venv-python/bin/python examples/python_tour.py out/tour

Steps whose package is missing are skipped with a message.
"""

import os
import sys

import numpy as np

import goniospec as gs

out = sys.argv[1] if len(sys.argv) > 1 else "out/tour"
os.makedirs(out, exist_ok=True)

# 1. The wavy film and its lobe in the plane of incidence at 30 degrees.
film = gs.Sample.load("meshes/thin-film-600nm.toml")
acc = gs.simulate(film, theta_i_deg=list(range(0, 90, 10)), wavelengths="380:780:20", rays=2048)
brdf = acc.build("table")
theta_o = np.linspace(-85, 85, 171)
f = brdf.eval(30, 0, np.abs(theta_o), np.where(theta_o >= 0, 180.0, 0.0))  # [171, n_lambda]
print("R at 30 deg:", np.round(acc.reflectance(30)["R"], 4))
try:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(subplot_kw={"projection": "polar"})
    for j in range(0, len(brdf.lambda_nm), 4):
        ax.plot(np.radians(theta_o), f[:, j] * np.cos(np.radians(theta_o)), label=f"{brdf.lambda_nm[j]:.0f} nm")
    ax.set_thetamin(-90)
    ax.set_thetamax(90)
    ax.set_theta_zero_location("N")
    ax.legend(fontsize=6)
    fig.savefig(os.path.join(out, "lobe.png"), dpi=120)
    print("wrote", os.path.join(out, "lobe.png"))
except ImportError:
    print("matplotlib not installed: no lobe plot")

# 2. The flat soap film against the tmm package (Byrnes).
flat = gs.Sample.load("meshes/flat-soap-film.toml")
ours = gs.analytic(flat, 30, wavelengths="450,550,650", monochromatic=True)
try:
    import tmm

    for lam, r in zip(ours["lambda_nm"], ours["R"]):
        ref = 0.5 * sum(tmm.coh_tmm(p, [1, 1.33, 1], [np.inf, 600, np.inf], np.radians(30), lam)["R"] for p in "sp")
        print(f"flat film at {lam:.0f} nm: goniospec {r:.10f}, tmm {ref:.10f}")
except ImportError:
    print("tmm not installed: no comparison")

# 3. Into Mitsuba 3 through an RGL .bsdf.
bsdf_path = os.path.join(out, "film.bsdf")
brdf.export(bsdf_path, format="rgl", sample=film, resolution=49)
try:
    import mitsuba as mi

    mi.set_variant("scalar_spectral")
    scene = mi.load_dict({
        "type": "scene",
        "integrator": {"type": "direct"},
        "sensor": {"type": "perspective", "fov": 30,
                   "to_world": mi.ScalarTransform4f().look_at(origin=[0, -5, 2], target=[0, 0, 0], up=[0, 0, 1]),
                   "film": {"type": "hdrfilm", "width": 128, "height": 128}},
        "light": {"type": "directional", "direction": [0.4, 0.6, -0.7], "irradiance": {"type": "d65", "scale": 3.14}},
        "shape": {"type": "sphere", "bsdf": {"type": "measured", "filename": bsdf_path}},
    })
    mi.util.write_bitmap(os.path.join(out, "sphere.exr"), mi.render(scene, spp=16))
    print("wrote", os.path.join(out, "sphere.exr"))
except ImportError:
    print("mitsuba not installed: no render")
