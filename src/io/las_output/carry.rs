//! The LAS/LAZ output of `process` for a LAS input (or a converted one, which `convert` makes
//! look like one): the input's header, VLRs and EVLRs carried over by the [`LasFileWriter`],
//! each record followed by the new columns, and the extra-bytes descriptors of all the input's
//! extra-bytes records, merged into one, extended with the new columns' (after an
//! "undocumented" descriptor for any extra bytes the input left undescribed). The output is
//! LAS 1.4 unless the input's version is kept ([`Version`]; `upgrade` rewrites the header).

use std::path::Path;

use crate::error::{Error, Result};
use crate::io::columns::output::OutputColumns;
use crate::io::las::extra_bytes::{self, encode, encode_undocumented, parse, DESCRIPTOR_SIZE};
use crate::io::las::parts::LasParts;
use crate::io::las::upgrade;
use crate::io::las::writer::{HeaderStart, LasFileSpec, LasFileWriter};

/// The LAS version of the output.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Version {
    /// The input's.
    Input,
    /// LAS 1.4, whatever the input's (a 1.0-1.3 header is rewritten by [`upgrade::to_las14`]).
    Las14,
}

/// Creates the writer of `output` for records of `input` followed by the columns `cols`.
pub(crate) fn create(
    input: LasParts<'_>,
    output: &Path,
    cols: &OutputColumns,
    provenance: &str,
    version: Version,
) -> Result<LasFileWriter> {
    let upgraded;
    let h = match version {
        Version::Input => input.header,
        Version::Las14 => {
            upgraded = upgrade::to_las14(input.header, input.vlrs);
            &upgraded
        }
    };
    let record_length =
        u16::try_from(h.record_length as usize + cols.record_size()).map_err(|_| {
            Error::bad_input(
                input.path,
                Some(105),
                format!(
                    "records of {} bytes plus {} new bytes exceed the LAS limit of 65535",
                    h.record_length,
                    cols.record_size()
                ),
            )
        })?;
    let spec = LasFileSpec {
        origin: Some(input.path),
        header: HeaderStart::Input(h),
        record_length,
        vlrs: input.vlrs,
        evlrs: input.evlrs,
        extra_bytes: extra_bytes_payload(&input, cols)?,
        provenance,
    };
    LasFileWriter::create(output, spec)
}

/// The extra-bytes descriptors of the output: the input's, from all its extra-bytes records
/// in file order (padded with an "undocumented" descriptor if the input's records have more
/// extra bytes than they describe), then ours. The writer stores them as one record.
pub(crate) fn extra_bytes_payload(input: &LasParts<'_>, cols: &OutputColumns) -> Result<Vec<u8>> {
    let records = crate::io::las::vlr::records(input.vlrs, input.evlrs);
    let mut data = extra_bytes::merged_payload(records)
        .map_err(|why| Error::bad_input(input.path, None, why))?;
    let described: usize = parse(&data)
        .map(|d| d.iter().map(|d| d.size).sum())
        .unwrap_or(0);
    // LasSource refuses descriptors past the records' extra bytes; saturating all the same.
    let mut gap = (input.header.extra_bytes_len() as usize).saturating_sub(described);
    while gap > 0 {
        let n = gap.min(255);
        data.extend_from_slice(&encode_undocumented(n as u8));
        gap -= n;
    }
    for c in cols.descriptors() {
        if input
            .extra
            .iter()
            .any(|d| d.name.eq_ignore_ascii_case(&c.name))
        {
            // `process` refuses this before any work (run::rerun); a safety net.
            return Err(Error::bad_input(input.path, None, format!(
                "the input already has an extra dimension named {:?}; leave the new column out with --columns, or rename the input's", c.name)));
        }
        data.extend_from_slice(&encode(&c));
    }
    debug_assert_eq!(data.len() % DESCRIPTOR_SIZE, 0);
    Ok(data)
}
