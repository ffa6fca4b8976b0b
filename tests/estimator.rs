//! The fast beamlet estimator against the reference one (`Estimator::reference`): pairs of
//! exits whose cross term is below `NEGLIGIBLE_CROSS` at the longest wavelength are culled
//! before the wavelength loop, which must not change the physics. On every shipped sample
//! the cell totals (R, T, absorbed) agree to 1e-12 relative, and every bucket to 1e-12 of
//! its cell's reflected plus transmitted power.

mod common;

use common::*;
use goniospec::accumulate::Coherence;
use goniospec::simulate::{SimConfig, Wavelengths};

/// Runs `s` with the fast and the reference estimator and checks that every cell's totals
/// agree to 1e-12 relative and every bucket to 1e-12 of its cell's R + T; returns whether
/// the two files differ at all (pairs were culled).
fn fast_equals_reference(s: &goniospec::sample::Sample, cfg: &SimConfig, name: &str) -> bool {
    let fast = run(s, cfg);
    let reference = run(
        s,
        &SimConfig {
            reference_estimator: true,
            ..cfg.clone()
        },
    );
    for (k, (a, b)) in fast.cells.iter().zip(&reference.cells).enumerate() {
        let (ra, ta) = a.totals(Coherence::Beamlet, &cfg.buckets);
        let (rb, tb) = b.totals(Coherence::Beamlet, &cfg.buckets);
        let close = |x: f64, y: f64| (x - y).abs() <= 1e-12 * y.abs().max(1e-300);
        assert!(
            close(ra, rb) && close(ta, tb),
            "{name} cell {k}: R {ra:e} vs {rb:e}, T {ta:e} vs {tb:e}"
        );
        assert!(close(a.absorbed, b.absorbed) || (a.absorbed - b.absorbed).abs() < 1e-15);
        let scale = (rb + tb).abs() * b.trees as f64;
        for (x, y) in a.sum.iter().zip(&b.sum) {
            assert!(
                (x - y).abs() <= 1e-12 * scale,
                "{name} cell {k}: bucket sum {x:e} vs {y:e}"
            );
        }
    }
    fast.to_bytes() != reference.to_bytes()
}

#[test]
fn the_fast_estimator_equals_the_reference_on_every_shipped_sample() {
    let mut culled_somewhere = false;
    for entry in std::fs::read_dir(root().join("meshes")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let s = shipped(&name);
        // Small runs: the multiply scattering paints with a coarse cutoff.
        let cfg = SimConfig {
            limits: goniospec::trace::TraceLimits {
                cutoff: 1e-3,
                ..Default::default()
            },
            ..config(
                &[0.0, 50.0],
                Wavelengths::Bins(vec![400.0, 480.0, 560.0, 640.0, 720.0]),
                24,
            )
        };
        culled_somewhere |= fast_equals_reference(&s, &cfg, &name);
    }
    // The comparison must have seen culled pairs, or it tested nothing.
    assert!(culled_somewhere, "no sample had a pair to cull");
}

/// Issue 30: trees with thousands of exits (a steep rough glass surface at 60 degrees)
/// find their pairs through a grid of directions instead of a double loop; the kept pairs,
/// and so every bucket, are the reference's to 1e-12. The sample is checked to produce
/// trees of more than 32 exits, where the grid is used.
#[test]
fn the_direction_grid_keeps_every_pair_that_matters_on_trees_with_many_exits() {
    use goniospec::sample::generate;
    let tile = [20_000.0, 20_000.0];
    let z = generate::gaussian_heights(3, tile, 128, 3000.0, 1500.0).unwrap();
    let mesh = generate::grid_mesh(tile, 128, &z, 0.0);
    let d = scratch("steep-glass");
    mesh.write_obj(&d.join("g.obj"), 1.0, "steep").unwrap();
    let s = sample_in(
        &d,
        "[sample]\nname = \"steep glass\"\nunit = \"nm\"\ntile = [20000.0, 20000.0]\n[media.air]\nn = 1.0\n[media.glass]\nn = 1.5\n[[interface]]\nmesh = \"g.obj\"\nfront = \"air\"\nback = \"glass\"\n",
    );
    // Some trees have many exits.
    let mut most = 0;
    for tree in trees_at_60_degrees(&s) {
        most = most.max(tree.exits.len());
    }
    assert!(
        most > 32,
        "the largest tree has {most} exits: the grid is not used"
    );
    let cfg = config(&[60.0], Wavelengths::Bins(vec![450.0, 550.0, 650.0]), 24);
    fast_equals_reference(&s, &cfg, "steep glass");
}

/// A steep wavy film of a weak absorber (1.5 um of 2.4 + 0.002i, slopes of tens of degrees,
/// light at 60 degrees; thicker than the wavelength, so its ray series are traced, not
/// handed to the local film, `trace::film`): its trees carry inhomogeneous exits (partial
/// waves that left the absorber through faces tilted against the one they entered by),
/// whose pairs are all candidates and take the
/// amplitude window (`accumulate::directional_exponent`), in the grid's trees of more than
/// 32 exits as in small ones; the fast estimator keeps the reference's sums to 1e-12, at
/// a finite radius and in the plane-wave limit.
#[test]
fn inhomogeneous_exits_pair_alike_in_the_fast_and_the_reference_estimator() {
    let spec = |surface: &str| {
        format!(
            "kind = \"wavy-film\", surface = \"{surface}\", thickness = 1500.0, thickness_rms = 0.0, roughness_rms = 400.0, correlation_length = 2000.0, resolution = 128, seed = 3"
        )
    };
    let d = scratch("steep-absorbing-film");
    let s = sample_in(
        &d,
        &format!(
            "[sample]\nname = \"steep absorbing film\"\nunit = \"nm\"\ntile = [20000.0, 20000.0]\n[media.air]\nn = 1.0\n[media.film]\nn = 2.4\nk = 0.002\n[media.glass]\nn = 1.5\n[[interface]]\ngenerator = {{ {} }}\nfront = \"air\"\nback = \"film\"\n[[interface]]\ngenerator = {{ {} }}\nfront = \"film\"\nback = \"glass\"\n",
            spec("top"),
            spec("bottom")
        ),
    );
    let (mut most, mut inhomogeneous) = (0, 0);
    for tree in trees_at_60_degrees(&s) {
        most = most.max(tree.exits.len());
        inhomogeneous += tree
            .exits
            .iter()
            .filter(|x| x.n_im != glam::DVec3::ZERO)
            .count();
    }
    assert!(
        most > 32 && inhomogeneous > 0,
        "{most} exits at most, {inhomogeneous} inhomogeneous"
    );
    // The comparison is of the two estimators on the same trees, whatever the run would
    // say of the result.
    let mut cfg = config(&[60.0], Wavelengths::Bins(vec![450.0, 550.0, 650.0]), 24);
    cfg.allow_unphysical = true;
    fast_equals_reference(&s, &cfg, "steep absorbing film");
    cfg.rho_nm = f64::INFINITY;
    fast_equals_reference(&s, &cfg, "steep absorbing film, plane wave");
}

/// 24 trees of sample `s` at 550 nm, light at 60 degrees, launched at spread points.
fn trees_at_60_degrees(s: &goniospec::sample::Sample) -> Vec<goniospec::trace::Tree> {
    let scene =
        goniospec::trace::Scene::new(s, goniospec::accel::Backend::default_available()).unwrap();
    let indices: Vec<_> = s
        .media
        .iter()
        .map(|m| {
            let (n, k) = m.model.eval(550.0).unwrap();
            num_complex::Complex64::new(n, k)
        })
        .collect();
    let t = 60f64.to_radians();
    let dir = glam::DVec3::new(t.sin(), 0.0, -t.cos());
    (0..24)
        .map(|i| {
            let mut tree = goniospec::trace::Tree::default();
            scene.trace(
                glam::DVec3::new(
                    800.0 * i as f64 + 37.0,
                    613.0 * i as f64 + 11.0,
                    scene.z_top,
                ),
                dir,
                goniospec::trace::launch_fields(dir),
                &indices,
                550.0,
                &goniospec::trace::TraceLimits::default(),
                &mut goniospec::trace::TraceStack::default(),
                &mut tree,
            );
            tree
        })
        .collect()
}
