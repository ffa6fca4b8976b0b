//! What a finished run has to say: the warnings `simulate` prints and `batch run` keeps with
//! each unit (issue 47), each with its numbers and what to do, from the run's statistics.

use super::{
    CREATED_WARN, DIFFRACTION_RATIO_WARN, LIMITED_EDGE_FACTOR, LIMITED_FILM_FACTOR, LIMITED_WARN,
    SimStats,
};
use crate::accumulate::file::Accumulator;
use crate::sample::Sample;

/// Above this fraction of the launched power per tree dropped by the power cutoff, a run
/// says so: the default cutoff keeps it near 1e-5 (`TraceLimits::CUTOFF`).
const CUTOFF_DROPPED_WARN: f64 = 1e-4;
/// The mean power per tree, in one cell, by which lossless trees' groups were rebalanced
/// (`SimStats::rebalanced`) above which the run says so: on the seed's wavy film it is
/// 3.8e-3 at 0 deg, 1.2e-2 at 30, 3.8e-2 at 60 and 1.4e-1 at 80-85 deg (4,096 trees).
const REBALANCED_WARN: f64 = 1e-2;

/// What a run keeps in its `.gsa` (`Header::warnings`): each direction's own warnings in
/// direction order, each sentence once: the validity findings at its angle, what
/// `--coherence auto` could not give it (`notes`, per direction), and [`run_warnings`] over
/// its cells alone. A direction's warnings depend on that direction only, so a batch
/// unit keeps what the whole run keeps for it, and its merged units keep the run's list.
pub(super) fn stored_warnings(
    sample: &Sample,
    cfg: &super::SimConfig,
    acc: &Accumulator,
    stats: &SimStats,
    notes: &[Vec<String>],
    sheets: &[Option<crate::sample::validity::Scales>],
) -> Vec<String> {
    use crate::sample::validity;
    let small = validity::small_bodies(sample, cfg.wavelengths.min());
    let nl = acc.header.settings.wavelength_count();
    let mut out: Vec<String> = Vec::new();
    for (di, &theta) in cfg.theta_i_deg.iter().enumerate() {
        let one = super::SimConfig {
            theta_i_deg: vec![theta],
            phi_each_deg: Vec::new(),
            ..cfg.clone()
        };
        let mut ctx = super::validity_context(&one);
        // The scale findings judge rays and the diffraction method: only over the cells
        // they gave (none where the rigorous solver gave every cell).
        let s = &acc.header.settings;
        let others: Vec<f64> = (0..nl)
            .filter(|&j| s.cell_mode(di, j) != crate::accumulate::Coherence::Rigorous)
            .map(|j| s.wavelength(j))
            .collect();
        ctx.lambda_min_nm = others.iter().copied().fold(f64::INFINITY, f64::min);
        ctx.lambda_max_nm = others.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let assessed = if others.is_empty() {
            Vec::new()
        } else {
            validity::assess_scales(sample, sheets, &ctx)
        };
        let mut found: Vec<String> = assessed
            .into_iter()
            .chain(small.iter().cloned())
            .map(|f| f.message)
            .collect();
        let st = SimStats {
            auto_notes: notes.get(di).cloned().unwrap_or_default(),
            ..stats.direction(di, nl)
        };
        // Each sentence names its polar angle; a direction lit from another azimuth than 0
        // also names that (the same in a batch unit of that direction).
        let phi = cfg.phi_of(di);
        found.extend(
            run_warnings(sample, &acc.direction(di), &st)
                .into_iter()
                .map(|w| match phi == 0.0 {
                    true => w,
                    false => format!("at phi_i {phi} deg: {w}"),
                }),
        );
        for w in found {
            if !out.contains(&w) {
                out.push(w);
            }
        }
    }
    // Coatings a finite radius does not act on, and particle media packed beyond what their
    // scattering model holds (as `validity::findings` says before a run), so that the file
    // holds every warning printed.
    if let Some(f) = validity::coatings_ignore_radius(sample, &super::validity_context(cfg))
        && !out.contains(&f.message)
    {
        out.push(f.message);
    }
    for m in &sample.media {
        if let Some(w) = m
            .scattering
            .as_ref()
            .and_then(|p| p.packing_warning(&m.name))
            && !out.contains(&w)
        {
            out.push(w);
        }
    }
    // A result kept by --allow-unphysical says so in its file, so that readers, which hold
    // what they read to the same checks (`check_file`), can tell it from a forged one.
    if cfg.allow_unphysical
        && let Err(e) = super::check_physical(acc, &sample.name, Some(stats))
    {
        out.push(format!("{}{e}", super::WRITTEN_UNPHYSICAL));
    }
    out
}

/// The warnings of a finished run of `sample`, one sentence each, without a prefix; and the
/// notes that are not warnings (an open sample's escaped power), prefixed "open sides".
pub fn run_warnings(sample: &Sample, acc: &Accumulator, stats: &SimStats) -> Vec<String> {
    let mut out = Vec::new();
    let settings = &acc.header.settings;
    let nl = settings.wavelength_count().max(1);
    // A cell's incident angle (deg) and wavelength bin (from 1).
    let where_ = |cell: usize| {
        let theta = settings.theta_i_deg.get(cell / nl);
        (theta.copied().unwrap_or(f64::NAN), cell % nl + 1)
    };
    let cut = stats.worst_limit_dropped(acc);
    if cut > 1e-6 {
        let (bound, _) = stats.worst_limit_bound(acc);
        out.push(format!(
            "R and T short by about {cut:.1e} (at most {bound:.1e} if it added in phase): up to that much of the launched power per tree was cut by --max-depth or --max-segments before the ray series converged; raise them, or model thin layers as a flat [stack]"
        ));
    }
    // What the power cutoff dropped: the cell's dropped power less what the limits, leaks
    // and open sides dropped (issue 47: --cutoff 0.5 on a glass sheet gave R = 0 unsaid).
    let (below, cell) = acc
        .cells
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let limits = stats.limit_dropped.get(i).copied().unwrap_or(0.0);
            ((c.dropped - limits) / c.trees.max(1) as f64, i)
        })
        .fold((0.0, 0), |w, v| if v.0 > w.0 { v } else { w });
    if below > CUTOFF_DROPPED_WARN {
        let (theta, bin) = where_(cell);
        out.push(format!(
            "a fraction {below:.1e} of the launched power per tree (theta_i {theta} deg, wavelength bin {bin}) was in branches weaker than --cutoff {} of the launched power, which are not followed: R and T are short by that much (it is in the dropped column). The default cutoff {:e} keeps this near 1e-5",
            settings.cutoff,
            crate::trace::TraceLimits::CUTOFF
        ));
    }
    let (limited, cell) = stats.worst_limited(acc);
    if limited > LIMITED_WARN {
        let (theta, bin) = where_(cell);
        out.push(format!(
            "R may be off by up to {LIMITED_EDGE_FACTOR} x {limited:.1e} (ridge tips, flake edges) or {LIMITED_FILM_FACTOR} x that (thin absorbing films meeting at 20 degrees or more) at theta_i {theta} deg, wavelength bin {bin}: that fraction of the launched power per tree met absorbing facets that change the wave by a good part of its index, where the plane-wave model is stretched; check such a sample against a rigorous solver"
        ));
    }
    let (moved, cell) = stats.worst_rebalanced(acc);
    if moved > REBALANCED_WARN {
        let (theta, bin) = where_(cell);
        out.push(format!(
            "partial coherence: at theta_i {theta} deg (wavelength bin {bin}) how the light divides between R, T and the buckets is uncertain by up to {moved:.1e} of the launched power: the beamlet overlaps of this lossless sample's partial waves did not conserve energy, and each tree was scaled to carry out what entered it; R + T is exact"
        ));
    }
    let (created, cell) = stats.worst_created(acc);
    if created > CREATED_WARN {
        let (theta, bin) = where_(cell);
        out.push(format!(
            "a fraction {created:.1e} of the launched power per tree (theta_i {theta} deg, wavelength bin {bin}) came from ray series that created energy: light crossed absorbing features thinner than their decay length (ridge tips at grazing light, sub-skin-depth wedges), where the partial waves of one region leave in directions that cannot interfere and no ray model holds; R is uncertain by up to about {LIMITED_EDGE_FACTOR} times that and the limited power together there (gold V-grooves against geometric optics and a rigorous solver). Check such a sample against a rigorous solver (RCWA), or use less grazing light or rounder ridges (docs/physics.md, \"Where the ray model stops\")"
        ));
    }
    if let Some(g) = sample.guard_nm {
        // Open sides: what left through them is reported, never silently lost.
        let (worst, cell) = stats.worst_escaped(acc);
        let (theta, bin) = where_(cell);
        out.push(format!(
            "open sides (guard band {g:.0} nm): up to {worst:.2e} of the launched power per tree escaped through the sides (theta_i {theta} deg, wavelength bin {bin}); it is counted with the dropped power{}",
            if worst > 0.01 {
                ": widen the guard band or use a larger scan to keep it small"
            } else {
                ""
            }
        ));
    }
    if stats.envelope_violations > 0 {
        out.push(format!(
            "{} particle scattering angles were drawn where the Mie phase function exceeded its tabulated envelope; those draws are slightly biased (please report the sample)",
            stats.envelope_violations
        ));
    }
    if stats.leaks > 0 {
        out.push(leak_warning(stats));
    }
    out.extend(stats.auto_notes.iter().cloned());
    if let Some(w) = fell_back_warning(acc, stats) {
        out.push(w);
    }
    if let Some(w) = diffraction_warning(acc, stats) {
        out.push(w);
    }
    out
}

/// `--coherence auto`: the cells whose diffraction transform could not hold the ray field
/// and took rays (`DiffractionCell::fell_back`), with the worst of them.
fn fell_back_warning(acc: &Accumulator, stats: &SimStats) -> Option<String> {
    let fell: Vec<(usize, &super::DiffractionCell)> = stats
        .diffraction
        .iter()
        .enumerate()
        .filter(|(_, d)| d.fell_back)
        .collect();
    let &(k, d) = fell.iter().max_by(|a, b| {
        (a.1.ratio() - 1.0)
            .abs()
            .total_cmp(&(b.1.ratio() - 1.0).abs())
    })?;
    let s = &acc.header.settings;
    let nl = s.wavelength_count().max(1);
    let theta = s.theta_i_deg.get(k / nl).copied().unwrap_or(f64::NAN);
    Some(format!(
        "in {} cells the diffraction transform held a share of the ray field's power in propagating orders outside [{}, {:.2}] (at worst {:.3}, theta_i {theta} deg, {} nm), so those cells took rays: their angular distribution misses the interference the method was chosen for (their total R is the rays'). More --rays sample the field more finely; where the ratio does not improve, the tangent plane fails and the rigorous solver (--coherence rigorous) holds these cells (docs/validity.md)",
        fell.len(),
        super::DIFFRACTION_RATIO_REFUSED,
        1.0 / super::DIFFRACTION_RATIO_REFUSED,
        d.ratio(),
        s.wavelength(k % nl)
    ))
}

/// The rays that met an interface from the wrong medium, in proportion to the run, and
/// what they mean. `goniospec check` walks the geometry for leaks (holes, gaps, interfaces
/// that cross); where it finds none and only a handful of the run's segments met a wrong
/// side, they are rays that started within the tracer's offset of a second surface (a thin
/// flake's edge, two surfaces nearly touching), and their power is in the dropped figure.
fn leak_warning(stats: &SimStats) -> String {
    let share = stats.leaks as f64 / stats.segments.max(1) as f64;
    if share < 1e-5 {
        format!(
            "{} of the run's {} traced segments ({share:.1e}) met an interface from the wrong medium and were dropped: a ray that starts within the tracer's offset of a second surface (a thin flake's edge, surfaces nearly touching) does so; at this share it is not a leak in the geometry (`goniospec check` walks it for those), and their power is part of the dropped figure",
            stats.leaks, stats.segments
        )
    } else {
        format!(
            "{} of the run's {} traced segments ({share:.1e}) met an interface from the wrong medium and were dropped: the geometry leaks (a hole, a gap, or interfaces that cross); run goniospec check, whose random walks find where",
            stats.leaks, stats.segments
        )
    }
}

/// The diffraction method's warning where its transform held a share of the ray field's
/// power in propagating orders outside `[DIFFRACTION_RATIO_WARN, 1 / DIFFRACTION_RATIO_WARN]`:
/// short of it (power beyond the horizon or unresolved) or beyond it (the rays sample the
/// field too coarsely, so the transform adds power the rays do not carry).
fn diffraction_warning(acc: &Accumulator, stats: &SimStats) -> Option<String> {
    let (k, d) = stats
        .diffraction
        .iter()
        .enumerate()
        .filter(|(_, d)| d.rays_r + d.rays_t > 0.0 && !d.fell_back)
        .max_by(|a, b| {
            (a.1.ratio() - 1.0)
                .abs()
                .total_cmp(&(b.1.ratio() - 1.0).abs())
        })?;
    let r = d.ratio();
    if (DIFFRACTION_RATIO_WARN..=1.0 / DIFFRACTION_RATIO_WARN).contains(&r) {
        return None;
    }
    let s = &acc.header.settings;
    let nl = s.wavelength_count().max(1);
    let theta = s.theta_i_deg.get(k / nl).copied().unwrap_or(f64::NAN);
    let lambda = s.wavelength(k % nl);
    Some(if r < 1.0 {
        format!(
            "the diffraction transform held {r:.3} of the ray field's power in propagating orders (theta_i {theta} deg, {lambda} nm): the rest fell beyond the horizon or was not resolved, so the angular distribution is uncertain by about {:.2}: raise --rays, or use --coherence rigorous where its structure nears the wavelength (docs/physics.md, \"Diffraction\")",
            1.0 - r
        )
    } else {
        format!(
            "the diffraction transform held {r:.3} times the ray field's power in propagating orders (theta_i {theta} deg, {lambda} nm): more than the rays carry, so the rays sample the field too coarsely for it and the angular distribution is uncertain by about {:.2}: raise --rays (docs/physics.md, \"Diffraction\")",
            r - 1.0
        )
    })
}
