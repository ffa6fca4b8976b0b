//! The analytic reference of a flat layered sample: the transfer-matrix reflectance and
//! transmittance of its `[stack]` (`goniospec analytic`).

use super::ReferenceError;
use crate::optics::C64;
use crate::optics::tmm::{Rt, StackIndices, solve, solve_band};

/// The indices and thicknesses of a `[stack]` sample at `lambda_nm`, for [`tmm::solve`].
pub fn stack_indices(
    sample: &crate::sample::Sample,
    lambda_nm: f64,
) -> Result<StackIndices, ReferenceError> {
    let st = sample.stack.as_ref().ok_or_else(|| {
        format!(
            "{} is not written as a [stack]: the analytic reference needs a flat layered sample",
            sample.path.display()
        )
    })?;
    let idx = |m: usize| -> Result<C64, String> {
        let (n, k) = sample.media[m]
            .model
            .eval(lambda_nm)
            .map_err(|e| format!("medium '{}': {e}", sample.media[m].name))?;
        Ok(C64::new(n, k))
    };
    let mut n = vec![idx(st.ambient)?];
    for &(m, _) in &st.layers {
        n.push(idx(m)?);
    }
    n.push(idx(st.substrate)?);
    Ok(StackIndices {
        n,
        d_nm: st.layers.iter().map(|l| l.1).collect(),
    })
}

/// The analytic reflectance and transmittance of a `[stack]` sample at `theta_i_deg`
/// (`goniospec analytic`): per wavelength for monochromatic sampling, bin-averaged
/// ([`tmm::solve_band`]) and reported at the bin centre for bins.
pub fn analytic(
    sample: &crate::sample::Sample,
    theta_i_deg: f64,
    wavelengths: &crate::spectrum::Wavelengths,
) -> Result<Vec<(f64, Rt)>, ReferenceError> {
    if !(theta_i_deg.is_finite() && (0.0..90.0).contains(&theta_i_deg)) {
        return Err(ReferenceError::from(format!(
            "theta_i must be in [0, 90) degrees, got {theta_i_deg}"
        )));
    }
    let Some(stack) = &sample.stack else {
        return Err("the sample is not written as a [stack]: the analytic reference needs a flat layered sample".into());
    };
    let media = std::iter::once(stack.ambient)
        .chain(stack.layers.iter().map(|l| l.0))
        .chain(std::iter::once(stack.substrate));
    if let Some(m) = media
        .map(|m| &sample.media[m])
        .find(|m| m.scattering.is_some())
    {
        return Err(ReferenceError::from(format!(
            "medium '{}' scatters in volume (particles or henyey_greenstein): the analytic reference is the transfer-matrix method of clear layers, which would give the clear host's R and T; simulate the sample, whose random walk takes the scattering",
            m.name
        )));
    }
    let th = theta_i_deg.to_radians();
    let stack_at = |l: f64| stack_indices(sample, l);
    let rows: Vec<(f64, Rt)> = match wavelengths {
        crate::spectrum::Wavelengths::Monochromatic(v) => v
            .iter()
            .map(|&l| Ok((l, solve(&stack_at(l)?, l, th))))
            .collect::<Result<_, ReferenceError>>()?,
        crate::spectrum::Wavelengths::Bins(e) => e
            .windows(2)
            .map(|w| {
                stack_at(w[0])?;
                stack_at(w[1])?;
                let rt = solve_band(
                    |l| stack_at(l).expect("range checked at the edges"),
                    w[0],
                    w[1],
                    th,
                );
                Ok((0.5 * (w[0] + w[1]), rt))
            })
            .collect::<Result<_, ReferenceError>>()?,
    };
    // No NaN or impossible value is ever printed: the matrix is kept finite, and a result
    // that still is not is an error.
    for (l, rt) in &rows {
        let all = [rt.r_s, rt.r_p, rt.t_s, rt.t_p];
        if !all
            .iter()
            .all(|v| v.is_finite() && (-1e-9..=1.0 + 1e-9).contains(v))
            || rt.r() + rt.t() > 1.0 + 1e-9
        {
            return Err(ReferenceError::from(format!(
                "the transfer matrix gave an impossible result at {l} nm (R {}, T {}): the stack is beyond what it can represent",
                rt.r(),
                rt.t()
            )));
        }
    }
    Ok(rows)
}
