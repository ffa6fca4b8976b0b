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
//! Data types are Mitsuba's `Struct::Type` codes (`include/mitsuba/core/struct.h`, and the
//! RGL loader's `Tensor::Type` in `powitacq.inl`, which numbers them alike): UInt8 = 1,
//! Int8 = 2, UInt16 = 3, Int16 = 4, UInt32 = 5, Int32 = 6, UInt64 = 7, Int64 = 8,
//! Float16 = 9, Float32 = 10, Float64 = 11. Every one is read (the measured files of the
//! RGL database store `version` as UInt32); the writer uses UInt8, UInt16 and Float32.

use super::ExportError;
use std::io::Write;
use std::path::Path;

const MAGIC: &[u8; 12] = b"tensor_file\0";

/// Element types of a field (Mitsuba `Struct::Type` codes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dtype {
    UInt8 = 1,
    Int8 = 2,
    UInt16 = 3,
    Int16 = 4,
    UInt32 = 5,
    Int32 = 6,
    UInt64 = 7,
    Int64 = 8,
    Float16 = 9,
    Float32 = 10,
    Float64 = 11,
}

impl Dtype {
    /// Every type, in code order.
    pub const ALL: [Dtype; 11] = [
        Dtype::UInt8,
        Dtype::Int8,
        Dtype::UInt16,
        Dtype::Int16,
        Dtype::UInt32,
        Dtype::Int32,
        Dtype::UInt64,
        Dtype::Int64,
        Dtype::Float16,
        Dtype::Float32,
        Dtype::Float64,
    ];
    fn from_code(c: u8) -> Option<Dtype> {
        Dtype::ALL.into_iter().find(|d| *d as u8 == c)
    }
    /// Bytes per element.
    pub fn size(self) -> usize {
        match self {
            Dtype::UInt8 | Dtype::Int8 => 1,
            Dtype::UInt16 | Dtype::Int16 | Dtype::Float16 => 2,
            Dtype::UInt32 | Dtype::Int32 | Dtype::Float32 => 4,
            Dtype::UInt64 | Dtype::Int64 | Dtype::Float64 => 8,
        }
    }
    pub fn name(self) -> &'static str {
        match self {
            Dtype::UInt8 => "uint8",
            Dtype::Int8 => "int8",
            Dtype::UInt16 => "uint16",
            Dtype::Int16 => "int16",
            Dtype::UInt32 => "uint32",
            Dtype::Int32 => "int32",
            Dtype::UInt64 => "uint64",
            Dtype::Int64 => "int64",
            Dtype::Float16 => "float16",
            Dtype::Float32 => "float32",
            Dtype::Float64 => "float64",
        }
    }
    /// Whether the type holds floating-point values.
    pub fn is_float(self) -> bool {
        matches!(self, Dtype::Float16 | Dtype::Float32 | Dtype::Float64)
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
    /// The element count (the product of the shape), or `None` where it overflows.
    pub fn len(&self) -> Option<u64> {
        self.shape.iter().try_fold(1u64, |a, &s| a.checked_mul(s))
    }

    /// Whether the field holds no element.
    pub fn is_empty(&self) -> bool {
        self.len() == Some(0)
    }

    /// The values as f64, C order: integers exactly up to 2^53, half floats by IEEE
    /// 754-2008 binary16 ([`f16_to_f64`]).
    pub fn values_f64(&self) -> Vec<f64> {
        let n = self.dtype.size();
        let words = self.data.chunks_exact(n);
        let b = |c: &[u8], k: usize| -> [u8; 8] {
            let mut a = [0u8; 8];
            a[..k].copy_from_slice(&c[..k]);
            a
        };
        match self.dtype {
            Dtype::UInt8 => self.data.iter().map(|&v| f64::from(v)).collect(),
            Dtype::Int8 => self.data.iter().map(|&v| f64::from(v as i8)).collect(),
            Dtype::UInt16 => words
                .map(|c| f64::from(u16::from_le_bytes([c[0], c[1]])))
                .collect(),
            Dtype::Int16 => words
                .map(|c| f64::from(i16::from_le_bytes([c[0], c[1]])))
                .collect(),
            Dtype::UInt32 => words
                .map(|c| f64::from(u32::from_le_bytes([c[0], c[1], c[2], c[3]])))
                .collect(),
            Dtype::Int32 => words
                .map(|c| f64::from(i32::from_le_bytes([c[0], c[1], c[2], c[3]])))
                .collect(),
            Dtype::UInt64 => words.map(|c| u64::from_le_bytes(b(c, 8)) as f64).collect(),
            Dtype::Int64 => words.map(|c| i64::from_le_bytes(b(c, 8)) as f64).collect(),
            Dtype::Float16 => words
                .map(|c| f16_to_f64(u16::from_le_bytes([c[0], c[1]])))
                .collect(),
            Dtype::Float32 => words
                .map(|c| f64::from(f32::from_le_bytes([c[0], c[1], c[2], c[3]])))
                .collect(),
            Dtype::Float64 => words.map(|c| f64::from_le_bytes(b(c, 8))).collect(),
        }
    }
}

/// An IEEE 754-2008 binary16 value (1 sign bit, 5 exponent bits of bias 15, 10 fraction
/// bits; subnormals, infinities and NaN included) as f64, exactly.
pub fn f16_to_f64(bits: u16) -> f64 {
    let sign = if bits & 0x8000 != 0 { -1.0 } else { 1.0 };
    let exp = i32::from((bits >> 10) & 0x1f);
    let frac = f64::from(bits & 0x3ff);
    sign * match exp {
        0 => frac * 2f64.powi(-24),
        31 if frac == 0.0 => f64::INFINITY,
        31 => f64::NAN,
        e => (1.0 + frac / 1024.0) * 2f64.powi(e - 15),
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
    // Every field's data lies within the file, and real files never overlap their fields:
    // the fields together may hold at most the file's own size, so that a header naming
    // many fields over the same bytes cannot make the reader allocate more than it read.
    let mut total = 0u64;
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
        total += len;
        if total > bytes.len() as u64 {
            return Err(ExportError::from(format!(
                "the fields up to '{name}' hold {total} bytes, more than the file's {}",
                bytes.len()
            )));
        }
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

    /// Every dtype of the format reads, with its code, size and values: integers of each
    /// width and sign, and IEEE binary16 at its landmarks (1, -2, the largest normal
    /// 65504, the smallest subnormal 2^-24, infinity), written here byte by byte.
    #[test]
    fn every_dtype_reads() {
        let field = |dtype: Dtype, data: Vec<u8>| Field {
            name: "x".into(),
            dtype,
            shape: vec![(data.len() / dtype.size()) as u64],
            data,
        };
        let cases: Vec<(Dtype, Vec<u8>, Vec<f64>)> = vec![
            (Dtype::UInt8, vec![0, 255], vec![0.0, 255.0]),
            (Dtype::Int8, vec![0x80, 0x7f], vec![-128.0, 127.0]),
            (Dtype::UInt16, vec![0xff, 0xff], vec![65535.0]),
            (Dtype::Int16, vec![0x00, 0x80], vec![-32768.0]),
            (
                Dtype::UInt32,
                vec![1, 0, 0, 0, 0, 0, 0, 0x80],
                vec![1.0, 2147483648.0],
            ),
            (Dtype::Int32, vec![0xff, 0xff, 0xff, 0xff], vec![-1.0]),
            (
                Dtype::UInt64,
                vec![0, 0, 0, 0, 1, 0, 0, 0],
                vec![4294967296.0],
            ),
            (
                Dtype::Int64,
                vec![0xfe, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff],
                vec![-2.0],
            ),
            (
                Dtype::Float16,
                vec![0x00, 0x3c, 0x00, 0xc0, 0xff, 0x7b, 0x01, 0x00, 0x00, 0x7c],
                vec![1.0, -2.0, 65504.0, 2f64.powi(-24), f64::INFINITY],
            ),
            (
                Dtype::Float32,
                0.15625f32.to_le_bytes().to_vec(),
                vec![0.15625],
            ),
            (Dtype::Float64, (-1.5f64).to_le_bytes().to_vec(), vec![-1.5]),
        ];
        for (code, (dtype, data, want)) in (1u8..).zip(cases) {
            assert_eq!(dtype as u8, code);
            let f = field(dtype, data);
            let bytes = to_bytes(std::slice::from_ref(&f));
            let back = from_bytes(&bytes).unwrap();
            assert_eq!(back[0].dtype, dtype);
            assert_eq!(back[0].values_f64(), want, "{}", dtype.name());
        }
        assert!(f16_to_f64(0x7e00).is_nan());
        assert_eq!(f16_to_f64(0x8000).to_bits(), (-0.0f64).to_bits());
    }

    /// A header whose fields all point at the same bytes would make the reader copy the
    /// file many times over: refused once the fields hold more than the file.
    #[test]
    fn fields_holding_more_than_the_file_are_refused() {
        let f = Field::f32("a", &[64], &[1.0; 64]);
        let mut many = to_bytes(&[f.clone(), f.clone(), f.clone()]);
        // Each field's header: name length, name, ndim, dtype, then its data offset.
        let header = |k: usize| 18 + k * (2 + 1 + 2 + 1 + 8 + 8) + 2 + 1 + 2 + 1;
        // Point the second and third fields at the first one's data.
        let off = u64::from_le_bytes(many[header(0)..header(0) + 8].try_into().unwrap());
        for k in 1..3 {
            many[header(k)..header(k) + 8].copy_from_slice(&off.to_le_bytes());
        }
        many.truncate(off as usize + 256 + 8);
        let e = from_bytes(&many).unwrap_err().to_string();
        assert!(e.contains("more than the file"), "{e}");
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
