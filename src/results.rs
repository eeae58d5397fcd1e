//! Per-tile result files: each finished tile writes its core points' encoded columns, sorted by
//! original point id, to `tile_<x>_<y>.res` in the work directory (temporary name, then rename),
//! and `assemble` merges them back in file order. Record: id (u64 LE) + the column bytes.

use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};

use crate::columns::ColumnSet;
use crate::compute::PointResult;
use crate::error::{Error, Result};
use crate::plan::TileKey;

const MAGIC: &[u8; 8] = b"TCRES001";

/// Writes one tile's results (sorted here by id) and returns the file's path.
pub fn write_tile(
    dir: &Path,
    key: TileKey,
    results: &mut [PointResult],
    cols: &ColumnSet,
) -> Result<PathBuf> {
    results.sort_unstable_by_key(|r| r.id);
    let path = dir.join(format!("tile_{}_{}.res", key.0, key.1));
    let tmp = path.with_extension("res.tmp");
    let file = File::create(&tmp).map_err(|e| Error::write(&tmp, e))?;
    let mut w = BufWriter::with_capacity(1 << 20, file);
    let mut buf = Vec::with_capacity(8 + cols.record_size());
    let mut io = || -> std::io::Result<()> {
        w.write_all(MAGIC)?;
        w.write_all(&(results.len() as u64).to_le_bytes())?;
        w.write_all(&(cols.record_size() as u64).to_le_bytes())?;
        for r in results.iter() {
            buf.clear();
            buf.extend_from_slice(&r.id.to_le_bytes());
            cols.encode(r, &mut buf);
            w.write_all(&buf)?;
        }
        w.flush()
    };
    io().map_err(|e| Error::write(&tmp, e))?;
    std::fs::rename(&tmp, &path).map_err(|e| Error::write(&path, e))?;
    Ok(path)
}

/// Reads one tile result file in id order.
pub struct TileResults {
    path: PathBuf,
    reader: BufReader<File>,
    remaining: u64,
    record: usize,
}

impl TileResults {
    /// Opens a result file written by [`write_tile`] with the same column set.
    pub fn open(path: &Path, cols: &ColumnSet) -> Result<Self> {
        let bad = |what: String| Error::Internal(format!("{}: {what}", path.display()));
        let file = File::open(path).map_err(|e| Error::ReadIo {
            path: path.to_path_buf(),
            source: e,
        })?;
        let mut reader = BufReader::with_capacity(256 << 10, file);
        let mut head = [0u8; 24];
        reader
            .read_exact(&mut head)
            .map_err(|e| bad(format!("result header unreadable: {e}")))?;
        if &head[..8] != MAGIC {
            return Err(bad("not a tilecurv result file".into()));
        }
        let remaining =
            u64::from_le_bytes(head[8..16].try_into().map_err(|_| bad("header".into()))?);
        let record =
            u64::from_le_bytes(head[16..24].try_into().map_err(|_| bad("header".into()))?) as usize;
        if record != cols.record_size() {
            return Err(bad(format!(
                "records of {record} bytes, expected {}",
                cols.record_size()
            )));
        }
        Ok(TileResults {
            path: path.to_path_buf(),
            reader,
            remaining,
            record,
        })
    }

    /// Reads the next record's id and column bytes into `cols` (resized); None at the end.
    pub fn next(&mut self, cols: &mut Vec<u8>) -> Result<Option<u64>> {
        if self.remaining == 0 {
            return Ok(None);
        }
        let mut id = [0u8; 8];
        cols.resize(self.record, 0);
        self.reader
            .read_exact(&mut id)
            .and_then(|_| self.reader.read_exact(cols))
            .map_err(|e| {
                Error::Internal(format!(
                    "{}: result file ends early: {e}",
                    self.path.display()
                ))
            })?;
        self.remaining -= 1;
        Ok(Some(u64::from_le_bytes(id)))
    }
}
