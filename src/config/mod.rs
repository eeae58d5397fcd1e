//! What a run is asked to do, validated once, apart from how it executes:
//!
//! - [`RunOptions`]: the options that change the output, as given, one field per row of the
//!   option table (`table::OPTIONS`, their one definition; [`options`] derives the rest);
//! - [`RunParams`]: the same, validated and resolved into what the engine reads (one `k`,
//!   the ladder of `-k auto`, the estimator's parameters, the class filter), built by
//!   [`RunParams::new`] from the command line, the work directory's manifest or Python's
//!   keyword arguments alike;
//! - [`Resolved`]: what the inputs settle (the tile size and radius in file units, the unit,
//!   the vertical scale, the normals' source), for the provenance;
//! - [`ExecOptions`]: threads, memory, chunk size and progress, which never change a byte.
//!
//! Plain data and parsing: nothing here opens a file.

pub mod options;
mod params;
mod table;
mod units;
mod values;

use crate::core::estimate::EstimatorKind;
use crate::core::scale::Ladder;
use crate::error::{Error, Result};
use crate::io::columns::ColumnChoice;
pub use params::RunParams;
pub use table::OPTIONS;
pub use units::{default_memory, parse_bytes, parse_count, Length};
pub use values::{KArg, OrientMode};

/// The options that change the output, as the user gave them (one field per row of
/// [`OPTIONS`]; `None` where an option without a default was not given).
#[derive(Debug, Clone, PartialEq)]
pub struct RunOptions {
    /// `--estimator`.
    pub estimator: EstimatorKind,
    /// `-k`: a count or `auto`; None for the default (30, 100 with `--radius`).
    pub k: Option<KArg>,
    /// `--k-range`: the ladder of `-k auto`.
    pub k_range: Option<Ladder>,
    /// `--radius`.
    pub radius: Option<Length>,
    /// `--seed`.
    pub seed: u64,
    /// `--triangles`.
    pub triangles: usize,
    /// `--jet-degree`.
    pub jet_degree: usize,
    /// `--ignore-file-normals`.
    pub ignore_file_normals: bool,
    /// `--orient`.
    pub orient: OrientMode,
    /// `--tile`.
    pub tile: Length,
    /// `--columns`.
    pub columns: ColumnChoice,
    /// `--directions`.
    pub directions: bool,
    /// `--features`.
    pub features: bool,
    /// `--f32`.
    pub f32: bool,
    /// `--f64`.
    pub f64: bool,
    /// `--keep-version`.
    pub keep_version: bool,
    /// `--ply-las-names`.
    pub ply_las_names: bool,
    /// `--classes`: None for every class.
    pub classes: Option<Vec<u8>>,
    /// `--skip-classes`.
    pub skip_classes: Vec<u8>,
    /// `--skip-withheld`.
    pub skip_withheld: bool,
    /// `--sample-faces`.
    pub sample_faces: Option<u64>,
}

/// Sets one field of [`RunOptions`] from the option's text.
type Setter = fn(&mut RunOptions, &str) -> std::result::Result<(), String>;

/// One option that changes the output.
pub struct OptionDef {
    /// Its key in the work directory's manifest and its Python keyword (`k_range`).
    pub key: &'static str,
    /// The long flag, without the dashes (`k-range`).
    pub long: &'static str,
    /// The short flag.
    pub short: Option<char>,
    /// Other long names the flag is accepted under.
    pub aliases: &'static [&'static str],
    /// The value's placeholder in the help; None for a switch (given or not).
    pub value_name: Option<&'static str>,
    /// The default, as text the setter reads (also shown by `--help`).
    pub default: Option<&'static str>,
    /// The help: a first paragraph for `-h`, the whole for `--help`.
    pub help: &'static str,
    /// The accepted values with a line of help each, when they are a fixed list.
    pub choices: Option<fn() -> Vec<Choice>>,
    /// Sets the field from text (a switch's text is `true` or `false`).
    pub set: Setter,
    /// The field as text that `set` reads back to the same value (empty: not given).
    pub get: fn(&RunOptions) -> String,
    /// What the output's provenance records for it (key and value), if anything.
    pub provenance: Option<ProvenanceLine>,
}

/// One accepted value of an option whose values are a fixed list.
pub struct Choice {
    /// The value as written.
    pub name: &'static str,
    /// A line of help for it.
    pub help: &'static str,
}

/// What the provenance records for an option: its key and its value in words (None: no line).
pub struct ProvenanceLine {
    /// The provenance key, e.g. `orientation` for `--orient`.
    pub key: &'static str,
    /// The value in words, from the validated options and what the inputs resolved.
    pub value: fn(&RunParams, &Resolved) -> Option<String>,
}

/// What the inputs settle about a run: the provenance records it beside the options.
#[derive(Debug, Clone, PartialEq)]
pub struct Resolved {
    /// The tile edge in file units.
    pub tile_size: f64,
    /// `--radius` in file units.
    pub radius: Option<f64>,
    /// The horizontal unit's symbol ("m", "ft", or "unit" without a CRS).
    pub unit_name: String,
    /// Factor from the inputs' z unit to their horizontal unit, and its words when not 1.
    pub z_scale: f64,
    /// The words of `z_scale` for the provenance, when it is not 1.
    pub z_words: Option<String>,
    /// Whether the inputs' normals are used instead of PCA.
    pub file_normals: bool,
}

/// One line of the provenance: `key=value`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Param {
    /// The key, e.g. `estimator`.
    pub key: &'static str,
    /// The value in words, e.g. `cnc-avg-hexagram`.
    pub value: String,
}

/// The rasters `process --raster` and `assemble --raster` write beside the outputs.
#[derive(Debug, Clone, PartialEq)]
pub struct RasterOptions {
    /// Cell size.
    pub cell: Length,
    /// How a cell's value is formed.
    pub stat: crate::core::raster::Stat,
    /// The columns by name (None: every curvature column of the outputs).
    pub columns: Option<Vec<String>>,
    /// The directory (None: beside the output, see `run::raster::default_dir`).
    pub dir: Option<std::path::PathBuf>,
}

/// How a run executes: none of it changes the output.
#[derive(Debug, Clone, PartialEq)]
pub struct ExecOptions {
    /// Worker threads.
    pub threads: usize,
    /// Memory budget in bytes for buckets and tiles in flight.
    pub memory_bytes: u64,
    /// Points per read chunk.
    pub chunk_points: usize,
    /// Append JSON progress lines to this file (`-`: standard output).
    pub progress_json: Option<std::path::PathBuf>,
    /// Rasters of the outputs' columns, made as they are written (none by default).
    pub rasters: Option<RasterOptions>,
}

impl Default for ExecOptions {
    /// Every core, half the machine's memory (at most 4 GiB), chunks of a million points.
    fn default() -> Self {
        ExecOptions {
            threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
            memory_bytes: default_memory(),
            chunk_points: 1_000_000,
            progress_json: None,
            rasters: None,
        }
    }
}

impl ExecOptions {
    /// Checks the settings.
    pub fn validate(&self) -> Result<()> {
        if self.threads == 0 {
            return Err(Error::Usage("--threads must be at least 1".into()));
        }
        if self.memory_bytes < crate::core::plan::MIN_BUDGET_BYTES {
            return Err(Error::Usage(format!(
                "--memory {} bytes is too small: at least 64M",
                self.memory_bytes
            )));
        }
        if self.chunk_points == 0 {
            return Err(Error::Usage("--chunk-size must be at least 1 point".into()));
        }
        Ok(())
    }
}
