//! The LAS/LAZ file format: header, VLRs, extra-bytes descriptors, and the one writer of LAS/LAZ
//! files ([`writer`]), which `process` reaches through `io::las_output` and `generate terrain`
//! uses directly. Reading points is `io::source`'s job. Below `io::columns` and `io::source`,
//! which use it.

pub mod chunks;
pub(crate) mod decode;
pub mod extra_bytes;
pub mod fields;
pub mod header;
pub mod parts;
pub mod provenance;
pub mod trim;
pub mod upgrade;
pub mod vlr;
pub mod writer;
