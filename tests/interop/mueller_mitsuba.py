"""Polarimetric BRDFs in Mitsuba 3 (issue 51): goniospec's Mueller matrices exported as
Mitsuba's measured_polarized tensor file (.pbsdf), loaded by its plugin in the
scalar_spectral_polarized variant, checked and rendered with the Stokes integrator.

1. Flat gold: the plugin's matrix near the specular direction, normalised by m00, against
   Mitsuba's own smooth `conductor` (its Fresnel Mueller matrix, an independent
   implementation) at the same directions, every element, in Mitsuba's Stokes bases.
2. Rough gold: the plugin's matrix against goniospec's own (`eval --mueller`, turned to
   Mitsuba's bases with its `rotate_mueller_basis`, S3 of its sign) at simulated incident
   angles, where the lobe holds: what the export's grid and interpolation keep (a
   resolution figure, printed; bounded loosely).
3. A render of a rough gold plane under a directional light with the `stokes` integrator:
   finite, lit, and every pixel's Stokes vector physical (|S1,S2,S3| <= S0).

    python tests/interop/mueller_mitsuba.py GONIOSPEC_BINARY WORKDIR
"""

import csv
import io
import os
import subprocess
import sys

import numpy as np
import mitsuba as mi

mi.set_variant("scalar_spectral_polarized")

BIN, WORK = sys.argv[1], sys.argv[2]
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
os.makedirs(WORK, exist_ok=True)


def run(*args):
    out = subprocess.run([BIN, *args], capture_output=True, text=True, cwd=ROOT)
    if out.returncode != 0:
        sys.exit(f"goniospec {' '.join(args)}: {out.stderr}")
    return out.stdout


def matrix(spec, k=0):
    """A Mitsuba MuellerMatrix spectrum's 4 x 4 at wavelength sample k."""
    return np.array([[spec[i, j][k] for j in range(4)] for i in range(4)])


def interaction(wi):
    si = mi.SurfaceInteraction3f()
    si.p = [0, 0, 0]
    si.n = [0, 0, 1]
    si.sh_frame = mi.Frame3f(si.n)
    si.wi = wi
    si.wavelengths = [550, 550, 550, 550]
    return si


def sph(theta_deg, phi_deg):
    t, p = np.radians(theta_deg), np.radians(phi_deg)
    return [np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)]


def our_frame_x(w):
    """goniospec's Stokes x axis (p) of a direction w: s = w x z normalised, p = s x w."""
    w = np.asarray(w, float)
    s = np.cross(w, [0, 0, 1])
    s /= np.linalg.norm(s)
    return np.cross(s, w)


def ours_in_mitsuba_bases(m, light, view):
    """goniospec's matrix for light from `light` seen from `view` (its frames) in Mitsuba's
    implicit Stokes bases, S3 of Mitsuba's sign."""
    win, wout = -np.asarray(light, float), np.asarray(view, float)
    r = mi.mueller.rotate_mueller_basis(mi.Matrix4f(m.tolist()), win, our_frame_x(win),
                                        mi.mueller.stokes_basis(win), wout, our_frame_x(wout),
                                        mi.mueller.stokes_basis(wout))
    r = np.array([[r[i, j] for j in range(4)] for i in range(4)])
    flip = np.diag([1.0, 1.0, 1.0, -1.0])
    return flip @ r @ flip


def flat_gold():
    sample = os.path.join(WORK, "flat-gold.toml")
    with open(sample, "w") as f:
        f.write('[sample]\nname = "flat gold"\nunit = "nm"\ntile = [1000.0, 1000.0]\n'
                '[media.air]\nn = 1.0\n[media.gold]\nn = 0.43\nk = 2.455\n'
                '[stack]\nmode = "mesh"\nambient = "air"\nlayers = []\nsubstrate = "gold"\n')
    gsa, pbsdf = os.path.join(WORK, "flat.gsa"), os.path.join(WORK, "flat.pbsdf")
    # Mirror directions at the centres of 2-degree buckets and on the 5-degree grid of
    # theta_d, so that the grid points around them hold this very matrix.
    run("simulate", sample, "--theta-i", "35,45,55", "--wavelengths", "440:660:20", "--rays",
        "16", "--mueller", "--coherence", "beamlet", "-o", gsa)
    run("export", gsa, "--format", "pbsdf", "-o", pbsdf)
    plugin = mi.load_dict({"type": "measured_polarized", "filename": pbsdf})
    conductor = mi.load_dict({"type": "conductor", "eta": 0.43, "k": 2.455})
    ctx = mi.BSDFContext()
    worst = 0.0
    for theta in [35.0, 45.0, 55.0]:
        # Mitsuba's mirror seen at theta; the plugin's matrix with the light 0.2 deg off the
        # mirror direction (its angles are undefined on it), in the simulated bucket.
        si = interaction(sph(theta, 180.0))
        _, w = conductor.sample(ctx, si, 0.5, [0.5, 0.5])
        want = matrix(w)
        want /= want[0, 0]
        got = matrix(plugin.eval(ctx, si, sph(theta + 0.2, 0.0)))
        assert got[0, 0] > 0, f"flat gold at {theta} deg: the plugin sees nothing"
        got /= got[0, 0]
        worst = max(worst, np.abs(got - want).max())
        assert np.allclose(got, want, atol=2e-3), f"flat gold at {theta} deg:\n{got}\nagainst Mitsuba's conductor\n{want}"
    print(f"mueller_flat_gold_worst_element: {worst:.2e}")


def rough_gold():
    gsa, pbsdf = os.path.join(WORK, "gold.gsa"), os.path.join(WORK, "gold.pbsdf")
    run("simulate", "meshes/rough-gold.toml", "--theta-i", "0,15,30,45,60,75", "--wavelengths",
        "440:660:20", "--rays", "16384", "--mueller", "--coherence", "beamlet", "-o", gsa)
    run("export", gsa, "--format", "pbsdf", "-o", pbsdf)
    plugin = mi.load_dict({"type": "measured_polarized", "filename": pbsdf, "alpha_sample": 0.2})
    ctx = mi.BSDFContext()
    rows, worst_norm, worst_m00 = 0, 0.0, 0.0
    for theta_i in [15.0, 30.0, 45.0]:
        light = sph(theta_i, 0.0)
        # Bucket centres (2 x 10 deg) around the specular direction.
        for theta_o, phi_o in [(theta_i + 1, 185), (theta_i - 3, 175), (theta_i + 5, 195),
                               (theta_i + 1, 205)]:
            view = sph(theta_o, phi_o)
            out = run("eval", gsa, "--mueller", "--theta-i", str(theta_i), "--theta-o",
                      str(theta_o), "--phi-o", str(phi_o))
            row = next(r for r in csv.DictReader(io.StringIO(out)) if r["lambda_nm"] == "550")
            m = np.array([[float(row[f"m{a}{b}"]) for b in range(4)] for a in range(4)])
            want = ours_in_mitsuba_bases(m, light, view)
            si = interaction(view)
            got = matrix(plugin.eval(ctx, si, light)) / np.cos(np.radians(theta_i))
            rel = abs(got[0, 0] / want[0, 0] - 1)
            dn = np.abs(got / got[0, 0] - want / want[0, 0]).max()
            worst_m00, worst_norm = max(worst_m00, rel), max(worst_norm, dn)
            rows += 1
            # What the export's resolution allows: the buckets (2 x 10 deg, constant within)
            # sampled on 5-degree cells of theta_d and phi_d, which the plugin interpolates
            # linearly across the buckets' steps, against the bucket's own value (measured
            # at most 0.21 of m00 on the lobe's flank at 45 deg, and 0.10 of a normalised
            # element near the pole, where the s/p frames turn fastest). Frames or S3 of
            # the wrong sign put off-diagonal elements 0.5-1 off; flat gold above checks
            # the conventions to float precision.
            assert rel < 0.3, f"theta_i {theta_i}, ({theta_o}, {phi_o}): m00 {got[0, 0]} against {want[0, 0]}"
            assert dn < 0.15, f"theta_i {theta_i}, ({theta_o}, {phi_o}):\n{got / got[0, 0]}\nagainst\n{want / want[0, 0]}"
    print(f"mueller_rough_gold_directions: {rows}")
    print(f"mueller_rough_gold_worst_m00_relative: {worst_m00:.3f}")
    print(f"mueller_rough_gold_worst_normalised_element: {worst_norm:.3f}")
    return pbsdf


def render(pbsdf):
    scene = mi.load_dict({
        "type": "scene",
        "integrator": {"type": "stokes", "integrator": {"type": "direct"}},
        "sensor": {
            "type": "perspective", "fov": 30,
            "to_world": mi.ScalarTransform4f().look_at(origin=[0, -2.5, 2.5], target=[0, 0, 0],
                                                       up=[0, 0, 1]),
            "film": {"type": "hdrfilm", "width": 24, "height": 24, "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": 16},
        },
        "plane": {"type": "rectangle", "bsdf": {"type": "measured_polarized", "filename": pbsdf,
                                                "alpha_sample": 0.2}},
        "light": {"type": "directional", "direction": [0, -1, -1], "irradiance": 1.0},
    })
    img = np.array(mi.render(scene))
    # The Stokes integrator's channels: the colour, then S0..S3 (each as RGB).
    s = img[..., 3:].reshape(img.shape[0], img.shape[1], 4, 3).mean(axis=3)
    assert np.all(np.isfinite(s)), "the render holds non-finite values"
    assert s[..., 0].mean() > 0, "the rough gold plane is dark"
    lin = np.sqrt((s[..., 1:] ** 2).sum(axis=2))
    dop = lin.sum() / s[..., 0].sum()
    assert np.all(lin <= s[..., 0] * 1.05 + 1e-6), "a pixel is more than fully polarised"
    print(f"mueller_render_mean_s0: {s[..., 0].mean():.4f}")
    print(f"mueller_render_degree_of_polarisation: {dop:.3f}")


flat_gold()
render(rough_gold())
print("mueller_mitsuba: ok")
