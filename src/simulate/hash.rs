//! The sample's hash: runs merge only when it agrees.

use crate::io::fnv1a;
use crate::sample::Sample;

/// Hash of everything in a sample that changes results: FNV-1a 64 of a canonical encoding of the sample's physics inputs: tile, media (names
/// and index models, [`crate::sample::IndexModel::canonical_bytes`]), interfaces (media,
/// coatings, vertices and triangles). Runs merge only when it agrees.
pub fn sample_hash(sample: &Sample) -> String {
    let mut bytes: Vec<u8> = Vec::new();
    for v in sample.tile_nm {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    for m in &sample.media {
        bytes.extend_from_slice(m.name.as_bytes());
        m.model.canonical_bytes(&mut bytes);
        // Scattering media only, so every other sample keeps its hash.
        if let Some(sc) = &m.scattering {
            sc.canonical_bytes(&mut bytes);
        }
    }
    // Open samples only, so periodic samples keep their hash.
    if let Some(g) = sample.guard_nm {
        bytes.extend_from_slice(b"guard");
        bytes.extend_from_slice(&g.to_le_bytes());
    }
    for i in &sample.interfaces {
        bytes.extend_from_slice(&(i.front as u64).to_le_bytes());
        bytes.extend_from_slice(&(i.back as u64).to_le_bytes());
        // Coated interfaces only, so uncoated samples keep their hash.
        for (m, d) in &i.coating {
            bytes.extend_from_slice(b"coat");
            bytes.extend_from_slice(&(*m as u64).to_le_bytes());
            bytes.extend_from_slice(&d.to_le_bytes());
        }
        for p in &i.mesh.positions_nm {
            for c in p.to_array() {
                bytes.extend_from_slice(&c.to_le_bytes());
            }
        }
        for t in &i.mesh.triangles {
            for c in t {
                bytes.extend_from_slice(&c.to_le_bytes());
            }
        }
    }
    format!("{:016x}", fnv1a(&bytes))
}
