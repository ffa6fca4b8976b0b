//! Adaptive spatial resolution for the C-method on reliefs with sharp corners (a disc's
//! trapezoidal track, a V-groove): docs/physics.md, "Reliefs with corners: adaptive spatial
//! resolution".
//!
//! The C-method expands the fields in Fourier harmonics along x; at a corner of a metal
//! relief the TM field is singular and its harmonics fall off slowly, so a trapezoid
//! converges as a power of the truncation (the optical disc at 30 deg and 500 nm: TM R still
//! moves by 2e-3 from 80 to 200 harmonics). Granet, Chandezon, Plumey & Raniriharinosy
//! (2001, JOSA A 18, 2102, "Reformulation of the coordinate transformation method through
//! the concept of adaptive spatial resolution. Application to trapezoidal gratings") take
//! the harmonics in a stretched coordinate `x₁` with `x = f(x₁)`, `f(x₁ + Λ) = f(x₁) + Λ`,
//! whose derivative `φ = f'` is small at the corners: there the harmonics see the field
//! through a magnifying glass. In the coordinates `(x₁, u = z − a(f(x₁)))` the covariant
//! Helmholtz equation `∂ᵢ(√g gⁱʲ ∂ⱼF) + ε √g F = 0` (`√g = φ`) has the C-method's form
//! with, in place of `ȧ`, `w = 1 / (1 + ȧ²)` and `ε`,
//!
//! ```text
//! s = ȧ(f(x₁)),     w̃ = 1 / (φ (1 + s²)),     ε φ
//! ```
//!
//! and the flux `G = φ (∂z − s ∂x) F` (so `F` and `G / η` are still what is continuous; in
//! conical incidence the tangential fields along `∂₁` are `φ` times those along `(1, 0, ȧ)`,
//! a factor both sides share). A plane wave `e^{i(αₙx ± βz)}` is the mode with
//! `F = e^{iαₙ(f − x₁)} e^{±iβa(f)}` times `e^{iαₙx₁ ± iβu}` and `G = iφ(±β − αₙ s) F`.
//!
//! The stretch is the one of Granet (1999, JOSA A 16, 2510) between consecutive corners
//! `x_l`, `x_{l+1}` (`Δ = x_{l+1} − x_l`):
//!
//! ```text
//! f(x₁) = x₁ − (1 − η) Δ / (2π) sin(2π (x₁ − x_l) / Δ),     φ = 1 − (1 − η) cos(2π (x₁ − x_l) / Δ)
//! ```
//!
//! so `f` fixes the corners, `φ = η` there (both sides: `φ` is continuous, with a continuous
//! derivative) and `η ≤ φ ≤ 2 − η`.

/// The stretch's `φ` at the corners: the harmonics resolve `1 / η` times finer there.
/// On the optical disc (aluminium, 400-700 nm, 0-60 deg) 0.1 reaches the check's 5e-3 at
/// fewer harmonics than 0.02, 0.05 or 0.2 (at 120 harmonics against 80: 2e-4 to 7e-3,
/// where 0.02 gives 7e-4 to 1.9e-2), and 1 (no stretch) does not converge by 200.
pub(super) const ETA: f64 = 0.1;

/// The smallest turn of the relief's direction at a vertex, rad, that counts as a corner
/// (10 deg: a meshed sinusoid of 256 facets turns by 0.5 deg a facet and keeps the plain
/// C-method, which converges fast on it).
const SHARP_RAD: f64 = 10.0 * std::f64::consts::PI / 180.0;

/// Slopes equal within this (relative) are one straight run of the samples.
const SAME_SLOPE: f64 = 1e-7;

/// A periodic polyline: vertices `(x, z)` (nm) with `0 ≤ x < Λ`, increasing.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Polyline {
    pub(super) period_nm: f64,
    pub(super) vertices: Vec<(f64, f64)>,
}

impl Polyline {
    /// The polyline's height and slope at `x` (nm; any real, taken modulo the period); at a
    /// vertex, the slope of the segment after it.
    pub(super) fn at(&self, x: f64) -> (f64, f64) {
        let l = self.period_nm;
        let x = x.rem_euclid(l);
        let v = &self.vertices;
        // The segment [v[k], v[k + 1]] (cyclically, the last one wrapping) holding x.
        let k = v.partition_point(|p| p.0 <= x);
        let (a, b) = if k == 0 {
            let last = v[v.len() - 1];
            ((last.0 - l, last.1), v[0])
        } else if k == v.len() {
            (v[k - 1], (v[0].0 + l, v[0].1))
        } else {
            (v[k - 1], v[k])
        };
        let slope = (b.1 - a.1) / (b.0 - a.0);
        (a.1 + slope * (x - a.0), slope)
    }

    /// The vertices where the direction turns by more than [`SHARP_RAD`]: x (nm).
    pub(super) fn corners(&self) -> Vec<f64> {
        let n = self.vertices.len();
        (0..n)
            .filter(|&k| {
                let x = self.vertices[k].0;
                let before = self.at(x - 1e-9 * self.period_nm).1;
                let after = self.at(x).1;
                (after.atan() - before.atan()).abs() > SHARP_RAD
            })
            .map(|k| self.vertices[k].0)
            .collect()
    }
}

/// The polyline through samples `heights` at `x_i = i Λ / S`, with its true corners: the
/// samples fall into straight runs, and a single interval between two runs of two or more
/// holds the corner where their lines meet (found there, not cut off by the samples).
pub(super) fn polyline(heights: &[f64], period_nm: f64) -> Polyline {
    let s = heights.len();
    let dx = period_nm / s as f64;
    let slope = |i: usize| (heights[(i + 1) % s] - heights[i]) / dx;
    // Runs of equal slope, as (first interval, intervals, slope), cyclically starting at a
    // slope change (a relief with none is flat).
    let same = |a: f64, b: f64| (a - b).abs() <= SAME_SLOPE * (1.0 + a.abs().max(b.abs()));
    let Some(start) = (0..s).find(|&i| !same(slope((i + s - 1) % s), slope(i))) else {
        return Polyline {
            period_nm,
            vertices: vec![(0.0, heights[0])],
        };
    };
    let mut runs: Vec<(usize, usize, f64)> = Vec::new();
    for k in 0..s {
        let i = (start + k) % s;
        match runs.last_mut() {
            Some(r) if same(r.2, slope(i)) => r.1 += 1,
            _ => runs.push((i, 1, slope(i))),
        }
    }
    // Unwrapped x of the sample that starts interval `i`, counted from `start`.
    let x_of = |i: usize| ((i + s - start) % s + start) as f64 * dx;
    let z_of = |i: usize| heights[i % s];
    let nr = runs.len();
    // The corner a single interval between two longer runs holds, where their lines meet.
    let corner = |k: usize| -> Option<(f64, f64)> {
        let (i, len, _) = runs[k];
        let (prev, next) = (runs[(k + nr - 1) % nr], runs[(k + 1) % nr]);
        if len != 1 || prev.1 < 2 || next.1 < 2 || nr < 3 || prev.2 == next.2 {
            return None;
        }
        let (x0, z0) = (x_of(i), z_of(i));
        let x1 = x0 + dx;
        let xc = (z_of(i + 1) - z0 + prev.2 * x0 - next.2 * x1) / (prev.2 - next.2);
        (xc >= x0 - 1e-9 * dx && xc <= x1 + 1e-9 * dx).then_some((xc, z0 + prev.2 * (xc - x0)))
    };
    let corners: Vec<Option<(f64, f64)>> = (0..nr).map(corner).collect();
    let mut vertices = Vec::with_capacity(nr);
    for k in 0..nr {
        match corners[k] {
            Some(c) => vertices.push(c),
            // A run's first sample, unless a corner interval before it stands in for it.
            None if corners[(k + nr - 1) % nr].is_none() => {
                vertices.push((x_of(runs[k].0), z_of(runs[k].0)));
            }
            None => {}
        }
    }
    let mut vertices: Vec<(f64, f64)> = vertices
        .into_iter()
        .map(|(x, z)| (x.rem_euclid(period_nm), z))
        .collect();
    vertices.sort_by(|a, b| a.0.total_cmp(&b.0));
    vertices.dedup_by(|a, b| (a.0 - b.0).abs() < 1e-12 * period_nm);
    Polyline {
        period_nm,
        vertices,
    }
}

/// The stretched coordinate's samples: at `x₁ = i Λ / S`, `f(x₁)` (nm) and `φ = f'(x₁)`,
/// with `corners` (nm, increasing, in `[0, Λ)`) fixed and `φ = ETA` there.
pub(super) fn stretch(corners: &[f64], period_nm: f64, samples: usize) -> Vec<(f64, f64)> {
    let two_pi = 2.0 * std::f64::consts::PI;
    (0..samples)
        .map(|i| {
            let x1 = i as f64 * period_nm / samples as f64;
            // The corner at or before x1 (cyclically) and the next one.
            let k = corners.partition_point(|&c| c <= x1);
            let (lo, hi) = if k == 0 {
                (corners[corners.len() - 1] - period_nm, corners[0])
            } else if k == corners.len() {
                (corners[k - 1], corners[0] + period_nm)
            } else {
                (corners[k - 1], corners[k])
            };
            let delta = hi - lo;
            let t = two_pi * (x1 - lo) / delta;
            let f = x1 - (1.0 - ETA) * delta / two_pi * t.sin();
            let phi = 1.0 - (1.0 - ETA) * t.cos();
            (f, phi)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The disc's trapezoid: 0 to 500 nm at 0, down to −200 at 550, flat to 1050, up to 0
    /// at 1100, over 1600 nm.
    fn trapezoid(x: f64) -> f64 {
        if x < 500.0 {
            0.0
        } else if x < 550.0 {
            -(x - 500.0) * 4.0
        } else if x < 1050.0 {
            -200.0
        } else if x < 1100.0 {
            -200.0 + (x - 1050.0) * 4.0
        } else {
            0.0
        }
    }

    #[test]
    fn a_sampled_trapezoid_gives_back_its_four_corners_exactly() {
        // 1000 samples: 1.6 nm apart, the corners at 500, 550 and 1050 on samples' x
        // (312.5, 343.75, 656.25 intervals) or between them.
        for s in [1000usize, 1024, 777] {
            let h: Vec<f64> = (0..s)
                .map(|i| trapezoid(i as f64 * 1600.0 / s as f64))
                .collect();
            let p = polyline(&h, 1600.0);
            let want = [
                (500.0, 0.0),
                (550.0, -200.0),
                (1050.0, -200.0),
                (1100.0, 0.0),
            ];
            assert_eq!(p.vertices.len(), 4, "{s}: {:?}", p.vertices);
            for (v, w) in p.vertices.iter().zip(want) {
                assert!(
                    (v.0 - w.0).abs() < 1e-9 && (v.1 - w.1).abs() < 1e-9,
                    "{v:?}"
                );
            }
            assert_eq!(p.corners().len(), 4);
            for x in [10.0, 520.0, 700.0, 1080.0, 1599.0, -3.0, 1610.0] {
                let (z, _) = p.at(x);
                assert!((z - trapezoid(x.rem_euclid(1600.0))).abs() < 1e-9, "{x}");
            }
        }
    }

    #[test]
    fn a_meshed_sinusoid_has_no_sharp_corner() {
        // 256 facets of 50 cos(2πx/1000) over 1024 samples.
        let facet = |x: f64| {
            let w = 1000.0 / 256.0;
            let k = (x / w).floor();
            let z = |x: f64| 50.0 * (2.0 * std::f64::consts::PI * x / 1000.0).cos();
            let t = (x - k * w) / w;
            z(k * w) * (1.0 - t) + z((k + 1.0) * w) * t
        };
        let h: Vec<f64> = (0..1024)
            .map(|i| facet(i as f64 * 1000.0 / 1024.0))
            .collect();
        assert!(polyline(&h, 1000.0).corners().is_empty());
    }

    #[test]
    fn the_stretch_fixes_the_corners_and_keeps_its_derivative() {
        let corners = [500.0, 550.0, 1050.0, 1100.0];
        let s = 4096;
        let st = stretch(&corners, 1600.0, s);
        let dx = 1600.0 / s as f64;
        for (i, &(f, phi)) in st.iter().enumerate() {
            assert!((ETA - 1e-12..=2.0 - ETA + 1e-12).contains(&phi));
            // φ is f's derivative: a centred difference, to second order in dx.
            let (fa, fb) = (st[(i + s - 1) % s].0, st[(i + 1) % s].0);
            let wrap = |d: f64| d - 1600.0 * (d / 1600.0).round();
            let fd = wrap(fb - fa) / (2.0 * dx);
            assert!((fd - phi).abs() < 1e-3, "{i}: {fd} {phi}");
            let _ = f;
        }
        // x₁ = 512 · 1600 / 4096 = 200 is not a corner; 1280 → 500 is.
        assert!((st[1280].0 - 500.0).abs() < 1e-12 && (st[1280].1 - ETA).abs() < 1e-12);
    }
}
