//! `goniospec bench rigorous`: the rigorous solver's time per cell (one wavelength and
//! angle) on a 1-D grating at 41 orders and a crossed grating at 11 x 11 orders, each of 24
//! slices, one solve and a cell with its convergence check, on one thread.

use std::time::Instant;

use glam::DVec3;

use crate::optics::C64;
use crate::optics::rcwa::{self, Grid, Harmonics, Layer, RcwaError, Slab, Structure};

/// A grating of `slices` slices over `period` nm (`two_d`: crossed, `z = A (cos 2πx/Λ +
/// cos 2πy/Λ) / 2`; else `z = A cos 2πx/Λ`), aluminium-like (ε = -40 + 15i) under air.
pub fn grating(two_d: bool, period: f64, amp: f64, slices: usize, pixels: usize) -> Structure {
    let metal = C64::new(-40.0, 15.0);
    let air = C64::new(1.0, 0.0);
    let ny = if two_d { pixels } else { 1 };
    let dz = 2.0 * amp / slices as f64;
    let layers = (0..slices)
        .map(|k| {
            let z = amp - (k as f64 + 0.5) * dz;
            let eps = (0..pixels * ny)
                .map(|i| {
                    let u = |j: usize, n: usize| {
                        (2.0 * std::f64::consts::PI * (j as f64 + 0.5) / n as f64).cos()
                    };
                    let h = if two_d {
                        amp * 0.5 * (u(i % pixels, pixels) + u(i / pixels, ny))
                    } else {
                        amp * u(i, pixels)
                    };
                    if h > z { metal } else { air }
                })
                .collect();
            Layer {
                thickness_nm: dz,
                slab: Slab::Grid(Grid {
                    n: [pixels, ny],
                    eps,
                }),
            }
        })
        .collect();
    Structure {
        period_nm: [period, if two_d { period } else { 1.0 }],
        eps_above: 1.0,
        layers,
        eps_below: metal,
    }
}

/// The median wall time of `runs` solves, s, and the last solution's R (unpolarised).
pub fn time_solve(s: &Structure, h: Harmonics, runs: usize) -> Result<(f64, f64), RcwaError> {
    let d = DVec3::new(30f64.to_radians().sin(), 0.0, -(30f64.to_radians().cos()));
    let mut times = Vec::with_capacity(runs);
    let mut r = 0.0;
    for _ in 0..runs {
        let t = Instant::now();
        let sol = rcwa::solve(s, 550.0, d, h)?;
        times.push(t.elapsed().as_secs_f64());
        r = 0.5 * (sol.r[0] + sol.r[1]);
    }
    times.sort_by(f64::total_cmp);
    Ok((times[times.len() / 2], r))
}

/// The median wall time of `runs` C-method solves of the 1-D relief `z = amp cos 2πx/Λ`
/// (the metal of [`grating`], 1,024 heights) with harmonics `-m..=m`, s, and the last R.
pub fn time_profile(period: f64, amp: f64, m: usize, runs: usize) -> Result<(f64, f64), RcwaError> {
    let p = rcwa::Profile {
        period_nm: period,
        heights_nm: (0..1024)
            .map(|i| amp * (2.0 * std::f64::consts::PI * i as f64 / 1024.0).cos())
            .collect(),
        eps_above: 1.0,
        eps_below: C64::new(-40.0, 15.0),
        planes: Vec::new(),
    };
    let d = DVec3::new(30f64.to_radians().sin(), 0.0, -(30f64.to_radians().cos()));
    let mut times = Vec::with_capacity(runs);
    let mut r = 0.0;
    for _ in 0..runs {
        let t = Instant::now();
        let sol = rcwa::solve_profile(&p, 550.0, d, m)?;
        times.push(t.elapsed().as_secs_f64());
        r = 0.5 * (sol.r[0] + sol.r[1]);
    }
    times.sort_by(f64::total_cmp);
    Ok((times[times.len() / 2], r))
}
