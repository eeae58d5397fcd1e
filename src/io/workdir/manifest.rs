//! The manifest of a work directory: a fingerprint of the inputs (path, size, modification
//! time, point count), of the tile size and of every option that changes the output, then the
//! same in words for a person, then the options as `param key=value` lines from which every
//! stage rebuilds the run. Work left by a run with another manifest is discarded, never mixed
//! in; how a run executes (threads, memory, tasks) is not in it.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// 64-bit FNV-1a: a fixed, documented hash (unlike `DefaultHasher`, which may change between
/// Rust releases), for fingerprints that must survive a rebuild of the tool.
#[derive(Debug, Clone, Copy)]
struct Fingerprint(u64);

impl Default for Fingerprint {
    fn default() -> Self {
        Fingerprint(0xcbf2_9ce4_8422_2325)
    }
}

impl Fingerprint {
    /// Feeds a string, then a separator, so that ("ab", "c") and ("a", "bc") differ.
    fn text(&mut self, s: &str) -> &mut Self {
        for &c in s.as_bytes().iter().chain(&[0xff]) {
            self.0 ^= c as u64;
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
        self
    }
}

/// An input as the manifest identifies it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct InputStamp {
    /// The path as the run was given it (absolute for a cluster run).
    pub path: PathBuf,
    /// Its points.
    pub points: u64,
}

/// What a run's manifest records.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Manifest {
    /// The inputs, in order.
    pub inputs: Vec<InputStamp>,
    /// The tile edge in file units: buckets depend on it bit for bit.
    pub tile_size: f64,
    /// The resolved parameters in words (the provenance's lines), for a person.
    pub words: Vec<(String, String)>,
    /// The options as `key=value`, from which the stages rebuild the run.
    pub params: Vec<(String, String)>,
}

/// The key of the `param` lines that name the inputs.
const INPUT: &str = "input";

impl Manifest {
    /// The manifest's text; its first line holds the fingerprint.
    pub(crate) fn text(&self) -> String {
        let mut fp = Fingerprint::default();
        let mut text = String::new();
        fp.text(env!("CARGO_PKG_VERSION"));
        let format = format!("work format {}\n", super::FORMAT_VERSION);
        fp.text(&format);
        text.push_str(&format);
        for i in &self.inputs {
            let meta = std::fs::metadata(&i.path).ok();
            let size = meta.as_ref().map_or(0, |m| m.len());
            let mtime = meta
                .and_then(|m| m.modified().ok())
                .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
                .map_or(0, |d| d.as_nanos());
            let canon = i.path.canonicalize().unwrap_or_else(|_| i.path.clone());
            fp.text(&canon.to_string_lossy())
                .text(&size.to_string())
                .text(&mtime.to_string())
                .text(&i.points.to_string());
            text.push_str(&format!(
                "input {} ({size} bytes, {} points)\n",
                canon.display(),
                i.points
            ));
        }
        fp.text(&self.tile_size.to_bits().to_string());
        for (k, v) in &self.words {
            text.push_str(&format!("{k}={v}\n"));
        }
        let inputs = self
            .inputs
            .iter()
            .map(|i| (INPUT, i.path.to_string_lossy()));
        let params = self
            .params
            .iter()
            .map(|(k, v)| (k.as_str(), v.as_str().into()));
        for (k, v) in inputs.chain(params) {
            let line = format!("param {k}={v}");
            fp.text(&line);
            text.push_str(&line);
            text.push('\n');
        }
        format!("tilecurv work directory, fingerprint {:016x}\n{text}", fp.0)
    }
}

/// What a stage reads back from a manifest: the inputs and the options.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Planned {
    /// The inputs as the run was given them.
    pub(crate) inputs: Vec<PathBuf>,
    /// The options as `key=value`, in order.
    pub(crate) params: Vec<(String, String)>,
}

/// Reads the inputs and options of the manifest `text` (of the file `path`); a manifest
/// without the header or without inputs is damaged work.
pub(crate) fn parse(path: &Path, text: &str) -> Result<Planned> {
    if !text.starts_with("tilecurv work directory, fingerprint ") {
        return Err(damaged(path, "it does not start with the tilecurv header"));
    }
    let mut planned = Planned {
        inputs: Vec::new(),
        params: Vec::new(),
    };
    for line in text.lines().filter_map(|l| l.strip_prefix("param ")) {
        let (k, v) = line
            .split_once('=')
            .ok_or_else(|| damaged(path, &format!("the line `param {line}` has no `=`")))?;
        if k == INPUT {
            planned.inputs.push(PathBuf::from(v));
        } else {
            planned.params.push((k.to_string(), v.to_string()));
        }
    }
    if planned.inputs.is_empty() {
        return Err(damaged(path, "it names no input"));
    }
    Ok(planned)
}

/// The error for a damaged manifest: exit 4, naming the file and what to do.
pub(crate) fn damaged(path: &Path, what: &str) -> Error {
    Error::damaged_work(
        path,
        &format!("a damaged manifest: {what}; a cluster run is planned again with `tilecurv plan`"),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fnv1a_reference_values() {
        // FNV-1a 64 of "a" is 0xaf63dc4c8601ec8c; ours adds a separator byte after each field.
        let mut f = Fingerprint::default();
        f.0 ^= b'a' as u64;
        f.0 = f.0.wrapping_mul(0x0000_0100_0000_01b3);
        assert_eq!(f.0, 0xaf63_dc4c_8601_ec8c);
        let mut a = Fingerprint::default();
        let mut b = Fingerprint::default();
        assert_ne!(a.text("ab").text("c").0, b.text("a").text("bc").0);
    }

    /// The stages read back exactly the inputs and options the manifest was written with,
    /// and the fingerprint changes with any option.
    #[test]
    fn inputs_and_options_round_trip() {
        let m = Manifest {
            inputs: vec![InputStamp {
                path: "/no/such/a b.las".into(),
                points: 12,
            }],
            tile_size: 50.0,
            words: vec![("k".into(), "30".into())],
            params: vec![("k".into(), "".into()), ("tile".into(), "50m".into())],
        };
        let text = m.text();
        let back = parse(Path::new("manifest.txt"), &text).expect("parses");
        assert_eq!(back.inputs, [PathBuf::from("/no/such/a b.las")]);
        assert_eq!(back.params, m.params);
        let other = Manifest {
            params: vec![("k".into(), "31".into()), ("tile".into(), "50m".into())],
            ..m.clone()
        };
        assert_ne!(text.lines().next(), other.text().lines().next());
        let e = parse(Path::new("manifest.txt"), "garbage\n").expect_err("damaged");
        assert!(
            e.to_string().contains("manifest.txt") && e.to_string().contains("plan"),
            "{e}"
        );
    }
}
