"""goniospec from Python: simulate microgeometry into spectral BRDFs and evaluate them
with numpy. Units are in every name: angles in degrees (``theta_i_deg``), lengths and
wavelengths in nanometres (``lambda_nm``), BRDF values in 1/sr.

    import goniospec as gs
    acc = gs.simulate(gs.Sample.load("meshes/thin-film-600nm.toml"), theta_i=[0, 30], rays=1024)
    brdf = acc.build("table"); brdf.eval(30, 0, 30, 180)   # -> [n_lambda]
"""

from ._goniospec import Accumulator, Brdf, Sample, analytic, backends, load, load_brdf, simulate

__all__ = ["Accumulator", "Brdf", "Sample", "analytic", "backends", "load", "load_brdf", "simulate"]
