//! `bench large`: microgeometry of millions of triangles, written once, then loaded and
//! traced.

use std::time::Instant;

use crate::accel::workload::{random_rays, trace_all};
use crate::accel::{Accel, Backend, Hit};
use crate::sample::Mesh;

use super::{raw_rate, shipped};

/// Why `bench large` could not write or measure a sample.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    #[error("{path}: {source}")]
    Io {
        path: std::path::PathBuf,
        source: std::io::Error,
    },
    #[error(transparent)]
    Generate(#[from] crate::sample::generate::GenerateError),
    #[error(transparent)]
    Sample(#[from] crate::sample::SampleError),
    #[error(transparent)]
    Scene(#[from] crate::trace::SceneError),
    #[error(transparent)]
    Accel(#[from] crate::accel::AccelError),
    #[error(transparent)]
    Simulation(#[from] crate::simulate::SimError),
    /// The peer benchmark's other process (`bench peer`).
    #[error("{0}")]
    Peer(String),
}

/// An I/O error at `path`.
pub(super) fn io(path: &std::path::Path) -> impl FnOnce(std::io::Error) -> BenchError + '_ {
    move |source| BenchError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// A sample of `goniospec bench large`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LargeSample {
    /// Rough gold, Gaussian heights (0.2 um RMS, 2.5 um correlation length), 89 nm cells:
    /// about 1M triangles on a 63 um tile.
    Gold1M,
    /// The same surface statistics, about 10M triangles on a 200 um tile.
    Gold10M,
    /// The seed's wavy soap film (600 nm, both surfaces rough) on a 200 um tile, 708^2
    /// cells per surface: about 2M triangles.
    Film2M,
}

impl LargeSample {
    pub const ALL: [LargeSample; 3] = [
        LargeSample::Gold1M,
        LargeSample::Film2M,
        LargeSample::Gold10M,
    ];

    pub fn name(self) -> &'static str {
        match self {
            LargeSample::Gold1M => "gold_1m",
            LargeSample::Gold10M => "gold_10m",
            LargeSample::Film2M => "film_2m",
        }
    }

    pub fn parse(s: &str) -> Option<LargeSample> {
        LargeSample::ALL
            .into_iter()
            .find(|k| k.name() == s.replace('-', "_"))
    }
}

/// Writes the sample `which` into `dir` (OBJ meshes and a TOML description), unless it is
/// already there; returns the TOML's path.
pub fn large_sample(
    dir: &std::path::Path,
    which: LargeSample,
    mut log: impl FnMut(&str),
) -> Result<std::path::PathBuf, BenchError> {
    use crate::sample::generate::GeneratorSpec;
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    let name = which.name();
    let toml = dir.join(format!("{name}.toml"));
    if toml.exists() {
        return Ok(toml);
    }
    let (tile_um, surfaces): (f64, Vec<(String, Vec<String>)>) = match which {
        LargeSample::Gold1M | LargeSample::Gold10M => {
            let (tile, res) = if which == LargeSample::Gold1M {
                (63.0, 707)
            } else {
                (200.0, 2236)
            };
            (
                tile,
                vec![(
                    "gaussian".into(),
                    vec![
                        "rms=0.2".into(),
                        "correlation_length=2.5".into(),
                        format!("resolution={res}"),
                        "seed=1".into(),
                    ],
                )],
            )
        }
        LargeSample::Film2M => (
            200.0,
            ["top", "bottom"]
                .iter()
                .map(|s| {
                    (
                        "wavy-film".to_string(),
                        vec![
                            format!("surface={s}"),
                            "thickness=0.6".into(),
                            "thickness_rms=0.008".into(),
                            "roughness_rms=0.06".into(),
                            "correlation_length=2".into(),
                            "resolution=708".into(),
                            "seed=7".into(),
                        ],
                    )
                })
                .collect(),
        ),
    };
    let mut meshes = Vec::new();
    for (k, (kind, params)) in surfaces.iter().enumerate() {
        let path = dir.join(format!("{name}-{k}.obj"));
        log(&format!(
            "# generating {} ({kind} {})",
            path.display(),
            params.join(" ")
        ));
        let spec = GeneratorSpec::from_key_values(kind, params)?;
        let out = spec.generate([tile_um * 1000.0; 2], 1000.0)?;
        let (mesh, _) = out.merged();
        mesh.write_obj(
            &path,
            1000.0,
            &format!("goniospec bench large: {kind} {}", params.join(" ")),
        )
        .map_err(io(&path))?;
        meshes.push(path);
    }
    let interfaces = match which {
        LargeSample::Film2M => format!(
            "[media.soap]\nn = 1.33\n[[interface]]\nmesh = \"{name}-0.obj\"\nfront = \"air\"\nback = \"soap\"\n[[interface]]\nmesh = \"{name}-1.obj\"\nfront = \"soap\"\nback = \"air\"\n"
        ),
        _ => format!(
            "[media.gold]\ntable = \"{}\"\n[[interface]]\nmesh = \"{name}-0.obj\"\nfront = \"air\"\nback = \"gold\"\n",
            std::path::absolute(shipped(std::path::Path::new("data/au-johnson.csv")))
                .unwrap_or_default()
                .display()
        ),
    };
    let text = format!(
        "# goniospec bench large\n[sample]\nname = \"{name}\"\nunit = \"um\"\ntile = [{tile_um}, {tile_um}]\n[media.air]\nn = 1.0\n{interfaces}"
    );
    crate::io::write_atomic(&toml, |w| std::io::Write::write_all(w, text.as_bytes()))
        .map_err(io(&toml))?;
    Ok(toml)
}

/// Measures one large sample, in this process (so the peak memory is this sample's):
/// reading its mesh files once, loading it without and with the mesh cache, building the
/// Embree scene, the raw intersector's random-ray rate on its geometry, and a simulation
/// of `rays` trees at 30 degrees over 40 bins (380-780 nm); one `name: value unit` line
/// per figure, prefixed with `key`.
pub fn large_case(
    sample_path: &std::path::Path,
    key: &str,
    rays: u64,
    mut log: impl FnMut(&str),
) -> Result<(), BenchError> {
    use crate::sample::{self, MeshOptions, cache};
    use crate::simulate::{SimConfig, Wavelengths, simulate};
    // Which mesh files the sample names: every interface's source.
    let first = sample::load(
        sample_path,
        MeshOptions {
            cache: cache::CachePolicy::Off,
            ..Default::default()
        },
    )?;
    let meshes: Vec<std::path::PathBuf> = first
        .interfaces
        .iter()
        .map(|i| i.mesh_path.clone())
        .filter(|p| p.is_file())
        .collect();
    drop(first);
    let bytes: u64 = meshes
        .iter()
        .map(|p| std::fs::metadata(p).map(|m| m.len()).unwrap_or(0))
        .sum();
    let t0 = Instant::now();
    for p in &meshes {
        std::hint::black_box(std::fs::read(p).map_err(io(p))?);
    }
    let read_s = t0.elapsed().as_secs_f64();
    for p in &meshes {
        let _ = std::fs::remove_file(cache::cache_path(p));
    }
    let opts = MeshOptions {
        cache: cache::CachePolicy::Always,
        ..Default::default()
    };
    let t0 = Instant::now();
    drop(sample::load(sample_path, opts)?);
    let cold_s = t0.elapsed().as_secs_f64();
    let t0 = Instant::now();
    let s = sample::load(sample_path, opts)?;
    let cached_s = t0.elapsed().as_secs_f64();
    let triangles = s.triangle_count();
    let t0 = Instant::now();
    let scene = crate::trace::Scene::new(&s, Backend::Embree)?;
    let build_s = t0.elapsed().as_secs_f64();
    drop(scene);
    // The raw intersector on the same geometry: random rays through the tile.
    let mut mesh = Mesh::default();
    for i in &s.interfaces {
        mesh.append(&i.mesh);
    }
    let accel = Accel::build(Backend::Embree, &mesh.to_soup())?;
    let rays_raw = random_rays(&mesh, 1_000_000, 1);
    drop(mesh);
    let mut hits = vec![Hit::MISS; rays_raw.len()];
    trace_all(&accel, &rays_raw[..50_000], &mut hits[..50_000]);
    let raw = raw_rate(&accel, &rays_raw, &mut hits, 3);
    drop((accel, rays_raw, hits));
    let edges: Vec<f64> = (0..=40).map(|k| 380.0 + 10.0 * f64::from(k)).collect();
    let cfg = SimConfig {
        backend: Backend::Embree,
        ..SimConfig::new(vec![30.0], Wavelengths::Bins(edges), rays)
    };
    let (_, st) = simulate(&s, &cfg, &|_| {})?;
    let seg_rate = st.segments as f64 / st.trace_seconds();
    let peak = crate::io::peak_rss_mb().unwrap_or(f64::NAN);
    for (name, value, unit) in [
        ("triangles", triangles as f64, "triangles"),
        ("mesh_file_bytes", bytes as f64, "B"),
        ("read_files_once_s", read_s, "s"),
        ("load_parse_s", cold_s, "s"),
        ("load_cached_s", cached_s, "s"),
        ("build_embree_s", build_s, "s"),
        ("load_cached_plus_build_s", cached_s + build_s, "s"),
        ("raw_embree_rays_per_s", raw, "rays/s"),
        ("simulate_rays", rays as f64, "trees"),
        ("simulate_s", st.seconds, "s"),
        ("simulate_setup_s", st.setup_seconds, "s"),
        (
            "trees_per_s",
            st.trees as f64 / st.trace_seconds(),
            "trees/s",
        ),
        ("segments_per_s", seg_rate, "segments/s"),
        ("fraction_of_raw_embree", 100.0 * seg_rate / raw, "%"),
        (
            "projected_1e7_rays_s",
            st.setup_seconds + 1e7 * st.trace_seconds() / st.trees as f64,
            "s",
        ),
        ("peak_rss_mb", peak, "MB"),
    ] {
        let v = if value.fract() == 0.0 && value.abs() < 1e15 {
            format!("{value:.0}")
        } else {
            format!("{value:.4}")
        };
        log(&format!("{key}_{name}: {v} {unit}"));
    }
    Ok(())
}
