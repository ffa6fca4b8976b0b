//! Loading samples: the happy path, and one clear error (naming file and line) for every
//! kind of bad input. Each test asserts on the message, not only on failure.

use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};

use goniospec::sample::{self, MeshOptions, SampleErrorKind};

/// A fresh folder under the system temp dir for one test.
fn scratch(tag: &str) -> PathBuf {
    static N: AtomicUsize = AtomicUsize::new(0);
    let d = std::env::temp_dir().join(format!(
        "goniospec-test-{}-{}-{}",
        std::process::id(),
        tag,
        N.fetch_add(1, Ordering::Relaxed)
    ));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

const SQUARE_OBJ: &str = "# unit square at z = 0
v 0 0 0
v 10 0 0
v 10 10 0
v 0 10 0
f 1 2 3
f 1 3 4
";

fn toml_with(mesh: &str, extra_header: &str, front: &str, tile: &str) -> String {
    format!(
        r#"[sample]
name = "test"
unit = "um"
tile = {tile}
{extra_header}
[media.air]
n = 1.0
[media.soap]
n = 1.33
k = 0.001

[[interface]]
mesh = "{mesh}"
front = "{front}"
back = "soap"
"#
    )
}

/// Writes `sample.toml` and `m.obj` into a scratch folder and loads the sample.
fn load_case(
    tag: &str,
    toml: &str,
    obj: &str,
    opts: MeshOptions,
) -> Result<sample::Sample, sample::SampleError> {
    let d = scratch(tag);
    std::fs::write(d.join("m.obj"), obj).unwrap();
    std::fs::write(d.join("sample.toml"), toml).unwrap();
    sample::load(&d.join("sample.toml"), opts)
}

fn err_case(tag: &str, toml: &str, obj: &str) -> sample::SampleError {
    load_case(tag, toml, obj, MeshOptions::default()).expect_err("this input must be refused")
}

fn good_toml() -> String {
    toml_with("m.obj", "", "air", "[10.0, 10.0]")
}

#[test]
fn a_valid_sample_loads_in_nanometres() {
    let s = load_case("ok", &good_toml(), SQUARE_OBJ, MeshOptions::default()).unwrap();
    assert_eq!(s.name, "test");
    assert_eq!(s.tile_nm, [10_000.0, 10_000.0]);
    assert_eq!(s.media.len(), 2);
    let itf = &s.interfaces[0];
    assert_eq!(s.media[itf.front].name, "air");
    assert_eq!(s.media[itf.back].name, "soap");
    assert_eq!(
        s.media[itf.back].model,
        goniospec::sample::IndexModel::Constant { n: 1.33, k: 0.001 }
    );
    assert_eq!(itf.mesh.triangles.len(), 2);
    let (lo, hi) = itf.mesh.bounds().unwrap();
    assert_eq!(lo, glam::DVec3::ZERO);
    assert_eq!(hi, glam::DVec3::new(10_000.0, 10_000.0, 0.0)); // 10 um
    // Normals of the square point up (+z), towards "front".
    assert!(itf.mesh.area_vector(0)[2] > 0.0);
    let (soup, first) = s.triangle_soup();
    assert_eq!(soup.triangles.len(), 2);
    assert_eq!(first, vec![0]);
}

#[test]
fn polygons_are_triangulated() {
    let quad = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n";
    let s = load_case("quad", &good_toml(), quad, MeshOptions::default()).unwrap();
    assert_eq!(s.interfaces[0].mesh.triangles.len(), 2);
}

#[test]
fn missing_sample_file() {
    let d = scratch("missing");
    let e = sample::load(&d.join("nope.toml"), MeshOptions::default()).unwrap_err();
    let m = e.to_string();
    assert!(
        m.contains("nope.toml") && m.contains("cannot read file"),
        "{m}"
    );
}

#[test]
fn missing_mesh_file() {
    let e = err_case(
        "missing-mesh",
        &toml_with("absent.obj", "", "air", "[10.0, 10.0]"),
        SQUARE_OBJ,
    );
    let m = e.to_string();
    assert!(
        m.contains("sample.toml:13:"),
        "names the TOML line of the mesh key: {m}"
    );
    assert!(
        m.contains("absent.obj") && m.contains("cannot read file"),
        "{m}"
    );
}

#[test]
fn malformed_obj_names_the_line() {
    let obj = "v 0 0 0\nv 1 0 0\nv 1 abc 0\nf 1 2 3\n";
    let m = err_case("malformed", &good_toml(), obj).to_string();
    assert!(
        m.contains("m.obj:3:") && m.contains("coordinate 2 is not a number"),
        "{m}"
    );

    let obj = "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 7\n";
    let m = err_case("badindex", &good_toml(), obj).to_string();
    assert!(
        m.contains("m.obj:4:") && m.contains("refers to vertex 7"),
        "{m}"
    );

    let obj = "v 0 0\n";
    let m = err_case("short", &good_toml(), obj).to_string();
    assert!(
        m.contains("m.obj:1:") && m.contains("needs 3 coordinates"),
        "{m}"
    );

    // Issue 12, item 9: a trailing comment, CR-only line endings and a byte-order mark are
    // read as the same square; a weight of zero and a concave face are refused at their
    // line.
    let want = load_case("square", &good_toml(), SQUARE_OBJ, MeshOptions::default()).unwrap();
    for (tag, obj) in [
        ("comment", SQUARE_OBJ.replace("\nf", " # corner\nf")),
        ("cr", SQUARE_OBJ.replace('\n', "\r")),
        ("bom", format!("\u{feff}{SQUARE_OBJ}")),
    ] {
        let s = load_case(tag, &good_toml(), &obj, MeshOptions::default()).unwrap();
        assert_eq!(s.interfaces[0].mesh, want.interfaces[0].mesh, "{tag}");
    }
    let m = err_case("w0", &good_toml(), "v 0 0 0 0\n").to_string();
    assert!(m.contains("m.obj:1:") && m.contains("weight"), "{m}");
    let concave = "v 0 0 0\nv 4 0 0\nv 4 4 0\nv 2 1 0\nv 0 4 0\nf 1 2 3 4 5\n";
    let m = err_case("concave", &good_toml(), concave).to_string();
    assert!(m.contains("m.obj:6:") && m.contains("not convex"), "{m}");
}

#[test]
fn nan_and_infinite_coordinates_are_refused() {
    for (tag, bad) in [("nan", "NaN"), ("inf", "inf"), ("neginf", "-inf")] {
        let obj = format!("v 0 0 0\nv 1 0 0\nv 1 1 {bad}\nf 1 2 3\n");
        let e = err_case(tag, &good_toml(), &obj);
        let m = e.to_string();
        assert!(m.contains("m.obj:3:") && m.contains("non-finite"), "{m}");
    }
}

#[test]
fn a_mesh_without_triangles_is_refused() {
    let e = err_case("empty", &good_toml(), "v 0 0 0\nv 1 0 0\n");
    assert!(e.to_string().contains("has no triangles"), "{e}");
    match e.kind {
        SampleErrorKind::Mesh { error, .. } => assert_eq!(error.kind, SampleErrorKind::EmptyMesh),
        other => panic!("wrong kind {other:?}"),
    }
}

#[test]
fn degenerate_triangles_are_counted_and_dropped_only_on_request() {
    // Triangle 2 repeats a vertex, triangle 3 is collinear.
    let obj = format!("{SQUARE_OBJ}f 1 1 2\nv 5 0 0\nf 1 2 5\n");
    let e = err_case("degenerate", &good_toml(), &obj);
    let m = e.to_string();
    assert!(m.contains("2 of 4 triangles are degenerate"), "{m}");
    assert!(
        m.contains("m.obj:8:"),
        "names the first degenerate face's line: {m}"
    );
    assert!(m.contains("--drop-degenerate"), "{m}");

    let s = load_case(
        "degenerate-drop",
        &good_toml(),
        &obj,
        MeshOptions {
            drop_degenerate: true,
            ..MeshOptions::default()
        },
    )
    .unwrap();
    assert_eq!(s.interfaces[0].mesh.triangles.len(), 2);
}

#[test]
fn unknown_medium_names_the_line_and_the_choices() {
    let e = err_case(
        "medium",
        &toml_with("m.obj", "", "vacuum", "[10.0, 10.0]"),
        SQUARE_OBJ,
    );
    let m = e.to_string();
    assert!(m.contains("sample.toml:14:"), "{m}");
    assert!(
        m.contains("unknown medium 'vacuum'") && m.contains("air, soap"),
        "{m}"
    );
}

#[test]
fn bad_tile_sizes_are_refused() {
    for tile in ["[0.0, 10.0]", "[10.0, -1.0]", "[nan, 1.0]", "[inf, 1.0]"] {
        let e = err_case("tile", &toml_with("m.obj", "", "air", tile), SQUARE_OBJ);
        let m = e.to_string();
        assert!(
            m.contains("sample.toml:4:") && m.contains("tile size must be positive"),
            "{tile}: {m}"
        );
    }
}

#[test]
fn unknown_toml_keys_are_refused_with_their_line() {
    let e = err_case(
        "key",
        &toml_with("m.obj", "colour = \"blue\"", "air", "[10.0, 10.0]"),
        SQUARE_OBJ,
    );
    let m = e.to_string();
    assert!(
        m.contains("sample.toml:5:") && m.contains("unknown field `colour`"),
        "{m}"
    );

    let t = good_toml().replace("n = 1.33", "n = 1.33\nkappa = 2.0");
    let m = err_case("key2", &t, SQUARE_OBJ).to_string();
    assert!(m.contains("unknown field `kappa`"), "{m}");
}

#[test]
fn bad_units_and_media_are_refused() {
    let t = good_toml().replace("unit = \"um\"", "unit = \"furlong\"");
    let m = err_case("unit", &t, SQUARE_OBJ).to_string();
    assert!(
        m.contains("sample.toml:3:") && m.contains("unknown unit 'furlong'"),
        "{m}"
    );

    let t = good_toml().replace("k = 0.001", "k = -0.5");
    let m = err_case("negk", &t, SQUARE_OBJ).to_string();
    assert!(
        m.contains("medium 'soap'") && m.contains("k must be finite and >= 0"),
        "{m}"
    );

    let t = good_toml().replace("n = 1.0", "n = 0.0");
    let m = err_case("zeron", &t, SQUARE_OBJ).to_string();
    assert!(
        m.contains("medium 'air'") && m.contains("n must be positive"),
        "{m}"
    );
}

#[test]
fn a_sample_without_interfaces_is_refused() {
    let t = "[sample]\nname = \"x\"\nunit = \"nm\"\ntile = [1.0, 1.0]\n[media.air]\nn = 1.0\n";
    let m = err_case("noif", t, SQUARE_OBJ).to_string();
    assert!(
        m.contains("declares no interface ([stack], [[interface]] or [[body]])"),
        "{m}"
    );
}

#[test]
fn generated_obj_round_trips() {
    let d = scratch("roundtrip");
    let tile = [2000.0, 1000.0];
    let mesh = sample::generate::height_field(
        [7, 5],
        tile,
        sample::generate::cosine_surface(3, tile, 50.0, 6, 3),
    );
    let p = d.join("hf.obj");
    mesh.write_obj(&p, 1000.0, "height field\nin um").unwrap();
    let back = sample::load_obj(&p, 1000.0, MeshOptions::default()).unwrap();
    // The reader renumbers vertices in order of first use; the triangles' corners, in order, must survive.
    assert_eq!(back.triangles.len(), mesh.triangles.len());
    for (ta, tb) in back.triangles.iter().zip(&mesh.triangles) {
        for c in 0..3 {
            let a = back.positions_nm[ta[c] as usize];
            let b = mesh.positions_nm[tb[c] as usize];
            for k in 0..3 {
                assert!(
                    (a[k] - b[k]).abs() <= 1e-9 * b[k].abs().max(1.0),
                    "{a:?} vs {b:?}"
                );
            }
        }
    }
    // The tile wraps: the x = 0 and x = Lx columns have identical heights, as do y = 0, Ly.
    let (nx, ny) = (7, 5);
    for j in 0..=ny {
        let a = mesh.positions_nm[j * (nx + 1)];
        let b = mesh.positions_nm[j * (nx + 1) + nx];
        assert_eq!(a[2], b[2]);
        assert_eq!(b[0] - a[0], tile[0]);
    }
    for i in 0..=nx {
        assert_eq!(
            mesh.positions_nm[i][2],
            mesh.positions_nm[ny * (nx + 1) + i][2]
        );
    }
    // No temporary file is left behind.
    let leftovers: Vec<_> = std::fs::read_dir(&d)
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name())
        .collect();
    assert_eq!(leftovers.len(), 1, "{leftovers:?}");
}

#[test]
fn every_shipped_sample_loads() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes");
    let mut n = 0;
    for e in std::fs::read_dir(&dir).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "toml") {
            let s = sample::load(&p, MeshOptions::default()).unwrap_or_else(|e| panic!("{e}"));
            assert!(s.triangle_count() > 0);
            n += 1;
        }
    }
    assert!(n >= 2, "expected shipped samples in {}", dir.display());
}

#[test]
fn physically_meaningless_indices_are_refused_with_file_and_line() {
    // n = 1e300, 1e-300 or k = 1e300 made R and T NaN with exit status 0.
    let d = std::env::temp_dir().join(format!("goniospec-nk-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    for (medium, want) in [
        ("n = 1e300", "n must be between"),
        ("n = 1e-300", "n must be between"),
        ("n = 1.5\nk = 1e300", "k must be between"),
    ] {
        let p = d.join("m.toml");
        std::fs::write(
            &p,
            format!("[sample]\nname = \"m\"\nunit = \"nm\"\ntile = [1000.0, 1000.0]\n[media.air]\nn = 1.0\n[media.x]\n{medium}\n[stack]\nambient = \"air\"\nsubstrate = \"x\"\n"),
        )
        .unwrap();
        let e = goniospec::sample::load(&p, Default::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains(want) && e.contains("m.toml:7"), "{medium}: {e}");
    }
}
