//! [`LasParts`]: what an output takes over from a LAS file besides its point records (the
//! header, the VLRs, the EVLRs, the extra-bytes descriptors). A borrowed view, so that a LAS
//! source hands it to a writer without a downcast and a converted source can build one.

use std::path::Path;

use super::extra_bytes::Descriptor;
use super::header::LasHeader;
use super::vlr::Vlr;

/// A LAS file's header, VLRs, EVLRs and extra-bytes descriptors.
#[derive(Debug, Clone, Copy)]
pub struct LasParts<'a> {
    /// The file, named in errors about these parts.
    pub path: &'a Path,
    /// The parsed header (with its raw bytes).
    pub header: &'a LasHeader,
    /// The VLRs, in file order.
    pub vlrs: &'a [Vlr],
    /// The EVLRs with their byte offsets in the file (a waveform record's offset is the
    /// header's waveform start).
    pub evlrs: &'a [(u64, Vlr)],
    /// The extra-bytes descriptors (empty if none).
    pub extra: &'a [Descriptor],
}
