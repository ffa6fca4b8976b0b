//! `goniospec generate`: write a generated microgeometry as OBJ.

use super::*;

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
    let mut text = format!("kind = {:?}\n", a.kind);
    for p in &a.params {
        let (k, v) = p
            .split_once('=')
            .with_context(|| format!("--param '{p}' is not KEY=VALUE"))?;
        let (k, v) = (k.trim(), v.trim());
        // A bare word that is not a TOML value (ggx, top) is taken as a string.
        let value = if toml::from_str::<toml::Table>(&format!("x = {v}")).is_ok() {
            v.to_string()
        } else {
            format!("{v:?}")
        };
        text.push_str(&format!("{k} = {value}\n"));
    }
    let spec: GeneratorSpec = toml::from_str(&text)
        .map_err(|e| anyhow::anyhow!("generator '{}': {}", a.kind, e.message().trim()))?;
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
    match out {
        Generated::Sheet(mesh) => {
            mesh.write_obj(&a.output, u, &comment)
                .with_context(|| format!("writing {}", a.output.display()))?;
            outln!(
                "wrote {} ({} triangles)",
                a.output.display(),
                mesh.triangles.len()
            );
        }
        Generated::Bodies(bodies) => {
            let mut cores = sample::Mesh::default();
            let mut shells = sample::Mesh::default();
            for (c, s) in &bodies {
                cores.append(c);
                if let Some(s) = s {
                    shells.append(s);
                }
            }
            cores
                .write_obj(&a.output, u, &format!("{comment}\n{} bodies", bodies.len()))
                .with_context(|| format!("writing {}", a.output.display()))?;
            outln!(
                "wrote {} ({} bodies, {} triangles)",
                a.output.display(),
                bodies.len(),
                cores.triangles.len()
            );
            if !shells.triangles.is_empty() {
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
        }
    }
    Ok(ExitCode::SUCCESS)
}
