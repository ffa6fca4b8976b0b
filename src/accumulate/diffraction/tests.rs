use super::*;

/// The setting of the lone-tube tests: normal incidence at 500 nm into vacuum, a 4 um
/// tile with 8 x 8 trees, plane-wave illumination.
fn lone_hemisphere() -> Hemisphere {
    Hemisphere {
        tile_nm: [4000.0, 4000.0],
        lambda_nm: 500.0,
        n_out: 1.0,
        k_in: [0.0, 0.0],
        cos_i: 1.0,
        lattice: [8, 8],
        rho_nm: f64::INFINITY,
        down: false,
        mueller: false,
    }
}

/// The propagating orders of `h` (the transverse wave vector `G`, 1/nm, inside the disk
/// `|G| < k n_out`; `k_in` is 0) with their indices, out to the ninth.
fn propagating_orders(h: &Hemisphere) -> Vec<([i64; 2], [f64; 2])> {
    let kn = 2.0 * PI / h.lambda_nm * h.n_out;
    let mut out = Vec::new();
    for ox in -9i64..=9 {
        for oy in -9i64..=9 {
            let g = [
                2.0 * PI * ox as f64 / h.tile_nm[0],
                2.0 * PI * oy as f64 / h.tile_nm[1],
            ];
            if g[0] * g[0] + g[1] * g[1] < kn * kn {
                out.push(([ox, oy], g));
            }
        }
    }
    out
}

/// A tube the same shape as at launch.
const UNMAPPED: TubeShape = TubeShape {
    jac: [[1.0, 0.0], [0.0, 1.0]],
    fallback: false,
};

/// One tube alone, leaving obliquely, on the grid sized by its own direction: every
/// propagating order's amplitude is its patch's continuous transform, `a amp / N exp(-i
/// G . x_w) exp(-(q - G)^T C (q - G) / 2)` (the Gaussian of covariance `C` normalised by
/// its integral, as the splat normalises by its sum; Goodman §2.2), to within the folded
/// copies and the cut. The grid keeps each copy `ALIAS_MARGIN` standard deviations off
/// the disk, so at any one order the nearest copy along each axis is at most `exp(-8)`
/// of the peak (the copy on the far side and the diagonal ones are below `exp(-16)`);
/// the cut at five standard deviations leaves out `exp(-12.5)` of the sum, and as much
/// again by the renormalisation. (Without the tubes' directions in the period, or
/// without its margin, the worst order is off by 1.3e-3 of the peak here.)
#[test]
fn a_lone_oblique_tube_has_its_patch_s_transform_in_every_order() {
    let h = lone_hemisphere();
    let c0 = C64::new(0.0, 0.0);
    // The last two, tubes a hundredth as strong: the margin shrinks so their copies stay under
    // the same absolute level (`alias_margin`), measured against the incident wave's.
    for (w, m) in [
        ([0.8, 0.3], 1.0),
        ([-0.55, 0.8], 1.0),
        ([0.0, 0.0], 1.0),
        ([0.7, -0.6], 1.0),
        ([0.7, -0.6], 0.01),
        ([0.0, 0.0], 0.01),
    ] {
        let c = Contribution {
            tree: 0,
            slot: 0,
            x: [1234.0, 2871.0],
            w,
            a: [[C64::new(m, 0.0), c0, c0], [c0, C64::new(0.0, m), c0]],
            tube: 1.0,
            path: 0,
            down: false,
        };
        let shape = UNMAPPED;
        let (amp, mass) = footprint(&h, &c, &shape);
        let kn = 2.0 * PI / h.lambda_nm;
        let [mx, my] = cells_for(h.tile_nm, kn, period(&h, [(c.w, mass)].into_iter()));
        let mut scratch = Scratch::default();
        let tube = ((&c, &shape), (amp, mass));
        exit_plane_field(&h, [tube].into_iter(), [mx, my], &mut scratch);
        fft2(&mut scratch.grids, [mx, my], &mut scratch.fft);
        // The covariance the splat used: the unmapped patch plus its floor, a quarter of
        // the larger cell side squared.
        let dx = (h.tile_nm[0] / mx as f64).max(h.tile_nm[1] / my as f64);
        let var = (PATCH_SIGMA_STEPS * 500.0).powi(2) + 0.25 * dx * dx;
        let q = [kn * w[0], kn * w[1]];
        // The peak of a tube as strong as the incident wave.
        let peak = amp / 64.0;
        let mut worst: f64 = 0.0;
        let mut orders = 0;
        for ([mxo, myo], g) in propagating_orders(&h) {
            orders += 1;
            let d2 = (q[0] - g[0]).powi(2) + (q[1] - g[1]).powi(2);
            let phase = C64::from_polar(1.0, -(g[0] * c.x[0] + g[1] * c.x[1]));
            let want = phase * (m * peak * (-0.5 * var * d2).exp());
            let cell = mxo.rem_euclid(mx as i64) as usize + mx * myo.rem_euclid(my as i64) as usize;
            // Polarisation 0 along x, polarisation 1 along y (times i).
            let got = [
                scratch.grids[0][cell],
                scratch.grids[4][cell] * C64::new(0.0, -1.0),
            ];
            for v in got {
                worst = worst.max((v - want).norm() / peak);
            }
        }
        assert!(orders > 150, "{orders} orders");
        let bound = 2.0 * ((-8.0f64).exp() + (-16.0f64).exp() + (-12.5f64).exp());
        assert!(
            worst < bound,
            "w {w:?}: {mx} x {my} cells, worst {worst:.2e} of the peak (at most {bound:.2e})"
        );
    }
}

/// A tube too weak for a patch (below `patch::POINT_MASS`) is deposited on the four cells
/// around its centre: at the order along its own direction its amplitude is exactly its
/// field, `a amp / N exp(-i q . x_w)` (the bilinear shares sum to one and each cell carries
/// the plane wave's phase there), and at every other propagating order it is within twice
/// the peak of its patch's continuous transform (the bound `patch::Patches::push_point`
/// states: both are at most the peak in modulus). The tube's direction is put on an order,
/// `q = G_(3, -2)`, and its centre off the grid's cells in both axes.
#[test]
fn a_tube_below_the_alias_level_keeps_its_own_order_exactly() {
    let h = lone_hemisphere();
    let kn = 2.0 * PI / h.lambda_nm;
    let g_own = [2.0 * PI * 3.0 / 4000.0, 2.0 * PI * -2.0 / 4000.0];
    let w = [g_own[0] / kn, g_own[1] / kn];
    let m = 1e-4;
    assert!(m < super::super::patch::POINT_MASS);
    let c0 = C64::new(0.0, 0.0);
    let a0 = C64::from_polar(m, 0.4);
    let c = Contribution {
        tree: 0,
        slot: 0,
        x: [1234.5, 2871.25],
        w,
        a: [[a0, c0, c0], [c0, a0 * C64::new(0.0, 1.0), c0]],
        tube: 1.0,
        path: 0,
        down: false,
    };
    let shape = UNMAPPED;
    let (amp, mass) = footprint(&h, &c, &shape);
    assert!(mass < super::super::patch::POINT_MASS, "mass {mass}");
    let [mx, my] = cells_for(h.tile_nm, kn, period(&h, [(c.w, mass)].into_iter()));
    let mut scratch = Scratch::default();
    exit_plane_field(
        &h,
        [((&c, &shape), (amp, mass))].into_iter(),
        [mx, my],
        &mut scratch,
    );
    // Not on a cell: the deposit is spread over four.
    let dx = h.tile_nm[0] / mx as f64;
    assert!((c.x[0] / dx).fract() > 0.05 && (c.x[1] / dx).fract() > 0.05);
    let nonzero = scratch.grids[0].iter().filter(|v| v.norm() > 0.0).count();
    assert_eq!(nonzero, 4, "cells holding the tube's field");
    fft2(&mut scratch.grids, [mx, my], &mut scratch.fft);
    let var = (PATCH_SIGMA_STEPS * 500.0).powi(2) + 0.25 * dx * dx;
    let peak = m * amp / 64.0;
    let cell_of = |o: [i64; 2]| {
        o[0].rem_euclid(mx as i64) as usize + mx * o[1].rem_euclid(my as i64) as usize
    };
    let mut orders = 0;
    for ([ox, oy], g) in propagating_orders(&h) {
        orders += 1;
        let phase = C64::from_polar(1.0, -(g[0] * c.x[0] + g[1] * c.x[1]));
        let d2 = (g_own[0] - g[0]).powi(2) + (g_own[1] - g[1]).powi(2);
        let want = phase * a0 * (amp / 64.0) * (-0.5 * var * d2).exp();
        let got = [
            scratch.grids[0][cell_of([ox, oy])],
            scratch.grids[4][cell_of([ox, oy])] * C64::new(0.0, -1.0),
        ];
        for v in got {
            if [ox, oy] == [3, -2] {
                assert!(
                    (v - want).norm() <= 1e-12 * peak,
                    "own order: {v} against {want}"
                );
            } else {
                assert!(
                    (v - want).norm() <= 2.0 * peak,
                    "order ({ox}, {oy}): {v} against {want}, peak {peak:e}"
                );
            }
        }
    }
    assert!(orders > 150, "{orders} orders");
}
