//! Measured surfaces: every height-map reader against a surface whose heights are known
//! (files written here, with writers independent of the readers), mirror and periodic
//! edges, missing points, bad files; PLY and STL against the same mesh as OBJ; and the
//! physics of a measured patch (a flat one is the Fresnel interface, a non-periodic one
//! equals its OBJ equivalent).

mod common;

use std::io::Write;
use std::path::Path;

use common::*;
use goniospec::sample::{self, MeshOptions, Sample};
use goniospec::simulate::Wavelengths;

/// The known surface, nm, at a point (nm): smooth, not periodic over the patch.
fn surface(x: f64, y: f64) -> f64 {
    120.0 * (x / 900.0).sin() + 80.0 * (y / 1300.0 + 0.3).cos() + 0.02 * x - 0.01 * y
}

const NX: usize = 33;
const NY: usize = 25;
/// Point spacing, nm (x, y).
const DX: f64 = 250.0;
const DY: f64 = 300.0;

fn heights() -> Vec<f64> {
    let mut z = Vec::new();
    for j in 0..NY {
        for i in 0..NX {
            z.push(surface(i as f64 * DX, j as f64 * DY));
        }
    }
    z
}

/// An X3P container: `main.xml` with the axes (metres) and the data as `kind` ("D": f64,
/// "F": f32, "I": int16 counts of `z_inc` metres), optionally a valid-point mask.
fn write_x3p(path: &Path, kind: &str, z_nm: &[f64], z_inc: f64, valid: Option<&[bool]>) {
    let bin: Vec<u8> = match kind {
        "D" => z_nm.iter().flat_map(|z| (z * 1e-9).to_le_bytes()).collect(),
        "F" => z_nm
            .iter()
            .flat_map(|z| ((z * 1e-9) as f32).to_le_bytes())
            .collect(),
        "I" => z_nm
            .iter()
            .flat_map(|z| ((z * 1e-9 / z_inc).round() as i16).to_le_bytes())
            .collect(),
        _ => unreachable!(),
    };
    let inc = if kind == "I" {
        format!("<Increment>{z_inc:e}</Increment>")
    } else {
        String::new()
    };
    let valid_link = if valid.is_some() {
        "<ValidPointsLink>bindata/valid.bin</ValidPointsLink>"
    } else {
        ""
    };
    let xml = format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<p:ISO5436_2 xmlns:p="http://www.opengps.eu/2008/ISO5436_2">
  <Record1>
    <Revision>ISO5436 - 2000</Revision>
    <FeatureType>SUR</FeatureType>
    <Axes>
      <CX><AxisType>I</AxisType><DataType>D</DataType><Increment>{:e}</Increment><Offset>0</Offset></CX>
      <CY><AxisType>I</AxisType><DataType>D</DataType><Increment>{:e}</Increment><Offset>0</Offset></CY>
      <CZ><AxisType>A</AxisType><DataType>{kind}</DataType>{inc}<Offset>0</Offset></CZ>
    </Axes>
  </Record1>
  <Record2><Date>2026-11-30T00:00:00</Date><Instrument><Manufacturer>test</Manufacturer><Model>synthetic</Model><Serial>0</Serial><Version>1</Version></Instrument><CalibrationDate>2026-01-01T00:00:00</CalibrationDate><ProbingSystem><Type>NonContacting</Type><Identification>none</Identification></ProbingSystem><Comment>known surface</Comment></Record2>
  <Record3>
    <MatrixDimension><SizeX>{NX}</SizeX><SizeY>{NY}</SizeY><SizeZ>1</SizeZ></MatrixDimension>
    <DataLink><PointDataLink>bindata/data.bin</PointDataLink>{valid_link}</DataLink>
  </Record3>
  <Record4><ChecksumFile>md5checksum.hex</ChecksumFile></Record4>
</p:ISO5436_2>
"#,
        DX * 1e-9,
        DY * 1e-9
    );
    let f = std::fs::File::create(path).unwrap();
    let mut zip = zip::ZipWriter::new(f);
    let opts = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated);
    zip.start_file("main.xml", opts).unwrap();
    zip.write_all(xml.as_bytes()).unwrap();
    zip.start_file("bindata/data.bin", opts).unwrap();
    zip.write_all(&bin).unwrap();
    if let Some(v) = valid {
        let mut mask = vec![0u8; v.len().div_ceil(8)];
        for (k, &ok) in v.iter().enumerate() {
            if ok {
                mask[k / 8] |= 1 << (k % 8);
            }
        }
        zip.start_file("bindata/valid.bin", opts).unwrap();
        zip.write_all(&mask).unwrap();
    }
    zip.finish().unwrap();
}

/// A Gwyddion Simple Field: heights in `z_unit`, lateral size in micrometres.
fn gsf_bytes(nx: usize, ny: usize, dx_nm: f64, dy_nm: f64, z: &[f32], z_unit: &str) -> Vec<u8> {
    let mut h = format!(
        "Gwyddion Simple Field 1.0\nXRes = {nx}\nYRes = {ny}\nXReal = {}\nYReal = {}\nXYUnits = um\nZUnits = {z_unit}\nTitle = known\n",
        nx as f64 * dx_nm / 1000.0,
        ny as f64 * dy_nm / 1000.0
    )
    .into_bytes();
    let pad = 4 - h.len() % 4;
    h.extend(std::iter::repeat_n(0u8, pad));
    for v in z {
        h.extend(v.to_le_bytes());
    }
    h
}

/// A 2-D float64 `.npy`, written by hand from the format's description (NEP 1).
fn npy_bytes(nx: usize, ny: usize, v: &[f64]) -> Vec<u8> {
    let mut dict = format!("{{'descr': '<f8', 'fortran_order': False, 'shape': ({ny}, {nx}), }}");
    while (10 + dict.len() + 1) % 64 != 0 {
        dict.push(' ');
    }
    dict.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend((dict.len() as u16).to_le_bytes());
    out.extend(dict.as_bytes());
    for x in v {
        out.extend(x.to_le_bytes());
    }
    out
}

fn sample_text(interface: &str) -> String {
    format!(
        "[sample]\nname = \"measured\"\nunit = \"um\"\n[media.air]\nn = 1.0\n[media.glass]\nn = 1.5\n\
         [[interface]]\n{interface}\nfront = \"air\"\nback = \"glass\"\n"
    )
}

fn load_in(dir: &Path, interface: &str) -> Result<Sample, String> {
    std::fs::write(dir.join("s.toml"), sample_text(interface)).unwrap();
    sample::load(&dir.join("s.toml"), MeshOptions::default()).map_err(|e| e.to_string())
}

/// Checks the loaded mesh against the known heights: the patch, and its mirror images
/// across the right and top edges; `tol` in nm.
fn check_mirrored(s: &Sample, z: &[f64], dx: f64, dy: f64, tol: f64) {
    let (cx, cy) = (2 * (NX - 1), 2 * (NY - 1));
    assert!(
        (s.tile_nm[0] - cx as f64 * dx).abs() < 1e-6,
        "{:?}",
        s.tile_nm
    );
    assert!(
        (s.tile_nm[1] - cy as f64 * dy).abs() < 1e-6,
        "{:?}",
        s.tile_nm
    );
    let m = &s.interfaces[0].mesh;
    assert_eq!(m.positions_nm.len(), (cx + 1) * (cy + 1));
    assert_eq!(m.triangles.len(), 2 * cx * cy);
    for p in &m.positions_nm {
        let (i, j) = ((p.x / dx).round() as usize, (p.y / dy).round() as usize);
        // Mirror: grid index i of the doubled tile is point min(i, 2(n-1) - i) mod the period.
        let fold = |k: usize, n: usize| {
            let k = k % (2 * (n - 1));
            if k < n { k } else { 2 * (n - 1) - k }
        };
        let want = z[fold(j, NY) * NX + fold(i, NX)];
        assert!((p.z - want).abs() <= tol, "({i}, {j}): {} vs {want}", p.z);
    }
}

#[test]
fn every_reader_gives_the_known_heights() {
    let d = scratch("heightmap-readers");
    let z = heights();
    // X3P, float64: exact to the rounding of metres and back.
    write_x3p(&d.join("d.x3p"), "D", &z, 0.0, None);
    let s = load_in(&d, "heightmap = \"d.x3p\"").unwrap();
    check_mirrored(&s, &z, DX, DY, 1e-9);
    assert!(
        s.interfaces[0]
            .mesh_path
            .to_string_lossy()
            .contains("mirrored")
    );
    // X3P, float32 and int16 counts of 0.1 nm: within their resolution.
    write_x3p(&d.join("f.x3p"), "F", &z, 0.0, None);
    check_mirrored(
        &load_in(&d, "heightmap = \"f.x3p\"").unwrap(),
        &z,
        DX,
        DY,
        1e-4,
    );
    write_x3p(&d.join("i.x3p"), "I", &z, 1e-10, None);
    check_mirrored(
        &load_in(&d, "heightmap = \"i.x3p\"").unwrap(),
        &z,
        DX,
        DY,
        0.05 + 1e-9,
    );
    // GSF, heights in nm as float32.
    let z32: Vec<f32> = z.iter().map(|&v| v as f32).collect();
    std::fs::write(d.join("g.gsf"), gsf_bytes(NX, NY, DX, DY, &z32, "nm")).unwrap();
    check_mirrored(
        &load_in(&d, "heightmap = \"g.gsf\"").unwrap(),
        &z,
        DX,
        DY,
        1e-4,
    );
    // npy in nm with the scale stated in the sample (um): pixel_size [0.25, 0.3] um,
    // height_scale 0.001 um per stored nm.
    std::fs::write(d.join("h.npy"), npy_bytes(NX, NY, &z)).unwrap();
    let s = load_in(
        &d,
        "heightmap = \"h.npy\"\npixel_size = [0.25, 0.3]\nheight_scale = 0.001",
    )
    .unwrap();
    check_mirrored(&s, &z, DX, DY, 1e-9);
    // EXR (float32 channel), in nm.
    {
        use exr::prelude::*;
        let ch = AnyChannel::new("Y", FlatSamples::F32(z32.clone()));
        let img = Image::from_channels((NX, NY), AnyChannels::sort(SmallVec::from_vec(vec![ch])));
        img.write().to_file(d.join("e.exr")).unwrap();
    }
    let s = load_in(
        &d,
        "heightmap = \"e.exr\"\npixel_size = [0.25, 0.3]\nheight_scale = 0.001",
    )
    .unwrap();
    check_mirrored(&s, &z, DX, DY, 1e-4);
    // 16-bit PNG and TIFF: counts of 0.01 nm above the lowest point.
    let lo = z.iter().copied().fold(f64::INFINITY, f64::min);
    let counts: Vec<u16> = z.iter().map(|v| ((v - lo) / 0.01).round() as u16).collect();
    let quantised: Vec<f64> = counts.iter().map(|&c| f64::from(c) * 0.01).collect();
    {
        let f = std::fs::File::create(d.join("p.png")).unwrap();
        let mut enc = png::Encoder::new(f, NX as u32, NY as u32);
        enc.set_color(png::ColorType::Grayscale);
        enc.set_depth(png::BitDepth::Sixteen);
        let mut w = enc.write_header().unwrap();
        let be: Vec<u8> = counts.iter().flat_map(|c| c.to_be_bytes()).collect();
        w.write_image_data(&be).unwrap();
    }
    let scaled = "pixel_size = [0.25, 0.3]\nheight_scale = 0.00001";
    let s = load_in(&d, &format!("heightmap = \"p.png\"\n{scaled}")).unwrap();
    check_mirrored(&s, &quantised, DX, DY, 1e-9);
    {
        let f = std::fs::File::create(d.join("t.tif")).unwrap();
        let mut enc = tiff::encoder::TiffEncoder::new(f).unwrap();
        enc.write_image::<tiff::encoder::colortype::Gray16>(NX as u32, NY as u32, &counts)
            .unwrap();
    }
    let s = load_in(&d, &format!("heightmap = \"t.tif\"\n{scaled}")).unwrap();
    check_mirrored(&s, &quantised, DX, DY, 1e-9);
    // Periodic edges: the patch is one period, the wrap joins the last row to the first.
    let s = load_in(&d, "heightmap = \"d.x3p\"\nedges = \"periodic\"").unwrap();
    assert!((s.tile_nm[0] - NX as f64 * DX).abs() < 1e-6);
    let m = &s.interfaces[0].mesh;
    assert_eq!(m.triangles.len(), 2 * NX * NY);
    let top_right = m.positions_nm.last().unwrap();
    assert!(
        (top_right.z - z[0]).abs() < 1e-9,
        "the wrap repeats point (0, 0)"
    );
}

#[test]
fn missing_points_are_refused_or_filled() {
    let d = scratch("heightmap-missing");
    let mut z = heights();
    let hole = 7 * NX + 11;
    z[hole] = f64::NAN;
    let z32: Vec<f32> = z.iter().map(|&v| v as f32).collect();
    std::fs::write(d.join("g.gsf"), gsf_bytes(NX, NY, DX, DY, &z32, "nm")).unwrap();
    let e = load_in(&d, "heightmap = \"g.gsf\"").unwrap_err();
    assert!(
        e.contains("1 of 825 points are missing")
            && e.contains("column 11, row 7")
            && e.contains("missing = \"fill\""),
        "{e}"
    );
    let s = load_in(&d, "heightmap = \"g.gsf\"\nmissing = \"fill\"").unwrap();
    // The filled point is the mean of its four neighbours.
    let want = (z[hole - 1] + z[hole + 1] + z[hole - NX] + z[hole + NX]) / 4.0;
    let p = s.interfaces[0]
        .mesh
        .positions_nm
        .iter()
        .find(|p| (p.x - 11.0 * DX).abs() < 1e-6 && (p.y - 7.0 * DY).abs() < 1e-6)
        .unwrap();
    assert!((p.z - want).abs() < 1e-3, "{} vs {want}", p.z);
    assert!(
        s.interfaces[0]
            .mesh_path
            .to_string_lossy()
            .contains("1 missing points filled")
    );
    // Integer X3P data mark missing points in the valid-point mask.
    let mut valid = vec![true; NX * NY];
    valid[3] = false;
    valid[400] = false;
    write_x3p(&d.join("i.x3p"), "I", &heights(), 1e-10, Some(&valid));
    let e = load_in(&d, "heightmap = \"i.x3p\"").unwrap_err();
    assert!(e.contains("2 of 825 points are missing"), "{e}");
    assert!(load_in(&d, "heightmap = \"i.x3p\"\nmissing = \"fill\"").is_ok());
    // A map with no known height at all is refused even with fill.
    let nan = vec![f32::NAN; 16];
    std::fs::write(d.join("n.gsf"), gsf_bytes(4, 4, DX, DY, &nan, "nm")).unwrap();
    let e = load_in(&d, "heightmap = \"n.gsf\"\nmissing = \"fill\"").unwrap_err();
    assert!(e.contains("no height is known"), "{e}");
}

#[test]
fn bad_files_get_clear_errors() {
    let d = scratch("heightmap-bad");
    let z32: Vec<f32> = heights().iter().map(|&v| v as f32).collect();
    let good = gsf_bytes(NX, NY, DX, DY, &z32, "nm");
    let cases: Vec<(&str, Vec<u8>, &str, &str)> = vec![
        (
            "a.gsf",
            b"Gwyddion Simple Field 2.0\nXRes = 2\n\0\0\0".to_vec(),
            "",
            "not a Gwyddion Simple Field",
        ),
        ("b.gsf", good[..good.len() - 100].to_vec(), "", "truncated"),
        (
            "d.gsf",
            {
                // Absurd size: refused before anything is allocated.
                let mut h = b"Gwyddion Simple Field 1.0\nXRes = 100000\nYRes = 100000\n".to_vec();
                h.extend([0u8; 3]);
                h
            },
            "",
            "more than",
        ),
        (
            "e.gsf",
            gsf_bytes(4, 4, DX, DY, &[0.0; 16], "furlong"),
            "",
            "not a length unit",
        ),
        ("f.x3p", b"PK\x03\x04 not really".to_vec(), "", "not an X3P"),
        (
            "g.npy",
            npy_bytes(NX, NY, &heights())[..300].to_vec(),
            "pixel_size = 0.1\nheight_scale = 1.0",
            ".npy",
        ),
        (
            "h.npy",
            npy_bytes(NX, NY, &heights()),
            "",
            "no physical scale",
        ),
        (
            "i.npy",
            npy_bytes(NX, NY, &heights()),
            "pixel_size = -1.0\nheight_scale = 1.0",
            "pixel_size must be positive",
        ),
        (
            "j.npy",
            npy_bytes(NX, NY, &heights()),
            "pixel_size = 0.1",
            "both pixel_size and height_scale",
        ),
        (
            "k.gsf",
            good.clone(),
            "pixel_size = 0.1\nheight_scale = 1.0",
            "states its own pixel size",
        ),
        (
            "l.npy",
            npy_bytes(1, 5, &[0.0; 5]),
            "pixel_size = 0.1\nheight_scale = 1.0",
            "at least 2 x 2",
        ),
        ("m.dat", good.clone(), "", "unknown height-map format"),
        (
            "n.gsf",
            gsf_bytes(2, 2, DX, DY, &[0.0, f32::INFINITY, 0.0, 0.0], "nm"),
            "",
            "not a measurement",
        ),
    ];
    for (name, bytes, extra, want) in cases {
        std::fs::write(d.join(name), bytes).unwrap();
        let e = load_in(&d, &format!("heightmap = \"{name}\"\n{extra}")).unwrap_err();
        assert!(e.contains(want) && e.contains(name), "{name}: {e}");
    }
    // X3P headers: a profile, and a missing size.
    write_x3p(&d.join("p.x3p"), "D", &heights(), 0.0, None);
    let xml_of = |path: &Path| {
        let mut z = zip::ZipArchive::new(std::fs::File::open(path).unwrap()).unwrap();
        let mut s = String::new();
        std::io::Read::read_to_string(&mut z.by_name("main.xml").unwrap(), &mut s).unwrap();
        let mut data = Vec::new();
        std::io::Read::read_to_end(&mut z.by_name("bindata/data.bin").unwrap(), &mut data).unwrap();
        (s, data)
    };
    let (xml, data) = xml_of(&d.join("p.x3p"));
    for (name, xml, data, want) in [
        (
            "q.x3p",
            xml.replace(">SUR<", ">PRF<"),
            data.clone(),
            "profile",
        ),
        (
            "r.x3p",
            xml.replace("<SizeX>33</SizeX>", ""),
            data.clone(),
            "SizeX",
        ),
        (
            "s.x3p",
            xml.clone(),
            data[..data.len() / 2].to_vec(),
            "truncated",
        ),
        (
            "t.x3p",
            xml.replace("<SizeX>33</SizeX>", "<SizeX>4000000000</SizeX>"),
            data.clone(),
            "more than",
        ),
        (
            "u.x3p",
            xml.replace(
                "<DataType>D</DataType><Offset>",
                "<DataType>Q</DataType><Offset>",
            ),
            data.clone(),
            "data type",
        ),
    ] {
        let f = std::fs::File::create(d.join(name)).unwrap();
        let mut zip = zip::ZipWriter::new(f);
        let o = zip::write::SimpleFileOptions::default();
        zip.start_file("main.xml", o).unwrap();
        zip.write_all(xml.as_bytes()).unwrap();
        zip.start_file("bindata/data.bin", o).unwrap();
        zip.write_all(&data).unwrap();
        zip.finish().unwrap();
        let e = load_in(&d, &format!("heightmap = \"{name}\"")).unwrap_err();
        assert!(e.contains(want) && e.contains(name), "{name}: {e}");
    }
    // The tile, when given, must be the map's.
    std::fs::write(d.join("ok.gsf"), &good).unwrap();
    std::fs::write(
        d.join("s.toml"),
        sample_text("heightmap = \"ok.gsf\"")
            .replace("unit = \"um\"\n", "unit = \"um\"\ntile = [10.0, 10.0]\n"),
    )
    .unwrap();
    let e = sample::load(&d.join("s.toml"), MeshOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("spans [16, 14.4] um") && e.contains("tile is [10, 10]"),
        "{e}"
    );
    // The heightmap keys belong to heightmap interfaces.
    let e = load_in(&d, "generator = { kind = \"flat\" }\nedges = \"mirror\"").unwrap_err();
    assert!(e.contains("belong to an interface with a heightmap"), "{e}");
}

/// Writes the known surface as `g.gsf` (f32 heights) in `dir`; returns the heights.
fn write_known_gsf(dir: &Path) -> Vec<f32> {
    let z32: Vec<f32> = heights().iter().map(|&v| v as f32).collect();
    std::fs::write(dir.join("g.gsf"), gsf_bytes(NX, NY, DX, DY, &z32, "nm")).unwrap();
    z32
}

/// The flat scan's angles (deg) and wavelengths (nm).
const FLAT_THETA: [f64; 3] = [0.0, 30.0, 60.0];
const FLAT_LAMBDA: [f64; 2] = [450.0, 600.0];

/// Simulates a flat glass patch at [`FLAT_THETA`] x [`FLAT_LAMBDA`] and checks R against the
/// independent TMM's bare interface within 1e-9; returns the run's statistics.
fn check_flat_glass_is_tmm(s: &Sample) -> goniospec::simulate::SimStats {
    let cfg = config(
        &FLAT_THETA,
        Wavelengths::Monochromatic(FLAT_LAMBDA.to_vec()),
        64,
    );
    let (acc, stats) = goniospec::simulate::simulate(s, &cfg, &|_| {}).unwrap();
    for (i, th) in FLAT_THETA.iter().enumerate() {
        for (j, &l) in FLAT_LAMBDA.iter().enumerate() {
            let (r, _) = totals(&acc, i, j);
            let (want, _) = tmm_ref(&[c(1.0, 0.0), c(1.5, 0.0)], &[], l, th.to_radians());
            assert!((r - want).abs() < 1e-9, "{th} deg {l} nm: {r} vs {want}");
        }
    }
    stats
}

#[test]
fn a_flat_measured_patch_is_the_fresnel_interface() {
    // A flat scan of glass (all heights 0): R at every angle is the bare interface's, from
    // the independent TMM with no layers.
    let d = scratch("heightmap-flat");
    std::fs::write(
        d.join("flat.gsf"),
        gsf_bytes(16, 12, 500.0, 500.0, &[0.0; 192], "nm"),
    )
    .unwrap();
    let s = load_in(&d, "heightmap = \"flat.gsf\"").unwrap();
    check_flat_glass_is_tmm(&s);
}

#[test]
fn a_non_periodic_patch_equals_its_obj_equivalent() {
    // The known surface as a GSF (mirror edges) against an OBJ of the same mirrored surface
    // written here, triangulated along the other diagonal: the same R within error bars.
    let d = scratch("heightmap-obj");
    let z32 = write_known_gsf(&d);
    let measured = load_in(&d, "heightmap = \"g.gsf\"").unwrap();
    let (cx, cy) = (2 * (NX - 1), 2 * (NY - 1));
    let mut obj = String::new();
    for j in 0..=cy {
        for i in 0..=cx {
            let fi = if i < NX { i } else { cx - i };
            let fj = if j < NY { j } else { cy - j };
            let h = f64::from(z32[fj * NX + fi]);
            obj += &format!(
                "v {} {} {}\n",
                i as f64 * DX / 1000.0,
                j as f64 * DY / 1000.0,
                h / 1000.0
            );
        }
    }
    let v = |i: usize, j: usize| j * (cx + 1) + i + 1;
    for j in 0..cy {
        for i in 0..cx {
            obj += &format!("f {} {} {}\n", v(i, j), v(i + 1, j), v(i, j + 1));
            obj += &format!("f {} {} {}\n", v(i + 1, j), v(i + 1, j + 1), v(i, j + 1));
        }
    }
    std::fs::write(d.join("m.obj"), obj).unwrap();
    let tile = format!(
        "tile = [{}, {}]\n",
        cx as f64 * DX / 1000.0,
        cy as f64 * DY / 1000.0
    );
    std::fs::write(
        d.join("o.toml"),
        sample_text("mesh = \"m.obj\"")
            .replace("unit = \"um\"\n", &format!("unit = \"um\"\n{tile}")),
    )
    .unwrap();
    let reference = sample::load(&d.join("o.toml"), MeshOptions::default()).unwrap();
    let cfg = config(&[20.0, 50.0], Wavelengths::Bins(vec![500.0, 600.0]), 4000);
    let (a, b) = (run(&measured, &cfg), run(&reference, &cfg));
    for i in 0..2 {
        let (ra, rb) = (totals(&a, i, 0).0, totals(&b, i, 0).0);
        let mode = goniospec::accumulate::Coherence::Beamlet;
        let se = (a.cell(i, 0).r_stderr(mode).unwrap().powi(2)
            + b.cell(i, 0).r_stderr(mode).unwrap().powi(2))
        .sqrt();
        assert!(
            (ra - rb).abs() < 4.0 * se + 1e-9,
            "theta {i}: {ra} vs {rb} (se {se})"
        );
        assert!(ra > 0.03 && ra < 0.2, "glass reflects a few per cent: {ra}");
    }
}

#[test]
fn ply_and_stl_load_the_same_mesh_as_obj() {
    let d = scratch("ply-stl");
    let obj = root().join("meshes/rough-gold-ggx.obj");
    let m = sample::load_obj(&obj, 1000.0, MeshOptions::default()).unwrap();
    // Binary little- and big-endian PLY with float64 vertices and uchar/int faces, an
    // extra vertex property and an extra element, and ASCII PLY.
    for (name, fmt) in [
        ("le.ply", "binary_little_endian"),
        ("be.ply", "binary_big_endian"),
        ("a.ply", "ascii"),
    ] {
        let mut out = format!(
            "ply\nformat {fmt} 1.0\ncomment test\nelement vertex {}\nproperty double x\nproperty double y\nproperty double z\nproperty uchar red\nelement face {}\nproperty list uchar int vertex_indices\nelement edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n",
            m.positions_nm.len(),
            m.triangles.len()
        )
        .into_bytes();
        let put = |out: &mut Vec<u8>, v: f64, bytes: Vec<u8>| {
            if fmt == "ascii" {
                out.extend(format!("{v:?} ").into_bytes());
            } else if fmt == "binary_big_endian" {
                out.extend(bytes.into_iter().rev());
            } else {
                out.extend(bytes);
            }
        };
        for p in &m.positions_nm {
            for c in p.to_array() {
                let u = c / 1000.0;
                put(&mut out, u, u.to_le_bytes().to_vec());
            }
            put(&mut out, 7.0, vec![7u8]);
            if fmt == "ascii" {
                out.push(b'\n');
            }
        }
        for t in &m.triangles {
            put(&mut out, 3.0, vec![3u8]);
            for &i in t {
                put(&mut out, f64::from(i), (i as i32).to_le_bytes().to_vec());
            }
        }
        put(&mut out, 0.0, 0i32.to_le_bytes().to_vec());
        put(&mut out, 1.0, 1i32.to_le_bytes().to_vec());
        std::fs::write(d.join(name), out).unwrap();
        let p = sample::load_mesh(&d.join(name), 1000.0, MeshOptions::default()).unwrap();
        assert_eq!(p.triangles, m.triangles, "{name}");
        for (a, b) in p.positions_nm.iter().zip(&m.positions_nm) {
            assert!((*a - *b).length() < 1e-9, "{name}: {a} vs {b}");
        }
    }
    // Binary STL (float32 corners; shared corners merged) and ASCII STL.
    let mut bin = vec![0u8; 80];
    bin[..5].copy_from_slice(b"solid"); // a binary header may start like ASCII
    bin.extend((m.triangles.len() as u32).to_le_bytes());
    let mut ascii = String::from("solid test\n");
    for t in &m.triangles {
        bin.extend([0u8; 12]);
        ascii += "facet normal 0 0 1\nouter loop\n";
        for &i in t {
            let p = m.positions_nm[i as usize] / 1000.0;
            for c in p.to_array() {
                bin.extend((c as f32).to_le_bytes());
            }
            ascii += &format!("vertex {} {} {}\n", p.x as f32, p.y as f32, p.z as f32);
        }
        bin.extend([0u8; 2]);
        ascii += "endloop\nendfacet\n";
    }
    ascii += "endsolid test\n";
    std::fs::write(d.join("b.stl"), &bin).unwrap();
    std::fs::write(d.join("a.stl"), ascii).unwrap();
    for name in ["b.stl", "a.stl"] {
        let s = sample::load_mesh(&d.join(name), 1000.0, MeshOptions::default()).unwrap();
        assert_eq!(s.triangles.len(), m.triangles.len(), "{name}");
        assert_eq!(
            s.positions_nm.len(),
            m.positions_nm.len(),
            "{name}: corners merged"
        );
        for (a, b) in s.triangles.iter().zip(&m.triangles) {
            for k in 0..3 {
                let (pa, pb) = (s.positions_nm[a[k] as usize], m.positions_nm[b[k] as usize]);
                // float32 micrometres: within 1e-7 relative of 20 um.
                assert!((pa - pb).length() < 0.01, "{name}: {pa} vs {pb}");
            }
        }
    }
    // A cut binary STL and a PLY whose face points past the vertices are refused.
    std::fs::write(d.join("cut.stl"), &bin[..bin.len() - 7]).unwrap();
    let e = sample::load_mesh(&d.join("cut.stl"), 1000.0, MeshOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("malformed STL") && e.contains("truncated"),
        "{e}"
    );
    // Issue 30: padding after the last triangle is named as such, not "truncated"; PLY and
    // STL errors name their format, not OBJ.
    let mut padded = bin.clone();
    padded.extend([0u8; 16]);
    std::fs::write(d.join("padded.stl"), &padded).unwrap();
    let e = sample::load_mesh(&d.join("padded.stl"), 1000.0, MeshOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("malformed STL")
            && e.contains("after the last triangle")
            && !e.contains("truncated"),
        "{e}"
    );
    // An element without properties but a count of 2^64 - 1 holds no data: it is skipped at
    // once (it looped for minutes), and the mesh around it loads.
    let t0 = std::time::Instant::now();
    std::fs::write(
        d.join("empty-element.ply"),
        "ply\nformat ascii 1.0\nelement nothing 18446744073709551615\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
    )
    .unwrap();
    let m1 = sample::load_mesh(&d.join("empty-element.ply"), 1.0, MeshOptions::default()).unwrap();
    assert_eq!(m1.triangles.len(), 1);
    assert!(t0.elapsed().as_secs_f64() < 5.0, "{:?}", t0.elapsed());
    std::fs::write(
        d.join("bad.ply"),
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 5\n",
    )
    .unwrap();
    let e = sample::load_mesh(&d.join("bad.ply"), 1.0, MeshOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("malformed PLY") && e.contains("refers to vertex 5"),
        "{e}"
    );
}

#[test]
fn guard_band_edges_keep_the_patch_and_open_the_sides() {
    let d = scratch("heightmap-guard");
    let z32 = write_known_gsf(&d);
    // The patch as it is: (NX - 1) x (NY - 1) cells, every point at its known height.
    let s = load_in(&d, "heightmap = \"g.gsf\"\nedges = \"guard\"").unwrap();
    let (lx, ly) = ((NX - 1) as f64 * DX, (NY - 1) as f64 * DY);
    assert!((s.tile_nm[0] - lx).abs() < 1e-6 && (s.tile_nm[1] - ly).abs() < 1e-6);
    let m = &s.interfaces[0].mesh;
    assert_eq!(m.positions_nm.len(), NX * NY);
    assert_eq!(m.triangles.len(), 2 * (NX - 1) * (NY - 1));
    for p in &m.positions_nm {
        let (i, j) = ((p.x / DX).round() as usize, (p.y / DY).round() as usize);
        assert!((p.z - f64::from(z32[j * NX + i])).abs() < 1e-6, "{p}");
    }
    // The default band: a tenth of the shorter side.
    let g = s.guard_nm.unwrap();
    assert!((g - 0.1 * lx.min(ly)).abs() < 1e-9, "{g}");
    // `check` walks end at an open side: no seam, no leak. The same patch with periodic
    // sides would not tile, and walks wrapping across the seam would report leaks.
    let opts = goniospec::check::CheckOptions {
        leak_rays: 4000,
        ..Default::default()
    };
    let report = goniospec::check::check(&s, &opts).unwrap();
    assert!(report.defects.is_empty(), "{:?}", report.defects);
    assert!(report.leak.crossings > 3000, "{:?}", report.leak);
    let periodic = Sample {
        guard_nm: None,
        ..s.clone()
    };
    let report = goniospec::check::check(&periodic, &opts).unwrap();
    assert!(
        report.defects.iter().any(|d| d.contains("does not tile")) && report.leak.leaks > 0,
        "{:?} {:?}",
        report.defects,
        report.leak
    );
    // [sample] guard sets it (sample units) and makes guard the default edges.
    let with_guard = |extra: &str, itf: &str| {
        std::fs::write(
            d.join("s.toml"),
            sample_text(itf).replace("unit = \"um\"\n", &format!("unit = \"um\"\n{extra}")),
        )
        .unwrap();
        sample::load(&d.join("s.toml"), MeshOptions::default()).map_err(|e| e.to_string())
    };
    let s = with_guard("guard = 0.5\n", "heightmap = \"g.gsf\"").unwrap();
    assert_eq!(s.guard_nm, Some(500.0));
    assert_eq!(s.interfaces[0].mesh.positions_nm.len(), NX * NY);
    // A periodic patch and open sides contradict each other; a band must leave an
    // interior.
    let e = with_guard("guard = 0.5\n", "heightmap = \"g.gsf\"\nedges = \"mirror\"").unwrap_err();
    assert!(
        e.contains("edges = \"mirror\" makes the patch periodic"),
        "{e}"
    );
    for bad in ["0.0", "-1.0", "3.6", "nan"] {
        let e = with_guard(&format!("guard = {bad}\n"), "heightmap = \"g.gsf\"").unwrap_err();
        assert!(e.contains("guard must leave an interior"), "{bad}: {e}");
    }
    // A flat scan with open sides is still the bare interface of the independent TMM, and
    // nothing escapes (the exits leave within the band).
    std::fs::write(
        d.join("flat.gsf"),
        gsf_bytes(16, 12, 500.0, 500.0, &[0.0; 192], "nm"),
    )
    .unwrap();
    let s = load_in(&d, "heightmap = \"flat.gsf\"\nedges = \"guard\"").unwrap();
    let stats = check_flat_glass_is_tmm(&s);
    assert!(
        stats.escaped.iter().all(|&e| e == 0.0),
        "{:?}",
        stats.escaped
    );
}

/// Open sides, checked against geometry: light refracted into a glass slab (its bottom an
/// index-matched interface, so nothing reflects there) walks sideways `D tan theta_t`
/// before it leaves through the bottom; trees launched uniformly in `[g, L - g]` whose walk
/// reaches the side escape, so the escaped power per tree is `(1 - R) f` with `f = (s - g)
/// / (L - 2 g)` for the total walk `s`, and the Fresnel `R` still leaves through the top.
#[test]
fn escaped_power_through_open_sides_is_the_fraction_that_walks_out() {
    let (l, g, depth) = (10_000.0, 1_000.0, 4_000.0);
    let s = sample_from(
        "guard-slab",
        &format!(
            "[sample]\nname = \"slab\"\nunit = \"nm\"\ntile = [{l}, {l}]\nguard = {g}\n\
             [media.air]\nn = 1.0\n[media.glass]\nn = 1.5\n[media.glass2]\nn = 1.5\n\
             [[interface]]\ngenerator = {{ kind = \"flat\" }}\nfront = \"air\"\nback = \"glass\"\n\
             [[interface]]\ngenerator = {{ kind = \"flat\", z = -{depth} }}\nfront = \"glass\"\nback = \"glass2\"\n"
        ),
    );
    assert_eq!(s.guard_nm, Some(g));
    let scene = goniospec::trace::Scene::new(&s, goniospec::accel::Backend::Obvhs).unwrap();
    let rays = 8192;
    for theta in [30.0f64, 60.0] {
        let cfg = config(&[theta], Wavelengths::Monochromatic(vec![550.0]), rays);
        let (acc, stats) = goniospec::simulate::simulate(&s, &cfg, &|_| {}).unwrap();
        let (t0, st) = (theta.to_radians(), theta.to_radians().sin() / 1.5);
        let tan_t = st / (1.0 - st * st).sqrt();
        // The walk from the launch height to the surface, then through the glass to the
        // exit plane below the slab.
        let walk = scene.z_top * t0.tan() - scene.z_bottom * tan_t;
        let f = ((walk - g) / (l - 2.0 * g)).clamp(0.0, 1.0);
        let (r, t) = totals(&acc, 0, 0);
        let (r_fresnel, _) = tmm_ref(&[c(1.0, 0.0), c(1.5, 0.0)], &[], 550.0, t0);
        let escaped = stats.escaped[0] / rays as f64;
        let want = (1.0 - r_fresnel) * f;
        // The launch points' x follow a Kronecker sequence: the share below a threshold is
        // within a few / N of its measure.
        assert!(
            (escaped - want).abs() < 8.0 / rays as f64,
            "{theta} deg: escaped {escaped} vs (1 - R) f = {want} (f {f})"
        );
        assert!(
            f > 0.05,
            "the geometry must make some light escape: f = {f}"
        );
        assert!((r - r_fresnel).abs() < 1e-9, "{r} vs {r_fresnel}");
        // Energy: what did not reflect either left through the bottom or escaped.
        assert!(
            (r + t + escaped - 1.0).abs() < 1e-9,
            "R {r} + T {t} + escaped {escaped} != 1"
        );
    }
}

/// Writes a float32 EXR with the given channels (each the known surface times a factor).
fn write_exr(path: &Path, channels: &[(&str, f32)]) {
    use exr::prelude::*;
    let z = heights();
    let list: Vec<AnyChannel<FlatSamples>> = channels
        .iter()
        .map(|&(name, f)| {
            AnyChannel::new(
                name,
                FlatSamples::F32(z.iter().map(|&v| v as f32 * f).collect()),
            )
        })
        .collect();
    let img = Image::from_channels((NX, NY), AnyChannels::sort(SmallVec::from_vec(list)));
    img.write().to_file(path).unwrap();
}

/// Issue 30: an EXR height map takes its heights from the channel named Z, else Y, else
/// its only channel; several channels and neither name are refused, not read from whichever
/// sorts first (an RGBA map became a flat surface taken from alpha). A header declaring a
/// 100000 x 100000 data window is refused before anything is allocated (it aborted on a
/// 40 GB allocation).
#[test]
fn exr_heights_come_from_a_named_channel_and_huge_windows_are_refused() {
    let d = scratch("heightmap-exr");
    let z = heights();
    let scaled = "pixel_size = [0.25, 0.3]\nheight_scale = 0.001";
    write_exr(&d.join("yz.exr"), &[("Y", 2.0), ("Z", 1.0)]);
    let s = load_in(&d, &format!("heightmap = \"yz.exr\"\n{scaled}")).unwrap();
    check_mirrored(&s, &z, DX, DY, 1e-4);
    write_exr(&d.join("ay.exr"), &[("A", 0.0), ("Y", 1.0)]);
    let s = load_in(&d, &format!("heightmap = \"ay.exr\"\n{scaled}")).unwrap();
    check_mirrored(&s, &z, DX, DY, 1e-4);
    write_exr(
        &d.join("rgba.exr"),
        &[("R", 1.0), ("G", 1.0), ("B", 1.0), ("A", 0.0)],
    );
    let e = load_in(&d, &format!("heightmap = \"rgba.exr\"\n{scaled}")).unwrap_err();
    assert!(
        e.contains("none named Z or Y") && e.contains("A, B, G, R"),
        "{e}"
    );
    // The data window patched to 100000 x 100000 in an otherwise valid header.
    write_exr(&d.join("small.exr"), &[("Z", 1.0)]);
    let mut bytes = std::fs::read(d.join("small.exr")).unwrap();
    let key = b"dataWindow\0box2i\0";
    let at = bytes
        .windows(key.len())
        .position(|w| w == key)
        .expect("a dataWindow attribute")
        + key.len()
        + 4;
    bytes[at + 8..at + 12].copy_from_slice(&99_999i32.to_le_bytes());
    bytes[at + 12..at + 16].copy_from_slice(&99_999i32.to_le_bytes());
    std::fs::write(d.join("huge.exr"), &bytes).unwrap();
    let e = load_in(&d, &format!("heightmap = \"huge.exr\"\n{scaled}")).unwrap_err();
    assert!(e.contains("100000 x 100000 points is more than"), "{e}");
}

/// Copies the X3P at `from` to `to` with `main.xml` edited by `edit`.
fn edit_x3p(from: &Path, to: &Path, edit: impl Fn(&str) -> String) {
    let mut src = zip::ZipArchive::new(std::fs::File::open(from).unwrap()).unwrap();
    let mut out = zip::ZipWriter::new(std::fs::File::create(to).unwrap());
    let opts = zip::write::SimpleFileOptions::default();
    for i in 0..src.len() {
        let mut f = src.by_index(i).unwrap();
        let name = f.name().to_string();
        let mut bytes = Vec::new();
        std::io::Read::read_to_end(&mut f, &mut bytes).unwrap();
        if name == "main.xml" {
            bytes = edit(std::str::from_utf8(&bytes).unwrap()).into_bytes();
        }
        out.start_file(name, opts).unwrap();
        out.write_all(&bytes).unwrap();
    }
    out.finish().unwrap();
}

/// Issue 30: an X3P increment of 0 flattened the surface silently (while height_scale = 0 is
/// refused); a denormal one printed a 935-byte message. Both are refused in a short line
/// naming the field.
#[test]
fn x3p_increments_must_be_positive_steps() {
    let d = scratch("x3p-increments");
    write_x3p(&d.join("i.x3p"), "I", &heights(), 1e-10, None);
    for (tag, from, to, field) in [
        (
            "z0",
            "<Increment>1e-10</Increment>",
            "<Increment>0</Increment>",
            "CZ/Increment",
        ),
        (
            "zneg",
            "<Increment>1e-10</Increment>",
            "<Increment>-1e-10</Increment>",
            "CZ/Increment",
        ),
        (
            "xdenormal",
            &format!("<Increment>{:e}</Increment>", DX * 1e-9),
            "<Increment>5e-324</Increment>",
            "CX/Increment",
        ),
    ] {
        let name = format!("{tag}.x3p");
        edit_x3p(&d.join("i.x3p"), &d.join(&name), |x| {
            assert!(x.contains(from), "{tag}: {from} not in main.xml");
            x.replacen(from, to, 1)
        });
        let e = load_in(&d, &format!("heightmap = \"{name}\"")).unwrap_err();
        assert!(
            e.contains(field) && e.contains("positive step") && e.len() < 300,
            "{tag}: {e}"
        );
    }
}

/// Issue 30: a signed 16-bit TIFF is a height map (counts either side of zero; it got
/// "Gray(16): must be 16-bit"), and a GSF written without its header padding is named as
/// such (it got "not UTF-8").
#[test]
fn signed_tiffs_load_and_unpadded_gsfs_are_named() {
    let d = scratch("heightmap-signed");
    let z = heights();
    let counts: Vec<i16> = z.iter().map(|v| (v / 0.01).round() as i16).collect();
    let quantised: Vec<f64> = counts.iter().map(|&c| f64::from(c) * 0.01).collect();
    {
        let f = std::fs::File::create(d.join("s.tif")).unwrap();
        let mut enc = tiff::encoder::TiffEncoder::new(f).unwrap();
        enc.write_image::<tiff::encoder::colortype::GrayI16>(NX as u32, NY as u32, &counts)
            .unwrap();
    }
    let s = load_in(
        &d,
        "heightmap = \"s.tif\"\npixel_size = [0.25, 0.3]\nheight_scale = 0.00001",
    )
    .unwrap();
    check_mirrored(&s, &quantised, DX, DY, 1e-9);
    // The header runs straight into float data: no NUL before binary bytes.
    let z32: Vec<f32> = z.iter().map(|&v| v as f32 + 1000.0).collect();
    let good = gsf_bytes(NX, NY, DX, DY, &z32, "nm");
    let text_end = good.iter().position(|&b| b == 0).unwrap();
    let data_at = (text_end / 4 + 1) * 4;
    let mut unpadded = good[..text_end].to_vec();
    unpadded.extend(&good[data_at..]);
    std::fs::write(d.join("u.gsf"), &unpadded).unwrap();
    let e = load_in(&d, "heightmap = \"u.gsf\"").unwrap_err();
    assert!(e.contains("padding"), "{e}");
}

/// Found by fuzzing (issue 30): a `.npy` header of nested braces hung the header parser
/// (it backtracks exponentially), and a dimension of 10^20 overflowed its product; both are
/// refused by a check of the header before it is parsed, at once.
#[test]
fn npy_headers_are_checked_before_parsing() {
    let d = scratch("npy-headers");
    let npy = |header: &str| {
        let mut h = header.to_string();
        while (10 + h.len() + 1) % 64 != 0 {
            h.push(' ');
        }
        h.push('\n');
        let mut b = b"\x93NUMPY\x01\x00".to_vec();
        b.extend((h.len() as u16).to_le_bytes());
        b.extend(h.as_bytes());
        b.extend([0u8; 64]);
        b
    };
    let t0 = std::time::Instant::now();
    for (name, header, want) in [
        (
            "nested.npy",
            format!(
                "{}'descr': '<f8', 'fortran_order': False, 'shape': (2, 2), }}",
                "{".repeat(40)
            ),
            "one flat dict",
        ),
        (
            "huge.npy",
            "{'descr': '<f8', 'fortran_order': False, 'shape': (5, 66666666666666666666), }"
                .to_string(),
            "more than",
        ),
    ] {
        std::fs::write(d.join(name), npy(&header)).unwrap();
        let e = load_in(
            &d,
            &format!("heightmap = \"{name}\"\npixel_size = 0.01\nheight_scale = 0.001"),
        )
        .unwrap_err();
        assert!(e.contains(want), "{name}: {e}");
    }
    assert!(t0.elapsed().as_secs_f64() < 5.0, "{:?}", t0.elapsed());
}
