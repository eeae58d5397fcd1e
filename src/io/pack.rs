//! Byte packing for the work directory's binary files (bucket frames, result blocks): LEB128
//! varints, the transposition of fixed-width records into byte planes (byte j of every record,
//! then byte j + 1, ...: the high bytes of similar numbers line up and compress to little), a
//! bounds-checked reader, and zstd frames that carry a checksum of their content, so that a
//! damaged frame fails to decode instead of decoding to other numbers. Functions of bytes; the
//! callers own the files.

use std::cell::RefCell;

use zstd::zstd_safe::CParameter;

/// How hard a work-directory frame is compressed: a frame is written once and read once or
/// twice, so never harder than zstd's level 1.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Effort {
    /// zstd level 1, for the bucket frames: grid integers that compress 2-3x, whose size is
    /// most of the work directory's disk.
    Small,
    /// zstd level -1, for the result blocks' frames (ids, flag bytes, the numbers' top bytes;
    /// the mantissa noise stays out of them: io::workdir::results::file): 1.7x as fast as
    /// level 1 when the noise was in the frame, for 0.7% more bytes; with it out, levels -1,
    /// -4 and -8 take the same time and -1 stores the fewest bytes (2M results of the terrain
    /// columns in 81 tiles: 33.1, 33.9 and 34.4 bytes a point).
    Fast,
}

impl Effort {
    fn level(self) -> i32 {
        match self {
            Effort::Small => 1,
            Effort::Fast => -1,
        }
    }
}

/// Appends `v` as an LEB128 varint (7 bits a byte, low first; 1 byte below 128).
pub(crate) fn put_varint(out: &mut Vec<u8>, mut v: u64) {
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

/// A signed difference as an unsigned number, small for small magnitudes (zigzag).
pub(crate) fn zigzag(v: i64) -> u64 {
    ((v << 1) ^ (v >> 63)) as u64
}

/// The inverse of [`zigzag`].
pub(crate) fn unzigzag(v: u64) -> i64 {
    ((v >> 1) as i64) ^ -((v & 1) as i64)
}

/// Appends the byte planes of `rows`, records of `width` bytes: byte 0 of every record, then
/// byte 1, and so on. `rows.len()` must be a multiple of `width`. Groups of 8 records are
/// moved 8 bytes at a time ([`transpose8`]): byte by byte, the result files' planes took 2% of
/// a run with the terrain columns.
pub(crate) fn put_planes(out: &mut Vec<u8>, rows: &[u8], width: usize) {
    if width == 0 {
        return;
    }
    let n = rows.len() / width;
    let start = out.len();
    out.resize(start + n * width, 0);
    let planes = &mut out[start..];
    let (groups, chunks) = (n / 8, width / 8);
    let record = |i: usize, j: usize, d: usize| (i + d) * width + j;
    let plane = |i: usize, j: usize, d: usize| (j + d) * n + i;
    transpose_blocks(rows, planes, (groups, chunks), record, plane);
    // The bytes past the whole chunks of the grouped records, and every byte of the others.
    for (i, row) in rows.chunks_exact(width).enumerate() {
        let done = if i < 8 * groups { 8 * chunks } else { 0 };
        for (j, &b) in row.iter().enumerate().skip(done) {
            planes[j * n + i] = b;
        }
    }
}

/// The whole 8x8 blocks of a transposition between records and planes. The block of records
/// `i..i + 8` and bytes `j..j + 8` (for `groups` groups and `chunks` chunks) is 8 lines of 8
/// contiguous bytes on either side: line `d` starts at `from(i, j, d)` in `src` and, once
/// transposed, at `to(i, j, d)` in `dst` (records: `(i + d) * width + j`; planes:
/// `(j + d) * n + i`).
fn transpose_blocks(
    src: &[u8],
    dst: &mut [u8],
    (groups, chunks): (usize, usize),
    from: impl Fn(usize, usize, usize) -> usize,
    to: impl Fn(usize, usize, usize) -> usize,
) {
    for i in (0..groups).map(|g| 8 * g) {
        for j in (0..chunks).map(|c| 8 * c) {
            let mut w = [0u64; 8];
            for (d, w) in w.iter_mut().enumerate() {
                *w = word(&src[from(i, j, d)..]);
            }
            transpose8(&mut w);
            for (d, w) in w.iter().enumerate() {
                let at = to(i, j, d);
                dst[at..at + 8].copy_from_slice(&w.to_le_bytes());
            }
        }
    }
}

/// The little-endian word of the first 8 bytes of `b`.
fn word(b: &[u8]) -> u64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(&b[..8]);
    u64::from_le_bytes(a)
}

/// Transposes the 8x8 bytes of `w` (byte k of word r is byte r of word k afterwards): blocks of
/// 4, then 2, then 1 byte swapped across the diagonal.
fn transpose8(w: &mut [u64; 8]) {
    const STAGES: [(usize, u64); 3] = [
        (4, 0x0000_0000_ffff_ffff),
        (2, 0x0000_ffff_0000_ffff),
        (1, 0x00ff_00ff_00ff_00ff),
    ];
    for (d, mask) in STAGES {
        for r in (0..8).filter(|r| r & d == 0) {
            let t = ((w[r] >> (8 * d)) ^ w[r + d]) & mask;
            w[r] ^= t << (8 * d);
            w[r + d] ^= t;
        }
    }
}

/// Appends the low `width` bytes (at most 8) of each word as byte planes: the same bytes as
/// [`put_planes`] of the words' little-endian rows cut to `width`, without the rows.
pub(crate) fn put_word_planes(out: &mut Vec<u8>, words: &[u64], width: usize) {
    let n = words.len();
    let start = out.len();
    out.resize(start + n * width.min(8), 0);
    for (j, plane) in out[start..].chunks_exact_mut(n.max(1)).enumerate() {
        for (b, &w) in plane.iter_mut().zip(words) {
            *b = (w >> (8 * j)) as u8;
        }
    }
}

/// The inverse of [`put_word_planes`]: `n` words of `width` bytes (at most 8) from their
/// planes, which must hold `n * width` bytes.
pub(crate) fn get_word_planes(planes: &[u8], n: usize, width: usize) -> Vec<u64> {
    let mut words = vec![0u64; n];
    for (j, plane) in planes.chunks_exact(n.max(1)).take(width.min(8)).enumerate() {
        for (w, &b) in words.iter_mut().zip(plane) {
            *w |= (b as u64) << (8 * j);
        }
    }
    words
}

/// The inverse of [`put_planes`]: `n` records of `width` bytes from their planes, appended to
/// `out`. `planes` must hold `n * width` bytes.
pub(crate) fn get_planes(out: &mut Vec<u8>, planes: &[u8], n: usize, width: usize) {
    let start = out.len();
    out.resize(start + n * width, 0);
    let rows = &mut out[start..];
    let (groups, chunks) = (n / 8, width / 8);
    let record = |i: usize, j: usize, d: usize| (i + d) * width + j;
    let plane = |i: usize, j: usize, d: usize| (j + d) * n + i;
    transpose_blocks(planes, rows, (groups, chunks), plane, record);
    for (j, plane) in planes.chunks_exact(n.max(1)).take(width).enumerate() {
        let done = if j < 8 * chunks { 8 * groups } else { 0 };
        for (i, &b) in plane.iter().enumerate().skip(done) {
            rows[i * width + j] = b;
        }
    }
}

/// A cursor over decoded bytes whose every read is checked: `None` past the end.
pub(crate) struct Cursor<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Cursor<'a> {
    /// A cursor at the start of `bytes`.
    pub(crate) fn new(bytes: &'a [u8]) -> Self {
        Cursor { bytes, at: 0 }
    }

    /// How many bytes are left.
    pub(crate) fn remaining(&self) -> usize {
        self.bytes.len() - self.at
    }

    /// Whether every byte was read.
    pub(crate) fn is_done(&self) -> bool {
        self.at == self.bytes.len()
    }

    /// The next `n` bytes.
    pub(crate) fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        let s = self.bytes.get(self.at..self.at.checked_add(n)?)?;
        self.at += n;
        Some(s)
    }

    /// The next byte.
    pub(crate) fn u8(&mut self) -> Option<u8> {
        self.take(1).map(|b| b[0])
    }

    /// The next little-endian u16.
    pub(crate) fn u16(&mut self) -> Option<u16> {
        Some(u16::from_le_bytes(self.take(2)?.try_into().ok()?))
    }

    /// The next little-endian u32.
    pub(crate) fn u32(&mut self) -> Option<u32> {
        Some(u32::from_le_bytes(self.take(4)?.try_into().ok()?))
    }

    /// The next little-endian u64.
    pub(crate) fn u64(&mut self) -> Option<u64> {
        Some(u64::from_le_bytes(self.take(8)?.try_into().ok()?))
    }

    /// The next little-endian f64 (its bits as written).
    pub(crate) fn f64(&mut self) -> Option<f64> {
        self.u64().map(f64::from_bits)
    }

    /// The next LEB128 varint ([`put_varint`]); None if it runs past the end or past 64 bits.
    pub(crate) fn varint(&mut self) -> Option<u64> {
        let mut v = 0u64;
        for shift in (0..64).step_by(7) {
            let b = self.u8()?;
            v |= ((b & 0x7f) as u64).checked_shl(shift)?;
            if b & 0x80 == 0 {
                return Some(v);
            }
        }
        None
    }
}

/// A 64-bit checksum of `bytes` (with their length), for data kept outside a zstd frame: four
/// lanes over the 8-byte words, each step `lane = rotl(lane + word * P2, 31) * P1` (the round
/// of xxHash's lanes: a bijection of the lane for a given word and of the word for a given
/// lane, so that any change to one word, or to the tail, changes its lane), the lanes folded
/// together and the result mixed so that every bit of it depends on every lane. Damage goes
/// unseen with a chance of about 2^-64; several times zstd's speed on the same bytes. Not a
/// defence against deliberate forgery.
pub(crate) fn checksum(bytes: &[u8]) -> u64 {
    let mut c = Checksum::new();
    c.update(bytes);
    c.finish()
}

const P1: u64 = 0x9e37_79b1_85eb_ca87;
const P2: u64 = 0xc2b2_ae3d_27d4_eb4f;
const P3: u64 = 0x1656_67b1_9e37_79f9;

/// One lane's step over a word ([`checksum`]).
fn step(lane: u64, w: u64) -> u64 {
    lane.wrapping_add(w.wrapping_mul(P2))
        .rotate_left(31)
        .wrapping_mul(P1)
}

/// [`checksum`] of bytes given in parts: the same sum as of the parts joined, for bytes read
/// into more than one buffer.
pub(crate) struct Checksum {
    lanes: [u64; 4],
    len: u64,
    /// The bytes of an unfinished 32-byte block.
    tail: [u8; 32],
    tail_len: usize,
}

impl Checksum {
    pub(crate) fn new() -> Self {
        Checksum {
            lanes: [P1, P2, P3, P1 ^ P2],
            len: 0,
            tail: [0; 32],
            tail_len: 0,
        }
    }

    fn block(&mut self, b: &[u8]) {
        for (i, lane) in self.lanes.iter_mut().enumerate() {
            *lane = step(*lane, word(&b[8 * i..]));
        }
    }

    /// Adds the next part.
    pub(crate) fn update(&mut self, mut bytes: &[u8]) {
        self.len += bytes.len() as u64;
        if self.tail_len > 0 {
            let take = (32 - self.tail_len).min(bytes.len());
            self.tail[self.tail_len..self.tail_len + take].copy_from_slice(&bytes[..take]);
            self.tail_len += take;
            bytes = &bytes[take..];
            if self.tail_len < 32 {
                return;
            }
            let tail = self.tail;
            self.block(&tail);
            self.tail_len = 0;
        }
        let mut blocks = bytes.chunks_exact(32);
        for b in &mut blocks {
            self.block(b);
        }
        let rest = blocks.remainder();
        self.tail[..rest.len()].copy_from_slice(rest);
        self.tail_len = rest.len();
    }

    /// The checksum of every part added.
    pub(crate) fn finish(mut self) -> u64 {
        for (i, w) in self.tail[..self.tail_len].chunks(8).enumerate() {
            let mut a = [0u8; 8];
            a[..w.len()].copy_from_slice(w);
            self.lanes[i] = step(self.lanes[i], u64::from_le_bytes(a));
        }
        let h = self.lanes.into_iter().fold(self.len, step);
        let h = (h ^ (h >> 33)).wrapping_mul(P2);
        let h = (h ^ (h >> 29)).wrapping_mul(P3);
        h ^ (h >> 32)
    }
}

thread_local! {
    /// One compression context per thread, reused frame after frame: creating one per frame
    /// allocates and initialises its tables every time.
    static COMPRESSOR: RefCell<Option<(Effort, zstd::bulk::Compressor<'static>)>> = const { RefCell::new(None) };
    /// One decompression context per thread: creating one per frame allocates and initialises
    /// its tables for every result block read (a visible share of the assemble stage:
    /// docs/performance.md).
    static DECOMPRESSOR: RefCell<Option<zstd::bulk::Decompressor<'static>>> = const { RefCell::new(None) };
}

/// A compression context at `effort` with content checksums.
fn new_compressor(effort: Effort) -> std::io::Result<zstd::bulk::Compressor<'static>> {
    let mut c = zstd::bulk::Compressor::new(effort.level())?;
    c.set_parameter(CParameter::ChecksumFlag(true))?;
    Ok(c)
}

/// `raw` as one zstd frame with a checksum of its content.
pub(crate) fn compress(raw: &[u8], effort: Effort) -> std::io::Result<Vec<u8>> {
    COMPRESSOR.with(|cell| {
        let Ok(mut cached) = cell.try_borrow_mut() else {
            return new_compressor(effort)?.compress(raw);
        };
        let (was, mut c) = match cached.take() {
            Some(cached) => cached,
            None => (effort, new_compressor(effort)?),
        };
        if was != effort {
            c.set_parameter(CParameter::CompressionLevel(effort.level()))?;
        }
        let (_, c) = cached.insert((effort, c));
        let frame = c.compress(raw);
        if frame.is_err() {
            *cached = None; // a context that failed is not reused
        }
        frame
    })
}

/// Largest `len` [`decompress_into`] reserves at once: a length read from a damaged file is
/// not trusted with an allocation of its size (the frame's own header may be damaged too), so a
/// larger frame is decoded as a stream that grows its buffer as the data comes.
const MAX_RESERVE: usize = 64 << 20;

/// Decodes one frame of [`compress`] into `out` (cleared first), which must come to exactly
/// `len` bytes; false if the frame is damaged (its checksum, its structure) or of another size.
pub(crate) fn decompress_into(frame: &[u8], len: usize, out: &mut Vec<u8>) -> bool {
    out.clear();
    if len > MAX_RESERVE {
        use std::io::Read;
        let Ok(d) = zstd::stream::read::Decoder::with_buffer(frame) else {
            return false;
        };
        let read = d.take(len as u64 + 1).read_to_end(out);
        return matches!(read, Ok(n) if n == len);
    }
    out.reserve(len);
    let decode = |d: &mut zstd::bulk::Decompressor<'static>, out: &mut Vec<u8>| matches!(d.decompress_to_buffer(frame, out), Ok(n) if n == len && out.len() == len);
    DECOMPRESSOR.with(|cell| {
        let fresh = || zstd::bulk::Decompressor::new().ok();
        let Ok(mut cached) = cell.try_borrow_mut() else {
            return fresh().is_some_and(|mut d| decode(&mut d, out));
        };
        let Some(d) = cached.take().or_else(fresh) else {
            return false;
        };
        let d = cached.insert(d);
        let ok = decode(d, out);
        if !ok {
            *cached = None; // a context that failed on a damaged frame is not reused
        }
        ok
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn varints_and_zigzag_round_trip() {
        let values = [0, 1, 127, 128, 300, u32::MAX as u64, u64::MAX];
        let mut b = Vec::new();
        values.iter().for_each(|&v| put_varint(&mut b, v));
        assert_eq!(b[..4], [0, 1, 127, 0x80]);
        let mut c = Cursor::new(&b);
        let back: Vec<u64> = values.iter().map(|_| c.varint().expect("varint")).collect();
        assert_eq!(back, values);
        assert!(c.is_done() && c.varint().is_none());
        // A varint cut short, or longer than 64 bits, is refused.
        assert!(Cursor::new(&[0x80, 0x80]).varint().is_none());
        assert!(Cursor::new(&[0xff; 11]).varint().is_none());
        for v in [0, 1, -1, 63, -64, i64::MAX, i64::MIN] {
            assert_eq!(unzigzag(zigzag(v)), v);
        }
        assert_eq!((zigzag(0), zigzag(-1), zigzag(1)), (0, 1, 2));
    }

    #[test]
    fn word_planes_are_the_planes_of_the_cut_rows() {
        let words: Vec<u64> = (0..37u64)
            .map(|i| i * 0x0123_4567_89ab + (i << 60))
            .collect();
        for width in [0, 1, 3, 8] {
            let rows: Vec<u8> = words
                .iter()
                .flat_map(|w| w.to_le_bytes().into_iter().take(width))
                .collect();
            let mut want = vec![7];
            put_planes(&mut want, &rows, width);
            let mut got = vec![7];
            put_word_planes(&mut got, &words, width);
            assert_eq!(got, want, "width {width}");
            let mask = u64::MAX.checked_shr(64 - 8 * width as u32).unwrap_or(0);
            let back = get_word_planes(&got[1..], words.len(), width);
            assert_eq!(back, words.iter().map(|w| w & mask).collect::<Vec<_>>());
        }
        assert!(get_word_planes(&[], 0, 4).is_empty());
    }

    #[test]
    fn planes_round_trip() {
        let rows: Vec<u8> = (0..30u8).collect();
        let mut planes = Vec::new();
        put_planes(&mut planes, &rows, 3);
        assert_eq!(planes[..4], [0, 3, 6, 9]);
        assert_eq!(planes[10], 1);
        let mut back = vec![42];
        get_planes(&mut back, &planes, 10, 3);
        assert_eq!(back[1..], rows[..]);
    }

    /// The blocked transposition against the definition, byte by byte, for every shape around
    /// the blocks' edges.
    #[test]
    fn planes_are_byte_j_of_every_record_for_any_width_and_count() {
        for width in 0..20usize {
            for n in 0..27usize {
                let rows: Vec<u8> = (0..n * width).map(|v| (v * 7 + 3) as u8).collect();
                let mut planes = vec![9];
                put_planes(&mut planes, &rows, width);
                assert_eq!(planes.len(), 1 + n * width);
                for i in 0..n {
                    for j in 0..width {
                        assert_eq!(planes[1 + j * n + i], rows[i * width + j], "{width} {n}");
                    }
                }
                let mut back = vec![5];
                get_planes(&mut back, &planes[1..], n, width);
                assert_eq!(back[1..], rows[..], "{width} {n}");
            }
        }
    }

    /// Every single flipped bit of a 101-byte buffer (whole blocks, whole words and a tail)
    /// changes the checksum, as do a byte more or less.
    /// A checksum of bytes given in parts, cut anywhere, is the checksum of the whole: against
    /// a reference written word by word from the definition.
    #[test]
    fn a_checksum_in_parts_is_the_checksum_of_the_whole() {
        fn reference(bytes: &[u8]) -> u64 {
            let mut lanes = [P1, P2, P3, P1 ^ P2];
            let mut words = Vec::new();
            for c in bytes.chunks(8) {
                let mut a = [0u8; 8];
                a[..c.len()].copy_from_slice(c);
                words.push(u64::from_le_bytes(a));
            }
            for (i, &w) in words.iter().enumerate() {
                lanes[i % 4] = step(lanes[i % 4], w);
            }
            let h = lanes.into_iter().fold(bytes.len() as u64, step);
            let h = (h ^ (h >> 33)).wrapping_mul(P2);
            let h = (h ^ (h >> 29)).wrapping_mul(P3);
            h ^ (h >> 32)
        }
        let bytes: Vec<u8> = (0..300u32).map(|i| (i * 131 % 251) as u8).collect();
        for len in [0, 1, 7, 8, 31, 32, 33, 64, 100, 300] {
            let whole = &bytes[..len];
            assert_eq!(checksum(whole), reference(whole), "{len}");
            for cuts in [
                [0, 0],
                [1, 5],
                [3, 40],
                [31, 33],
                [32, 64],
                [10, 10],
                [50, 299],
            ] {
                let [a, b] = cuts.map(|c| c.min(len));
                let mut c = Checksum::new();
                for part in [&whole[..a], &whole[a..b.max(a)], &whole[b.max(a)..]] {
                    c.update(part);
                }
                assert_eq!(c.finish(), checksum(whole), "{len} cut at {cuts:?}");
            }
        }
    }

    #[test]
    fn the_checksum_sees_every_flipped_bit_and_the_length() {
        let bytes: Vec<u8> = (0..101u32).map(|i| (i * 37 + 11) as u8).collect();
        let sum = checksum(&bytes);
        let mut seen = std::collections::HashSet::new();
        for at in 0..bytes.len() {
            for bit in 0..8 {
                let mut b = bytes.clone();
                b[at] ^= 1 << bit;
                let s = checksum(&b);
                assert_ne!(s, sum, "bit {bit} of byte {at}");
                seen.insert(s);
            }
        }
        assert_eq!(seen.len(), 808, "two damaged buffers share a sum");
        assert_ne!(checksum(&bytes[..100]), sum);
        let mut longer = bytes.clone();
        longer.push(0);
        assert_ne!(checksum(&longer), sum);
        assert_ne!(checksum(&[]), checksum(&[0]));
    }

    #[test]
    fn frames_detect_damage() {
        let raw: Vec<u8> = (0..10_000u32).flat_map(|v| (v / 7).to_le_bytes()).collect();
        let frame = compress(&raw, Effort::Small).expect("compress");
        let mut out = Vec::new();
        assert!(decompress_into(&frame, raw.len(), &mut out));
        assert_eq!(out, raw);
        assert!(!decompress_into(&frame, raw.len() + 1, &mut out));
        assert!(!decompress_into(
            &frame[..frame.len() - 1],
            raw.len(),
            &mut out
        ));
        // One flipped bit anywhere in the frame: refused (the checksum, if nothing else).
        for at in [frame.len() / 2, frame.len() - 2] {
            let mut bad = frame.clone();
            bad[at] ^= 0x10;
            assert!(!decompress_into(&bad, raw.len(), &mut out), "bit at {at}");
        }
        // A damaged length far past what the frame holds is refused without reserving it.
        assert!(!decompress_into(&frame, 1 << 40, &mut out));
        assert!(out.capacity() < 1 << 30, "{}", out.capacity());
        // Frames past the reserve limit decode as a stream, to the same bytes.
        let big = vec![7u8; MAX_RESERVE + 5];
        let frame = compress(&big, Effort::Fast).expect("compress");
        assert!(decompress_into(&frame, big.len(), &mut out) && out == big);
        assert!(!decompress_into(&frame, big.len() + 1, &mut out));
        let mut bad = frame.clone();
        let at = bad.len() - 2;
        bad[at] ^= 0x10;
        assert!(!decompress_into(&bad, big.len(), &mut out));
    }
}
