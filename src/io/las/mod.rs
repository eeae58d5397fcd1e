//! The LAS/LAZ file format: header, VLRs, extra-bytes descriptors, and the one writer of LAS/LAZ
//! files ([`writer`]), which `process` reaches through [`carry`] (a LAS input's parts carried
//! over) or [`convert`] (any other input converted) and `generate terrain` uses directly.
//! Reading points is `io::source`'s job.

pub mod carry;
pub mod chunks;
pub mod convert;
pub mod extra_bytes;
pub mod fields;
pub mod header;
pub mod parts;
pub mod provenance;
pub mod trim;
pub mod upgrade;
pub mod vlr;
pub mod writer;
