//! The orientation sidecars of `--orient propagate` (`tile_<x>_<y>.ori` beside the result
//! files): each tile's patch anchors and the normals it shares with other tiles, read back by
//! the cross-tile sign resolution (run::orientation).

use std::path::{Path, PathBuf};

use crate::core::plan::TileKey;
use crate::error::{Error, Result};
use crate::io::workdir::tmp_name;

const ORIENT_MAGIC: &[u8; 8] = b"TCORI002";

/// The orientation sidecar of a tile (`--orient propagate`): its patch anchors and the normals
/// it shares with other tiles, for the cross-tile sign resolution.
pub fn orientation_path(dir: &Path, key: TileKey) -> PathBuf {
    dir.join(format!("tile_{}_{}.ori", key.0, key.1))
}

/// What a tile's passes contribute to the cross-tile orientation.
#[derive(Debug, Clone, Default)]
pub struct TileSidecar {
    /// One anchor per patch (patches numbered within the tile).
    pub anchors: Vec<crate::core::orient::PatchAnchor>,
    /// Normals of points other passes also orient.
    pub shared: Vec<crate::core::orient::SharedNormal>,
}

/// Bytes of one anchor in a sidecar: patch (u32), dist2 (f64), position (3 f64), id (u64),
/// outward (u8), little-endian.
const ANCHOR_BYTES: usize = 4 + 8 + 24 + 8 + 1;

pub(super) fn write_sidecar(path: &Path, s: &TileSidecar) -> Result<PathBuf> {
    let tmp = tmp_name(path);
    let mut b = Vec::with_capacity(24 + ANCHOR_BYTES * s.anchors.len() + 36 * s.shared.len());
    b.extend_from_slice(ORIENT_MAGIC);
    b.extend_from_slice(&(s.anchors.len() as u64).to_le_bytes());
    b.extend_from_slice(&(s.shared.len() as u64).to_le_bytes());
    for a in &s.anchors {
        b.extend_from_slice(&a.patch.to_le_bytes());
        b.extend_from_slice(&a.dist2.to_le_bytes());
        for c in a.pos {
            b.extend_from_slice(&c.to_le_bytes());
        }
        b.extend_from_slice(&a.id.to_le_bytes());
        b.push(a.outward as u8);
    }
    for n in &s.shared {
        b.extend_from_slice(&n.id.to_le_bytes());
        b.extend_from_slice(&n.patch.to_le_bytes());
        for c in n.normal {
            b.extend_from_slice(&c.to_le_bytes());
        }
    }
    std::fs::write(&tmp, &b).map_err(|e| Error::write(&tmp, e))?;
    Ok(tmp)
}

/// Reads a tile's orientation sidecar.
pub fn read_sidecar(path: &Path) -> Result<TileSidecar> {
    let bad = || {
        Error::Internal(format!(
            "{}: orientation sidecar is damaged; delete the work directory and run again",
            path.display()
        ))
    };
    let b = std::fs::read(path).map_err(|e| Error::read_work(path, e))?;
    let u64_at = |o: usize| {
        b.get(o..o + 8)
            .and_then(|s| s.try_into().ok())
            .map(u64::from_le_bytes)
            .ok_or_else(bad)
    };
    let u32_at = |o: usize| {
        b.get(o..o + 4)
            .and_then(|s| s.try_into().ok())
            .map(u32::from_le_bytes)
            .ok_or_else(bad)
    };
    let f64_at = |o: usize| u64_at(o).map(f64::from_bits);
    if b.get(..8) != Some(&ORIENT_MAGIC[..]) {
        return Err(bad());
    }
    let (na, ns) = (u64_at(8)? as usize, u64_at(16)? as usize);
    let mut out = TileSidecar::default();
    let mut o = 24;
    for _ in 0..na {
        let outward = *b.get(o + 44).ok_or_else(bad)? == 1;
        out.anchors.push(crate::core::orient::PatchAnchor {
            patch: u32_at(o)?,
            dist2: f64_at(o + 4)?,
            pos: [f64_at(o + 12)?, f64_at(o + 20)?, f64_at(o + 28)?],
            id: u64_at(o + 36)?,
            outward,
        });
        o += ANCHOR_BYTES;
    }
    for _ in 0..ns {
        out.shared.push(crate::core::orient::SharedNormal {
            id: u64_at(o)?,
            patch: u32_at(o + 8)?,
            normal: [f64_at(o + 12)?, f64_at(o + 20)?, f64_at(o + 28)?],
        });
        o += 36;
    }
    Ok(out)
}
