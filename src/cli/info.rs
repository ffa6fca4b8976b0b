//! `goniospec info` and `goniospec backends`: describe files and accelerators.

use super::*;

#[derive(Args)]
pub(super) struct InfoArgs {
    /// A .gsa or .gsb file.
    file: PathBuf,
}

pub(super) fn backends() -> Result<ExitCode> {
    let mut any = false;
    for b in accel::available_backends() {
        match b {
            Ok(info) => {
                any = true;
                let default = if info.backend == Backend::default_available() {
                    "  (default)"
                } else {
                    ""
                };
                outln!(
                    "{} {}{}  [{}]",
                    info.backend,
                    info.version,
                    default,
                    info.detail
                );
            }
            Err(msg) => outln!("unavailable: {msg}"),
        }
    }
    Ok(if any {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

pub(super) fn info(a: InfoArgs) -> Result<ExitCode> {
    use goniospec::brdf::{self, Brdf};
    let head = {
        use std::io::Read;
        let mut f = std::fs::File::open(&a.file)
            .with_context(|| format!("opening {}", a.file.display()))?;
        let mut b = [0u8; 8];
        f.read_exact(&mut b).ok();
        b
    };
    if &head == goniospec::accumulate::file::MAGIC {
        let acc = Accumulator::read(&a.file)?;
        let h = &acc.header;
        outln!("{}: goniospec accumulator (.gsa)", a.file.display());
        outln!(
            "sample: '{}' (hash {})",
            h.settings.sample_name,
            h.settings.sample_hash
        );
        outln!(
            "incident angles (deg): {:?}, phi_i {} deg",
            h.settings.theta_i_deg,
            h.settings.phi_i_deg
        );
        outln!(
            "wavelengths: {} {} ({}..{} nm)",
            h.settings.wavelength_count(),
            h.settings.wavelength_mode,
            h.settings.wavelengths_nm.first().unwrap_or(&0.0),
            h.settings.wavelengths_nm.last().unwrap_or(&0.0)
        );
        outln!(
            "estimator: {}, coherence radius {} nm, cutoff {:e}, max depth {}",
            h.settings.coherence,
            h.settings.coherence_radius_nm,
            h.settings.cutoff,
            h.settings.max_depth
        );
        outln!(
            "buckets: {} x {} per hemisphere",
            h.settings.theta_o_bins,
            h.settings.phi_o_bins
        );
        outln!(
            "rays per direction: {:?} (seeds {:?}), backend {}, path sharing {}, leaks {}",
            h.rays_per_direction,
            h.seeds,
            h.backend,
            h.settings.path_sharing,
            h.leaks
        );
        let st = &h.settings;
        outln!(
            "limits: cutoff {:e}, max depth {}, max wraps {}, max segments {}; entry points {}{}",
            st.cutoff,
            st.max_depth,
            st.max_wraps,
            st.max_segments,
            st.entry_points,
            match (st.tolerance, st.max_rays) {
                (Some(t), Some(m)) => format!("; adaptive to {t} relative error, at most {m} rays"),
                _ => String::new(),
            }
        );
    } else if &head == brdf::file::MAGIC {
        let r = brdf::file::read(&a.file)?;
        let m = r.meta();
        outln!(
            "{}: goniospec BRDF (.gsb), representation {}",
            a.file.display(),
            m.repr
        );
        outln!("sample: '{}' (hash {})", m.sample_name, m.sample_hash);
        outln!(
            "wavelengths: {} ({}..{} nm)",
            m.wavelengths_nm.len(),
            m.wavelengths_nm.first().unwrap_or(&0.0),
            m.wavelengths_nm.last().unwrap_or(&0.0)
        );
        outln!(
            "isotropic {}, reciprocal {}, median relative stderr of the buckets {}",
            m.isotropic,
            m.reciprocal,
            m.median_rel_stderr
                .map_or("unknown".to_string(), |v| format!("{v:.3}"))
        );
        match &r {
            brdf::Representation::KdTree(k) => {
                outln!("kd-tree: {} points, k = {}", k.points.len(), k.k)
            }
            brdf::Representation::Table(t) => outln!(
                "table: {} incident angles x {} x {}",
                t.theta_i.len(),
                t.theta_bins,
                t.phi_bins
            ),
            brdf::Representation::Subdivided(s) => outln!(
                "subdivided: {} incident angles, {} leaves, tolerance {}",
                s.theta_i.len(),
                (0..s.theta_i.len())
                    .map(|i| s.leaves(i).count())
                    .sum::<usize>(),
                s.tolerance
            ),
        }
    } else {
        bail!(
            "{}: neither a .gsa nor a .gsb file (unknown magic bytes)",
            a.file.display()
        );
    }
    Ok(ExitCode::SUCCESS)
}
