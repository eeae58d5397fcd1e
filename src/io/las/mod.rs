//! The LAS/LAZ file format: header, VLRs, extra-bytes descriptors, and the one writer of LAS/LAZ
//! files. Reading points is `io::source`'s job.

pub mod extra_bytes;
pub mod fields;
pub mod header;
pub mod vlr;
pub mod writer;
