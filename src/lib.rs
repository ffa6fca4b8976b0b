//! goniospec: a virtual goniospectrometer. It traces an explicit microgeometry sample
//! with coherent spectral ray optics and accumulates what leaves it into a BRDF.
//!
//! The modules follow the pipeline (see ARCHITECTURE.md):
//! [`sample`] (geometry, media) → [`accel`] (Embree, obvhs) → … → [`bench`] and the CLI.

/// `From<String>` and `From<&str>` for an error whose message variant (or tuple struct) is
/// `$path`, so a room's checks can write `Err(format!(..).into())` and `?` on a message.
macro_rules! message_error {
    ($ty:ty, $path:path) => {
        impl From<String> for $ty {
            fn from(message: String) -> Self {
                $path(message)
            }
        }

        impl From<&str> for $ty {
            fn from(message: &str) -> Self {
                $path(message.to_string())
            }
        }
    };
}

pub mod accel;
pub mod accumulate;
pub mod batch;
pub mod bench;
pub mod brdf;
pub mod check;
pub mod compare;
pub mod container;
pub mod export;
pub mod fit;
pub mod geom;
pub mod io;
pub mod machine;
pub mod optics;
pub mod output;
pub mod plot;
pub mod recipe;
pub mod reference;
pub mod render;
pub mod rng;
pub mod sample;
pub mod simulate;
pub mod spectrum;
pub mod study;
pub mod trace;
pub mod warning_codes;
