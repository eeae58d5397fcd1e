//! A sequential file writer that bypasses the page cache where it can (`O_DIRECT` on Linux):
//! the outputs are written once and not read back by this process, and copying the records
//! into the page cache costs the writing thread far more system time than writing them direct
//! (docs/performance.md, "Writing"). Records are
//! gathered in a block-aligned buffer and written in whole aligned blocks through a second,
//! direct descriptor; the unaligned tail and later rewrites (a header patched at the end) go
//! through the ordinary descriptor. A file system that refuses direct I/O (tmpfs, some network
//! and FUSE file systems answer EINVAL) gets the same bytes through the ordinary descriptor.

use std::fs::File;
use std::io;
use std::os::unix::fs::FileExt;
use std::path::Path;

/// Alignment of the buffer, of every direct write's offset and of its length: the logical
/// block size of every common device divides it.
const ALIGN: usize = 4096;

/// Bytes gathered before a direct write.
const BLOCK: usize = 4 << 20;

/// A file written front to back (see the module doc).
pub(crate) struct DirectFile {
    /// The ordinary descriptor: the tail, rewrites, and everything when `direct` is None.
    file: File,
    /// The direct descriptor of the same file, None where the file system refuses it.
    direct: Option<File>,
    /// Backing storage of the buffer; the buffer is `buf[start..start + BLOCK]`, aligned.
    buf: Vec<u8>,
    start: usize,
    /// Bytes held in the buffer.
    held: usize,
    /// File offset of the buffer's first byte (a multiple of [`ALIGN`]).
    at: u64,
}

impl DirectFile {
    /// A writer at the start of `file`, the newly created, empty file at `path`.
    pub(crate) fn new(file: File, path: &Path) -> DirectFile {
        let buf = vec![0u8; BLOCK + ALIGN];
        let start = buf.as_ptr().align_offset(ALIGN);
        DirectFile {
            file,
            direct: open_direct(path),
            buf,
            start,
            held: 0,
            at: 0,
        }
    }

    /// Appends `data`.
    pub(crate) fn write_all(&mut self, mut data: &[u8]) -> io::Result<()> {
        while !data.is_empty() {
            let n = (BLOCK - self.held).min(data.len());
            let from = self.start + self.held;
            self.buf[from..from + n].copy_from_slice(&data[..n]);
            self.held += n;
            data = &data[n..];
            if self.held == BLOCK {
                self.write_aligned(BLOCK)?;
                self.at += BLOCK as u64;
                self.held = 0;
            }
        }
        Ok(())
    }

    /// Bytes written so far (the file offset of the next byte).
    pub(crate) fn position(&self) -> u64 {
        self.at + self.held as u64
    }

    /// Writes what is held and returns the ordinary descriptor, for rewrites and the sync.
    pub(crate) fn into_file(mut self) -> io::Result<File> {
        let aligned = self.held / ALIGN * ALIGN;
        if aligned > 0 {
            self.write_aligned(aligned)?;
        }
        let from = self.start + aligned;
        self.file.write_all_at(
            &self.buf[from..self.start + self.held],
            self.at + aligned as u64,
        )?;
        Ok(self.file)
    }

    /// Writes the buffer's first `n` bytes (a multiple of [`ALIGN`]) at `self.at`: direct,
    /// or through the ordinary descriptor once the file system has refused direct writes.
    fn write_aligned(&mut self, n: usize) -> io::Result<()> {
        let block = &self.buf[self.start..self.start + n];
        if let Some(direct) = &self.direct {
            match direct.write_all_at(block, self.at) {
                Ok(()) => return Ok(()),
                // Refused (or a short write left an unaligned rest): the whole block again,
                // buffered, from here on.
                Err(e) if e.raw_os_error() == Some(libc::EINVAL) => self.direct = None,
                Err(e) => return Err(e),
            }
        }
        self.file.write_all_at(block, self.at)
    }
}

/// A direct descriptor for writing `path`; None where the platform or file system has none.
#[cfg(target_os = "linux")]
fn open_direct(path: &Path) -> Option<File> {
    use std::os::unix::fs::OpenOptionsExt;
    std::fs::OpenOptions::new()
        .write(true)
        .custom_flags(libc::O_DIRECT)
        .open(path)
        .ok()
}

#[cfg(not(target_os = "linux"))]
fn open_direct(_: &Path) -> Option<File> {
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The file holds exactly the bytes appended, across block boundaries, with an unaligned
    /// tail and a rewrite at the front, written direct (where the test's file system takes
    /// it), through the ordinary descriptor, and on tmpfs where there is one (kernels before
    /// 6.6 refuse O_DIRECT there at open, EINVAL: the ordinary descriptor then writes it all).
    #[test]
    fn writes_the_bytes_appended() {
        let tmp = std::env::temp_dir();
        for direct in [true, false] {
            appends(&tmp, direct);
        }
        let shm = Path::new("/dev/shm");
        if shm.is_dir() {
            appends(shm, true);
        }
    }

    fn appends(base: &Path, direct: bool) {
        let dir = base.join(format!("tilecurv-direct-{}-{direct}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("creates the directory");
        let path = dir.join("out.bin");
        let file = File::create(&path).expect("creates the file");
        let mut w = DirectFile::new(file, &path);
        if !direct {
            w.direct = None;
        }
        let mut expected = Vec::new();
        let mut state = 1u32;
        for len in [7usize, 4089, BLOCK - 3, 1, BLOCK + 5000, 123] {
            let chunk: Vec<u8> = (0..len)
                .map(|_| {
                    state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                    (state >> 24) as u8
                })
                .collect();
            w.write_all(&chunk).expect("writes");
            expected.extend_from_slice(&chunk);
            assert_eq!(w.position(), expected.len() as u64);
        }
        let file = w.into_file().expect("writes the tail");
        file.write_all_at(b"HEAD", 0).expect("rewrites");
        expected[..4].copy_from_slice(b"HEAD");
        file.sync_all().expect("syncs");
        drop(file);
        let read = std::fs::read(&path).expect("reads back");
        assert_eq!(read.len(), expected.len());
        assert!(read == expected, "the file differs from the bytes written");
        std::fs::remove_dir_all(&dir).expect("cleans up");
    }
}
