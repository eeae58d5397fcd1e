//! Writing points. A [`PointSink`] receives each input record followed by its new column bytes,
//! in file order, and makes the output appear atomically on `finish`. [`create_sink`] picks the
//! writer from the output's extension.

use std::path::Path;

use crate::columns::ColumnSet;
use crate::error::{Error, Result};
use crate::source::PointSource;

/// An output being written: records in, a complete file (or nothing) out.
pub trait PointSink {
    /// Appends whole output records (input record + new columns), in file order.
    fn write_points(&mut self, records: &[u8]) -> Result<()>;
    /// Completes the file and renames it over the output.
    fn finish(self: Box<Self>) -> Result<()>;
    /// Removes the temporary file (after a failure or an interruption).
    fn abandon(self: Box<Self>);
}

/// Checks that the output path has a supported extension before any work is done.
pub fn check_output_path(output: &Path) -> Result<()> {
    crate::las_out::output_is_laz(output).map(|_| ())
}

/// Creates the writer for `output` (.las or .laz).
pub fn create_sink(
    source: &dyn PointSource,
    output: &Path,
    cols: &ColumnSet,
    provenance: &str,
) -> Result<Box<dyn PointSink>> {
    crate::las_out::output_is_laz(output)?;
    let las = source.as_las().ok_or_else(|| {
        Error::Usage(format!(
            "{}: LAS/LAZ output needs a LAS/LAZ input",
            output.display()
        ))
    })?;
    Ok(Box::new(crate::las_out::LasWriter::create(
        las, output, cols, provenance,
    )?))
}
