//! A fit written for renderers: the parameter sets as JSON (the fit itself, OpenPBR,
//! Standard Surface) and a glTF 2.0 material (`KHR_materials_iridescence`,
//! `KHR_materials_ior`, `KHR_materials_clearcoat`).

use std::path::Path;

use super::{Base, Data, Film, Fit, reflectance};
use crate::render::colour;

/// The base's reflectance at normal incidence as linear sRGB under D65 (glTF baseColor of
/// a metal), and its mean real index (dielectric `ior`).
fn base_colour(fit: &Fit, data: &Data) -> [f64; 3] {
    let weights = colour::bin_weights(&data.lambda_nm);
    let white = colour::xyz(&vec![1.0; data.lambda_nm.len()], &weights);
    let f0: Vec<f64> = data
        .lambda_nm
        .iter()
        .enumerate()
        .map(|(j, &l)| reflectance(&fit.base, None, 0.0, l, j))
        .collect();
    let x = colour::xyz(&f0, &weights);
    let w = white[1].max(1e-300);
    colour::xyz_to_linear_srgb([x[0] / w, x[1] / w, x[2] / w]).map(|v| v.clamp(0.0, 1.0))
}

/// Metalness (0 or 1) and the real index a renderer's `ior` takes: the dielectric's, or a
/// conductor's mean real part.
fn metal_and_ior(fit: &Fit) -> (f64, f64) {
    match &fit.base {
        Base::Dielectric { n } => (0.0, *n),
        Base::Conductor { n } => (1.0, n.iter().map(|c| c.re).sum::<f64>() / n.len() as f64),
    }
}

/// The parameter sets as JSON: the fit, OpenPBR (`thin_film_thickness` in um) and Standard
/// Surface (`thin_film_thickness` in nm).
pub fn to_json(fit: &Fit, data: &Data) -> serde_json::Value {
    use serde_json::json;
    let roughness = fit.alpha.sqrt();
    let colour = base_colour(fit, data);
    let (metal, ior) = metal_and_ior(fit);
    let film = fit.film.unwrap_or(Film {
        thickness_nm: 0.0,
        n: 1.5,
        weight: 0.0,
    });
    json!({
        "fit": {
            "ggx_alpha": fit.alpha,
            "base": match &fit.base {
                Base::Dielectric { n } => json!({"kind": "dielectric", "ior": n}),
                Base::Conductor { n } => json!({
                    "kind": "conductor",
                    "lambda_nm": data.lambda_nm,
                    "n": n.iter().map(|c| c.re).collect::<Vec<_>>(),
                    "k": n.iter().map(|c| c.im).collect::<Vec<_>>(),
                    "f0_linear_srgb": colour,
                }),
            },
            "film": fit.film.map(|f| json!({"thickness_nm": f.thickness_nm, "ior": f.n, "weight": f.weight})),
            "coat": fit.coat.map(|c| json!({"ior": c.ior, "ggx_alpha": c.alpha, "weight": 1.0})),
            "rms_reflectance_error": fit.rms_residual,
            "delta_e2000_per_incident_angle": fit.delta_e2000,
            "theta_i_deg": data.theta_i_rad.iter().map(|t| t.to_degrees()).collect::<Vec<_>>(),
            "warnings": fit.warnings,
        },
        "openpbr": {
            "base_weight": 1.0,
            "base_color": if metal > 0.0 { colour } else { [0.0, 0.0, 0.0] },
            "base_metalness": metal,
            "specular_weight": 1.0,
            "specular_color": [1.0, 1.0, 1.0],
            "specular_roughness": roughness,
            "specular_ior": ior,
            "thin_film_weight": film.weight,
            "thin_film_thickness": film.thickness_nm / 1000.0,
            "thin_film_ior": film.n,
            "coat_weight": if fit.coat.is_some() { 1.0 } else { 0.0 },
            "coat_color": [1.0, 1.0, 1.0],
            "coat_roughness": fit.coat.map_or(0.0, |c| c.alpha.sqrt()),
            "coat_ior": fit.coat.map_or(1.6, |c| c.ior),
        },
        "standard_surface": {
            "base": 1.0,
            "base_color": if metal > 0.0 { colour } else { [0.0, 0.0, 0.0] },
            "metalness": metal,
            "specular": 1.0,
            "specular_color": [1.0, 1.0, 1.0],
            "specular_roughness": roughness,
            "specular_IOR": ior,
            "thin_film_thickness": film.thickness_nm * film.weight.signum(),
            "thin_film_IOR": film.n,
            "coat": if fit.coat.is_some() { 1.0 } else { 0.0 },
            "coat_color": [1.0, 1.0, 1.0],
            "coat_roughness": fit.coat.map_or(0.1, |c| c.alpha.sqrt()),
            "coat_IOR": fit.coat.map_or(1.5, |c| c.ior),
        },
    })
}

/// A glTF 2.0 file with a UV sphere carrying the fitted material (`KHR_materials_ior`, and
/// `KHR_materials_iridescence` with the film), its geometry in an embedded base64 buffer.
pub fn to_gltf(fit: &Fit, data: &Data, name: &str) -> serde_json::Value {
    use serde_json::json;
    let (stacks, slices) = (24usize, 48usize);
    let (mut pos, mut nrm, mut idx) = (Vec::<f32>::new(), Vec::<f32>::new(), Vec::<u16>::new());
    for s in 0..=stacks {
        let t = std::f64::consts::PI * s as f64 / stacks as f64;
        for k in 0..=slices {
            let p = std::f64::consts::TAU * k as f64 / slices as f64;
            let v = [t.sin() * p.cos(), t.cos(), t.sin() * p.sin()];
            pos.extend(v.map(|c| c as f32));
            nrm.extend(v.map(|c| c as f32));
        }
    }
    for s in 0..stacks {
        for k in 0..slices {
            let a = (s * (slices + 1) + k) as u16;
            let b = a + (slices + 1) as u16;
            idx.extend([a, a + 1, b, a + 1, b + 1, b]);
        }
    }
    let mut bytes = Vec::new();
    for v in pos.iter().chain(&nrm) {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    for i in &idx {
        bytes.extend_from_slice(&i.to_le_bytes());
    }
    while bytes.len() % 4 != 0 {
        bytes.push(0);
    }
    let nv = pos.len() / 3;
    let vb = nv * 12;
    let colour = base_colour(fit, data);
    let (metal, ior) = metal_and_ior(fit);
    let mut ext = json!({ "KHR_materials_ior": { "ior": ior.max(1.0) } });
    let mut used = vec!["KHR_materials_ior"];
    if let Some(f) = fit.film {
        ext["KHR_materials_iridescence"] = json!({
            "iridescenceFactor": f.weight,
            "iridescenceIor": f.n,
            // Without a thickness texture the maximum is the film's thickness (the minimum
            // only applies to a texture).
            "iridescenceThicknessMaximum": f.thickness_nm,
        });
        used.push("KHR_materials_iridescence");
    }
    if let Some(c) = fit.coat {
        // glTF's clear coat has index 1.5 (KHR_materials_clearcoat); the fitted index is in
        // the JSON.
        ext["KHR_materials_clearcoat"] = json!({
            "clearcoatFactor": 1.0,
            "clearcoatRoughnessFactor": c.alpha.sqrt().clamp(0.0, 1.0),
        });
        used.push("KHR_materials_clearcoat");
    }
    json!({
        "asset": { "version": "2.0", "generator": "goniospec fit" },
        "extensionsUsed": used,
        "scene": 0,
        "scenes": [ { "nodes": [0] } ],
        "nodes": [ { "mesh": 0, "name": name } ],
        "meshes": [ { "primitives": [ {
            "attributes": { "POSITION": 0, "NORMAL": 1 }, "indices": 2, "material": 0
        } ] } ],
        "materials": [ {
            "name": name,
            "pbrMetallicRoughness": {
                "baseColorFactor": [colour[0], colour[1], colour[2], 1.0],
                "metallicFactor": metal,
                "roughnessFactor": fit.alpha.sqrt().clamp(0.0, 1.0),
            },
            "extensions": ext,
        } ],
        "buffers": [ {
            "byteLength": bytes.len(),
            "uri": format!("data:application/octet-stream;base64,{}", base64(&bytes)),
        } ],
        "bufferViews": [
            { "buffer": 0, "byteOffset": 0, "byteLength": vb, "target": 34962 },
            { "buffer": 0, "byteOffset": vb, "byteLength": vb, "target": 34962 },
            { "buffer": 0, "byteOffset": 2 * vb, "byteLength": idx.len() * 2, "target": 34963 },
        ],
        "accessors": [
            { "bufferView": 0, "componentType": 5126, "count": nv, "type": "VEC3",
              "min": [-1.0, -1.0, -1.0], "max": [1.0, 1.0, 1.0] },
            { "bufferView": 1, "componentType": 5126, "count": nv, "type": "VEC3" },
            { "bufferView": 2, "componentType": 5123, "count": idx.len(), "type": "SCALAR" },
        ],
    })
}

/// Standard base64 (RFC 4648 §4) for the glTF data URI.
fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for c in bytes.chunks(3) {
        let b = [c[0], *c.get(1).unwrap_or(&0), *c.get(2).unwrap_or(&0)];
        let v = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for k in 0..4 {
            if k <= c.len() {
                s.push(A[((v >> (18 - 6 * k)) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

/// Writes JSON atomically.
pub fn write_json(path: &Path, v: &serde_json::Value) -> std::io::Result<()> {
    crate::io::write_atomic(path, |w| {
        serde_json::to_writer_pretty(&mut *w, v).map_err(std::io::Error::other)?;
        std::io::Write::write_all(w, b"\n")
    })
}
