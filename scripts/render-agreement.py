"""How closely Mitsuba 3 renders an exported material to `goniospec render`, at the sets of
incident angles users simulate (issue 71). For each material and angle set it simulates,
builds a table, exports the .bsdf with the Mitsuba scene (`export --scene mitsuba`), and
renders the scene in Mitsuba 3 and the table with `goniospec render` under the same view
(the default directional light and constant environment, 96 x 96). Over the sphere's
interior pixels it prints the CIEDE2000 of the images' mean colours, the per-pixel mean,
and the ratio of Mitsuba's mean luminance to goniospec's.

    .venv-interop/bin/python scripts/render-agreement.py GONIOSPEC_BINARY WORKDIR \
        [--materials car-paint,rough-gold] [--sets 3,5,9] [--rays N]

Angle sets: 3 = 0,40,80; 5 = 0 to 80 by 20; 9 = 0 to 80 by 10; 3short = 0,30,60 (exported with
--force: what a file that ends at 60 deg renders as). One line per run, `name: value unit`
figures after it.
"""

import argparse
import os
import subprocess
import sys
import time

import mitsuba as mi
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "tests", "interop"))
from colourdiff import de2000, lab  # noqa: E402

mi.set_variant("scalar_spectral")

SETS = {"3": "0,40,80", "5": "0,20,40,60,80", "9": "0,10,20,30,40,50,60,70,80", "3short": "0,30,60"}
MATERIALS = {"car-paint": "meshes/car-paint.toml", "rough-gold": "meshes/rough-gold.toml",
             "metallic-paint": "meshes/metallic-paint.toml"}
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def run(binary, *args):
    r = subprocess.run([binary, *args], cwd=ROOT, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"goniospec {' '.join(args)} failed:\n{r.stderr}")
    return r.stdout


def luminance(rgb):
    """Y of linear sRGB (IEC 61966-2-1)."""
    return float(np.asarray(rgb) @ np.array([0.2126, 0.7152, 0.0722]))


def interior(ours):
    """The sphere's pixels one in from the silhouette (the renderers filter edges apart)."""
    obj = ours.sum(axis=-1) > 0
    inner = np.zeros_like(obj)
    inner[1:-1, 1:-1] = obj[1:-1, 1:-1] & obj[:-2, 1:-1] & obj[2:, 1:-1] & obj[1:-1, :-2] & obj[1:-1, 2:]
    return inner


def agreement(binary, work, name, toml, angles, rays, force):
    stem = os.path.join(work, f"{name}-{angles.replace(':', '_').replace(',', '-')}")
    gsa, gsb, bsdf, exr = stem + ".gsa", stem + ".gsb", stem + ".bsdf", stem + "-goniospec.exr"
    t0 = time.time()
    run(binary, "simulate", toml, "--theta-i", angles, "--rays", str(rays),
        "--wavelengths", "400:700:20", "-o", gsa)
    run(binary, "build", gsa, "--repr", "table", "-o", gsb)
    view = ["--width", "96", "--height", "96"]
    run(binary, "export", gsb, "--sample", toml, "-o", bsdf, "--scene", "mitsuba", *view,
        "--spp", "256", *(["--force"] if force else []))
    run(binary, "render", gsb, "-o", exr, *view, "--spp", "16")
    ours = np.array(mi.Bitmap(exr), dtype=np.float64)[..., :3]
    theirs = np.array(mi.render(mi.load_file(stem + ".xml")), dtype=np.float64)[..., :3]
    inner = interior(ours)
    a, b = ours[inner].mean(axis=0), theirs[inner].mean(axis=0)
    px = [de2000(lab(p), lab(q)) for p, q in zip(ours[inner], theirs[inner])]
    return {"mean_colour_de2000": de2000(lab(a), lab(b)), "pixel_de2000_mean": float(np.mean(px)),
            "luminance_ratio": luminance(b) / luminance(a), "seconds": time.time() - t0}


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("binary")
    p.add_argument("work")
    p.add_argument("--materials", default="car-paint,rough-gold")
    p.add_argument("--sets", default="3,5,9")
    p.add_argument("--rays", type=int, default=1024)
    a = p.parse_args()
    os.makedirs(a.work, exist_ok=True)
    binary = os.path.abspath(a.binary)
    for name in a.materials.split(","):
        for key in a.sets.split(","):
            r = agreement(binary, a.work, name, MATERIALS[name], SETS[key], a.rays, key == "3short")
            print(f"{name} at theta_i {SETS[key]} ({a.rays} trees):")
            for k, v in r.items():
                unit = " s" if k == "seconds" else ""
                print(f"  {name}_{key}_{k}: {v:.3f}{unit}")
            sys.stdout.flush()


if __name__ == "__main__":
    main()
