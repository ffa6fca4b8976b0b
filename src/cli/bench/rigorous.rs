//! `goniospec bench rigorous`: the rigorous solver's time per cell.

use super::super::{Args, ExitCode, Result, emit, thread_pool};

#[derive(Args)]
pub(crate) struct RigorousBenchArgs {
    /// Solves per figure (the median is printed).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u64).range(1..=100))]
    runs: u64,
}

pub(crate) fn bench_rigorous(a: RigorousBenchArgs) -> Result<ExitCode> {
    use goniospec::bench::rigorous::{grating, time_profile, time_solve};
    use goniospec::optics::rcwa::Harmonics;
    let runs = a.runs as usize;
    let pool = thread_pool(1)?;
    pool.install(|| -> Result<()> {
        for (name, two_d, period, m, pixels) in [
            ("1d_41_orders", false, 2000.0, [20, 0], 720),
            ("2d_11x11_orders", true, 1000.0, [5, 5], 96),
        ] {
            let fine = grating(two_d, period, 100.0, 24, pixels);
            let coarse = grating(two_d, period, 100.0, 12, pixels);
            let (solve, r) = time_solve(&fine, Harmonics { m }, runs)?;
            let (check, _) = time_solve(
                &coarse,
                Harmonics {
                    m: m.map(|k| (2 * k).div_ceil(3)),
                },
                runs,
            )?;
            emit(&format!("rigorous_{name}_solve_s: {solve:.4} s"));
            emit(&format!("rigorous_{name}_cell_s: {:.4} s", solve + check));
            emit(&format!("rigorous_{name}_r: {r:.6} 1"));
        }
        // The same 1-D relief by the C-method (a bare smooth relief: no slices), with its
        // check at two thirds of the harmonics.
        let (solve, r) = time_profile(2000.0, 100.0, 20, runs)?;
        let (check, _) = time_profile(2000.0, 100.0, 14, runs)?;
        emit(&format!(
            "rigorous_1d_cmethod_41_orders_solve_s: {solve:.4} s"
        ));
        emit(&format!(
            "rigorous_1d_cmethod_41_orders_cell_s: {:.4} s",
            solve + check
        ));
        emit(&format!("rigorous_1d_cmethod_41_orders_r: {r:.6} 1"));
        Ok(())
    })?;
    Ok(ExitCode::SUCCESS)
}
