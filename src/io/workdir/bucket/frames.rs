//! The bucket files: one zstd frame per spill of a tile's points, appended to `b_<x>_<y>.zst`
//! in a bucket task's directory. A frame's content is [`MAGIC`] (the format's version), the
//! number of runs, then runs of consecutive points of one input. A run stores its ids as zigzag
//! varints of their differences (buckets are filled in scan order: mostly +1), then each
//! coordinate as a column: the integers the input decoded it from, relative to the run's
//! smallest (`(q * scale + offset) * z factor` gives back the f64 bits, checked when the run is
//! written), or f32 where every value is one, else raw f64; then the file normals if any (f32
//! or f64 columns). Columns are stored as byte planes ([`crate::io::pack`]). Whatever the
//! encoding chosen, the decoded points are the bits that were scanned.

use std::fs::OpenOptions;
use std::io::Write;
use std::path::Path;

use rayon::prelude::*;

use crate::core::grid::AxisGrid;
use crate::core::plan::TileKey;
use crate::core::point::Points;
use crate::error::{Error, Result};
use crate::io::pack::{get_word_planes, put_varint, put_word_planes, unzigzag, zigzag, Cursor};
use crate::io::workdir::names::bucket_file;

/// The first bytes of every decoded frame: the bucket format and its version.
const MAGIC: &[u8; 4] = b"TCB3";

/// The inputs of a scan by id range, with the grids their coordinates decode from.
#[derive(Debug, Clone, Default)]
pub(super) struct Grids {
    /// (first id, grids of x, y and z or None) per input, in id order.
    inputs: Vec<(u64, Option<[AxisGrid; 3]>)>,
}

impl Grids {
    /// Adds the next input: its first global id, and its coordinates' grids if it has some.
    pub(super) fn push(&mut self, first_id: u64, axes: Option<[AxisGrid; 3]>) {
        self.inputs.push((first_id, axes));
    }

    /// The index of the input that point `id` comes from.
    fn input_of(&self, id: u64) -> usize {
        self.inputs
            .partition_point(|(first, _)| *first <= id)
            .max(1)
            - 1
    }

    /// The grid of input `i` on `axis`.
    fn axis(&self, i: usize, axis: usize) -> Option<AxisGrid> {
        self.inputs.get(i).and_then(|(_, a)| a.map(|a| a[axis]))
    }
}

/// Column encodings (the first byte of a column).
const RAW_F64: u8 = 0;
const EXACT_F32: u8 = 1;
const INTEGERS: u8 = 2;

/// Appends one column of values, in the most compact encoding that gives back their bits.
fn put_column(out: &mut Vec<u8>, values: &[f64], grid: Option<AxisGrid>) {
    if let Some(g) = grid {
        let mut q = Vec::with_capacity(values.len());
        if values
            .iter()
            .all(|&v| g.integer(v).map(|i| q.push(i)).is_some())
        {
            let base = q.iter().copied().min().unwrap_or(0);
            let words: Vec<u64> = q.iter().map(|&v| v.abs_diff(base)).collect();
            let span = words.iter().copied().max().unwrap_or(0);
            let width = 8 - span.leading_zeros() as usize / 8;
            out.push(INTEGERS);
            for f in [g.scale(), g.offset(), g.post()] {
                out.extend_from_slice(&f.to_le_bytes());
            }
            out.extend_from_slice(&base.to_le_bytes());
            out.push(width as u8);
            put_word_planes(out, &words, width);
            return;
        }
    }
    if values
        .iter()
        .all(|&v| (v as f32 as f64).to_bits() == v.to_bits())
    {
        out.push(EXACT_F32);
        let words: Vec<u64> = values
            .iter()
            .map(|&v| (v as f32).to_bits() as u64)
            .collect();
        put_word_planes(out, &words, 4);
    } else {
        out.push(RAW_F64);
        let words: Vec<u64> = values.iter().map(|v| v.to_bits()).collect();
        put_word_planes(out, &words, 8);
    }
}

/// Reads one column of `n` values ([`put_column`]).
fn get_column(c: &mut Cursor<'_>, n: usize) -> Option<Vec<f64>> {
    let tag = c.u8()?;
    let (width, grid, base) = match tag {
        INTEGERS => {
            let g = AxisGrid::new(c.f64()?, c.f64()?, c.f64()?);
            let base = c.u64()? as i64;
            (c.u8()? as usize, Some(g), base)
        }
        EXACT_F32 => (4, None, 0),
        RAW_F64 => (8, None, 0),
        _ => return None,
    };
    if width > 8 {
        return None;
    }
    let words = get_word_planes(c.take(n.checked_mul(width)?)?, n, width);
    // A zero-width column (every integer the same) decodes every value from `base` alone.
    Some(match (tag, grid) {
        (INTEGERS, Some(g)) => words
            .iter()
            .map(|&w| g.value(base.wrapping_add(w as i64)))
            .collect(),
        (EXACT_F32, _) => words
            .iter()
            .map(|&w| f32::from_bits(w as u32) as f64)
            .collect(),
        _ => words.iter().map(|&w| f64::from_bits(w)).collect(),
    })
}

/// Appends one run: the points `run` of `points`, of one input (`grids` input `input`).
fn put_run(
    out: &mut Vec<u8>,
    points: &Points,
    run: std::ops::Range<usize>,
    grids: &Grids,
    input: usize,
) {
    out.extend_from_slice(&(run.len() as u32).to_le_bytes());
    let mut prev = 0u64;
    for &id in &points.ids()[run.clone()] {
        put_varint(out, zigzag(id.wrapping_sub(prev) as i64));
        prev = id;
    }
    let xyz = &points.xyz()[run.clone()];
    for axis in 0..3 {
        let v: Vec<f64> = xyz.iter().map(|p| p[axis]).collect();
        put_column(out, &v, grids.axis(input, axis));
    }
    // Counted and read by index: no column of 32-byte options built per run while spilling.
    let with = run.clone().filter(|&i| points.normal(i).is_some()).count();
    match with {
        0 => out.push(0),
        n if n == run.len() => out.push(1),
        _ => {
            out.push(2);
            out.extend(run.clone().map(|i| points.normal(i).is_some() as u8));
        }
    }
    if with > 0 {
        for axis in 0..3 {
            let v: Vec<f64> = run
                .clone()
                .filter_map(|i| Some(points.normal(i)?[axis]))
                .collect();
            put_column(out, &v, None);
        }
    }
}

/// Reads one run ([`put_run`]), appending its points to `out`.
fn get_run(c: &mut Cursor<'_>, out: &mut Points) -> Option<()> {
    let n = c.u32()? as usize;
    // Every point takes at least its id's byte: a larger count is damage, not an allocation.
    if n > c.remaining() {
        return None;
    }
    let mut ids = Vec::with_capacity(n);
    let mut prev = 0u64;
    for _ in 0..n {
        prev = prev.wrapping_add(unzigzag(c.varint()?) as u64);
        ids.push(prev);
    }
    let xyz = [get_column(c, n)?, get_column(c, n)?, get_column(c, n)?];
    let has: Vec<bool> = match c.u8()? {
        0 => vec![false; n],
        1 => vec![true; n],
        // Any byte but 0 or 1 is damage, like every other field of a frame.
        2 => c
            .take(n)?
            .iter()
            .map(|&b| (b <= 1).then_some(b == 1))
            .collect::<Option<_>>()?,
        _ => return None,
    };
    let with = has.iter().filter(|&&h| h).count();
    let normals = if with > 0 {
        [
            get_column(c, with)?,
            get_column(c, with)?,
            get_column(c, with)?,
        ]
    } else {
        Default::default()
    };
    let xyz: Vec<[f64; 3]> = (0..n).map(|i| [xyz[0][i], xyz[1][i], xyz[2][i]]).collect();
    let mut k = 0;
    let normals: Vec<Option<[f64; 3]>> = match with {
        0 => Vec::new(),
        _ => has
            .iter()
            .map(|&h| {
                h.then(|| {
                    k += 1;
                    [normals[0][k - 1], normals[1][k - 1], normals[2][k - 1]]
                })
            })
            .collect(),
    };
    out.append_columns(&ids, &xyz, &normals);
    Some(())
}

/// Encodes points (in scan order) as one frame: runs of one input each.
pub(super) fn encode_frame(points: &Points, grids: &Grids) -> std::io::Result<Vec<u8>> {
    let mut runs = Vec::new();
    let mut start = 0;
    let ids = points.ids();
    while start < ids.len() {
        let input = grids.input_of(ids[start]);
        let len = ids[start..]
            .iter()
            .take_while(|&&id| grids.input_of(id) == input)
            .count();
        runs.push((start..start + len, input));
        start += len;
    }
    let mut raw = Vec::with_capacity(points.len() * 12 + 16);
    raw.extend_from_slice(MAGIC);
    raw.extend_from_slice(&(runs.len() as u32).to_le_bytes());
    for (range, input) in runs {
        put_run(&mut raw, points, range, grids, input);
    }
    crate::io::pack::compress(&raw, crate::io::pack::Effort::Small)
}

/// Decodes every frame of a bucket file (`bytes`, read from `path`). A damaged or truncated
/// file, or one of another format, is an error that names it.
pub(super) fn decode_frames(path: &Path, bytes: &[u8]) -> Result<Points> {
    let bad = |what: &str| Error::damaged_work(path, &format!("bucket file {what}"));
    let raw = zstd::stream::decode_all(bytes).map_err(|_| bad("is damaged or truncated"))?;
    let mut c = Cursor::new(&raw);
    let mut out = Points::default();
    while !c.is_done() {
        if c.take(MAGIC.len()) != Some(&MAGIC[..]) {
            return Err(bad("is not of this version of tilecurv"));
        }
        let runs = c.u32().ok_or_else(|| bad("is truncated"))?;
        for _ in 0..runs {
            get_run(&mut c, &mut out).ok_or_else(|| bad("is damaged"))?;
        }
    }
    Ok(out)
}

/// Appends one frame per bucket of `buckets` to its bucket file. The frames are compressed in
/// parallel (on the caller's rayon pool), then appended in the given order.
pub(super) fn spill(dir: &Path, buckets: Vec<(TileKey, Points)>, grids: &Grids) -> Result<()> {
    let frames: Vec<(TileKey, std::io::Result<Vec<u8>>)> = buckets
        .into_par_iter()
        .map(|(key, points)| (key, encode_frame(&points, grids)))
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
#[path = "frames_tests.rs"]
mod tests;
