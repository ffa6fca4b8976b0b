//! Whether a sample is rotation-symmetric about its normal, so that its BRDF depends on
//! the azimuths only through `phi_o - phi_i`.
//!
//! A grating, grooves, a brushed or scanned surface, pillars on a square lattice: their
//! facets' normals lean towards a few azimuths, and light from one azimuth is not light
//! from another. What is measured is the azimuthal Fourier content of the facets' tilt:
//! with `w_k = |(a_k)_xy|` the horizontal part of facet `k`'s area vector `a_k` (its area
//! times the sine of its tilt) and `phi_k` the azimuth of that part, harmonic `m` is
//!
//! `H_m = |sum_k w_k exp(i m phi_k)| / sum_k w_k`,
//!
//! 1 for facets all leaning along one line (grooves give `H_2 = 1`, square pillars
//! `H_4 = 1`). The sheets (reliefs spanning the tile) are one deterministic surface, taken
//! as they are. Closed bodies (flakes, pigments) are placed at random spins, so theirs is
//! a random walk of phasors whose expected length is the noise `sqrt(sum_k w_k^2) /
//! sum_k w_k` (Rayleigh 1880) or more (a flake's facets turn together). The sample is
//! anisotropic where some `H_m`, `m = 1..=6`, of its sheets, or of its bodies beyond
//! [`NOISE_MULTIPLE`] times their noise, exceeds [`ANISOTROPY_THRESHOLD`]
//! (docs/design.md §4, "Incident directions"). Flat samples (no tilted facet) are
//! symmetric.

use super::Sample;

/// The harmonic strength above which facet tilts lean towards some azimuths (1: all along
/// the harmonic's directions). A GGX or Gaussian height field triangulated on a square
/// grid leans a little along the grid and stays below it (the shipped rough gold: `H_4` =
/// 0.20; rough glass `H_3` = 0.07; the scanned gold `H_2` = 0.03), gratings and grooves
/// are at 1.
pub const ANISOTROPY_THRESHOLD: f64 = 0.5;

/// How many noise levels the bodies' harmonic must exceed to count (the shipped metallic
/// paint's few tens of randomly spun flakes: `H_4` = 0.28 at a noise of 0.07).
pub const NOISE_MULTIPLE: f64 = 4.0;

/// The harmonics examined: up to 6 (hexagonal lattices).
pub const MAX_HARMONIC: u32 = 6;

/// The strongest azimuthal harmonic of a sample's facet tilts.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Anisotropy {
    /// Its order `m` (0 where no facet is tilted).
    pub harmonic: u32,
    /// `H_m`, in [0, 1].
    pub strength: f64,
    /// The strength facets of random azimuth would give, `sqrt(sum w^2) / sum w` (0 for
    /// sheets, which are one deterministic relief).
    pub noise: f64,
}

impl Anisotropy {
    /// Whether the sample's BRDF depends on the incident azimuth beyond `phi_o - phi_i`.
    pub fn anisotropic(&self) -> bool {
        self.strength > ANISOTROPY_THRESHOLD && self.strength > NOISE_MULTIPLE * self.noise
    }
}

/// The strongest azimuthal harmonic of the facet tilts of `sample`: its sheets', or its
/// closed bodies' where those count and the sheets' do not.
pub fn anisotropy(sample: &Sample) -> Anisotropy {
    let of = |closed: bool| {
        let h = harmonics(sample.interfaces.iter().filter(|i| i.closed == closed));
        if closed {
            h
        } else {
            Anisotropy { noise: 0.0, ..h }
        }
    };
    let (sheets, bodies) = (of(false), of(true));
    if !sheets.anisotropic() && bodies.anisotropic() {
        bodies
    } else {
        sheets
    }
}

/// The strongest harmonic of the facets of `interfaces`, with its noise.
fn harmonics<'a>(interfaces: impl Iterator<Item = &'a super::Interface>) -> Anisotropy {
    let (mut total, mut total_sq) = (0.0, 0.0);
    let mut sums = [[0.0f64; 2]; MAX_HARMONIC as usize];
    for itf in interfaces {
        for k in 0..itf.mesh.triangles.len() {
            let a = itf.mesh.area_vector(k);
            let w = a.x.hypot(a.y);
            if !(w.is_finite() && w > 0.0) {
                continue;
            }
            total += w;
            total_sq += w * w;
            let phi = a.y.atan2(a.x);
            for (m, s) in sums.iter_mut().enumerate() {
                let (sin, cos) = ((m + 1) as f64 * phi).sin_cos();
                s[0] += w * cos;
                s[1] += w * sin;
            }
        }
    }
    if total <= 0.0 {
        return Anisotropy {
            harmonic: 0,
            strength: 0.0,
            noise: 0.0,
        };
    }
    let (m, strength) = sums
        .iter()
        .enumerate()
        .map(|(m, s)| (m as u32 + 1, s[0].hypot(s[1]) / total))
        .fold((0, 0.0), |best, x| if x.1 > best.1 { x } else { best });
    Anisotropy {
        harmonic: m,
        strength,
        noise: total_sq.sqrt() / total,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sample::parse;

    fn sample(generator: &str) -> Sample {
        let text = format!(
            "[sample]\nname = \"t\"\nunit = \"nm\"\ntile = [1000.0, 1000.0]\n[media.air]\nn = 1.0\n[media.glass]\nn = 1.5\n[[interface]]\ngenerator = {generator}\nfront = \"air\"\nback = \"glass\"\n"
        );
        parse(std::path::Path::new("t.toml"), &text, Default::default())
            .expect("the test sample parses")
    }

    #[test]
    fn grooves_lean_along_one_line() {
        // z = A cos(2 pi x / L): every tilted facet's normal lies in the x-z plane, so
        // H_2 = 1 exactly (azimuths 0 and 180 deg).
        let a = anisotropy(&sample(
            "{ kind = \"cosine\", amplitude = 100.0, resolution = 64 }",
        ));
        assert_eq!(a.harmonic, 2, "{a:?}");
        assert!((a.strength - 1.0).abs() < 1e-9, "{a:?}");
        assert!(a.anisotropic());
    }

    #[test]
    fn shipped_samples_are_classed_as_their_structure_is() {
        // Reliefs that run along one direction (gratings, grooves, a disc's track) are
        // anisotropic; random roughness, films, coats and randomly spun flakes are not.
        let anisotropic = [
            "holographic-foil",
            "hri-hologram",
            "optical-disc-track",
            "v-grooves-aluminium",
        ];
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes");
        let mut seen = 0;
        for e in std::fs::read_dir(&dir).expect("meshes/ is shipped") {
            let p = e.expect("a directory entry").path();
            if p.extension().is_none_or(|x| x != "toml") {
                continue;
            }
            let name = p.file_stem().and_then(|s| s.to_str()).unwrap_or_default();
            let s = crate::sample::load(&p, Default::default()).expect("a shipped sample loads");
            let a = anisotropy(&s);
            assert_eq!(
                a.anisotropic(),
                anisotropic.contains(&name),
                "{name}: {a:?}"
            );
            seen += 1;
        }
        assert!(seen >= 10, "only {seen} shipped samples found");
    }

    #[test]
    fn a_flat_sample_is_symmetric() {
        let a = anisotropy(&sample("{ kind = \"flat\", z = 0.0 }"));
        assert_eq!(a.strength, 0.0);
        assert!(!a.anisotropic());
    }
}
