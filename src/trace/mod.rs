//! Coherent ray trees through a periodic sample (docs/design.md §3).
//!
//! A tree starts as one ray of a plane wave on the launch plane above the sample and splits
//! at every interface into a reflected and a transmitted child, each carrying the complex
//! electric field of two orthogonal incident polarisations, power-normalised so `|E|^2` is
//! the fraction of launched power where the wave is in a lossless medium, the complex
//! index vector `N` of its (possibly inhomogeneous) plane wave, and the complex optical
//! path length `sum N . dr` (nm) from the launch plane (`optics::fresnel` has the wave
//! model: inside an absorbing medium the attenuation follows the depth below the interface
//! the wave entered through, not the ray length). A child is dropped below a power cutoff or at a depth limit;
//! dropped power is recorded, never hidden. Rays wrap around the tile's sides with their
//! unwrapped offset kept for the phase; hits are refined in f64 against the triangle's
//! plane; the current medium is tracked and every mismatch (a leak) is counted.
//!
//! Propagation phases are kept out of the fields: a tree's exit amplitude at wavelength
//! `lambda` is `E * exp(i 2 pi OPL / lambda)`. When no medium is dispersive or absorbing
//! (thin absorbing films take wavelength-dependent transfer-matrix amplitudes, `film`) the
//! coefficients do not depend on wavelength either, so one traced tree serves every
//! wavelength (spectral path sharing). Otherwise [`Scene::trace_lanes`] traces every
//! wavelength of a tree at once, sharing each ray until it refracts into a dispersive
//! medium and evaluating the coefficients per wavelength along it (wavelength sharing).

use crate::accel::{Accel, AccelError, Backend, Intersector, Ray};
use crate::optics::C64;
use crate::optics::fresnel::{Field, field_power};
use crate::optics::particles::ScatterModel;
use crate::rng::Rng;
use crate::sample::Sample;
use glam::DVec3;

mod children;
mod escape;
mod events;
mod film;
mod random;
mod spread;
mod tree;
mod walk;

pub use escape::{NEE_ROULETTE, SPREAD_ROULETTE, SpreadGrid};
pub use random::{ROULETTE_AFTER_SEGMENTS, ROULETTE_BELOW};

pub use events::{PLANE_WAVE_TILT, deflection, event_weights, recombination_weight};
pub use film::{FILM_TILT_FULL, FILM_TILT_NONE, depth_weight, tilt_weight};
pub use tree::{Dropped, DroppedPower, Exit, Tree};

/// Limits of a tree.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TraceLimits {
    /// A child whose power falls below this fraction of the launched power is dropped.
    pub cutoff: f64,
    /// Interface events along one path before it is dropped.
    pub max_depth: u32,
    /// Tile-side crossings of one segment chain before it is dropped (rays running
    /// nearly parallel to the layers).
    pub max_wraps: u32,
    /// Traced segments of one tree before its remaining rays are dropped: a guard against
    /// the exponential growth of trees in multiply scattering samples (pigments, flakes).
    pub max_segments: u32,
}

impl TraceLimits {
    /// The default power cutoff: a dropped child's amplitude (the square root) enters the
    /// coherent sum, so 1e-10 keeps its effect on R near 1e-5.
    pub const CUTOFF: f64 = 1e-10;
    /// Light guided in a film near its critical angle needs thousands of events (the
    /// seed's wavy film at 85 deg loses 2.4e-2 of its power here and 1.2e-4 at 4,096, for
    /// 1.9 times the time; the demo runs it at 4,096). The default stays 64 because deeper
    /// series of absorbing wedges compound the power their limited events may add: a gold
    /// roof of 40 degrees (tests/tilted_absorbers.rs) created 1.7e-2 of the launched power
    /// at 64 and 2.4e10 at 4,096.
    pub const MAX_DEPTH: u32 = 64;
    pub const MAX_WRAPS: u32 = 10_000;
    pub const MAX_SEGMENTS: u32 = 20_000;
}

impl Default for TraceLimits {
    fn default() -> Self {
        TraceLimits {
            cutoff: Self::CUTOFF,
            max_depth: Self::MAX_DEPTH,
            max_wraps: Self::MAX_WRAPS,
            max_segments: Self::MAX_SEGMENTS,
        }
    }
}

/// A sample prepared for tracing: its accelerator, per-triangle f64 geometry and the
/// media above and below it.
pub struct Scene<'a> {
    pub sample: &'a Sample,
    accel: Accel,
    /// Per triangle: owning interface.
    owner: Vec<u32>,
    /// Per triangle: a vertex and the unit normal, f64.
    plane: Vec<(DVec3, DVec3)>,
    /// Launch / top exit plane and bottom exit plane, nm.
    pub z_top: f64,
    pub z_bottom: f64,
    /// Offset that moves a new ray off its surface, nm.
    eps: f64,
    /// Medium above everything and below everything.
    pub ambient: usize,
    pub substrate: usize,
    /// Per medium: its volume scattering, once [`Scene::prepare_scattering`] has
    /// tabulated it (`None` for a clear medium).
    scatter: Vec<Option<ScatterModel>>,
    /// Whether some medium scatters.
    scatters: bool,
    /// Per triangle: whether light entering its back (bit 0) or front (bit 1) medium
    /// through it could find a far face there (`film::film_faces`); only there is one
    /// probed for.
    film_faces: Vec<u8>,
    /// Whether long trees play Russian roulette: samples with bodies (flakes, pigments) or
    /// scattering media only. A meshed multilayer's long series is one coherent sum whose
    /// deep terms matter (its cross terms are not small): it keeps every branch and is
    /// refused when the limits cut it.
    roulette: bool,
    /// Next-event estimation's geometry, once [`Scene::enable_next_event`] found it applies.
    escape: Option<escape::Escape>,
}

/// Why a scene cannot be traced.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error(transparent)]
    Accel(#[from] AccelError),
    #[error("{0}")]
    Geometry(String),
}

impl<'a> Scene<'a> {
    pub fn new(sample: &'a Sample, backend: Backend) -> Result<Scene<'a>, SceneError> {
        let (soup, first) = sample.triangle_soup();
        let accel = Accel::build(backend, &soup)?;
        let mut owner = Vec::with_capacity(soup.triangles.len());
        let mut plane = Vec::with_capacity(soup.triangles.len());
        let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for (i, itf) in sample.interfaces.iter().enumerate() {
            let m = &itf.mesh;
            for k in 0..m.triangles.len() {
                let v0 = m.positions_nm[m.triangles[k][0] as usize];
                owner.push(i as u32);
                plane.push((v0, m.area_vector(k).normalize()));
            }
            if let Some((a, b)) = m.bounds() {
                lo = lo.min(a);
                hi = hi.max(b);
            }
        }
        debug_assert_eq!(
            owner.len(),
            first.last().map_or(0, |&f| f as usize)
                + sample
                    .interfaces
                    .last()
                    .map_or(0, |i| i.mesh.triangles.len())
        );
        let [lx, ly] = sample.tile_nm;
        let extent = lx.max(ly).max(hi[2] - lo[2]);
        // Children start `eps` off their surface so the accelerator (f32) does not find it
        // again. Its f32 spacing at the scene's far corner is 1.2e-7 of the extent; a
        // scattering medium puts events anywhere, next to its faces too, and a scattered
        // ray must then still see the face it heads for, so there the offset is 1e-6 (8
        // spacings; `volume_event` keeps events as far from the face ahead). At 1e-7 a
        // hiding chart 110 um deep leaked (issue 71).
        let scatters = sample.media.iter().any(|m| m.scattering.is_some());
        let eps = (if scatters { 1e-6 } else { 1e-7 } * extent).max(1e-4);
        let margin = 1e-3 * extent + 1.0;
        let mut scene = Scene {
            sample,
            accel,
            owner,
            plane,
            z_top: hi[2] + margin,
            z_bottom: lo[2] - margin,
            eps,
            ambient: 0,
            substrate: 0,
            scatter: Vec::new(),
            film_faces: Vec::new(),
            scatters,
            roulette: sample.media.iter().any(|m| m.scattering.is_some())
                || sample.interfaces.iter().any(|i| i.closed),
            escape: None,
        };
        let faces: Vec<_> = scene
            .owner
            .iter()
            .zip(&scene.plane)
            .map(|(&o, &(_, n))| {
                let itf = &sample.interfaces[o as usize];
                (n, itf.front, itf.back)
            })
            .collect();
        scene.film_faces = film::film_faces(sample.media.len(), &faces);
        scene.ambient = scene.outer_medium(true)?;
        scene.substrate = scene.outer_medium(false)?;
        for (m, side) in [(scene.ambient, "above"), (scene.substrate, "below")] {
            if sample.media[m].scattering.is_some() {
                return Err(SceneError::Geometry(format!(
                    "medium '{}' scatters in volume and is the medium {side} the sample, which goes on without end: the tracer follows light only between the sample's top and bottom planes, so its particles would be ignored there. Give it a finite depth as a layer (one many transport mean free paths deep, which goniospec check prints, reflects as a half-space does) over a clear medium{}",
                    sample.media[m].name,
                    if side == "above" {
                        "; a BRDF is measured in a clear medium above the sample"
                    } else {
                        ""
                    }
                )));
            }
        }
        Ok(scene)
    }

    /// Turns next-event estimation on where it applies (a scattering layer of a flat stack
    /// under clear layers only: `escape`); returns whether it does. With `spread`, a
    /// shallow event's estimate goes to every bucket of that grid at once ([`Tree::nee`],
    /// `spread`), else to one direction as an exit of its own.
    pub fn enable_next_event(&mut self, spread: Option<SpreadGrid>) -> bool {
        self.escape = escape::Escape::of(self.sample).map(|mut e| {
            e.spread = spread.map(|g| (g, spread::polar_edges(g)));
            e
        });
        self.escape.is_some()
    }

    /// The medium beyond the sample above (or below) it, from vertical probe rays; the
    /// probes must agree.
    fn outer_medium(&self, above: bool) -> Result<usize, SceneError> {
        let [lx, ly] = self.sample.tile_nm;
        let mut found: Option<usize> = None;
        for k in 0..9 {
            let (fx, fy) = (0.123 + 0.1 * k as f64, 0.317 + 0.071 * k as f64);
            let (z, dz) = if above {
                (self.z_top, -1.0)
            } else {
                (self.z_bottom, 1.0)
            };
            let ray = Ray::new(
                [(fx * lx) as f32, ((fy % 1.0) * ly) as f32, z as f32],
                [0.0, 0.0, dz as f32],
            );
            let h = self.accel.closest_hit(&ray);
            if !h.is_hit() {
                continue;
            }
            let itf = &self.sample.interfaces[self.owner[h.prim as usize] as usize];
            let facing_front = (f64::from(h.ng[2]) * dz) < 0.0;
            let m = if facing_front { itf.front } else { itf.back };
            if let Some(f) = found
                && f != m
            {
                return Err(SceneError::Geometry(format!(
                    "the sample's {} side is not one medium ('{}' and '{}'); run goniospec check",
                    if above { "upper" } else { "lower" },
                    self.sample.media[f].name,
                    self.sample.media[m].name
                )));
            }
            found = Some(m);
        }
        found.ok_or_else(|| {
            SceneError::Geometry(format!(
                "vertical rays from {} miss the sample: no sheet covers the tile",
                if above { "above" } else { "below" }
            ))
        })
    }

    pub fn backend(&self) -> Backend {
        self.accel.backend()
    }
}

/// Drops every field the ray carries (`cur`, lanes from `first`) by a limit or a leak.
fn drop_all(cur: &[Option<[Field; 2]>], first: usize, opl: C64, trees: &mut [Tree]) {
    for (k, f) in cur.iter().enumerate() {
        if let Some(e) = f {
            trees[first + k].drop_field(e, opl, true);
        }
    }
}

/// One wavelength of a spectral trace: every medium's complex index there and the
/// wavelength (nm).
#[derive(Clone, Copy, Debug)]
pub struct Lane<'a> {
    pub indices: &'a [C64],
    pub lambda_nm: f64,
}

/// `RayState::lane` of a ray that carries every lane.
const ALL: u32 = u32::MAX;

/// A tracer's reusable state: rays in flight, the fields of shared rays (a stack parallel
/// to the rays': one field pair per lane, `None` where that lane dropped it), and
/// scratch.
#[derive(Default)]
pub struct TraceStack {
    rays: Vec<RayState>,
    fields: Vec<Option<[Field; 2]>>,
    cur: Vec<Option<[Field; 2]>>,
    splits: Vec<LaneSplit>,
    /// Per medium: whether its index differs between the lanes.
    varies: Vec<bool>,
    /// Free paths and scattering directions in particle media, and Russian roulette
    /// ([`TraceStack::set_stream`]).
    rng: Rng,
    /// Coherence groups handed out in this tree (random events start one each).
    groups: u32,
}

impl TraceStack {
    /// Seeds the random stream volume scattering draws from (the driver gives every tree
    /// and wavelength its own, so results do not depend on scheduling). Tracing without
    /// particle media draws nothing.
    pub fn set_stream(&mut self, seed: u64, stream: u64) {
        self.rng = Rng::new(seed, stream);
    }

    fn clear(&mut self) {
        self.rays.clear();
        self.fields.clear();
        self.cur.clear();
        self.varies.clear();
        self.groups = 0;
    }
}

/// [`Exit::path`] of a launched ray (the FNV-1a offset basis; each event is mixed in as
/// FNV-1a mixes a byte, `(h ^ x) * 0x100000001b3`).
const PATH_START: u64 = 0xCBF2_9CE4_8422_2325;

/// One lane's split at an interface: the children's directions and complex index
/// vectors, and their fields of the two polarisations.
#[derive(Default)]
struct LaneSplit {
    dir_r: DVec3,
    n_r: (DVec3, DVec3),
    dir_t: Option<DVec3>,
    n_t: (DVec3, DVec3),
    er: [Field; 2],
    et: [Field; 2],
    /// The wave a thin film hands on from its far face ([`super::film`]), where one does.
    dir_t2: Option<DVec3>,
    n_t2: (DVec3, DVec3),
    et2: [Field; 2],
}

/// A ray in flight.
#[derive(Clone, Copy, Debug)]
struct RayState {
    pos: DVec3,
    /// Unit direction of travel: the real part of the index vector, normalised.
    dir: DVec3,
    /// Complex index vector of the ray's plane wave (`optics::fresnel`): real part and
    /// imaginary part (the latter normal to the interface the wave entered through).
    n_re: DVec3,
    n_im: DVec3,
    /// Unwrapped offset of the current tile copy, nm.
    off: [f64; 2],
    medium: usize,
    opl: C64,
    depth: u32,
    /// The lane it carries, or [`ALL`].
    lane: u32,
    /// A single lane's ray: its field of each polarisation.
    e: [Field; 2],
    /// A shared ray: where its fields (one pair per lane) start on the field stack.
    at: u32,
    /// Coherence group ([`Exit::group`]).
    group: u32,
    /// Cross-section of the ray's tube relative to the launched one ([`Exit::tube`]).
    tube: f64,
    /// The facets it met and how (reflected or transmitted), hashed ([`Exit::path`]).
    path: u64,
    /// Ended by Russian roulette: popped and discarded.
    killed: bool,
    /// The product of the recombination weights of the events the ray came through
    /// ([`recombination_weight`]; 1 where every event kept its exact amplitudes): its
    /// exit's inhomogeneity is scaled by it ([`Exit::n_im`]), so the partial waves of
    /// energy-limited events (ridge tips, flake edges) are not recombined by the estimator
    /// either.
    coherent: f64,
    /// The normal of the facet at which the wave was made, its last interface event (zero
    /// for a launched ray): [`event_weights`].
    last_facet: DVec3,
    /// Light of a volume event whose straight escape next-event estimation counted
    /// (`escape`): set at the event, kept through clear layers, cleared where the ray
    /// enters a scattering medium again; such a ray leaving through the top is not
    /// counted a second time.
    nee: bool,
}

/// The two launched fields for a wave travelling along `d` (unit): s (perpendicular to the
/// plane of incidence) and p, each of unit power, in the frame of
/// [`crate::optics::mueller::frame`].
pub fn launch_fields(d: DVec3) -> [Field; 2] {
    let (p, s) = crate::optics::mueller::frame(d);
    let f = |v: DVec3| v.to_array().map(|x| C64::new(x, 0.0));
    [f(s), f(p)]
}
