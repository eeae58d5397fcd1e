//! What every output writer implements: the [`PointSink`] trait (records in, a complete file or
//! nothing out, through `durable::TempFile`). It imports no writer, so that the writers
//! (`las::writer`, `ply`) can use it while `sink` picks among them.

use crate::error::Result;
use crate::io::durable::Ready;

/// An output being written: records in, a complete file (or nothing) out.
pub(crate) trait PointSink {
    /// Appends whole output records (input record + new columns), in file order.
    fn write_points(&mut self, records: &[u8]) -> Result<()>;
    /// Completes and syncs the file, which the [`Ready`] renames over the output; on failure
    /// the temporary file is removed.
    fn finish(self: Box<Self>) -> Result<Ready>;
    /// Removes the temporary file (after a failure or an interruption).
    fn abandon(self: Box<Self>);
}
