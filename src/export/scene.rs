//! Scenes for Mitsuba 3 and pbrt-v4 that show an exported material as `goniospec render`
//! shows it: the same shape, camera, light, environment and units (docs/design.md §10).
//!
//! `goniospec render` works in radiance factors relative to illuminant D65: a light of
//! strength `s` puts an irradiance of `pi s` (times D65) on a surface facing it, so that a
//! white Lambertian surface there has radiance factor `s`; a constant environment of
//! strength `e` has radiance `e` (times D65) in every direction. Both renderers normalise
//! their D65 so that a unit radiance renders as white (1, 1, 1) in linear sRGB:
//!
//! - Mitsuba 3: `d65` spectra with `scale` (the `directional` emitter's `irradiance` is
//!   `pi s`; the `constant` emitter's `radiance` is `e`; a point light's `intensity` is
//!   `pi s |q|^2`, its strength being `s` at the distance of the origin);
//! - pbrt-v4: `"spectrum L" "stdillum D65"`, which its lights divide by the spectrum's
//!   luminance (`SpectrumToPhotometric`, `src/pbrt/lights.cpp`) so that `scale` is in nits:
//!   the `distant` light's `scale` is `pi s`, the `infinite` light's `e`, the `point`
//!   light's `pi s |q|^2`; the `rgb` film's default sensor (`cie1931`, ISO 100, exposure
//!   1 s) maps one nit of D65 to white.
//!
//! The camera looks from `RenderConfig::camera` at the shape's centre with z up (y where it
//! looks along z), with the vertical field of view; both renderers take the material's
//! `.bsdf` in their `measured` BSDF. goniospec's sky environment has no counterpart in
//! either renderer's constant lights and is refused.

use super::ExportError;
use crate::render::{Env, Light, RenderConfig};
use glam::DVec3;

/// The words every scene this module writes carries in its first lines, by which the output
/// policy knows it may replace one (`output::OutputKind::Scene`).
pub const MARK: &str = "Written by goniospec export";

/// The shapes a scene can hold: those of `goniospec render` with a closed form in both
/// renderers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SceneShape {
    /// Radius 1 at the origin.
    Sphere,
    /// The square `[-1, 1]^2` at z = 0, facing +z.
    Plane,
}

impl SceneShape {
    /// The centre the camera looks at.
    fn centre(self) -> DVec3 {
        DVec3::ZERO
    }
}

/// The camera's up vector for `cfg` looking at `centre`: z, or y where it looks along z
/// (`render::camera_frame`).
fn up(cfg: &RenderConfig, centre: DVec3) -> DVec3 {
    let fwd = (centre - cfg.camera).normalize();
    if fwd.z.abs() > 0.99 {
        DVec3::Y
    } else {
        DVec3::Z
    }
}

fn refuse_sky(cfg: &RenderConfig) -> Result<(), ExportError> {
    if cfg.env == Env::Sky {
        return Err(ExportError::from(
            "--env sky has no counterpart among Mitsuba's and pbrt-v4's constant lights: use --env constant or none for an exported scene",
        ));
    }
    if cfg.camera.is_nan() || !(cfg.fov_deg > 0.0 && cfg.fov_deg < 180.0) {
        return Err(ExportError::from(
            "the camera must be finite with a field of view in (0, 180) degrees",
        ));
    }
    Ok(())
}

/// Three numbers as `x, y, z` (Mitsuba) or `x y z` (pbrt), written exactly enough to
/// read back the same f64 (Rust's shortest round-trip form).
fn triple(v: DVec3, sep: &str) -> String {
    format!("{:?}{sep}{:?}{sep}{:?}", v.x, v.y, v.z)
}

/// A Mitsuba 3 scene (XML, `<scene version="3.0.0">`) of `shape` made of the RGL file
/// `bsdf_file` (a path as the scene should name it), seen and lit as `cfg` says; the
/// `direct` integrator, an `independent` sampler of `cfg.spp` samples and an RGB
/// `hdrfilm` with a box filter.
pub fn mitsuba_xml(
    cfg: &RenderConfig,
    shape: SceneShape,
    bsdf_file: &str,
) -> Result<String, ExportError> {
    refuse_sky(cfg)?;
    let centre = shape.centre();
    let pi = std::f64::consts::PI;
    let mut s = String::new();
    s += "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n";
    s += "<!-- Written by goniospec export: the view of `goniospec render` with the same flags\n";
    s += "     (radiance factors relative to D65; README, \"Using a material in Mitsuba 3 or pbrt-v4\"). -->\n";
    s += "<scene version=\"3.0.0\">\n";
    // goniospec draws the background black: the environment lights the object only.
    s += "    <integrator type=\"direct\">\n        <boolean name=\"hide_emitters\" value=\"true\"/>\n    </integrator>\n";
    s += "    <sensor type=\"perspective\">\n";
    s += &format!(
        "        <float name=\"fov\" value=\"{:?}\"/>\n        <string name=\"fov_axis\" value=\"y\"/>\n",
        cfg.fov_deg
    );
    s += "        <transform name=\"to_world\">\n";
    s += &format!(
        "            <lookat origin=\"{}\" target=\"{}\" up=\"{}\"/>\n",
        triple(cfg.camera, ", "),
        triple(centre, ", "),
        triple(up(cfg, centre), ", ")
    );
    s += "        </transform>\n";
    s += &format!(
        "        <sampler type=\"independent\">\n            <integer name=\"sample_count\" value=\"{}\"/>\n            <integer name=\"seed\" value=\"{}\"/>\n        </sampler>\n",
        cfg.spp, cfg.seed
    );
    s += &format!(
        "        <film type=\"hdrfilm\">\n            <integer name=\"width\" value=\"{}\"/>\n            <integer name=\"height\" value=\"{}\"/>\n            <string name=\"pixel_format\" value=\"rgb\"/>\n            <rfilter type=\"box\"/>\n        </film>\n",
        cfg.width, cfg.height
    );
    s += "    </sensor>\n";
    match cfg.light {
        Light::None => {}
        Light::Directional(l) => {
            s += &format!(
                "    <emitter type=\"directional\">\n        <vector name=\"direction\" value=\"{}\"/>\n        <spectrum type=\"d65\" name=\"irradiance\">\n            <float name=\"scale\" value=\"{:?}\"/>\n        </spectrum>\n    </emitter>\n",
                triple(-l, ", "),
                pi * cfg.light_strength
            );
        }
        Light::Point(q) => {
            s += &format!(
                "    <emitter type=\"point\">\n        <point name=\"position\" value=\"{}\"/>\n        <spectrum type=\"d65\" name=\"intensity\">\n            <float name=\"scale\" value=\"{:?}\"/>\n        </spectrum>\n    </emitter>\n",
                triple(q, ", "),
                pi * cfg.light_strength * q.length_squared()
            );
        }
    }
    if cfg.env == Env::Constant {
        s += &format!(
            "    <emitter type=\"constant\">\n        <spectrum type=\"d65\" name=\"radiance\">\n            <float name=\"scale\" value=\"{:?}\"/>\n        </spectrum>\n    </emitter>\n",
            cfg.env_strength
        );
    }
    let bsdf = format!(
        "        <bsdf type=\"measured\">\n            <string name=\"filename\" value=\"{}\"/>\n        </bsdf>\n",
        xml_escape(bsdf_file)
    );
    match shape {
        SceneShape::Sphere => {
            s += "    <shape type=\"sphere\">\n";
        }
        SceneShape::Plane => {
            s += "    <shape type=\"rectangle\">\n";
        }
    }
    s += &bsdf;
    s += "    </shape>\n</scene>\n";
    Ok(s)
}

fn xml_escape(v: &str) -> String {
    v.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// A pbrt-v4 scene of `shape` made of the RGL file `bsdf_file`, seen and lit as `cfg`
/// says, rendering to `image_file`: `Scale -1 1 1` first (pbrt's camera space is
/// left-handed; the flip keeps the image as goniospec and Mitsuba draw it), the `path`
/// integrator limited to direct light (`maxdepth` 1, as goniospec renders), an
/// `independent` sampler and the `rgb` film. pbrt's `fov` is that of the image's shorter
/// side, so a portrait image gets the horizontal angle that matches the vertical one.
pub fn pbrt_scene(
    cfg: &RenderConfig,
    shape: SceneShape,
    bsdf_file: &str,
    image_file: &str,
) -> Result<String, ExportError> {
    refuse_sky(cfg)?;
    let centre = shape.centre();
    let pi = std::f64::consts::PI;
    let aspect = cfg.width as f64 / cfg.height as f64;
    let fov = if aspect >= 1.0 {
        cfg.fov_deg
    } else {
        2.0 * ((cfg.fov_deg.to_radians() / 2.0).tan() * aspect)
            .atan()
            .to_degrees()
    };
    let quote = |v: &str| v.replace('\\', "\\\\").replace('"', "\\\"");
    let mut s = String::new();
    s += "# Written by goniospec export: the view of `goniospec render` with the same flags\n";
    s += "# (radiance factors relative to D65; README, \"Using a material in Mitsuba 3 or pbrt-v4\").\n";
    s += "Scale -1 1 1\n";
    s += &format!(
        "LookAt {}\n       {}\n       {}\n",
        triple(cfg.camera, " "),
        triple(centre, " "),
        triple(up(cfg, centre), " ")
    );
    s += &format!("Camera \"perspective\" \"float fov\" [ {fov:?} ]\n");
    s += &format!(
        "Sampler \"independent\" \"integer pixelsamples\" [ {} ] \"integer seed\" [ {} ]\n",
        cfg.spp, cfg.seed
    );
    s += "Integrator \"path\" \"integer maxdepth\" [ 1 ]\n";
    s += &format!(
        "Film \"rgb\" \"integer xresolution\" [ {} ] \"integer yresolution\" [ {} ]\n     \"string filename\" [ \"{}\" ]\n",
        cfg.width,
        cfg.height,
        quote(image_file)
    );
    s += "WorldBegin\n";
    match cfg.light {
        Light::None => {}
        Light::Directional(l) => {
            s += &format!(
                "LightSource \"distant\" \"point3 from\" [ {} ] \"point3 to\" [ 0 0 0 ]\n    \"spectrum L\" \"stdillum-D65\" \"float scale\" [ {:?} ]\n",
                triple(l, " "),
                pi * cfg.light_strength
            );
        }
        Light::Point(q) => {
            s += &format!(
                "LightSource \"point\" \"point3 from\" [ {} ]\n    \"spectrum I\" \"stdillum-D65\" \"float scale\" [ {:?} ]\n",
                triple(q, " "),
                pi * cfg.light_strength * q.length_squared()
            );
        }
    }
    if cfg.env == Env::Constant {
        s += &format!(
            "LightSource \"infinite\" \"spectrum L\" \"stdillum-D65\" \"float scale\" [ {:?} ]\n",
            cfg.env_strength
        );
    }
    s += &format!(
        "Material \"measured\" \"string filename\" [ \"{}\" ]\n",
        quote(bsdf_file)
    );
    match shape {
        SceneShape::Sphere => s += "Shape \"sphere\" \"float radius\" [ 1 ]\n",
        SceneShape::Plane => {
            s += "Shape \"trianglemesh\" \"point3 P\" [ -1 -1 0  1 -1 0  1 1 0  -1 1 0 ]\n    \"integer indices\" [ 0 1 2  0 2 3 ]\n    \"normal N\" [ 0 0 1  0 0 1  0 0 1  0 0 1 ]\n";
        }
    }
    Ok(s)
}
