//! The LAS/LAZ output of `process`, built on `io::las`'s one writer: [`carry`] (a LAS input's
//! header, VLRs and extra bytes carried over, the new columns appended) and [`convert`] (any
//! other input converted to LAS records first). Above `io::las`, `io::columns` and
//! `io::source`, which it combines.

pub(crate) mod carry;
pub(crate) mod convert;
