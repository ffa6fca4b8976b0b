//! `goniospec info` and `goniospec backends`: describe files and accelerators.

use super::{Accumulator, Args, Backend, Context, ExitCode, PathBuf, Result, accel, bail};

#[derive(Args)]
pub(super) struct InfoArgs {
    /// A .gsa, .gsb or .bsdf file (an RGL tensor file: a measured material of the RGL
    /// database, or one goniospec exported).
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
        let mut b = [0u8; 12];
        f.read_exact(&mut b).ok();
        b
    };
    if goniospec::export::tensor::is_tensor_file(&head) {
        let bytes = goniospec::io::read_input(&a.file, u64::MAX)
            .with_context(|| format!("reading {}", a.file.display()))?;
        let fields = goniospec::export::tensor::from_bytes(&bytes)
            .map_err(|m| anyhow::anyhow!("{}: {m}", a.file.display()))?;
        outln!("{}: RGL tensor file (.bsdf)", a.file.display());
        match goniospec::export::measured::MeasuredBrdf::from_fields(&fields) {
            Ok(m) => outln!("{}", m.describe().trim_end()),
            Err(e) => outln!("not a BRDF the RGL readers evaluate: {e}"),
        }
        outln!(
            "{}",
            goniospec::export::tensor::describe(&fields).trim_end()
        );
    } else if head[..8] == goniospec::accumulate::file::MAGIC[..] {
        let acc = Accumulator::read(&a.file)?;
        outln!("{}: goniospec accumulator (.gsa)", a.file.display());
        outln!("{}", acc.header.describe().trim_end());
        if let Some(r) = acc.realisability() {
            outln!(
                "Mueller matrices: {} buckets of positive m00, {} not realisable; the smallest coherency eigenvalue {:.2e} of its m00 ({:.1} standard errors)",
                r.checked,
                r.failed,
                r.worst_relative,
                r.worst_sigmas
            );
        }
        // `info` describes what a file holds, impossible or not; the commands that use
        // its results refuse it.
        match goniospec::simulate::check_file(&acc, &a.file.display().to_string()) {
            Ok(()) => {
                outln!("physics: every cell passes the checks its run applied before writing")
            }
            Err(e) => outln!("physics: IMPOSSIBLE: {e}"),
        }
    } else if head[..8] == brdf::file::MAGIC[..] {
        let r = brdf::file::read(&a.file)?;
        outln!(
            "{}: goniospec BRDF (.gsb), representation {}",
            a.file.display(),
            r.meta().repr
        );
        outln!("{}", r.describe().trim_end());
    } else {
        bail!(
            "{}: not a .gsa, .gsb or .bsdf file (unknown magic bytes)",
            a.file.display()
        );
    }
    Ok(ExitCode::SUCCESS)
}
