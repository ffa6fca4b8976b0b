//! The refusal of impossible results: R or T outside [0, 1], negative absorption,
//! energy created, series cut before they converged.

use super::SimError;
use super::SimStats;
use crate::accumulate::Coherence;
use crate::accumulate::file::Accumulator;

/// Standard errors allowed before a result counts as impossible rather than noise.
const NOISE_SIGMAS: f64 = 5.0;
/// Rounding allowance on totals that are sums of many terms of order 1.
const ROUNDING: f64 = 1e-9;
/// Energy allowance of the finite-radius beamlet estimator (docs/design.md §4): its Gaussian
/// overlap weights interference partially, by design, so its reflected and transmitted
/// cross terms need not cancel exactly. Lossless trees are rebalanced to carry out what
/// entered them (`accumulate::conserve`) and their cells are held to rounding instead
/// (`BALANCED_ROUNDING`); this allowance is for trees that met absorption, whose residual
/// is their absorbed power. Measured before the rebalancing (2,000 trees, 0-60 deg,
/// 400-700 nm): at most 1.9e-3 (the seed's wavy film), 4.5e-5 on flat films. The
/// plane-wave limit (`rho = inf`) and the other estimators get none.
pub const BEAMLET_ENERGY_SLACK: f64 = 5e-3;
/// Rounding allowance of `R + T + dropped = 1` in a cell whose trees met no absorption,
/// where each tree balances exactly (`accumulate::conserve`): every Fresnel event splits
/// power to about 1e-15 and a cell sums millions of trees, each of up to thousands of
/// events.
const BALANCED_ROUNDING: f64 = 1e-9;
/// Mean power per tree cut by limits above which a result is refused as not converged (R
/// and T then uncertain by up to `2 sqrt(0.1) = 0.6`). Below it the cut power is reported
/// and allowed for: light guided sideways in a wavy film at 85 degrees loses 2.7e-2 to the
/// depth limit, multiply scattering paints 3e-3 to 5e-3; a meshed 5-pair mirror, whose
/// series diverges, 0.83.
pub const NOT_CONVERGED: f64 = 0.1;
/// Mean power per tree created by ray series that do not recombine
/// ([`SimStats::created`]) above which `simulate` warns: R and T are then uncertain by
/// about that much. On a flat or gently tilted absorbing film the figure is zero (thin
/// films are taken by the local transfer-matrix film, `trace::film`); the shipped rough gold
/// reports none at 0-89 degrees (before the exits of inhomogeneous TM waves were written on
/// the power basis, `optics::fresnel::on_power_basis`, 1.1e-3 at 85 degrees and 650 nm),
/// the metallic paint's flake edges 2.7e-3 at 30 degrees. Films thinner than the wave's
/// decay length seen from its direction, with faces meeting too steeply for the local film,
/// still do (a 5-15 nm gold roof at 60 degrees: thousands of times the power, refused).
pub const CREATED_WARN: f64 = 1e-3;
/// Mean power per tree that met facets tilted against the planes of constant amplitude of
/// the wave inside an absorber (`SimStats::limited`, weighted by `1 - w0` of
/// `trace::event_weights`), or that thin films whose faces meet at 20-30 degrees left to
/// their ray series (`trace::film`), above which `simulate` warns. Below it the runs
/// measured were within 2e-3 of their references (before the local film took thin films:
/// gold films whose faces meet at up to 2 degrees, 1.8e-3 at 1 degree over 9.2 um facets
/// with 3.2e-5 limited); above it, the error per unit of limited and created power is
/// [`LIMITED_EDGE_FACTOR`] or [`LIMITED_FILM_FACTOR`] (tests/tilted_absorbers.rs asserts
/// both).
pub const LIMITED_WARN: f64 = 5e-5;
/// What the warnings state R may be off by, per unit of limited and created power, where
/// light crosses ridge tips and flake edges: gold V-grooves (60 degrees, 2 um) at 0-89
/// degrees, against geometric optics up to 0.6 times (0.085 off at 89 degrees with 0.17
/// limited) and against RCWA's TE up to 5.3 times beyond the reference's uncertainty
/// (1.5e-2 off at 60 degrees with 2.2e-3 limited: a period of 3.6 wavelengths diffracts).
/// (It was 3 while the TM exits' overstated flux, `optics::fresnel::on_power_basis`,
/// counted as created power there.)
pub const LIMITED_EDGE_FACTOR: f64 = 6.0;
/// The same for thin absorbing films whose faces meet at 20 degrees or more, where the
/// local film (`trace::film`) gives way to the ray series: 15-25 nm gold roofs at 20.5 to
/// 50 degrees against the local transfer-matrix film, measured 0.41 to 1.75 times (6.2e-3
/// off with 6.2e-3 limited at 20.5 degrees; 0.47 off with 0.27 limited at 30). (It was 60
/// while the ray series took films from a few tenths of a degree: 1.2 to 52 times on roofs
/// of 0.5 to 2 degrees, whose error the limited power tracked poorly.)
pub const LIMITED_FILM_FACTOR: f64 = 3.0;
/// Mean power per tree created by ray series that do not recombine above which the result
/// is refused: a tenth of the light came out of a model that does not hold.
pub const CREATED_REFUSED: f64 = 0.1;

/// How the warning that a file holds a result its run refused, written with
/// `--allow-unphysical`, begins (`simulate` stores it; [`check_file`]'s callers read such a
/// file with a warning instead of refusing it).
pub const WRITTEN_UNPHYSICAL: &str =
    "written with --allow-unphysical (for debugging), though impossible: ";

/// Optical depth of a scattering sample above which a series cut by the limits is put down
/// to diffusion: light that crosses `tau` mean free paths scatters about `tau^2` times,
/// past the default `--max-depth` from a few tens of mean free paths.
const DIFFUSION_DEPTH: f64 = 20.0;

/// Refuses impossible and unconverged results (docs/design.md §4, "never clamp silently"):
/// non-finite totals, a cell that lost more than [`NOT_CONVERGED`] of its power to limits,
/// and in every cell
/// (incident direction, wavelength), a reflectance or transmittance above 1 or below 0, a
/// negative absorbed power or `R + T + dropped > 1` (energy created). (A single bucket
/// may end negative where a pair of one tree's exits straddles a bucket edge and their
/// cross term is split between the two: docs/design.md §4 has such buckets counted and reported,
/// which `goniospec reflectance` does, not refused.) Each allows rounding plus `NOISE_SIGMAS` standard errors of the
/// per-tree spread (Monte Carlo noise of the cross terms is legitimate; a systematic
/// excess is not), plus the largest coherent effect of the dropped amplitudes, `2 sqrt(D
/// (R + T)) + D` for the dropped power `D` (`|a + b|^2 - |a|^2 <= 2 |a| |b| + |b|^2`, and
/// Cauchy-Schwarz over trees; the run's `stats`, where given, tell the part cut by limits
/// ([`SimStats::limit_dropped`]), for the convergence test), and for energy balances with a finite beamlet radius [`BEAMLET_ENERGY_SLACK`].
/// A refusal names its likely cause: series cut by limits, or ray series that created
/// energy ([`SimStats::created`], above [`CREATED_WARN`] in that cell).
pub fn check_physical(
    acc: &Accumulator,
    sample_name: &str,
    stats: Option<&SimStats>,
) -> Result<(), SimError> {
    judge_cells(acc, sample_name, stats, Judged::Run)?;
    check_realisable(acc, sample_name, Judged::Run)
}

/// The allowance of energy balances for partial coherence: [`BEAMLET_ENERGY_SLACK`] where
/// the beamlet estimator's finite radius made the totals (the diffraction method's totals
/// are the beamlet estimator's on the same trees), else none.
fn energy_slack(acc: &Accumulator) -> f64 {
    let s = &acc.header.settings;
    if matches!(
        s.coherence_mode(),
        Coherence::Auto | Coherence::Beamlet | Coherence::Diffraction
    ) && s.coherence_radius_nm.is_finite()
    {
        BEAMLET_ENERGY_SLACK
    } else {
        0.0
    }
}

/// Holds an accumulator read from a file to the checks its run applied before writing
/// (docs/design.md §4, "never clamp silently"): a file's checksum proves it was not
/// damaged, not that its numbers are physics. Refuses, naming the cell, what
/// [`check_physical`] refuses (without the run's statistics, which a file does not keep),
/// and in a `--mueller` file the totals for light in each fully polarised state (S1, S2,
/// S3 = +-1): each of R and T outside [0, 1], or `R + T` above 1, beyond the same
/// allowances ([`judge_polarised`]). `name` names the file in the message.
pub fn check_file(acc: &Accumulator, name: &str) -> Result<(), SimError> {
    judge_cells(acc, name, None, Judged::File)?;
    check_realisable(acc, name, Judged::File)?;
    judge_polarised(acc, name)
}

/// The polarised totals of [`check_file`]. For a fully polarised state `s` the reflected
/// power is the sum over buckets of `m0k s_k` (the first row of each Mueller matrix applied
/// to `s`: Chipman, Lam & Young 2018, *Polarized Light and Optical Systems*, §6.3), and
/// energy holds for each state alone. The allowance is rounding, [`NOISE_SIGMAS`] times the
/// sum over buckets of `sum_k |s_k| se(m0k)` (a bound on the total's standard error, which
/// needs no covariances), the coherent bound of the dropped power for a polarised state
/// (up to twice the unpolarised dropped power `D`, as unpolarised light is the mean of two
/// orthogonal states: `2 sqrt(2D (R + T)) + 2D`), and for `R + T` the partial-coherence
/// slack ([`energy_slack`]).
fn judge_polarised(acc: &Accumulator, name: &str) -> Result<(), SimError> {
    const STATES: [(&str, [f64; 4]); 6] = [
        ("p (S1 = +1)", [1.0, 1.0, 0.0, 0.0]),
        ("s (S1 = -1)", [1.0, -1.0, 0.0, 0.0]),
        ("+45 (S2 = +1)", [1.0, 0.0, 1.0, 0.0]),
        ("-45 (S2 = -1)", [1.0, 0.0, -1.0, 0.0]),
        ("circular+ (S3 = +1)", [1.0, 0.0, 0.0, 1.0]),
        ("circular- (S3 = -1)", [1.0, 0.0, 0.0, -1.0]),
    ];
    let s = &acc.header.settings;
    if !s.mueller {
        return Ok(());
    }
    let nl = s.wavelength_count();
    let slack = energy_slack(acc);
    for (i, theta) in s.theta_i_deg.iter().enumerate() {
        for j in 0..nl {
            let c = acc.cell(i, j);
            if c.trees == 0 {
                continue;
            }
            let d2 = 2.0 * c.dropped / c.trees as f64;
            for (label, state) in &STATES {
                // [R, T] and their standard-error bounds.
                let (mut p, mut se) = ([0.0f64; 2], [0.0f64; 2]);
                for kk in 0..c.mueller.len() {
                    let Some(m) = c.mueller(kk) else { continue };
                    p[kk % 2] += (0..4).map(|b| m[b] * state[b]).sum::<f64>();
                    se[kk % 2] += c
                        .mueller_stderr(kk)
                        .map_or(0.0, |e| (0..4).map(|b| e[b] * state[b].abs()).sum());
                }
                let [r, t] = p;
                let tol = ROUNDING
                    + NOISE_SIGMAS * (se[0] + se[1])
                    + 2.0 * (d2 * (r + t).abs()).sqrt()
                    + d2;
                let what = if !(r.is_finite() && t.is_finite()) {
                    Some(format!("a non-finite total (R {r}, T {t})"))
                } else if !(-tol..=1.0 + tol).contains(&r) {
                    Some(format!("R = {r:.6}, outside [0, 1]"))
                } else if !(-tol..=1.0 + tol).contains(&t) {
                    Some(format!("T = {t:.6}, outside [0, 1]"))
                } else if r + t > 1.0 + tol + slack {
                    Some(format!("R + T = {:.6} > 1, energy created", r + t))
                } else {
                    None
                };
                if let Some(what) = what {
                    return Err(SimError::Unphysical(format!(
                        "{name}, theta_i {theta} deg, phi_i {} deg, lambda {} nm, light in {label}: \
                         {what} (its Mueller matrices' first rows summed over the buckets; \
                         tolerance {tol:.1e}: rounding, {NOISE_SIGMAS} standard errors and the \
                         dropped power's coherent bound). {}",
                        s.phi_of(i),
                        s.wavelength(j),
                        Judged::File.verdict()
                    )));
                }
            }
        }
    }
    Ok(())
}

/// Whose result is judged: a run's, before it is written (a refusal says so and offers
/// `--allow-unphysical`), or a file's, after it is read (a refusal says the file holds it).
#[derive(Clone, Copy, PartialEq)]
enum Judged {
    Run,
    File,
}

impl Judged {
    /// Who the message is about: the sample of a run, the file read.
    fn whose(self, name: &str) -> String {
        match self {
            Judged::Run => format!("sample '{name}'"),
            Judged::File => name.to_string(),
        }
    }

    /// What a refusal says after what failed.
    fn verdict(self) -> &'static str {
        match self {
            Judged::Run => "The result is impossible and was not written.",
            Judged::File => {
                "No run writes such a result without --allow-unphysical: the file was made so or changed and resealed, and is refused."
            }
        }
    }
}

/// The cells' totals judged as [`check_physical`] states.
fn judge_cells(
    acc: &Accumulator,
    sample_name: &str,
    stats: Option<&SimStats>,
    judged: Judged,
) -> Result<(), SimError> {
    let s = &acc.header.settings;
    let mode = s.coherence_mode();
    let buckets = s.buckets();
    let nl = s.wavelength_count();
    let slack = energy_slack(acc);
    let partial = |slack: f64| {
        if slack > 0.0 {
            " (with a finite beamlet radius this can also be the estimator's partial coherence on steeply curved films, beyond its allowance: a smaller --coherence-radius-nm pairs fewer partial waves)"
        } else {
            ""
        }
    };
    for (i, theta) in s.theta_i_deg.iter().enumerate() {
        for j in 0..nl {
            let c = acc.cell(i, j);
            if c.trees == 0 {
                continue;
            }
            let n = c.trees as f64;
            let (r, t) = c.totals(mode, &buckets);
            let (a, d) = (c.absorbed / n, c.dropped / n);
            let se_r = c.r_stderr(mode).unwrap_or(0.0);
            let se_t = c.t_stderr(mode).unwrap_or(0.0);
            // Every dropped amplitude, by the cutoff or a limit, can change the coherent
            // totals by up to the Cauchy-Schwarz bound; a cell that lost more than
            // NOT_CONVERGED to limits is refused outright below.
            let d_limit = stats.map_or(0.0, |st| st.limit_dropped[i * nl + j] / n);
            let created = stats.map_or(0.0, |st| st.created[i * nl + j] / n);
            let truncation = 2.0 * (d * (r + t).abs()).sqrt() + d;
            let tol = ROUNDING + NOISE_SIGMAS * (se_r + se_t) + truncation;
            let tol_energy = tol + slack;
            // A file whose lossless trees conserve power (`Header::balanced`): a cell of
            // rays (or of the diffraction method, which carries the rays' totals) that met
            // no absorption balances to rounding, whatever its noise, as each of its trees
            // does (`absorbed` is exactly 0 only where no tree absorbed).
            let balanced = acc.header.balanced
                && c.absorbed == 0.0
                && matches!(
                    s.cell_mode(i, j),
                    Coherence::Beamlet | Coherence::Diffraction
                );
            let hint = if d_limit > 1e-6 {
                format!(
                    " The ray series did not converge: {d_limit:.1e} of the power per tree was cut by --max-depth / --max-segments."
                )
            } else {
                String::new()
            };
            let what = if !(r.is_finite() && t.is_finite() && a.is_finite() && d.is_finite()) {
                Some(format!(
                    "a non-finite result (R {r}, T {t}, absorbed {a}, dropped {d}): a medium's index or the geometry is outside what the optics can represent"
                ))
            } else if d_limit > NOT_CONVERGED {
                Some(format!(
                    "the ray series did not converge: {d_limit:.1e} of the launched power per tree was cut by --max-depth / --max-segments, so R and T are uncertain by up to 2 sqrt({d_limit:.1e}) = {:.2}",
                    2.0 * d_limit.sqrt()
                ))
            } else if r > 1.0 + tol {
                Some(format!("R = {r:.9} > 1"))
            } else if r < -tol {
                Some(format!("R = {r:.3e} < 0"))
            } else if t < -tol {
                Some(format!("T = {t:.3e} < 0"))
            } else if t > 1.0 + tol {
                Some(format!("T = {t:.9} > 1"))
            } else if a < -tol_energy {
                Some(format!(
                    "absorbed power {a:.3e} < 0: R + T + dropped = {:.9} > 1, energy created{}",
                    r + t + d,
                    partial(slack)
                ))
            } else if r + t + d > 1.0 + tol_energy {
                Some(format!(
                    "R + T + dropped = {:.9} > 1, energy created{}",
                    r + t + d,
                    partial(slack)
                ))
            } else {
                None
            };
            if let Some(what) = what {
                let diffusing = stats
                    .and_then(|st| st.densest_scatterer.as_ref())
                    .filter(|(_, depth)| *depth > DIFFUSION_DEPTH && d_limit > 1e-6);
                let causes = if let Some((medium, depth)) = diffusing {
                    format!(
                        " The cause: the medium '{medium}' scatters so densely that the sample is \
                         about {depth:.1e} mean free paths deep; light diffusing through that many \
                         takes about their square in scattering events (a random walk), beyond \
                         --max-depth. A layer this deep is opaque, and its light leaves from its \
                         top few mean free paths: check the medium's scattering_per_um or \
                         volume_fraction and the layer's thickness (and their units), or raise \
                         --max-depth (docs/physics.md, \"Particle media\")."
                    )
                } else if created > CREATED_WARN {
                    format!(
                        " The cause: {created:.3} of the launched power per tree came from ray series \
                         that created energy, where light crossed absorbing features thinner than \
                         their decay length (ridge tips at grazing light, sub-skin-depth wedges) and \
                         no ray model holds (docs/physics.md, \"Where the ray model stops\"): use a \
                         rigorous solver for this geometry, less grazing light or rounder ridges."
                    )
                } else {
                    " Likely causes: meshed thin layers whose ray series does not converge \
                     (high-contrast multilayers, absorbing layers thinner than their decay \
                     length): model them as a coating, a [stack] in its default mode or \
                     coating = [...] on the interface (docs/physics.md); or a bug."
                        .to_string()
                };
                return Err(SimError::Unphysical(format!(
                    "{}, theta_i {theta} deg, phi_i {} deg, lambda {} nm: {what} \
                     (tolerance {tol:.1e}: rounding, {NOISE_SIGMAS} standard errors and the dropped \
                     power's coherent bound; energy balances also {slack:.0e} for partial coherence). {}{}",
                    judged.whose(sample_name),
                    s.phi_of(i),
                    s.wavelength(j),
                    judged.verdict(),
                    if judged == Judged::Run {
                        format!(
                            "{hint}{causes} Pass --allow-unphysical to write it anyway for debugging."
                        )
                    } else {
                        String::new()
                    },
                )));
            }
            if balanced {
                let at = format!(
                    "{}, theta_i {theta} deg, phi_i {} deg, lambda {} nm",
                    judged.whose(sample_name),
                    s.phi_of(i),
                    s.wavelength(j)
                );
                balance(r + t + d, judged, &at)?;
            }
        }
    }
    Ok(())
}

/// A cell that met no absorption in a file whose lossless trees conserve power
/// (`Header::balanced`): `R + T + dropped` (`sum`) must be 1 to [`BALANCED_ROUNDING`].
/// `at` names the cell.
fn balance(sum: f64, judged: Judged, at: &str) -> Result<(), SimError> {
    if (sum - 1.0).abs() <= BALANCED_ROUNDING {
        return Ok(());
    }
    Err(SimError::Unphysical(format!(
        "{at}: R + T + dropped = {sum:.12} in a cell without absorption, where each tree's \
         exits carry out exactly what entered it (docs/design.md §4, \"Energy of lossless \
         groups\"; allowed: {BALANCED_ROUNDING:.0e} of rounding): power was {} by the \
         bookkeeping, not by the physics. {}{}",
        if sum > 1.0 { "created" } else { "lost" },
        judged.verdict(),
        if judged == Judged::Run {
            " This is a bug, please report it with the sample; pass --allow-unphysical to \
             write it anyway for debugging."
        } else {
            ""
        },
    )))
}

/// A `--mueller` run's matrices must each be physically realisable: a coherency
/// eigenvalue more than `REALISABLE_SIGMAS` standard errors below zero is a matrix no
/// sample can have (`Accumulator::realisability`).
fn check_realisable(acc: &Accumulator, sample_name: &str, judged: Judged) -> Result<(), SimError> {
    use crate::accumulate::polarimetric::REALISABLE_SIGMAS;
    let Some(r) = acc.realisability().filter(|r| r.failed > 0) else {
        return Ok(());
    };
    let s = &acc.header.settings;
    let (i, j, kk) = r.worst_at;
    let (t, p) = s.buckets().centre(kk / 2);
    Err(SimError::Unphysical(format!(
        "{}: {} of {} buckets hold a Mueller matrix that is not physically realisable (a coherency eigenvalue more than {REALISABLE_SIGMAS} standard errors below zero; Cloude 1986); the worst, {:.2e} of its m00 ({:.1} standard errors), at theta_i {} deg, lambda {} nm, the {} bucket at theta_o {:.1} deg, phi_o {:.1} deg. {}",
        judged.whose(sample_name),
        r.failed,
        r.checked,
        r.worst_relative,
        r.worst_sigmas,
        s.theta_i_deg.get(i).copied().unwrap_or(f64::NAN),
        s.wavelength(j),
        if kk % 2 == 0 {
            "reflection"
        } else {
            "transmission"
        },
        t.to_degrees(),
        p.to_degrees(),
        match judged {
            Judged::Run =>
                "The result is impossible and was not written; this is a bug, please report it with the sample, or pass --allow-unphysical to write it anyway for debugging",
            Judged::File => judged.verdict(),
        }
    )))
}

/// Why [`read_judged`] refused a file.
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    /// Unreadable, damaged, or not a `.gsa`.
    #[error(transparent)]
    File(#[from] crate::accumulate::file::FileError),
    /// Read whole, but holding a result no run writes ([`check_file`]).
    #[error(transparent)]
    Impossible(#[from] SimError),
}

/// Reads a `.gsa` and holds it to [`check_file`]. A file whose run stored
/// [`WRITTEN_UNPHYSICAL`] among its warnings is read anyway, and the refusal comes back as
/// the warning a front end prints; any other failing file is refused.
pub fn read_judged(path: &std::path::Path) -> Result<(Accumulator, Option<String>), ReadError> {
    let acc = Accumulator::read(path)?;
    match check_file(&acc, &path.display().to_string()) {
        Ok(()) => Ok((acc, None)),
        Err(e)
            if acc
                .header
                .warnings
                .iter()
                .any(|w| w.starts_with(WRITTEN_UNPHYSICAL)) =>
        {
            let w = format!("{e} (read anyway: its run wrote it with --allow-unphysical)");
            Ok((acc, Some(w)))
        }
        Err(e) => Err(e.into()),
    }
}
