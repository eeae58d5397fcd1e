//! Choosing the writer of an output. A [`PointSink`] receives each input record followed by its
//! new column bytes, in file order, and makes the output appear atomically on `finish`;
//! [`create_sink`] picks the writer from the output's extension. The trait and the atomic-output
//! steps live in `io::output`, which imports no writer, so that the writers can use them while
//! this module imports the writers.

use std::path::Path;

use crate::error::{Error, Result};
use crate::io::columns::output::{Encoding, OutputColumns};
use crate::io::columns::ColumnSet;
use crate::io::las_output::carry;
use crate::io::las_output::convert::{self, ConvertedSink};
use crate::io::ply::{PlyNames, PlyWriter};
use crate::io::source::{PointSource, SourceLayout};

pub(crate) use crate::io::output::PointSink;

/// Which existing file `path` names, None when it names none: its device and inode, so that a
/// symbolic link and a hard link (two names of one file, which a path cannot tell apart) are
/// the file they name.
#[cfg(unix)]
pub(crate) fn file_id(path: &Path) -> Option<(u64, u64)> {
    use std::os::unix::fs::MetadataExt;
    std::fs::metadata(path).ok().map(|m| (m.dev(), m.ino()))
}

/// Which existing file `path` names, None when it names none: its canonical path.
#[cfg(not(unix))]
pub(crate) fn file_id(path: &Path) -> Option<PathBuf> {
    path.canonicalize().ok()
}

/// Whether `a` and `b` name the same existing file ([`file_id`]).
pub(crate) fn same_file(a: &Path, b: &Path) -> bool {
    file_id(a).is_some_and(|x| file_id(b) == Some(x))
}

/// The output formats, chosen by the output's extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum OutputFormat {
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
pub(crate) fn output_format(output: &Path) -> Result<OutputFormat> {
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
pub(crate) fn check_output_path(output: &Path) -> Result<()> {
    output_format(output).map(|_| ())
}

/// How outputs are written, besides their columns (the options of a run that change the
/// output's bytes but not its values).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct OutputOptions {
    /// A LAS/LAZ output keeps its LAS input's version instead of becoming LAS 1.4.
    pub keep_las_version: bool,
    /// How a PLY output names the new columns.
    pub ply_names: PlyNames,
}

/// The new columns of `output` as `encoding` stores them: in a PLY output, which has no scale
/// field, scaled integers become f32.
pub(crate) fn output_columns(
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

/// The extra-bytes descriptors (encoded) of a LAS/LAZ output of `source` with the new columns
/// `cols`: the one payload its writer stores (the input's descriptors, merged, or a converted
/// input's, then the new columns'), whose size decides whether it fits a VLR.
pub(crate) fn extra_bytes_payload(
    source: &dyn PointSource,
    cols: &OutputColumns,
) -> Result<Vec<u8>> {
    match source.layout() {
        SourceLayout::Las(parts) => carry::extra_bytes_payload(&parts, cols),
        SourceLayout::Converted => {
            let mut data = convert::input_descriptors(source)?;
            for c in cols.descriptors() {
                data.extend_from_slice(&crate::io::las::extra_bytes::encode(&c));
            }
            Ok(data)
        }
    }
}

/// Creates the writer for `output`: LAS/LAZ (a LAS input's records kept byte for byte, any
/// other input converted) or PLY, with the new columns `cols` ([`output_columns`]).
pub(crate) fn create_sink(
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::source::{open_bytes, Format, InputBytes};

    /// What is left in `dir` besides `keep`.
    fn leftovers(dir: &Path, keep: &str) -> Vec<String> {
        std::fs::read_dir(dir)
            .expect("lists")
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| n != keep)
            .collect()
    }

    /// A LAS 1.2 file of three point format 0 records.
    fn tiny_las() -> Vec<u8> {
        use crate::io::las::writer::{tests, LasFileWriter};
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("tiny.las");
        let mut w = LasFileWriter::create(&path, tests::spec(3)).expect("creates");
        for xyz in [[0i32, 0, 0], [100, 0, 0], [0, 100, 100]] {
            w.write_records(&tests::record(xyz)).expect("writes");
        }
        w.finish().expect("finishes");
        std::fs::read(&path).expect("reads back")
    }

    /// Whichever way a writer ends short of a committed output (the final
    /// rename fails, it is abandoned, it is dropped unfinished), no temporary file is left
    /// beside the output, for every writer: LAS and LAZ (a LAS input's records carried, and a
    /// converted one), binary and ASCII PLY. Failed writes and flushes are the integration
    /// tests' (`faults::write_failures_*`), which make the disk fail for real.
    #[test]
    fn every_writer_leaves_no_temp_file_on_any_failure() {
        let ply = b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n1 0 0\n0 1 1\n";
        let ply_in = open_bytes(
            Path::new("in.ply"),
            Format::Ply,
            InputBytes::Owned(ply.to_vec()),
        )
        .expect("opens the PLY");
        let las_in = open_bytes(
            Path::new("in.las"),
            Format::Las,
            InputBytes::Owned(tiny_las()),
        )
        .expect("opens the LAS");
        let set = ColumnSet {
            choice: Default::default(),
            extra: Vec::new(),
            unit: "m".into(),
            wide: true,
        };
        let cols = crate::io::columns::output::OutputColumns::new(
            &set,
            crate::io::columns::output::Encoding::F32,
        );
        let records = |src: &dyn PointSource| {
            let mut out = Vec::new();
            src.for_each_chunk(1024, &mut |_, recs| {
                for r in recs.chunks_exact(src.record_length()) {
                    out.extend_from_slice(r);
                    out.resize(out.len() + cols.record_size(), 0);
                }
                Ok(())
            })
            .expect("reads");
            out
        };
        let dir = tempfile::tempdir().expect("temp dir");
        for src in [ply_in.as_ref(), las_in.as_ref()] {
            for name in ["o.las", "o.laz", "o.ply", "o.ascii.ply"] {
                let out = dir.path().join(name);
                let what = format!("{} -> {name}", src.path().display());
                let sink = || {
                    let mut s = create_sink(src, &out, &cols, "test", &OutputOptions::default())
                        .expect("creates");
                    s.write_points(&records(src)).expect("writes");
                    s
                };
                // The rename fails: a non-empty directory stands where the output goes.
                std::fs::create_dir_all(out.join("x")).expect("blocking directory");
                let e = (sink().finish())
                    .and_then(|r| r.commit())
                    .expect_err("the rename fails");
                assert!(
                    matches!(&e, Error::WriteIo { path, .. } if path == &out),
                    "{what}: {e}"
                );
                assert!(leftovers(dir.path(), name).is_empty(), "{what}");
                std::fs::remove_dir_all(&out).expect("unblock");
                sink().abandon();
                assert!(leftovers(dir.path(), "").is_empty(), "{what}: abandon");
                drop(sink());
                assert!(leftovers(dir.path(), "").is_empty(), "{what}: drop");
                drop(sink().finish().expect("finishes"));
                assert!(
                    leftovers(dir.path(), "").is_empty(),
                    "{what}: not committed"
                );
                assert!(!out.exists(), "{what}: not committed");
                (sink().finish())
                    .and_then(|r| r.commit())
                    .expect("finishes");
                assert_eq!(leftovers(dir.path(), name), Vec::<String>::new(), "{what}");
                std::fs::remove_file(&out).expect("clean");
            }
        }
    }
}
