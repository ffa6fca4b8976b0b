//! Where trees enter the tile: the R2 sequence (rays) or a lattice (diffraction).

/// Entry point `i` of `n` on the tile: the R2 low-discrepancy sequence (Roberts 2018,
/// "The unreasonable effectiveness of quasirandom sequences") with a random shift.
/// `guard` (nm) keeps the points that far from every side (open samples; 0 otherwise).
pub(super) fn entry_point(i: u64, shift: [f64; 2], tile: [f64; 2], guard: f64) -> [f64; 2] {
    const G: f64 = 1.324_717_957_244_746; // plastic number
    let a = [1.0 / G, 1.0 / (G * G)];
    let f = |k: usize| (shift[k] + (i as f64) * a[k]).rem_euclid(1.0);
    // With no guard this is `f * tile` exactly (`0 + x` and `L - 0` round to themselves).
    [0, 1].map(|k| guard + f(k) * (tile[k] - 2.0 * guard))
}

/// The diffraction method's entry points: an `nx x ny` lattice over the tile with about
/// `rays` points and cells as square as the tile allows (`nx / ny` near `Lx / Ly`). Its
/// tubes' footprints tile the exit plane with a near-constant overlap, so the Gaussian
/// patches of `accumulate::diffraction` sum to a uniform field (on a lattice of spacing d,
/// patches of 0.6 d ripple by `2 exp(-2 pi^2 0.36) = 1.6e-3`; an R2 set ripples by
/// percents and scatters that much power into spurious orders).
///
/// Each side's count is a prime (the first at or above the nearest count), so it shares no
/// factor with a mesh's grid below it: a lattice commensurate with the mesh puts every tree
/// at the same place in its facet, a biased quadrature (issue 48: the seed's film, meshed
/// 64 x 64, on a 64 x 64 lattice at 15 deg and 430-440 nm had R 0.0605 and R + T 1.009,
/// against 0.0571 and 1.0007 from R2 points; `tests/auto.rs`).
pub fn diffraction_lattice(rays: u64, tile_nm: [f64; 2]) -> [u64; 2] {
    let nx = ((rays as f64 * tile_nm[0] / tile_nm[1]).sqrt().round() as u64).max(1);
    let ny = ((rays as f64 / nx as f64).round() as u64).max(1);
    [next_prime(nx), next_prime(ny)]
}

/// The least prime at or above `n` (0 and 1 stay: a single tree has no lattice to alias).
fn next_prime(n: u64) -> u64 {
    let prime = |m: u64| m >= 2 && (2..).take_while(|d| d * d <= m).all(|d| m % d != 0);
    if n <= 1 {
        return n;
    }
    (n..).find(|&m| prime(m)).unwrap_or(n)
}

/// Point `i` of the lattice `n` (see [`diffraction_lattice`]), shifted by `shift` cells.
pub(super) fn lattice_point(i: u64, n: [u64; 2], shift: [f64; 2], tile: [f64; 2]) -> [f64; 2] {
    let (ix, iy) = (i % n[0], i / n[0]);
    [
        (ix as f64 + shift[0]) / n[0] as f64 * tile[0],
        (iy as f64 + shift[1]) / n[1] as f64 * tile[1],
    ]
}
