//! Bringing each cell's points together out of core: an external sort of (cell key, values)
//! records. Records are kept in memory up to a budget; past it they are sorted by key and
//! written as a run file, and the runs are merged back in key order, so a cell's values arrive
//! together and the cells arrive in the order a north-up raster is written
//! ([`crate::core::raster::Cell::key`]). Memory is the budget plus a read buffer per run,
//! whatever the number of points or cells. The run files are temporary: they live in a
//! directory the caller names and are removed when the bins are dropped.

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};

use crate::core::radix::sort_by_key;
use crate::error::{Error, Result};

/// Runs merged at once; past it, runs are first merged into longer runs. Each open run holds
/// one read buffer ([`Bins::buffer`]).
const MAX_FAN_IN: usize = 256;

/// The most bytes of each run's read buffer and of the run writer's buffer.
const READ_BUFFER: usize = 256 << 10;

/// The two words that carry `v` in a record: its low and high halves.
pub(super) fn words_of(v: i64) -> [u32; 2] {
    [v as u64 as u32, (v as u64 >> 32) as u32]
}

/// The integer of the two words `low`, `high` ([`words_of`]).
pub(super) fn from_words(low: u32, high: u32) -> i64 {
    (u64::from(high) << 32 | u64::from(low)) as i64
}

/// Records of `columns` 32-bit words per point (a column's f32 bits, or words of integers and
/// tallies), binned by cell key.
pub(crate) struct Bins {
    dir: PathBuf,
    /// The start of the run files' names (bins of different records share a directory).
    name: &'static str,
    columns: usize,
    /// Per record in memory: its key and its index in `values`.
    keys: Vec<(u64, u32)>,
    values: Vec<u32>,
    /// Records kept in memory before a run is written.
    capacity: usize,
    /// Bytes of each run file's buffer: the budget shared by a merge's readers and a writer
    /// (within 4 KiB to [`READ_BUFFER`]), whose records' memory is freed before the merge.
    buffer: usize,
    runs: Vec<PathBuf>,
    /// Run files written so far (their names are numbered).
    written: usize,
    /// Whether `dir` was made by these bins (and is removed with them).
    made_dir: bool,
}

/// Bytes a record takes in memory (key, index, values) and in a run file (key, values).
pub(super) fn record_bytes(columns: usize) -> usize {
    16 + 4 * columns
}

impl Bins {
    /// Bins for records of `columns` values, keeping at most `budget` bytes of them in memory;
    /// run files go to `dir` (made when the first run is written), named `name1.bin`,
    /// `name2.bin`, ... Room for `expected` records
    /// (at most what the budget holds) is made at once: grown by doubling, the records were
    /// copied and their pages touched twice over.
    pub(crate) fn new(
        dir: &Path,
        name: &'static str,
        columns: usize,
        budget: u64,
        expected: u64,
    ) -> Self {
        let capacity = (budget as usize / record_bytes(columns)).clamp(1 << 12, u32::MAX as usize);
        let room = usize::try_from(expected).map_or(capacity, |e| e.min(capacity));
        Bins {
            dir: dir.to_path_buf(),
            name,
            columns,
            keys: Vec::with_capacity(room),
            values: Vec::with_capacity(room * columns),
            capacity,
            buffer: (budget as usize / (MAX_FAN_IN + 1)).clamp(4 << 10, READ_BUFFER),
            runs: Vec::new(),
            written: 0,
            made_dir: false,
        }
    }

    /// Adds one record: its cell key and one value per column (a point's values, NaN for
    /// undefined; or the words of a cell's tallies).
    pub(crate) fn push(&mut self, key: u64, values: &[u32]) -> Result<()> {
        debug_assert_eq!(values.len(), self.columns);
        self.keys.push((key, self.keys.len() as u32));
        self.values.extend_from_slice(values);
        if self.keys.len() >= self.capacity {
            self.spill()?;
        }
        Ok(())
    }

    /// Sorts the records in memory by key (stably: [`sort_by_key`]).
    fn sort(&mut self) {
        let mut spare = Vec::new();
        sort_by_key(&mut self.keys, &mut spare);
    }

    /// The path of the next run file.
    fn run_path(&mut self) -> PathBuf {
        self.written += 1;
        self.dir.join(format!("{}{}.bin", self.name, self.written))
    }

    /// Writes the records in memory as a sorted run file.
    pub(crate) fn spill(&mut self) -> Result<()> {
        if self.keys.is_empty() {
            return Ok(());
        }
        if !self.made_dir {
            std::fs::create_dir_all(&self.dir).map_err(|e| Error::write(&self.dir, e))?;
            self.made_dir = true;
        }
        self.sort();
        let path = self.run_path();
        let mut w = RunWriter::create(&path, self.buffer)?;
        let n = self.columns;
        for &(key, i) in &self.keys {
            let i = i as usize * n;
            w.put(key, &self.values[i..i + n])?;
        }
        w.finish()?;
        self.runs.push(path);
        self.keys.clear();
        self.values.clear();
        Ok(())
    }

    /// The records in key order: from memory when they never outgrew it, else merged from the
    /// run files (past [`MAX_FAN_IN`] runs, merged into longer runs first).
    pub(crate) fn into_cells(mut self) -> Result<Cells> {
        if self.runs.is_empty() {
            self.sort();
            let source = Source::Memory {
                keys: std::mem::take(&mut self.keys),
                values: std::mem::take(&mut self.values),
                next: 0,
            };
            return Ok(Cells::new(self, source));
        }
        self.spill()?;
        // The records' memory goes to the merge's buffers.
        (self.keys, self.values) = (Vec::new(), Vec::new());
        while self.runs.len() > MAX_FAN_IN {
            let group: Vec<PathBuf> = self.runs.drain(..MAX_FAN_IN).collect();
            let path = self.run_path();
            let mut merged = Merge::open(&group, self.columns, self.buffer)?;
            let mut w = RunWriter::create(&path, self.buffer)?;
            let mut values = vec![0; self.columns];
            while let Some(key) = merged.next_record(&mut values)? {
                w.put(key, &values)?;
            }
            w.finish()?;
            drop(merged);
            for p in &group {
                let _ = std::fs::remove_file(p);
            }
            self.runs.push(path);
        }
        let merge = Merge::open(&self.runs, self.columns, self.buffer)?;
        Ok(Cells::new(self, Source::Runs(merge)))
    }
}

impl Drop for Bins {
    fn drop(&mut self) {
        for p in &self.runs {
            let _ = std::fs::remove_file(p);
        }
        if self.made_dir {
            let _ = std::fs::remove_dir(&self.dir);
        }
    }
}

/// Writes one run file.
struct RunWriter {
    path: PathBuf,
    w: BufWriter<File>,
}

impl RunWriter {
    fn create(path: &Path, buffer: usize) -> Result<RunWriter> {
        let f = File::create(path).map_err(|e| Error::write(path, e))?;
        Ok(RunWriter {
            path: path.to_path_buf(),
            w: BufWriter::with_capacity(buffer, f),
        })
    }

    fn put(&mut self, key: u64, values: &[u32]) -> Result<()> {
        let mut rec = [0u8; 8];
        rec.copy_from_slice(&key.to_le_bytes());
        self.w
            .write_all(&rec)
            .map_err(|e| Error::write(&self.path, e))?;
        for v in values {
            self.w
                .write_all(&v.to_le_bytes())
                .map_err(|e| Error::write(&self.path, e))?;
        }
        Ok(())
    }

    fn finish(mut self) -> Result<()> {
        self.w.flush().map_err(|e| Error::write(&self.path, e))
    }
}

/// One run file being read back.
struct RunReader {
    path: PathBuf,
    r: BufReader<File>,
    rec: Vec<u8>,
}

impl RunReader {
    /// The next record's key, its values in `values`; None at the end.
    fn next(&mut self, values: &mut [u32]) -> Result<Option<u64>> {
        match self.r.read_exact(&mut self.rec) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => return Ok(None),
            Err(e) => return Err(Error::read_work(&self.path, e)),
        }
        let (key, rest) = self.rec.split_at(8);
        for (v, b) in values.iter_mut().zip(rest.chunks_exact(4)) {
            *v = u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
        }
        Ok(Some(u64::from_le_bytes(key.try_into().unwrap_or([0; 8]))))
    }
}

/// A k-way merge of sorted run files. Equal keys come run by run in the order of the runs,
/// which does not matter: a cell's values are sorted before they are reduced, and its partial
/// tallies merge exactly.
struct Merge {
    runs: Vec<RunReader>,
    /// Per run, its current record's values.
    heads: Vec<Vec<u32>>,
    heap: BinaryHeap<Reverse<(u64, usize)>>,
}

impl Merge {
    fn open(paths: &[PathBuf], columns: usize, buffer: usize) -> Result<Self> {
        let mut m = Merge {
            runs: Vec::with_capacity(paths.len()),
            heads: vec![vec![0; columns]; paths.len()],
            heap: BinaryHeap::with_capacity(paths.len()),
        };
        for (i, p) in paths.iter().enumerate() {
            let f = File::open(p).map_err(|e| Error::read_work(p, e))?;
            m.runs.push(RunReader {
                path: p.clone(),
                r: BufReader::with_capacity(buffer, f),
                rec: vec![0; 8 + 4 * columns],
            });
            if let Some(k) = m.runs[i].next(&mut m.heads[i])? {
                m.heap.push(Reverse((k, i)));
            }
        }
        Ok(m)
    }

    /// The next record in key order into `values`; None at the end.
    fn next_record(&mut self, values: &mut [u32]) -> Result<Option<u64>> {
        let Some(Reverse((key, i))) = self.heap.pop() else {
            return Ok(None);
        };
        values.copy_from_slice(&self.heads[i]);
        if let Some(k) = self.runs[i].next(&mut self.heads[i])? {
            self.heap.push(Reverse((k, i)));
        }
        Ok(Some(key))
    }
}

/// Where the sorted records come from.
enum Source {
    Memory {
        keys: Vec<(u64, u32)>,
        values: Vec<u32>,
        next: usize,
    },
    Runs(Merge),
}

/// The cells in key order, each with its points' values per column.
pub(crate) struct Cells {
    /// Kept so that the run files live until the cells are read.
    bins: Bins,
    source: Source,
    /// From runs: the record read past the last cell, the first of the next one.
    pending: Option<u64>,
    pending_values: Vec<u32>,
    started: bool,
}

impl Cells {
    fn new(bins: Bins, source: Source) -> Self {
        let columns = bins.columns;
        Cells {
            bins,
            source,
            pending: None,
            pending_values: vec![0; columns],
            started: false,
        }
    }

    /// The next cell's key, its values column by column in `out` (one vector a column,
    /// cleared first: `out[c]` holds column `c`'s values of the cell's records); None after
    /// the last cell.
    pub(crate) fn next_cell(&mut self, out: &mut Vec<Vec<u32>>) -> Result<Option<u64>> {
        let n = self.bins.columns;
        out.resize_with(n, Vec::new);
        out.iter_mut().for_each(Vec::clear);
        let merge = match &mut self.source {
            Source::Memory { keys, values, next } => {
                // The cell's records are the next run of its key: each column gathered in one
                // loop, without a copy of every record and a push of every value.
                let Some(&(key, _)) = keys.get(*next) else {
                    return Ok(None);
                };
                let len = keys[*next..].iter().take_while(|r| r.0 == key).count();
                let cell = &keys[*next..*next + len];
                for (c, o) in out.iter_mut().take(n).enumerate() {
                    o.extend(cell.iter().map(|&(_, i)| values[i as usize * n + c]));
                }
                *next += len;
                return Ok(Some(key));
            }
            Source::Runs(m) => m,
        };
        if !self.started {
            self.started = true;
            self.pending = merge.next_record(&mut self.pending_values)?;
        }
        let Some(key) = self.pending else {
            return Ok(None);
        };
        loop {
            for (o, &v) in out.iter_mut().zip(&self.pending_values) {
                o.push(v);
            }
            self.pending = merge.next_record(&mut self.pending_values)?;
            if self.pending != Some(key) {
                return Ok(Some(key));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every record of a cell arrives with it and the cells arrive in key order, whether the
    /// records stayed in memory or went through runs (and through a merge into longer runs).
    #[test]
    fn cells_come_back_whole_and_in_key_order_through_runs() {
        let tmp = tempfile::tempdir().expect("temp dir");
        let n = 40_000u64;
        // Keys in a scrambled order; cell k holds the points i with i % 997 == k.
        let record = |i: u64| ((i * 7919) % n, [i as u32, !(i as u32)]);
        for (budget, runs) in [(1u64 << 30, false), (4096 * 24, true)] {
            let dir = tmp.path().join(format!("b{budget}"));
            let mut bins = Bins::new(&dir, "run", 2, budget, 1000);
            for i in 0..n {
                let (p, v) = record(i);
                bins.push(p % 997, &v).expect("push");
            }
            assert_eq!(!bins.runs.is_empty(), runs);
            let mut cells = bins.into_cells().expect("cells");
            let mut out = vec![Vec::new(), Vec::new()];
            let (mut last, mut seen) = (None, 0);
            while let Some(key) = cells.next_cell(&mut out).expect("cell") {
                assert!(last < Some(key), "keys in order");
                last = Some(key);
                let mut got: Vec<u32> = out[0].clone();
                got.sort_unstable();
                let want: Vec<u32> = (0..n)
                    .filter(|&i| record(i).0 % 997 == key)
                    .map(|i| i as u32)
                    .collect();
                assert_eq!(got, want, "cell {key}");
                assert!(out[0].iter().zip(&out[1]).all(|(a, b)| *a == !*b));
                seen += out[0].len();
            }
            assert_eq!((seen as u64, last), (n, Some(996)));
            drop(cells);
            assert!(!dir.exists(), "run files removed");
        }
    }

    /// Past the fan-in the runs are merged into longer ones first; nothing is lost.
    #[test]
    fn many_runs_are_merged_in_passes() {
        let tmp = tempfile::tempdir().expect("temp dir");
        let dir = tmp.path().join("runs");
        let mut bins = Bins::new(&dir, "run", 1, 0, 0);
        let n = (MAX_FAN_IN as u64 + 40) * 4096;
        for i in 0..n {
            bins.push(n - 1 - i, &[i as u32]).expect("push");
        }
        let mut cells = bins.into_cells().expect("cells");
        let mut out = vec![Vec::new()];
        let mut k = 0;
        while let Some(key) = cells.next_cell(&mut out).expect("cell") {
            assert_eq!((key, out[0].as_slice()), (k, &[(n - 1 - k) as u32][..]));
            k += 1;
        }
        assert_eq!(k, n);
    }
}
