//! `tilecurv._tilecurv`, the compiled half of the Python package: thin calls into the engine
//! crate (`tilecurv`), which knows nothing of Python. The package's `tilecurv/__init__.py`
//! turns Python's arguments (arrays, laspy data, keyword options) into what these take.
//!
//! Every call that computes runs the engine on a thread of its own while the calling thread
//! waits without the GIL, wakes every 50 ms to hand progress events to the callback and to
//! check Python's signals: Ctrl-C sets the engine's cancel flag (the one the command line's
//! SIGINT handler sets), the run stops at its next check, and KeyboardInterrupt is raised.

use std::ffi::OsString;
use std::io::Write;
use std::ops::Deref;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use crossbeam_channel::{unbounded as channel, RecvTimeoutError, Sender};

use numpy::{
    PyArray1, PyArrayDescrMethods, PyReadonlyArray1, PyUntypedArray, PyUntypedArrayMethods,
};
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyKeyboardInterrupt};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use tilecurv::config::{parse_bytes, ExecOptions, Length, RasterOptions, RunOptions, OPTIONS};
use tilecurv::core::raster::Stat;
use tilecurv::error::{Error, ExitClass};
use tilecurv::io::las::header::Quantisation;
use tilecurv::io::las::vlr::Vlr;
use tilecurv::io::source::memory::{Coordinates, MemorySource};
use tilecurv::progress::TermReporter;
use tilecurv::run::memory::Values;
use tilecurv::run::raster::RasterJob;

create_exception!(
    _tilecurv,
    TilecurvError,
    PyException,
    "A tilecurv run failed: the base of the classes named after the command line's exit classes."
);
create_exception!(
    _tilecurv,
    UsageError,
    TilecurvError,
    "A bad option or value (the command line's exit 2)."
);
create_exception!(
    _tilecurv,
    BadInputError,
    TilecurvError,
    "An unreadable, malformed or unsupported input (exit 3)."
);
create_exception!(_tilecurv, OutputError, TilecurvError, "The output or the work directory could not be written or read, or a limit of the machine stopped the run (exit 4): the same call resumes once the cause is fixed.");
create_exception!(
    _tilecurv,
    TasksMissingError,
    TilecurvError,
    "A cluster stage found tasks of an earlier stage not done (exit 5)."
);
create_exception!(
    _tilecurv,
    InternalError,
    TilecurvError,
    "A bug in tilecurv (exit 1): please report it."
);

/// The Python exception of an engine error, with the command line's message.
fn py_error(e: Error) -> PyErr {
    let msg = e.to_string();
    match e.exit_class() {
        ExitClass::Usage => UsageError::new_err(msg),
        ExitClass::BadInput => BadInputError::new_err(msg),
        ExitClass::Output => OutputError::new_err(msg),
        ExitClass::Incomplete => TasksMissingError::new_err(msg),
        ExitClass::Interrupted => PyKeyboardInterrupt::new_err(msg),
        ExitClass::Internal => InternalError::new_err(msg),
    }
}

/// A numpy array's bytes, read in place by the engine. The array is kept alive and unresized by
/// the Python frame that passed it, which waits for the run to end before it returns.
struct ArrayBytes {
    ptr: *const u8,
    len: usize,
}

// SAFETY: the bytes are only read, and outlive every reader (see `ArrayBytes`).
unsafe impl Send for ArrayBytes {}
// SAFETY: as above: shared reads of memory nobody writes during the run.
unsafe impl Sync for ArrayBytes {}

impl Deref for ArrayBytes {
    type Target = [u8];

    fn deref(&self) -> &[u8] {
        // SAFETY: `ptr` points at `len` bytes of a live C-contiguous array (checked in `bytes_of`).
        unsafe { std::slice::from_raw_parts(self.ptr, self.len) }
    }
}

/// The bytes of a C-contiguous array, and its length in records.
fn bytes_of(a: &Bound<'_, PyUntypedArray>) -> PyResult<ArrayBytes> {
    if !a.is_c_contiguous() {
        return Err(UsageError::new_err(
            "the array is not C-contiguous: pass numpy.ascontiguousarray(points)",
        ));
    }
    let len = a.len() * a.dtype().itemsize();
    // SAFETY: a numpy array object; its data pointer is valid for its nbytes.
    let ptr = unsafe { (*a.as_array_ptr()).fields.data as *const u8 };
    Ok(ArrayBytes { ptr, len })
}

/// JSON lines written by the engine's reporter, sent line by line to the waiting thread.
struct Lines {
    tx: Sender<String>,
    partial: Vec<u8>,
}

impl Write for Lines {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.partial.extend_from_slice(buf);
        while let Some(at) = self.partial.iter().position(|&b| b == b'\n') {
            let line: Vec<u8> = self.partial.drain(..=at).collect();
            let _ = self
                .tx
                .send(String::from_utf8_lossy(&line[..at]).into_owned());
        }
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// Runs `work` on a thread of its own while this one waits without the GIL: each line `work`
/// sends goes to `on_line` (with the GIL), Python's signals are checked every 50 ms and a
/// KeyboardInterrupt (or an exception of `on_line`) sets the cancel flag `work` watches; it is
/// raised once `work` has stopped.
fn run_waiting<T: Send>(
    py: Python<'_>,
    on_line: &dyn Fn(&str) -> PyResult<()>,
    work: impl FnOnce(&AtomicBool, Sender<String>) -> tilecurv::error::Result<T> + Send,
) -> PyResult<T> {
    let cancel = AtomicBool::new(false);
    let (tx, rx) = channel::<String>();
    let mut raised: Option<PyErr> = None;
    let r = std::thread::scope(|s| {
        let worker = s.spawn(|| work(&cancel, tx));
        loop {
            match py.detach(|| rx.recv_timeout(Duration::from_millis(50))) {
                Ok(line) if raised.is_none() => {
                    if let Err(e) = on_line(&line) {
                        cancel.store(true, Ordering::SeqCst);
                        raised = Some(e);
                    }
                }
                Ok(_) | Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => break,
            }
            if let Err(e) = py.check_signals() {
                cancel.store(true, Ordering::SeqCst);
                raised.get_or_insert(e);
            }
        }
        py.detach(|| worker.join())
    });
    let r = r.unwrap_or_else(|p| std::panic::resume_unwind(p));
    match (raised, r) {
        (Some(e), _) => Err(e),
        (None, r) => r.map_err(py_error),
    }
}

/// The options that change the output from `(key, text)` pairs, as the command line's flags
/// would set them.
fn run_options(pairs: Vec<(String, String)>) -> PyResult<RunOptions> {
    let mut o = RunOptions::default();
    for (k, v) in pairs {
        o.set(&k, &v).map_err(UsageError::new_err)?;
    }
    Ok(o)
}

/// How the run executes: `threads` (default every core), `memory` (`2G`; default half the
/// machine's memory, at most 4 GiB).
fn exec_options(threads: Option<usize>, memory: Option<&str>) -> PyResult<ExecOptions> {
    let mut e = ExecOptions::default();
    if let Some(t) = threads {
        e.threads = t;
    }
    if let Some(m) = memory {
        e.memory_bytes =
            parse_bytes(m).map_err(|why| UsageError::new_err(format!("memory: {why}")))?;
    }
    Ok(e)
}

/// The option table: `(key, flag, default text, help, is a switch)` per row, in its order.
#[pyfunction]
fn options() -> Vec<(
    &'static str,
    String,
    Option<&'static str>,
    &'static str,
    bool,
)> {
    OPTIONS
        .iter()
        .map(|o| (o.key, o.flag(), o.default, o.help, o.value_name.is_none()))
        .collect()
}

/// Where the coordinates are in the records: `(kind, offsets, scale, offset)` with kind `f64` or
/// `las` (i32 with the scale and offset).
type CoordSpec = (String, [usize; 3], Option<[f64; 3]>, Option<[f64; 3]>);

/// The LAS part of an input: its point format and its VLRs and EVLRs as (user id, record id,
/// payload).
type LasSpec = (u8, Vec<(String, u16, Vec<u8>)>);

/// Computes the curvature columns of the records of `records` (one per element; a structured
/// or (n, 3) float64 array) into a dict of numpy arrays, with the run's warnings.
#[pyfunction]
#[pyo3(signature = (records, record_length, coords, las, normals, options, threads, memory, work_dir))]
#[allow(clippy::too_many_arguments)]
fn curvature<'py>(
    py: Python<'py>,
    records: &Bound<'py, PyUntypedArray>,
    record_length: usize,
    coords: CoordSpec,
    las: Option<LasSpec>,
    normals: Option<PyReadonlyArray1<'py, f64>>,
    options: Vec<(String, String)>,
    threads: Option<usize>,
    memory: Option<String>,
    work_dir: Option<PathBuf>,
) -> PyResult<(Bound<'py, PyDict>, Vec<String>)> {
    let bytes = bytes_of(records)?;
    let coordinates = match (coords.0.as_str(), coords.2, coords.3) {
        ("las", Some(scale), Some(offset)) => Coordinates::Las {
            at: coords.1,
            grid: Quantisation { scale, offset },
        },
        _ => Coordinates::F64(coords.1),
    };
    let mut source = MemorySource::new("<array>", Box::new(bytes), record_length, coordinates)
        .map_err(py_error)?;
    if let Some((format, vlrs)) = las {
        let vlrs = vlrs
            .into_iter()
            .map(|(user_id, record_id, data)| Vlr {
                user_id,
                record_id,
                description: [0; 32],
                reserved: 0,
                data,
            })
            .collect();
        source = source.with_las(format, vlrs).map_err(py_error)?;
    }
    if let Some(n) = normals {
        source = source
            .with_normals(n.as_slice()?.to_vec())
            .map_err(py_error)?;
    }
    let options = run_options(options)?;
    let exec = exec_options(threads, memory.as_deref())?;
    let parent = work_dir.unwrap_or_else(std::env::temp_dir);
    let reporter = Warnings::default();
    let columns = run_waiting(py, &|_| Ok(()), |cancel, _tx| {
        tilecurv::run::memory::curvature(source, options, &exec, &parent, &reporter, cancel)
    })?;
    let out = PyDict::new(py);
    let warnings = reporter.0.into_inner().unwrap_or_default();
    for c in columns {
        match c.values {
            Values::F64(v) => out.set_item(c.name, PyArray1::from_vec(py, v))?,
            Values::U8(v) => out.set_item(c.name, PyArray1::from_vec(py, v))?,
            Values::U16(v) => out.set_item(c.name, PyArray1::from_vec(py, v))?,
        }
    }
    Ok((out, warnings))
}

/// A reporter that keeps the warnings (given to Python's `warnings` by the package) and drops
/// the rest.
#[derive(Default)]
struct Warnings(std::sync::Mutex<Vec<String>>);

impl tilecurv::progress::Reporter for Warnings {
    fn phase(&self, _: &str, _: u64) {}
    fn advance(&self, _: u64) {}
    fn finish_phase(&self) {}
    fn info(&self, _: &str) {}
    fn warn(&self, msg: &str) {
        if let Ok(mut w) = self.0.lock() {
            w.push(msg.to_string());
        }
    }
}

/// `tilecurv process`: runs the command line's run of `inputs` into `output`; `progress` gets
/// each `--progress-json` line (a JSON text). Returns the run's summary.
#[pyfunction]
#[pyo3(signature = (inputs, output, options, work_dir, dry_run, threads, memory, quiet, progress, rasters))]
#[allow(clippy::too_many_arguments)]
fn process(
    py: Python<'_>,
    inputs: Vec<PathBuf>,
    output: PathBuf,
    options: Vec<(String, String)>,
    work_dir: Option<PathBuf>,
    dry_run: bool,
    threads: Option<usize>,
    memory: Option<String>,
    quiet: bool,
    progress: Option<Py<PyAny>>,
    rasters: (
        Option<String>,
        Option<PathBuf>,
        Option<Vec<String>>,
        Option<String>,
    ),
) -> PyResult<Bound<'_, PyDict>> {
    let options = run_options(options)?;
    let mut job = tilecurv::run::Process::new(inputs, output, options).map_err(py_error)?;
    job.work_dir = work_dir;
    job.dry_run = dry_run;
    let (cell, dir, columns, stat) = rasters;
    let exec = ExecOptions {
        rasters: raster_options(cell, dir, columns, stat.as_deref())?,
        ..exec_options(threads, memory.as_deref())?
    };
    let on_line = |line: &str| -> PyResult<()> {
        match &progress {
            Some(cb) => cb.call1(py, (line,)).map(drop),
            None => Ok(()),
        }
    };
    let summary = run_waiting(py, &on_line, |cancel, tx| {
        let lines = Lines {
            tx,
            partial: Vec::new(),
        };
        let reporter = TermReporter::with_json_writer(quiet, Some(Box::new(lines)));
        let s = tilecurv::run::process(&job, &exec, &reporter, cancel)?;
        if !job.dry_run {
            reporter.summary(&s.json_fields(), s.seconds);
        }
        Ok(s)
    })?;
    let d = PyDict::new(py);
    d.set_item("points", summary.points)?;
    d.set_item("undefined", summary.undefined)?;
    d.set_item("tiles", summary.tiles)?;
    d.set_item("tiles_resumed", summary.tiles_resumed)?;
    d.set_item("retried", summary.retried)?;
    d.set_item("seconds", summary.seconds)?;
    d.set_item("outputs", summary.outputs)?;
    Ok(d)
}

/// The rasters `process(raster=...)` asks for, checked as the command line checks them.
fn raster_options(
    cell: Option<String>,
    dir: Option<PathBuf>,
    columns: Option<Vec<String>>,
    stat: Option<&str>,
) -> PyResult<Option<RasterOptions>> {
    let Some(cell) = cell else {
        if dir.is_some() || columns.is_some() || stat.is_some() {
            return Err(UsageError::new_err(
                "raster_dir, raster_columns and raster_stat need raster (the cell size, e.g. raster=\"1m\")",
            ));
        }
        return Ok(None);
    };
    Ok(Some(RasterOptions {
        cell: Length::parse(&cell).map_err(|why| UsageError::new_err(format!("raster: {why}")))?,
        stat: parse_stat(stat.unwrap_or("mean"))?,
        columns: non_empty(columns)?,
        dir,
    }))
}

/// `columns` unless it names none (the command line refuses an empty list too).
fn non_empty(columns: Option<Vec<String>>) -> PyResult<Option<Vec<String>>> {
    match columns {
        Some(c) if c.is_empty() => Err(UsageError::new_err("columns: name at least one column")),
        c => Ok(c),
    }
}

/// The statistic named `stat`, or the usage error naming the choices.
fn parse_stat(stat: &str) -> PyResult<Stat> {
    Stat::parse(stat).map_err(|why| UsageError::new_err(format!("stat: {why}")))
}

/// `tilecurv raster`: the rasters of `inputs`' columns into the directory `output`.
#[pyfunction]
#[pyo3(signature = (inputs, output, cell, columns, stat, memory, quiet))]
#[allow(clippy::too_many_arguments)]
fn raster(
    py: Python<'_>,
    inputs: Vec<PathBuf>,
    output: PathBuf,
    cell: String,
    columns: Option<Vec<String>>,
    stat: String,
    memory: Option<String>,
    quiet: bool,
) -> PyResult<Bound<'_, PyDict>> {
    let job = RasterJob {
        inputs,
        cell: Length::parse(&cell).map_err(|why| UsageError::new_err(format!("cell: {why}")))?,
        columns: non_empty(columns)?,
        stat: parse_stat(&stat)?,
        dir: output,
    };
    let exec = exec_options(None, memory.as_deref())?;
    let s = run_waiting(py, &|_| Ok(()), |cancel, tx| {
        let lines = Lines {
            tx,
            partial: Vec::new(),
        };
        let reporter = TermReporter::with_json_writer(quiet, Some(Box::new(lines)));
        tilecurv::run::raster::raster(
            &job,
            exec.memory_bytes,
            exec.chunk_points,
            &reporter,
            cancel,
        )
    })?;
    let d = PyDict::new(py);
    d.set_item("files", s.files)?;
    d.set_item("points", s.points)?;
    d.set_item("cells", s.cells)?;
    d.set_item("width", s.grid.width)?;
    d.set_item("height", s.grid.height)?;
    d.set_item("cell", s.grid.cell)?;
    Ok(d)
}

/// What `tilecurv info --json FILES` prints.
#[pyfunction]
fn info_json(py: Python<'_>, files: Vec<PathBuf>) -> PyResult<String> {
    py.detach(|| tilecurv::info_json(&files)).map_err(py_error)
}

/// The `tilecurv` command: parses `argv` (the program name first) and runs it, as the binary
/// does; returns the exit code.
#[pyfunction]
fn main(py: Python<'_>, argv: Vec<OsString>) -> i32 {
    py.detach(|| tilecurv::main_with_args(argv))
}

#[pymodule]
fn _tilecurv(m: &Bound<'_, PyModule>) -> PyResult<()> {
    // The binary's check: an ImportError that says what to do instead of a crash at the
    // first AVX2 instruction.
    let missing = tilecurv::missing_cpu_features();
    if !missing.is_empty() {
        return Err(pyo3::exceptions::PyImportError::new_err(format!(
            "this processor lacks {}, which this build of tilecurv uses (built for x86-64-v3); build it for any x86-64 processor with RUSTFLAGS=\"-C target-cpu=x86-64\" pip install python/",
            missing.join(", ")
        )));
    }
    let py = m.py();
    m.add("TilecurvError", py.get_type::<TilecurvError>())?;
    m.add("UsageError", py.get_type::<UsageError>())?;
    m.add("BadInputError", py.get_type::<BadInputError>())?;
    m.add("OutputError", py.get_type::<OutputError>())?;
    m.add("TasksMissingError", py.get_type::<TasksMissingError>())?;
    m.add("InternalError", py.get_type::<InternalError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_function(wrap_pyfunction!(options, m)?)?;
    m.add_function(wrap_pyfunction!(curvature, m)?)?;
    m.add_function(wrap_pyfunction!(process, m)?)?;
    m.add_function(wrap_pyfunction!(raster, m)?)?;
    m.add_function(wrap_pyfunction!(info_json, m)?)?;
    m.add_function(wrap_pyfunction!(main, m)?)?;
    Ok(())
}
