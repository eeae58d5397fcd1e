//! The bucket files: one zstd frame per spill of a tile's points (id, x, y, z in f64, a
//! normal flag and the normal), appended to `b_<x>_<y>.zst` in a bucket task's directory.

use std::fs::OpenOptions;
use std::io::Write;
use std::path::{Path, PathBuf};

use rayon::prelude::*;

use crate::core::plan::TileKey;
use crate::core::point::SourcePoint;
use crate::error::{Error, Result};

/// The bucket file of a tile in a bucket task's directory.
pub fn bucket_file(dir: &Path, key: TileKey) -> PathBuf {
    dir.join(format!("b_{}_{}.zst", key.0, key.1))
}

/// Encodes points as a zstd frame: per point id, x, y, z and a normal flag (+ normal).
pub fn encode_frame(points: &[SourcePoint]) -> std::io::Result<Vec<u8>> {
    let mut raw = Vec::with_capacity(points.len() * 57);
    for p in points {
        raw.extend_from_slice(&p.id.to_le_bytes());
        for c in p.xyz {
            raw.extend_from_slice(&c.to_le_bytes());
        }
        match p.normal {
            Some(n) => {
                raw.push(1);
                for c in n {
                    raw.extend_from_slice(&c.to_le_bytes());
                }
            }
            None => raw.push(0),
        }
    }
    zstd::bulk::compress(&raw, 1)
}

pub fn decode_frames(path: &Path, bytes: &[u8]) -> Result<Vec<SourcePoint>> {
    let bad = |what: &str| {
        Error::Internal(format!(
            "{}: spill file {what}; delete the work directory and run again",
            path.display()
        ))
    };
    let raw = zstd::stream::decode_all(bytes).map_err(|_| bad("is corrupt"))?;
    let mut out = Vec::with_capacity(raw.len() / 33);
    let mut pos = 0;
    let f = |b: &[u8], at: usize| -> Option<f64> {
        Some(f64::from_le_bytes(b.get(at..at + 8)?.try_into().ok()?))
    };
    while pos < raw.len() {
        let id = u64::from_le_bytes(
            raw.get(pos..pos + 8)
                .and_then(|s| s.try_into().ok())
                .ok_or_else(|| bad("is truncated"))?,
        );
        let xyz = [f(&raw, pos + 8), f(&raw, pos + 16), f(&raw, pos + 24)];
        let [Some(x), Some(y), Some(z)] = xyz else {
            return Err(bad("is truncated"));
        };
        let has_normal = *raw.get(pos + 32).ok_or_else(|| bad("is truncated"))?;
        pos += 33;
        let normal = if has_normal == 1 {
            let n = [f(&raw, pos), f(&raw, pos + 8), f(&raw, pos + 16)];
            pos += 24;
            match n {
                [Some(a), Some(b), Some(c)] => Some([a, b, c]),
                _ => return Err(bad("is truncated")),
            }
        } else {
            None
        };
        out.push(SourcePoint {
            id,
            xyz: [x, y, z],
            normal,
        });
    }
    Ok(out)
}

/// Appends one frame per bucket of `buckets` to its bucket file. The frames are compressed in
/// parallel (on the caller's rayon pool), then appended in the given order.
pub fn spill(dir: &Path, buckets: Vec<(TileKey, Vec<SourcePoint>)>) -> Result<()> {
    let frames: Vec<(TileKey, std::io::Result<Vec<u8>>)> = buckets
        .into_par_iter()
        .map(|(key, points)| (key, encode_frame(&points)))
        .collect();
    for (key, frame) in frames {
        let path = bucket_file(dir, key);
        let frame = frame.map_err(|e| Error::write(&path, e))?;
        let mut f = OpenOptions::new()
            .create(true)
            .append(true)
            .open(&path)
            .map_err(|e| Error::write(&path, e))?;
        f.write_all(&frame).map_err(|e| Error::write(&path, e))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_round_trip() {
        let pts = vec![
            SourcePoint {
                id: 7,
                xyz: [1.5, -2.25, 1e6 + 0.125],
                normal: None,
            },
            SourcePoint {
                id: u64::MAX,
                xyz: [0.1, 0.2, 0.3],
                normal: Some([0.0, 0.6, 0.8]),
            },
        ];
        let mut bytes = encode_frame(&pts).expect("encode");
        bytes.extend(encode_frame(&pts[..1]).expect("encode"));
        let back = decode_frames(Path::new("x"), &bytes).expect("decode");
        assert_eq!(back, [pts[0], pts[1], pts[0]]);
    }
}
