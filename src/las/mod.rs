//! The LAS/LAZ file format: header, VLRs, extra-bytes descriptors. Parsing only; reading points
//! is `source`'s job and writing files is `las_out`'s.

pub mod extra_bytes;
pub mod header;
pub mod vlr;
