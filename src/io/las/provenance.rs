//! tilecurv's provenance records (VLR `tilecurv`, 1): the text `process` and `generate` write
//! into every output, and what a re-run reads back from an input's records: the newest
//! `process` record, the run it names and the columns it wrote ([`PreviousRun`]). Reads text
//! only: what a run does with those columns is `run::rerun`'s.
//!
//! A `process` record is `tilecurv <version>`, then `inputs=...`, one `key=value` line per
//! parameter, and (since scaled columns) one `column.<name>=<type>` line per column written.
//! A `generate` record names no inputs. The writer carries an input's records over and appends
//! its own, so in file order the last record is the newest.

use super::extra_bytes::Descriptor;
use super::vlr::Vlr;

/// User id and record id of the provenance VLR.
pub const PROVENANCE: (&str, u16) = ("tilecurv", 1);

/// The texts of the provenance records among `records` (a file's VLRs, then its EVLRs), in
/// file order, without the NUL padding some writers add.
pub fn texts<'a>(records: impl IntoIterator<Item = &'a Vlr>) -> Vec<String> {
    records
        .into_iter()
        .filter(|v| v.is(PROVENANCE.0, PROVENANCE.1))
        .map(|v| {
            String::from_utf8_lossy(&v.data)
                .trim_end_matches('\0')
                .to_string()
        })
        .collect()
}

/// An earlier `process` run that wrote a file, from the file's newest `process` record.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PreviousRun {
    /// The record's first line: `tilecurv <version>`.
    pub tool: String,
    /// Its inputs (the `inputs=` value: file names).
    pub inputs: String,
    /// The columns it wrote that the file still has, as the file names them, in the file's
    /// order.
    pub columns: Vec<String>,
    /// Whether the record lists its columns (`column.<name>=` lines). Records written before
    /// the lines existed do not: every name tilecurv writes is then taken as the run's (but
    /// NormalX/Y/Z, when it says `normals=file`: those were its input's).
    pub listed: bool,
}

/// Whether a record's text is a `process` record (a `generate` record names no inputs).
pub fn is_process_record(text: &str) -> bool {
    let mut lines = text.lines();
    lines.next().is_some_and(|l| l.starts_with("tilecurv "))
        && lines.any(|l| l.starts_with("inputs="))
}

/// The newest `process` record among `texts` (oldest first), with the columns it wrote that
/// `extra` (the file's extra dimensions) holds; `known` are the names tilecurv writes, taken
/// for a record that does not list its columns. None without a `process` record.
pub fn previous_run(texts: &[String], extra: &[Descriptor], known: &[&str]) -> Option<PreviousRun> {
    let text = texts.iter().rev().find(|t| is_process_record(t))?;
    let value = |key: &str| {
        text.lines()
            .find_map(|l| l.strip_prefix(key)?.strip_prefix('='))
            .unwrap_or("")
            .to_string()
    };
    let listed: Vec<&str> = text
        .lines()
        .filter_map(|l| l.strip_prefix("column.")?.split_once('='))
        .map(|(name, _)| name)
        .collect();
    let file_normals = value("normals") == "file";
    let claimed: Vec<&str> = if listed.is_empty() {
        known
            .iter()
            .copied()
            .filter(|n| !(file_normals && n.starts_with("Normal")))
            .collect()
    } else {
        listed.clone()
    };
    let columns = extra
        .iter()
        .filter(|d| claimed.iter().any(|c| c.eq_ignore_ascii_case(&d.name)))
        .map(|d| d.name.clone())
        .collect();
    Some(PreviousRun {
        tool: text.lines().next().unwrap_or("tilecurv").to_string(),
        inputs: value("inputs"),
        columns,
        listed: !listed.is_empty(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::las::extra_bytes::{encode, parse, NewColumn, ScalarType};

    fn dims(names: &[&str]) -> Vec<Descriptor> {
        let data: Vec<u8> = names
            .iter()
            .flat_map(|n| encode(&NewColumn::plain(*n, ScalarType::F32, "")))
            .collect();
        parse(&data).expect("parses")
    }

    /// The newest `process` record decides (a `generate` record is none), and its column
    /// lines say which columns were its: a dimension it does not list is not claimed.
    #[test]
    fn the_newest_process_record_lists_the_columns() {
        let generate = "tilecurv 0.1.0 generate terrain\npoints=10\n".to_string();
        let old =
            "tilecurv 0.0.9\ninputs=a.las\ncolumn.K=i32 scale 1e-5 offset 0 no_data -2147483648\n";
        let new = "tilecurv 0.1.0\ninputs=b.las\nnormals=pca\ncolumn.H=i32 scale 1e-3 offset 0 no_data -2147483648\ncolumn.CurvatureFlags=u8\n\0\0";
        let extra = dims(&["TrueH", "H", "K", "CurvatureFlags"]);
        let texts = texts(&[
            Vlr::new("tilecurv", 1, "", generate.clone().into_bytes()),
            Vlr::new("other", 1, "", b"tilecurv 9\ninputs=x".to_vec()),
            Vlr::new("tilecurv", 1, "", old.as_bytes().to_vec()),
            Vlr::new("tilecurv", 1, "", new.as_bytes().to_vec()),
        ]);
        assert_eq!(texts.len(), 3);
        assert!(!texts[3 - 1].ends_with('\0'));
        let run = previous_run(&texts, &extra, &["H", "K"]).expect("a process record");
        assert_eq!(
            run,
            PreviousRun {
                tool: "tilecurv 0.1.0".into(),
                inputs: "b.las".into(),
                columns: vec!["H".into(), "CurvatureFlags".into()],
                listed: true,
            }
        );
        assert_eq!(previous_run(&[generate], &extra, &["H"]), None);
    }

    /// A record without column lines (an output of an older tilecurv) claims every name
    /// tilecurv writes that the file has, but NormalX/Y/Z when its normals came from the file.
    #[test]
    fn a_record_without_column_lines_claims_the_known_names() {
        let extra = dims(&["NormalX", "NormalY", "NormalZ", "Amplitude", "H", "k1"]);
        let known = ["NormalX", "NormalY", "NormalZ", "H", "K", "k1", "k2"];
        for (normals, want) in [
            ("pca", &["NormalX", "NormalY", "NormalZ", "H", "k1"][..]),
            ("file", &["H", "k1"][..]),
        ] {
            let text = format!("tilecurv 0.0.1\ninputs=a.las\nnormals={normals}\n");
            let run = previous_run(&[text], &extra, &known).expect("a process record");
            assert_eq!(run.columns, want, "normals={normals}");
            assert!(!run.listed);
        }
    }
}
