"""Type stubs of goniospec's Python API (units in every name or doc)."""

from os import PathLike
from typing import Literal, Sequence, Union

import numpy as np
import numpy.typing as npt

_Path = Union[str, PathLike[str]]
_Angles = Union[float, Sequence[float], npt.NDArray[np.float64]]

class Sample:
    @staticmethod
    def load(path: _Path) -> "Sample": ...
    @property
    def name(self) -> str: ...
    def check(self) -> dict[str, list[str]]:
        """`goniospec check`: {"facts": [...], "warnings": [...], "defects": [...]}."""
    def __repr__(self) -> str:
        """Sample('name': media, interfaces, triangles, tile in nm, sides, file)."""

class Brdf:
    def eval(self, theta_i_deg: _Angles, phi_i_deg: _Angles, theta_o_deg: _Angles, phi_o_deg: _Angles) -> npt.NDArray[np.float64]:
        """BRDF in 1/sr at angles in degrees (broadcast); shape [..., n_lambda]."""
    @property
    def lambda_nm(self) -> npt.NDArray[np.float64]:
        """Centre of each wavelength bin (or each exact wavelength), nm: eval's last axis."""
    @property
    def wavelengths_nm(self) -> npt.NDArray[np.float64]:
        """The old name of lambda_nm, kept for one release."""
    @property
    def theta_i_deg(self) -> list[float]: ...
    def __repr__(self) -> str:
        """Brdf('sample': representation, theta_i_deg, wavelengths, trees, method, symmetry)."""
    def save(self, path: _Path, force: bool = False) -> None: ...
    def export(self, path: _Path, format: Literal["npz", "merl", "rgl"] = "npz", sample: Sample | None = None, resolution: int = 65, force: bool = False) -> None:
        """npz: NumPy arrays; merl: sRGB (loses the spectrum); rgl: Mitsuba 3 / pbrt-v4 .bsdf (needs sample; odd resolution)."""

class Accumulator:
    def reflectance(
        self, theta_i_deg: float, incident: str | None = None, phi_i_deg: float | None = None
    ) -> dict[str, npt.NDArray[np.float64]]:
        """Keys lambda_nm, R, T, absorbed, dropped, R_stderr (fractions of incident power).
        With incident (a run with mueller=True; "s", "p", "+45", "-45", "circular+",
        "circular-", "unpolarised" or "S0,S1,S2,S3"): lambda_nm, R and T for that state."""
    def mueller(self, theta_i_deg: float, theta_o_deg: float, phi_o_deg: float = 180.0) -> dict[str, npt.NDArray[np.float64]]:
        """From a run with mueller=True: keys lambda_nm (n), M and M_stderr (n x 4 x 4, 1/sr,
        row-major, each direction's own s/p frame; M[:, 0, 0] is the unpolarised BRDF), dop
        (degree of polarisation for unpolarised light in)."""
    def save(self, path: _Path, force: bool = False) -> None: ...
    def build(
        self,
        repr: Literal["table", "kdtree", "subdivided"] = "table",
        isotropic: bool | None = None,
    ) -> Brdf: ...
    @property
    def theta_i_deg(self) -> list[float]: ...
    @property
    def directions_phi_i_deg(self) -> list[float]: ...
    @property
    def phi_i_deg(self) -> float: ...
    @property
    def lambda_nm(self) -> npt.NDArray[np.float64]:
        """Centre of each wavelength bin (or each exact wavelength), nm."""
    @property
    def trees(self) -> list[int]:
        """Trees traced per incident direction."""
    @property
    def warnings(self) -> list[str]:
        """What the run had to say about its result (kept in the .gsa), one sentence each."""
    @property
    def methods(self) -> list[str]:
        """Per incident direction under coherence="auto", one letter per wavelength cell:
        r (rays), d (the diffraction method) or m (the rigorous solver); empty otherwise."""
    def __repr__(self) -> str:
        """Accumulator('sample': theta_i_deg, phi_i_deg, wavelengths, trees, method)."""

class Measured:
    """A measured RGL material (or an RGL .bsdf goniospec exported): `load("x.bsdf")`."""
    def eval(self, theta_i_deg: _Angles, phi_i_deg: _Angles, theta_o_deg: _Angles, phi_o_deg: _Angles) -> npt.NDArray[np.float64]:
        """BRDF (1/sr), shape [..., 3] (linear sRGB) or [..., n_lambda]."""
    @property
    def rgb(self) -> bool: ...
    @property
    def lambda_nm(self) -> npt.NDArray[np.float64] | None: ...
    @property
    def theta_i_deg(self) -> list[float]: ...
    @property
    def phi_i_deg(self) -> list[float]: ...
    @property
    def description(self) -> str: ...
    def __repr__(self) -> str: ...

def load(path: _Path) -> Accumulator | Measured: ...
def load_brdf(path: _Path) -> Brdf: ...
def simulate(
    sample: Sample,
    theta_i_deg: Sequence[float],
    wavelengths: str = "380:780:10",
    rays: int = 4096,
    *,
    seed: int = 1,
    coherence: Literal["auto", "beamlet", "diffraction", "rigorous", "bucket", "global"] = "auto",
    coherence_radius_nm: float = 5000.0,
    cutoff: float = 1e-10,
    monochromatic: bool = False,
    phi_i_deg: float | Sequence[float] = 0.0,
    threads: int = 0,
    backend: Literal["embree", "obvhs"] | None = None,
    theta_o_bins: int = 45,
    phi_o_bins: int = 36,
    max_depth: int = 64,
    max_segments: int = 20000,
    tolerance: float | None = None,
    max_rays: int = 1000000,
    no_path_sharing: bool = False,
    no_wavelength_sharing: bool = False,
    no_next_event: bool = False,
    mueller: bool = False,
    orders: int | None = None,
    slices: int = 24,
    rigorous_tolerance: float = 5e-3,
    progress: bool | None = None,
) -> Accumulator:
    """goniospec simulate's flags as keywords (the same settings type, defaults and checks;
    an unknown keyword is a ValueError): theta_i_deg and phi_i_deg in degrees (their old
    names theta_i and phi_i, the flags', are still taken for one release), wavelengths in nm as
    --wavelengths, coherence_radius_nm in nm, cutoff a fraction of launched power; orders,
    slices and rigorous_tolerance the rigorous solver's effort (coherence="rigorous", or
    auto's cells finer than the wavelength).
    progress: a bar on sys.stderr when it is a terminal (None), always (True), never (False)."""
def analytic(sample: Sample, theta_i_deg: float, wavelengths: str = "380:780:10", monochromatic: bool = False) -> dict[str, npt.NDArray[np.float64]]:
    """Transfer-matrix lambda_nm, Rs, Rp, R, Ts, Tp, T of a [stack] sample, and delta_deg, the
    phase difference arg(r_p conj r_s) of the reflected amplitudes (docs/physics.md,
    "Polarisation"); theta_i_deg in degrees."""
def backends() -> list[dict[str, object]]:
    """The acceleration backends of this build: name, available, version, detail."""
