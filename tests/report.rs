//! `goniospec batch report`: the page over a merged library. Its links and images resolve,
//! its colours are the reflectance under D65 (recomputed here from the CLI's reflectance
//! CSV and the CIE tables), it is the same bytes whatever the thread count, and it follows
//! the output policy. The browser checks are in scripts/report-browser.sh.

mod common;

use std::path::{Path, PathBuf};

use common::*;

fn ok(args: &[&str]) -> String {
    let (code, out, err) = goniospec(args);
    assert_eq!(code, 0, "{args:?}: {err}");
    out
}

/// Plans, runs and merges a library of three materials in `dir`.
fn library(dir: &Path) {
    std::fs::create_dir_all(dir).unwrap();
    let root = root().display().to_string();
    let plan = dir.join("plan.toml");
    std::fs::write(
        &plan,
        format!(
            "[defaults]\ntheta_i = [0, 30, 60]\nwavelengths = \"400:700:50\"\nrays = 64\nrepresentations = [\"table\"]\n\n\
             [[material]]\nsample = \"{root}/meshes/rough-gold.toml\"\nname = \"gold\"\n\n\
             [[material]]\nsample = \"{root}/meshes/thin-film-600nm.toml\"\nname = \"soap-film\"\n\n\
             [[material]]\nsample = \"{root}/meshes/flat-soap-film.toml\"\nname = \"flat-film\"\nrepresentations = [\"kdtree\"]\n"
        ),
    )
    .unwrap();
    let b = dir.join("b");
    ok(&[
        "batch",
        "plan",
        plan.to_str().unwrap(),
        "-o",
        b.to_str().unwrap(),
    ]);
    ok(&["batch", "run", b.to_str().unwrap()]);
    ok(&["batch", "merge", b.to_str().unwrap()]);
}

/// Every value of `attr="..."` in `html`.
fn attrs(html: &str, attr: &str) -> Vec<String> {
    let key = format!(" {attr}=\"");
    html.match_indices(&key)
        .map(|(i, _)| {
            let rest = &html[i + key.len()..];
            rest[..rest.find('"').unwrap()].to_string()
        })
        .collect()
}

/// Undoes the page's percent-encoding of link paths.
fn unpercent(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' {
            out.push(u8::from_str_radix(&s[i + 1..i + 3], 16).unwrap());
            i += 3;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    String::from_utf8(out).unwrap()
}

/// The width and height of a PNG, from its IHDR chunk.
fn png_size(p: &Path) -> (u32, u32) {
    let b = std::fs::read(p).unwrap();
    assert!(
        b.starts_with(b"\x89PNG\r\n\x1a\n"),
        "{} is not a PNG",
        p.display()
    );
    let be = |o: usize| u32::from_be_bytes(b[o..o + 4].try_into().unwrap());
    (be(16), be(20))
}

/// Luminous reflectance Y of R(lambda) given at bin centres, under D65, from the shipped CIE
/// tables: Y = sum over 1 nm rows of R(bin of row) D65 y_bar / sum over all rows of D65
/// y_bar (CIE 15:2004 §7.1), R constant over each bin (edges at the midpoints between
/// centres, the outer bins as wide as their neighbours), rows on an edge split half and half.
fn luminous_y(centres: &[f64], r: &[f64]) -> f64 {
    let read = |name: &str| -> Vec<Vec<f64>> {
        std::fs::read_to_string(root().join("data/colour").join(name))
            .unwrap()
            .lines()
            .filter(|l| !l.starts_with('#') && !l.starts_with("lambda") && !l.trim().is_empty())
            .map(|l| l.split(',').map(|x| x.trim().parse().unwrap()).collect())
            .collect()
    };
    let cmf = read("cie1931-2deg.csv");
    let d65 = read("cie-d65.csv");
    // D65 between its tabulated points, linearly; zero outside its table.
    let d65_at = |l: f64| {
        let Some(k) = d65.iter().position(|row| row[0] >= l) else {
            return 0.0;
        };
        if k == 0 && d65[0][0] > l {
            return 0.0;
        }
        if d65[k][0] == l {
            return d65[k][1];
        }
        let t = (l - d65[k - 1][0]) / (d65[k][0] - d65[k - 1][0]);
        d65[k - 1][1] * (1.0 - t) + d65[k][1] * t
    };
    let step = centres[1] - centres[0];
    let (lo, hi) = (
        centres[0] - step / 2.0,
        centres[centres.len() - 1] + step / 2.0,
    );
    let (mut num, mut den) = (0.0, 0.0);
    for row in &cmf {
        let (l, ybar) = (row[0], row[2]);
        let w = d65_at(l) * ybar;
        den += w;
        if l < lo || l > hi {
            continue;
        }
        let x = (l - lo) / step;
        let (k, frac) = (x.floor() as usize, x - x.floor());
        let r_here = if frac == 0.0 && k > 0 && k < centres.len() {
            0.5 * (r[k - 1] + r[k])
        } else if frac == 0.0 {
            // The outer edges: half the row lies in the bin.
            0.5 * r[k.min(centres.len() - 1)]
        } else {
            r[k]
        };
        num += w * r_here;
    }
    num / den
}

#[test]
fn the_page_links_images_and_colours_hold() {
    let dir = scratch("report-page");
    library(&dir);
    let b = dir.join("b");
    let out = ok(&["batch", "report", b.to_str().unwrap()]);
    assert!(out.contains("(3 materials)"), "{out}");
    let page = b.join("report").join("index.html");
    let html = std::fs::read_to_string(&page).unwrap();
    assert!(html.starts_with("<!DOCTYPE html>\n<!-- goniospec batch report -->"));
    // Nothing remote: every src and href is a relative file that exists.
    let folder = page.parent().unwrap();
    let (srcs, hrefs) = (attrs(&html, "src"), attrs(&html, "href"));
    assert_eq!(srcs.len(), 6, "a lobe and a sphere per material: {srcs:?}");
    for link in srcs.iter().chain(hrefs.iter().filter(|h| *h != "data:,")) {
        assert!(!link.contains("://") && !link.starts_with('/'), "{link}");
        let p = folder.join(unpercent(link));
        assert!(p.is_file(), "{link} does not resolve ({})", p.display());
    }
    for name in ["gold", "soap-film", "flat-film"] {
        assert_eq!(
            png_size(&folder.join(format!("{name}-sphere.png"))),
            (160, 160)
        );
        assert_eq!(
            png_size(&folder.join(format!("{name}-lobe.png"))),
            (1200, 600)
        );
        assert!(hrefs.contains(&format!("../out/{name}.gsa")), "{hrefs:?}");
        let fit: serde_json::Value = serde_json::from_slice(
            &std::fs::read(folder.join(format!("{name}-fit.json"))).unwrap(),
        )
        .unwrap();
        assert!(fit["fit"]["ggx_alpha"].as_f64().unwrap() > 0.0);
    }
    // The sort key of each row is the mean Y over the angles of the accumulator's R.
    for name in ["gold", "soap-film", "flat-film"] {
        let gsa = b.join("out").join(format!("{name}.gsa"));
        let mut ys = Vec::new();
        for t in ["0", "30", "60"] {
            let csv = ok(&["reflectance", gsa.to_str().unwrap(), "--theta-i", t]);
            let rows: Vec<Vec<f64>> = csv
                .lines()
                .skip(1)
                .map(|l| l.split(',').take(2).map(|x| x.parse().unwrap()).collect())
                .collect();
            let centres: Vec<f64> = rows.iter().map(|r| r[0]).collect();
            let r: Vec<f64> = rows.iter().map(|r| r[1]).collect();
            ys.push(luminous_y(&centres, &r));
        }
        let want = ys.iter().sum::<f64>() / 3.0;
        let key = format!("data-name=\"{name}\" data-y=\"");
        let at = html.find(&key).unwrap() + key.len();
        let got: f64 = html[at..at + html[at..].find('"').unwrap()]
            .parse()
            .unwrap();
        // The page prints 6 decimals; the CSV 8.
        assert!(
            (got - want).abs() < 2e-6,
            "{name}: page Y {got}, recomputed {want}"
        );
    }
}

#[test]
fn the_report_is_the_same_bytes_whatever_the_threads() {
    let dir = scratch("report-threads");
    library(&dir);
    let b = dir.join("b");
    let files = |d: &Path| -> Vec<(PathBuf, Vec<u8>)> {
        let mut v: Vec<_> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| {
                let p = e.unwrap().path();
                (
                    PathBuf::from(p.file_name().unwrap()),
                    std::fs::read(&p).unwrap(),
                )
            })
            .collect();
        v.sort();
        v
    };
    let one = b.join("one").join("index.html");
    let two = b.join("two").join("index.html");
    for (threads, page) in [("1", &one), ("2", &two)] {
        ok(&[
            "batch",
            "report",
            b.to_str().unwrap(),
            "--no-fit",
            "--threads",
            threads,
            "-o",
            page.to_str().unwrap(),
        ]);
    }
    let (a, c) = (files(one.parent().unwrap()), files(two.parent().unwrap()));
    assert_eq!(
        a.len(),
        8,
        "a page, a lobe and a sphere per material, and the list of what goniospec wrote"
    );
    assert!(a == c, "the report differs between 1 and 2 threads");
    assert!(
        std::fs::read_to_string(&one)
            .unwrap()
            .contains("not fitted")
    );
}

#[test]
fn the_report_refuses_unmerged_libraries_and_foreign_files() {
    let dir = scratch("report-refusals");
    library(&dir);
    let b = dir.join("b");
    let bs = b.to_str().unwrap();
    // `batch report DIR EXTRA... -o OUT`: its status and standard error.
    let report = |extra: &[&str], out: &Path| {
        let out = out.to_str().unwrap().to_string();
        let args = [&["batch", "report", bs][..], extra, &["-o", out.as_str()]].concat();
        let (code, _, err) = goniospec(&args);
        (code, err)
    };
    // A foreign page is kept unless --force.
    let page = dir.join("mine.html");
    std::fs::write(&page, "<p>mine</p>\n").unwrap();
    let (code, err) = report(&["--no-fit"], &page);
    assert_ne!(code, 0);
    assert!(err.contains("--force"), "{err}");
    assert_eq!(std::fs::read_to_string(&page).unwrap(), "<p>mine</p>\n");
    assert_eq!(report(&["--no-fit", "--force"], &page).0, 0);
    // A report it wrote is replaced without --force.
    assert_eq!(report(&["--no-fit"], &page).0, 0);
    // A user's own image of a material's image name beside the page is kept (issue 47),
    // unless --force; a second report into the same folder replaces its own images.
    let photos = dir.join("photos");
    std::fs::create_dir(&photos).unwrap();
    let photo = photos.join("gold-sphere.png");
    std::fs::write(&photo, b"\x89PNG\r\n\x1a\nmy photo").unwrap();
    let (code, err) = report(&["--no-fit"], &photos.join("page.html"));
    assert_ne!(code, 0);
    assert!(err.contains("gold-sphere.png would be replaced"), "{err}");
    assert_eq!(std::fs::read(&photo).unwrap(), b"\x89PNG\r\n\x1a\nmy photo");
    assert!(!photos.join("page.html").exists() && !photos.join("gold-lobe.png").exists());
    std::fs::remove_file(&photo).unwrap();
    assert_eq!(report(&["--no-fit"], &photos.join("page.html")).0, 0);
    assert_eq!(report(&["--no-fit"], &photos.join("page.html")).0, 0);
    // The page is never an input.
    let gsa = b.join("out").join("gold.gsa");
    let before = std::fs::read(&gsa).unwrap();
    let (code, err) = report(&["--force"], &gsa);
    assert_ne!(code, 0);
    assert!(err.contains("is the input"), "{err}");
    assert_eq!(std::fs::read(&gsa).unwrap(), before);
    // A material not merged yet is named, with what to run.
    std::fs::remove_file(b.join("out").join("soap-film.gsa")).unwrap();
    let (code, _, err) = goniospec(&["batch", "report", bs, "--no-fit", "--force"]);
    assert_ne!(code, 0);
    assert!(
        err.contains("soap-film") && err.contains("batch merge"),
        "{err}"
    );
    // Bad options are refused by the parser.
    let (code, _, err) = goniospec(&["batch", "report", bs, "--spp", "0"]);
    assert_ne!(code, 0);
    assert!(err.contains("--spp"), "{err}");
}
