"""goniospec's Python API against its CLI and an independent transfer-matrix model."""

import csv
import io
import os
import subprocess

import numpy as np
import pytest

import goniospec as gs

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
CLI = os.environ["GONIOSPEC_BIN"]


def cli(*args):
    out = subprocess.run([CLI, *args], capture_output=True, text=True, cwd=ROOT, check=True)
    return list(csv.DictReader(io.StringIO(out.stdout)))


def mesh(name):
    return os.path.join(ROOT, "meshes", name)


def test_reflectance_is_the_clis(tmp_path):
    s = gs.Sample.load(mesh("rough-gold.toml"))
    acc = gs.simulate(s, theta_i_deg=[0, 30], wavelengths="400:700:50", rays=256, seed=3)
    gsa = tmp_path / "gold.gsa"
    subprocess.run([CLI, "simulate", mesh("rough-gold.toml"), "--theta-i", "0,30", "--wavelengths",
                    "400:700:50", "--rays", "256", "--seed", "3", "-o", str(gsa)], check=True, cwd=ROOT,
                   capture_output=True)
    acc.save(tmp_path / "py.gsa")
    assert (tmp_path / "py.gsa").read_bytes() == gsa.read_bytes()
    r = acc.reflectance(30)
    rows = cli("reflectance", str(gsa), "--theta-i", "30")
    assert list(r["lambda_nm"]) == [float(x["lambda_nm"]) for x in rows]
    for key in ["R", "T", "absorbed"]:
        # The CLI prints 8 decimals.
        assert np.all(np.abs(r[key] - [float(x[key]) for x in rows]) <= 5e-9), key


def test_every_simulate_flag_is_a_keyword(tmp_path):
    s = gs.Sample.load(mesh("rough-gold.toml"))
    kw = dict(theta_o_bins=30, phi_o_bins=24, max_depth=32, max_segments=5000, cutoff=1e-8,
              backend="obvhs", phi_i=15.0, tolerance=0.2, max_rays=512, no_path_sharing=True,
              no_wavelength_sharing=True)
    acc = gs.simulate(s, theta_i=[20], wavelengths="400:700:100", rays=128, progress=True, **kw)
    acc.save(tmp_path / "py.gsa")
    flags = []
    for k, v in kw.items():
        flag = "--" + k.replace("_", "-")
        flags += [flag] if v is True else [flag, str(v)]
    subprocess.run([CLI, "simulate", mesh("rough-gold.toml"), "--theta-i", "20", "--wavelengths",
                    "400:700:100", "--rays", "128", *flags, "-o", str(tmp_path / "cli.gsa")],
                   check=True, cwd=ROOT, capture_output=True)
    assert (tmp_path / "py.gsa").read_bytes() == (tmp_path / "cli.gsa").read_bytes()


def test_mueller_matrices_are_the_clis_and_flat_gold_is_fresnels(tmp_path):
    s = gs.Sample.load(mesh("rough-gold.toml"))
    acc = gs.simulate(s, theta_i_deg=[30], wavelengths="500:600:50", rays=64, mueller=True,
                      coherence="beamlet")
    gsa = tmp_path / "gold.gsa"
    acc.save(gsa)
    m = acc.mueller(30, 30)
    assert m["M"].shape == (2, 4, 4) and m["M_stderr"].shape == (2, 4, 4)
    rows = cli("eval", str(gsa), "--mueller", "--theta-i", "30", "--theta-o", "30")
    for j, row in enumerate(rows):
        for a in range(4):
            for b in range(4):
                want = float(row[f"m{a}{b}"])
                assert abs(m["M"][j, a, b] - want) <= 1e-8 * abs(m["M"][j, 0, 0]), (a, b)
    # The buckets as an archive numpy reads: theta_o 31 deg and phi_o 185 deg lie in the
    # bucket (15, 18) of 2 x 10 deg.
    npz = tmp_path / "gold.npz"
    subprocess.run([CLI, "export", str(gsa), "--format", "npz", "-o", str(npz)], check=True,
                   cwd=ROOT, capture_output=True)
    z = np.load(npz)
    assert z["mueller"].shape == (1, 1, 45, 36, 2, 4, 4)
    assert np.array_equal(z["mueller"][0, 0, 15, 18], acc.mueller(30, 31, 185)["M"])
    assert np.array_equal(z["brdf"][0, 0, 15, 18], acc.mueller(30, 31, 185)["M"][:, 0, 0])
    # Flat gold's specular matrix against the Fresnel coefficients (numpy, written here):
    # J = diag(r_p of the transverse H, r_s); m00 = (|rp|^2 + |rs|^2) / 2, m22 = Re(rp rs*).
    flat = tmp_path / "flat.toml"
    flat.write_text('[sample]\nname = "flat gold"\nunit = "nm"\ntile = [1000.0, 1000.0]\n'
                    '[media.air]\nn = 1.0\n[media.gold]\nn = 0.43\nk = 2.455\n'
                    '[stack]\nmode = "mesh"\nambient = "air"\nlayers = []\nsubstrate = "gold"\n')
    # One degree per polar bucket, one azimuth sector: the specular exit at 44.5 deg lies
    # inside the bucket [44, 45] deg.
    acc = gs.simulate(gs.Sample.load(str(flat)), theta_i_deg=[44.5], wavelengths="549:551:2",
                      rays=4, mueller=True, coherence="beamlet", theta_o_bins=90, phi_o_bins=1)
    n2, t = 0.43 + 2.455j, np.radians(44.5)
    ct = np.sqrt(1 - (np.sin(t) / n2) ** 2)
    rs = (np.cos(t) - n2 * ct) / (np.cos(t) + n2 * ct)
    rp = (n2 * np.cos(t) - ct) / (n2 * np.cos(t) + ct)
    m = acc.mueller(44.5, 44.5)
    omega = 0.5 * (2 * np.pi) * (np.sin(np.radians(45)) ** 2 - np.sin(np.radians(44)) ** 2)
    got = m["M"][0] * omega
    assert abs(got[0, 0] - 0.5 * (abs(rp) ** 2 + abs(rs) ** 2)) < 1e-12
    assert abs(got[0, 1] - 0.5 * (abs(rp) ** 2 - abs(rs) ** 2)) < 1e-12
    assert abs(got[2, 2] - (rp * np.conj(rs)).real) < 1e-12
    assert abs(got[2, 3] - (rp * np.conj(rs)).imag) < 1e-12
    assert abs(m["dop"][0] - abs(got[1, 0]) / got[0, 0]) < 1e-12
    # Polarised light in: R for s and p light are Fresnel's |r_s|^2 and |r_p|^2.
    assert abs(acc.reflectance(44.5, incident="s")["R"][0] - abs(rs) ** 2) < 1e-12
    assert abs(acc.reflectance(44.5, incident="p")["R"][0] - abs(rp) ** 2) < 1e-12
    with pytest.raises(ValueError, match="polarisation state"):
        acc.reflectance(44.5, incident="sideways")
    with pytest.raises(ValueError, match="mueller"):
        gs.simulate(s, theta_i_deg=[30], wavelengths="500:600:50", rays=8).mueller(30, 30)


def test_target_stderr_is_a_keyword_and_the_cli_flag(tmp_path):
    # Issue 49: the adaptive budget by the BRDF's quality, the same bytes as the CLI's.
    s = gs.Sample.load(mesh("rough-gold.toml"))
    acc = gs.simulate(s, theta_i_deg=[20], wavelengths="400:700:100", rays=128, target_stderr=0.3,
                      max_rays=4096)
    acc.save(tmp_path / "py.gsa")
    subprocess.run([CLI, "simulate", mesh("rough-gold.toml"), "--theta-i", "20", "--wavelengths",
                    "400:700:100", "--rays", "128", "--target-stderr", "0.3", "--max-rays", "4096",
                    "-o", str(tmp_path / "cli.gsa")], check=True, cwd=ROOT, capture_output=True)
    assert (tmp_path / "py.gsa").read_bytes() == (tmp_path / "cli.gsa").read_bytes()
    with pytest.raises(ValueError, match="target"):
        gs.simulate(s, theta_i_deg=[20], rays=16, target_stderr=0.3, tolerance=0.3)


def test_eval_matches_cli_and_vectorises(tmp_path):
    s = gs.Sample.load(mesh("rough-gold.toml"))
    brdf = gs.simulate(s, theta_i_deg=[0, 30, 60], wavelengths="400:700:50", rays=256).build("table")
    brdf.save(tmp_path / "g.gsb")
    ti = np.array([10.0, 30.0, 50.0])
    to = np.array([20.0, 35.0, 60.0])
    po = np.array([180.0, 170.0, 90.0])
    v = brdf.eval(ti, 0.0, to, po)
    assert v.shape == (3, len(brdf.lambda_nm))
    for k in range(3):
        assert np.array_equal(v[k], brdf.eval(ti[k], 0, to[k], po[k]))
        rows = cli("eval", str(tmp_path / "g.gsb"), "--theta-i", str(ti[k]), "--theta-o", str(to[k]),
                   "--phi-o", str(po[k]))
        # The CLI prints 9 significant digits.
        assert np.allclose(v[k], [float(x["brdf"]) for x in rows], rtol=1e-8, atol=0)
    grid = brdf.eval(30, 0, np.linspace(0, 80, 12).reshape(3, 4), 180)
    assert grid.shape == (3, 4, len(brdf.lambda_nm))


def tmm_reference(n, d, lam, theta_deg):
    """The flat film with the PyPI tmm package (Byrnes), unpolarised R."""
    tmm = pytest.importorskip("tmm")
    th = np.radians(theta_deg)
    rs = tmm.coh_tmm("s", n, d, th, lam)["R"]
    rp = tmm.coh_tmm("p", n, d, th, lam)["R"]
    return 0.5 * (rs + rp)


def test_flat_soap_film_matches_the_tmm_package():
    s = gs.Sample.load(mesh("flat-soap-film.toml"))
    a = gs.analytic(s, 30, wavelengths="450,550,650", monochromatic=True)
    # meshes/flat-soap-film.toml: 600 nm of index 1.33 between air.
    for lam, r in zip(a["lambda_nm"], a["R"]):
        want = tmm_reference([1.0, 1.33, 1.0], [np.inf, 600.0, np.inf], lam, 30)
        assert abs(r - want) < 1e-12, (lam, r, want)
    acc = gs.simulate(s, theta_i_deg=[30], wavelengths="450,550,650", monochromatic=True, rays=64,
                      coherence_radius_nm=float("inf"))
    sim = acc.reflectance(30)["R"]
    # The plane-wave limit equals the TMM up to the power dropped below the cutoff (1e-10).
    assert np.allclose(sim, a["R"], rtol=0, atol=1e-6)
    # The reflected p-s phase difference against the tmm package's amplitudes (Byrnes's
    # convention, the transfer matrix's own: r_p of the transverse H field).
    import tmm
    for lam, delta in zip(a["lambda_nm"], a["delta_deg"]):
        rs = tmm.coh_tmm("s", [1.0, 1.33, 1.0], [np.inf, 600.0, np.inf], np.radians(30), lam)["r"]
        rp = tmm.coh_tmm("p", [1.0, 1.33, 1.0], [np.inf, 600.0, np.inf], np.radians(30), lam)["r"]
        assert abs(delta - np.degrees(np.angle(rp * np.conj(rs)))) < 1e-9, (lam, delta)


def test_errors_are_exceptions_with_the_clis_messages(tmp_path):
    with pytest.raises(ValueError, match="nowhere.toml"):
        gs.Sample.load("nowhere.toml")
    s = gs.Sample.load(mesh("rough-gold.toml"))
    with pytest.raises(ValueError, match="coherence"):
        gs.simulate(s, theta_i_deg=[0], coherence="laser")
    with pytest.raises(ValueError, match="wavelength"):
        gs.simulate(s, theta_i_deg=[0], wavelengths="700:400:10")
    for bad in [dict(rays=0), dict(theta_i_deg=[95]), dict(phi_i_deg=float("inf")), dict(cutoff=float("nan")),
                dict(coherence_radius_nm=-1.0), dict(tolerance=-1.0), dict(theta_o_bins=0),
                dict(max_depth=0), dict(threads=100000), dict(coherence_radius_nm=float("nan")),
                dict(colour=1), dict(seed="one")]:
        kw = dict(theta_i_deg=[0], rays=16, wavelengths="500:600:50")
        kw.update(bad)
        with pytest.raises(ValueError):
            gs.simulate(s, **kw)
    acc = gs.simulate(s, theta_i_deg=[0], wavelengths="400:700:100", rays=16)
    with pytest.raises(ValueError, match="no incident angle 45"):
        acc.reflectance(45)
    with pytest.raises(ValueError, match="unknown representation"):
        acc.build("cube")
    brdf = acc.build()
    with pytest.raises(ValueError, match="needs sample"):
        brdf.export("x.bsdf", format="rgl")
    for n in [0, 1, 16, 10_000]:
        with pytest.raises(ValueError, match="resolution must be odd"):
            brdf.export(str(tmp_path / "x.bsdf"), format="rgl", sample=s, resolution=n)
    assert not any(tmp_path.iterdir())
    with pytest.raises(ValueError, match="polar angles"):
        brdf.eval(95, 0, 10, 0)
    with pytest.raises(ValueError, match="broadcast together"):
        brdf.eval([1, 2], 0, [1, 2, 3], 0)
    # Issue 47: shapes NumPy refuses to broadcast are refused, though their sizes match; a
    # row against a column broadcasts as NumPy does.
    with pytest.raises(ValueError, match="broadcast together"):
        brdf.eval(np.full((2, 3), 30.0), 0, np.full((3, 2), 30.0), 0)
    outer = brdf.eval(np.array([[10.0], [40.0]]), 0, np.array([20.0, 30.0, 50.0]), 180)
    assert outer.shape == (2, 3, len(brdf.lambda_nm))
    assert np.array_equal(outer[1, 2], brdf.eval(40.0, 0, 50.0, 180))
    # Issue 30: None names itself (it read "got NaN"); a broadcast view of 10^11 angles is a
    # MemoryError (it aborted the interpreter).
    with pytest.raises(TypeError, match="phi_o_deg is None"):
        brdf.eval(30, 0, 30, None)
    with pytest.raises(MemoryError, match="evaluate in chunks"):
        brdf.eval(np.broadcast_to(30.0, (10**6, 10**5)), 0, 30, 0)


def test_ctrl_c_interrupts_a_long_run_and_returns_nothing(tmp_path):
    import signal
    import threading
    import time

    # Python installs its KeyboardInterrupt handler only where SIGINT was not ignored when it
    # started (a job started in the background of a non-interactive shell inherits it
    # ignored): installed here, the test does not depend on how it was launched.
    signal.signal(signal.SIGINT, signal.default_int_handler)
    s = gs.Sample.load(mesh("rough-gold.toml"))
    out = tmp_path / "never.gsa"
    timer = threading.Timer(0.3, lambda: os.kill(os.getpid(), signal.SIGINT))
    t0 = time.monotonic()
    timer.start()
    with pytest.raises(KeyboardInterrupt):
        # About a minute of work uninterrupted.
        acc = gs.simulate(s, theta_i_deg=[0, 30, 60], rays=3_000_000)
        acc.save(out)
    timer.cancel()
    assert time.monotonic() - t0 < 10
    assert not out.exists()
    assert not any(tmp_path.iterdir())


def test_outputs_never_replace_inputs_or_foreign_files(tmp_path):
    """Issue 30: save and export follow the CLI's output policy. They overwrote the sample
    or the file an object came from."""
    import shutil
    shutil.copytree(os.path.join(ROOT, "meshes"), tmp_path / "m")
    sample_toml = tmp_path / "m" / "flat-soap-film.toml"
    original = sample_toml.read_bytes()
    s = gs.Sample.load(str(sample_toml))
    acc = gs.simulate(s, theta_i_deg=[30], wavelengths="500", monochromatic=True, rays=4)
    with pytest.raises(FileExistsError, match="is the input"):
        acc.save(sample_toml, force=True)
    assert sample_toml.read_bytes() == original
    acc.save(tmp_path / "a.gsa")
    loaded = gs.load(str(tmp_path / "a.gsa"))
    with pytest.raises(FileExistsError, match="is the input"):
        loaded.save(tmp_path / "a.gsa")
    brdf = loaded.build("table")
    with pytest.raises(FileExistsError, match="is the input"):
        brdf.export(tmp_path / "a.gsa", format="npz", force=True)
    notes = tmp_path / "notes.txt"
    notes.write_text("mine\n")
    with pytest.raises(FileExistsError, match="--force"):
        brdf.save(notes)
    assert notes.read_text() == "mine\n"
    brdf.save(notes, force=True)
    assert notes.read_bytes()[:4] != b"mine"


def test_ctrl_c_is_prompt_on_trees_of_thousands_of_segments(tmp_path):
    """Issue 30: on a steep height map (trees of up to 20,000 segments) Ctrl-C took 20 s; the
    run now stops within a tree."""
    import signal
    import threading
    import time

    subprocess.run([CLI, "generate", "gaussian", "--tile", "20,20", "--unit", "um", "-p", "rms=3",
                    "-p", "correlation_length=0.5", "-p", "resolution=256", "-o",
                    str(tmp_path / "steep.obj")], check=True, capture_output=True)
    (tmp_path / "steep.toml").write_text(
        '[sample]\nname = "steep"\nunit = "um"\ntile = [20.0, 20.0]\n[media.air]\nn = 1.0\n'
        '[media.glass]\nn = 1.5\n[[interface]]\nmesh = "steep.obj"\nfront = "air"\nback = "glass"\n')
    s = gs.Sample.load(str(tmp_path / "steep.toml"))
    signal.signal(signal.SIGINT, signal.default_int_handler)  # as in the test above
    timer = threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT))
    timer.start()
    with pytest.raises(KeyboardInterrupt):
        t0 = time.monotonic()
        try:
            gs.simulate(s, theta_i_deg=[60], rays=1_000_000, max_segments=20000)
        finally:
            stopped = time.monotonic()
    timer.cancel()
    # From the signal (0.5 s after the start) to the return.
    assert stopped - t0 < 0.5 + 2.0, stopped - t0


def test_ctrl_c_stops_a_particle_medium_s_set_up(tmp_path):
    """Issue 50: Ctrl-C did not stop the Mie tabulation of a particle medium. Spheres of a
    wide distribution reaching 9 um (median 0.5 um, sigma 0.5) take tens of seconds to
    tabulate over 380-780 nm on two cores; the tabulation now asks between wavelengths."""
    import signal
    import threading
    import time

    (tmp_path / "big.toml").write_text(
        '[sample]\nname = "big"\nunit = "um"\ntile = [5.0, 5.0]\n[media.air]\nn = 1.0\n'
        '[media.pig]\nn = 2.6\n[media.paint]\nn = 1.5\nparticles = { medium = "pig", '
        'log_normal = { median_radius_nm = 500, sigma = 0.5 }, volume_fraction = 0.05 }\n'
        '[stack]\nambient = "air"\nlayers = [{ medium = "paint", thickness = 20.0 }]\n'
        'substrate = "air"\n')
    s = gs.Sample.load(str(tmp_path / "big.toml"))
    signal.signal(signal.SIGINT, signal.default_int_handler)  # as in the tests above
    timer = threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT))
    timer.start()
    t0 = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        try:
            gs.simulate(s, theta_i_deg=[0], rays=4)
        finally:
            stopped = time.monotonic()
    timer.cancel()
    assert stopped - t0 < 0.5 + 2.5, stopped - t0


def _run_child(code, terminal):
    """Runs `code` in a fresh interpreter, its stderr a pseudo-terminal or a pipe; returns
    what it wrote to stderr."""
    import pty
    import subprocess
    import sys

    if terminal:
        master, slave = pty.openpty()
        p = subprocess.Popen([sys.executable, "-c", code], stderr=slave, stdout=subprocess.DEVNULL,
                             cwd=ROOT)
        os.close(slave)
        chunks = []
        while True:
            try:
                data = os.read(master, 4096)
            except OSError:  # EIO: the child closed the terminal
                break
            if not data:
                break
            chunks.append(data)
        os.close(master)
        assert p.wait(timeout=120) == 0
        return b"".join(chunks).decode("utf-8", "replace")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, cwd=ROOT, timeout=120)
    assert p.returncode == 0, p.stderr
    return p.stderr.decode()


def test_progress_is_a_bar_on_a_terminal_and_nothing_in_a_pipe():
    """Issue 29: a bar on a terminal, nothing when stderr is not one, progress=False silences
    it and progress=True forces it."""
    run = ("import goniospec as gs; s = gs.Sample.load('meshes/rough-gold.toml'); "
           "gs.simulate(s, theta_i_deg=[0, 30], wavelengths='500:600:50', rays=512{})")
    tty = _run_child(run.format(""), terminal=True)
    assert "goniospec 100% |" in tty and "1024/1024 trees" in tty, tty
    assert "\u2588" * 24 in tty, tty
    assert _run_child(run.format(""), terminal=False) == ""
    assert _run_child(run.format(", progress=False"), terminal=True) == ""
    forced = _run_child(run.format(", progress=True"), terminal=False)
    assert "1024/1024 trees" in forced, forced


def test_backends_name_the_library_behind_each():
    b = {x["name"]: x for x in gs.backends()}
    assert b["obvhs"]["available"] and b["obvhs"]["version"]
    assert set(b) == {"embree", "obvhs"}
    if b["embree"]["available"]:
        # Debian 12 ships Embree 3.13.5; whatever the build found, a version is read from a
        # live device.
        assert b["embree"]["version"].count(".") == 2, b["embree"]


def test_validity_warnings_and_the_diffraction_method():
    """A 5 um grating: rays warn (UserWarning) that they miss its orders; the diffraction
    method does not, keeps R, and check() lists the warning beside the grating's scales."""
    s = gs.Sample.load(os.path.join(ROOT, "studies", "samples", "grating-5um.toml"))
    with pytest.warns(UserWarning, match="--coherence diffraction"):
        rays = gs.simulate(s, theta_i_deg=[0], wavelengths="550", monochromatic=True, rays=1024,
                           coherence="beamlet")
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        diff = gs.simulate(s, theta_i_deg=[0], wavelengths="550", monochromatic=True, rays=4096,
                           coherence="diffraction")
    # The diffraction method's R is the ray field's (at the same entry points it would be
    # the same bits; here the lattice and the R2 set differ by their sampling noise).
    # The warning lives with the result too (issue 48), and auto's choice is recorded.
    assert any("--coherence diffraction" in w for w in rays.warnings), rays.warnings
    auto = gs.simulate(s, theta_i_deg=[0], wavelengths="550", monochromatic=True, rays=1024)
    assert auto.methods == ["d"], auto.methods
    assert not any("--coherence" in w for w in auto.warnings), auto.warnings
    r_rays = rays.reflectance(0)["R"][0]
    r_diff = diff.reflectance(0)["R"][0]
    assert abs(r_diff - r_rays) < 2e-3, (r_diff, r_rays)
    # check() judges the default run (auto): it lists the method auto takes instead of
    # advising one.
    c = s.check()
    assert any("period 5000 nm" in f for f in c["facts"])
    assert any("auto" in f and "the diffraction method at 0 deg" in f for f in c["facts"]), c
    assert not any("--coherence diffraction" in w for w in c["warnings"]), c["warnings"]


def test_analytic_refuses_a_particle_layer():
    """Issue 50: the transfer-matrix reference of clear layers would give the white paint's
    clear binder; it refuses the stack and names the medium."""
    s = gs.Sample.load(mesh("paint-pigments.toml"))
    with pytest.raises(ValueError, match="medium 'paint' scatters in volume"):
        gs.analytic(s, 0, wavelengths="550", monochromatic=True)


def test_every_warning_the_run_keeps_is_a_user_warning():
    """Issue 48: what a run finds on its way (auto's note that the film's 75 deg cells
    needed the diffraction method where its tangent plane fails) is a UserWarning as the
    CLI prints it, and every warning stored with the result was given, each once."""
    import warnings

    s = gs.Sample.load(mesh("thin-film-600nm.toml"))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        acc = gs.simulate(s, theta_i_deg=[75], wavelengths="550", monochromatic=True, rays=64)
    given = [str(w.message) for w in caught if issubclass(w.category, UserWarning)]
    assert any("tangent plane" in g for g in given), given
    assert acc.warnings, "the run kept no warning"
    for w in acc.warnings:
        assert given.count(w) == 1, (w, given)


def test_one_name_for_one_thing_and_reprs_that_say_what_they_hold(tmp_path):
    """Issue 45: the wavelengths are `lambda_nm` in reflectance()'s dict, on Accumulator and
    Brdf, in the CLI's CSV and in the NPZ; angles are `*_deg`. The old names (`theta_i`,
    `phi_i`, `Brdf.wavelengths_nm`) still give the same results for a release; giving
    both is an error. Printed objects name what they hold."""
    s = gs.Sample.load(mesh("rough-gold.toml"))
    new = gs.simulate(s, theta_i_deg=[0, 30], phi_i_deg=10.0, wavelengths="400:700:100", rays=64)
    old = gs.simulate(s, theta_i=[0, 30], phi_i=10.0, wavelengths="400:700:100", rays=64)
    new.save(tmp_path / "new.gsa")
    old.save(tmp_path / "old.gsa")
    assert (tmp_path / "new.gsa").read_bytes() == (tmp_path / "old.gsa").read_bytes()
    with pytest.raises(ValueError, match="not both"):
        gs.simulate(s, theta_i_deg=[0], theta_i=[0], rays=16)
    with pytest.raises(ValueError, match="not both"):
        gs.simulate(s, theta_i_deg=[0], phi_i_deg=5.0, phi_i=5.0, rays=16)
    with pytest.raises(TypeError, match="theta_i_deg"):
        gs.simulate(s, rays=16)
    # The bin centres: 400-500 and 600-700 nm bins centred at 450, 550, 650 nm.
    assert list(new.lambda_nm) == [450.0, 550.0, 650.0]
    assert list(new.reflectance(30)["lambda_nm"]) == list(new.lambda_nm)
    assert new.theta_i_deg == [0.0, 30.0] and new.phi_i_deg == 10.0
    assert new.trees == [64, 64]
    brdf = new.build("table")
    assert list(brdf.lambda_nm) == list(new.lambda_nm)
    assert list(brdf.wavelengths_nm) == list(brdf.lambda_nm)
    assert brdf.theta_i_deg == [0.0, 30.0]
    brdf.export(tmp_path / "b.npz", format="npz")
    z = np.load(tmp_path / "b.npz")
    assert list(z["lambda_nm"]) == list(brdf.lambda_nm)
    assert np.allclose(z["theta_i_deg"], [0.0, 30.0], rtol=0, atol=1e-12)
    brdf.save(tmp_path / "b.gsb")
    rows = cli("eval", str(tmp_path / "b.gsb"), "--theta-i", "30", "--phi-i", "10", "--theta-o", "30",
               "--phi-o", "190")
    assert [float(r["lambda_nm"]) for r in rows] == list(brdf.lambda_nm)
    again = gs.load_brdf(tmp_path / "b.gsb")
    for text in [repr(s), repr(new), repr(brdf), repr(again)]:
        assert "rough" in text.lower(), text
    assert "Sample(" in repr(s) and "media [" in repr(s) and "triangles" in repr(s)
    for text in [repr(new), repr(again)]:
        for part in ["theta_i_deg [0.0, 30.0]", "3 wavelengths 450-650 nm", "trees [64, 64]",
                     "method auto (radius 5000 nm)"]:
            assert part in text, (part, text)
    assert repr(again).startswith("Brdf(") and "table" in repr(again)


def test_the_rigorous_solver_is_the_clis_and_conserves_energy(tmp_path):
    """coherence="rigorous" with its effort keywords: the bytes of the CLI's run, and the
    lossless transparent hologram's R + T = 1 (the solver's own balance)."""
    s = gs.Sample.load(mesh("hri-hologram.toml"))
    acc = gs.simulate(s, theta_i_deg=[0, 30], wavelengths="500:600:50", coherence="rigorous",
                      orders=20, slices=12, rigorous_tolerance=0.05)
    acc.save(tmp_path / "py.gsa")
    subprocess.run([CLI, "simulate", mesh("hri-hologram.toml"), "--theta-i", "0,30", "--wavelengths",
                    "500:600:50", "--coherence", "rigorous", "--orders", "20", "--slices", "12",
                    "--rigorous-tolerance", "0.05", "-o", str(tmp_path / "cli.gsa")],
                   check=True, cwd=ROOT, capture_output=True)
    assert (tmp_path / "py.gsa").read_bytes() == (tmp_path / "cli.gsa").read_bytes()
    for theta in (0, 30):
        r = acc.reflectance(theta)
        assert np.all(np.abs(r["R"] + r["T"] - 1) < 1e-9), r
    with pytest.raises(ValueError, match="slices"):
        gs.simulate(s, theta_i_deg=[0], coherence="rigorous", slices=0)


def test_a_measured_material_evaluates_as_the_cli_and_broadcasts(tmp_path):
    path = os.path.join(ROOT, "data", "measured", "cc_ibiza_sunset_rgb.bsdf")
    m = gs.load(path)
    assert isinstance(m, gs.Measured)
    assert m.rgb and m.lambda_nm is None
    assert len(m.theta_i_deg) == 8 and m.phi_i_deg == [0.0]
    assert "TeckWrap" in repr(m)
    pairs = tmp_path / "pairs.csv"
    angles = [(30.0, 0.0, t, 180.0) for t in (10.0, 20.0, 30.0, 45.0)]
    pairs.write_text("theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg\n" + "".join("%g,%g,%g,%g\n" % a for a in angles))
    out = subprocess.run([CLI, "eval", path, "--pairs", str(pairs)], capture_output=True, text=True, check=True)
    rows = list(csv.DictReader(io.StringIO(out.stdout)))
    got = m.eval(30.0, 0.0, np.array([10.0, 20.0, 30.0, 45.0]), 180.0)
    assert got.shape == (4, 3)
    for k, row in enumerate(rows):
        # The CLI prints 9 significant digits.
        want = [float(row[c]) for c in "rgb"]
        assert np.allclose(got[k], want, rtol=1e-7), (got[k], want)
    # NumPy's broadcasting: (2, 1) with (3,) is (2, 3); shapes that do not broadcast are refused.
    assert m.eval(np.array([[10.0], [40.0]]), 0.0, np.array([5.0, 15.0, 25.0]), 180.0).shape == (2, 3, 3)
    with pytest.raises(ValueError):
        m.eval(np.zeros((2, 3)), 0.0, np.zeros((3, 2)), 180.0)


def test_several_azimuths_are_the_clis_and_keep_their_axis(tmp_path):
    """phi_i_deg as a list: every pair of angle and azimuth, the bytes of the CLI's
    --phi-i 0,90; each direction's azimuth; reflectance per azimuth; build keeps the
    grooves anisotropic and refuses to average one azimuth unless asked."""
    s = gs.Sample.load(mesh("v-grooves-aluminium.toml"))
    acc = gs.simulate(s, theta_i_deg=[0, 30], phi_i_deg=[0, 90], wavelengths="400:700:100", rays=1024)
    acc.save(tmp_path / "py.gsa")
    subprocess.run([CLI, "simulate", mesh("v-grooves-aluminium.toml"), "--theta-i", "0,30", "--phi-i", "0,90",
                    "--wavelengths", "400:700:100", "--rays", "1024", "-o", str(tmp_path / "cli.gsa")],
                   check=True, cwd=ROOT, capture_output=True)
    assert (tmp_path / "py.gsa").read_bytes() == (tmp_path / "cli.gsa").read_bytes()
    assert acc.theta_i_deg == [0.0, 30.0, 0.0, 30.0]
    assert acc.directions_phi_i_deg == [0.0, 0.0, 90.0, 90.0]
    rows = cli("reflectance", str(tmp_path / "cli.gsa"), "--theta-i", "30", "--phi-i", "90")
    r = acc.reflectance(30, phi_i_deg=90)
    assert np.all(np.abs(r["R"] - [float(x["R"]) for x in rows]) <= 5e-9)
    assert np.any(np.abs(r["R"] - acc.reflectance(30)["R"]) > 1e-3), "the azimuths differ"
    assert ", isotropic" not in repr(acc.build("kdtree"))
    one = gs.simulate(s, theta_i_deg=[30], wavelengths="400:700:100", rays=1024)
    with pytest.raises(ValueError, match="not rotation-symmetric"):
        one.build("kdtree")
    assert ", isotropic" in repr(one.build("kdtree", isotropic=True))
