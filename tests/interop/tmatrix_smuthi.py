#!/usr/bin/env python3
"""A reference for dependent scattering beyond the Percus-Yevick formula (issue 50): the
coherent attenuation of light in random packings of TiO2-like spheres, from SMUTHI's
multiple-sphere T-matrix solution (Egel et al. 2021, JQSRT 273, 107846), which keeps every
near- and far-field interaction between the spheres.

The method, in our words (docs/physics.md, "Dependent scattering: the T-matrix check"):
  1. Pack N hard spheres (radius 100 nm, n = 2.6, in a host of n = 1.5) in a ball at the
     nominal volume fraction: random sequential addition, then Metropolis sweeps of
     hard-core displacements, so the packing is the equilibrium hard-sphere fluid whose
     structure factor Percus-Yevick approximates.
  2. Solve the multiple-scattering problem at 550 nm under a plane wave (SMUTHI, l_max 4)
     and take the scattered field's amplitudes S1, S2 at 0-24 deg.
  3. Average the complex amplitudes over independent packings: the mean (coherent) field.
     It is the field a homogeneous sphere of an effective complex index scatters (the
     Foldy-Lax mean field); fitting Mie's S1, S2 (miepython) for that index and the
     sphere's radius gives the coherent attenuation mu = 4 pi kappa_eff n_host / lambda
     and the packing's effective volume fraction N (a / R)^3. Jackknife over packings gives
     the standard errors.
  4. In the dilute limit this mu is N sigma_ext / V (Foldy 1945): the 1 % case checks it.

The per-packing amplitudes are mapped onto Bohren & Huffman's S1, S2 (miepython's
convention) by one constant measured on a single sphere: SMUTHI's plane-wave amplitude g
gives S = c cos(theta) conj(g), constant to 1e-4 over angle and sphere (checked in
calibrate()).

SMUTHI needs gfortran and an older NumPy to build (the stored result in
tests/reference/tmatrix-dependent.json is what this script wrote; tests/particle_media.rs
reads it):
    apt-get install -y gfortran
    python3 -m venv /tmp/smv && . /tmp/smv/bin/activate
    pip install numpy==1.24.4 "setuptools<65" wheel "cython<3" scipy==1.11.4 sympy miepython
    pip download --no-deps --no-binary :all: smuthi==2.2.4 && tar xf smuthi-2.2.4.tar.gz
    cd smuthi-2.2.4 && cython -3 smuthi/utility/cython/cython_speedups.pyx \
      && pip install --no-build-isolation .
Then (about 30 minutes on two cores):
    python tests/interop/tmatrix_smuthi.py tests/reference/tmatrix-dependent.json
"""
import json
import os
import sys
import time

import numpy as np
import miepython as mp
from scipy.optimize import least_squares
import smuthi.initial_field as init
import smuthi.layers as lay
import smuthi.particles as part
import smuthi.postprocessing.scattered_field as sf
import smuthi.simulation as sim

A_NM, N_PARTICLE, N_HOST, WAVELENGTH_NM = 100.0, 2.6, 1.5, 550.0
THETA_DEG = np.arange(0.0, 25.0, 2.0)
# (nominal volume fraction, spheres per packing): the clusters are a few optical depths
# across, so the coherent field still carries their attenuation
# (0.3, 60 spheres cannot be placed: the small ball of centres jams.)
CASES = [(0.01, 60), (0.05, 150), (0.1, 100), (0.2, 100), (0.3, 100),
         (0.05, 60), (0.1, 60), (0.2, 60)]
PACKINGS, SWEEPS, LMAX = 16, 100, 4


def packing(n, a, rc, rng, sweeps):
    """n hard spheres (radius a) with centres in a ball of radius rc - a: random sequential
    addition, then `sweeps` Metropolis sweeps of hard-core displacements (equilibrium)."""
    rin = rc - a
    pos = np.empty((0, 3))
    tries = 0
    while len(pos) < n:
        tries += 1
        if tries > 2_000_000:
            raise SystemExit(f"could not place {n} spheres")
        p = rng.uniform(-rin, rin, 3)
        if p @ p > rin * rin:
            continue
        if len(pos) and np.min(np.sum((pos - p) ** 2, axis=1)) < (2 * a) ** 2:
            continue
        pos = np.vstack([pos, p])
    step = 0.5 * a
    for _ in range(sweeps):
        acc = 0
        for i in rng.permutation(n):
            p = pos[i] + rng.uniform(-step, step, 3)
            if p @ p > rin * rin:
                continue
            d2 = np.sum((pos - p) ** 2, axis=1)
            d2[i] = np.inf
            if np.min(d2) < (2 * a) ** 2:
                continue
            pos[i] = p
            acc += 1
        step *= 1.1 if acc > 0.4 * n else 0.9
    return pos


def amplitudes(parts, lmax_check=None):
    """The scattered field's plane-wave amplitudes at THETA_DEG under a normally incident
    plane wave (SMUTHI polarization 0): TE in the x-z plane (S1) and TM in the y-z plane
    (S2), as cos(theta) conj(g) (SMUTHI's time convention is the conjugate of miepython's;
    cos(theta) is the plane-wave Jacobian)."""
    ls = lay.LayerSystem(thicknesses=[0, 0], refractive_indices=[N_HOST, N_HOST])
    pw = init.PlaneWave(vacuum_wavelength=WAVELENGTH_NM, polar_angle=0.0, azimuthal_angle=0.0,
                        polarization=0, reference_point=[0, 0, 0])
    s = sim.Simulation(layer_system=ls, particle_list=parts, initial_field=pw, log_to_terminal=False,
                       solver_type='gmres', solver_tolerance=1e-7, store_coupling_matrix=True)
    s.run()
    k = 2 * np.pi * N_HOST / WAVELENGTH_NM
    th = np.radians(THETA_DEG)
    pwe, _ = sf.scattered_field_pwe(WAVELENGTH_NM, parts, ls, 1, k_parallel=k * np.sin(th),
                                    azimuthal_angles=np.array([0.0, np.pi / 2]),
                                    include_direct=True, include_layer_response=True)
    return np.concatenate([np.cos(th) * np.conj(pwe.coefficients[0, :, 0]),
                           np.cos(th) * np.conj(pwe.coefficients[1, :, 1])])


def mie12(m, x):
    s1, s2 = mp.S1_S2(m, x, np.cos(np.radians(THETA_DEG)), norm='wiscombe')
    return np.concatenate([s1, s2])


def calibrate(lmax):
    """The constant c with S = c cos(theta) conj(g): one sphere against Mie, checked on a
    second, larger one at every angle."""
    k = 2 * np.pi * N_HOST / WAVELENGTH_NM
    cs = []
    for r, n, l in ((A_NM, N_PARTICLE, lmax), (300.0, 2.0, 8)):
        g = amplitudes([part.Sphere(position=[0, 0, 0], refractive_index=n, radius=r, l_max=l)])
        cs.append(mie12(n / N_HOST, k * r) / g)
    c = cs[0][0]
    spread = max(np.max(np.abs(x / c - 1)) for x in cs)
    if spread > 1e-3:
        raise SystemExit(f"amplitude calibration varies by {spread:.1e} over angle and sphere")
    return c


def fit(mean, se, r0):
    """Effective index n - i kappa (relative to the host) and radius of the homogeneous
    sphere whose Mie S1, S2 are the mean amplitudes, by weighted least squares."""
    k = 2 * np.pi * N_HOST / WAVELENGTH_NM

    def res(p):
        z = (mie12(complex(p[0], -p[1]), k * p[2]) - mean) / se
        return np.concatenate([z.real, z.imag])
    best = None
    for kap in (0.005, 0.02, 0.05):
        for n in (1.05, 1.15, 1.3):
            for r in (r0 - 50, r0):
                sol = least_squares(res, [n, kap, r], bounds=([1.0, 0.0, 0.5 * r0], [2.0, 0.5, 1.5 * r0]),
                                    x_scale=[0.05, 0.01, 20])
                if best is None or sol.cost < best.cost:
                    best = sol
    return best


def case(f, n, c, seed):
    rc = A_NM * (n / f) ** (1 / 3)
    rng = np.random.default_rng(seed)
    amps = []
    for k in range(PACKINGS):
        t = time.time()
        pos = packing(n, A_NM, rc, rng, SWEEPS)
        parts = [part.Sphere(position=list(p), refractive_index=N_PARTICLE, radius=A_NM, l_max=LMAX) for p in pos]
        amps.append(c * amplitudes(parts))
        print(f"  f {f} N {n} packing {k + 1}/{PACKINGS} ({time.time() - t:.1f} s)", file=sys.stderr)
    S = np.array(amps)
    K = len(S)
    se = np.maximum(np.abs(S.std(0, ddof=1)) / np.sqrt(K), 1e-3 * np.abs(S.mean(0)).max())
    r0 = rc - A_NM / 2

    def summary(mean):
        sol = fit(mean, se, r0)
        nr, kap, r = sol.x
        mu = 4 * np.pi * N_HOST * kap / WAVELENGTH_NM * 1e3  # 1/um
        return np.array([mu, r, nr * N_HOST, n * (A_NM / r) ** 3]), 2 * sol.cost / (2 * len(mean) - 3)
    v, chi2 = summary(S.mean(0))
    jk = np.array([summary(np.delete(S, i, 0).mean(0))[0] for i in range(K)])
    sev = np.sqrt((K - 1) / K * np.sum((jk - jk.mean(0)) ** 2, 0))
    row = dict(nominal_fraction=f, spheres=n, packings=K, container_radius_nm=rc,
               mu_coherent_per_um=v[0], mu_se=sev[0], radius_nm=v[1], radius_se=sev[1],
               n_effective=v[2], n_effective_se=sev[2], volume_fraction=v[3], volume_fraction_se=sev[3],
               chi2_per_dof=chi2)
    print(json.dumps(row), file=sys.stderr)
    return row


def write(path, rows):
    out = dict(source="tests/interop/tmatrix_smuthi.py (SMUTHI 2.2.4 multiple-sphere T-matrix, miepython fit)",
               sphere_radius_nm=A_NM, n_sphere=N_PARTICLE, n_host=N_HOST, wavelength_nm=WAVELENGTH_NM,
               lmax=LMAX, sweeps=SWEEPS, packings=PACKINGS, theta_deg=THETA_DEG.tolist(), cases=rows)
    tmp = path + ".tmp"
    with open(tmp, "w") as fh:
        json.dump(out, fh, indent=1)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)


def main():
    if len(sys.argv) != 2:
        raise SystemExit("usage: tmatrix_smuthi.py OUT.json")
    # Written after every case, and the cases already in OUT are kept: a stopped run resumes.
    rows = json.load(open(sys.argv[1]))["cases"] if os.path.exists(sys.argv[1]) else []
    done = {(r["nominal_fraction"], r["spheres"]) for r in rows}
    c = calibrate(LMAX)
    for f, n in CASES:
        if (f, n) not in done:
            rows.append(case(f, n, c, seed=1))
            write(sys.argv[1], rows)


if __name__ == "__main__":
    main()
