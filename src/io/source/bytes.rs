//! An input's bytes: a read-only memory map of the file (every run), or bytes already in memory
//! (the fuzz targets and tests), behind one type so that each reader has one implementation.

use memmap2::Mmap;

/// The bytes a source reads from.
pub enum InputBytes {
    /// A read-only map of the input file.
    Map(Mmap),
    /// Bytes in memory.
    Owned(Vec<u8>),
}

impl std::ops::Deref for InputBytes {
    type Target = [u8];

    fn deref(&self) -> &[u8] {
        match self {
            InputBytes::Map(m) => m,
            InputBytes::Owned(v) => v,
        }
    }
}

impl InputBytes {
    /// The map, when the bytes are a mapped file (to hand pages back to the kernel).
    pub fn mapped(&self) -> Option<&Mmap> {
        match self {
            InputBytes::Map(m) => Some(m),
            InputBytes::Owned(_) => None,
        }
    }
}
