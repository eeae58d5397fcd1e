//! Re-running on an output, part of `prepare`. A LAS/LAZ input with
//! tilecurv's provenance record is opened without the columns its newest `process` record says
//! that run wrote (`LasSource::drop_extra`): every stage then sees the input as it was before
//! that run, so the new columns replace the old ones, the old normals are not taken as the
//! file's, and the result is the one a run on the original file gives; one warning names the
//! columns and the run. Any other extra dimension or property named like a new column is
//! refused before any work, naming the file and the column and saying what to do. A PLY output
//! of tilecurv given back is refused for now.

use std::path::{Path, PathBuf};

use crate::config::RunParams;
use crate::error::{Error, Result};
use crate::io::columns::{every_name, Column, ColumnSet};
use crate::io::las::provenance::{self, is_process_record, PreviousRun};
use crate::io::las::vlr::Vlr;
use crate::io::ply::PlyNames;
use crate::io::sink::{output_format, OutputFormat};
use crate::io::source::{self, Format, LasSource, PointSource, SourceLayout};

/// An input opened for a run.
pub(crate) struct Opened {
    /// The input.
    pub(crate) source: Box<dyn PointSource>,
    /// The warning that its previous run's columns are replaced, for the caller to give once
    /// every check passed.
    pub(crate) note: Option<String>,
}

/// Opens the input `path` of a run: a LAS/LAZ tilecurv output without its previous run's
/// columns, with the warning that says so, a tilecurv PLY output refused, any other file as
/// it is.
pub(crate) fn open_input(path: &Path) -> Result<Opened> {
    let plain = |source| Opened { source, note: None };
    match source::detect(path)? {
        Format::Las => {
            let mut s = LasSource::from_bytes(path, source::map_file(path)?)?;
            let texts = record_texts(&s.vlrs, &s.evlrs);
            let run = provenance::previous_run(&texts, &s.extra, &every_name());
            let mut note = None;
            if let Some(run) = run.filter(|r| !r.columns.is_empty()) {
                s.drop_extra(&run.columns)?;
                note = Some(replaced_note(path, &run));
            }
            Ok(Opened {
                source: Box::new(s),
                note,
            })
        }
        Format::Ply => {
            let map = source::map_file(path)?;
            match source::ply::provenance(path, &map)?.filter(|t| is_process_record(t)) {
                Some(text) => Err(Error::bad_input(
                    path,
                    None,
                    format!(
                        "a PLY output of {}: re-running on a PLY output is not supported yet (its nx ny nz would be taken as the file's normals and its scalar_* columns kept beside the new ones); process the original file, or a LAS/LAZ output of tilecurv, whose own columns are replaced",
                        run_words(&text)
                    ),
                )),
                None => Ok(plain(source::ply::from_bytes(path, map)?)),
            }
        }
        format => Ok(plain(source::open_format(path, format)?)),
    }
}

/// The provenance texts among a LAS file's VLRs, then its EVLRs.
fn record_texts(vlrs: &[Vlr], evlrs: &[(u64, Vlr)]) -> Vec<String> {
    provenance::texts(crate::io::las::vlr::records(vlrs, evlrs))
}

/// The previous run in words: `tilecurv 0.1.0 (inputs a.las)`.
fn run_words(text: &str) -> String {
    match provenance::previous_run(&[text.to_string()], &[], &[]) {
        Some(r) if !r.inputs.is_empty() => format!("{} (inputs {})", r.tool, r.inputs),
        Some(r) => r.tool,
        None => "tilecurv".into(),
    }
}

/// The warning of a re-run: which columns are replaced, and the run that wrote them.
fn replaced_note(path: &Path, run: &PreviousRun) -> String {
    let how = if run.listed {
        "its provenance record lists them"
    } else {
        "its provenance record does not list its columns, so every column name tilecurv writes is taken as its"
    };
    let inputs = if run.inputs.is_empty() {
        String::new()
    } else {
        format!(" on {}", run.inputs)
    };
    format!(
        "{}: replacing {}, the columns of an earlier run ({}{inputs}; {how}): they are computed afresh (its normals are not the file's), and its provenance records are kept",
        path.display(),
        run.columns.join(", "),
        run.tool,
    )
}

/// The refusal of a new column whose name the input already has (`what`: its dimension or
/// property, named), with what to do: `--columns` without the column's group, or a rename.
fn clash(cfg: &RunParams, source: &dyn PointSource, what: &str, column: &Column) -> Error {
    let texts = match source.layout() {
        SourceLayout::Las(p) => record_texts(p.vlrs, p.evlrs),
        SourceLayout::Converted => Vec::new(),
    };
    let whose = if texts.iter().any(|t| is_process_record(t)) {
        "the input's tilecurv provenance record does not list it among that run's columns, so it is not replaced"
    } else {
        "the input has no provenance record of a tilecurv run that wrote it, so it is not a tilecurv column to replace"
    };
    let without = cfg.columns.without_value(column.value).to_string();
    let todo = if without.is_empty() {
        "rename the input's dimension (the new column is the only one asked for)".to_string()
    } else {
        format!("leave the new one out with --columns {without}, or rename the input's dimension")
    };
    Error::bad_input(
        source.path(),
        None,
        format!(
            "the input already has {what}, and the new column {} would repeat it ({whose}); {todo}",
            column.name
        ),
    )
}

/// Refuses, before any work, an input that has an extra dimension or property named like one
/// of the new columns (any case, as LAS readers match names): the output would hold two.
/// Tilecurv's own columns are gone by now ([`open_input`]), so this is someone else's column.
pub(crate) fn check_new_names(
    cfg: &RunParams,
    sources: &[Box<dyn PointSource>],
    cols: &ColumnSet,
) -> Result<()> {
    for s in sources {
        let props = s.properties();
        for c in cols.columns() {
            if let Some(p) = props.iter().find(|p| p.name.eq_ignore_ascii_case(c.name)) {
                let what = format!("an extra dimension named {:?}", p.name);
                return Err(clash(cfg, s.as_ref(), &what, &c));
            }
        }
    }
    Ok(())
}

/// Refuses, before any work, a PLY output (among `outputs`, one per source) whose new
/// columns' PLY names (`scalar_H`, `nx`, as `style` names them) an input property already has.
pub(crate) fn check_ply_names(
    cfg: &RunParams,
    sources: &[Box<dyn PointSource>],
    outputs: &[PathBuf],
    cols: &ColumnSet,
    style: PlyNames,
) -> Result<()> {
    let columns = cols.columns();
    for (s, output) in sources.iter().zip(outputs) {
        if !matches!(output_format(output)?, OutputFormat::Ply { .. }) {
            continue;
        }
        let props = s.properties();
        let input: Vec<&str> = props.iter().map(|p| p.name.as_str()).collect();
        let names = columns.iter().map(|c| c.name);
        if let Err((name, column)) = crate::io::ply::column_names(&input, names, style) {
            let what = format!(
                "a property named {name:?} (the PLY name of {column} in {})",
                output.display()
            );
            if let Some(c) = columns.iter().find(|c| c.name == column) {
                return Err(clash(cfg, s.as_ref(), &what, c));
            }
        }
    }
    Ok(())
}
