//! The one container of goniospec's binary files: `.gsa` accumulators and `.gsb` BRDFs.
//!
//! Layout (little endian):
//!
//! ```text
//! magic        8 bytes   b"GSPECACC" (.gsa) or b"GSPECBRD" (.gsb)
//! version      u32       the format's version
//! header_len   u32       bytes of the header
//! payload_len  u64       bytes of the payload
//! header       UTF-8     TOML describing the payload
//! payload      bytes     the format's arrays
//! crc32        u32       CRC-32 (IEEE 802.3, `crc32fast`) of every byte before it
//! ```
//!
//! Both lengths are declared up front, so a cut file is reported as truncated (with the
//! size it should have) before the checksum is computed, and a damaged one as corrupted.
//! The checksum proves a file was not damaged, not that its writer made sense: each format
//! validates its header and payload after [`decode`].
//!
//! Files of the previous layout (`.gsa` version 2, `.gsb` version 1: no payload length, an
//! FNV-1a 64 trailer) still read; any other version is refused with a message naming it.

use std::path::Path;

/// One file format carried by the container.
#[derive(Clone, Copy, Debug)]
pub struct Format {
    pub magic: &'static [u8; 8],
    /// What the file is, for messages: "accumulator (.gsa)".
    pub what: &'static str,
    /// The version this build writes.
    pub version: u32,
    /// The version of the previous layout (FNV-1a 64 trailer) this build still reads.
    pub legacy_version: Option<u32>,
}

/// A decoded frame: the version it was written with, its header and its payload.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame<'a> {
    pub version: u32,
    pub header: &'a str,
    pub payload: &'a [u8],
}

/// Why a goniospec file was refused.
#[derive(Debug, thiserror::Error)]
pub enum FileError {
    #[error("{path}: cannot read: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("{path}: not a goniospec {what} file (wrong magic bytes)")]
    Magic { path: String, what: &'static str },
    #[error("{path}: {what} format version {found} is not supported (this build reads {reads})")]
    Version {
        path: String,
        what: &'static str,
        found: u32,
        reads: String,
    },
    #[error("{path}: the file is truncated ({0} bytes, expected {1})", .sizes.0, .sizes.1)]
    Truncated { path: String, sizes: (u64, u64) },
    #[error("{path}: checksum mismatch: the file is corrupted")]
    Checksum { path: String },
    #[error("{path}: bad content: {message}")]
    Content { path: String, message: String },
    #[error("cannot merge: {0}")]
    Merge(String),
}

impl FileError {
    /// A content error for `path`.
    pub fn content(path: &str, message: impl Into<String>) -> FileError {
        FileError::Content {
            path: path.to_string(),
            message: message.into(),
        }
    }
}

/// Bytes before the header in the current layout.
const PREAMBLE: usize = 8 + 4 + 4 + 8;
/// Bytes before the header in the legacy layout.
const LEGACY_PREAMBLE: usize = 8 + 4 + 4;

/// CRC-32 (IEEE) of `bytes`.
pub fn checksum(bytes: &[u8]) -> u32 {
    crc32fast::hash(bytes)
}

/// Frames `header` and `payload` (deterministic bytes).
pub fn encode(format: &Format, header: &str, payload: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(PREAMBLE + header.len() + payload.len() + 4);
    out.extend_from_slice(format.magic);
    out.extend_from_slice(&format.version.to_le_bytes());
    let hlen = u32::try_from(header.len()).expect("headers are small");
    out.extend_from_slice(&hlen.to_le_bytes());
    out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    out.extend_from_slice(payload);
    let sum = checksum(&out);
    out.extend_from_slice(&sum.to_le_bytes());
    out
}

/// Recomputes the trailing checksum of a current-layout file in place (tools that craft
/// files on purpose: tests and fuzzers). Does nothing to a buffer shorter than a trailer.
pub fn reseal(bytes: &mut [u8]) {
    if let Some(n) = bytes.len().checked_sub(4) {
        let sum = checksum(&bytes[..n]);
        bytes[n..].copy_from_slice(&sum.to_le_bytes());
    }
}

/// Reads `path` whole and decodes it with [`decode`]; returns the bytes for the caller to
/// borrow the frame from.
pub fn read(path: &Path) -> Result<Vec<u8>, FileError> {
    crate::io::read_input(path, u64::MAX).map_err(|source| FileError::Io {
        path: path.display().to_string(),
        source,
    })
}

fn u32_at(bytes: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(bytes[at..at + 4].try_into().expect("4 bytes"))
}

fn u64_at(bytes: &[u8], at: usize) -> u64 {
    u64::from_le_bytes(bytes[at..at + 8].try_into().expect("8 bytes"))
}

/// Checks magic, version, lengths and checksum; returns the header and payload.
pub fn decode<'a>(format: &Format, bytes: &'a [u8], path: &str) -> Result<Frame<'a>, FileError> {
    let p = || path.to_string();
    if bytes.len() < 8 || &bytes[..8] != format.magic {
        return Err(FileError::Magic {
            path: p(),
            what: format.what,
        });
    }
    let n = bytes.len() as u64;
    if bytes.len() < 12 {
        return Err(FileError::Truncated {
            path: p(),
            sizes: (n, PREAMBLE as u64),
        });
    }
    let version = u32_at(bytes, 8);
    if Some(version) == format.legacy_version {
        return decode_legacy(bytes, version, path);
    }
    if version != format.version {
        let reads = match format.legacy_version {
            Some(v) => format!("versions {v} and {}", format.version),
            None => format!("version {}", format.version),
        };
        return Err(FileError::Version {
            path: p(),
            what: format.what,
            found: version,
            reads,
        });
    }
    if bytes.len() < PREAMBLE {
        return Err(FileError::Truncated {
            path: p(),
            sizes: (n, PREAMBLE as u64),
        });
    }
    let hlen = u64::from(u32_at(bytes, 12));
    let plen = u64_at(bytes, 16);
    // Declared sizes in u128: a damaged length cannot overflow the sum.
    let want = PREAMBLE as u128 + u128::from(hlen) + u128::from(plen) + 4;
    if u128::from(n) != want {
        if u128::from(n) < want {
            return Err(FileError::Truncated {
                path: p(),
                sizes: (n, u64::try_from(want).unwrap_or(u64::MAX)),
            });
        }
        // Extra bytes: the lengths or the file were damaged.
        return Err(FileError::Checksum { path: p() });
    }
    let end = bytes.len() - 4;
    if checksum(&bytes[..end]) != u32_at(bytes, end) {
        return Err(FileError::Checksum { path: p() });
    }
    let h_end = PREAMBLE + hlen as usize;
    let header = std::str::from_utf8(&bytes[PREAMBLE..h_end])
        .map_err(|_| FileError::content(path, "the header is not UTF-8"))?;
    Ok(Frame {
        version,
        header,
        payload: &bytes[h_end..end],
    })
}

/// The previous layout: magic, version, header length (u32), header, payload, FNV-1a 64 of
/// everything before it. It declared no payload length, so a cut file shows as corrupted
/// unless the header itself is cut.
fn decode_legacy<'a>(bytes: &'a [u8], version: u32, path: &str) -> Result<Frame<'a>, FileError> {
    let n = bytes.len();
    if n < LEGACY_PREAMBLE + 8 {
        return Err(FileError::Truncated {
            path: path.to_string(),
            sizes: (n as u64, (LEGACY_PREAMBLE + 8) as u64),
        });
    }
    let hlen = u32_at(bytes, 12) as usize;
    if LEGACY_PREAMBLE + hlen + 8 > n {
        return Err(FileError::Truncated {
            path: path.to_string(),
            sizes: (n as u64, (LEGACY_PREAMBLE + hlen + 8) as u64),
        });
    }
    if crate::io::fnv1a(&bytes[..n - 8]) != u64_at(bytes, n - 8) {
        return Err(FileError::Checksum {
            path: path.to_string(),
        });
    }
    let h_end = LEGACY_PREAMBLE + hlen;
    let header = std::str::from_utf8(&bytes[LEGACY_PREAMBLE..h_end])
        .map_err(|_| FileError::content(path, "the header is not UTF-8"))?;
    Ok(Frame {
        version,
        header,
        payload: &bytes[h_end..n - 8],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const F: Format = Format {
        magic: b"GSPECTST",
        what: "test (.gst)",
        version: 7,
        legacy_version: Some(6),
    };

    /// The CRC-32 check value of the IEEE polynomial (the catalogue's "123456789" test
    /// vector, Greg Cook's CRC RevEng catalogue: CRC-32/ISO-HDLC check = 0xCBF43926).
    #[test]
    fn checksum_is_crc32_ieee() {
        assert_eq!(checksum(b"123456789"), 0xCBF4_3926);
    }

    #[test]
    fn round_trip_and_every_damage_is_named() {
        let bytes = encode(&F, "a = 1\n", &[1, 2, 3, 4, 5]);
        let f = decode(&F, &bytes, "x").unwrap();
        assert_eq!(
            (f.version, f.header, f.payload),
            (7, "a = 1\n", &[1u8, 2, 3, 4, 5][..])
        );
        // Every cut is truncated, naming the size it should have.
        for cut in 12..bytes.len() {
            let e = decode(&F, &bytes[..cut], "x").unwrap_err().to_string();
            assert!(
                e.contains("truncated") && e.contains(&format!("expected {}", bytes.len()))
                    || cut < PREAMBLE && e.contains("truncated"),
                "{cut}: {e}"
            );
        }
        // Every flipped bit after the version is caught.
        for i in 12..bytes.len() {
            for bit in 0..8 {
                let mut bad = bytes.clone();
                bad[i] ^= 1 << bit;
                assert!(decode(&F, &bad, "x").is_err(), "byte {i} bit {bit}");
            }
        }
        let mut v = bytes.clone();
        v[8] = 9;
        let e = decode(&F, &v, "x").unwrap_err().to_string();
        assert!(
            e.contains("version 9") && e.contains("versions 6 and 7"),
            "{e}"
        );
        let e = decode(&F, b"GSPECACC", "x").unwrap_err().to_string();
        assert!(
            e.contains("wrong magic") && e.contains("test (.gst)"),
            "{e}"
        );
        let mut long = bytes.clone();
        long.push(0);
        assert!(decode(&F, &long, "x").is_err());
    }

    /// A legacy frame, written here byte by byte from its documented layout.
    #[test]
    fn legacy_frames_still_read() {
        let mut b = b"GSPECTST".to_vec();
        b.extend_from_slice(&6u32.to_le_bytes());
        b.extend_from_slice(&3u32.to_le_bytes());
        b.extend_from_slice(b"h=1");
        b.extend_from_slice(&[9, 8]);
        // FNV-1a 64: offset basis 0xcbf29ce484222325, prime 0x100000001b3.
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        for &x in &b {
            h = (h ^ u64::from(x)).wrapping_mul(0x0100_0000_01b3);
        }
        b.extend_from_slice(&h.to_le_bytes());
        let f = decode(&F, &b, "x").unwrap();
        assert_eq!((f.version, f.header, f.payload), (6, "h=1", &[9u8, 8][..]));
        let n = b.len();
        b[n - 9] ^= 1;
        assert!(
            decode(&F, &b, "x")
                .unwrap_err()
                .to_string()
                .contains("checksum")
        );
    }

    #[test]
    fn reseal_makes_a_crafted_file_pass_the_checksum() {
        let mut bytes = encode(&F, "a = 1\n", &[1, 2, 3]);
        let at = PREAMBLE + 6;
        bytes[at] = 42;
        assert!(decode(&F, &bytes, "x").is_err());
        reseal(&mut bytes);
        assert_eq!(decode(&F, &bytes, "x").unwrap().payload, &[42, 2, 3]);
    }
}
