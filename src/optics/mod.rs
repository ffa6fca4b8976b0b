//! Optics: complex Fresnel amplitude coefficients, the electric-field bookkeeping at an
//! interface, propagation through absorbing media, and the transfer-matrix method as an
//! analytic reference for layered stacks.
//!
//! Conventions (docs/design.md §3): lengths and wavelengths in nanometres; a complex index is
//! `n + i k` with `k >= 0` absorbing; a field travelling a length `l` is multiplied by
//! `exp(i 2 pi (n + i k) l / lambda)`.

pub mod fresnel;
pub mod mie;
pub mod mueller;
pub mod particles;
pub mod rcwa;
pub mod tmm;

pub use num_complex::Complex64 as C64;
