//! Choosing the writer of an output. A [`PointSink`] receives each input record followed by its
//! new column bytes, in file order, and makes the output appear atomically on `finish`;
//! [`create_sink`] picks the writer from the output's extension. The trait and the atomic-output
//! steps live in `io::output`, which imports no writer, so that the writers can use them while
//! this module imports the writers.

use std::path::Path;

use crate::error::{Error, Result};
use crate::io::columns::output::{Encoding, OutputColumns};
use crate::io::columns::ColumnSet;
use crate::io::las::{carry, convert::ConvertedSink};
use crate::io::ply::{PlyNames, PlyWriter};
use crate::io::source::{PointSource, SourceLayout};

pub use crate::io::output::PointSink;

/// The output formats, chosen by the output's extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OutputFormat {
    /// `.las`
    Las,
    /// `.laz`
    Laz,
    /// `.ply`: binary little endian, or ASCII when the name ends in `.ascii.ply`.
    Ply {
        /// Whether to write ASCII PLY.
        ascii: bool,
    },
}

/// The format an output path asks for.
pub fn output_format(output: &Path) -> Result<OutputFormat> {
    let name = output
        .file_name()
        .map(|n| n.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let ext = name.rsplit_once('.').map(|(_, e)| e);
    match ext {
        Some("las") => Ok(OutputFormat::Las),
        Some("laz") => Ok(OutputFormat::Laz),
        Some("ply") => Ok(OutputFormat::Ply {
            ascii: name.ends_with(".ascii.ply"),
        }),
        _ => Err(Error::Usage(format!(
            "{}: the output must end in .las, .laz or .ply (.ascii.ply for ASCII PLY): the extension chooses the format",
            output.display()
        ))),
    }
}

/// Checks that the output path has a supported extension before any work is done.
pub fn check_output_path(output: &Path) -> Result<()> {
    output_format(output).map(|_| ())
}

/// How outputs are written, besides their columns (the options of a run that change the
/// output's bytes but not its values).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct OutputOptions {
    /// A LAS/LAZ output keeps its LAS input's version instead of becoming LAS 1.4.
    pub keep_las_version: bool,
    /// How a PLY output names the new columns.
    pub ply_names: PlyNames,
}

/// The new columns of `output` as `encoding` stores them: in a PLY output, which has no scale
/// field, scaled integers become f32.
pub fn output_columns(
    output: &Path,
    cols: &ColumnSet,
    encoding: Encoding,
) -> Result<OutputColumns> {
    let encoding = match output_format(output)? {
        OutputFormat::Ply { .. } => encoding.floats(),
        OutputFormat::Las | OutputFormat::Laz => encoding,
    };
    Ok(OutputColumns::new(cols, encoding))
}

/// Creates the writer for `output`: LAS/LAZ (a LAS input's records kept byte for byte, any
/// other input converted) or PLY, with the new columns `cols` ([`output_columns`]).
pub fn create_sink(
    source: &dyn PointSource,
    output: &Path,
    cols: &OutputColumns,
    provenance: &str,
    options: &OutputOptions,
) -> Result<Box<dyn PointSink>> {
    Ok(match output_format(output)? {
        OutputFormat::Las | OutputFormat::Laz => match source.layout() {
            SourceLayout::Las(parts) => {
                let version = if options.keep_las_version {
                    carry::Version::Input
                } else {
                    carry::Version::Las14
                };
                Box::new(carry::create(parts, output, cols, provenance, version)?)
            }
            SourceLayout::Converted => {
                Box::new(ConvertedSink::create(source, output, cols, provenance)?)
            }
        },
        OutputFormat::Ply { ascii } => Box::new(PlyWriter::create(
            source,
            output,
            cols,
            provenance,
            ascii,
            options.ply_names,
        )?),
    })
}
