//! One function per parser: each takes arbitrary bytes and must return (an error is
//! fine) without panicking, aborting or hanging. Binary formats get their checksum
//! recomputed first, so mutations reach the content validation behind it.

use std::path::Path;

use goniospec::sample::{self, MeshOptions};

/// A harness: arbitrary bytes in, nothing out.
pub type Harness = fn(&[u8]);

/// The targets, by name.
pub const TARGETS: &[(&str, Harness)] = &[
    ("obj", obj),
    ("sample", sample),
    ("media-table", media_table),
    ("media-model", media_model),
    ("gsa", gsa),
    ("gsb", gsb),
    ("bsdf", bsdf),
    ("study", study),
    ("cli-values", cli_values),
    ("x3p", x3p),
    ("gsf", gsf),
    ("npy", npy),
    ("exr", exr),
    ("png", png),
    ("tiff", tiff),
    ("ply", ply),
    ("stl", stl),
    ("mesh-cache", mesh_cache),
    ("batch-plan", batch_plan),
    ("batch-manifest", batch_manifest),
];

/// The target called `name`.
pub fn target(name: &str) -> Option<Harness> {
    TARGETS.iter().find(|(n, _)| *n == name).map(|(_, f)| *f)
}

/// Where relative paths in fuzzed files resolve: a folder that does not exist, so a
/// fuzzed sample or study never reads the repository's files by accident.
fn base() -> &'static Path {
    Path::new("/nonexistent-goniospec-fuzz/input")
}

fn text(data: &[u8]) -> Option<&str> {
    std::str::from_utf8(data).ok()
}

pub fn obj(data: &[u8]) {
    if let Some(t) = text(data) {
        for drop_degenerate in [false, true] {
            let _ = sample::parse_obj(
                base(),
                t,
                1000.0,
                MeshOptions {
                    drop_degenerate,
                    ..MeshOptions::default()
                },
            );
        }
    }
}

pub fn sample(data: &[u8]) {
    if let Some(t) = text(data) {
        let _ = sample::parse(&base().join("s.toml"), t, MeshOptions::default());
    }
}

pub fn media_table(data: &[u8]) {
    if let Some(t) = text(data)
        && let Ok(m) = sample::media::parse_table(base(), t)
    {
        for l in [200.0, 380.0, 550.0, 780.0, 2000.0] {
            let _ = m.eval(l);
        }
    }
}

pub fn media_model(data: &[u8]) {
    if let Some(t) = text(data)
        && let Ok(m) = sample::media::parse_model_file(&base().join("m.toml"), t)
    {
        for l in [200.0, 380.0, 550.0, 780.0, 2000.0] {
            let _ = m.eval(l);
        }
    }
}

/// Replaces the trailing checksum of a current-version file with the right one, so the
/// fuzzer reaches the parsers behind it (legacy-version seeds keep their own checksum).
fn with_checksum(data: &[u8], format: &goniospec::container::Format) -> Vec<u8> {
    let mut b = data.to_vec();
    if b.get(8..12) == Some(&format.version.to_le_bytes()[..]) {
        goniospec::container::reseal(&mut b);
    }
    b
}

pub fn gsa(data: &[u8]) {
    let b = with_checksum(data, &goniospec::accumulate::file::FORMAT);
    if let Ok(acc) = goniospec::accumulate::file::Accumulator::from_bytes(&b, "fuzz.gsa") {
        // What readers do next: merge with itself (refused: same seed), build a BRDF.
        let mut m = acc.clone();
        let _ = m.merge(&acc);
        let _ = goniospec::brdf::BucketData::from_accumulator(&acc);
    }
}

pub fn gsb(data: &[u8]) {
    use goniospec::brdf::{Brdf};
    use goniospec::geom::from_spherical;
    let b = with_checksum(data, &goniospec::brdf::file::FORMAT);
    if let Ok(r) = goniospec::brdf::file::from_bytes(&b, "fuzz.gsb") {
        let mut out = vec![0.0; r.meta().lambda_nm.len()];
        for (ti, to, p) in [(0.0, 0.3, 1.0), (0.7, 0.7, 3.1), (1.5, 0.1, 6.0)] {
            r.eval(from_spherical(ti, 0.0), from_spherical(to, p), &mut out);
        }
    }
}

/// An RGL `.bsdf` (a measured material of the RGL database, or an export): the tensor
/// reader, the measured reader's checks and interpolants, an evaluation and the nodes'
/// directions.
pub fn bsdf(data: &[u8]) {
    use goniospec::brdf::Brdf;
    use goniospec::geom::from_spherical;
    let Ok(fields) = goniospec::export::tensor::from_bytes(data) else {
        return;
    };
    if let Ok(m) = goniospec::export::measured::MeasuredBrdf::from_fields(&fields) {
        let mut out = vec![0.0; m.channels()];
        for (ti, to, p) in [(0.0, 0.3, 1.0), (0.7, 0.7, 3.1), (1.5, 0.1, 6.0)] {
            m.eval(from_spherical(ti, 0.0), from_spherical(to, p), &mut out);
            let _ = m.node_direction(ti, 0.0, 0, 1);
        }
        let _ = m.describe();
    }
}

pub fn study(data: &[u8]) {
    if let Some(t) = text(data) {
        let _ = goniospec::study::parse(&base().join("study.toml"), t);
    }
}

/// The command line's value parsers: `--wavelengths` (both modes) and `--light`, `--env`.
pub fn cli_values(data: &[u8]) {
    if let Some(t) = text(data) {
        for mono in [false, true] {
            let _ = goniospec::simulate::Wavelengths::parse(t, mono);
        }
        let _ = goniospec::render::Light::parse(t);
        let _ = goniospec::render::Env::parse(t);
    }
}

/// A height map in `format` (its scale given where the format has none), then what the
/// loader does next: fill missing points, mesh it with each edge mode.
fn heightmap(format: goniospec::sample::heightmap::Format, data: &[u8]) {
    use goniospec::sample::heightmap::{self, Edges, Missing, Scale};
    let scale = (!format.is_calibrated()).then_some(Scale {
        dx_nm: 10.0,
        dy_nm: 10.0,
        dz_nm: 1.0,
    });
    if let Ok(mut m) = heightmap::from_bytes(format, data, scale)
        && m.resolve_missing(Missing::Fill).is_ok()
        && m.nx * m.ny <= 1 << 16
    {
        for e in [Edges::Mirror, Edges::Periodic, Edges::Guard] {
            let _ = m.mesh(e);
        }
    }
}

pub fn x3p(data: &[u8]) {
    heightmap(goniospec::sample::heightmap::Format::X3p, data);
}

pub fn gsf(data: &[u8]) {
    heightmap(goniospec::sample::heightmap::Format::Gsf, data);
}

pub fn npy(data: &[u8]) {
    heightmap(goniospec::sample::heightmap::Format::Npy, data);
}

pub fn exr(data: &[u8]) {
    heightmap(goniospec::sample::heightmap::Format::Exr, data);
}

pub fn png(data: &[u8]) {
    heightmap(goniospec::sample::heightmap::Format::Png, data);
}

pub fn tiff(data: &[u8]) {
    heightmap(goniospec::sample::heightmap::Format::Tiff, data);
}

pub fn ply(data: &[u8]) {
    for drop_degenerate in [false, true] {
        let opts = MeshOptions {
            drop_degenerate,
            ..MeshOptions::default()
        };
        let _ = sample::plystl::parse_ply(&base().join("m.ply"), data, 1000.0, opts);
    }
}

pub fn stl(data: &[u8]) {
    for drop_degenerate in [false, true] {
        let opts = MeshOptions {
            drop_degenerate,
            ..MeshOptions::default()
        };
        let _ = sample::plystl::parse_stl(&base().join("m.stl"), data, 1000.0, opts);
    }
}

/// The mesh cache: its checksum recomputed so mutations reach the content checks, the
/// key taken from the file itself (a cache is only ever used under its own key).
pub fn mesh_cache(data: &[u8]) {
    use goniospec::sample::cache::{FORMAT, decode};
    let b = with_checksum(data, &FORMAT);
    if let Ok(frame) = goniospec::container::decode(&FORMAT, &b, "fuzz.gsmesh") {
        let key = frame.header.to_string();
        if let Some(m) = decode(&b, &key) {
            let _ = m.bounds();
        }
    }
}

pub fn batch_plan(data: &[u8]) {
    if let Some(t) = text(data) {
        let _ = goniospec::batch::Manifest::plan_text(&base().join("plan.toml"), t);
    }
}

/// A manifest, then what status and run ask of it: every unit's material and config.
pub fn batch_manifest(data: &[u8]) {
    if let Some(t) = text(data)
        && let Ok(m) = goniospec::batch::Manifest::from_text(&base().join("manifest.toml"), t)
    {
        for u in &m.units {
            let _ = m.material(&u.material);
            let _ = m.unit_config(u);
        }
        let _ = m.shard(1, 2);
    }
}
