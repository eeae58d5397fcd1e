//! The final pass: streams the input in file order and merges the per-tile result files in by
//! point id (a k-way merge), writing each input record untouched followed by its new columns.

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use crate::columns::ColumnSet;
use crate::error::{Error, Result};
use crate::progress::Reporter;
use crate::results::TileResults;
use crate::sink::{create_sink, PointSink};
use crate::source::PointSource;

/// Writes `output` from `source` and the tile result files. The output appears only if every
/// point was matched with its result; otherwise the temporary file is removed.
pub fn assemble(
    source: &dyn PointSource,
    result_files: &[PathBuf],
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
        result_files,
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

fn merge_into(
    writer: &mut dyn PointSink,
    source: &dyn PointSource,
    result_files: &[PathBuf],
    cols: &ColumnSet,
    chunk_points: usize,
    reporter: &dyn Reporter,
    cancel: &AtomicBool,
) -> Result<()> {
    let mut readers = result_files
        .iter()
        .map(|p| TileResults::open(p, cols))
        .collect::<Result<Vec<_>>>()?;
    let mut heads: Vec<Vec<u8>> = vec![Vec::new(); readers.len()];
    let mut heap = BinaryHeap::new();
    for (i, r) in readers.iter_mut().enumerate() {
        if let Some(id) = r.next(&mut heads[i])? {
            heap.push(Reverse((id, i)));
        }
    }
    let rl = source.record_length();
    let mut out = Vec::new();
    source.for_each_chunk(chunk_points, &mut |first, records| {
        if cancel.load(Ordering::Relaxed) {
            return Err(Error::Interrupted);
        }
        out.clear();
        for (j, rec) in records.chunks_exact(rl).enumerate() {
            let id = first + j as u64;
            let Some(Reverse((rid, i))) = heap.pop() else {
                return Err(Error::Internal(format!("no result for point {id}")));
            };
            if rid != id {
                return Err(Error::Internal(format!(
                    "result for point {rid} where point {id} was expected"
                )));
            }
            out.extend_from_slice(rec);
            out.extend_from_slice(&heads[i]);
            if let Some(next) = readers[i].next(&mut heads[i])? {
                heap.push(Reverse((next, i)));
            }
        }
        writer.write_points(&out)?;
        reporter.advance((records.len() / rl) as u64);
        Ok(())
    })?;
    if let Some(Reverse((id, _))) = heap.pop() {
        return Err(Error::Internal(format!(
            "result for point {id}, past the last point"
        )));
    }
    Ok(())
}
