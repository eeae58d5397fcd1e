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
        let merge = Merge {
            source: source.as_ref(),
            first_id: *first,
            flips: flips.as_deref(),
            stored: &spec.cols,
            cols: &out_cols,
            select: &spec.select,
            chunk_points: chunk,
            reporter: exec.reporter,
            cancel: exec.cancel,
        };
        undefined += assemble(
            &merge,
            &mut merger,
            output,
            &provenance,
            &spec.output_options,
        )?;
    }
    exec.reporter.finish_phase();
    Ok(undefined)
}

/// What one output's merge reads: its input, the results' layout and the output's columns.
pub struct Merge<'a> {
    /// The input whose records the output repeats.
    pub source: &'a dyn PointSource,
    /// The global id of the input's point 0.
    pub first_id: u64,
    /// With `--orient propagate`: per tile of the plan, the patches to write flipped.
    pub flips: Option<&'a [Vec<bool>]>,
    /// The run's column set, as the result files store it.
    pub stored: &'a ColumnSet,
    /// The output's columns.
    pub cols: &'a OutputColumns,
    /// The points the run computed (the others are written as not computed).
    pub select: &'a ClassFilter,
    /// Points read from `source` at a time.
    pub chunk_points: usize,
    /// Progress.
    pub reporter: &'a dyn Reporter,
    /// Set on a signal: the merge stops.
    pub cancel: &'a AtomicBool,
}

/// Writes `output` from `m.source` (whose point 0 has global id `m.first_id`) and the next
/// results of `merger`; with `m.flips` (`--orient propagate`), the results of the patches
/// marked there are written with the opposite orientation. The output appears only if every
/// point was matched with its result; otherwise the temporary file is removed. Points
/// `m.select` does not select have no result and are written as not computed. Returns the
/// number of points written whose curvature is undefined.
pub fn assemble(
    m: &Merge<'_>,
    merger: &mut Merger,
    output: &Path,
    provenance: &str,
    options: &OutputOptions,
) -> Result<u64> {
    let mut writer = create_sink(m.source, output, m.cols, provenance, options)?;
    match merge_into(writer.as_mut(), m, merger) {
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
fn merge_into(writer: &mut dyn PointSink, m: &Merge<'_>, merger: &mut Merger) -> Result<u64> {
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
                merge_records(m, merger, &mut hand_off)
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

/// Streams `m.source` in chunks and appends to a buffer each record followed by its encoded
/// result (taken from `merger` in id order; not computed for the points `m.select` leaves
/// out), handing the buffer to `hand_off` whenever it holds [`HANDOFF_BYTES`], and at the end.
/// Returns the number of points whose curvature is undefined.
fn merge_records(
    m: &Merge<'_>,
    merger: &mut Merger,
    hand_off: &mut dyn FnMut(&mut Vec<u8>) -> Result<()>,
) -> Result<u64> {
    let Merge {
        source,
        first_id,
        flips,
        stored,
        cols,
        select,
        chunk_points,
        reporter,
        cancel,
    } = *m;
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
