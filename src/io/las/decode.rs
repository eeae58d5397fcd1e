//! LAZ chunks decoded in parallel, each through a reader that bounds the decoder's stack.
//!
//! The laz crate's GPS-time decoder for point formats 1, 3, 4 and 5 calls itself once for
//! every "switch to another time sequence" symbol it decodes, and nothing bounds how many a
//! corrupt chunk holds: past the thread's stack the process aborts ("stack overflow"), which
//! no error handling can catch. The decoder reads its input one byte at a time as its
//! arithmetic coder renormalises, so the reader is where the depth can be watched:
//! [`Guarded`] compares the stack pointer at every read with the one where the reader was made
//! and fails the read (an error that unwinds the recursion through its `?`s) once the decoder
//! is [`TRIP`] bytes deeper.
//!
//! Why this holds for any input: between two reads the coder decodes at most
//! [`MAX_SYMBOLS_BETWEEN_READS`] symbols (each shrinks its interval, and a read comes when the
//! interval falls below 2^24; see that constant), and the recursion decodes one symbol per
//! level, so the stack grows by at most that many frames between two checks. The decoding
//! threads have [`DECODE_STACK`] bytes of stack, [`TRIP`] plus room for that many frames of
//! up to [`MAX_FRAME`] bytes: the recursive functions' frames are 80 and 64 bytes in a release
//! build of laz 0.13 on x86_64 (their prologues: six and four pushes and 24 bytes, plus the
//! return address), so the bound has a margin of 12. Stacks are address space, touched only as
//! deep as a decode goes.

use std::io::{self, Read, Seek, SeekFrom};

use laz::record::{
    LayeredPointRecordDecompressor, RecordDecompressor, SequentialPointRecordDecompressor,
};
use laz::LazVlr;
use rayon::prelude::*;

use crate::error::{Error, Result};

/// Stack depth past the chunk's start at which a read fails: legitimate decoding stays within
/// a few kilobytes.
const TRIP: usize = 16 << 20;

/// The most symbols the arithmetic decoder decodes without reading a byte. Its interval length
/// `L` is at most 2^32 - 1 after a read and a read comes once it is below 2^24. Decoding a
/// symbol leaves at most `L - (L >> 15)`: a model's symbol counts never drop below 1 and their
/// total stays within 2^15, so the other symbols keep at least one 2^15th of the interval
/// (`L >> 15` times their quantised share). Iterating `L -= L >> 15` from 2^32 - 1 to below
/// 2^24 takes 181,734 steps (a test runs it; ln(2^8) / -ln(1 - 2^-15) = 181,702 without the
/// floor).
const MAX_SYMBOLS_BETWEEN_READS: usize = 181_734;

/// The largest frame of the recursive decoder this bound allows for.
const MAX_FRAME: usize = 1024;

/// Stack of the decoding threads: [`TRIP`], the frames that can come between two reads, and
/// 16 MiB for everything else.
pub(crate) const DECODE_STACK: usize = TRIP + MAX_SYMBOLS_BETWEEN_READS * MAX_FRAME + (16 << 20);

/// The address of a local of the caller's frame: where the stack is now.
#[inline(always)]
fn stack_address() -> usize {
    let here = 0u8;
    std::hint::black_box(&here) as *const u8 as usize
}

/// Why a read failed: the decoder went [`TRIP`] deeper than the chunk started.
#[derive(Debug)]
struct TooDeep;

impl std::fmt::Display for TooDeep {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "the decoder recursed more than {} MiB deep (a GPS-time sequence switch repeated without end)",
            TRIP >> 20
        )
    }
}

impl std::error::Error for TooDeep {}

/// One chunk's bytes, read by a decoder whose stack depth is checked at every read against
/// where the reader was made: the decoding must run on the thread that made it.
struct Guarded<'a> {
    data: &'a [u8],
    pos: usize,
    base: usize,
}

impl<'a> Guarded<'a> {
    /// A reader of `data`, its depth counted from the caller's frame.
    #[inline(always)]
    fn new(data: &'a [u8]) -> Self {
        Self {
            data,
            pos: 0,
            base: stack_address(),
        }
    }
}

impl Guarded<'_> {
    /// Fails once the stack is [`TRIP`] deeper than where the reader was made. The stack grows
    /// down on every target Rust's std supports threads on with guard pages.
    #[inline(always)]
    fn check_depth(&self) -> io::Result<()> {
        if self.base.saturating_sub(stack_address()) > TRIP {
            return Err(io::Error::other(TooDeep));
        }
        Ok(())
    }
}

impl Read for Guarded<'_> {
    #[inline]
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        self.check_depth()?;
        let rest = &self.data[self.pos.min(self.data.len())..];
        let n = rest.len().min(buf.len());
        buf[..n].copy_from_slice(&rest[..n]);
        self.pos += n;
        Ok(n)
    }

    /// The decoder reads one byte at a time as it renormalises: the common case is a single
    /// bounds check.
    #[inline]
    fn read_exact(&mut self, buf: &mut [u8]) -> io::Result<()> {
        self.check_depth()?;
        match self.data.get(self.pos..self.pos.saturating_add(buf.len())) {
            Some(src) => {
                buf.copy_from_slice(src);
                self.pos += buf.len();
                Ok(())
            }
            None => {
                self.pos = self.data.len();
                Err(io::Error::from(io::ErrorKind::UnexpectedEof))
            }
        }
    }
}

impl Seek for Guarded<'_> {
    fn seek(&mut self, to: SeekFrom) -> io::Result<u64> {
        let len = self.data.len() as i128;
        let at = match to {
            SeekFrom::Start(p) => p as i128,
            SeekFrom::End(d) => len + d as i128,
            SeekFrom::Current(d) => self.pos as i128 + d as i128,
        };
        if at < 0 {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                "seek before the chunk's start",
            ));
        }
        self.pos = at.min(usize::MAX as i128) as usize;
        Ok(self.pos as u64)
    }
}

/// Decodes one chunk's `bytes` into `out` (whole records of the layout `vlr`).
fn decode_chunk(vlr: &LazVlr, bytes: &[u8], out: &mut [u8]) -> io::Result<()> {
    decompressor(vlr, Guarded::new(bytes))?.decompress_many(out)
}

/// The record decompressor of the layout `vlr` over `reader`.
fn decompressor<'a>(
    vlr: &LazVlr,
    reader: Guarded<'a>,
) -> io::Result<Box<dyn RecordDecompressor<Guarded<'a>> + Send + 'a>> {
    let items = vlr.items();
    let version = items.first().map_or(0, |i| i.version());
    let mut dec: Box<dyn RecordDecompressor<Guarded<'a>> + Send + 'a> = match version {
        1 | 2 => Box::new(SequentialPointRecordDecompressor::new(reader)),
        3 | 4 => Box::new(LayeredPointRecordDecompressor::new(reader)),
        v => {
            return Err(io::Error::new(
                io::ErrorKind::Unsupported,
                format!("LAZ item version {v} is not supported (1 to 4 are)"),
            ))
        }
    };
    dec.set_fields_from(items).map_err(io::Error::other)?;
    Ok(dec)
}

/// One chunk to decode: its compressed bytes and where its records go.
pub(crate) struct ChunkJob<'a> {
    /// The chunk's index in the file, for errors.
    pub index: usize,
    /// Its compressed bytes.
    pub bytes: &'a [u8],
    /// Its decoded records.
    pub out: &'a mut [u8],
}

/// Threads with [`DECODE_STACK`] stacks that decode chunks.
pub(crate) struct ChunkDecoder {
    pool: rayon::ThreadPool,
}

impl ChunkDecoder {
    /// A decoder with `threads` threads.
    pub(crate) fn new(threads: usize) -> io::Result<Self> {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads.max(1))
            .stack_size(DECODE_STACK)
            .thread_name(|i| format!("tilecurv-laz-{i}"))
            .build()
            .map_err(io::Error::other)?;
        Ok(Self { pool })
    }

    /// Decodes whole chunks in parallel. The first failure comes back with its chunk's index.
    pub(crate) fn decode(
        &self,
        vlr: &LazVlr,
        jobs: Vec<ChunkJob<'_>>,
    ) -> std::result::Result<(), (usize, io::Error)> {
        self.pool.install(|| {
            jobs.into_par_iter().try_for_each(|job| {
                decode_chunk(vlr, job.bytes, job.out).map_err(|e| (job.index, e))
            })
        })
    }

    /// Decodes one chunk of `records` records piece by piece into `buf` (at most `per`
    /// records at a time), handing each piece to `f` with its first record's index within the
    /// chunk: for a chunk that declares more points than one buffer should hold. A decoding
    /// failure goes through `bad`.
    pub(crate) fn stream(
        &self,
        vlr: &LazVlr,
        bytes: &[u8],
        records: usize,
        per: usize,
        bad: &dyn Fn(io::Error) -> Error,
        f: &mut dyn FnMut(usize, &[u8]) -> Result<()>,
    ) -> Result<()> {
        let rl = vlr.items_size() as usize;
        let per = per.clamp(1, records.max(1));
        let mut buf = vec![0u8; per * rl];
        // One thread: the reader's depth is counted on the thread that made it.
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .stack_size(DECODE_STACK)
            .build()
            .map_err(|e| bad(io::Error::other(e)))?;
        let mut dec = one
            .install(|| decompressor(vlr, Guarded::new(bytes)))
            .map_err(bad)?;
        let mut done = 0;
        while done < records {
            let m = (records - done).min(per);
            let out = &mut buf[..m * rl];
            one.install(|| dec.decompress_many(out)).map_err(bad)?;
            f(done, out)?;
            done += m;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The interval's worst-case shrinking, run step by step as the decoder's integers do it.
    #[test]
    fn the_symbols_between_two_reads_are_bounded() {
        let (mut length, mut steps) = (u32::MAX as u64, 0usize);
        while length >= 1 << 24 {
            length -= length >> 15;
            steps += 1;
        }
        assert_eq!(steps, MAX_SYMBOLS_BETWEEN_READS);
        // The continuous bound, ln(2^8) / -ln(1 - 2^-15): the floor only adds steps, a few.
        let continuous = 256f64.ln() / -(1.0 - 2f64.powi(-15)).ln();
        assert!(steps as f64 >= continuous && (steps as f64) < continuous * 1.001);
        assert!(DECODE_STACK - TRIP >= steps * MAX_FRAME);
    }

    /// A reader's read fails once the stack is [`TRIP`] deeper than where the decoding started.
    #[test]
    fn a_read_past_the_trip_depth_fails() {
        #[inline(never)]
        fn deep(n: usize, r: &mut Guarded<'_>) -> io::Result<u8> {
            let pad = std::hint::black_box([0u8; 4096]);
            if n == 0 {
                let mut b = [0u8; 1];
                r.read_exact(&mut b)?;
                return Ok(b[0] ^ pad[0]);
            }
            deep(n - 1, r)
        }
        let data = [7u8; 4];
        let run = |levels: usize| {
            std::thread::Builder::new()
                .stack_size(64 << 20)
                .spawn(move || deep(levels, &mut Guarded::new(&data)))
                .expect("thread")
                .join()
                .expect("join")
        };
        assert_eq!(run(10).expect("shallow"), 7);
        let e = run((TRIP >> 12) + 16).expect_err("too deep");
        assert!(e.get_ref().is_some_and(|i| i.is::<TooDeep>()), "{e}");
    }
}
