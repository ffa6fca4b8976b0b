"""goniospec from Python: simulate microgeometry into spectral BRDFs and evaluate them
with numpy. Angles are degrees, lengths and wavelengths nanometres, BRDF values 1/sr; the
unit is in the name (``theta_i_deg``, ``lambda_nm``, ``coherence_radius_nm``) except for
``simulate``'s ``theta_i`` and ``phi_i``, which mirror the CLI's ``--theta-i`` and
``--phi-i`` flags and are degrees too.

    import goniospec as gs
    acc = gs.simulate(gs.Sample.load("meshes/thin-film-600nm.toml"), theta_i=[0, 30], rays=1024)
    brdf = acc.build("table"); brdf.eval(30, 0, 30, 180)   # -> [n_lambda]
    paper = gs.load("data/measured/paper_white_rgb.bsdf")   # a measured RGL material
    paper.eval(30, 0, [10, 20, 30], 180)                    # -> [3, 3]: linear sRGB per direction
"""

from ._goniospec import Accumulator, Brdf, Measured, Sample, analytic, backends, load, load_brdf, simulate

__all__ = ["Accumulator", "Brdf", "Measured", "Sample", "analytic", "backends", "load", "load_brdf", "simulate"]
