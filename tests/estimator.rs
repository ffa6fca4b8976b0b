//! The fast beamlet estimator against the reference one (`Estimator::reference`): pairs of
//! exits whose cross term is below `NEGLIGIBLE_CROSS` at the longest wavelength are culled
//! before the wavelength loop, which must not change the physics. On every shipped sample
//! the cell totals (R, T, absorbed) agree to 1e-12 relative, and every bucket to 1e-12 of
//! its cell's reflected plus transmitted power.

mod common;

use common::*;
use goniospec::accumulate::Coherence;
use goniospec::simulate::{SimConfig, Wavelengths};

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
        let fast = run(&s, &cfg);
        let reference = run(
            &s,
            &SimConfig {
                reference_estimator: true,
                ..cfg.clone()
            },
        );
        culled_somewhere |= fast.to_bytes() != reference.to_bytes();
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
    }
    // The comparison must have seen culled pairs, or it tested nothing.
    assert!(culled_somewhere, "no sample had a pair to cull");
}
