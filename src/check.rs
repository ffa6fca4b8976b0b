//! `goniospec check`: what a user should know before spending hours simulating a sample.
//!
//! Reports triangle counts, bounds and media, and looks for defects: interfaces whose
//! normals point the wrong way, closed bodies that are not watertight, interfaces that cut
//! through each other, sheets whose boundary does not tile periodically (periodic sides
//! only), and leaks: random rays walk the sample (reflecting or passing at random at each
//! crossing, wrapping around the tile's sides, or ending at a side of an open sample) while
//! tracking the current medium, and every crossing whose source medium does not match is
//! counted (docs/design.md §2).

use glam::DVec3;
use std::collections::HashMap;

use crate::accel::{Accel, AccelError, Backend, Hit, Intersector, Ray};
use crate::rng::Rng;
use crate::sample::{Sample, generate::enclosed_volume};

/// Settings of the leak test.
#[derive(Clone, Debug)]
pub struct CheckOptions {
    pub backend: Backend,
    /// Random walks of the leak test.
    pub leak_rays: usize,
    /// Crossings per walk before it is abandoned.
    pub max_events: usize,
    pub seed: u64,
    /// Where the methods hold ([`crate::sample::validity`]): the run to judge the sample for, or
    /// `None` for no such warnings.
    pub validity: Option<crate::sample::validity::Context>,
}

impl Default for CheckOptions {
    fn default() -> Self {
        CheckOptions {
            backend: Backend::default_available(),
            leak_rays: 20_000,
            max_events: 64,
            seed: 1,
            validity: None,
        }
    }
}

/// What the leak test found.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LeakStats {
    pub walks: usize,
    pub crossings: usize,
    /// Crossings entered from a side whose medium was not the current one.
    pub leaks: usize,
    /// Walks that hit the event limit (inside strongly reflecting geometry), not defects.
    pub abandoned: usize,
}

/// Everything `check` found: facts to print, and defects (non-empty means exit 1).
#[derive(Clone, Debug, Default)]
pub struct CheckReport {
    pub facts: Vec<String>,
    pub defects: Vec<String>,
    /// Where the sample asks more of ray optics than it gives (not defects of the mesh).
    pub warnings: Vec<String>,
    pub leak: LeakStats,
    /// Each interface's feature scales (`None` for a flat one), as measured for the facts
    /// and the validity warnings; `crate::simulate::auto::check` judges the default run's
    /// methods with them.
    pub sheets: Vec<Option<crate::sample::validity::Scales>>,
}

/// Checks `sample`. Errors only when an accelerator cannot be built.
pub fn check(sample: &Sample, opts: &CheckOptions) -> Result<CheckReport, AccelError> {
    let mut r = CheckReport::default();
    let [lx, ly] = sample.tile_nm;
    r.facts.push(format!(
        "sample '{}': tile {lx} nm x {ly} nm, {} media, {} interfaces, {} triangles",
        sample.name,
        sample.media.len(),
        sample.interfaces.len(),
        sample.triangle_count()
    ));
    r.facts.push(match sample.guard_nm {
        Some(g) => format!(
            "sides: open, with a guard band of {g} nm (trees launch in [{g}, {}] x [{g}, {}] nm; light reaching a side escapes and is reported)",
            lx - g,
            ly - g
        ),
        None => "sides: periodic (rays leaving the tile re-enter on the opposite side)".into(),
    });
    for (i, m) in sample.media.iter().enumerate() {
        r.facts
            .push(format!("medium {:<14} {}", m.name, m.model.describe()));
        match scattering_fact(sample, i, 550.0) {
            Some(Ok(f)) => r.facts.push(f),
            Some(Err(e)) => r.defects.push(format!("medium '{}': {e}", m.name)),
            None => {}
        }
        if let Some(w) = m
            .scattering
            .as_ref()
            .and_then(|sc| sc.packing_warning(&m.name))
        {
            r.warnings.push(w);
        }
    }
    let tol = 1e-6 * lx.max(ly);
    // Every sheet's feature scales, measured once for the facts and the validity warnings.
    let sheets = crate::sample::validity::sheet_scales(sample);
    // Coatings are judged against the run's beamlet, or the default one for a plane wave
    // (under which a thick coating's transfer matrix is exact, but a unit slip is not).
    let coating_rho = opts
        .validity
        .as_ref()
        .map(|c| c.rho_nm)
        .filter(|r| r.is_finite())
        .unwrap_or(crate::sample::validity::DEFAULT_COHERENCE_RADIUS_NM);
    for (i, itf) in sample.interfaces.iter().enumerate() {
        check_interface(sample, i, itf, sheets[i], tol, coating_rho, &mut r);
    }

    let (soup, first) = sample.triangle_soup();
    let accel = Accel::build(opts.backend, &soup)?;

    let crossings = crossings(sample, &accel, &first);
    // Bodies small against the wavelength: ray optics does not hold for them.
    r.warnings.extend(
        crate::sample::validity::small_bodies(sample, 550.0)
            .into_iter()
            .map(|f| f.message),
    );
    if let Some(ctx) = &opts.validity {
        r.warnings.extend(
            crate::sample::validity::assess_scales(sample, &sheets, ctx)
                .into_iter()
                .map(|f| f.message),
        );
    }
    for ((i, j), n) in crossings.iter().take(20) {
        r.defects.push(format!(
            "interfaces {i} and {j} intersect ({n} edges of one cross the other)"
        ));
    }
    if crossings.len() > 20 {
        r.defects.push(format!(
            "... and {} more intersecting pairs",
            crossings.len() - 20
        ));
    }

    r.leak = leak_test(sample, &accel, &first, opts);
    if r.leak.walks == 0 && opts.leak_rays > 0 {
        r.defects.push(
            "vertical rays from above miss the sample: no sheet covers the tile, so the medium above it is undefined".into(),
        );
    } else if r.leak.crossings == 0 && opts.leak_rays > 0 {
        // A check that crossed nothing tested nothing: never report it as clean.
        r.defects.push(format!(
            "the leak test's {} walks crossed no interface: it tested nothing (is the geometry far taller than the tile, or does the walk miss it?)",
            r.leak.walks
        ));
    }
    r.facts.push(format!(
        "leak test: {} walks, {} crossings, {} leaks, {} walks abandoned after {} crossings",
        r.leak.walks, r.leak.crossings, r.leak.leaks, r.leak.abandoned, opts.max_events
    ));
    if r.leak.leaks > 0 {
        r.defects.push(format!(
            "{} of {} crossings entered an interface from a medium other than the ray's: the geometry leaks (overlapping bodies, a body poking through a sheet, or wrong front/back media)",
            r.leak.leaks, r.leak.crossings
        ));
    }
    r.sheets = sheets;
    Ok(r)
}

/// What a scattering medium does at `lambda_nm`: its extinction coefficient, albedo and
/// asymmetry, the transport mean free path `1 / (mu_ext (1 - omega g))`, and for a size
/// distribution how well its size integral converged (`optics::particles`); `None` for a
/// clear medium.
fn scattering_fact(
    sample: &Sample,
    i: usize,
    lambda_nm: f64,
) -> Option<Result<String, crate::optics::particles::ParticleError>> {
    use crate::optics::particles::{Radius, ScatterModel};
    use crate::sample::Scattering;
    let m = &sample.media[i];
    let index = |k: usize| {
        let (n, kk) = sample.media[k]
            .model
            .eval(lambda_nm)
            .unwrap_or((f64::NAN, f64::NAN));
        crate::optics::C64::new(n, kk)
    };
    let (model, what) = match m.scattering.as_ref()? {
        Scattering::HenyeyGreenstein {
            g,
            scattering_per_um,
            absorption_per_um,
        } => (
            ScatterModel::henyey_greenstein(*g, *scattering_per_um, *absorption_per_um),
            "Henyey-Greenstein".to_string(),
        ),
        Scattering::Particles {
            medium,
            radius,
            volume_fraction,
            dependent,
        } => (
            ScatterModel::mie(
                *radius,
                *volume_fraction,
                *dependent,
                lambda_nm,
                lambda_nm,
                &|_| index(i),
                &|_| index(*medium),
                &|| false,
            ),
            format!(
                "particles of '{}' ({}) at {} % by volume, {}",
                sample.media[*medium].name,
                match radius {
                    Radius::Fixed { radius_nm } => format!("radius {radius_nm} nm"),
                    Radius::LogNormal { median_nm, sigma } =>
                        format!("log-normal by number, median {median_nm} nm, sigma {sigma}"),
                },
                100.0 * volume_fraction,
                if *dependent {
                    "dependent scattering (Percus-Yevick structure factor)"
                } else {
                    "independent scattering"
                }
            ),
        ),
    };
    Some(model.map(|model| {
        let (mu, albedo) = model.coefficients(lambda_nm);
        let g = model.asymmetry(lambda_nm);
        let transport_um = 1e-3 / (mu * (1.0 - albedo * g));
        let size = match model.size_uncertainty() {
            0.0 => String::new(),
            u => format!("; size integral converged to {u:.1e}"),
        };
        format!(
            "medium {:<14} {what}: at {lambda_nm} nm extinction {:.4} per um, albedo {albedo:.4}, g {g:.4}, transport mean free path {transport_um:.3} um{size}",
            m.name,
            mu * 1e3
        )
    }))
}

/// A coating's layers as facts (medium and thickness in nm, outermost first), and a warning
/// for a layer too thick for the coating model: it applies the layers' transfer-matrix
/// amplitudes at the interface, exact for layers thin against the beamlet and flat across
/// it, where every reflection inside overlaps the others. A layer thicker than the beamlet
/// radius, or whose round trip at 60 degrees walks `2 d tan(theta_t)` more than half of it
/// sideways, is not: its partial waves separate (issue 47: `thickness = 300` in a sample
/// whose unit is um is a 300 um "thin" layer).
fn coating_facts(
    sample: &Sample,
    name: &str,
    itf: &crate::sample::Interface,
    rho_nm: f64,
    r: &mut CheckReport,
) {
    let layers: Vec<String> = itf
        .coating
        .iter()
        .map(|&(m, d)| format!("{} {d} nm", sample.media[m].name))
        .collect();
    r.facts.push(format!(
        "{name}: coating of {} layers on its front ({}), outermost first: {}",
        itf.coating.len(),
        sample.media[itf.front].name,
        layers.join(", ")
    ));
    for &(m, d) in &itf.coating {
        let n = sample.media[m]
            .model
            .eval(550.0)
            .map_or(1.0, |(n, _)| n.max(1.0));
        let sin_t = 60f64.to_radians().sin() / n;
        let walk = 2.0 * d * sin_t / (1.0 - sin_t * sin_t).max(1e-12).sqrt();
        if d > rho_nm || walk > 0.5 * rho_nm {
            r.warnings.push(format!(
                "{name}: its coating layer of '{}' is {d} nm thick: a coating is applied as thin layers whose reflections all overlap, which holds for layers thin against the beamlet ({rho_nm} nm); at 60 degrees this one walks light {walk:.0} nm sideways per round trip. A coating's thickness is in the sample's unit: was it meant in nm (thickness = 300 in a sample of unit = \"um\" is 300 um)? A layer this thick belongs in the mesh: a [stack] with mode = \"mesh\", or interfaces",
                sample.media[m].name,
            ));
        }
    }
}

/// The facts and defects of interface `i`: its bounds against the tile, and a closed
/// body's orientation and watertightness or a sheet's orientation, feature scales
/// (`scales`, measured once for the validity warnings too) and periodicity.
fn check_interface(
    sample: &Sample,
    i: usize,
    itf: &crate::sample::Interface,
    scales: Option<crate::sample::validity::Scales>,
    tol: f64,
    coating_rho_nm: f64,
    r: &mut CheckReport,
) {
    let [lx, ly] = sample.tile_nm;
    let (lo, hi) = itf.mesh.bounds().expect("loaded meshes are non-empty");
    let name = format!("interface {i} ({})", itf.mesh_path.display());
    r.facts.push(format!(
        "{name}: {} triangles, {} {} / {}, bounds [{:.1}, {:.1}, {:.1}] .. [{:.1}, {:.1}, {:.1}] nm",
        itf.mesh.triangles.len(),
        if itf.closed { "closed body, outside / inside:" } else { "sheet, front / back:" },
        sample.media[itf.front].name,
        sample.media[itf.back].name,
        lo.x,
        lo.y,
        lo.z,
        hi.x,
        hi.y,
        hi.z
    ));
    if !itf.coating.is_empty() {
        coating_facts(sample, &name, itf, coating_rho_nm, r);
    }
    if lo.x < -tol || lo.y < -tol || hi.x > lx + tol || hi.y > ly + tol {
        r.defects.push(format!(
            "{name} reaches outside the tile [0, {lx}] x [0, {ly}] nm; geometry must lie within one tile"
        ));
    }
    if itf.closed {
        let v = enclosed_volume(&itf.mesh);
        if v < 0.0 {
            r.defects.push(format!(
                "{name}: normals point inwards (enclosed volume {v:.3e} nm³ < 0); flip the triangles or swap inside/outside"
            ));
        }
        let w = watertightness(&itf.mesh);
        if w.open_edges + w.nonmanifold_edges + w.misoriented_edges > 0 {
            r.defects.push(format!(
                "{name} is not watertight: {} open edges, {} edges shared by more than two triangles, {} edges whose triangles disagree in orientation",
                w.open_edges, w.nonmanifold_edges, w.misoriented_edges
            ));
        }
    } else {
        let (up, total) = (0..itf.mesh.triangles.len()).fold((0.0, 0.0), |(u, t), k| {
            let a = itf.mesh.area_vector(k);
            (u + a.z, t + a.length())
        });
        r.facts.push(format!(
            "{name}: mean normal z = {:.3} (front medium '{}' {})",
            up / total,
            sample.media[itf.front].name,
            if up > 0.0 { "above" } else { "below" }
        ));
        if up <= 0.0 {
            r.defects.push(format!(
                "{name}: normals point down on average, so its front medium '{}' lies below it; swap front and back or flip the mesh",
                sample.media[itf.front].name
            ));
        }
        if let Some(sc) = scales.filter(crate::sample::validity::Scales::structured) {
            r.facts.push(format!(
                "{name}: RMS height {:.1} nm, RMS slope {:.3}, lateral scale 2 pi sigma / slope {}, strongest axis mode period {:.0} nm ({:.0} % of the height variance), curvature radius {:.0} nm (docs/validity.md)",
                sc.rms_height_nm,
                sc.rms_slope,
                if sc.lateral_nm.is_finite() {
                    format!("{:.0} nm", sc.lateral_nm)
                } else {
                    "none (no sloped facets: vertical walls and flat faces)".to_string()
                },
                sc.period_nm,
                100.0 * sc.period_share,
                sc.curvature_radius_nm
            ));
        }
        let p = periodicity(&itf.mesh, sample.tile_nm, tol);
        if p.interior_boundary_edges > 0 {
            r.defects.push(format!(
                "{name} has {} boundary edges inside the tile (holes or cracks)",
                p.interior_boundary_edges
            ));
        }
        if p.unmatched > 0 && sample.guard_nm.is_none() {
            r.defects.push(format!(
                "{name} does not tile: {} boundary edges on the tile's sides have no partner on the opposite side",
                p.unmatched
            ));
        }
    }
}

/// Pairs of interfaces that cut through each other, with how many edges of one cross a
/// triangle of the other, sorted by pair.
fn crossings(sample: &Sample, accel: &Accel, first: &[u32]) -> Vec<((usize, usize), usize)> {
    let owner = |prim: u32| first.partition_point(|&f| f <= prim) - 1;
    let mut crossings: HashMap<(usize, usize), usize> = HashMap::new();
    for (i, itf) in sample.interfaces.iter().enumerate() {
        for t in &itf.mesh.triangles {
            for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                if a > b {
                    continue; // each undirected edge once (sheets' boundary edges twice is harmless)
                }
                let (p, q) = (
                    itf.mesh.positions_nm[a as usize],
                    itf.mesh.positions_nm[b as usize],
                );
                let d = q - p;
                let ray = Ray {
                    origin: p.as_vec3().to_array(),
                    tmin: 1e-4,
                    dir: d.as_vec3().to_array(),
                    tmax: 1.0 - 1e-4,
                };
                let h = accel.closest_hit(&ray);
                if h.is_hit() {
                    let j = owner(h.prim);
                    if j != i {
                        *crossings.entry((i.min(j), i.max(j))).or_default() += 1;
                    }
                }
            }
        }
    }
    let mut pairs: Vec<_> = crossings.into_iter().collect();
    pairs.sort();
    pairs
}

/// Tile-side crossings of one leak-test walk before it is abandoned (a walk in a sample
/// much taller than its tile wraps many times between crossings).
const MAX_WRAPS: u32 = 10_000;

/// Edge statistics of a mesh meant to be closed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Watertightness {
    pub open_edges: usize,
    pub nonmanifold_edges: usize,
    pub misoriented_edges: usize,
}

/// Every edge of a closed, consistently oriented mesh is used by exactly two triangles,
/// once in each direction. Vertices are identified by position, so duplicated vertices
/// do not count as cracks.
pub fn watertightness(mesh: &crate::sample::Mesh) -> Watertightness {
    let key = |i: u32| mesh.positions_nm[i as usize].to_array().map(f64::to_bits);
    let mut edges: HashMap<([u64; 3], [u64; 3]), (u32, u32)> = HashMap::new();
    for t in &mesh.triangles {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            let (ka, kb) = (key(a), key(b));
            let (lo, hi, forward) = if ka < kb {
                (ka, kb, true)
            } else {
                (kb, ka, false)
            };
            let e = edges.entry((lo, hi)).or_default();
            if forward {
                e.0 += 1;
            } else {
                e.1 += 1;
            }
        }
    }
    let mut w = Watertightness::default();
    for &(f, b) in edges.values() {
        match f + b {
            1 => w.open_edges += 1,
            2 if f != 1 => w.misoriented_edges += 1,
            2 => {}
            _ => w.nonmanifold_edges += 1,
        }
    }
    w
}

/// Boundary-edge statistics of a sheet.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Periodicity {
    /// Boundary edges not lying on a tile side.
    pub interior_boundary_edges: usize,
    /// Boundary edges on the tile's sides that no edge on the opposite side (or, at the
    /// tile's corners, on any periodic image) completes.
    pub unmatched: usize,
}

/// A sheet tiles when its boundary edges all lie on the tile's sides and, with x taken
/// modulo Lx and y modulo Ly, every boundary edge appears an even number of times (the
/// edge on x = 0 meets its partner on x = Lx; at the tile's corners up to four images
/// meet). Boundaries are counted mod 2, so saddle edges where four walls meet are
/// interior. Positions match within `tol` nm.
pub fn periodicity(mesh: &crate::sample::Mesh, tile_nm: [f64; 2], tol: f64) -> Periodicity {
    let q = |v: f64| (v / tol).round() as i64;
    let (lx, ly) = (q(tile_nm[0]), q(tile_nm[1]));
    // Edges by quantised position (vertices may be duplicated at equal positions).
    let mut by_pos: HashMap<([i64; 3], [i64; 3]), u32> = HashMap::new();
    for t in &mesh.triangles {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            let (kp, kr) = (
                mesh.positions_nm[a as usize].to_array().map(q),
                mesh.positions_nm[b as usize].to_array().map(q),
            );
            let k = if kp <= kr { (kp, kr) } else { (kr, kp) };
            *by_pos.entry(k).or_default() += 1;
        }
    }
    let mut out = Periodicity::default();
    let near = |v: i64, target: i64| (v - target).abs() <= 1;
    let on_side = |p: [i64; 3]| near(p[0], 0) || near(p[0], lx) || near(p[1], 0) || near(p[1], ly);
    let wrap = |p: [i64; 3]| {
        [
            if near(p[0], lx) { 0 } else { p[0] },
            if near(p[1], ly) { 0 } else { p[1] },
            p[2],
        ]
    };
    let mut wrapped: HashMap<([i64; 3], [i64; 3]), u32> = HashMap::new();
    for (&(p, r), &n) in &by_pos {
        if n % 2 == 0 {
            continue;
        }
        // A boundary edge must run along a tile side: both ends on the same side line.
        let same_side = (near(p[0], 0) && near(r[0], 0))
            || (near(p[0], lx) && near(r[0], lx))
            || (near(p[1], 0) && near(r[1], 0))
            || (near(p[1], ly) && near(r[1], ly));
        if !(on_side(p) && on_side(r) && same_side) {
            out.interior_boundary_edges += 1;
            continue;
        }
        let (a, b) = (wrap(p), wrap(r));
        *wrapped
            .entry(if a <= b { (a, b) } else { (b, a) })
            .or_default() += 1;
    }
    out.unmatched = wrapped.values().filter(|&&c| c % 2 == 1).count();
    out
}

/// Random walks through the sample tracking the current medium.
fn leak_test(sample: &Sample, accel: &Accel, first: &[u32], opts: &CheckOptions) -> LeakStats {
    let owner = |prim: u32| first.partition_point(|&f| f <= prim) - 1;
    let (soup_lo, soup_hi) = sample
        .interfaces
        .iter()
        .filter_map(|i| i.mesh.bounds())
        .fold(
            (DVec3::INFINITY, DVec3::NEG_INFINITY),
            |(lo, hi), (a, b)| (lo.min(a), hi.max(b)),
        );
    let [lx, ly] = sample.tile_nm;
    let extent = lx.max(ly).max(soup_hi.z - soup_lo.z);
    let eps = (1e-6 * extent).max(1e-3);
    let z_top = soup_hi.z + 0.01 * extent + 1.0;
    let z_bottom = soup_lo.z - 0.01 * extent - 1.0;
    // The medium above everything, seen from vertical rays down the tile (a few tries, in
    // case one runs exactly along a vertical wall).
    let mut probe = Rng::new(opts.seed, u64::MAX);
    let mut ambient = None;
    for _ in 0..16 {
        let down = Ray::new(
            [
                probe.range(0.0, lx) as f32,
                probe.range(0.0, ly) as f32,
                z_top as f32,
            ],
            [0.0, 0.0, -1.0],
        );
        let h = accel.closest_hit(&down);
        if h.is_hit() {
            let itf = &sample.interfaces[owner(h.prim)];
            ambient = Some(if h.ng[2] > 0.0 { itf.front } else { itf.back });
            break;
        }
    }
    let Some(ambient) = ambient else {
        return LeakStats::default();
    };

    let mut stats = LeakStats::default();
    for w in 0..opts.leak_rays {
        let mut rng = Rng::new(opts.seed, w as u64);
        let mut pos = DVec3::new(rng.range(0.0, lx), rng.range(0.0, ly), z_top);
        let cos_t = rng.range(0.2, 1.0);
        let phi = rng.range(0.0, std::f64::consts::TAU);
        let s = (1.0 - cos_t * cos_t).sqrt();
        let mut dir = DVec3::new(s * phi.cos(), s * phi.sin(), -cos_t);
        let mut medium = ambient;
        stats.walks += 1;
        let mut events = 0;
        let mut wraps = 0u32;
        loop {
            if events >= opts.max_events || wraps >= MAX_WRAPS {
                stats.abandoned += 1;
                break;
            }
            // Distance to the tile's sides along dir (the walk wraps there).
            let mut t_side = f64::INFINITY;
            let mut side_axis = 0usize;
            for (a, l) in [(0usize, lx), (1, ly)] {
                if dir[a] > 0.0 {
                    let t = (l - pos[a]) / dir[a];
                    if t < t_side {
                        t_side = t;
                        side_axis = a;
                    }
                } else if dir[a] < 0.0 {
                    let t = -pos[a] / dir[a];
                    if t < t_side {
                        t_side = t;
                        side_axis = a;
                    }
                }
            }
            // Geometry may lie exactly on the tile's side (a wall at x = Lx): search a little
            // past the side, and re-enter a little outside the opposite side, so such
            // geometry is found from both directions.
            let t_limit = if t_side.is_finite() {
                t_side + eps / dir[side_axis].abs()
            } else {
                1e30
            };
            let ray = Ray {
                origin: pos.as_vec3().to_array(),
                tmin: 0.0,
                dir: dir.as_vec3().to_array(),
                tmax: t_limit as f32,
            };
            let hit: Hit = accel.closest_hit(&ray);
            if !hit.is_hit() || f64::from(hit.t) > t_limit {
                if t_side.is_finite() && sample.guard_nm.is_none() {
                    // Wrap around the tile side and go on.
                    wraps += 1;
                    pos += dir * t_side;
                    let l = [lx, ly][side_axis];
                    pos[side_axis] = if dir[side_axis] > 0.0 { -eps } else { l + eps };
                    if pos.z > z_top || pos.z < z_bottom {
                        break;
                    }
                    continue;
                }
                // A vertical ray that left the sample, or one that left an open sample
                // through a side (no medium is known beyond it).
                break;
            }
            events += 1;
            stats.crossings += 1;
            let itf = &sample.interfaces[owner(hit.prim)];
            let n = DVec3::from(hit.ng.map(f64::from));
            let cos = dir.dot(n);
            let (from, to) = if cos < 0.0 {
                (itf.front, itf.back)
            } else {
                (itf.back, itf.front)
            };
            if from != medium {
                stats.leaks += 1;
            }
            let t = f64::from(hit.t);
            let p = pos + dir * t;
            // Pass through or reflect, at random; then step off the surface to the side the
            // new direction points to.
            if rng.uniform() < 0.5 {
                medium = to;
            } else {
                medium = from;
                dir -= n * (2.0 * cos);
            }
            let off = dir.dot(n).signum();
            pos = p + n * (off * eps);
            pos.x = pos.x.rem_euclid(lx);
            pos.y = pos.y.rem_euclid(ly);
        }
    }
    stats
}
