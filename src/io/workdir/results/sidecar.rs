//! The orientation sidecars of `--orient propagate` (`tile_<x>_<y>.ori` beside the result
//! files): each tile's patch anchors and the normals it shares with other tiles, read back by
//! the cross-tile sign resolution (run::orientation).

use std::path::{Path, PathBuf};

use crate::core::plan::TileKey;
use crate::error::{Error, Result};
use crate::io::durable::tmp_name;
use crate::io::pack::{compress, decompress_into, get_planes, put_planes, Cursor, Effort};

const ORIENT_MAGIC: &[u8; 8] = b"TCORI003";

/// The orientation sidecar of a tile (`--orient propagate`): its patch anchors and the normals
/// it shares with other tiles, for the cross-tile sign resolution.
pub(crate) fn orientation_path(dir: &Path, key: TileKey) -> PathBuf {
    crate::io::workdir::names::tile_orientation(dir, key)
}

/// What a tile's passes contribute to the cross-tile orientation.
#[derive(Debug, Clone, Default)]
pub(crate) struct TileSidecar {
    /// One anchor per patch (patches numbered within the tile).
    pub anchors: Vec<crate::core::orient::PatchAnchor>,
    /// Normals of points other passes also orient.
    pub shared: Vec<crate::core::orient::SharedNormal>,
}

/// Bytes of one anchor in a sidecar: patch (u32), dist2 (f64), position (3 f64), id (u64),
/// outward (u8), little-endian.
const ANCHOR_BYTES: usize = 4 + 8 + 24 + 8 + 1;

/// Bytes of one shared normal: id (u64), patch (u32), normal (3 f64).
const SHARED_BYTES: usize = 8 + 4 + 24;

/// Writes a sidecar under its temporary name and returns it: [`ORIENT_MAGIC`], the content's
/// length (u64) and one zstd frame with a checksum ([`crate::io::pack`]) of the counts of
/// anchors and shared normals (u64 each) and the byte planes of their records.
pub(super) fn write_sidecar(path: &Path, s: &TileSidecar) -> Result<PathBuf> {
    let tmp = tmp_name(path);
    let mut anchors = Vec::with_capacity(ANCHOR_BYTES * s.anchors.len());
    for a in &s.anchors {
        anchors.extend_from_slice(&a.patch.to_le_bytes());
        anchors.extend_from_slice(&a.dist2.to_le_bytes());
        for c in a.pos {
            anchors.extend_from_slice(&c.to_le_bytes());
        }
        anchors.extend_from_slice(&a.id.to_le_bytes());
        anchors.push(a.outward as u8);
    }
    let mut shared = Vec::with_capacity(SHARED_BYTES * s.shared.len());
    for n in &s.shared {
        shared.extend_from_slice(&n.id.to_le_bytes());
        shared.extend_from_slice(&n.patch.to_le_bytes());
        for c in n.normal {
            shared.extend_from_slice(&c.to_le_bytes());
        }
    }
    let mut raw = Vec::with_capacity(16 + anchors.len() + shared.len());
    raw.extend_from_slice(&(s.anchors.len() as u64).to_le_bytes());
    raw.extend_from_slice(&(s.shared.len() as u64).to_le_bytes());
    put_planes(&mut raw, &anchors, ANCHOR_BYTES);
    put_planes(&mut raw, &shared, SHARED_BYTES);
    let frame = compress(&raw, Effort::Small).map_err(|e| Error::write(&tmp, e))?;
    let b = [&ORIENT_MAGIC[..], &(raw.len() as u64).to_le_bytes(), &frame].concat();
    std::fs::write(&tmp, &b).map_err(|e| Error::write(&tmp, e))?;
    Ok(tmp)
}

/// Reads a tile's orientation sidecar (`write_sidecar`); a damaged one is an error naming
/// it.
pub(crate) fn read_sidecar(path: &Path) -> Result<TileSidecar> {
    let bad = || Error::damaged_work(path, "orientation sidecar is damaged");
    let b = std::fs::read(path).map_err(|e| Error::read_work(path, e))?;
    let mut c = Cursor::new(&b);
    if c.take(8) != Some(&ORIENT_MAGIC[..]) {
        return Err(Error::damaged_work(
            path,
            "orientation sidecar is not of this version of tilecurv",
        ));
    }
    let len = c.u64().ok_or_else(bad)? as usize;
    let frame = c.take(c.remaining()).ok_or_else(bad)?;
    let mut raw = Vec::new();
    // A damaged length is refused before it is allocated: zstd packs at most ~32000:1.
    if len > frame.len().saturating_mul(1 << 15) || !decompress_into(frame, len, &mut raw) {
        return Err(bad());
    }
    let mut c = Cursor::new(&raw);
    let (na, ns) = (c.u64().ok_or_else(bad)?, c.u64().ok_or_else(bad)?);
    let sizes = (na as usize).checked_mul(ANCHOR_BYTES);
    let Some((a_len, s_len)) = sizes.zip((ns as usize).checked_mul(SHARED_BYTES)) else {
        return Err(bad());
    };
    let (Some(a_planes), Some(s_planes)) = (c.take(a_len), c.take(s_len)) else {
        return Err(bad());
    };
    if !c.is_done() {
        return Err(bad());
    }
    let (mut anchors, mut shared) = (Vec::new(), Vec::new());
    get_planes(&mut anchors, a_planes, na as usize, ANCHOR_BYTES);
    get_planes(&mut shared, s_planes, ns as usize, SHARED_BYTES);
    // Records of a fixed size cut from planes of that size: every field is there.
    let anchor = |r: &[u8]| {
        let mut c = Cursor::new(r);
        Some(crate::core::orient::PatchAnchor {
            patch: c.u32()?,
            dist2: c.f64()?,
            pos: [c.f64()?, c.f64()?, c.f64()?],
            id: c.u64()?,
            outward: c.u8()? == 1,
        })
    };
    let normal = |r: &[u8]| {
        let mut c = Cursor::new(r);
        Some(crate::core::orient::SharedNormal {
            id: c.u64()?,
            patch: c.u32()?,
            normal: [c.f64()?, c.f64()?, c.f64()?],
        })
    };
    let anchors: Option<Vec<_>> = anchors.chunks_exact(ANCHOR_BYTES).map(anchor).collect();
    let shared: Option<Vec<_>> = shared.chunks_exact(SHARED_BYTES).map(normal).collect();
    let (Some(anchors), Some(shared)) = (anchors, shared) else {
        return Err(bad());
    };
    let out = TileSidecar { anchors, shared };
    // A tile numbers its patches 0, 1, ... in the order of their anchors; a checksum-valid but
    // inconsistent sidecar would otherwise skew the orientation signs of the whole scene.
    let numbered = out
        .anchors
        .iter()
        .enumerate()
        .all(|(i, a)| a.patch as usize == i);
    if !numbered || na > u64::from(u32::MAX) {
        return Err(bad());
    }
    if out.shared.iter().any(|n| u64::from(n.patch) >= na) {
        return Err(bad());
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::orient::{PatchAnchor, SharedNormal};

    #[test]
    fn sidecars_round_trip_and_damage_is_refused() {
        let dir = tempfile::tempdir().expect("temp dir");
        let s = TileSidecar {
            anchors: (0..40u32)
                .map(|i| PatchAnchor {
                    patch: i,
                    dist2: i as f64 * 0.25,
                    pos: [5e5 + i as f64, 4.1e6, -0.0],
                    id: 1000 + i as u64,
                    outward: i % 3 == 0,
                })
                .collect(),
            shared: (0..500u64)
                .map(|i| SharedNormal {
                    id: i * 7,
                    patch: (i % 40) as u32,
                    normal: [0.6, 0.0, 0.8 - i as f64 * 1e-9],
                })
                .collect(),
        };
        let path = orientation_path(dir.path(), (3, -4));
        std::fs::rename(write_sidecar(&path, &s).expect("write"), &path).expect("rename");
        let back = read_sidecar(&path).expect("read");
        assert_eq!(format!("{:?}", back), format!("{s:?}"));
        let good = std::fs::read(&path).expect("bytes");
        assert!(good.len() < 16 + 45 * 40 + 36 * 500, "{} bytes", good.len());
        let mut flipped = good.clone();
        flipped[good.len() / 2] ^= 2;
        for bad in [&good[..good.len() - 1], &flipped[..], &good[..12]] {
            std::fs::write(&path, bad).expect("write");
            let e = read_sidecar(&path).expect_err("damaged");
            assert_eq!(e.exit_class(), crate::error::ExitClass::Output);
            assert!(e.to_string().contains("tile_3_-4.ori"), "{e}");
        }
        // Checksum-valid but inconsistent: a shared normal of a patch the tile has no anchor
        // for, and anchors not numbered 0, 1, ... in order.
        let mut stray = s.clone();
        stray.shared[7].patch = 40;
        let mut misnumbered = s.clone();
        misnumbered.anchors.swap(3, 4);
        for bad in [stray, misnumbered] {
            std::fs::rename(write_sidecar(&path, &bad).expect("write"), &path).expect("rename");
            let e = read_sidecar(&path).expect_err("inconsistent");
            assert!(
                e.to_string().contains("orientation sidecar is damaged"),
                "{e}"
            );
        }
    }
}
