//! The fixed-size text fields of LAS records (header identifiers, VLR user ids and descriptions,
//! extra-bytes names): NUL-padded on writing, trimmed at the first NUL on reading. Its own
//! module because the header, the VLRs and the extra-bytes descriptors all use it.

/// A fixed-size NUL-padded field from a string (truncated if longer).
pub fn padded<const N: usize>(s: &str) -> [u8; N] {
    let mut out = [0u8; N];
    let b = s.as_bytes();
    let n = b.len().min(N);
    out[..n].copy_from_slice(&b[..n]);
    out
}

/// The text of a NUL-padded field: up to its first NUL, invalid UTF-8 replaced.
pub fn trimmed(b: &[u8]) -> String {
    let end = b.iter().position(|&c| c == 0).unwrap_or(b.len());
    String::from_utf8_lossy(&b[..end]).into_owned()
}
