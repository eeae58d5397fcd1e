//! The assemble stage: streams each input in file order and takes the results of its points
//! from the id-ordered merge of the tile result files in the work directory, writing each input
//! record untouched followed by its new columns, one output per input. The steps of scaled
//! columns come first, from the statistics the tile result files carry (so every output of a
//! run shares one encoding); with `--orient propagate` the cross-tile signs are solved first
//! too (run::orientation).

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use crossbeam_channel::{bounded, Receiver, Sender};
use rayon::prelude::*;

use crate::core::compute::PointResult;
use crate::core::estimate::flags;
use crate::core::orient::GlobalPatch;
use crate::core::plan::TilePlan;
use crate::core::select::ClassFilter;
use crate::error::{Error, Result};
use crate::io::columns::output::{Encoding, OutputColumns, Steps};
use crate::io::columns::{
    ColumnSet, ColumnType, Group, ResultLayout, Stored, TerrainValue, Transcoder, Value,
};
use crate::io::durable::Ready;
use crate::io::sink::{create_sink, output_columns, OutputOptions, PointSink};
use crate::io::source::PointSource;
use crate::io::workdir::results::{record_size, scene_stats, Merger};
use crate::io::workdir::ResultStore;
use crate::progress::Reporter;
use crate::run::bucket::chunk_points;
use crate::run::orientation::resolve_orientation;
use crate::run::raster::{default_dir, OutputRasters, Tap};
use crate::run::{Exec, Run};

/// The steps of the scaled curvature columns `cols` writes, for the log ("H 1.5e-5 1/m; K ...";
/// k1, k2 and the terrain curvatures share k1's step); None when it writes none.
fn steps_note(cols: &ColumnSet, steps: &Steps) -> Option<String> {
    let has = |g| cols.choice.has(g);
    let u = &cols.unit;
    let mut parts = Vec::new();
    if has(Group::H) {
        parts.push(format!("H {:e} 1/{u}", steps.h));
    }
    if has(Group::K) {
        parts.push(format!("K {:e} 1/{u}^2", steps.k));
    }
    let principal: Vec<&str> = (cols.columns().into_iter())
        .filter(|c| {
            use TerrainValue::*;
            matches!(
                c.value,
                Value::K1 | Value::K2 | Value::Terrain(Profile | Tangential | Plan | Curvedness)
            )
        })
        .map(|c| c.name)
        .collect();
    if !principal.is_empty() {
        parts.push(format!(
            "{} {:e} 1/{u}",
            principal.join(", "),
            steps.principal
        ));
    }
    (!parts.is_empty()).then(|| {
        format!(
            "scaled curvature columns (LAS/LAZ outputs), i32 steps: {} (the error is at most half a step)",
            parts.join("; ")
        )
    })
}

/// Writes every output of `run` from its tile results (the tiles of `tiles`, all finished).
/// Returns the number of points written whose curvature is undefined (from every tile's
/// results, whichever run computed them; points the class filter left out are not counted).
pub(crate) fn assemble_outputs(run: &Run, tiles: &TilePlan, exec: &Exec<'_>) -> Result<u64> {
    let spec = &run.spec;
    let Finished {
        store,
        files,
        flips,
    } = finished(run, tiles, exec.reporter)?;
    let steps = Steps::from_stats(&scene_stats(&files, &spec.cols)?);
    if spec.params.column_type == ColumnType::Scaled {
        if let Some(note) = steps_note(&spec.cols, &steps) {
            exec.reporter.info(&note);
        }
    }
    let encoding = Encoding::new(spec.params.column_type, steps);
    let outs = (spec.outputs.iter())
        .map(|output| output_columns(output, &spec.cols, encoding))
        .collect::<Result<Vec<_>>>()?;
    let mut rasters = match &exec.rasters {
        Some(o) => {
            let dir = o.dir.clone().unwrap_or_else(|| default_dir(&spec.outputs));
            let budget = exec.memory.budget_bytes as u64;
            Some(OutputRasters::new(
                o,
                &spec.cols,
                (&spec.sources, &outs),
                dir,
                budget,
            )?)
        }
        None => None,
    };
    let mut merger = Merger::open(store.dir(), &files, &spec.cols, exec.memory.budget_bytes)?;
    exec.reporter.phase("write", spec.total_points);
    let chunk = chunk_points(spec, exec);
    let mut undefined = 0;
    let mut ready = Vec::new();
    let outputs = spec.sources.iter().zip(&spec.outputs).zip(&spec.first_ids);
    for (i, (((source, output), first), out_cols)) in outputs.zip(outs).enumerate() {
        let provenance = format!("{}{}", spec.provenance(), out_cols.provenance());
        let merge = Merge {
            source: source.as_ref(),
            first_id: *first,
            flips: flips.as_deref(),
            stored: &spec.cols,
            cols: &out_cols,
            select: &spec.params.select,
            chunk_points: chunk,
            reporter: exec.reporter,
            cancel: exec.cancel,
            pool: &exec.pool,
        };
        let mut tap = match rasters.as_mut() {
            Some(r) => Some(r.tap(i, source.as_ref(), &out_cols)?),
            None => None,
        };
        let (n, out) = assemble(
            &merge,
            &mut merger,
            (output, tap.as_mut()),
            &provenance,
            &spec.output_options,
        )?;
        undefined += n;
        ready.push(out);
    }
    exec.reporter.finish_phase();
    // The point outputs replace what their paths held only once every output and raster is
    // written: an interrupted run leaves them as they were. A raster failing otherwise leaves
    // the point outputs, which `tilecurv raster` turns into rasters.
    let commit = |ready: Vec<Ready>| ready.into_iter().try_for_each(Ready::commit);
    if let Err(e) = finish_rasters(rasters, exec) {
        if !matches!(e, Error::Interrupted) {
            commit(ready)?;
            let outputs: Vec<String> = spec
                .outputs
                .iter()
                .map(|o| o.display().to_string())
                .collect();
            exec.reporter.warn(&format!(
                "the point outputs are complete ({}), the rasters failed: once the cause is fixed, `tilecurv raster` makes them from the outputs",
                outputs.join(", ")
            ));
        }
        return Err(e);
    }
    commit(ready)?;
    Ok(undefined)
}

/// Writes `rasters`, if asked for, and reports them.
fn finish_rasters(rasters: Option<OutputRasters>, exec: &Exec<'_>) -> Result<()> {
    let Some(r) = rasters else {
        return Ok(());
    };
    let s = r.finish(exec.reporter, exec.cancel)?;
    for w in s.warnings() {
        exec.reporter.warn(&w);
    }
    exec.reporter.info(&format!(
        "rasters: {} files of {}x{} cells of {} ({} with a point) in {}",
        s.files.len(),
        s.grid.width,
        s.grid.height,
        s.cell_text(),
        s.cells,
        s.files
            .first()
            .and_then(|f| f.parent())
            .map_or(String::new(), |d| d.display().to_string())
    ));
    Ok(())
}

/// The finished tiles' results of a run: the result store, the files to merge and, with
/// `--orient propagate`, the patches to write flipped, per tile of the plan.
pub(crate) struct Finished {
    /// The result store.
    pub store: ResultStore,
    /// The tiles' result files.
    pub files: Vec<PathBuf>,
    /// The cross-tile signs (`run::orientation`), with `--orient propagate`.
    pub flips: Option<Vec<Vec<bool>>>,
}

/// The results of the tiles of `tiles` in `run`'s work directory, their orientation resolved.
pub(crate) fn finished(run: &Run, tiles: &TilePlan, reporter: &dyn Reporter) -> Result<Finished> {
    let store = run.work.results()?;
    let files = store.files(&tiles.tiles);
    let flips = match run.spec.propagates() {
        true => Some(resolve_orientation(store.dir(), tiles, reporter)?),
        false => None,
    };
    Ok(Finished {
        store,
        files,
        flips,
    })
}

/// What one output's merge reads: its input, the results' layout and the output's columns.
pub(crate) struct Merge<'a> {
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
    /// The threads that decode and encode.
    pub pool: &'a rayon::ThreadPool,
}

/// Writes `output` from `m.source` (whose point 0 has global id `m.first_id`) and the next
/// results of `merger`; with `m.flips` (`--orient propagate`), the results of the patches
/// marked there are written with the opposite orientation. The output is ready to appear only
/// if every point was matched with its result; otherwise the temporary file is removed. Points
/// `m.select` does not select have no result and are written as not computed. Returns the
/// number of points written whose curvature is undefined and the written file, which its
/// [`Ready::commit`] renames over the output.
pub(crate) fn assemble(
    m: &Merge<'_>,
    merger: &mut Merger,
    (output, tap): (&Path, Option<&mut Tap<'_>>),
    provenance: &str,
    options: &OutputOptions,
) -> Result<(u64, Ready)> {
    let mut writer = create_sink(m.source, output, m.cols, provenance, options)?;
    match merge_into(writer.as_mut(), m, merger, tap) {
        Ok(undefined) => writer.finish().map(|r| (undefined, r)),
        Err(e) => {
            writer.abandon();
            Err(e)
        }
    }
}

/// Bytes of output records the merge hands to the writer at a time: small enough that the
/// buffers in flight stay a few MiB whatever the chunk size, large enough that a hand-off per
/// buffer costs nothing.
const HANDOFF_BYTES: usize = 2 << 20;

/// Buffers filled at a time (each by one thread of the pool), and so at most in flight.
const GROUP: usize = 4;

/// The filled buffers' way to the writer, and the written ones' way back.
struct HandOff {
    full: Sender<Vec<u8>>,
    free: Receiver<Vec<u8>>,
}

impl HandOff {
    /// An empty buffer, a written one if any came back.
    fn buffer(&self) -> Vec<u8> {
        self.free.try_recv().unwrap_or_default()
    }

    /// Hands `buf` to the writer; a failed send means the writer stopped, and it reports why.
    fn send(&self, buf: Vec<u8>) -> Result<()> {
        self.full.send(buf).map_err(|_| Error::Interrupted)
    }
}

/// Merges the results into `source`'s records ([`merge_records`]) and writes them to `writer`.
/// The merge (reading, decoding, encoding) runs on a thread of its own and hands filled buffers
/// to this one, which writes them: the writes overlap the merge instead of following it. At
/// most [`GROUP`] buffers circulate, so memory does not grow. The output's bytes are those of
/// one thread: the buffers are written in the order of the records they hold.
fn merge_into(
    writer: &mut dyn PointSink,
    m: &Merge<'_>,
    merger: &mut Merger,
    tap: Option<&mut Tap<'_>>,
) -> Result<u64> {
    let (full_tx, full_rx) = bounded::<Vec<u8>>(GROUP);
    let (free_tx, free_rx) = bounded::<Vec<u8>>(GROUP);
    std::thread::scope(|s| {
        let hand = HandOff {
            full: full_tx,
            free: free_rx,
        };
        let merge = std::thread::Builder::new()
            .name("assemble merge".into())
            .spawn_scoped(s, move || merge_records(m, merger, &hand, tap));
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

/// The results of a group of records, in record order, and where each piece's begin.
#[derive(Default)]
struct GroupResults {
    /// The results' records (global patch, then the stored columns: [`record_size`] bytes
    /// each, as every result file gives them back), one after the other.
    bytes: Vec<u8>,
    /// Per piece of the group, the index of its first result.
    pieces: Vec<usize>,
}

/// Streams `m.source` in chunks, in groups of [`GROUP`] pieces of about [`HANDOFF_BYTES`] of
/// output. A group's results are taken from `merger` in id order (one thread: the merge is
/// sequential) while the previous group is encoded ([`encode_group`], on `m.pool`'s other
/// threads), whose buffers then go to the writer in order: the decoding and encoding were two
/// thirds of this thread's time. Returns the number of points whose curvature is undefined.
fn merge_records(
    m: &Merge<'_>,
    merger: &mut Merger,
    hand: &HandOff,
    mut tap: Option<&mut Tap<'_>>,
) -> Result<u64> {
    let rl = m.source.record_length();
    let piece = (HANDOFF_BYTES / (rl + m.cols.record_size())).max(1);
    let mut results: [GroupResults; 2] = Default::default();
    let mut undefined = 0u64;
    m.source
        .for_each_chunk(m.chunk_points, &mut |first, records| {
            let groups: Vec<&[u8]> = records.chunks(GROUP * piece * rl).collect();
            let first_of = |g: usize| m.first_id + first + (g * GROUP * piece) as u64;
            let [ready, next] = &mut results;
            for g in 0..=groups.len() {
                // Checked at every group, not once a chunk: a chunk of a million LAZ points
                // takes a second or more to merge, encode and write.
                if m.cancel.load(Ordering::Relaxed) {
                    return Err(Error::Interrupted);
                }
                let (taken, encoded) = m.pool.install(|| {
                    rayon::join(
                        || match groups.get(g) {
                            Some(records) => {
                                group_results(m, merger, first_of(g), records, piece, next)
                            }
                            None => Ok(()),
                        },
                        || match g.checked_sub(1) {
                            Some(p) => encode_group(m, hand, first_of(p), groups[p], piece, ready),
                            None => Vec::new(),
                        },
                    )
                });
                for e in encoded {
                    undefined += e.undefined;
                    if let Some(t) = tap.as_deref_mut() {
                        t.feed(&e.buf)?;
                    }
                    hand.send(e.buf)?;
                }
                if let Some(p) = g.checked_sub(1) {
                    m.reporter.advance((groups[p].len() / rl) as u64);
                }
                taken?;
                std::mem::swap(ready, next);
            }
            Ok(())
        })?;
    Ok(undefined)
}

/// One piece of output records, encoded.
struct Encoded {
    /// The output records.
    buf: Vec<u8>,
    /// How many of them have an undefined curvature.
    undefined: u64,
}

/// The buffers of a group of `records` (the first is point `first_id`) with their `results`:
/// each piece of `piece` records fills one, in parallel, in order.
fn encode_group(
    m: &Merge<'_>,
    hand: &HandOff,
    first_id: u64,
    records: &[u8],
    piece: usize,
    results: &GroupResults,
) -> Vec<Encoded> {
    let rl = m.source.record_length();
    let encode = |(p, records): (usize, &[u8])| {
        let mut buf = hand.buffer();
        let first_id = first_id + (p * piece) as u64;
        let undefined = encode_piece(m, first_id, records, results, p, &mut buf);
        Encoded { buf, undefined }
    };
    records
        .par_chunks(piece * rl)
        .enumerate()
        .map(encode)
        .collect()
}

/// Takes from `merger` the results of the selected points among `records` (the first is point
/// `first_id`), in pieces of `piece` records, into `out`; an error if the next result is
/// another point's.
fn group_results(
    m: &Merge<'_>,
    merger: &mut Merger,
    first_id: u64,
    records: &[u8],
    piece: usize,
    out: &mut GroupResults,
) -> Result<()> {
    let rl = m.source.record_length();
    let size = record_size(m.stored);
    out.bytes.clear();
    out.pieces.clear();
    for (j, r) in records.chunks_exact(rl).enumerate() {
        if j % piece == 0 {
            out.pieces.push(out.bytes.len() / size);
        }
        if !m.select.selects(m.source.class_of(r)) {
            continue;
        }
        let id = first_id + j as u64;
        match merger.append_next(&mut out.bytes)? {
            Some(rid) if rid == id => {}
            found => return Err(merger.mismatch(id, found)),
        }
    }
    Ok(())
}

/// Appends to `out` each of `records` (piece `p` of its group; the first is point `first_id`)
/// followed by its encoded result from `results` (not computed for the points `m.select`
/// leaves out; with `m.flips`, the patches marked there flipped). Returns the number of points
/// whose curvature is undefined.
fn encode_piece(
    m: &Merge<'_>,
    first_id: u64,
    records: &[u8],
    results: &GroupResults,
    p: usize,
    out: &mut Vec<u8>,
) -> u64 {
    let (rl, size) = (m.source.record_length(), record_size(m.stored));
    // Found once a piece (thousands of records), not per record.
    let transcoder = Transcoder::new(&m.stored.layout(), m.cols, &m.stored.extra);
    let row = rl + m.cols.record_size();
    let start = out.len();
    out.resize(start + records.len() / rl * row, 0);
    let rows = &mut out[start..];
    let mut stored = Vec::with_capacity(records.len() / rl);
    let first = results.pieces[p];
    let mut next = first;
    let mut undefined = 0;
    let mut not_computed = Vec::new();
    for (j, (r, o)) in records
        .chunks_exact(rl)
        .zip(rows.chunks_exact_mut(row))
        .enumerate()
    {
        o[..rl].copy_from_slice(r);
        if !m.select.selects(m.source.class_of(r)) {
            // Left out of the buckets by the scan: no result, NaN and flag 128.
            not_computed.clear();
            m.cols.encode(
                &PointResult::not_computed(first_id + j as u64),
                &mut not_computed,
            );
            o[rl..].copy_from_slice(&not_computed);
            stored.push(None);
            continue;
        }
        let (patch, columns) = results.bytes[next * size..(next + 1) * size].split_at(8);
        next += 1;
        undefined += (transcoder.flags(columns) & flags::UNDEFINED != 0) as u64;
        stored.push(Some((columns, flipped(patch, m.flips))));
    }
    // Every point with a result and none flipped: the results are one run of records.
    let stored = match m.flips.is_none() && stored.iter().all(Option::is_some) {
        true => Stored::Run {
            bytes: &results.bytes[first * size..next * size],
            size,
            at: 8,
        },
        false => Stored::Each(&stored),
    };
    transcoder.encode_all(stored, rows, row, rl);
    undefined
}

/// Whether the point whose global patch is `patch` (u64 LE) is written flipped: with `flips`
/// (`--orient propagate`, per tile of the plan) marking its patch.
fn flipped(patch: &[u8], flips: Option<&[Vec<bool>]>) -> bool {
    let patch = GlobalPatch(u64::from_le_bytes(patch.try_into().unwrap_or([0xff; 8])));
    (flips.zip(patch.parts()))
        .and_then(|(f, (tile, local))| f.get(tile)?.get(local).copied())
        .unwrap_or(false)
}

/// The result of one merged record `rec` (the point's global patch, a u64, then its columns
/// as `layout` stores them), flipped where `flips` (`--orient propagate`, per tile of the
/// plan) marks its patch: what an output holds for the point.
pub(crate) fn point_result(
    rec: &[u8],
    layout: &ResultLayout,
    stored: &ColumnSet,
    flips: Option<&[Vec<bool>]>,
) -> PointResult {
    let (patch, columns) = rec.split_at(8);
    let flip = flipped(patch, flips);
    let result = layout.decode(columns);
    match flip {
        true => result.flipped(&stored.extra),
        false => result,
    }
}
