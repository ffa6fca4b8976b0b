//! What a `--mueller` run's accumulator holds of polarisation: every bucket's Mueller
//! matrix as a BRDF (1/sr) with its standard errors, and the check that each one is
//! physically realisable within them (docs/physics.md, "Polarisation").

use glam::DVec3;

use super::file::{Accumulator, NotSimulated};
use crate::optics::mueller::{Mueller, coherency_eigenvalues, degree_of_polarisation};

/// One wavelength's directional reflectance and transmittance for polarised light in.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PolarisedRow {
    /// Bin centre or exact wavelength, nm.
    pub lambda_nm: f64,
    /// Fractions of the incident power.
    pub r: f64,
    pub t: f64,
}

/// Standard errors a coherency eigenvalue may fall below zero before the matrix counts as
/// not realisable rather than noisy.
pub const REALISABLE_SIGMAS: f64 = 5.0;

/// One wavelength's Mueller-matrix BRDF at a pair of directions.
#[derive(Clone, Debug, PartialEq)]
pub struct MuellerSample {
    /// Bin centre or exact wavelength, nm.
    pub lambda_nm: f64,
    /// The matrix over the bucket's projected solid angle, 1/sr, row-major; `m[0]` is the
    /// unpolarised BRDF.
    pub m: Mueller,
    /// Each element's standard error (per-tree spread), 1/sr; `None` with one tree.
    pub stderr: Option<Mueller>,
    /// The degree of polarisation of the light sent out for unpolarised light in.
    pub dop: f64,
}

/// Why an accumulator cannot give a Mueller matrix.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MuellerError {
    #[error(
        "the accumulator holds no Mueller matrices: simulate with --mueller (Python: mueller=True)"
    )]
    NotKept,
    #[error(transparent)]
    NotSimulated(#[from] NotSimulated),
    #[error("the outgoing direction must be a unit vector off the horizon, got {0}")]
    Direction(DVec3),
}

/// The bucket that was least realisable over a whole accumulator.
#[derive(Clone, Debug, PartialEq)]
pub struct Realisability {
    /// Buckets with a Mueller matrix of positive `m00` that were checked.
    pub checked: usize,
    /// Of those, the ones whose smallest coherency eigenvalue lies more than
    /// [`REALISABLE_SIGMAS`] standard errors below zero.
    pub failed: usize,
    /// The bucket whose smallest eigenvalue lies furthest below zero against what noise
    /// and rounding allow: that eigenvalue over `m00`'s magnitude and in standard errors,
    /// and where (direction index, wavelength index, bucket key).
    pub worst_relative: f64,
    pub worst_sigmas: f64,
    pub worst_at: (usize, usize, usize),
}

impl Accumulator {
    /// The Mueller-matrix BRDF (or BTDF, for `wo` below the surface) at the simulated
    /// incident angle `theta_i_deg` (and azimuth, when given) towards the unit direction
    /// `wo`, one sample per wavelength: the matrix of the bucket `wo` falls in over that
    /// bucket's projected solid angle, in `wo`'s own s/p frame (`optics::mueller::frame`).
    pub fn mueller_brdf(
        &self,
        theta_i_deg: f64,
        phi_i_deg: Option<f64>,
        wo: DVec3,
    ) -> Result<Vec<MuellerSample>, MuellerError> {
        let s = &self.header.settings;
        if !s.mueller {
            return Err(MuellerError::NotKept);
        }
        if !(wo.is_finite() && (wo.length() - 1.0).abs() < 1e-6 && wo.z != 0.0) {
            return Err(MuellerError::Direction(wo));
        }
        let i = self.direction_of(theta_i_deg, phi_i_deg)?;
        let buckets = s.buckets();
        let b = buckets.index(wo);
        let kk = super::key(b, wo.z < 0.0) as usize;
        let omega = buckets.projected_solid_angle(b);
        Ok((0..s.wavelength_count())
            .map(|j| {
                let c = self.cell(i, j);
                let m = c.mueller(kk).unwrap_or([0.0; 16]).map(|x| x / omega);
                MuellerSample {
                    lambda_nm: s.wavelength(j),
                    m,
                    stderr: c.mueller_stderr(kk).map(|e| e.map(|x| x / omega)),
                    dop: degree_of_polarisation(&m),
                }
            })
            .collect())
    }

    /// The directional reflectance and transmittance at the simulated incident angle
    /// `theta_i_deg` for light in the state `stokes` (normalised to `S0 = 1`, in the
    /// incident direction's s/p frame): each bucket's first row of its Mueller matrix
    /// applied to it, summed over the hemisphere (the outgoing intensity needs no frame).
    pub fn polarised_reflectance(
        &self,
        theta_i_deg: f64,
        phi_i_deg: Option<f64>,
        stokes: &[f64; 4],
    ) -> Result<Vec<PolarisedRow>, MuellerError> {
        let s = &self.header.settings;
        if !s.mueller {
            return Err(MuellerError::NotKept);
        }
        let i = self.direction_of(theta_i_deg, phi_i_deg)?;
        Ok((0..s.wavelength_count())
            .map(|j| {
                let c = self.cell(i, j);
                let (mut r, mut t) = (0.0, 0.0);
                for kk in 0..c.mueller.len() {
                    let m = c.mueller(kk).unwrap_or([0.0; 16]);
                    let v: f64 = (0..4).map(|b| m[b] * stokes[b]).sum();
                    if kk % 2 == 0 { r += v } else { t += v }
                }
                PolarisedRow {
                    lambda_nm: s.wavelength(j),
                    r,
                    t,
                }
            })
            .collect())
    }

    /// Every bucket's Mueller matrix judged by its coherency eigenvalues (Cloude 1986):
    /// realisable where the smallest is at least `-REALISABLE_SIGMAS` standard errors
    /// (the eigenvalue's error is at most the coherency matrix's Frobenius error, half the
    /// root sum of the elements' squared standard errors). `None` without Mueller
    /// matrices.
    pub fn realisability(&self) -> Option<Realisability> {
        if !self.header.settings.mueller {
            return None;
        }
        let nl = self.header.settings.wavelength_count().max(1);
        let mut out = Realisability {
            checked: 0,
            failed: 0,
            worst_relative: 0.0,
            worst_sigmas: 0.0,
            worst_at: (0, 0, 0),
        };
        let mut worst = 0.0;
        for (ci, c) in self.cells.iter().enumerate() {
            for kk in 0..c.mueller.len() {
                let Some(m) = c.mueller(kk) else { continue };
                // A negative m00 is the beamlet estimator's share of a pair's cross term
                // (docs/design.md §4), kept and reported as the unpolarised buckets are
                // (`Reflectance::negative_buckets`); its matrix is not judged.
                if m[0] <= 0.0 {
                    continue;
                }
                out.checked += 1;
                let low = coherency_eigenvalues(&m)[0];
                let sigma = c
                    .mueller_stderr(kk)
                    .map_or(0.0, |e| 0.5 * e.iter().map(|x| x * x).sum::<f64>().sqrt());
                // Rounding of sums of order-one terms.
                let allowed = REALISABLE_SIGMAS * sigma + 1e-12 * m[0];
                if low < -allowed {
                    out.failed += 1;
                }
                // The worst: furthest below zero against what it is allowed.
                if low / allowed < worst {
                    worst = low / allowed;
                    out.worst_relative = low / m[0];
                    out.worst_sigmas = if sigma > 0.0 { low / sigma } else { 0.0 };
                    out.worst_at = (ci / nl, ci % nl, kk);
                }
            }
        }
        Some(out)
    }
}
