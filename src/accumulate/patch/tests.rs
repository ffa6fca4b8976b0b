use super::*;

/// The patch's splat against the definition evaluated cell by cell: every cell of the
/// grid whose unwrapped offset `(u, v)` from the tube's point lies inside the ellipse
/// `quad(u, v) <= radius^2` gets `a exp(-quad / 2) exp(i q . (u, v))`, added at its
/// place modulo the grid (periodic images), and the Gaussian's sum is their sum.
fn reference(
    inv: [f64; 3],
    radius: f64,
    q: [f64; 2],
    xw: [f64; 2],
    d: [f64; 2],
    [mx, my]: [usize; 2],
    a: [Field; 2],
) -> (Vec<[f64; 12]>, f64) {
    let [ixx, iyy, ixy] = inv;
    let mut cells = vec![[0.0; 12]; mx * my];
    let mut sum = 0.0;
    let reach = 8 * mx.max(my) as i64;
    for iy in -reach..reach {
        for ix in -reach..reach {
            let (u, v) = (ix as f64 * d[0] - xw[0], iy as f64 * d[1] - xw[1]);
            let quad = ixx * u * u + 2.0 * ixy * u * v + iyy * v * v;
            if quad > radius * radius {
                continue;
            }
            let g = (-0.5 * quad).exp();
            sum += g;
            let w = C64::from_polar(g, q[0] * u + q[1] * v);
            let cell = &mut cells[wrap(iy, my) * mx + wrap(ix, mx)];
            for (comp, f) in a.iter().flatten().enumerate() {
                let z = f * w;
                cell[2 * comp] += z.re;
                cell[2 * comp + 1] += z.im;
            }
        }
    }
    (cells, sum)
}

/// The rows, their weights by recurrence four cells a lane, and the runs split at the
/// tile's edge give what the definition gives, cell by cell: a round patch, a sheared
/// one cut at the smallest radius, one wider than a lane crossing both edges of the
/// grid, and one larger than the grid itself (its images overlap).
#[test]
fn the_splat_is_the_gaussian_times_the_plane_wave_in_every_cell() {
    let a: [Field; 2] = [
        [
            C64::new(0.3, -0.1),
            C64::new(0.05, 0.2),
            C64::new(-0.02, 0.01),
        ],
        [
            C64::new(-0.1, 0.4),
            C64::new(0.2, 0.0),
            C64::new(0.0, -0.03),
        ],
    ];
    // (inverse covariance from cxx, cyy, cxy in nm^2; radius; q in 1/nm; point in nm;
    // spacing in nm; cells).
    type Case = ([f64; 3], f64, [f64; 2], [f64; 2], [f64; 2], [usize; 2]);
    let cases: [Case; 5] = [
        (
            [15_000.0, 15_000.0, 0.0],
            5.0,
            [0.004, -0.002],
            [1013.7, 987.2],
            [103.0, 97.0],
            [20, 21],
        ),
        (
            [40_000.0, 9_000.0, 15_000.0],
            1.5,
            [-0.011, 0.007],
            [777.7, 1201.3],
            [101.0, 99.0],
            [24, 25],
        ),
        (
            [90_000.0, 30_000.0, -20_000.0],
            4.2,
            [0.013, 0.009],
            [30.5, 1911.1],
            [99.0, 103.0],
            [20, 20],
        ),
        (
            [250_000.0, 200_000.0, 50_000.0],
            5.0,
            [0.002, 0.001],
            [500.3, 400.9],
            [100.0, 100.0],
            [9, 8],
        ),
        // A tube squeezed to the covariance's floor across and stretched along a
        // diagonal (correlation 0.99): the recurrences' ratios at their extremes.
        (
            [2_600.0, 250_000.0, 0.99 * (2_600.0f64 * 250_000.0).sqrt()],
            5.0,
            [-0.015, 0.012],
            [1503.1, 1188.4],
            [100.0, 101.0],
            [30, 31],
        ),
    ];
    for (k, &([cxx, cyy, cxy], radius, q, xw, d, n)) in cases.iter().enumerate() {
        let det = cxx * cyy - cxy * cxy;
        let inv = [cyy / det, cxx / det, -cxy / det];
        let (want, want_sum) = reference(inv, radius, q, xw, d, n, a);
        let mut p = Patches::default();
        let spec = Spec {
            inv,
            sx: cxx.sqrt(),
            radius,
            q,
            xw,
        };
        let rows = patch_rows(&mut p, spec, d, n);
        let sum = rows.sum();
        let mut got = vec![[0.0; 12]; n[0] * n[1]];
        rows.splat(&mut got, a);
        assert!(
            (sum - want_sum).abs() <= 1e-12 * want_sum,
            "case {k}: sum {sum} against {want_sum}"
        );
        let scale = want.iter().flatten().fold(0.0f64, |m, x| m.max(x.abs()));
        assert!(scale > 0.0);
        for (c, (g, w)) in got.iter().zip(&want).enumerate() {
            for i in 0..12 {
                assert!(
                    (g[i] - w[i]).abs() <= 1e-12 * scale,
                    "case {k}, cell {c}, real {i}: {} against {}",
                    g[i],
                    w[i]
                );
            }
        }
    }
}

/// `ceil_i` and `floor_i` against the library's, at integers, halves, either side of
/// them and far out.
#[test]
fn ceil_and_floor_are_the_librarys() {
    for x in [
        0.0f64,
        -0.0,
        0.5,
        -0.5,
        1.0,
        -1.0,
        2.5,
        -2.5,
        3.4999,
        -3.4999,
        1e-300,
        -1e-300,
        123456.75,
        -98765.25,
        1.0e15 + 0.5,
        -(1.0e15 + 0.5),
    ] {
        for y in [x, x.next_up(), x.next_down()] {
            assert_eq!(ceil_i(y), y.ceil() as i64, "ceil {y}");
            assert_eq!(floor_i(y), y.floor() as i64, "floor {y}");
        }
    }
}

/// Where a tube's patch is cut: at `PATCH_RADIUS` for a tube as strong as the incident
/// wave or stronger, where `m exp(-r^2 / 2) = exp(-PATCH_RADIUS^2 / 2)` below it, and
/// never under `MIN_RADIUS` (a vanishing tube, too).
#[test]
fn weaker_tubes_are_cut_at_the_same_absolute_level() {
    assert_eq!(radius(1.0), PATCH_RADIUS);
    assert_eq!(radius(3.0), PATCH_RADIUS);
    assert_eq!(radius(f64::NAN), PATCH_RADIUS);
    for m in [0.5, 1e-2, 2e-3] {
        let r = radius(m);
        let level = m * (-0.5 * r * r).exp();
        let want = (-0.5 * PATCH_RADIUS * PATCH_RADIUS).exp();
        assert!((level / want - 1.0).abs() < 1e-12, "m {m}: r {r}");
    }
    assert_eq!(radius(1e-9), MIN_RADIUS);
    assert_eq!(radius(0.0), MIN_RADIUS);
}
