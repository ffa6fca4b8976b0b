//! A recipe's template: a sample file whose numbers `match` varies, named by their TOML
//! paths (`media.paint.particles.volume_fraction`, `stack.layers.0.thickness`), and the
//! candidates written from it. The template is edited with `toml_edit`, so a candidate is
//! the user's file with only those numbers changed, comments and layout kept.

use std::path::{Component, Path, PathBuf};

use toml_edit::{DocumentMut, Item, Table, Value};

use super::RecipeError;
use crate::sample::{MeshOptions, Sample};

/// Significant digits a candidate's values are written with: a search step of 1e-5 of a
/// value is far below what the simulations' noise resolves, and the file stays readable.
pub const DIGITS: i32 = 5;

/// One varied parameter: `PATH=LO:HI` (linear) or `PATH=LO:HI:log` (searched in its
/// logarithm: for quantities that span decades, like a volume fraction or a roughness).
#[derive(Clone, Debug, PartialEq)]
pub struct Vary {
    /// The TOML path as written: keys joined by dots, array elements by their index from 0.
    pub path: String,
    keys: Vec<Key>,
    pub lo: f64,
    pub hi: f64,
    pub log: bool,
}

#[derive(Clone, Debug, PartialEq)]
enum Key {
    Name(String),
    Index(usize),
}

impl Vary {
    /// Parses `PATH=LO:HI[:log]`.
    pub fn parse(spec: &str) -> Result<Vary, RecipeError> {
        let bad = |why: &str| RecipeError::from(format!("--vary '{spec}': {why}"));
        let (path, range) = spec
            .split_once('=')
            .ok_or_else(|| bad("expected PATH=LO:HI or PATH=LO:HI:log"))?;
        let path = path.trim();
        if path.is_empty() {
            return Err(bad("the path is empty"));
        }
        let keys = path
            .split('.')
            .map(|k| match k.parse::<usize>() {
                Ok(i) => Ok(Key::Index(i)),
                Err(_) if k.is_empty() => Err(bad("the path has an empty key (two dots)")),
                Err(_) => Ok(Key::Name(k.to_string())),
            })
            .collect::<Result<Vec<_>, _>>()?;
        let parts: Vec<&str> = range.split(':').map(str::trim).collect();
        let log = match parts.as_slice() {
            [_, _] => false,
            [_, _, "log"] => true,
            [_, _, other] => return Err(bad(&format!("'{other}' is not 'log'"))),
            _ => return Err(bad("the range is LO:HI or LO:HI:log")),
        };
        let num = |s: &str| {
            s.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| bad(&format!("'{s}' is not a finite number")))
        };
        let (lo, hi) = (num(parts[0])?, num(parts[1])?);
        if lo >= hi {
            return Err(bad(&format!(
                "the range {lo}:{hi} is empty (LO must be below HI)"
            )));
        }
        if log && lo <= 0.0 {
            return Err(bad(&format!(
                "a log range needs LO > 0 (the search is in the logarithm), got {lo}"
            )));
        }
        Ok(Vary {
            path: path.to_string(),
            keys,
            lo,
            hi,
            log,
        })
    }

    /// The value at `u` in [0, 1] of the range (linear, or geometric for a log range),
    /// written to [`DIGITS`] significant digits and kept within the range.
    pub fn value_at(&self, u: f64) -> f64 {
        let v = if self.log {
            (self.lo.ln() + u * (self.hi.ln() - self.lo.ln())).exp()
        } else {
            self.lo + u * (self.hi - self.lo)
        };
        round_significant(v, DIGITS).clamp(self.lo, self.hi)
    }

    /// Where `v` lies in the range, 0 at LO and 1 at HI (outside [0, 1] when `v` does).
    pub fn unit_of(&self, v: f64) -> f64 {
        if self.log {
            (v.ln() - self.lo.ln()) / (self.hi.ln() - self.lo.ln())
        } else {
            (v - self.lo) / (self.hi - self.lo)
        }
    }
}

/// `v` to `digits` significant digits.
pub fn round_significant(v: f64, digits: i32) -> f64 {
    if v == 0.0 || !v.is_finite() {
        return v;
    }
    let scale = 10f64.powi(digits - 1 - v.abs().log10().floor() as i32);
    (v * scale).round() / scale
}

/// A template sample file and the values its varied numbers hold.
#[derive(Clone, Debug)]
pub struct Template {
    pub path: PathBuf,
    doc: DocumentMut,
    /// The template's own value of each varied number.
    pub values: Vec<f64>,
}

/// What a path leads to while it is walked: a table's entry, an inline value, or a table
/// of an array of tables.
enum Node<'a> {
    Item(&'a mut Item),
    Value(&'a mut Value),
    Table(&'a mut Table),
}

impl Template {
    /// Reads the template and finds every varied number in it. Refused: a file that is not
    /// TOML, a path that leads nowhere or to something other than a real number (an
    /// integer is refused: `match` varies real numbers), and a template that does not
    /// load as a sample.
    pub fn read(path: &Path, vary: &[Vary]) -> Result<Template, RecipeError> {
        let text = crate::io::read_text(path)
            .map_err(|e| RecipeError::from(format!("{}: {e}", path.display())))?;
        let doc: DocumentMut = text
            .parse()
            .map_err(|e| RecipeError::from(format!("{}: not TOML: {e}", path.display())))?;
        let mut t = Template {
            path: path.to_path_buf(),
            doc,
            values: Vec::new(),
        };
        for (k, v) in vary.iter().enumerate() {
            if vary[..k].iter().any(|w| w.path == v.path) {
                return Err(format!("--vary names {} twice", v.path).into());
            }
            let value = t.number(v)?;
            t.values.push(value);
        }
        t.load(&t.doc.to_string()).map_err(|e| {
            RecipeError::from(format!(
                "the template {} does not load as a sample: {e}",
                path.display()
            ))
        })?;
        Ok(t)
    }

    /// The real number at `v`'s path, or why there is none.
    fn number(&mut self, v: &Vary) -> Result<f64, RecipeError> {
        let shown = self.path.display().to_string();
        let value = walk(&mut self.doc, &v.keys)
            .map_err(|why| RecipeError::from(format!("--vary {}: {shown} {why}", v.path)))?;
        match value {
            Value::Float(f) => Ok(*f.value()),
            Value::Integer(i) => Err(format!(
                "--vary {}: {shown} holds the integer {} there; match varies real numbers (write it as {}.0 where the sample takes a real number)",
                v.path,
                i.value(),
                i.value()
            )
            .into()),
            other => Err(format!(
                "--vary {}: {shown} holds {} there, not a number",
                v.path,
                other.type_name()
            )
            .into()),
        }
    }

    /// The template's text with the varied numbers set to `values`.
    pub fn with_values(&self, vary: &[Vary], values: &[f64]) -> String {
        let mut doc = self.doc.clone();
        for (v, &x) in vary.iter().zip(values) {
            let slot = walk(&mut doc, &v.keys).expect("a path Template::read found");
            let decor = slot.decor().clone();
            *slot = Value::from(x);
            *slot.decor_mut() = decor;
        }
        doc.to_string()
    }

    /// Loads a candidate's text as a sample, its relative paths (meshes, tables) taken
    /// from the template's folder.
    pub fn load(&self, text: &str) -> Result<Sample, RecipeError> {
        crate::sample::parse(&self.path, text, MeshOptions::default())
            .map_err(|e| RecipeError::from(e.to_string()))
    }

    /// Checks that the sample loads with each varied number at either end of its range
    /// (the others at `start`): a range past what the sample takes (a negative thickness, a
    /// volume fraction above 1, a roughness of 0) is refused before any simulation, with
    /// the sample's own reason.
    pub fn check_ranges(&self, vary: &[Vary], start: &[f64]) -> Result<(), RecipeError> {
        for (k, v) in vary.iter().enumerate() {
            for end in [v.lo, v.hi] {
                let mut values = start.to_vec();
                values[k] = end;
                self.load(&self.with_values(vary, &values)).map_err(|e| {
                    RecipeError::from(format!(
                        "--vary {}={}:{}: the sample is refused with {} = {end}: {e}",
                        v.path, v.lo, v.hi, v.path
                    ))
                })?;
            }
        }
        Ok(())
    }

    /// The fitted recipe as a file in `out_dir`: the template with `values`, its relative
    /// file names (meshes, tables) rewritten to reach the same files from `out_dir`, and
    /// `header` (comment lines) on top.
    pub fn fitted(&self, vary: &[Vary], values: &[f64], out_dir: &Path, header: &str) -> String {
        let mut doc: DocumentMut = self
            .with_values(vary, values)
            .parse()
            .expect("a template's own text parses");
        let base = self.path.parent().unwrap_or(Path::new("."));
        rebase_paths(doc.as_item_mut(), base, out_dir);
        let mut text = String::new();
        for line in header.lines() {
            text.push_str("# ");
            text.push_str(line);
            text.push('\n');
        }
        text.push('\n');
        text.push_str(&doc.to_string());
        text
    }
}

/// Follows `keys` from the document's root to a value; the error says what the file has
/// instead ("has no 'q' in media.metal").
fn walk<'a>(doc: &'a mut DocumentMut, keys: &[Key]) -> Result<&'a mut Value, RecipeError> {
    let mut node = Node::Table(doc.as_table_mut());
    let mut walked = String::new();
    for key in keys {
        let here = if walked.is_empty() {
            "the top level".to_string()
        } else {
            walked.clone()
        };
        node = match (node, key) {
            (Node::Table(t), Key::Name(n)) => t.get_mut(n).map(Node::Item),
            (Node::Item(Item::Table(t)), Key::Name(n)) => t.get_mut(n).map(Node::Item),
            (Node::Item(Item::Value(Value::InlineTable(t))), Key::Name(n))
            | (Node::Value(Value::InlineTable(t)), Key::Name(n)) => t.get_mut(n).map(Node::Value),
            (Node::Item(Item::ArrayOfTables(a)), Key::Index(i)) => a.get_mut(*i).map(Node::Table),
            (Node::Item(Item::Value(Value::Array(a))), Key::Index(i))
            | (Node::Value(Value::Array(a)), Key::Index(i)) => a.get_mut(*i).map(Node::Value),
            (_, Key::Index(i)) => {
                return Err(format!("has no array at {here} to take element {i} of").into());
            }
            (_, Key::Name(n)) => {
                return Err(format!("has no table at {here} to find '{n}' in").into());
            }
        }
        .ok_or_else(|| {
            RecipeError::from(match key {
                Key::Name(n) => format!("has no '{n}' in {here}"),
                Key::Index(i) => format!("has no element {i} in {here}"),
            })
        })?;
        if !walked.is_empty() {
            walked.push('.');
        }
        walked.push_str(&match key {
            Key::Name(n) => n.clone(),
            Key::Index(i) => i.to_string(),
        });
    }
    match node {
        Node::Item(Item::Value(v)) | Node::Value(v) => Ok(v),
        _ => Err(format!("holds a table at {walked}, not a number").into()),
    }
}

/// Rewrites every string that names an existing file relative to `base` so that it names
/// it from `out_dir` instead.
fn rebase_paths(item: &mut Item, base: &Path, out_dir: &Path) {
    match item {
        Item::Table(t) => t
            .iter_mut()
            .for_each(|(_, i)| rebase_paths(i, base, out_dir)),
        Item::ArrayOfTables(a) => a.iter_mut().for_each(|t| {
            t.iter_mut()
                .for_each(|(_, i)| rebase_paths(i, base, out_dir))
        }),
        Item::Value(v) => rebase_value(v, base, out_dir),
        Item::None => {}
    }
}

fn rebase_value(v: &mut Value, base: &Path, out_dir: &Path) {
    match v {
        Value::String(s) => {
            let named = Path::new(s.value());
            if named.is_relative()
                && base.join(named).is_file()
                && let Some(to) = relative_path(out_dir, &base.join(named))
            {
                let decor = s.decor().clone();
                *v = Value::from(to.to_string_lossy().replace('\\', "/"));
                *v.decor_mut() = decor;
            }
        }
        Value::Array(a) => a.iter_mut().for_each(|x| rebase_value(x, base, out_dir)),
        Value::InlineTable(t) => t
            .iter_mut()
            .for_each(|(_, x)| rebase_value(x, base, out_dir)),
        _ => {}
    }
}

/// The path of `file` relative to the folder `from` (both resolved), or `None` where
/// either cannot be resolved.
pub fn relative_path(from: &Path, file: &Path) -> Option<PathBuf> {
    let from = std::fs::canonicalize(from).ok()?;
    let file = std::fs::canonicalize(file).ok()?;
    let a: Vec<Component> = from.components().collect();
    let b: Vec<Component> = file.components().collect();
    let common = a.iter().zip(&b).take_while(|(x, y)| x == y).count();
    let mut out = PathBuf::new();
    for _ in common..a.len() {
        out.push("..");
    }
    for c in &b[common..] {
        out.push(c);
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_parse_and_map_both_ways() {
        let v = Vary::parse("stack.layers.0.thickness=100:500").unwrap();
        assert_eq!(v.keys.len(), 4);
        assert_eq!(v.keys[2], Key::Index(0));
        assert_eq!(v.value_at(0.25), 200.0);
        assert_eq!(v.unit_of(200.0), 0.25);
        let l = Vary::parse("a.b=0.01:1:log").unwrap();
        // The geometric middle of 0.01 and 1 is 0.1.
        assert!((l.value_at(0.5) - 0.1).abs() < 1e-12);
        assert!((l.unit_of(0.1) - 0.5).abs() < 1e-12);
        assert_eq!(round_significant(0.123456789, 5), 0.12346);
        assert_eq!(round_significant(-98765.4, 3), -98800.0);
        for bad in [
            "a.b",
            "=1:2",
            "a.b=2:1",
            "a.b=1:1",
            "a.b=0:1:log",
            "a.b=1:x",
            "a..b=1:2",
            "a.b=1:2:lin",
            "a.b=1:inf",
        ] {
            assert!(Vary::parse(bad).is_err(), "{bad} was taken");
        }
    }

    #[test]
    fn paths_reach_tables_inline_tables_and_arrays() {
        let text = "# a comment\n[stack]\nlayers = [{ medium = \"m\", thickness = 400.0 }]\n\n[[interface]]\ngenerator = { kind = \"x\", alpha = 0.2, resolution = 64 } # kept\n";
        let mut doc: DocumentMut = text.parse().unwrap();
        let at = |doc: &mut DocumentMut, p: &str| {
            let v = Vary::parse(&format!("{p}=0:1")).unwrap();
            walk(doc, &v.keys)
                .map(|v| v.to_string())
                .map_err(|e| e.to_string())
        };
        assert_eq!(
            at(&mut doc, "stack.layers.0.thickness").unwrap().trim(),
            "400.0"
        );
        assert_eq!(
            at(&mut doc, "interface.0.generator.alpha").unwrap().trim(),
            "0.2"
        );
        assert!(
            at(&mut doc, "stack.layers.1.thickness")
                .unwrap_err()
                .contains("element 1")
        );
        assert!(at(&mut doc, "stack.depth").unwrap_err().contains("'depth'"));
        assert!(at(&mut doc, "stack").unwrap_err().contains("table"));
        // Setting keeps the comments.
        let t = Template {
            path: PathBuf::from("x.toml"),
            doc,
            values: vec![],
        };
        let vary = [Vary::parse("interface.0.generator.alpha=0.1:0.5").unwrap()];
        let out = t.with_values(&vary, &[0.35]);
        assert!(out.contains("alpha = 0.35,"), "{out}");
        assert!(
            out.contains("# a comment") && out.contains("# kept"),
            "{out}"
        );
    }

    #[test]
    fn a_fitted_recipe_names_the_template_s_files_from_its_own_folder() {
        let root = std::env::temp_dir().join(format!("goniospec-rebase-{}", std::process::id()));
        let (a, b) = (root.join("samples"), root.join("out").join("fit"));
        std::fs::create_dir_all(a.join("data")).unwrap();
        std::fs::create_dir_all(&b).unwrap();
        std::fs::write(a.join("data").join("n.csv"), "x").unwrap();
        let text = "[media.m]\ntable = \"data/n.csv\" # kept\nother = \"not a file\"\nk = 1.0\n";
        let t = Template {
            path: a.join("t.toml"),
            doc: text.parse().unwrap(),
            values: vec![],
        };
        let vary = [Vary::parse("media.m.k=0.5:2").unwrap()];
        let out = t.fitted(&vary, &[1.5], &b, "fitted\nby a test");
        assert!(out.starts_with("# fitted\n# by a test\n"), "{out}");
        assert!(
            out.contains("table = \"../../samples/data/n.csv\" # kept"),
            "{out}"
        );
        assert!(out.contains("other = \"not a file\""), "{out}");
        assert!(out.contains("k = 1.5"), "{out}");
        let _ = std::fs::remove_dir_all(&root);
    }
}
