//! Stages 7 and 8 of [`super`]: the `[stack]`, the `[[interface]]` sheets and the
//! `[[body]]` solids, each with its media and coatings.

use std::path::PathBuf;

use toml::Spanned;

use super::media::Names;
use super::{Ctx, Measured};
use crate::sample::generate::{self, Generated, GeneratorSpec};
use crate::sample::limits::{MIN_SEPARATION_RESOLUTIONS, check_length, f32_resolution_nm};
use crate::sample::raw::{RawCoating, RawLayer, RawSample};
use crate::sample::{Interface, SampleError, SampleErrorKind, Stack, load_mesh};

/// Stage 7: a `[stack]`, as one coated flat interface (the exact default) or as flat
/// meshed interfaces, top (ambient side) first.
pub(super) fn stack(
    names: &Names,
    raw: &RawSample,
    tile_nm: [f64; 2],
) -> Result<(Option<Stack>, Vec<Interface>), SampleError> {
    let cx = names.cx;
    let Some(st) = &raw.stack else {
        return Ok((None, Vec::new()));
    };
    let ambient = names.medium(&st.get_ref().ambient)?;
    let substrate = names.medium(&st.get_ref().substrate)?;
    let layers = names.layers(&st.get_ref().layers)?;
    // The tracer follows light between the sample's planes only: a scattering medium
    // without end above or below would be traced as its clear host.
    for (m, which, side) in [
        (ambient, &st.get_ref().ambient, "ambient"),
        (substrate, &st.get_ref().substrate, "substrate"),
    ] {
        if names.media[m].scattering.is_some() {
            return Err(cx.at(
                which.span(),
                SampleErrorKind::Invalid(format!(
                    "the {side} '{}' scatters in volume, but the {side} goes on without end and the tracer follows light only between the sample's top and bottom planes, so its particles would be ignored; give it a finite depth as a layer (one many transport mean free paths deep, which goniospec check prints, reflects as a half-space does) {}",
                    which.get_ref(),
                    if side == "ambient" {
                        "below a clear ambient (a BRDF is measured in a clear medium)"
                    } else {
                        "over a clear substrate"
                    }
                )),
            ));
        }
    }
    let stack = Stack {
        ambient,
        layers: layers.clone(),
        substrate,
    };
    if !stack_is_meshed(names, raw, &layers)? {
        let coated = Interface {
            mesh: generate::flat(tile_nm, 0.0),
            mesh_path: PathBuf::from("[stack] coated interface (z = 0 nm)"),
            closed: false,
            front: ambient,
            back: substrate,
            coating: layers,
        };
        return Ok((Some(stack), vec![coated]));
    }
    // Every layer becomes two meshed planes: they must stay apart in f32.
    let total: f64 = layers.iter().map(|l| l.1).sum();
    if !layers.is_empty() {
        check_length("total stack thickness", total / cx.scale, cx.unit, total)
            .map_err(|m| cx.at(st.span(), m))?;
    }
    let res = f32_resolution_nm(tile_nm[0].max(tile_nm[1]).max(total));
    for (l, &(_, t)) in st.get_ref().layers.iter().zip(&layers) {
        if t < MIN_SEPARATION_RESOLUTIONS * res {
            return Err(cx.at(
                l.thickness.span(),
                SampleErrorKind::Invalid(format!(
                    "a meshed layer of {t:e} nm is thinner than f32 geometry can separate at this tile size ({MIN_SEPARATION_RESOLUTIONS} x {res:.2e} nm); use the exact [stack] mode = \"coating\""
                )),
            ));
        }
    }
    let mut interfaces = Vec::new();
    let mut above = ambient;
    let mut z = total;
    for (i, &(m, t)) in layers.iter().enumerate() {
        interfaces.push(Interface {
            mesh: generate::flat(tile_nm, z),
            mesh_path: PathBuf::from(format!("[stack] interface {i} (z = {z} nm)")),
            closed: false,
            front: above,
            back: m,
            coating: Vec::new(),
        });
        above = m;
        z -= t;
    }
    interfaces.push(Interface {
        mesh: generate::flat(tile_nm, 0.0),
        mesh_path: PathBuf::from(format!("[stack] interface {} (z = 0 nm)", layers.len())),
        closed: false,
        front: above,
        back: substrate,
        coating: Vec::new(),
    });
    Ok((Some(stack), interfaces))
}

/// Whether a `[stack]` is meshed: as its `mode` says, or by default when it shares the
/// sample with bodies or other interfaces (a binder holding pigments lives inside its
/// layers) or a layer scatters (a volume the tracer walks through).
fn stack_is_meshed(
    names: &Names,
    raw: &RawSample,
    layers: &[(usize, f64)],
) -> Result<bool, SampleError> {
    let Some(st) = &raw.stack else {
        return Ok(false);
    };
    let others = !raw.interface.is_empty() || !raw.body.is_empty();
    let scattering = layers
        .iter()
        .any(|&(m, _)| names.media[m].scattering.is_some());
    let Some(m) = st.get_ref().mode.as_ref() else {
        return Ok(others || scattering);
    };
    match m.get_ref().as_str() {
        "coating" if scattering => Err(names.cx.at(
            m.span(),
            SampleErrorKind::Invalid(
                "a [stack] with a scattering layer (particles or henyey_greenstein) cannot be an exact coating: remove mode or use mode = \"mesh\"".into(),
            ),
        )),
        "coating" => Ok(false),
        "mesh" => Ok(true),
        other => Err(names.cx.at(
            m.span(),
            SampleErrorKind::Invalid(format!(
                "unknown [stack] mode '{other}' (use \"coating\", the exact default, or \"mesh\")"
            )),
        )),
    }
}

/// Loads a mesh or runs a generator for an `[[interface]]` (`want_bodies` false) or a
/// `[[body]]`: the geometry and a description of where it came from.
fn source(
    cx: &Ctx,
    mesh: &Option<Spanned<String>>,
    generator: &Option<Spanned<GeneratorSpec>>,
    want_bodies: bool,
    tile_nm: [f64; 2],
) -> Result<(Generated, String), SampleError> {
    match (mesh, generator) {
        (Some(m), None) => {
            let mesh_path = cx.base.join(m.get_ref());
            let mesh = load_mesh(&mesh_path, cx.scale, cx.opts).map_err(|e| {
                cx.at(
                    m.span(),
                    SampleErrorKind::Mesh {
                        mesh: m.get_ref().clone(),
                        error: Box::new(e),
                    },
                )
            })?;
            let desc = mesh_path.display().to_string();
            Ok((
                if want_bodies {
                    Generated::Bodies(vec![(mesh, None)])
                } else {
                    Generated::Sheet(mesh)
                },
                desc,
            ))
        }
        (None, Some(g)) => {
            let spec = g.get_ref();
            if spec.makes_bodies() != want_bodies {
                let (makes, belongs) = if spec.makes_bodies() {
                    ("closed bodies", "[[body]]")
                } else {
                    ("a sheet", "[[interface]]")
                };
                return Err(cx.at(
                    g.span(),
                    SampleErrorKind::Invalid(format!(
                        "generator '{}' makes {makes}, so it belongs in {belongs}",
                        spec.kind()
                    )),
                ));
            }
            let out = spec.generate(tile_nm, cx.scale).map_err(|e| {
                cx.at(
                    g.span(),
                    SampleErrorKind::Generator {
                        kind: spec.kind().to_string(),
                        message: e.to_string(),
                    },
                )
            })?;
            Ok((out, format!("generator {}", spec.kind())))
        }
        _ => {
            let what = if want_bodies {
                "[[body]]"
            } else {
                "[[interface]]"
            };
            Err(cx.file(SampleErrorKind::Invalid(format!(
                "every {what} needs exactly one of mesh = \"FILE.obj\" or generator = {{ kind = ... }}"
            ))))
        }
    }
}

/// Stage 8a: every `[[interface]]`, from its mesh, generator or (already read) height map.
pub(super) fn sheets(
    names: &Names,
    raw: &RawSample,
    measured: Vec<Option<Measured>>,
    tile_nm: [f64; 2],
) -> Result<Vec<Interface>, SampleError> {
    let mut interfaces = Vec::new();
    for (ri, m) in raw.interface.iter().zip(measured) {
        let front = names.medium(&ri.front)?;
        let back = names.medium(&ri.back)?;
        let (mesh, desc) = match m {
            Some((mesh, _, desc)) => {
                if ri.mesh.is_some() || ri.generator.is_some() {
                    return Err(names.cx.at(
                        ri.front.span(),
                        SampleErrorKind::Invalid(
                            "an [[interface]] takes one of mesh, generator or heightmap".into(),
                        ),
                    ));
                }
                (mesh, desc)
            }
            None => {
                let (g, desc) = source(names.cx, &ri.mesh, &ri.generator, false, tile_nm)?;
                let Generated::Sheet(mesh) = g else {
                    unreachable!("sheet requested")
                };
                (mesh, desc)
            }
        };
        let coating = names.coating(ri.coating.as_deref().unwrap_or_default())?;
        interfaces.push(Interface {
            mesh,
            mesh_path: PathBuf::from(desc),
            closed: false,
            front,
            back,
            coating,
        });
    }
    Ok(interfaces)
}

/// Stage 8b: every `[[body]]`: closed meshes with an inside and an outside, and either a
/// meshed coating shell (`coating = "MEDIUM"`, the generator's coated bodies) or thin
/// layers on the outside (`coating = [ { medium, thickness }, ... ]`).
pub(super) fn bodies(
    names: &Names,
    raw: &RawSample,
    tile_nm: [f64; 2],
    stack: Option<&Stack>,
) -> Result<Vec<Interface>, SampleError> {
    let mut interfaces = Vec::new();
    for (number, rb) in raw.body.iter().enumerate() {
        let first = interfaces.len();
        let inside = names.medium(&rb.inside)?;
        let outside = names.medium(&rb.outside)?;
        let (coating, thin) = match &rb.coating {
            Some(RawCoating::Shell(m)) => {
                let m = Spanned::new(rb.inside.span(), m.clone());
                (Some(names.medium(&m)?), Vec::new())
            }
            Some(RawCoating::Layers(l)) => {
                let span = rb.inside.span();
                let spanned: Vec<RawLayer> = l
                    .iter()
                    .map(|x| RawLayer {
                        medium: Spanned::new(span.clone(), x.medium.clone()),
                        thickness: Spanned::new(span.clone(), x.thickness),
                    })
                    .collect();
                (None, names.coating(&spanned)?)
            }
            None => (None, Vec::new()),
        };
        let (g, desc) = source(names.cx, &rb.mesh, &rb.generator, true, tile_nm)?;
        let Generated::Bodies(bodies) = g else {
            unreachable!("bodies requested")
        };
        for (i, (core, shell)) in bodies.into_iter().enumerate() {
            let body = |mesh, front, back, coating| Interface {
                mesh,
                mesh_path: PathBuf::from(format!("{desc} body {i}")),
                closed: true,
                front,
                back,
                coating,
            };
            match (shell, coating) {
                (Some(shell), Some(c)) => {
                    interfaces.push(Interface {
                        mesh_path: PathBuf::from(format!("{desc} body {i} coating")),
                        ..body(shell, outside, c, Vec::new())
                    });
                    interfaces.push(body(core, c, inside, Vec::new()));
                }
                (Some(_), None) => {
                    return Err(names.cx.file(SampleErrorKind::Invalid(format!(
                        "{desc}: the bodies are coated, so the [[body]] needs coating = \"MEDIUM\""
                    ))));
                }
                (None, _) => interfaces.push(body(core, outside, inside, thin.clone())),
            }
        }
        if let Some(st) = stack {
            within_outside(names, rb, number, &desc, st, outside, &interfaces[first..])?;
        }
    }
    Ok(interfaces)
}

/// A `[[body]]` inside a `[stack]` must lie where its `outside` medium is: within a layer
/// of that medium (or above the stack for the ambient, below it for the substrate).
/// Anywhere else the tracer would meet a body whose outside disagrees with the medium
/// around it at every crossing (issue 74: flakes placed in the coat, or a binder typed
/// 0.015 um for 15, ran and blamed --max-depth or "a bug"). The error names the body, its
/// extent in z and the extents of its medium's layers, in the sample's unit.
fn within_outside(
    names: &Names,
    rb: &crate::sample::raw::RawBody,
    number: usize,
    desc: &str,
    st: &Stack,
    outside: usize,
    made: &[Interface],
) -> Result<(), SampleError> {
    let zs = made
        .iter()
        .flat_map(|i| i.mesh.positions_nm.iter().map(|p| p.z));
    let (lo, hi) = zs.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), z| {
        (a.min(z), b.max(z))
    });
    if lo > hi {
        // No vertices.
        return Ok(());
    }
    // Each place the medium fills: (bottom, top), nm, z = 0 at the substrate.
    let total: f64 = st.layers.iter().map(|l| l.1).sum();
    let mut places = Vec::new();
    if st.ambient == outside {
        places.push((total, f64::INFINITY));
    }
    let mut z = total;
    for &(m, t) in &st.layers {
        if m == outside {
            places.push((z - t, z));
        }
        z -= t;
    }
    if st.substrate == outside {
        places.push((f64::NEG_INFINITY, 0.0));
    }
    // Rounding of f32-placed vertices and of the layers' sums.
    let slack = 1e-6 * total.max(hi.abs()).max(1.0);
    if places
        .iter()
        .any(|&(b, t)| lo >= b - slack && hi <= t + slack)
    {
        return Ok(());
    }
    let cx = names.cx;
    // Four decimals in the sample's unit (a unit slip shows as well as a misplacement).
    let u = |nm: f64| {
        let v = nm / cx.scale;
        if v == 0.0 || v.abs() >= 1e-3 {
            let t = format!("{v:.4}");
            t.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            format!("{v:.3e}")
        }
    };
    let name = rb.outside.get_ref();
    let where_ = if places.is_empty() {
        format!("no layer of the [stack] is '{name}'")
    } else {
        let spans: Vec<String> = places
            .iter()
            .map(|&(b, t)| match (b.is_finite(), t.is_finite()) {
                (true, true) => format!("z = {} to {} {}", u(b), u(t), cx.unit),
                (true, false) => format!("above z = {} {} (the ambient)", u(b), cx.unit),
                _ => format!("below z = {} {} (the substrate)", u(t), cx.unit),
            })
            .collect();
        format!("'{name}' fills {}", spans.join(" and "))
    };
    Err(cx.at(
        rb.outside.span(),
        SampleErrorKind::Invalid(format!(
            "[[body]] {} ({desc}, outside = \"{name}\"): its bodies span z = {} to {} {}, but {where_}; bodies must lie inside their outside medium, or the tracer meets media that disagree at every crossing. Place them inside it (a generator's layer = [bottom, top]) or check the layers' thicknesses and the unit ({}), z = 0 being the substrate's top",
            number + 1,
            u(lo),
            u(hi),
            cx.unit,
            cx.unit
        )),
    ))
}
