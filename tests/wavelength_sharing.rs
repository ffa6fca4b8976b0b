//! Wavelength sharing (`Scene::trace_lanes`, `SimConfig::wavelength_sharing`): tracing
//! every wavelength of a tree at once, rays shared until they refract into a dispersive
//! medium, must give exactly what tracing each wavelength on its own gives, because the
//! geometry is the same. The reference is the per-wavelength tracer (validated against
//! the TMM in tests/physics_*.rs); equality is to the bit, so no tolerance is involved.

mod common;

use common::*;
use glam::DVec3;
use goniospec::optics::C64;
use goniospec::sample::Sample;
use goniospec::simulate::{SimConfig, Wavelengths, simulate};
use goniospec::trace::{Lane, Scene, TraceLimits, TraceStack, Tree, launch_fields};

/// Every medium's index at `lambda` nm.
fn indices(s: &Sample, lambda: f64) -> Vec<C64> {
    s.media
        .iter()
        .map(|m| {
            let (n, k) = m.model.eval(lambda).unwrap();
            C64::new(n, k)
        })
        .collect()
}

/// Bitwise equality of two trees (exits and dropped entries in order, counters).
fn assert_same_tree(a: &Tree, b: &Tree, what: &str) {
    let bits = |z: C64| (z.re.to_bits(), z.im.to_bits());
    let v = |x: DVec3| x.to_array().map(f64::to_bits);
    assert_eq!(a.exits.len(), b.exits.len(), "{what}: exit count");
    for (k, (x, y)) in a.exits.iter().zip(&b.exits).enumerate() {
        assert_eq!(bits(x.opl), bits(y.opl), "{what}: exit {k} optical path");
        assert_eq!(v(x.dir), v(y.dir), "{what}: exit {k} direction");
        assert_eq!(v(x.x), v(y.x), "{what}: exit {k} position");
        assert_eq!(x.up, y.up, "{what}: exit {k} side");
        for p in 0..2 {
            for c in 0..3 {
                assert_eq!(bits(x.e[p][c]), bits(y.e[p][c]), "{what}: exit {k} field");
            }
        }
    }
    assert_eq!(a.dropped.len(), b.dropped.len(), "{what}: dropped count");
    for (x, y) in a.dropped.iter().zip(&b.dropped) {
        assert_eq!(
            x.power.map(f64::to_bits),
            y.power.map(f64::to_bits),
            "{what}"
        );
        assert_eq!(x.im.to_bits(), y.im.to_bits(), "{what}");
        assert_eq!(x.limit, y.limit, "{what}");
    }
    assert_eq!(a.absorbing, b.absorbing, "{what}: absorbing");
    assert_eq!(a.leaks, b.leaks, "{what}: leaks");
    assert_eq!(a.segments, b.segments, "{what}: segments");
    assert_eq!(a.energy_faults, b.energy_faults, "{what}: energy faults");
}

/// Traces `entries` trees of `s` at 30 deg with lanes at `lambdas` both ways and compares
/// every lane's tree; returns (segments traced at once, segments traced one by one).
fn compare_tracers(
    s: &Sample,
    lambdas: &[f64],
    limits: &TraceLimits,
    entries: usize,
) -> (u64, u64) {
    let scene = Scene::new(s, goniospec::accel::Backend::default_available()).unwrap();
    let idx: Vec<Vec<C64>> = lambdas.iter().map(|&l| indices(s, l)).collect();
    let lanes: Vec<Lane> = idx
        .iter()
        .zip(lambdas)
        .map(|(v, &l)| Lane {
            indices: v,
            lambda_nm: l,
        })
        .collect();
    let t = 30f64.to_radians();
    let d = DVec3::new(-t.sin(), 0.0, -t.cos());
    let mut stack = TraceStack::default();
    let mut shared: Vec<Tree> = lambdas.iter().map(|_| Tree::default()).collect();
    let mut single = Tree::default();
    let (mut at_once, mut one_by_one) = (0, 0);
    for i in 0..entries {
        // A grid of entry points over the tile.
        let (u, v) = (
            (i % 17) as f64 / 17.0 + 0.013,
            (i / 17) as f64 / 17.0 + 0.029,
        );
        let origin = DVec3::new(u * s.tile_nm[0], (v % 1.0) * s.tile_nm[1], scene.z_top);
        at_once += scene.trace_lanes(
            origin,
            d,
            launch_fields(d),
            &lanes,
            limits,
            &mut stack,
            &mut shared,
        );
        for (j, lane) in lanes.iter().enumerate() {
            one_by_one += scene.trace(
                origin,
                d,
                launch_fields(d),
                lane.indices,
                lane.lambda_nm,
                limits,
                &mut stack,
                &mut single,
            );
            assert_same_tree(
                &shared[j],
                &single,
                &format!("{}, entry {i}, lane {j}", s.name),
            );
        }
    }
    (at_once, one_by_one)
}

const LAMBDAS: [f64; 8] = [400.0, 437.5, 475.0, 512.5, 550.0, 600.0, 650.0, 700.0];

#[test]
fn rough_gold_traced_at_once_equals_each_wavelength_alone() {
    // A metal: the light that enters gold is absorbed, so nearly the whole tree is shared.
    let s = shipped("rough-gold.toml");
    let (at_once, one_by_one) = compare_tracers(&s, &LAMBDAS, &TraceLimits::default(), 289);
    assert!(
        (at_once as f64) < 0.5 * one_by_one as f64,
        "sharing must trace fewer segments: {at_once} vs {one_by_one}"
    );
}

#[test]
fn dispersive_glass_and_aluminium_grooves_traced_at_once_equal_each_wavelength_alone() {
    // Fused silica (Sellmeier): rays branch per wavelength at their first refraction into
    // the glass; what reflects above it stays shared. Aluminium V-grooves: multiple
    // reflections between metal walls, all shared.
    for name in ["rough-glass.toml", "v-grooves-aluminium.toml"] {
        let s = shipped(name);
        let (at_once, one_by_one) = compare_tracers(&s, &LAMBDAS, &TraceLimits::default(), 289);
        assert!(at_once < one_by_one, "{name}: {at_once} vs {one_by_one}");
    }
}

#[test]
fn per_lane_cutoff_and_segment_limit_match_each_wavelength_alone() {
    // A wavy film of a constant-index absorbing medium between dispersive air-like and
    // glass-like media: the cutoff (which weighs the absorption at each wavelength) keeps
    // different branches in different lanes, and a small segment limit cuts each lane's
    // tree at its own count. Both must still equal the per-wavelength trees.
    let d = scratch("lanes-cutoff");
    for f in ["thin-film-600nm-top.obj", "thin-film-600nm-bottom.obj"] {
        std::fs::copy(root().join("meshes").join(f), d.join(f)).unwrap();
    }
    let s = sample_in(
        &d,
        "[sample]\nname = \"absorbing wavy film\"\nunit = \"um\"\ntile = [20.0, 20.0]\n\
         [media.air]\nn = 1.0\n[media.ink]\nn = 1.6\nk = 0.004\n\
         [media.glass]\ncauchy = { a = 1.45, b_nm2 = 8000.0 }\n\
         [[interface]]\nmesh = \"thin-film-600nm-top.obj\"\nfront = \"air\"\nback = \"ink\"\n\
         [[interface]]\nmesh = \"thin-film-600nm-bottom.obj\"\nfront = \"ink\"\nback = \"glass\"\n",
    );
    let limits = TraceLimits {
        cutoff: 1e-4,
        max_segments: 12,
        ..TraceLimits::default()
    };
    compare_tracers(&s, &LAMBDAS, &limits, 289);
    compare_tracers(&s, &LAMBDAS, &TraceLimits::default(), 100);
}

/// Runs `s` with and without wavelength sharing and checks the accumulators are the same
/// bytes; returns the segments traced (with, without).
fn compare_runs(s: &Sample, cfg: &SimConfig) -> (u64, u64) {
    let (a, sa) = simulate(s, cfg, &|_| {}).unwrap();
    let per = SimConfig {
        wavelength_sharing: false,
        ..cfg.clone()
    };
    let (b, sb) = simulate(s, &per, &|_| {}).unwrap();
    assert!(sa.wavelength_sharing && !sb.wavelength_sharing);
    assert!(a.to_bytes() == b.to_bytes(), "{}: results differ", s.name);
    assert_eq!(sa.leaks, sb.leaks);
    (sa.segments, sb.segments)
}

#[test]
fn simulate_with_wavelength_sharing_writes_the_same_bytes() {
    let bins = Wavelengths::Bins((0..=30).map(|k| 400.0 + 10.0 * k as f64).collect());
    for name in ["rough-gold.toml", "rough-glass.toml", "ar-coating.toml"] {
        let s = shipped(name);
        let cfg = config(&[0.0, 45.0], bins.clone(), 400);
        let (with, without) = compare_runs(&s, &cfg);
        assert!(with < without, "{name}: {with} vs {without} segments");
    }
    // Monochromatic lines and the global estimator take the same path.
    let s = shipped("rough-gold.toml");
    let cfg = SimConfig {
        coherence: goniospec::accumulate::Coherence::Global,
        ..config(
            &[30.0],
            Wavelengths::Monochromatic(vec![450.0, 532.0, 633.0]),
            300,
        )
    };
    compare_runs(&s, &cfg);
}
