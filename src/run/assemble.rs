//! The final pass: streams each input in file order and takes the results of its points from
//! the id-ordered merge of the tile result files, writing each input record untouched followed
//! by its new columns.

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};

use crate::error::{Error, Result};
use crate::io::columns::ColumnSet;
use crate::io::results::Merger;
use crate::io::sink::{create_sink, PointSink};
use crate::io::source::PointSource;
use crate::progress::Reporter;

/// Writes `output` from `source` (whose point 0 has global id `first_id`) and the next results
/// of `merger`; with `flips` (`--orient propagate`), the results of the patches marked there
/// (per tile of the plan) are written with the opposite orientation. The output appears only if
/// every point was matched with its result; otherwise the temporary file is removed.
#[allow(clippy::too_many_arguments)]
pub fn assemble(
    source: &dyn PointSource,
    first_id: u64,
    merger: &mut Merger,
    flips: Option<&[Vec<bool>]>,
    cols: &ColumnSet,
    output: &Path,
    provenance: &str,
    chunk_points: usize,
    reporter: &dyn Reporter,
    cancel: &AtomicBool,
) -> Result<()> {
    let mut writer = create_sink(source, output, cols, provenance)?;
    match merge_into(
        writer.as_mut(),
        source,
        first_id,
        merger,
        flips,
        cols,
        chunk_points,
        reporter,
        cancel,
    ) {
        Ok(()) => writer.finish(),
        Err(e) => {
            writer.abandon();
            Err(e)
        }
    }
}

#[allow(clippy::too_many_arguments)]
fn merge_into(
    writer: &mut dyn PointSink,
    source: &dyn PointSource,
    first_id: u64,
    merger: &mut Merger,
    flips: Option<&[Vec<bool>]>,
    cols: &ColumnSet,
    chunk_points: usize,
    reporter: &dyn Reporter,
    cancel: &AtomicBool,
) -> Result<()> {
    let rl = source.record_length();
    let mut out = Vec::new();
    let mut rec = Vec::new();
    source.for_each_chunk(chunk_points, &mut |first, records| {
        if cancel.load(Ordering::Relaxed) {
            return Err(Error::Interrupted);
        }
        out.clear();
        for (j, r) in records.chunks_exact(rl).enumerate() {
            let id = first_id + first + j as u64;
            match merger.next(&mut rec)? {
                Some(rid) if rid == id => {}
                Some(rid) => {
                    return Err(Error::Internal(format!(
                        "result for point {rid} where point {id} was expected"
                    )))
                }
                None => return Err(Error::Internal(format!("no result for point {id}"))),
            }
            // The record is the point's global patch (u64) then its columns.
            let (patch, columns) = rec.split_at_mut(8);
            let patch = u64::from_le_bytes(patch.try_into().unwrap_or([0xff; 8]));
            if let Some(f) = flips.filter(|_| patch != u64::MAX) {
                let (tile, local) = ((patch >> 32) as usize, (patch & 0xffff_ffff) as usize);
                if f.get(tile)
                    .and_then(|t| t.get(local))
                    .copied()
                    .unwrap_or(false)
                {
                    cols.flip_encoded(columns);
                }
            }
            out.extend_from_slice(r);
            out.extend_from_slice(columns);
        }
        writer.write_points(&out)?;
        reporter.advance((records.len() / rl) as u64);
        Ok(())
    })
}
