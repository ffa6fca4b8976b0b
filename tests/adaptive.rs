//! Adaptive budgets: with a tolerance, every direction stops once its reflectance's relative
//! standard error is at or below it, and the run spends fewer rays than a fixed budget that
//! reaches the same error in every direction.

mod common;

use std::path::Path;

use common::*;
use goniospec::accumulate::{Buckets, Coherence};
use goniospec::simulate::{Wavelengths, simulate};

#[test]
fn tolerance_is_met_with_fewer_rays_than_a_fixed_budget() {
    let s = goniospec::sample::load(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes/rough-glass.toml"),
        Default::default(),
    )
    .unwrap();
    let mut cfg = config(
        &[20.0, 50.0, 75.0],
        Wavelengths::Monochromatic(vec![550.0]),
        512,
    );
    cfg.buckets = Buckets {
        theta_bins: 9,
        phi_bins: 8,
    };
    cfg.tolerance = Some(0.1);
    cfg.max_rays = 200_000;
    let (acc, stats) = simulate(&s, &cfg, &|_| {}).unwrap();
    let tol = 0.1;
    // Check the achieved error here, from the cells: total R and every bucket holding at
    // least a tenth of the brightest bucket's power.
    for (i, d) in stats.directions.iter().enumerate() {
        assert!(d.converged, "{d:?}");
        let c = acc.cell(i, 0);
        assert_eq!(c.trees, d.rays);
        let n = c.trees as f64;
        let r = c.r_sum / n;
        assert!(c.r_stderr(Coherence::Beamlet).unwrap() <= tol * r);
        let fmax = (0..c.sum.len())
            .step_by(2)
            .map(|k| c.sum[k] / n)
            .fold(0.0, f64::max);
        for k in (0..c.sum.len()).step_by(2) {
            let f = c.sum[k] / n;
            if f >= 0.1 * fmax && f > 0.0 {
                let se = goniospec::accumulate::stderr(c.sum[k], c.sumsq[k], c.trees);
                assert!(
                    se <= tol * f,
                    "direction {i}, bucket {k}: {se} > {tol} x {f}"
                );
            }
        }
    }
    let spent: u64 = stats.directions.iter().map(|d| d.rays).sum();
    let most = stats.directions.iter().map(|d| d.rays).max().unwrap();
    eprintln!(
        "adaptive: {:?} rays (total {spent}); a fixed budget needs {most} per direction",
        stats.directions.iter().map(|d| d.rays).collect::<Vec<_>>()
    );
    // The fixed budget that reaches the same error everywhere spends `most` per direction.
    let mut fixed = cfg.clone();
    fixed.tolerance = None;
    fixed.rays = most;
    let (_, fs) = simulate(&s, &fixed, &|_| {}).unwrap();
    for d in &fs.directions {
        assert!(d.achieved.unwrap() <= tol * 1.05, "fixed budget: {d:?}");
    }
    assert!(
        spent < most * 3,
        "adaptive {spent} should be below fixed {}",
        most * 3
    );
    // Deterministic: batches are whole blocks, whatever the thread count.
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| run(&s, &cfg));
    assert!(one.to_bytes() == acc.to_bytes());
}
