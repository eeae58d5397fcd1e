//! A run over points held in memory ([`MemorySource`]): the stages of `process` (prepare, plan,
//! bucket, tiles) on a work directory of its own, then the results collected in the points'
//! order into one array per column instead of an output file. The values are those a
//! `process --f64` run writes for the same points: the same scan, tile plan, neighbour search,
//! halo verification, estimators, orientation (propagation's cross-tile signs included) and
//! `-k auto`, and the same f64 result files. The Python package's `curvature` is this.
//!
//! Memory: the caller's records are read in place; the run holds what `process` holds under
//! the same `--memory` budget (buckets in memory while they fit 2/5 of it, then spilled to the
//! work directory; the tiles in flight), and the columns collected take 8 bytes a point each
//! (1 for the flags, 2 for `ScaleK`), reserved before any work so that a run that cannot hold
//! them fails at once with [`Error::Resource`].

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use crate::config::{ExecOptions, RunOptions, RunParams};
use crate::core::compute::PointResult;
use crate::core::plan::TilePlan;
use crate::core::tasks::TaskLayout;
use crate::error::{Error, Result};
use crate::io::columns::{TerrainValue, Value};
use crate::io::source::memory::MemorySource;
use crate::io::source::PointSource;
use crate::io::workdir::results::{record_size, Merger};
use crate::progress::Reporter;
use crate::run::assemble::{finished, point_result, Finished};
use crate::run::{bucket, prepare, tiles, Exec, Run};

/// One column's values, one per point in the source's order.
#[derive(Debug, Clone, PartialEq)]
pub enum Values {
    /// Curvatures, normals, directions, features: NaN where undefined.
    F64(Vec<f64>),
    /// `CurvatureFlags`, `ScaleFlags` and `TerrainFlags`.
    U8(Vec<u8>),
    /// `ScaleK`.
    U16(Vec<u16>),
}

/// A computed column: its LAS name (`H`, `CurvatureFlags`, ...) and values.
#[derive(Debug, Clone, PartialEq)]
pub struct Column {
    /// The name an output file gives it.
    pub name: &'static str,
    /// The values.
    pub values: Values,
}

/// Reserves room for `n` values, or says that they do not fit.
fn reserve<T>(n: usize, name: &str) -> Result<Vec<T>> {
    let mut v = Vec::new();
    v.try_reserve_exact(n).map_err(|_| {
        Error::Resource(format!(
            "cannot allocate {} MiB for the column {name} of {n} points: free memory, or compute the points in parts (the results do not depend on the split only if each part carries its neighbours: prefer tilecurv.process on a file, which streams)",
            (n * std::mem::size_of::<T>()) >> 20
        ))
    })?;
    Ok(v)
}

impl Values {
    fn for_value(value: Value, n: usize, name: &str) -> Result<Self> {
        Ok(match value {
            Value::Flags | Value::ScaleFlags | Value::Terrain(TerrainValue::Flags) => {
                Values::U8(reserve(n, name)?)
            }
            Value::ScaleK => Values::U16(reserve(n, name)?),
            _ => Values::F64(reserve(n, name)?),
        })
    }

    fn push(&mut self, v: f64) {
        match self {
            Values::F64(a) => a.push(v),
            Values::U8(a) => a.push(v as u8),
            Values::U16(a) => a.push(v as u16),
        }
    }
}

/// A work directory for one run under `parent` that no other run uses (the process id and a
/// counter): points in memory have no fingerprint a rerun could resume from.
fn fresh_work_dir(parent: &Path) -> PathBuf {
    static RUNS: AtomicU64 = AtomicU64::new(0);
    let n = RUNS.fetch_add(1, Ordering::Relaxed);
    parent.join(format!(".tilecurv-memory-{}-{n}", std::process::id()))
}

/// Computes the columns of `source` with `options` (the encoding options, `--f32` and
/// `--f64`, do not apply: the values are f64 as `--f64` stores them). The work directory is
/// made under `work_parent` and removed whatever the outcome. Stops with
/// [`Error::Interrupted`] soon after `cancel` is set.
pub fn curvature(
    source: MemorySource,
    mut options: RunOptions,
    opts: &ExecOptions,
    work_parent: &Path,
    reporter: &dyn Reporter,
    cancel: &AtomicBool,
) -> Result<Vec<Column>> {
    options.f32 = false;
    options.f64 = true;
    let params = RunParams::new(options)?;
    let name = source.path().to_path_buf();
    let sources: Vec<Box<dyn PointSource>> = vec![Box::new(source)];
    let spec = prepare::resolve(&[name], sources, Vec::new(), params, Vec::new(), reporter)?;
    let exec = Exec::new(opts, &spec, reporter, cancel)?;
    let columns = empty_columns(&spec.cols.columns(), spec.total_points as usize)?;
    let layout = TaskLayout::single(&spec.input_points());
    let run = Run::plan(spec, &fresh_work_dir(work_parent), layout, reporter)?;
    let r = (|| {
        let scan = bucket::bucket_all(&run, &exec)?;
        let done = tiles::tiles(&run, &scan, None, &exec)?;
        drop(scan);
        crate::io::limits::return_free_memory();
        collect(&run, &done.plan, &exec, columns)
    })();
    run.work.remove();
    r
}

/// The columns, empty, with room for `n` points each.
fn empty_columns(cols: &[crate::io::columns::Column], n: usize) -> Result<Vec<Column>> {
    cols.iter()
        .map(|c| {
            Ok(Column {
                name: c.name,
                values: Values::for_value(c.value, n, c.name)?,
            })
        })
        .collect()
}

/// Fills `out` from the merge of the tile results, in the source's order: what `assemble`
/// writes after each record (points the class filter leaves out are not computed).
fn collect(
    run: &Run,
    tiles: &TilePlan,
    exec: &Exec<'_>,
    mut out: Vec<Column>,
) -> Result<Vec<Column>> {
    let spec = &run.spec;
    let Finished {
        store,
        files,
        flips,
    } = finished(run, tiles, exec.reporter)?;
    let mut merger = Merger::open(store.dir(), &files, &spec.cols, exec.memory.budget_bytes)?;
    let cols = spec.cols.columns();
    let layout = spec.cols.layout();
    let mut rec = Vec::with_capacity(record_size(&spec.cols));
    let source = spec.sources[0].as_ref();
    let rl = source.record_length();
    exec.reporter.phase("collect", spec.total_points);
    source.for_each_chunk(bucket::chunk_points(spec, exec), &mut |first, records| {
        if exec.cancel.load(Ordering::Relaxed) {
            return Err(Error::Interrupted);
        }
        for (j, r) in records.chunks_exact(rl).enumerate() {
            let id = first + j as u64;
            let result = match spec.params.select.selects(source.class_of(r)) {
                false => PointResult::not_computed(id),
                true => {
                    rec.clear();
                    match merger.append_next(&mut rec)? {
                        Some(rid) if rid == id => {}
                        other => {
                            return Err(Error::Internal(format!(
                                "result {other:?} where point {id} was expected"
                            )))
                        }
                    }
                    point_result(&rec, &layout, &spec.cols, flips.as_deref())
                }
            };
            for (c, o) in cols.iter().zip(&mut out) {
                o.values.push(c.value.get(&result));
            }
        }
        exec.reporter.advance((records.len() / rl) as u64);
        Ok(())
    })?;
    exec.reporter.finish_phase();
    Ok(out)
}
