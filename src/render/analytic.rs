//! The analytic reference image of a flat `[stack]` sample: its specular reflection handled
//! exactly. Under an environment the pixel is `R_TMM(theta_o) L_env(r)` with `r` the
//! mirror direction (the light, a delta direction, contributes nothing to a delta lobe).

use super::{Env, Image, RenderConfig, RenderError, Shape, colour};
use crate::brdf::Meta;
use crate::optics::tmm::{solve, solve_band};
use crate::sample::Sample;

/// Renders the stack's exact specular reflection with the same camera and environment,
/// in the wavelength cells of `meta`: a bin's reflectance averaged over the bin (Simpson,
/// [`solve_band`]), an exact wavelength's at that wavelength.
pub fn stack_image(
    s: &Sample,
    meta: &Meta,
    shape: &Shape,
    cfg: &RenderConfig,
) -> Result<Image, RenderError> {
    if s.stack.is_none() {
        return Err(RenderError::from(format!(
            "{} is not written as a [stack]",
            s.path.display()
        )));
    }
    let sampling = meta.sampling();
    let nl = sampling.count();
    for &l in &[sampling.min(), sampling.max()] {
        crate::reference::stack_indices(s, l).map_err(|e| RenderError::from(e.to_string()))?;
    }
    let stack_at =
        |l: f64| crate::reference::stack_indices(s, l).expect("checked at the band edges");
    let centres_nm = sampling.centres();
    // R(theta_o) per bin on a fine angle table.
    let n_t = 180;
    let table: Vec<Vec<f64>> = (0..n_t)
        .map(|k| {
            let th = (k as f64 + 0.5) / n_t as f64 * std::f64::consts::FRAC_PI_2;
            (0..nl)
                .map(|j| match sampling.band(j) {
                    (lo, hi) if lo < hi => solve_band(stack_at, lo, hi, th).r(),
                    (l, _) => solve(&stack_at(l), l, th).r(),
                })
                .collect()
        })
        .collect();
    let weights = colour::bin_weights(&centres_nm);
    let cam = super::camera_frame(shape, cfg);
    let mut img = Image {
        width: cfg.width,
        height: cfg.height,
        rgb: Vec::new(),
        spectra: Vec::new(),
        bins: nl,
    };
    for y in 0..cfg.height {
        for x in 0..cfg.width {
            // Pixel centre (the reference needs no anti-aliasing noise).
            let d = cam.ray(cfg, x as f64 + 0.5, y as f64 + 0.5);
            let mut spec = vec![0.0; nl];
            if let Some((_, n)) = shape.hit(cfg.camera, d) {
                let cos_o = -d.dot(n);
                if cos_o > 0.0 {
                    let k = ((cos_o.min(1.0).acos() / std::f64::consts::FRAC_PI_2) * n_t as f64)
                        as usize;
                    let r = d + (n * (2.0 * cos_o));
                    let l = match cfg.env {
                        Env::None => 0.0,
                        Env::Constant => 1.0,
                        Env::Sky => 0.25 + 0.75 * r[2].max(0.0),
                    };
                    for (s, v) in spec.iter_mut().zip(&table[k.min(n_t - 1)]) {
                        *s = cfg.env_strength * l * v;
                    }
                }
            }
            img.rgb
                .push(colour::xyz_to_linear_srgb(colour::xyz(&spec, &weights)).map(|c| c as f32));
            img.spectra.extend(spec.iter().map(|&v| v as f32));
        }
    }
    Ok(img)
}

/// How far an image is from a reference.
#[derive(Clone, Copy, Debug)]
pub struct Difference {
    /// RMS of the per-pixel spectral difference over the RMS of the reference.
    pub rel_rmse: f64,
    /// Mean CIE DE2000 over object pixels (colours relative to the D65 white).
    pub mean_de2000: f64,
    pub pixels: usize,
}

/// Compares two images of the same size over the pixels where the reference is non-black.
pub fn compare(img: &Image, reference: &Image) -> Difference {
    let white = colour::white_xyz();
    let nl = img.bins;
    let weights_rgb_to_xyz = |c: [f32; 3]| -> [f64; 3] {
        // Inverse of the sRGB matrix (IEC 61966-2-1).
        let (r, g, b) = (f64::from(c[0]), f64::from(c[1]), f64::from(c[2]));
        [
            0.4124 * r + 0.3576 * g + 0.1805 * b,
            0.2126 * r + 0.7152 * g + 0.0722 * b,
            0.0193 * r + 0.1192 * g + 0.9505 * b,
        ]
    };
    let (mut num, mut den, mut de, mut n) = (0.0, 0.0, 0.0, 0usize);
    for p in 0..reference.rgb.len() {
        let rs = &reference.spectra[p * nl..(p + 1) * nl];
        if rs.iter().all(|&v| v == 0.0) {
            continue;
        }
        let is = &img.spectra[p * nl..(p + 1) * nl];
        for (a, b) in is.iter().zip(rs) {
            num += f64::from(a - b).powi(2);
            den += f64::from(*b).powi(2);
        }
        let (l1, l2) = (
            colour::lab(weights_rgb_to_xyz(img.rgb[p]), white),
            colour::lab(weights_rgb_to_xyz(reference.rgb[p]), white),
        );
        de += colour::delta_e2000(l1, l2);
        n += 1;
    }
    Difference {
        rel_rmse: if den > 0.0 { (num / den).sqrt() } else { 0.0 },
        mean_de2000: if n > 0 { de / n as f64 } else { 0.0 },
        pixels: n,
    }
}
