//! The assemble stage: streams each input in file order and takes the results of its points
//! from the id-ordered merge of the tile result files in the work directory, writing each input
//! record untouched followed by its new columns, one output per input. The steps of scaled
//! columns come first, from the statistics the tile result files carry (so every output of a
//! run shares one encoding); with `--orient propagate` the cross-tile signs are solved first
//! too (run::orientation).

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use crossbeam_channel::bounded;

use crate::config::OrientMode;
use crate::core::compute::PointResult;
use crate::core::estimate::flags;
use crate::core::orient::GlobalPatch;
use crate::core::plan::TilePlan;
use crate::core::select::ClassFilter;
use crate::error::{Error, Result};
use crate::io::columns::output::{Encoding, OutputColumns, Steps};
use crate::io::columns::{ColumnSet, ColumnType, Group};
use crate::io::results::{scene_stats, tile_path, Merger};
use crate::io::sink::{create_sink, output_columns, OutputOptions, PointSink};
use crate::io::source::PointSource;
use crate::io::workdir::WorkDir;
use crate::progress::Reporter;
use crate::run::bucket::chunk_points;
use crate::run::orientation::resolve_orientation;
use crate::run::spec::RunSpec;
use crate::run::Exec;

/// Writes every output of `spec` from the tile results in `work` (the tiles of `tiles`, all
/// finished). Returns the number of points written whose curvature is undefined (from every
/// tile's results, whichever run computed them; points the class filter left out are not
/// counted).
pub fn assemble_outputs(
    work: &WorkDir,
    spec: &RunSpec,
    tiles: &TilePlan,
    exec: &Exec<'_>,
) -> Result<u64> {
    let results_dir = work.path().join("results");
    let files: Vec<PathBuf> = tiles
        .tiles
        .iter()
        .map(|t| tile_path(&results_dir, t.key))
        .collect();
    let flips = match spec.orientation {
        OrientMode::Propagate => Some(resolve_orientation(&results_dir, tiles, exec.reporter)?),
        _ => None,
    };
    let steps = Steps::from_stats(&scene_stats(&files, &spec.cols)?);
    let curvature = [Group::H, Group::K, Group::K1, Group::K2];
    if spec.column_type == ColumnType::Scaled && curvature.iter().any(|&g| spec.cols.choice.has(g))
    {
        exec.reporter.info(&format!(
            "scaled columns (LAS/LAZ outputs): unit vectors i16 at 1/32767; H, K, and k1 with k2 i32 at steps {:e}, {:e}, {:e} (the error is at most half a step)",
            steps.h, steps.k, steps.principal
        ));
    }
    let encoding = Encoding::new(spec.column_type, steps);
    let mut merger = Merger::open(&results_dir, &files, &spec.cols, exec.memory.budget_bytes)?;
    exec.reporter.phase("write", spec.total_points);
    let chunk = chunk_points(spec, exec);
    let mut undefined = 0;
    for ((source, output), first) in spec.sources.iter().zip(&spec.outputs).zip(&spec.first_ids) {
        let out_cols = output_columns(output, &spec.cols, encoding)?;
        let provenance = format!("{}{}", spec.provenance(), out_cols.provenance());
        undefined += assemble(
            source.as_ref(),
            *first,
            &mut merger,
            flips.as_deref(),
            (&spec.cols, &out_cols),
            &spec.select,
            output,
            &provenance,
            &spec.output_options,
            chunk,
            exec.reporter,
            exec.cancel,
        )?;
    }
    exec.reporter.finish_phase();
    Ok(undefined)
}

/// Writes `output` from `source` (whose point 0 has global id `first_id`) and the next results
/// of `merger` (stored as the run's column set says), written as the output's columns say;
/// with `flips` (`--orient propagate`), the results of the patches marked there (per tile of
/// the plan) are written with the opposite orientation. The output appears only if every point
/// was matched with its result; otherwise the temporary file is removed. Points `select` does
/// not select have no result and are written as not computed. Returns the number of points
/// written whose curvature is undefined.
#[allow(clippy::too_many_arguments)]
pub fn assemble(
    source: &dyn PointSource,
    first_id: u64,
    merger: &mut Merger,
    flips: Option<&[Vec<bool>]>,
    cols: (&ColumnSet, &OutputColumns),
    select: &ClassFilter,
    output: &Path,
    provenance: &str,
    options: &OutputOptions,
    chunk_points: usize,
    reporter: &dyn Reporter,
    cancel: &AtomicBool,
) -> Result<u64> {
    let mut writer = create_sink(source, output, cols.1, provenance, options)?;
    match merge_into(
        writer.as_mut(),
        source,
        first_id,
        merger,
        flips,
        cols,
        select,
        chunk_points,
        reporter,
        cancel,
    ) {
        Ok(undefined) => writer.finish().map(|_| undefined),
        Err(e) => {
            writer.abandon();
            Err(e)
        }
    }
}

/// Bytes of output records the merge hands to the writer at a time: small enough that the
/// buffers in flight stay a few MiB whatever the chunk size, large enough that a hand-off per
/// buffer costs nothing.
const HANDOFF_BYTES: usize = 4 << 20;

/// Merges the results into `source`'s records ([`merge_records`]) and writes them to `writer`.
/// The merge (reading, decoding, encoding) runs on a thread of its own and hands filled buffers
/// to this one, which writes them: the write system calls, whose copying into the page cache
/// was most of this phase's time, overlap the merge instead of following it. Two buffers
/// circulate, so memory does not grow. The output's bytes are those of one thread: the buffers
/// are written in the order they were filled.
#[allow(clippy::too_many_arguments)]
fn merge_into(
    writer: &mut dyn PointSink,
    source: &dyn PointSource,
    first_id: u64,
    merger: &mut Merger,
    flips: Option<&[Vec<bool>]>,
    cols: (&ColumnSet, &OutputColumns),
    select: &ClassFilter,
    chunk_points: usize,
    reporter: &dyn Reporter,
    cancel: &AtomicBool,
) -> Result<u64> {
    let (full_tx, full_rx) = bounded::<Vec<u8>>(1);
    let (free_tx, free_rx) = bounded::<Vec<u8>>(2);
    std::thread::scope(|s| {
        let merge = std::thread::Builder::new()
            .name("assemble merge".into())
            .spawn_scoped(s, move || {
                // A failed send means the writer stopped, and it reports why.
                let mut hand_off = |buf: &mut Vec<u8>| {
                    let empty = free_rx.try_recv().unwrap_or_default();
                    full_tx
                        .send(std::mem::replace(buf, empty))
                        .map_err(|_| Error::Interrupted)
                };
                merge_records(
                    source,
                    first_id,
                    merger,
                    flips,
                    cols,
                    select,
                    chunk_points,
                    reporter,
                    cancel,
                    &mut hand_off,
                )
            });
        let merge = match merge {
            Ok(m) => m,
            Err(e) => {
                return Err(Error::Resource(format!(
                    "cannot start a thread to merge the results: {e}; lower --threads, or raise the limits on processes (ulimit -u) or memory (ulimit -v), then run the same command again: it resumes"
                )))
            }
        };
        let mut failed = None;
        for mut buf in full_rx.iter() {
            if let Err(e) = writer.write_points(&buf) {
                failed = Some(e);
                break;
            }
            buf.clear();
            let _ = free_tx.try_send(buf);
        }
        // The merge stops at its next hand-off once nobody receives.
        drop(full_rx);
        drop(free_tx);
        let merged = merge
            .join()
            .unwrap_or_else(|p| std::panic::resume_unwind(p));
        match failed {
            Some(e) => Err(e),
            None => merged,
        }
    })
}

/// Streams `source` in chunks and appends to a buffer each record followed by its encoded
/// result (taken from `merger` in id order; not computed for the points `select` leaves out),
/// handing the buffer to `hand_off` whenever it holds [`HANDOFF_BYTES`], and at the end.
/// Returns the number of points whose curvature is undefined.
#[allow(clippy::too_many_arguments)]
fn merge_records(
    source: &dyn PointSource,
    first_id: u64,
    merger: &mut Merger,
    flips: Option<&[Vec<bool>]>,
    (stored, cols): (&ColumnSet, &OutputColumns),
    select: &ClassFilter,
    chunk_points: usize,
    reporter: &dyn Reporter,
    cancel: &AtomicBool,
    hand_off: &mut dyn FnMut(&mut Vec<u8>) -> Result<()>,
) -> Result<u64> {
    let rl = source.record_length();
    let mut out = Vec::new();
    let mut rec = Vec::new();
    let mut undefined = 0u64;
    source.for_each_chunk(chunk_points, &mut |first, records| {
        if cancel.load(Ordering::Relaxed) {
            return Err(Error::Interrupted);
        }
        for (j, r) in records.chunks_exact(rl).enumerate() {
            if out.len() >= HANDOFF_BYTES {
                hand_off(&mut out)?;
            }
            let id = first_id + first + j as u64;
            if !select.selects(source.class_of(r)) {
                // Left out of the buckets by the scan: no result, NaN and flag 128.
                out.extend_from_slice(r);
                cols.encode(&PointResult::not_computed(id), &mut out);
                continue;
            }
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
            let (patch, columns) = rec.split_at(8);
            let patch = GlobalPatch(u64::from_le_bytes(patch.try_into().unwrap_or([0xff; 8])));
            out.extend_from_slice(r);
            let flip = flips
                .zip(patch.parts())
                .and_then(|(f, (tile, local))| f.get(tile)?.get(local).copied())
                .unwrap_or(false);
            let result = stored.decode_result(columns);
            undefined += (result.curvature.flags & flags::UNDEFINED != 0) as u64;
            if flip {
                cols.encode(&result.flipped(&stored.extra), &mut out);
            } else {
                cols.encode(&result, &mut out);
            }
        }
        reporter.advance((records.len() / rl) as u64);
        Ok(())
    })?;
    if !out.is_empty() {
        hand_off(&mut out)?;
    }
    Ok(undefined)
}
