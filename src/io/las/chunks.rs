//! The LAZ chunk table, read and checked before the decompressor sees it: its offset, its chunk
//! count and every chunk's size against the point count and the file size. A corrupt table is
//! then an error naming the byte offset, never an allocation abort or a panic in the codec
//! (which allocates its buffers from these numbers). The table also gives each chunk's byte
//! offset, so decode errors can name where the bad chunk lies.

use std::io::Cursor;
use std::path::Path;

use super::header::LasHeader;
use crate::error::{Error, Result};

/// One LAZ chunk: the points it holds and where its bytes lie.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Chunk {
    /// Index of its first point in the file.
    pub first_point: u64,
    /// Byte offset of its compressed data in the file.
    pub offset: u64,
    /// Length of its compressed data.
    pub bytes: u64,
}

fn u32_at(b: &[u8], o: usize) -> u32 {
    u32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]])
}

fn i64_at(b: &[u8], o: usize) -> i64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(&b[o..o + 8]);
    i64::from_le_bytes(a)
}

/// Reads and checks the chunk table of the LAZ file `file` (all its bytes) with layout `vlr`.
pub fn read_chunk_table(
    path: &Path,
    file: &[u8],
    header: &LasHeader,
    vlr: &laz::LazVlr,
) -> Result<Vec<Chunk>> {
    let bad = |off: u64, what: String| Error::bad_input(path, Some(off), what);
    let len = file.len() as u64;
    let start = header.offset_to_point_data as u64;
    let n = header.point_count;
    if start + 8 > len {
        return Err(bad(start, format!("the LAZ point data at byte {start} is too short to hold the 8-byte offset of its chunk table; the file ({len} bytes) is truncated")));
    }
    // As LASzip does: an offset not written (a writer that could not seek back) is looked
    // for in the last 8 bytes of the file.
    let mut table_at = i64_at(file, start as usize);
    if table_at <= start as i64 {
        table_at = i64_at(file, file.len() - 8);
    }
    if table_at < (start + 8) as i64 {
        return Err(bad(start, format!("the LAZ chunk table offset {table_at} points before the compressed data, which starts at byte {}; the file is corrupt", start + 8)));
    }
    if (table_at as u64).checked_add(8).is_none_or(|e| e > len) {
        return Err(bad(start, format!("the LAZ chunk table offset {table_at} leaves no room for the table's 8-byte header before the file ends at byte {len}; the file is truncated (re-copy it) or the offset is corrupt")));
    }
    let table_at = table_at as u64;
    let data_bytes = table_at - (start + 8);
    let count = u32_at(file, table_at as usize + 4) as u64;
    let variable = vlr.uses_variable_size_chunks();
    let chunk_points = vlr.chunk_size() as u64;
    let needed = if variable || chunk_points == 0 {
        1
    } else {
        n.div_ceil(chunk_points)
    };
    // Every chunk holds at least one point and one byte: bounds the table before it is read.
    let most = if variable { n } else { needed + 1 };
    if count < needed || count > most.min(data_bytes) {
        return Err(bad(table_at + 4, format!(
            "the LAZ chunk table declares {count} chunks, but {n} points in {} {} and {data_bytes} bytes of compressed data allow {needed} to {}; the chunk table is corrupt",
            if variable { "variable-size" } else { "fixed chunks of" },
            if variable { "chunks".to_string() } else { format!("{chunk_points} points") },
            most.min(data_bytes))));
    }
    let mut cursor = Cursor::new(&file[table_at as usize..]);
    let table = laz::laszip::ChunkTable::read(&mut cursor, variable).map_err(|e| {
        bad(
            table_at,
            format!("the LAZ chunk table cannot be read: {e}; the file is truncated or corrupt"),
        )
    })?;
    let layers = layer_count(vlr);
    let mut chunks = Vec::with_capacity(table.len());
    let (mut offset, mut first_point) = (start + 8, 0u64);
    for (i, e) in table.as_ref().iter().enumerate() {
        let points = if variable {
            e.point_count
        } else {
            chunk_points
        };
        if e.byte_count == 0 || points == 0 || e.byte_count > data_bytes {
            return Err(bad(table_at, format!("LAZ chunk {i} of {count} is declared with {points} points in {} bytes; the chunk table is corrupt", e.byte_count)));
        }
        // Variable-size chunks hold the file's points between them: one declaring more than
        // are left would size the codec's buffer from garbage (a fuzz finding: 2^32-2 points,
        // a 4 GiB allocation).
        if variable && points > n - first_point.min(n) {
            return Err(bad(table_at, format!("LAZ chunk {i} of {count} is declared with {points} points, but only {} of the header's {n} points are left for it; the chunk table is corrupt", n - first_point.min(n))));
        }
        // The chunk must end before the chunk table, checked before its layer sizes are read
        // from it (a chunk starting at the table with a large byte count would read them past
        // the end of the file).
        if offset + e.byte_count > table_at {
            return Err(bad(table_at, format!("LAZ chunk {i} of {count} ends at byte {}, past the chunk table at byte {table_at}: the chunk sizes are corrupt", offset + e.byte_count)));
        }
        if let Some(layers) = layers {
            check_layers(file, offset, e.byte_count, vlr.items_size(), layers).map_err(|what| {
                bad(
                    offset,
                    format!("LAZ chunk {i} of {count}: {what}; the chunk is corrupt"),
                )
            })?;
        }
        chunks.push(Chunk {
            first_point,
            offset,
            bytes: e.byte_count,
        });
        offset += e.byte_count;
        first_point = first_point.saturating_add(points);
    }
    if first_point < n {
        return Err(bad(table_at, format!("the LAZ chunk table holds {first_point} points but the header says {n}; the file is truncated or its point count is wrong")));
    }
    Ok(chunks)
}

/// The number of layers of a layered (LAS 1.4 point format 6-10) chunk, None for point-wise
/// chunks: as the laz crate's decompressors read them, 9 for the point, 1 for RGB, 2 for RGB +
/// NIR, 1 for a wave packet and one per extra byte.
fn layer_count(vlr: &laz::LazVlr) -> Option<u64> {
    use laz::LazItemType as T;
    let mut n = 0u64;
    for item in vlr.items() {
        n += match item.item_type() {
            T::Point14 => 9,
            T::RGB14 | T::WavePacket14 => 1,
            T::RGBNIR14 => 2,
            T::Byte14(b) => b as u64,
            _ => return None,
        };
    }
    Some(n)
}

/// Checks a layered chunk's layer sizes before the codec sizes its buffers from them (a fuzz
/// finding: a layer of 2.8 GB in a 30 kB file): the first point's raw bytes, the point count,
/// one u32 size per layer, and the layers, all within the chunk's `bytes` at `offset`.
fn check_layers(
    file: &[u8],
    offset: u64,
    bytes: u64,
    first: u64,
    layers: u64,
) -> std::result::Result<(), String> {
    let table = first + 4;
    let head = table + 4 * layers;
    if head > bytes {
        return Err(format!(
            "{bytes} bytes cannot hold its first point and its {layers} layer sizes ({head} bytes)"
        ));
    }
    let at = (offset + table) as usize;
    let sum: u64 = (0..layers as usize)
        .map(|l| u32_at(file, at + 4 * l) as u64)
        .sum();
    if sum > bytes - head {
        return Err(format!(
            "its layers declare {sum} bytes but only {} follow their sizes",
            bytes - head
        ));
    }
    Ok(())
}

/// A chunk of a chunk table and its place there.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ChunkAt {
    /// Its index in the table.
    pub index: usize,
    /// The chunk.
    pub chunk: Chunk,
}

/// The chunk holding point `point`.
pub fn chunk_of(chunks: &[Chunk], point: u64) -> Option<ChunkAt> {
    let i = chunks
        .partition_point(|c| c.first_point <= point)
        .checked_sub(1)?;
    Some(ChunkAt {
        index: i,
        chunk: chunks[i],
    })
}
