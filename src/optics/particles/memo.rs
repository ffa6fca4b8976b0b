//! Mie tables remembered across the runs of one process.
//!
//! A particle medium's table ([`ScatterModel::mie`](super::ScatterModel::mie)) is one
//! [`LambdaEntry`] per whole nanometre, and building them is most of a short run's time:
//! 301 entries for 400-700 nm take 0.9 s of set-up and a further second of the run on two
//! cores for the shipped white paint, where its 128 trees take 0.1 s. Commands that run
//! one sample many times (`hiding`: two backings at a dozen thicknesses; `batch` and
//! `study` over angles or recipes sharing a medium) paid that every time.
//!
//! An entry is a pure function of what [`Key`] holds: the wavelength, the size
//! distribution, the number density, the packing and the two complex indices at that
//! wavelength (`lambda_entry` evaluates the index models only there). So an entry built
//! once is the entry any later run would build, bit for bit, and remembering it changes
//! no result: runs stay byte-identical whatever ran before them in the process.
//!
//! The memory is bounded: past [`MAX_ENTRIES`] the store is emptied and refilled (a
//! table of the white paint's is about 0.3 MB an entry, so at most about 300 MB).

use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};

use super::sizes::Radius;
use super::{C64, LambdaEntry, Packing, ParticleError};

/// Entries kept before the store is emptied: three media over 400-700 nm.
pub const MAX_ENTRIES: usize = 1024;

/// Everything a [`LambdaEntry`] depends on, as bits (so `-0.0` and `0.0`, or two NaNs,
/// are different keys: a miss, never a wrong hit).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(super) struct Key([u64; 11]);

impl Key {
    pub(super) fn new(
        lambda_nm: f64,
        radius: Radius,
        density: f64,
        packing: Option<Packing>,
        host: C64,
        particle: C64,
    ) -> Key {
        let (kind, a, b) = match radius {
            Radius::Fixed { radius_nm } => (0, radius_nm, 0.0),
            Radius::LogNormal { median_nm, sigma } => (1, median_nm, sigma),
        };
        // No packing: a volume fraction no packed medium has.
        let (f, d) = packing.map_or((-1.0, -1.0), |p| (p.f, p.d_nm));
        let bits = [
            lambda_nm,
            a,
            b,
            density,
            f,
            d,
            host.re,
            host.im,
            particle.re,
            particle.im,
        ]
        .map(f64::to_bits);
        let mut k = [kind; 11];
        k[1..].copy_from_slice(&bits);
        Key(k)
    }
}

fn store() -> &'static Mutex<HashMap<Key, Arc<LambdaEntry>>> {
    static STORE: OnceLock<Mutex<HashMap<Key, Arc<LambdaEntry>>>> = OnceLock::new();
    STORE.get_or_init(|| Mutex::new(HashMap::new()))
}

/// The entry for `key`, built by `build` unless an earlier run built it. Errors are not
/// remembered (they are cheap and say where they arose). Two threads asking for the same
/// missing key may both build it; the results are identical, and the first stored wins.
pub(super) fn entry(
    key: Key,
    build: impl FnOnce() -> Result<LambdaEntry, ParticleError>,
) -> Result<Arc<LambdaEntry>, ParticleError> {
    // A poisoned lock only means another thread panicked while holding it; the map
    // itself is always whole (inserts and clears are single calls).
    let lock = || store().lock().unwrap_or_else(|p| p.into_inner());
    if let Some(e) = lock().get(&key) {
        return Ok(e.clone());
    }
    let built = Arc::new(build()?);
    let mut map = lock();
    if map.len() >= MAX_ENTRIES {
        map.clear();
    }
    Ok(map.entry(key).or_insert(built).clone())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Keys differ in every field they hold, and the same inputs give the same key.
    #[test]
    fn keys_tell_every_input_apart() {
        let r = Radius::LogNormal {
            median_nm: 120.0,
            sigma: 0.25,
        };
        let p = Some(Packing {
            f: 0.1,
            d_nm: 260.0,
        });
        let n = C64::new(1.49, 0.0);
        let m = C64::new(2.7, 0.01);
        let base = Key::new(550.0, r, 1e-8, p, n, m);
        assert_eq!(base, Key::new(550.0, r, 1e-8, p, n, m));
        let others = [
            Key::new(551.0, r, 1e-8, p, n, m),
            Key::new(550.0, Radius::Fixed { radius_nm: 120.0 }, 1e-8, p, n, m),
            Key::new(
                550.0,
                Radius::LogNormal {
                    median_nm: 120.0,
                    sigma: 0.3,
                },
                1e-8,
                p,
                n,
                m,
            ),
            Key::new(550.0, r, 2e-8, p, n, m),
            Key::new(550.0, r, 1e-8, None, n, m),
            Key::new(550.0, r, 1e-8, p, C64::new(1.5, 0.0), m),
            Key::new(550.0, r, 1e-8, p, n, C64::new(2.7, 0.02)),
        ];
        for o in others {
            assert_ne!(base, o);
        }
    }

    /// An entry is built once per key: a second run asking for it gets the same table
    /// without building (the builder is not called), and the table equals a fresh build's
    /// (the key holds everything the entry depends on).
    #[test]
    fn an_entry_is_built_once_and_equals_a_fresh_build() {
        let r = Radius::Fixed { radius_nm: 150.0 };
        let (nh, np) = (C64::new(1.5, 0.0), C64::new(2.0, 0.0));
        let build = || super::super::lambda_entry(612.0, r, 1e-9, None, &|_| nh, &|_| np);
        let key = Key::new(612.0, r, 1e-9, None, nh, np);
        let first = entry(key, build).unwrap();
        let second = entry(key, || panic!("built again")).unwrap();
        assert!(Arc::ptr_eq(&first, &second));
        let fresh = build().unwrap();
        assert_eq!(first.mu_ext_per_nm.to_bits(), fresh.mu_ext_per_nm.to_bits());
        assert_eq!(first.albedo.to_bits(), fresh.albedo.to_bits());
        assert_eq!(first.g.to_bits(), fresh.g.to_bits());
        assert_eq!(first.size_cdf, fresh.size_cdf);
    }
}
