//! References computed from a sample, independent of the ray tracer: the transfer-matrix
//! result of a flat `[stack]` ([`stack`]) and the local-film (tangent-plane) reference of
//! curved and wedged films ([`local_film`]). They sit above `sample` and `accel`, which
//! they read; `optics` below them holds only the physics of plane waves and interfaces.

/// What a reference cannot compute: a sample that is not a flat [stack] or a two-sheet film, an angle or wavelength out of range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReferenceError {
    /// The message says what and where.
    #[error("{0}")]
    Invalid(String),
}

message_error!(ReferenceError, ReferenceError::Invalid);
pub mod grating;
pub mod local_film;
pub mod rigorous;
pub mod stack;

pub use stack::{analytic, stack_indices};
