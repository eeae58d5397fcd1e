//! LAZ records streamed chunk by chunk through the depth-guarded decoder
//! ([`crate::io::las::decode`]).

use std::ops::Range;

use super::{page_below, LasSource};
use crate::error::{Error, Result};
use crate::io::las::chunks::chunk_of;
use crate::io::las::decode::{ChunkDecoder, ChunkJob};
use crate::io::source::within;

/// Chunks declaring more points than this (LASzip writes 50,000) are decoded piece by piece
/// rather than into one buffer.
const STREAMED_CHUNK: usize = 1 << 20;

impl LasSource {
    /// Decodes the LAZ chunks that hold the points `points` in file order, whole chunks of
    /// about `chunk_points` points at a time (in parallel, [`ChunkDecoder`]), and hands each
    /// batch's records of `points` to `f`. A chunk declaring more than [`STREAMED_CHUNK`]
    /// points (or the batch size, if larger) is decoded alone, piece by piece.
    pub(super) fn for_each_laz_chunk(
        &self,
        vlr: &laz::LazVlr,
        points: Range<u64>,
        chunk_points: usize,
        f: &mut dyn FnMut(u64, &[u8]) -> Result<()>,
    ) -> Result<()> {
        if points.is_empty() {
            return Ok(());
        }
        let rl = vlr.items_size() as usize;
        let n = self.header.point_count;
        let mut f = |first: u64, records: &[u8]| within(&points, first, records, rl, f);
        let dec = ChunkDecoder::new(rayon::current_num_threads())
            .map_err(|e| Error::Resource(format!("cannot start the LAZ decoding threads: {e}")))?;
        let want = chunk_points.max(1);
        // One limit for both tests below: a chunk the batch loop would not take is streamed.
        let cap = STREAMED_CHUNK.max(want);
        // The chunks from the one holding the range's first point to the last holding any.
        let live = self
            .chunks
            .partition_point(|c| c.first_point < n.min(points.end));
        let mut i = chunk_of(&self.chunks, points.start).map_or(0, |c| c.index);
        let at = self.chunks.get(i).map_or(0, |c| c.offset as usize);
        let (mut released, mut buf) = (page_below(at), Vec::new());
        while i < live {
            let first = self.chunks[i].first_point;
            if self.chunk_points(i) > cap {
                let bad = |e| self.chunk_error(i, e);
                let mut piece = |k: usize, recs: &[u8]| {
                    self.check_decoded(first + k as u64, recs)?;
                    f(first + k as u64, recs)
                };
                let bytes = self.chunk_bytes(i);
                dec.stream(vlr, bytes, self.chunk_points(i), want, &bad, &mut piece)?;
                released = self.release(released, self.chunk_end(i));
                i += 1;
                continue;
            }
            let (mut j, mut points) = (i, 0usize);
            while j < live && (j == i || points < want) && self.chunk_points(j) <= cap {
                points += self.chunk_points(j);
                j += 1;
            }
            buf.resize(points * rl, 0);
            let mut jobs = Vec::with_capacity(j - i);
            let mut rest = &mut buf[..];
            for c in i..j {
                let (out, tail) = rest.split_at_mut(self.chunk_points(c) * rl);
                let bytes = self.chunk_bytes(c);
                jobs.push(ChunkJob {
                    index: c,
                    bytes,
                    out,
                });
                rest = tail;
            }
            dec.decode(vlr, jobs)
                .map_err(|(c, e)| self.chunk_error(c, e))?;
            self.check_decoded(first, &buf)?;
            f(first, &buf)?;
            released = self.release(released, self.chunk_end(j - 1));
            i = j;
        }
        Ok(())
    }

    /// The points of LAZ chunk `c` (the last one's up to the header's count).
    fn chunk_points(&self, c: usize) -> usize {
        let n = self.header.point_count;
        let end = self
            .chunks
            .get(c + 1)
            .map_or(n, |next| next.first_point.min(n));
        end.saturating_sub(self.chunks[c].first_point) as usize
    }

    /// The compressed bytes of LAZ chunk `c` (within the file: the table was checked).
    fn chunk_bytes(&self, c: usize) -> &[u8] {
        let ch = self.chunks[c];
        &self.map[ch.offset as usize..self.chunk_end(c)]
    }

    /// The byte offset just past LAZ chunk `c`.
    fn chunk_end(&self, c: usize) -> usize {
        let ch = self.chunks[c];
        (ch.offset + ch.bytes) as usize
    }

    /// The error of LAZ chunk `c` failing to decode with `e`.
    fn chunk_error(&self, c: usize, e: std::io::Error) -> Error {
        let ch = self.chunks[c];
        let end = ch.first_point + self.chunk_points(c) as u64;
        Error::bad_input(&self.path, Some(ch.offset), format!(
            "LAZ chunk {c} of {} (points {}..{end}, {} bytes from the byte offset given) cannot be decoded: {e}; the chunk is corrupt or the file is truncated (the header says {} points)",
            self.chunks.len(), ch.first_point, ch.bytes, self.header.point_count))
    }
}
