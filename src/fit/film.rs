//! The thin film of a fit: a grid start and Nelder-Mead over thickness, index, weight and a
//! dielectric base's index, and the films no material is (at the bounds of the search).

use rayon::prelude::*;

use super::{Base, Film, nelder_mead};

/// Why a fitted film is not a material but the fit running out of model, or `None`: its
/// index or thickness at the bounds of the search (index 1.0-3.0, within 0.05; thickness
/// within 10 nm of 20 or 2000 nm), or a free-standing film (the base air) on a sample that
/// transmits less than `mean_t` 0.05 (a free film would transmit). The shipped metallic
/// paint, aluminium flakes in a binder, was fitted as "a free-standing 41 nm film of ior
/// 3.0 on ior 1.0" (issue 46).
pub(super) fn implausible_film(base: &Base, f: &Film, mean_t: f64) -> Option<String> {
    let free = matches!(base, Base::Dielectric { n } if *n < 1.001);
    let at_bound = f.n < 1.05 || f.n > 2.95 || f.thickness_nm < 30.0 || f.thickness_nm > 1990.0;
    (at_bound || (free && mean_t < 0.05)).then(|| {
        format!(
            "a {}{:.0} nm film of ior {:.2}{}",
            if free { "free-standing " } else { "" },
            f.thickness_nm,
            f.n,
            match base {
                Base::Dielectric { n } => format!(" on ior {n:.2}"),
                Base::Conductor { .. } => " on a conductor".to_string(),
            }
        )
    })
}

/// A film on `base`: the best start on a thickness x index grid, refined with the
/// dielectric base's index free. `total` is the cost of a base and film, `on_base` the
/// same on `base` (its bare terms computed once). Returns (cost, base, film).
pub(super) fn fit_film(
    base: &Base,
    total: &dyn Fn(&Base, Option<Film>) -> f64,
    on_base: &(dyn Fn(Option<Film>) -> f64 + Sync),
) -> (f64, Base, Film) {
    // The grid, thickness 20-2000 nm by 5 and index 1.2-2.6 by 0.05 (11,513 starts),
    // costed in parallel; the first lowest in the sequential order wins, so the start is
    // the same whatever the thread count.
    let mut grid = Vec::new();
    let mut d = 20.0;
    while d <= 2000.0 {
        let mut nf = 1.2;
        while nf <= 2.6 + 1e-9 {
            grid.push((d, nf));
            nf += 0.05;
        }
        d += 5.0;
    }
    let costs: Vec<f64> = grid
        .par_iter()
        .map(|&(d, nf)| {
            on_base(Some(Film {
                thickness_nm: d,
                n: nf,
                weight: 1.0,
            }))
        })
        .collect();
    let mut start = (f64::INFINITY, 0.0, 0.0);
    for (&c, &(d, nf)) in costs.iter().zip(&grid) {
        if c < start.0 {
            start = (c, d, nf);
        }
    }
    let dielectric = matches!(base, Base::Dielectric { .. });
    let nb0 = match base {
        Base::Dielectric { n } => *n,
        Base::Conductor { .. } => 1.0,
    };
    let make = |p: &[f64]| -> (Base, Film) {
        let b = if dielectric {
            Base::Dielectric {
                n: p[3].clamp(1.0, 3.0),
            }
        } else {
            base.clone()
        };
        (
            b,
            Film {
                thickness_nm: p[0].abs(),
                n: p[1].clamp(1.0, 3.0),
                weight: p[2].clamp(0.0, 1.0),
            },
        )
    };
    let f = |p: &[f64]| {
        let (b, fm) = make(p);
        total(&b, Some(fm))
    };
    let p = nelder_mead(
        &f,
        &[start.1, start.2, 1.0, nb0],
        &[5.0, 0.03, 0.1, 0.05],
        600,
    );
    let (b, fm) = make(&p);
    (f(&p), b, fm)
}
