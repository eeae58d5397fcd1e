//! The final pass: streams each input in file order and takes the results of its points from
//! the id-ordered merge of the tile result files, writing each input record untouched followed
//! by its new columns.

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};

use crate::columns::ColumnSet;
use crate::error::{Error, Result};
use crate::progress::Reporter;
use crate::results::Merger;
use crate::sink::{create_sink, PointSink};
use crate::source::PointSource;

/// Writes `output` from `source` (whose point 0 has global id `first_id`) and the next results
/// of `merger`. The output appears only if every point was matched with its result; otherwise
/// the temporary file is removed.
#[allow(clippy::too_many_arguments)]
pub fn assemble(
    source: &dyn PointSource,
    first_id: u64,
    merger: &mut Merger,
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

fn merge_into(
    writer: &mut dyn PointSink,
    source: &dyn PointSource,
    first_id: u64,
    merger: &mut Merger,
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
            out.extend_from_slice(r);
            out.extend_from_slice(&rec);
        }
        writer.write_points(&out)?;
        reporter.advance((records.len() / rl) as u64);
        Ok(())
    })
}
