//! Ray–triangle acceleration behind one interface: Embree through FFI, or obvhs (CWBVH) in
//! pure Rust, chosen at run time.
//!
//! The accelerator works in f32, as both libraries do. The tracer refines every hit in f64
//! against the hit triangle's plane (docs/design.md §1), so the accelerator only has to find the
//! right triangle; distances and barycentrics here are for that search, not for phase.
//!
//! Hot-path rules: [`Intersector::closest_hit`] and [`Intersector::closest_hits`] allocate
//! nothing and never return `Result`; [`Accel`] is an enum so the inner loop dispatches by
//! `match`, not through a vtable.

pub mod brute;
pub mod cwbvh;
#[cfg(embree)]
pub mod embree;
#[cfg(embree)]
pub(crate) mod embree_sys;
pub mod workload;

use std::fmt;
use std::str::FromStr;

/// Primitive id of a miss.
pub const INVALID_PRIM: u32 = u32::MAX;

pub use crate::geom::{SoupError, TriangleSoup};

/// A ray segment `origin + t * dir` for `t` in `[tmin, tmax]`. `dir` need not be unit
/// length; `t` is measured in multiples of it. Laid out like the first half of Embree's
/// `RTCRay` so batches can be converted cheaply.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    pub origin: [f32; 3],
    pub tmin: f32,
    pub dir: [f32; 3],
    pub tmax: f32,
}

impl Ray {
    pub fn new(origin: [f32; 3], dir: [f32; 3]) -> Self {
        Ray {
            origin,
            tmin: 0.0,
            dir,
            tmax: f32::INFINITY,
        }
    }
}

/// The closest hit of a ray, or a miss (`prim == INVALID_PRIM`).
///
/// The hit point is `(1 - u - v) v0 + u v1 + v v2` (Embree's convention). `ng` is the unit
/// geometric normal `normalize((v1 - v0) x (v2 - v0))`, whichever side the ray came from.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f32,
    pub prim: u32,
    pub u: f32,
    pub v: f32,
    pub ng: [f32; 3],
}

impl Hit {
    pub const MISS: Hit = Hit {
        t: f32::INFINITY,
        prim: INVALID_PRIM,
        u: 0.0,
        v: 0.0,
        ng: [0.0; 3],
    };

    #[inline]
    pub fn is_hit(&self) -> bool {
        self.prim != INVALID_PRIM
    }
}

impl Default for Hit {
    fn default() -> Self {
        Hit::MISS
    }
}

/// The closest-hit query every backend answers.
pub trait Intersector: Send + Sync {
    /// The closest hit of `ray` with `t` in `[ray.tmin, ray.tmax]`, or [`Hit::MISS`].
    fn closest_hit(&self, ray: &Ray) -> Hit;

    /// The closest hits of many rays at once (`hits[i]` for `rays[i]`). Backends may use
    /// packets; callers get the best speed by ordering rays coherently (by position, then
    /// direction) before the call.
    ///
    /// # Panics
    /// When `rays` and `hits` differ in length.
    fn closest_hits(&self, rays: &[Ray], hits: &mut [Hit]) {
        assert_eq!(rays.len(), hits.len(), "one hit slot per ray");
        for (r, h) in rays.iter().zip(hits.iter_mut()) {
            *h = self.closest_hit(r);
        }
    }

    /// Number of triangles in the structure.
    fn triangle_count(&self) -> usize;
}

/// Which accelerator to use.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Backend {
    /// Intel Embree, through FFI (the faster one; needs the system library).
    Embree,
    /// obvhs compressed wide BVH (CWBVH), pure Rust.
    Obvhs,
}

impl Backend {
    pub const ALL: [Backend; 2] = [Backend::Embree, Backend::Obvhs];

    pub fn name(self) -> &'static str {
        match self {
            Backend::Embree => "embree",
            Backend::Obvhs => "obvhs",
        }
    }

    /// Whether this build can use the backend.
    pub fn is_available(self) -> bool {
        match self {
            Backend::Embree => cfg!(embree),
            Backend::Obvhs => true,
        }
    }

    /// Embree where it is available, else obvhs.
    pub fn default_available() -> Backend {
        if Backend::Embree.is_available() {
            Backend::Embree
        } else {
            Backend::Obvhs
        }
    }
}

impl fmt::Display for Backend {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Backend {
    type Err = AccelError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.to_ascii_lowercase().as_str() {
            "embree" => Ok(Backend::Embree),
            "obvhs" => Ok(Backend::Obvhs),
            other => Err(AccelError::UnknownBackend(other.to_string())),
        }
    }
}

/// What went wrong while building an accelerator.
#[derive(Debug, thiserror::Error)]
pub enum AccelError {
    #[error("unknown backend '{0}' (choose embree or obvhs)")]
    UnknownBackend(String),
    #[error(
        "the embree backend is not available in this build (Embree headers were not found at build time; on Debian: apt-get install -y libembree-dev libclang-dev pkg-config, then rebuild)"
    )]
    EmbreeUnavailable,
    #[error("invalid accelerator input: {0}")]
    InvalidInput(String),
    #[error("the mesh has no triangles")]
    Empty,
    #[cfg(embree)]
    #[error(transparent)]
    Embree(#[from] embree::EmbreeError),
}

/// A built accelerator of either backend. An enum rather than a trait object so the
/// per-ray call is a `match`.
pub enum Accel {
    #[cfg(embree)]
    Embree(embree::EmbreeScene),
    Obvhs(cwbvh::ObvhsScene),
}

impl Accel {
    /// Builds the chosen backend over `soup`.
    pub fn build(backend: Backend, soup: &TriangleSoup) -> Result<Accel, AccelError> {
        soup.validate()
            .map_err(|e| AccelError::InvalidInput(e.to_string()))?;
        if soup.triangles.is_empty() {
            return Err(AccelError::Empty);
        }
        match backend {
            #[cfg(embree)]
            Backend::Embree => Ok(Accel::Embree(embree::EmbreeScene::build(soup)?)),
            #[cfg(not(embree))]
            Backend::Embree => Err(AccelError::EmbreeUnavailable),
            Backend::Obvhs => Ok(Accel::Obvhs(cwbvh::ObvhsScene::build(soup))),
        }
    }

    pub fn backend(&self) -> Backend {
        match self {
            #[cfg(embree)]
            Accel::Embree(_) => Backend::Embree,
            Accel::Obvhs(_) => Backend::Obvhs,
        }
    }
}

impl Intersector for Accel {
    #[inline]
    fn closest_hit(&self, ray: &Ray) -> Hit {
        match self {
            #[cfg(embree)]
            Accel::Embree(s) => s.closest_hit(ray),
            Accel::Obvhs(s) => s.closest_hit(ray),
        }
    }

    fn closest_hits(&self, rays: &[Ray], hits: &mut [Hit]) {
        match self {
            #[cfg(embree)]
            Accel::Embree(s) => s.closest_hits(rays, hits),
            Accel::Obvhs(s) => s.closest_hits(rays, hits),
        }
    }

    fn triangle_count(&self) -> usize {
        match self {
            #[cfg(embree)]
            Accel::Embree(s) => s.triangle_count(),
            Accel::Obvhs(s) => s.triangle_count(),
        }
    }
}

/// A backend this build offers, with the version of the library behind it.
#[derive(Clone, Debug)]
pub struct BackendInfo {
    pub backend: Backend,
    /// For example "3.13.5".
    pub version: String,
    /// Extra facts worth printing (the header the bindings came from).
    pub detail: String,
}

/// The backends this build offers, Embree first when present. Embree's version is read
/// from a live device, so a missing or broken shared library shows up here.
pub fn available_backends() -> Vec<Result<BackendInfo, String>> {
    #[cfg(embree)]
    let embree = embree::Device::new("")
        .map(|d| BackendInfo {
            backend: Backend::Embree,
            version: d.version().to_string(),
            detail: format!(
                "FFI, bindings from {}",
                option_env!("GONIOSPEC_EMBREE_HEADER").unwrap_or("?")
            ),
        })
        .map_err(|e| format!("embree: {e}"));
    #[cfg(not(embree))]
    let embree = Err(
        "embree: not built in (headers not found at build time; apt-get install -y libembree-dev libclang-dev pkg-config, then rebuild)".to_string(),
    );
    vec![
        embree,
        Ok(BackendInfo {
            backend: Backend::Obvhs,
            version: cwbvh::OBVHS_VERSION.to_string(),
            detail: "pure Rust, CWBVH (Ylitie et al. 2017)".to_string(),
        }),
    ]
}
