//! Procedural periodic microgeometry, written as ordinary meshes (and OBJ files) so every
//! generated sample can be shared and re-imported.
//!
//! Every generator works on the periodic tile `[0, Lx) x [0, Ly)` in nanometres. Sheets
//! (height fields, films, microfacets, grooves) span the whole tile and their opposite
//! boundary edges coincide after a shift by the tile size; bodies (pigments, flakes) are
//! closed meshes kept inside the tile. Every generator is deterministic in its seed.
//!
//! Resolution parameters say what they control: `resolution` is grid cells per tile side
//! for height fields (the mesh has `2 * resolution^2` triangles), `subdivisions` the
//! icosphere level of a pigment (20 * 4^level triangles).

use serde::Deserialize;

use super::mesh::Mesh;

/// What a generator refuses: an unknown kind or key, a value of the wrong type or outside its range, more triangles or bodies than the limits allow.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GenerateError {
    /// The message says what and where.
    #[error("{0}")]
    Invalid(String),
}

message_error!(GenerateError, GenerateError::Invalid);

mod bodies;
pub(crate) mod height;
mod microfacet;

pub use bodies::{enclosed_volume, flakes, icosphere, pigment_spheres};
pub use height::{cosine_surface, flat, gaussian_heights, grid_mesh, height_field, v_grooves};
pub use microfacet::{Distribution, MIN_CELLS_PER_CORRELATION, microfacet_surface};

/// The most triangles one generator makes: 2^26 (67 million), about 10 GB once the
/// accelerators are built (docs/design.md §2; the largest height field, resolution
/// 4096, makes 2 x 4096^2 = 33.5 million).
pub const MAX_GENERATED_TRIANGLES: u64 = 1 << 26;

/// The most bodies one generator places (each becomes an interface of its own).
pub const MAX_BODIES: u64 = 1_000_000;

/// Which surface of a wavy film.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FilmSurface {
    Top,
    Bottom,
}

/// A generator as written in a sample (`generator = { kind = "...", ... }`) or on the
/// command line (`goniospec generate KIND --param key=value`). Lengths are in the sample's
/// unit; `resolution` counts grid cells per tile side.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum GeneratorSpec {
    /// A flat plane at height `z`.
    Flat {
        #[serde(default)]
        z: f64,
    },
    /// A periodic Gaussian random height field: RMS height `rms`, Gaussian correlation
    /// length `correlation_length`, mean height `z`.
    Gaussian {
        rms: f64,
        correlation_length: f64,
        resolution: usize,
        #[serde(default = "default_seed")]
        seed: u64,
        #[serde(default)]
        z: f64,
    },
    /// One surface of the seed's wavy film: both surfaces follow one Gaussian roughness
    /// (`roughness_rms`), and the thickness `thickness` varies by `thickness_rms`, both
    /// with correlation length `correlation_length`. The film's lower surface has mean
    /// height `z`. Use the same parameters and seed for `surface = "top"` and `"bottom"`.
    WavyFilm {
        surface: FilmSurface,
        thickness: f64,
        thickness_rms: f64,
        roughness_rms: f64,
        correlation_length: f64,
        resolution: usize,
        #[serde(default = "default_seed")]
        seed: u64,
        #[serde(default)]
        z: f64,
    },
    /// A microfacet surface whose facet normals follow GGX or Beckmann with roughness
    /// `alpha`; `resolution` facets per tile side.
    Microfacet {
        distribution: Distribution,
        alpha: f64,
        resolution: usize,
        /// Correlation length of the heights, in the sample's unit (default: tile / 8).
        correlation_length: Option<f64>,
        #[serde(default = "default_seed")]
        seed: u64,
        #[serde(default)]
        z: f64,
    },
    /// A gently curved sheet: `z + amplitude cos(2 pi x / Lx)`, one period across the tile
    /// along x, flat along y; `resolution` cells along x. The steepest slope is
    /// `atan(2 pi amplitude / Lx)`. Two sheets with the same amplitude and different `z`
    /// make a curved film of constant vertical thickness.
    Cosine {
        amplitude: f64,
        resolution: usize,
        #[serde(default)]
        z: f64,
    },
    /// A periodic wedge: `z + tan(slope_deg) |x - Lx/2|`, a roof of two planes of slope
    /// `slope_deg` across the tile (one kink at the centre, one at the edges). Over a flat
    /// sheet it makes a film whose thickness varies linearly, by `tan(slope) Lx / 2`.
    Wedge {
        slope_deg: f64,
        #[serde(default)]
        z: f64,
    },
    /// `count` symmetric V-grooves along y with opening angle `angle_deg`, ridges at `z`.
    VGrooves {
        angle_deg: f64,
        count: usize,
        #[serde(default)]
        z: f64,
    },
    /// Pigment spheres (bodies) in the layer `layer = [z0, z1]`.
    PigmentSpheres {
        radius: f64,
        volume_fraction: f64,
        #[serde(deserialize_with = "exactly_two")]
        layer: [f64; 2],
        #[serde(default = "default_subdivisions")]
        subdivisions: u32,
        #[serde(default = "default_seed")]
        seed: u64,
    },
    /// Square pearlescent flakes (bodies) in the layer `layer = [z0, z1]`, optionally
    /// coated (`coating` thickness; the body then needs a `coating` medium).
    Flakes {
        size: f64,
        thickness: f64,
        tilt_sd_deg: f64,
        #[serde(default)]
        coating: f64,
        volume_fraction: f64,
        #[serde(deserialize_with = "exactly_two")]
        layer: [f64; 2],
        #[serde(default = "default_seed")]
        seed: u64,
    },
}

/// A `[z0, z1]` pair: exactly two numbers (serde would otherwise ignore extra ones).
fn exactly_two<'de, D: serde::Deserializer<'de>>(d: D) -> Result<[f64; 2], D::Error> {
    let v = Vec::<f64>::deserialize(d)?;
    <[f64; 2]>::try_from(v.as_slice()).map_err(|_| {
        serde::de::Error::custom(format!(
            "expected [z0, z1] (two numbers), got {} values",
            v.len()
        ))
    })
}

fn default_seed() -> u64 {
    1
}
fn default_subdivisions() -> u32 {
    2
}

/// What a generator produced.
#[derive(Clone, Debug)]
pub enum Generated {
    /// A sheet spanning the tile.
    Sheet(Mesh),
    /// Closed bodies, each with an optional coating shell.
    Bodies(Vec<(Mesh, Option<Mesh>)>),
}

impl Generated {
    /// The bodies' cores as one mesh and their coating shells as another (empty when the
    /// bodies are bare); a sheet is its own core.
    pub fn merged(&self) -> (Mesh, Mesh) {
        match self {
            Generated::Sheet(m) => (m.clone(), Mesh::default()),
            Generated::Bodies(bodies) => {
                let (mut cores, mut shells) = (Mesh::default(), Mesh::default());
                for (c, s) in bodies {
                    cores.append(c);
                    if let Some(s) = s {
                        shells.append(s);
                    }
                }
                (cores, shells)
            }
        }
    }
}

impl GeneratorSpec {
    /// A generator from its kind and `KEY=VALUE` parameters as the command line gives
    /// them: each value is a TOML value (number, "string", [array]), and a bare word that
    /// is not one (`ggx`, `top`) is taken as a string. Unknown kinds and keys, and values
    /// of the wrong type, are refused with the generator's name.
    pub fn from_key_values(kind: &str, params: &[String]) -> Result<GeneratorSpec, GenerateError> {
        let mut text = format!("kind = {kind:?}\n");
        for p in params {
            let (k, v) = p
                .split_once('=')
                .ok_or_else(|| format!("--param '{p}' is not KEY=VALUE"))?;
            let (k, v) = (k.trim(), v.trim());
            if k.is_empty() || !k.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
                return Err(GenerateError::from(format!(
                    "--param '{p}': '{k}' is not a parameter name"
                )));
            }
            let value = if toml::from_str::<toml::Table>(&format!("x = {v}")).is_ok() {
                v.to_string()
            } else {
                format!("{v:?}")
            };
            text.push_str(&format!("{k} = {value}\n"));
        }
        toml::from_str(&text).map_err(|e| {
            GenerateError::Invalid(format!("generator '{kind}': {}", e.message().trim()))
        })
    }

    /// The kind's name as written in TOML.
    pub fn kind(&self) -> &'static str {
        match self {
            GeneratorSpec::Flat { .. } => "flat",
            GeneratorSpec::Gaussian { .. } => "gaussian",
            GeneratorSpec::WavyFilm { .. } => "wavy-film",
            GeneratorSpec::Microfacet { .. } => "microfacet",
            GeneratorSpec::VGrooves { .. } => "v-grooves",
            GeneratorSpec::Cosine { .. } => "cosine",
            GeneratorSpec::Wedge { .. } => "wedge",
            GeneratorSpec::PigmentSpheres { .. } => "pigment-spheres",
            GeneratorSpec::Flakes { .. } => "flakes",
        }
    }

    /// Whether the generator makes closed bodies (else a sheet).
    pub fn makes_bodies(&self) -> bool {
        matches!(
            self,
            GeneratorSpec::PigmentSpheres { .. } | GeneratorSpec::Flakes { .. }
        )
    }

    /// Runs the generator; `u` is nanometres per sample unit. Sizes are checked before
    /// anything is allocated, and every coordinate of the result must be finite and within
    /// [`crate::sample::MAX_LENGTH_NM`] (a NaN `z` or a huge amplitude is refused, not written).
    pub fn generate(&self, tile_nm: [f64; 2], u: f64) -> Result<Generated, GenerateError> {
        let out = self.run(tile_nm, u)?;
        let meshes: Vec<&Mesh> = match &out {
            Generated::Sheet(m) => vec![m],
            Generated::Bodies(b) => b
                .iter()
                .flat_map(|(c, s)| std::iter::once(c).chain(s.as_ref()))
                .collect(),
        };
        let lim = crate::sample::MAX_LENGTH_NM;
        for m in meshes {
            if let Some(c) = m
                .positions_nm
                .iter()
                .flat_map(|p| p.to_array())
                .find(|c| !(c.is_finite() && c.abs() <= lim))
            {
                return Err(GenerateError::from(format!(
                    "a generated coordinate is {c:e} nm: lengths (z, amplitude, layer, ...) must be finite and keep the mesh within +-{lim:e} nm"
                )));
            }
        }
        Ok(out)
    }

    fn run(&self, tile_nm: [f64; 2], u: f64) -> Result<Generated, GenerateError> {
        Ok(match *self {
            GeneratorSpec::Flat { z } => Generated::Sheet(flat(tile_nm, z * u)),
            GeneratorSpec::Gaussian {
                rms,
                correlation_length,
                resolution,
                seed,
                z,
            } => {
                check_resolution(resolution)?;
                let h =
                    gaussian_heights(seed, tile_nm, resolution, rms * u, correlation_length * u)?;
                Generated::Sheet(grid_mesh(tile_nm, resolution, &h, z * u))
            }
            GeneratorSpec::WavyFilm {
                surface,
                thickness,
                thickness_rms,
                roughness_rms,
                correlation_length,
                resolution,
                seed,
                z,
            } => {
                check_resolution(resolution)?;
                let h = wavy_film(
                    seed,
                    tile_nm,
                    resolution,
                    surface,
                    thickness * u,
                    thickness_rms * u,
                    roughness_rms * u,
                    correlation_length * u,
                )?;
                Generated::Sheet(grid_mesh(tile_nm, resolution, &h, z * u))
            }
            GeneratorSpec::Microfacet {
                distribution,
                alpha,
                resolution,
                correlation_length,
                seed,
                z,
            } => {
                check_resolution(resolution)?;
                let corr = correlation_length.map_or(tile_nm[0] / 8.0, |l| l * u);
                Generated::Sheet(microfacet_surface(
                    seed,
                    tile_nm,
                    resolution,
                    distribution,
                    alpha,
                    corr,
                    z * u,
                )?)
            }
            GeneratorSpec::VGrooves {
                angle_deg,
                count,
                z,
            } => Generated::Sheet(v_grooves(tile_nm, count, angle_deg, z * u)?),
            GeneratorSpec::Cosine {
                amplitude,
                resolution,
                z,
            } => {
                check_resolution(resolution)?;
                if !amplitude.is_finite() {
                    return Err(GenerateError::from(format!(
                        "amplitude must be finite, got {amplitude}"
                    )));
                }
                let (a, z, lx) = (amplitude * u, z * u, tile_nm[0]);
                Generated::Sheet(height_field([resolution, 1], tile_nm, move |x, _| {
                    z + a * (std::f64::consts::TAU * x / lx).cos()
                }))
            }
            GeneratorSpec::Wedge { slope_deg, z } => {
                if slope_deg.is_nan() || slope_deg.abs() >= 45.0 {
                    return Err(GenerateError::from(format!(
                        "slope_deg must lie between -45 and 45 degrees, got {slope_deg}"
                    )));
                }
                let (s, z, lx) = (slope_deg.to_radians().tan(), z * u, tile_nm[0]);
                // Two cells along x put the kink exactly on a grid line.
                Generated::Sheet(height_field([2, 1], tile_nm, move |x, _| {
                    z + s * (x - lx / 2.0).abs()
                }))
            }
            GeneratorSpec::PigmentSpheres {
                radius,
                volume_fraction,
                layer,
                subdivisions,
                seed,
            } => {
                if subdivisions > 5 {
                    return Err(GenerateError::from(format!(
                        "subdivisions must be at most 5 (20 * 4^5 triangles per sphere), got {subdivisions}"
                    )));
                }
                Generated::Bodies(
                    pigment_spheres(
                        seed,
                        tile_nm,
                        radius * u,
                        volume_fraction,
                        layer.map(|v| v * u),
                        subdivisions,
                    )?
                    .into_iter()
                    .map(|m| (m, None))
                    .collect(),
                )
            }
            GeneratorSpec::Flakes {
                size,
                thickness,
                tilt_sd_deg,
                coating,
                volume_fraction,
                layer,
                seed,
            } => Generated::Bodies(flakes(
                seed,
                tile_nm,
                size * u,
                thickness * u,
                tilt_sd_deg,
                coating * u,
                volume_fraction,
                layer.map(|v| v * u),
            )?),
        })
    }
}

/// Heights (nm) of one surface of a wavy film of mean thickness `t` nm: a rough mid-surface
/// (RMS `roughness_rms` nm) shared by both faces, and a thickness variation (RMS
/// `thickness_rms` nm, the next seed) split between them; both Gaussian-correlated over
/// `l` nm. Refused where the film would vanish.
#[allow(clippy::too_many_arguments)]
fn wavy_film(
    seed: u64,
    tile_nm: [f64; 2],
    resolution: usize,
    surface: FilmSurface,
    t: f64,
    thickness_rms: f64,
    roughness_rms: f64,
    l: f64,
) -> Result<Vec<f64>, GenerateError> {
    if t.is_nan() || t <= 0.0 {
        return Err(GenerateError::from(format!(
            "thickness must be positive, got {t} nm"
        )));
    }
    let rough = gaussian_heights(seed, tile_nm, resolution, roughness_rms, l)?;
    let var = gaussian_heights(seed.wrapping_add(1), tile_nm, resolution, thickness_rms, l)?;
    if let Some(min) = var.iter().map(|v| t + v).reduce(f64::min)
        && min <= 0.0
    {
        return Err(GenerateError::from(format!(
            "the thickness variation makes the film vanish (minimum thickness {min:.1} nm); lower thickness_rms"
        )));
    }
    Ok(rough
        .iter()
        .zip(&var)
        .map(|(r, v)| match surface {
            FilmSurface::Top => t + r + v / 2.0,
            FilmSurface::Bottom => r - v / 2.0,
        })
        .collect())
}

/// A height-field resolution: 1 to 4096 cells per side, and, since the mesh and the
/// spectral arrays behind it are built in memory, no more than this machine has
/// available (about 100 bytes per triangle while generating).
fn check_resolution(r: usize) -> Result<(), GenerateError> {
    if !(1..=4096).contains(&r) {
        return Err(GenerateError::from(format!(
            "resolution must be between 1 and 4096 cells per side, got {r}"
        )));
    }
    let bytes = 2.0 * (r as f64).powi(2) * GENERATE_BYTES_PER_TRIANGLE;
    if let Some(avail) = crate::io::available_memory_bytes()
        && bytes > avail as f64
    {
        return Err(GenerateError::from(format!(
            "resolution {r} needs about {:.1} GB to generate, more than the {:.1} GB available",
            bytes / 1e9,
            avail as f64 / 1e9
        )));
    }
    Ok(())
}

/// Bytes per height-field triangle while generating (mesh, heights, FFT buffers).
const GENERATE_BYTES_PER_TRIANGLE: f64 = 100.0;

#[cfg(test)]
mod tests {
    use super::*;

    fn kv(kind: &str, p: &[&str]) -> Result<GeneratorSpec, GenerateError> {
        GeneratorSpec::from_key_values(kind, &p.iter().map(|s| s.to_string()).collect::<Vec<_>>())
    }

    #[test]
    fn key_values_become_a_typed_spec() {
        let g = kv(
            "gaussian",
            &[
                "rms=0.1",
                " correlation_length = 2",
                "resolution=64",
                "seed=7",
            ],
        )
        .unwrap();
        assert_eq!(
            g,
            GeneratorSpec::Gaussian {
                rms: 0.1,
                correlation_length: 2.0,
                resolution: 64,
                seed: 7,
                z: 0.0
            }
        );
        // A bare word is a string: the distribution's name.
        let m = kv(
            "microfacet",
            &["distribution=ggx", "alpha=0.2", "resolution=32"],
        )
        .unwrap();
        assert!(matches!(
            m,
            GeneratorSpec::Microfacet {
                distribution: Distribution::Ggx,
                ..
            }
        ));
    }

    #[test]
    fn bad_key_values_are_refused_by_name() {
        let e = kv("gaussian", &["rms"]).unwrap_err().to_string();
        assert!(e.contains("'rms' is not KEY=VALUE"), "{e}");
        let e = kv("gaussian", &["=1"]).unwrap_err().to_string();
        assert!(e.contains("not a parameter name"), "{e}");
        let e = kv(
            "gaussian",
            &[
                "rms=0.1",
                "colour=1",
                "correlation_length=1",
                "resolution=8",
            ],
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("generator 'gaussian'") && e.contains("colour"),
            "{e}"
        );
        let e = kv(
            "gaussian",
            &["rms=wide", "correlation_length=1", "resolution=8"],
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("generator 'gaussian'"), "{e}");
        let e = kv("teapot", &[]).unwrap_err().to_string();
        assert!(e.contains("teapot"), "{e}");
    }
}
