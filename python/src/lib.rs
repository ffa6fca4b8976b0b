//! Python bindings of goniospec (pyo3): the library's API, not the CLI's. Errors become
//! Python exceptions with the CLI's messages; long runs release the GIL.

use std::path::{Path, PathBuf};

use numpy::{
    IntoPyArray, PyArray1, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use goniospec::brdf::{Brdf as _, Kind, Representation};
use goniospec::output::OutputKind;
use goniospec::simulate::defaults;

fn value_err(e: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// A sample: media, interfaces and the periodic tile (`Sample.load(path)`).
#[pyclass(module = "goniospec", frozen)]
struct Sample {
    inner: goniospec::sample::Sample,
}

#[pymethods]
impl Sample {
    /// Loads a sample TOML (lengths in its unit, converted to nanometres).
    #[staticmethod]
    fn load(path: PathBuf) -> PyResult<Sample> {
        goniospec::sample::load(&path, goniospec::sample::MeshOptions::default())
            .map(|inner| Sample { inner })
            .map_err(value_err)
    }

    /// The sample's name.
    #[getter]
    fn name(&self) -> String {
        self.inner.name.clone()
    }

    /// `Sample('name': media, interfaces, triangles, tile in nm, sides, file)`.
    fn __repr__(&self) -> String {
        let s = &self.inner;
        let triangles: usize = s.interfaces.iter().map(|i| i.mesh.triangles.len()).sum();
        let media: Vec<&str> = s.media.iter().map(|m| m.name.as_str()).collect();
        format!(
            "Sample('{}': media [{}], {} interfaces, {} triangles, tile {} x {} nm, {}{}, from {})",
            s.name,
            media.join(", "),
            s.interfaces.len(),
            triangles,
            s.tile_nm[0],
            s.tile_nm[1],
            match s.guard_nm {
                Some(g) => format!("open sides with a {g} nm guard band"),
                None => "periodic".into(),
            },
            if s.stack.is_some() { ", a [stack]" } else { "" },
            s.path.display()
        )
    }

    /// `goniospec check`: a dict with `facts`, `warnings` and `defects` (lists of str).
    fn check<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let r = py
            .allow_threads(|| {
                goniospec::simulate::auto::check(
                    &self.inner,
                    &goniospec::check::CheckOptions {
                        // The validity warnings as `goniospec check` gives them by default.
                        validity: Some(goniospec::simulate::check_validity_context(
                            550.0,
                            0.0,
                            defaults::COHERENCE_RADIUS_NM,
                            goniospec::accumulate::Coherence::Auto,
                        )),
                        ..Default::default()
                    },
                )
            })
            .map_err(value_err)?;
        let d = PyDict::new(py);
        d.set_item("facts", r.facts)?;
        d.set_item("warnings", r.warnings)?;
        d.set_item("defects", r.defects)?;
        Ok(d)
    }
}

/// Accumulated buckets of a simulation (a `.gsa`).
#[pyclass(module = "goniospec", frozen)]
struct Accumulator {
    inner: goniospec::accumulate::file::Accumulator,
    /// The files it came from (the `.gsa` it was loaded from, or the sample's own files):
    /// what `save` and the BRDF's `save` and `export` must never replace.
    inputs: Vec<PathBuf>,
}

#[pymethods]
impl Accumulator {
    /// Directional reflectance at `theta_i_deg` (a simulated angle): a dict of numpy
    /// arrays keyed like the CLI's CSV columns: `lambda_nm`, `R`, `T`, `absorbed`,
    /// `dropped`, `R_stderr` (NaN in global mode). With `incident` (a run with
    /// `mueller=True`): polarised light in, a named state ("s", "p", "+45", "-45",
    /// "circular+", "circular-", "unpolarised") or a Stokes vector string "S0,S1,S2,S3",
    /// as the CLI's `--incident`; then only `lambda_nm`, `R` and `T`. `phi_i_deg`: the
    /// direction's azimuth, for a run over several (default: the first).
    #[pyo3(signature = (theta_i_deg, incident = None, phi_i_deg = None))]
    fn reflectance<'py>(
        &self,
        py: Python<'py>,
        theta_i_deg: f64,
        incident: Option<&str>,
        phi_i_deg: Option<f64>,
    ) -> PyResult<Bound<'py, PyDict>> {
        if let Some(state) = incident {
            let stokes = goniospec::optics::mueller::stokes_state(state).map_err(value_err)?;
            let rows = self
                .inner
                .polarised_reflectance(theta_i_deg, phi_i_deg, &stokes)
                .map_err(value_err)?;
            let col = |f: &dyn Fn(&goniospec::accumulate::polarimetric::PolarisedRow) -> f64| {
                rows.iter().map(f).collect::<Vec<f64>>().into_pyarray(py)
            };
            let d = PyDict::new(py);
            d.set_item("lambda_nm", col(&|x| x.lambda_nm))?;
            d.set_item("R", col(&|x| x.r))?;
            d.set_item("T", col(&|x| x.t))?;
            return Ok(d);
        }
        let r = self
            .inner
            .reflectance(theta_i_deg, phi_i_deg)
            .map_err(value_err)?;
        let col = |f: &dyn Fn(&goniospec::accumulate::file::ReflectanceRow) -> f64| {
            r.rows.iter().map(f).collect::<Vec<f64>>().into_pyarray(py)
        };
        let d = PyDict::new(py);
        d.set_item("lambda_nm", col(&|x| x.lambda_nm))?;
        d.set_item("R", col(&|x| x.r))?;
        d.set_item("T", col(&|x| x.t))?;
        d.set_item("absorbed", col(&|x| x.absorbed))?;
        d.set_item("dropped", col(&|x| x.dropped))?;
        d.set_item("R_stderr", col(&|x| x.r_stderr.unwrap_or(f64::NAN)))?;
        Ok(d)
    }

    /// The Mueller-matrix BRDF (1/sr) at the simulated incident angle `theta_i_deg`
    /// towards (`theta_o_deg`, `phi_o_deg`), from a run with `mueller=True`: a dict with
    /// `lambda_nm` (n), `M` and `M_stderr` (n x 4 x 4, row-major, each direction's own s/p
    /// frame; `M[:, 0, 0]` is the unpolarised BRDF) and `dop` (n, the degree of
    /// polarisation for unpolarised light in). `theta_o_deg` above 90 reads the
    /// transmission side.
    #[pyo3(signature = (theta_i_deg, theta_o_deg, phi_o_deg = 180.0))]
    fn mueller<'py>(
        &self,
        py: Python<'py>,
        theta_i_deg: f64,
        theta_o_deg: f64,
        phi_o_deg: f64,
    ) -> PyResult<Bound<'py, PyDict>> {
        let wo = goniospec::geom::from_spherical(theta_o_deg.to_radians(), phi_o_deg.to_radians());
        let rows = self
            .inner
            .mueller_brdf(theta_i_deg, None, wo)
            .map_err(value_err)?;
        let n = rows.len();
        let m: Vec<f64> = rows.iter().flat_map(|r| r.m).collect();
        let e: Vec<f64> = rows
            .iter()
            .flat_map(|r| r.stderr.unwrap_or([f64::NAN; 16]))
            .collect();
        let d = PyDict::new(py);
        d.set_item(
            "lambda_nm",
            rows.iter()
                .map(|r| r.lambda_nm)
                .collect::<Vec<f64>>()
                .into_pyarray(py),
        )?;
        d.set_item("M", m.into_pyarray(py).reshape([n, 4, 4])?)?;
        d.set_item("M_stderr", e.into_pyarray(py).reshape([n, 4, 4])?)?;
        d.set_item(
            "dop",
            rows.iter()
                .map(|r| r.dop)
                .collect::<Vec<f64>>()
                .into_pyarray(py),
        )?;
        Ok(d)
    }

    /// Writes the accumulator as a `.gsa` (atomically). It never replaces a file it came
    /// from, nor an existing file that is not a `.gsa` unless `force` (the CLI's policy).
    #[pyo3(signature = (path, force = false))]
    fn save(&self, path: PathBuf, force: bool) -> PyResult<()> {
        guard(&path, &self.inputs, OutputKind::Gsa, force)?;
        self.inner
            .write(&path)
            .map_err(|e| PyOSError::new_err(format!("{}: {e}", path.display())))
    }

    /// Builds a BRDF representation: "table", "kdtree" or "subdivided". `isotropic` as
    /// `goniospec build`: None decides (anisotropic where the run has several incident
    /// azimuths; a ValueError for a sample that is not rotation-symmetric lit from one),
    /// True averages over the incident azimuth, False keeps absolute azimuths (kdtree).
    #[pyo3(signature = (repr = "table", isotropic = None))]
    fn build(&self, py: Python<'_>, repr: &str, isotropic: Option<bool>) -> PyResult<Brdf> {
        let kind = Kind::parse(repr).map_err(value_err)?;
        let iso = goniospec::brdf::symmetry::isotropic(&self.inner.header.settings, isotropic)
            .map_err(value_err)?;
        let inner = py.allow_threads(|| {
            let data = goniospec::brdf::BucketData::from_accumulator(&self.inner);
            let opts = goniospec::brdf::BuildOptions {
                isotropic: iso,
                ..Default::default()
            };
            Representation::build(kind, &data, &opts)
        });
        inner
            .map(|inner| Brdf {
                inner,
                inputs: self.inputs.clone(),
            })
            .map_err(value_err)
    }

    /// The simulated incident angles, degrees, one per direction (a run over several
    /// azimuths repeats them once per azimuth: `directions_phi_i_deg` gives each one's).
    #[getter]
    fn theta_i_deg(&self) -> Vec<f64> {
        self.inner.header.settings.theta_i_deg.clone()
    }

    /// Each direction's incident azimuth, degrees, aligned with `theta_i_deg`.
    #[getter]
    fn directions_phi_i_deg(&self) -> Vec<f64> {
        let s = &self.inner.header.settings;
        (0..s.theta_i_deg.len()).map(|i| s.phi_of(i)).collect()
    }

    /// The simulated incident azimuth, degrees (the first, where the run has several).
    #[getter]
    fn phi_i_deg(&self) -> f64 {
        self.inner.header.settings.phi_i_deg
    }

    /// Centre wavelength of each bin (or each exact wavelength), nm: the `lambda_nm` of
    /// `reflectance()` and of the CLI's CSV.
    #[getter]
    fn lambda_nm<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        let s = &self.inner.header.settings;
        (0..s.wavelength_count())
            .map(|j| s.wavelength(j))
            .collect::<Vec<f64>>()
            .into_pyarray(py)
    }

    /// Trees traced per incident direction (summed over merged runs).
    #[getter]
    fn trees(&self) -> Vec<u64> {
        self.inner.header.rays_per_direction.clone()
    }

    /// What the run had to say about its result (the `.gsa`'s warnings: validity findings
    /// and the run's own, each direction's in direction order), one sentence each.
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.inner.header.warnings.clone()
    }

    /// Each incident direction's methods under `coherence="auto"` (one letter per
    /// wavelength cell: `r` rays, `d` the diffraction method); empty otherwise.
    #[getter]
    fn methods(&self) -> Vec<String> {
        self.inner.header.settings.methods.clone()
    }

    /// `Accumulator('sample': theta_i_deg, phi_i_deg, wavelengths, trees, method)`.
    fn __repr__(&self) -> String {
        let h = &self.inner.header;
        let s = &h.settings;
        let n = s.wavelength_count();
        format!(
            "Accumulator('{}': theta_i_deg {:?}, phi_i_deg {}, {} wavelengths {}-{} nm ({}), trees {:?}, method {}{})",
            s.sample_name,
            s.theta_i_deg,
            s.phi_i_deg,
            n,
            if n > 0 { s.wavelength(0) } else { 0.0 },
            if n > 0 { s.wavelength(n - 1) } else { 0.0 },
            s.wavelength_mode,
            h.rays_per_direction,
            s.coherence,
            method_radius(s.coherence, s.coherence_radius_nm)
        )
    }
}

/// The coherence radius a method's description names: ", radius 5000 nm", or the
/// plane-wave limit; nothing for the methods that take none.
fn method_radius(c: goniospec::accumulate::Coherence, rho_nm: f64) -> String {
    use goniospec::accumulate::Coherence;
    match c {
        Coherence::Auto | Coherence::Beamlet | Coherence::Diffraction if rho_nm.is_infinite() => {
            " (plane-wave limit)".into()
        }
        Coherence::Auto | Coherence::Beamlet | Coherence::Diffraction => {
            format!(" (radius {rho_nm} nm)")
        }
        _ => String::new(),
    }
}

/// A BRDF's values (1/sr) at directions given by polar and azimuth angles in degrees, each
/// a number or a numpy array (broadcast together as NumPy broadcasts): `[..., channels]`.
fn eval_broadcast<'py>(
    py: Python<'py>,
    brdf: &(dyn goniospec::brdf::Brdf + Sync),
    theta_i_deg: &Bound<'py, PyAny>,
    phi_i_deg: &Bound<'py, PyAny>,
    theta_o_deg: &Bound<'py, PyAny>,
    phi_o_deg: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    // Numbers, lists and arrays alike, as numpy.asarray(x, float64) sees them.
    let np = py.import("numpy")?;
    let as_array = |name: &str, x: &Bound<'py, PyAny>| -> PyResult<Bound<'py, PyAny>> {
        if x.is_none() {
            // numpy makes None a NaN, which read as "got NaN".
            return Err(pyo3::exceptions::PyTypeError::new_err(format!(
                "{name} is None: give an angle in degrees, or an array of them"
            )));
        }
        np.call_method1("asarray", (x, "float64"))
    };
    let given = (
        as_array("theta_i_deg", theta_i_deg)?,
        as_array("phi_i_deg", phi_i_deg)?,
        as_array("theta_o_deg", theta_o_deg)?,
        as_array("phi_o_deg", phi_o_deg)?,
    );
    // NumPy's own broadcasting rules (views, nothing copied yet): shapes (2, 3) and
    // (3, 2) are refused as NumPy refuses them, not matched by their sizes (issue 47).
    let views = np.call_method1("broadcast_arrays", given).map_err(|e| {
        value_err(format!(
            "the four angle arrays must broadcast together as NumPy's rules say: {}",
            e.value(py)
        ))
    })?;
    let arrays: Vec<PyReadonlyArrayDyn<'py, f64>> = views
        .try_iter()?
        .map(|v| v?.extract())
        .collect::<PyResult<_>>()?;
    let shape: Vec<usize> = arrays[0].shape().to_vec();
    let n: usize = shape.iter().product();
    // Four angle columns, two directions and the result per query: refused as a
    // MemoryError before anything is allocated when it cannot fit (a broadcast view of
    // 10^11 angles aborted the interpreter).
    let nl = brdf.meta().lambda_nm.len();
    let bytes = n
        .checked_mul(4 + 6 + nl)
        .and_then(|v| v.checked_mul(8))
        .filter(|&b| {
            goniospec::io::available_memory_bytes().is_none_or(|avail| (b as u64) < avail / 2)
        });
    let Some(_) = bytes else {
        return Err(pyo3::exceptions::PyMemoryError::new_err(format!(
            "evaluating {n} angle sets at {nl} wavelengths needs more memory than this machine has available: evaluate in chunks"
        )));
    };
    let cols: Vec<Vec<f64>> = arrays
        .iter()
        .map(|a| a.as_array().iter().copied().collect())
        .collect();
    for (name, c) in ["theta_i_deg", "theta_o_deg"]
        .iter()
        .zip([&cols[0], &cols[2]])
    {
        if let Some(t) = c
            .iter()
            .find(|t| !(t.is_finite() && (0.0..=90.0).contains(*t)))
        {
            return Err(value_err(format!(
                "{name}: polar angles must be in [0, 90] degrees, got {t}"
            )));
        }
    }
    for (name, c) in ["phi_i_deg", "phi_o_deg"].iter().zip([&cols[1], &cols[3]]) {
        if let Some(p) = c.iter().find(|p| !p.is_finite()) {
            return Err(value_err(format!(
                "{name}: azimuths must be finite, got {p}"
            )));
        }
    }
    let dir = |t: f64, p: f64| goniospec::geom::from_spherical(t.to_radians(), p.to_radians());
    let pairs: Vec<_> = (0..n)
        .map(|k| (dir(cols[0][k], cols[1][k]), dir(cols[2][k], cols[3][k])))
        .collect();
    let mut out = vec![0.0; n * nl];
    py.allow_threads(|| brdf.eval_batch(&pairs, &mut out));
    let mut full = shape.clone();
    full.push(nl);
    numpy::ndarray::ArrayD::from_shape_vec(full, out)
        .map(|a| a.into_pyarray(py))
        .map_err(value_err)
}

/// A built BRDF (a `.gsb`).
#[pyclass(module = "goniospec", frozen)]
struct Brdf {
    inner: Representation,
    /// As `Accumulator::inputs`, with the `.gsb` it was loaded from.
    inputs: Vec<PathBuf>,
}

#[pymethods]
impl Brdf {
    /// The BRDF (1/sr) at directions given by polar and azimuth angles in degrees, each
    /// a number or a numpy array (broadcast together); returns `[..., n_lambda]`.
    fn eval<'py>(
        &self,
        py: Python<'py>,
        theta_i_deg: &Bound<'py, PyAny>,
        phi_i_deg: &Bound<'py, PyAny>,
        theta_o_deg: &Bound<'py, PyAny>,
        phi_o_deg: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        eval_broadcast(
            py,
            &self.inner,
            theta_i_deg,
            phi_i_deg,
            theta_o_deg,
            phi_o_deg,
        )
    }

    /// Centre wavelength of each bin (or each exact wavelength), nm: the last axis of
    /// `eval`, and the `lambda_nm` of every CSV and NPZ.
    #[getter]
    fn lambda_nm<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.inner.meta().lambda_nm.clone().into_pyarray(py)
    }

    /// The old name of `lambda_nm` (before 0.x, issue 45), kept for one release.
    #[getter]
    fn wavelengths_nm<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.lambda_nm(py)
    }

    /// The simulated incident angles, degrees (from the simulation's settings).
    #[getter]
    fn theta_i_deg(&self) -> PyResult<Vec<f64>> {
        Ok(self.settings()?.theta_i_deg)
    }

    /// `Brdf('sample': representation, theta_i_deg, wavelengths, trees, method, symmetry)`.
    fn __repr__(&self) -> String {
        let m = self.inner.meta();
        let n = m.lambda_nm.len();
        let (angles, trees, method) = match self.settings() {
            Ok(s) => (
                format!("{:?}", s.theta_i_deg),
                match &m.trees_per_direction {
                    Some(v) => format!("trees {v:?}"),
                    None => "trees not recorded".into(),
                },
                format!(
                    "{}{}",
                    s.coherence,
                    method_radius(s.coherence, s.coherence_radius_nm)
                ),
            ),
            Err(_) => ("?".into(), "?".into(), "?".into()),
        };
        format!(
            "Brdf('{}': {}, theta_i_deg {}, {} wavelengths {}-{} nm, {}, method {}{}{})",
            m.sample_name,
            m.repr.name(),
            angles,
            n,
            m.lambda_nm.first().unwrap_or(&0.0),
            m.lambda_nm.last().unwrap_or(&0.0),
            trees,
            method,
            if m.isotropic { ", isotropic" } else { "" },
            if m.reciprocal { ", reciprocal" } else { "" },
        )
    }

    /// Writes the BRDF as a `.gsb` (atomically). It never replaces a file it came from,
    /// nor an existing file that is not a `.gsb` unless `force` (the CLI's policy).
    #[pyo3(signature = (path, force = false))]
    fn save(&self, path: PathBuf, force: bool) -> PyResult<()> {
        guard(&path, &self.inputs, OutputKind::Gsb, force)?;
        goniospec::brdf::file::write(&self.inner, &path)
            .map_err(|e| PyOSError::new_err(format!("{}: {e}", path.display())))
    }

    /// Exports the BRDF: format "npz" (NumPy arrays on the bucket grid), "merl" (sRGB),
    /// or "rgl" (the RGL `.bsdf` of Mitsuba 3 and pbrt-v4; needs `sample`, whose facets
    /// give the microfacet distribution, and an odd `resolution`).
    /// It never replaces a file it came from or the sample's files, nor an existing file
    /// of another kind unless `force`.
    #[pyo3(signature = (path, format = "npz", sample = None, resolution = 65, force = false))]
    fn export(
        &self,
        py: Python<'_>,
        path: PathBuf,
        format: &str,
        sample: Option<&Sample>,
        resolution: usize,
        force: bool,
    ) -> PyResult<()> {
        let kind = match format {
            "npz" => OutputKind::Npz,
            "merl" => OutputKind::Merl,
            _ => OutputKind::Tensor,
        };
        let mut inputs = self.inputs.clone();
        if let Some(s) = sample {
            inputs.extend(s.inner.inputs.iter().cloned());
        }
        guard(&path, &inputs, kind, force)?;
        let bytes = py
            .allow_threads(|| -> Result<Vec<u8>, goniospec::export::ExportError> {
                match format {
                    "npz" => {
                        let s: goniospec::accumulate::file::Settings =
                            toml::from_str(&self.inner.meta().simulation)
                                .map_err(|e| e.to_string())?;
                        let grid = goniospec::export::npz::Grid::of(
                            &self.inner,
                            s.theta_o_bins as usize,
                            s.phi_o_bins as usize,
                        )?;
                        goniospec::export::npz::npz_bytes(&self.inner, &grid)
                    }
                    "merl" => goniospec::export::merl::merl_bytes(&self.inner),
                    "rgl" => {
                        let s = sample.ok_or("format 'rgl' needs sample=Sample.load(...)")?;
                        goniospec::export::rgl_for(&self.inner, &s.inner, resolution, None)
                            .map(|(fields, _)| goniospec::export::tensor::to_bytes(&fields))
                    }
                    other => Err(format!("unknown format '{other}' (npz, merl or rgl)").into()),
                }
            })
            .map_err(value_err)?;
        goniospec::io::write_atomic(&path, |w| std::io::Write::write_all(w, &bytes))
            .map_err(|e| PyOSError::new_err(format!("{}: {e}", path.display())))
    }
}

impl Brdf {
    /// The simulation's settings, from the `.gsb`'s metadata.
    fn settings(&self) -> PyResult<goniospec::accumulate::file::Settings> {
        toml::from_str(&self.inner.meta().simulation).map_err(value_err)
    }
}

/// A measured material of the RGL database (or an RGL `.bsdf` goniospec exported), read as
/// the database's loader and Mitsuba 3 read it (`goniospec.load("x.bsdf")`).
#[pyclass(module = "goniospec", frozen)]
struct Measured {
    inner: goniospec::export::measured::MeasuredBrdf,
}

#[pymethods]
impl Measured {
    /// The BRDF (1/sr) at directions given by polar and azimuth angles in degrees, each a
    /// number or a numpy array (broadcast together); returns `[..., 3]` (linear sRGB) for
    /// an RGB file, `[..., n_lambda]` for a spectral one.
    fn eval<'py>(
        &self,
        py: Python<'py>,
        theta_i_deg: &Bound<'py, PyAny>,
        phi_i_deg: &Bound<'py, PyAny>,
        theta_o_deg: &Bound<'py, PyAny>,
        phi_o_deg: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        eval_broadcast(
            py,
            &self.inner,
            theta_i_deg,
            phi_i_deg,
            theta_o_deg,
            phi_o_deg,
        )
    }

    /// Whether the channels are linear sRGB (r, g, b) rather than wavelengths.
    #[getter]
    fn rgb(&self) -> bool {
        self.inner.meta().rgb
    }

    /// The wavelengths of a spectral file, nm; `None` for an RGB file.
    #[getter]
    fn lambda_nm<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        match &self.inner.form {
            goniospec::export::measured::Form::Spectral(l) => Some(l.clone().into_pyarray(py)),
            goniospec::export::measured::Form::Rgb => None,
        }
    }

    /// The measured incident elevations, degrees.
    #[getter]
    fn theta_i_deg(&self) -> Vec<f64> {
        self.inner
            .theta_i_rad
            .iter()
            .map(|t| t.to_degrees())
            .collect()
    }

    /// The measured incident azimuths, degrees (one for an isotropic material).
    #[getter]
    fn phi_i_deg(&self) -> Vec<f64> {
        self.inner
            .phi_i_rad
            .iter()
            .map(|t| t.to_degrees())
            .collect()
    }

    /// The file's description of the material.
    #[getter]
    fn description(&self) -> String {
        self.inner.description.clone()
    }

    /// `Measured('description': RGB|spectral, theta_i_deg [...], grid w x h)`.
    fn __repr__(&self) -> String {
        let m = &self.inner;
        format!(
            "Measured('{}': {}, theta_i_deg {:?}, {} x {} nodes{})",
            m.description,
            match &m.form {
                goniospec::export::measured::Form::Rgb => "RGB (linear sRGB)".to_string(),
                goniospec::export::measured::Form::Spectral(l) => format!(
                    "spectral, {} wavelengths {:.0}-{:.0} nm",
                    l.len(),
                    l[0],
                    l[l.len() - 1]
                ),
            },
            self.theta_i_deg()
                .iter()
                .map(|t| (t * 100.0).round() / 100.0)
                .collect::<Vec<_>>(),
            m.grid.0,
            m.grid.1,
            if m.isotropic { ", isotropic" } else { "" }
        )
    }
}

/// The output policy (`goniospec::output::guard`): refusals are `FileExistsError`.
fn guard(path: &Path, inputs: &[PathBuf], kind: OutputKind, force: bool) -> PyResult<()> {
    let inputs: Vec<&Path> = inputs.iter().map(|p| p.as_path()).collect();
    goniospec::output::guard(path, &inputs, kind, force)
        .map_err(|e| pyo3::exceptions::PyFileExistsError::new_err(e.to_string()))
}

/// Loads a `.gsa` accumulator, or an RGL `.bsdf` (a measured material, or one goniospec
/// exported) as a `Measured` BRDF; told apart by their magic bytes.
#[pyfunction]
fn load(py: Python<'_>, path: PathBuf) -> PyResult<PyObject> {
    use std::io::Read;
    let mut head = [0u8; 12];
    std::fs::File::open(&path)
        .and_then(|mut f| f.read(&mut head))
        .map_err(|e| PyOSError::new_err(format!("{}: {e}", path.display())))?;
    if goniospec::export::tensor::is_tensor_file(&head) {
        let inner = goniospec::export::measured::MeasuredBrdf::read(&path).map_err(value_err)?;
        return Ok(Measured { inner }.into_pyobject(py)?.into_any().unbind());
    }
    // Held to the physics its run was held to (`simulate::check_file`).
    let (inner, warning) = goniospec::simulate::read_judged(&path).map_err(value_err)?;
    if let Some(w) = warning {
        let text = std::ffi::CString::new(w).unwrap_or_default();
        PyErr::warn(
            py,
            &py.get_type::<pyo3::exceptions::PyUserWarning>(),
            &text,
            1,
        )?;
    }
    Ok(Accumulator {
        inner,
        inputs: vec![path.clone()],
    }
    .into_pyobject(py)?
    .into_any()
    .unbind())
}

/// Loads a `.gsb` BRDF.
#[pyfunction]
fn load_brdf(path: PathBuf) -> PyResult<Brdf> {
    goniospec::brdf::file::read(&path)
        .map(|inner| Brdf {
            inner,
            inputs: vec![path.clone()],
        })
        .map_err(value_err)
}

/// Simulates the virtual goniospectrometer (`goniospec simulate`, with its flags as
/// keywords of the same names, `_` for `-`, and the same defaults): `rays` coherent ray
/// trees per incident direction `theta_i_deg` (degrees) at azimuth `phi_i_deg` (degrees;
/// `theta_i` and `phi_i`, the flags' names, are still taken for one release);
/// `wavelengths` as `--wavelengths` (nm: "A:B:STEP" bins, or a comma list of edges; exact
/// wavelengths with `monochromatic=True`); the estimator `coherence` with
/// `coherence_radius_nm` (float("inf"): the plane-wave limit); `theta_o_bins` x
/// `phi_o_bins` outgoing buckets; power `cutoff`, `max_depth`, `max_segments`; an adaptive
/// budget to relative standard error `tolerance` (every bright bucket), or to a median
/// relative standard error `target_stderr` of the buckets holding 95 % of each
/// wavelength's reflected power, with at most `max_rays` trees per direction;
/// `no_path_sharing`; `no_wavelength_sharing`; `no_next_event` (particle media: the walk
/// alone); `backend` ("embree" or "obvhs"); `seed`. An unknown keyword is a ValueError naming the known ones.
/// Releases the GIL; Ctrl-C raises KeyboardInterrupt within 50 ms and returns nothing;
/// `progress`: a bar on `sys.stderr` (trees done, rate, time left) when it is a terminal and
/// nothing otherwise (`None`, the default); `True` draws it always, `False` never;
/// `threads=0` uses all cores and results do not depend on it.
#[pyfunction]
#[pyo3(signature = (sample, theta_i_deg = None, wavelengths = None, rays = None, *, threads = 0, progress = None, theta_i = None, **settings))]
#[allow(clippy::too_many_arguments)]
fn simulate(
    py: Python<'_>,
    sample: &Sample,
    theta_i_deg: Option<Vec<f64>>,
    wavelengths: Option<&str>,
    rays: Option<u64>,
    threads: usize,
    progress: Option<bool>,
    theta_i: Option<Vec<f64>>,
    settings: Option<&Bound<'_, PyDict>>,
) -> PyResult<Accumulator> {
    // `theta_i` and `phi_i` are the names before issue 45 (the CLI's flags), kept for a
    // release beside `theta_i_deg` and `phi_i_deg`, the names every output uses.
    let theta_i = match (theta_i_deg, theta_i) {
        (Some(t), None) | (None, Some(t)) => t,
        (Some(_), Some(_)) => {
            return Err(value_err(
                "simulate(): give theta_i_deg, or its old name theta_i, not both",
            ));
        }
        (None, None) => {
            return Err(pyo3::exceptions::PyTypeError::new_err(
                "simulate() needs the incident angles theta_i_deg (degrees), e.g. [0, 30, 60]",
            ));
        }
    };
    // The keywords become the CLI's settings (`SimSettings`, deserialised with its
    // defaults and its checks), resolved into the run's configuration in one place.
    let mut table = toml::Table::new();
    table.insert(
        "theta_i".into(),
        toml::Value::Array(theta_i.into_iter().map(toml::Value::Float).collect()),
    );
    if let Some(w) = wavelengths {
        table.insert("wavelengths".into(), toml::Value::String(w.into()));
    }
    if let Some(r) = rays {
        table.insert(
            "rays".into(),
            toml::Value::Integer(
                i64::try_from(r).map_err(|_| value_err(format!("rays: {r} is out of range")))?,
            ),
        );
    }
    if let Some(kw) = settings {
        for (k, v) in kw.iter() {
            if !v.is_none() {
                let mut k = k.extract::<String>()?;
                if k == "phi_i_deg" {
                    if kw.get_item("phi_i")?.is_some_and(|p| !p.is_none()) {
                        return Err(value_err(
                            "simulate(): give phi_i_deg, or its old name phi_i, not both",
                        ));
                    }
                    k = "phi_i".into();
                }
                table.insert(k, to_toml(&v)?);
            }
        }
    }
    let settings: goniospec::simulate::SimSettings = toml::Value::Table(table)
        .try_into()
        .map_err(|e: toml::de::Error| value_err(format!("simulate(): {}", e.message())))?;
    let mut cfg = settings.resolve().map_err(value_err)?;
    let total = settings.budget();
    // Where the method asked for does not hold for this sample: a UserWarning each, before
    // the run (the CLI's `simulate` prints the same lines), for settings known to be valid.
    let ctx = goniospec::simulate::validity_context(&cfg);
    let warn = |py: Python<'_>, text: &str| -> PyResult<()> {
        let msg = std::ffi::CString::new(text).map_err(value_err)?;
        PyErr::warn(
            py,
            &py.get_type::<pyo3::exceptions::PyUserWarning>(),
            &msg,
            1,
        )
    };
    let before: Vec<String> = goniospec::sample::validity::findings(&sample.inner, &ctx)
        .into_iter()
        .map(|f| f.message)
        .collect();
    for m in &before {
        warn(py, m)?;
    }
    let pool = goniospec::simulate::thread_pool(threads).map_err(value_err)?;
    // The run goes on a worker thread without the GIL; this thread wakes every 50 ms to
    // let Python handle signals, and Ctrl-C (KeyboardInterrupt) cancels the run.
    let cancel = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    cfg.cancel = Some(cancel.clone());
    let done = std::sync::atomic::AtomicU64::new(0);
    // The bar's total is what the run will trace, as it knows it (`ProgressPlan`).
    let plan = std::sync::Arc::new(goniospec::simulate::ProgressPlan::default());
    cfg.progress_plan = Some(plan.clone());
    let mut bar = match progress {
        Some(false) => None,
        Some(true) => Some(Bar::new(total)),
        None => stderr_is_terminal(py).then(|| Bar::new(total)),
    };
    let (result, interrupt) = py.allow_threads(|| {
        std::thread::scope(|scope| {
            let run = scope.spawn(|| {
                pool.install(|| {
                    goniospec::simulate::simulate(&sample.inner, &cfg, &|n| {
                        done.store(n, std::sync::atomic::Ordering::Relaxed)
                    })
                })
            });
            let mut interrupt = None;
            while !run.is_finished() {
                std::thread::sleep(std::time::Duration::from_millis(50));
                Python::with_gil(|py| {
                    if let Some(bar) = bar.as_mut() {
                        let n = done.load(std::sync::atomic::Ordering::Relaxed);
                        bar.total = plan.total().max(n).max(1);
                        bar.draw(py, n, false);
                    }
                    if interrupt.is_none()
                        && let Err(e) = py.check_signals()
                    {
                        cancel.store(true, std::sync::atomic::Ordering::Relaxed);
                        interrupt = Some(e);
                    }
                });
            }
            (
                run.join().expect("the simulation thread does not panic"),
                interrupt,
            )
        })
    });
    if let Some(bar) = bar.as_mut() {
        let n = done.load(std::sync::atomic::Ordering::Relaxed);
        bar.total = plan.total().max(n).max(1);
        bar.draw(py, n, true);
    }
    if let Some(e) = interrupt {
        return Err(e);
    }
    let (acc, _) = result.map_err(value_err)?;
    // What the run found on its way (the `.gsa`'s warnings, as the CLI prints them), each
    // a UserWarning too, less those given before it.
    for w in acc.header.warnings.iter().filter(|w| !before.contains(w)) {
        warn(py, w)?;
    }
    Ok(Accumulator {
        inner: acc,
        inputs: sample.inner.inputs.clone(),
    })
}

/// A Python keyword's value as TOML (bool, int, float, str, or a list of them), for
/// deserialising settings.
fn to_toml(v: &Bound<'_, PyAny>) -> PyResult<toml::Value> {
    use pyo3::types::{PyBool, PyFloat, PyInt, PyList, PyString, PyTuple};
    Ok(if v.is_instance_of::<PyBool>() {
        toml::Value::Boolean(v.extract()?)
    } else if v.is_instance_of::<PyInt>() {
        toml::Value::Integer(
            v.extract()
                .map_err(|_| value_err(format!("{v} is out of range")))?,
        )
    } else if v.is_instance_of::<PyFloat>() {
        toml::Value::Float(v.extract()?)
    } else if v.is_instance_of::<PyString>() {
        toml::Value::String(v.extract()?)
    } else if v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>() {
        toml::Value::Array(
            v.try_iter()?
                .map(|x| to_toml(&x?))
                .collect::<PyResult<Vec<_>>>()?,
        )
    } else {
        return Err(value_err(format!(
            "{v}: a setting is a bool, int, float, str or a list of them"
        )));
    })
}

/// Whether `sys.stderr` is a terminal (False when it is missing, replaced or a pipe).
fn stderr_is_terminal(py: Python<'_>) -> bool {
    py.import("sys")
        .and_then(|sys| sys.getattr("stderr"))
        .and_then(|e| e.call_method0("isatty"))
        .and_then(|t| t.extract::<bool>())
        .unwrap_or(false)
}

/// A progress bar written to Python's `sys.stderr` (so it follows any redirection Python
/// makes), redrawn in place with a carriage return at most every 200 ms.
struct Bar {
    total: u64,
    start: std::time::Instant,
    shown: Option<std::time::Instant>,
}

impl Bar {
    fn new(total: u64) -> Bar {
        Bar {
            total: total.max(1),
            start: std::time::Instant::now(),
            shown: None,
        }
    }

    /// Redraws the bar with `done` trees; `last` draws it whatever the time and ends the line.
    fn draw(&mut self, py: Python<'_>, done: u64, last: bool) {
        if !last && self.shown.is_some_and(|t| t.elapsed().as_millis() < 200) {
            return;
        }
        self.shown = Some(std::time::Instant::now());
        let line = bar_line(done, self.total, self.start.elapsed().as_secs_f64(), last);
        // A stderr that cannot be written to (closed, or None under pythonw) shows no bar.
        let _ = py.import("sys").and_then(|sys| {
            let err = sys.getattr("stderr")?;
            err.call_method1("write", (line,))?;
            err.call_method0("flush")
        });
    }
}

/// One line of the bar: `goniospec  37% |#####-----| 1520/4096 trees, 812 trees/s, 3 s left`.
fn bar_line(done: u64, total: u64, elapsed_s: f64, last: bool) -> String {
    const WIDTH: usize = 24;
    let frac = (done as f64 / total as f64).clamp(0.0, 1.0);
    let filled = (frac * WIDTH as f64).round() as usize;
    let rate = if elapsed_s > 0.0 {
        done as f64 / elapsed_s
    } else {
        0.0
    };
    let tail = if last {
        format!("{elapsed_s:.1} s\n")
    } else if rate > 0.0 {
        format!("{:.0} s left", (total.saturating_sub(done)) as f64 / rate)
    } else {
        String::from("starting")
    };
    format!(
        "\rgoniospec {:3.0}% |{}{}| {done}/{total} trees, {rate:.0} trees/s, {tail}",
        100.0 * frac,
        "\u{2588}".repeat(filled),
        " ".repeat(WIDTH - filled),
    )
}

/// The acceleration backends of this build: a list of dicts with `name`, `available`,
/// `version` (of the library behind it, read from a live device for Embree) and `detail`
/// (how it is bound, or why it is missing).
#[pyfunction]
fn backends<'py>(py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
    let mut out = Vec::new();
    for b in goniospec::accel::available_backends() {
        let d = PyDict::new(py);
        match b {
            Ok(info) => {
                d.set_item("name", info.backend.name())?;
                d.set_item("available", true)?;
                d.set_item("version", info.version)?;
                d.set_item("detail", info.detail)?;
            }
            Err(why) => {
                let name = why.split(':').next().unwrap_or("").to_string();
                d.set_item("name", name)?;
                d.set_item("available", false)?;
                d.set_item("version", py.None())?;
                d.set_item("detail", why)?;
            }
        }
        out.push(d);
    }
    Ok(out)
}

/// The transfer-matrix reflectance and transmittance of a `[stack]` sample at
/// `theta_i_deg` (degrees; `theta_i`, its old name, still taken for one release): a dict of
/// numpy arrays `lambda_nm`, `Rs`, `Rp`, `R`, `Ts`, `Tp`, `T` (`goniospec analytic`).
#[pyfunction]
#[pyo3(signature = (sample, theta_i_deg = None, wavelengths = goniospec::spectrum::DEFAULT_WAVELENGTHS, monochromatic = false, *, theta_i = None))]
fn analytic<'py>(
    py: Python<'py>,
    sample: &Sample,
    theta_i_deg: Option<f64>,
    wavelengths: &str,
    monochromatic: bool,
    theta_i: Option<f64>,
) -> PyResult<Bound<'py, PyDict>> {
    let theta_i = match (theta_i_deg, theta_i) {
        (Some(t), None) | (None, Some(t)) => t,
        (Some(_), Some(_)) => {
            return Err(value_err(
                "analytic(): give theta_i_deg, or its old name theta_i, not both",
            ));
        }
        (None, None) => {
            return Err(pyo3::exceptions::PyTypeError::new_err(
                "analytic() needs the incident angle theta_i_deg (degrees)",
            ));
        }
    };
    let w = goniospec::spectrum::Wavelengths::parse(wavelengths, monochromatic)
        .map_err(|e| value_err(format!("wavelengths: {e}")))?;
    let rows = goniospec::reference::analytic(&sample.inner, theta_i, &w).map_err(value_err)?;
    let col = |f: &dyn Fn(&(f64, goniospec::optics::tmm::Rt)) -> f64| {
        rows.iter().map(f).collect::<Vec<f64>>().into_pyarray(py)
    };
    let d = PyDict::new(py);
    d.set_item("lambda_nm", col(&|x| x.0))?;
    d.set_item("Rs", col(&|x| x.1.r_s))?;
    d.set_item("Rp", col(&|x| x.1.r_p))?;
    d.set_item("R", col(&|x| x.1.r()))?;
    d.set_item("Ts", col(&|x| x.1.t_s))?;
    d.set_item("Tp", col(&|x| x.1.t_p))?;
    d.set_item("T", col(&|x| x.1.t()))?;
    d.set_item("delta_deg", col(&|x| x.1.delta_deg()))?;
    Ok(d)
}

#[pymodule]
fn _goniospec(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Sample>()?;
    m.add_class::<Accumulator>()?;
    m.add_class::<Brdf>()?;
    m.add_class::<Measured>()?;
    m.add_function(wrap_pyfunction!(load, m)?)?;
    m.add_function(wrap_pyfunction!(load_brdf, m)?)?;
    m.add_function(wrap_pyfunction!(simulate, m)?)?;
    m.add_function(wrap_pyfunction!(analytic, m)?)?;
    m.add_function(wrap_pyfunction!(backends, m)?)?;
    Ok(())
}
