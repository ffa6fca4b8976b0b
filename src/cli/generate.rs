//! `goniospec generate`: write a generated microgeometry as OBJ.

use super::{
    Args, Context, ExitCode, OutputKind, PathBuf, Result, bail, finite, guard_output, sample,
};

#[derive(Args)]
pub(super) struct GenerateArgs {
    /// Generator kind (see above).
    kind: String,
    /// Parameters as key=value (TOML values: numbers, "strings", [arrays]); repeatable.
    #[arg(long = "param", short = 'p', value_name = "KEY=VALUE")]
    params: Vec<String>,
    /// Tile size Lx,Ly in --unit.
    #[arg(long, value_parser = finite, value_delimiter = ',', default_values_t = [20.0, 20.0])]
    tile: Vec<f64>,
    /// Unit of the tile, the lengths and the OBJ coordinates: nm or um.
    #[arg(long, default_value = "um")]
    unit: String,
    /// Output OBJ (written atomically).
    #[arg(short, long)]
    output: PathBuf,
    /// Overwrite an existing output that is not an OBJ written by goniospec generate.
    #[arg(long)]
    force: bool,
}

pub(super) fn generate(a: GenerateArgs) -> Result<ExitCode> {
    use goniospec::sample::generate::{Generated, GeneratorSpec};
    guard_output(&a.output, &[], OutputKind::Obj, a.force)?;
    let u = sample::nm_per_unit(&a.unit)
        .with_context(|| format!("unknown --unit '{}' (use nm or um)", a.unit))?;
    if a.tile.len() != 2 {
        bail!("--tile needs two sizes Lx,Ly, got {:?}", a.tile);
    }
    let tile_nm = [a.tile[0] * u, a.tile[1] * u];
    if !tile_nm.iter().all(|t| t.is_finite() && *t > 0.0) {
        bail!("--tile must be two positive sizes, got {:?}", a.tile);
    }
    let spec = GeneratorSpec::from_key_values(&a.kind, &a.params)?;
    let comment = format!(
        "goniospec generate {} {} --tile {},{} --unit {}\nCoordinates in {}.",
        a.kind,
        a.params
            .iter()
            .map(|p| format!("--param {p}"))
            .collect::<Vec<_>>()
            .join(" "),
        a.tile[0],
        a.tile[1],
        a.unit,
        a.unit
    );
    let out = spec
        .generate(tile_nm, u)
        .map_err(|e| anyhow::anyhow!("generator '{}': {e}", a.kind))?;
    let (cores, shells) = out.merged();
    let note = match &out {
        Generated::Sheet(_) => comment.clone(),
        Generated::Bodies(b) => format!("{comment}\n{} bodies", b.len()),
    };
    cores
        .write_obj(&a.output, u, &note)
        .with_context(|| format!("writing {}", a.output.display()))?;
    match &out {
        Generated::Sheet(_) => outln!(
            "wrote {} ({} triangles)",
            a.output.display(),
            cores.triangles.len()
        ),
        Generated::Bodies(b) => outln!(
            "wrote {} ({} bodies, {} triangles)",
            a.output.display(),
            b.len(),
            cores.triangles.len()
        ),
    }
    if let Generated::Bodies(bodies) = &out
        && !shells.triangles.is_empty()
    {
        let stem = a.output.file_stem().unwrap_or_default().to_string_lossy();
        let p = a.output.with_file_name(format!("{stem}-coating.obj"));
        shells
            .write_obj(
                &p,
                u,
                &format!("{comment}\ncoating shells of {} bodies", bodies.len()),
            )
            .with_context(|| format!("writing {}", p.display()))?;
        outln!(
            "wrote {} ({} triangles)",
            p.display(),
            shells.triangles.len()
        );
    }
    Ok(ExitCode::SUCCESS)
}
