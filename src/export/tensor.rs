//! The tensor file of the RGL material database (`.bsdf`), as Mitsuba 3's `TensorFile`
//! (`src/core/tensor.cpp`) and pbrt-v4's `measured` material read it.
//!
//! Layout (little endian):
//!
//! ```text
//! magic     12 bytes  "tensor_file\0"
//! version   2 bytes   major 1, minor 0
//! fields    u32       field count
//! per field: name length u16, name (UTF-8), ndim u16, dtype u8, data offset u64,
//!            shape u64 x ndim
//! data      each field's array, C order, at its offset (8-byte aligned here)
//! ```
//!
//! Data types are Mitsuba's `Struct::Type` codes: UInt8 = 1, Float32 = 10 (the only two
//! the `measured` plugin uses), UInt16 = 3 (the `measured_polarized` plugin's
//! wavelengths); Float64 = 11 is read too.

use super::ExportError;
use std::io::Write;
use std::path::Path;

const MAGIC: &[u8; 12] = b"tensor_file\0";

/// Element types of a field (Mitsuba `Struct::Type` codes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dtype {
    UInt8 = 1,
    UInt16 = 3,
    Float32 = 10,
    Float64 = 11,
}

impl Dtype {
    fn from_code(c: u8) -> Option<Dtype> {
        match c {
            1 => Some(Dtype::UInt8),
            3 => Some(Dtype::UInt16),
            10 => Some(Dtype::Float32),
            11 => Some(Dtype::Float64),
            _ => None,
        }
    }
    /// Bytes per element.
    pub fn size(self) -> usize {
        match self {
            Dtype::UInt8 => 1,
            Dtype::UInt16 => 2,
            Dtype::Float32 => 4,
            Dtype::Float64 => 8,
        }
    }
    pub fn name(self) -> &'static str {
        match self {
            Dtype::UInt8 => "uint8",
            Dtype::UInt16 => "uint16",
            Dtype::Float32 => "float32",
            Dtype::Float64 => "float64",
        }
    }
}

/// One named array.
#[derive(Clone, Debug, PartialEq)]
pub struct Field {
    pub name: String,
    pub dtype: Dtype,
    pub shape: Vec<u64>,
    /// Little-endian element bytes, C order.
    pub data: Vec<u8>,
}

impl Field {
    /// A float32 field; `values.len()` must equal the product of `shape`.
    pub fn f32(name: &str, shape: &[usize], values: &[f32]) -> Field {
        assert_eq!(
            shape.iter().product::<usize>(),
            values.len(),
            "{name}: shape"
        );
        Field {
            name: name.into(),
            dtype: Dtype::Float32,
            shape: shape.iter().map(|&s| s as u64).collect(),
            data: values.iter().flat_map(|v| v.to_le_bytes()).collect(),
        }
    }
    /// A uint8 field of one dimension.
    pub fn u8(name: &str, values: &[u8]) -> Field {
        Field {
            name: name.into(),
            dtype: Dtype::UInt8,
            shape: vec![values.len() as u64],
            data: values.to_vec(),
        }
    }
    /// A uint16 field of one dimension (the `measured_polarized` plugin's wavelengths).
    pub fn u16(name: &str, values: &[u16]) -> Field {
        Field {
            name: name.into(),
            dtype: Dtype::UInt16,
            shape: vec![values.len() as u64],
            data: values.iter().flat_map(|v| v.to_le_bytes()).collect(),
        }
    }
    /// The values as f64 (float fields), C order.
    pub fn values_f64(&self) -> Vec<f64> {
        match self.dtype {
            Dtype::UInt8 => self.data.iter().map(|&b| f64::from(b)).collect(),
            Dtype::UInt16 => self
                .data
                .chunks_exact(2)
                .map(|c| f64::from(u16::from_le_bytes([c[0], c[1]])))
                .collect(),
            Dtype::Float32 => self
                .data
                .chunks_exact(4)
                .map(|c| f64::from(f32::from_le_bytes(c.try_into().expect("4 bytes"))))
                .collect(),
            Dtype::Float64 => self
                .data
                .chunks_exact(8)
                .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
                .collect(),
        }
    }
}

/// Serialises fields (deterministic bytes: fields in the given order).
pub fn to_bytes(fields: &[Field]) -> Vec<u8> {
    let mut head = Vec::new();
    head.extend_from_slice(MAGIC);
    head.extend_from_slice(&[1, 0]);
    head.extend_from_slice(&(fields.len() as u32).to_le_bytes());
    let head_len = head.len()
        + fields
            .iter()
            .map(|f| 2 + f.name.len() + 2 + 1 + 8 + 8 * f.shape.len())
            .sum::<usize>();
    let align = |x: usize| x.div_ceil(8) * 8;
    let mut offset = align(head_len);
    let mut offsets = Vec::with_capacity(fields.len());
    for f in fields {
        offsets.push(offset);
        offset = align(offset + f.data.len());
    }
    for (f, &off) in fields.iter().zip(&offsets) {
        head.extend_from_slice(&(f.name.len() as u16).to_le_bytes());
        head.extend_from_slice(f.name.as_bytes());
        head.extend_from_slice(&(f.shape.len() as u16).to_le_bytes());
        head.push(f.dtype as u8);
        head.extend_from_slice(&(off as u64).to_le_bytes());
        for s in &f.shape {
            head.extend_from_slice(&s.to_le_bytes());
        }
    }
    debug_assert_eq!(head.len(), head_len);
    let mut out = head;
    for (f, &off) in fields.iter().zip(&offsets) {
        out.resize(off, 0);
        out.extend_from_slice(&f.data);
    }
    out.resize(align(out.len()), 0);
    out
}

/// Writes fields atomically.
pub fn write(fields: &[Field], path: &Path) -> std::io::Result<()> {
    let bytes = to_bytes(fields);
    crate::io::write_atomic(path, |w| w.write_all(&bytes))
}

/// Whether `bytes` start like a tensor file.
pub fn is_tensor_file(bytes: &[u8]) -> bool {
    bytes.starts_with(MAGIC)
}

/// Parses a tensor file, checking every field's extent against the file.
pub fn from_bytes(bytes: &[u8]) -> Result<Vec<Field>, ExportError> {
    if !is_tensor_file(bytes) {
        return Err(ExportError::from("not a tensor file (wrong magic bytes)"));
    }
    let mut pos = 12;
    let take = |pos: &mut usize, n: usize| -> Result<&[u8], String> {
        let s = bytes
            .get(*pos..pos.saturating_add(n))
            .ok_or("the header is truncated")?;
        *pos += n;
        Ok(s)
    };
    let version = take(&mut pos, 2)?;
    if version != [1, 0] {
        return Err(ExportError::from(format!(
            "tensor file version {}.{} (this build reads 1.0)",
            version[0], version[1]
        )));
    }
    let count = u32::from_le_bytes(take(&mut pos, 4)?.try_into().expect("4 bytes"));
    let mut fields = Vec::new();
    for _ in 0..count {
        let nlen = u16::from_le_bytes(take(&mut pos, 2)?.try_into().expect("2 bytes")) as usize;
        let name = std::str::from_utf8(take(&mut pos, nlen)?)
            .map_err(|_| "a field name is not UTF-8")?
            .to_string();
        let ndim = u16::from_le_bytes(take(&mut pos, 2)?.try_into().expect("2 bytes")) as usize;
        let code = take(&mut pos, 1)?[0];
        let dtype = Dtype::from_code(code)
            .ok_or_else(|| format!("field '{name}': unsupported dtype code {code}"))?;
        let offset = u64::from_le_bytes(take(&mut pos, 8)?.try_into().expect("8 bytes"));
        let mut shape = Vec::with_capacity(ndim.min(8));
        for _ in 0..ndim {
            shape.push(u64::from_le_bytes(
                take(&mut pos, 8)?.try_into().expect("8 bytes"),
            ));
        }
        let len = shape
            .iter()
            .try_fold(dtype.size() as u64, |a, &s| a.checked_mul(s))
            .ok_or_else(|| format!("field '{name}': its size overflows"))?;
        let end = offset
            .checked_add(len)
            .filter(|&e| e <= bytes.len() as u64)
            .ok_or_else(|| format!("field '{name}' reaches past the end of the file"))?;
        fields.push(Field {
            name,
            dtype,
            shape,
            data: bytes[offset as usize..end as usize].to_vec(),
        });
    }
    Ok(fields)
}

/// What `goniospec info` prints about a tensor file: the description, then one line per
/// field with its dtype and shape.
pub fn describe(fields: &[Field]) -> String {
    let mut s = String::new();
    if let Some(d) = fields.iter().find(|f| f.name == "description") {
        s += &format!("description: {}\n", String::from_utf8_lossy(&d.data));
    }
    for f in fields {
        let shape: Vec<String> = f.shape.iter().map(|v| v.to_string()).collect();
        s += &format!(
            "field {:<12} {:<8} [{}]\n",
            f.name,
            f.dtype.name(),
            shape.join(", ")
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The header bytes of a one-field file, laid out by hand from tensor.cpp's reader.
    #[test]
    fn layout_matches_the_reader() {
        let b = to_bytes(&[Field::u8("jacobian", &[1])]);
        assert_eq!(&b[..12], b"tensor_file\0");
        assert_eq!(&b[12..14], &[1, 0]);
        assert_eq!(u32::from_le_bytes(b[14..18].try_into().unwrap()), 1);
        assert_eq!(u16::from_le_bytes(b[18..20].try_into().unwrap()), 8);
        assert_eq!(&b[20..28], b"jacobian");
        assert_eq!(u16::from_le_bytes(b[28..30].try_into().unwrap()), 1); // ndim
        assert_eq!(b[30], 1); // UInt8
        let off = u64::from_le_bytes(b[31..39].try_into().unwrap()) as usize;
        assert_eq!(u64::from_le_bytes(b[39..47].try_into().unwrap()), 1); // shape
        assert_eq!(off % 8, 0);
        assert_eq!(b[off], 1);
    }

    #[test]
    fn round_trip_and_damage() {
        let fields = vec![
            Field::u8("description", b"test"),
            Field::f32("a", &[2, 3], &[1.0, 2.0, 3.0, 4.0, 5.0, 6.5]),
        ];
        let b = to_bytes(&fields);
        assert_eq!(from_bytes(&b).unwrap(), fields);
        assert_eq!(from_bytes(&b).unwrap()[1].values_f64()[5], 6.5);
        for cut in [0, 11, 13, 20, 40] {
            assert!(from_bytes(&b[..cut]).is_err(), "{cut}");
        }
        // A field reaching past the end.
        let mut short = b.clone();
        short.truncate(b.len() - 16);
        assert!(
            from_bytes(&short)
                .unwrap_err()
                .to_string()
                .contains("past the end")
        );
        assert!(describe(&fields).contains("field a            float32  [2, 3]"));
    }
}
