//! References computed from a sample, independent of the ray tracer: the transfer-matrix
//! result of a flat `[stack]` ([`stack`]) and the local-film (tangent-plane) reference of
//! curved and wedged films ([`local_film`]). They sit above `sample` and `accel`, which
//! they read; `optics` below them holds only the physics of plane waves and interfaces.

pub mod local_film;
pub mod stack;

pub use stack::{analytic, stack_indices};
