//! Stage 5 of [`super`]: media, their volume scattering, and names resolved against them.

use toml::Spanned;

use super::Ctx;
use crate::sample::limits::check_length;
use crate::sample::media::{RawMedium, build_model};
use crate::sample::raw::{RawLayer, RawSample};
use crate::sample::{Medium, SampleError, SampleErrorKind, Scattering};

/// The radii a particle medium holds, nm: from an atom's size to where a sphere is many
/// wavelengths across (size parameter about 250 at 380 nm in a binder of n 1.5). Above it,
/// ray optics holds for the sphere itself, and the Mie set-up (growing as the square of
/// the size parameter at every tabulated wavelength) takes longer than the run: 1e6 nm
/// gave no answer in 30 s (issue 47).
pub const PARTICLE_RADIUS_NM: [f64; 2] = [0.1, crate::optics::particles::MAX_RADIUS_NM];
const PARTICLE_RADIUS_WHY: &str = "below 0.1 nm a particle is smaller than an atom; above 10 um a sphere is many wavelengths across, where ray optics holds: mesh it as bodies instead (goniospec generate pigment-spheres)";

/// Stage 5: every medium's index model (sorted by name, so ids are deterministic), then
/// its volume scattering.
pub(super) fn media(cx: &Ctx, raw: &RawSample) -> Result<Vec<Medium>, SampleError> {
    let mut media = Vec::new();
    for (name, m) in &raw.media {
        let model = build_model(m.get_ref(), cx.base, true).map_err(|e| match e.file {
            Some((file, line)) => {
                let inner = SampleError {
                    path: file.clone(),
                    line,
                    kind: SampleErrorKind::Invalid(e.message.clone()),
                };
                cx.at(
                    m.span(),
                    SampleErrorKind::MediumFile {
                        file: file.display().to_string(),
                        message: format!("medium '{name}': {inner}"),
                    },
                )
            }
            None => cx.at(
                m.span(),
                SampleErrorKind::BadMedium {
                    name: name.clone(),
                    message: e.message,
                },
            ),
        })?;
        media.push(Medium {
            name: name.clone(),
            model,
            scattering: None,
        });
    }
    for (name, m) in &raw.media {
        let scattering =
            scattering_of(raw, &media, name, m.get_ref()).map_err(|kind| cx.at(m.span(), kind))?;
        if let Some(s) = scattering
            && let Some(m) = media.iter_mut().find(|x| &x.name == name)
        {
            m.scattering = Some(s);
        }
    }
    Ok(media)
}

/// A medium's volume scattering: particles of another (homogeneous) medium, or a
/// Henyey-Greenstein phase function with its coefficients; `None` for a clear medium.
fn scattering_of(
    raw: &RawSample,
    media: &[Medium],
    name: &str,
    m: &RawMedium,
) -> Result<Option<Scattering>, SampleErrorKind> {
    use crate::optics::particles::{Radius, ScatterModel};
    let bad = |message: String| SampleErrorKind::BadMedium {
        name: name.to_string(),
        message,
    };
    match (&m.particles, &m.henyey_greenstein) {
        (None, None) => Ok(None),
        (Some(_), Some(_)) => Err(bad(
            "has both particles and henyey_greenstein; give one".into()
        )),
        (Some(p), None) => {
            let Some(pm) = media.iter().position(|x| x.name == p.medium) else {
                return Err(bad(format!("particles of unknown medium '{}'", p.medium)));
            };
            if pm
                == media
                    .iter()
                    .position(|x| x.name == name)
                    .unwrap_or(usize::MAX)
            {
                return Err(bad("particles cannot be of the medium they are in".into()));
            }
            if raw.media[&p.medium].get_ref().particles.is_some()
                || raw.media[&p.medium].get_ref().henyey_greenstein.is_some()
            {
                return Err(bad(format!(
                    "particles of '{}', itself a scattering medium: a particle is one homogeneous medium",
                    p.medium
                )));
            }
            let radius = match (p.radius_nm, &p.log_normal) {
                (Some(r), None) => {
                    if !(r.is_finite()
                        && (PARTICLE_RADIUS_NM[0]..=PARTICLE_RADIUS_NM[1]).contains(&r))
                    {
                        return Err(bad(format!(
                            "particles: radius_nm must lie in [{}, {}] nm, got {}: {}",
                            PARTICLE_RADIUS_NM[0],
                            PARTICLE_RADIUS_NM[1],
                            crate::sample::limits::show(r),
                            PARTICLE_RADIUS_WHY
                        )));
                    }
                    Radius::Fixed { radius_nm: r }
                }
                (None, Some(ln)) => {
                    let (r, sg) = (ln.median_radius_nm, ln.sigma);
                    if !(sg.is_finite() && sg > 0.0 && sg <= 1.0) {
                        return Err(bad(format!(
                            "particles: the log-normal sigma (of ln r) must lie in (0, 1], got {sg}"
                        )));
                    }
                    let ln = Radius::LogNormal {
                        median_nm: r,
                        sigma: sg,
                    };
                    // The radii the size integral samples, not only the median, must be
                    // in range.
                    let [lo, hi] = if r.is_finite() && r > 0.0 {
                        ln.span_nm()
                    } else {
                        [r, r]
                    };
                    if !(r.is_finite()
                        && lo >= PARTICLE_RADIUS_NM[0]
                        && hi <= PARTICLE_RADIUS_NM[1])
                    {
                        let z = crate::optics::particles::TAIL_Z;
                        return Err(bad(format!(
                            "particles: median_radius_nm {} with sigma {sg} has its size integral over radii from {lo:.3e} to {hi:.3e} nm (the median times e^(sigma z), z from 2 sigma - {z} to 3 sigma + {z}, where the volume and cross-sections leave 1e-5 of their integrals), which must lie in [{}, {}] nm: {}",
                            crate::sample::limits::show(r),
                            PARTICLE_RADIUS_NM[0],
                            PARTICLE_RADIUS_NM[1],
                            PARTICLE_RADIUS_WHY
                        )));
                    }
                    ln
                }
                _ => {
                    return Err(bad(
                        "particles need radius_nm or log_normal = { median_radius_nm, sigma }, not both"
                            .into(),
                    ));
                }
            };
            let f = p.volume_fraction;
            use crate::optics::particles::structure::{PY_FROM, RANDOM_CLOSE_PACKING};
            if !(f.is_finite() && f > 0.0 && f < RANDOM_CLOSE_PACKING) {
                return Err(bad(format!(
                    "particles: volume_fraction must lie in (0, {RANDOM_CLOSE_PACKING}), got {f}: {RANDOM_CLOSE_PACKING} is random close packing, the densest a suspension of spheres can be"
                )));
            }
            let dependent = match p.dependent.as_deref() {
                None => f >= PY_FROM,
                Some("percus-yevick") => true,
                Some("none") => false,
                Some(other) => {
                    return Err(bad(format!(
                        "particles: dependent must be \"percus-yevick\" (the packed spheres' structure factor, the default from {PY_FROM} by volume) or \"none\" (independent scattering), got \"{other}\""
                    )));
                }
            };
            Ok(Some(Scattering::Particles {
                medium: pm,
                radius,
                volume_fraction: f,
                dependent,
            }))
        }
        (None, Some(h)) => {
            ScatterModel::henyey_greenstein(h.g, h.scattering_per_um, h.absorption_per_um)
                .map_err(|e| bad(format!("henyey_greenstein: {e}")))?;
            Ok(Some(Scattering::HenyeyGreenstein {
                g: h.g,
                scattering_per_um: h.scattering_per_um,
                absorption_per_um: h.absorption_per_um,
            }))
        }
    }
}

/// Media by name, and layer lists resolved against them.
pub(super) struct Names<'a> {
    pub(super) cx: &'a Ctx<'a>,
    pub(super) media: &'a [Medium],
}

impl Names<'_> {
    /// The index of the medium `s` names, or an error listing the known ones.
    pub(super) fn medium(&self, s: &Spanned<String>) -> Result<usize, SampleError> {
        self.media
            .iter()
            .position(|m| &m.name == s.get_ref())
            .ok_or_else(|| {
                let known = if self.media.is_empty() {
                    "no media".to_string()
                } else {
                    self.media
                        .iter()
                        .map(|m| m.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                };
                self.cx.at(
                    s.span(),
                    SampleErrorKind::UnknownMedium {
                        name: s.get_ref().clone(),
                        known,
                    },
                )
            })
    }

    /// Layers (of a `[stack]` or a coating) as (medium, thickness in nm).
    pub(super) fn layers(&self, raw: &[RawLayer]) -> Result<Vec<(usize, f64)>, SampleError> {
        let mut layers = Vec::new();
        for l in raw {
            let t = *l.thickness.get_ref();
            check_length("layer thickness", t, self.cx.unit, t * self.cx.scale)
                .map_err(|m| self.cx.at(l.thickness.span(), m))?;
            layers.push((self.medium(&l.medium)?, t * self.cx.scale));
        }
        Ok(layers)
    }

    /// A coating's layers: a thin stack applied by transfer matrices, so no layer may
    /// scatter in its volume.
    pub(super) fn coating(&self, raw: &[RawLayer]) -> Result<Vec<(usize, f64)>, SampleError> {
        let layers = self.layers(raw)?;
        for (l, &(m, _)) in raw.iter().zip(&layers) {
            if self.media[m].scattering.is_some() {
                return Err(self.cx.at(
                    l.medium.span(),
                    SampleErrorKind::Invalid(format!(
                        "coating layer '{}' scatters (particles or henyey_greenstein), but a coating is a thin film applied by transfer matrices; make it a meshed layer",
                        self.media[m].name
                    )),
                ));
            }
        }
        Ok(layers)
    }
}
