//! Validated run configuration: what the command line asked for, with units parsed. Plain data;
//! `cli` builds it, the engine reads it.

use std::path::PathBuf;

use crate::core::estimate::{EstimatorKind, EstimatorParams};
use crate::core::geometry::V3;
use crate::core::normals::Orientation;
use crate::core::scale::Ladder;
use crate::core::select::{parse_classes, ClassFilter, Classes};
use crate::error::{Error, Result};
use crate::io::columns::{ColumnChoice, ColumnType, Group};
use crate::io::crs::LengthUnit;

/// A length with its unit as the user wrote it (`50m`, `150ft`, `150usft`, or a bare number in
/// file units).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Length {
    /// Metres.
    Metres(f64),
    /// International feet (0.3048 m).
    Feet(f64),
    /// US survey feet (1200/3937 m).
    UsFeet(f64),
    /// The file's own coordinate unit.
    FileUnits(f64),
}

impl Length {
    /// Parses `50m`, `50 m`, `164.04ft`, `150usft`, `0.05km` or `50` (file units).
    pub fn parse(s: &str) -> std::result::Result<Self, String> {
        let t = s.trim().to_ascii_lowercase();
        let split = t
            .find(|c: char| !(c.is_ascii_digit() || c == '.' || c == 'e' || c == '-' || c == '+'))
            .unwrap_or(t.len());
        let (num, unit) = t.split_at(split);
        let v: f64 = num.parse().map_err(|_| format!("{s:?} is not a length: expected a number with an optional unit (m, km, ft, usft), e.g. 50m"))?;
        if !(v.is_finite() && v > 0.0) {
            return Err(format!("{s:?}: a length must be positive"));
        }
        Ok(match unit.trim() {
            "" => Length::FileUnits(v),
            "m" | "metre" | "metres" | "meter" | "meters" => Length::Metres(v),
            "km" => Length::Metres(v * 1000.0),
            "cm" => Length::Metres(v / 100.0),
            "ft" | "foot" | "feet" => Length::Feet(v),
            "usft" | "us-ft" | "ftus" | "sft" => Length::UsFeet(v),
            other => return Err(format!("{s:?}: unknown unit {other:?}; use m, km, cm, ft (international foot) or usft (US survey foot), or no unit for file units")),
        })
    }

    /// This length in the file's units. `unit` is the file's horizontal unit, None when the file
    /// has no CRS (then lengths with a unit are taken as file units, and the caller warns).
    pub fn in_file_units(&self, unit: Option<&LengthUnit>) -> f64 {
        let metres = match *self {
            Length::FileUnits(v) => return v,
            Length::Metres(v) => v,
            Length::Feet(v) => v * 0.3048,
            Length::UsFeet(v) => v * 1200.0 / 3937.0,
        };
        match unit {
            Some(u) => metres / u.metres,
            None => match *self {
                Length::Metres(v) | Length::Feet(v) | Length::UsFeet(v) | Length::FileUnits(v) => v,
            },
        }
    }

    /// Whether the user gave a unit (so a file without CRS deserves a warning).
    pub fn has_unit(&self) -> bool {
        !matches!(self, Length::FileUnits(_))
    }
}

impl std::fmt::Display for Length {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Length::Metres(v) => write!(f, "{v}m"),
            Length::Feet(v) => write!(f, "{v}ft"),
            Length::UsFeet(v) => write!(f, "{v}usft"),
            Length::FileUnits(v) => write!(f, "{v}"),
        }
    }
}

/// Parses a byte size: `2G`, `512M`, `1.5GiB`, `4096` (bytes). K, M, G, T are powers of 1024.
pub fn parse_bytes(s: &str) -> std::result::Result<u64, String> {
    let t = s.trim().to_ascii_lowercase();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (num, unit) = t.split_at(split);
    let v: f64 = num.parse().map_err(|_| {
        format!("{s:?} is not a size: expected a number with an optional unit, e.g. 2G or 512M")
    })?;
    let mult = match unit.trim().trim_end_matches("ib").trim_end_matches('b') {
        "" => 1u64,
        "k" => 1 << 10,
        "m" => 1 << 20,
        "g" => 1 << 30,
        "t" => 1 << 40,
        other => {
            return Err(format!(
                "{s:?}: unknown size unit {other:?}; use K, M, G or T"
            ))
        }
    };
    let bytes = v * mult as f64;
    if !(bytes.is_finite() && bytes >= 1.0) {
        return Err(format!("{s:?}: a size must be positive"));
    }
    Ok(bytes as u64)
}

/// The default memory budget: half the machine's memory, at most 4 GiB, at least 256 MiB.
pub fn default_memory() -> u64 {
    // SAFETY: sysconf has no preconditions.
    let (pages, page) = unsafe {
        (
            libc::sysconf(libc::_SC_PHYS_PAGES),
            libc::sysconf(libc::_SC_PAGESIZE),
        )
    };
    let total = if pages > 0 && page > 0 {
        pages as u64 * page as u64
    } else {
        8 << 30
    };
    (total / 2).clamp(256 << 20, 4 << 30)
}

/// How PCA normals are oriented, as the user asked for it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum OrientMode {
    /// Towards +Z (aerial scans).
    Up,
    /// Towards a scanner position, in file coordinates (terrestrial scans).
    Viewpoint(V3),
    /// Away from the centroid of all points (closed, star-shaped objects).
    Outward,
    /// Consistent orientation by propagation over the neighbour graph (Hoppe et al. 1992),
    /// seeded outward: objects where no per-point rule works (orient.rs).
    Propagate,
}

impl OrientMode {
    /// Parses `up`, `outward`, `propagate` or `viewpoint:X,Y,Z`.
    pub fn parse(s: &str) -> std::result::Result<OrientMode, String> {
        if s == "up" {
            return Ok(OrientMode::Up);
        }
        if s == "outward" {
            return Ok(OrientMode::Outward);
        }
        if s == "propagate" {
            return Ok(OrientMode::Propagate);
        }
        if let Some(rest) = s.strip_prefix("viewpoint:") {
            let v: Vec<f64> = rest
                .split(',')
                .map(|c| c.trim().parse::<f64>())
                .collect::<std::result::Result<_, _>>()
                .map_err(|_| format!("{s:?}: expected viewpoint:X,Y,Z with three numbers"))?;
            if let [x, y, z] = v[..] {
                if [x, y, z].iter().all(|c| c.is_finite()) {
                    return Ok(OrientMode::Viewpoint([x, y, z]));
                }
            }
            return Err(format!(
                "{s:?}: expected viewpoint:X,Y,Z with three finite numbers"
            ));
        }
        Err(format!(
            "{s:?}: expected `up`, `outward`, `propagate` or `viewpoint:X,Y,Z`"
        ))
    }

    /// The orientation rule once the cloud's centroid is known.
    pub fn resolve(self, centroid: V3) -> Orientation {
        match self {
            OrientMode::Up => Orientation::Up,
            OrientMode::Viewpoint(v) => Orientation::Viewpoint(v),
            // Propagation starts from outward normals and then makes each patch consistent.
            OrientMode::Outward | OrientMode::Propagate => Orientation::Outward(centroid),
        }
    }
}

impl std::fmt::Display for OrientMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            OrientMode::Up => write!(f, "up"),
            OrientMode::Viewpoint(v) => write!(f, "viewpoint:{},{},{}", v[0], v[1], v[2]),
            OrientMode::Outward => write!(f, "outward"),
            OrientMode::Propagate => write!(f, "propagate"),
        }
    }
}

/// The value of `-k`: a count, or `auto`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KArg {
    /// This many neighbours.
    Count(usize),
    /// The scale chosen per point (`--k-range`).
    Auto,
}

impl KArg {
    /// Parses `-k`: a whole number or `auto`.
    pub fn parse(text: &str) -> std::result::Result<KArg, String> {
        if text.eq_ignore_ascii_case("auto") {
            return Ok(KArg::Auto);
        }
        text.parse::<usize>()
            .map(KArg::Count)
            .map_err(|_| format!("{text:?} is neither a number of neighbours (e.g. 30) nor auto"))
    }
}

/// Everything a `process` run needs.
#[derive(Debug, Clone)]
pub struct Config {
    /// The input files: one scene (halos cross file borders), one output per input.
    pub inputs: Vec<PathBuf>,
    /// The output file (.las or .laz) for one input, or a directory for several.
    pub output: PathBuf,
    /// Memory budget in bytes for buckets and tiles in flight.
    pub memory_bytes: u64,
    /// Print the plan and estimates, compute nothing.
    pub dry_run: bool,
    /// Append JSON progress lines to this file.
    pub progress_json: Option<PathBuf>,
    /// Tile edge length.
    pub tile: Length,
    /// Neighbours per point, the point itself included; with `radius`, the cap on them; with
    /// `scale`, its top rung.
    pub k: usize,
    /// `-k auto`: the ladder the scale is chosen from per point (`--k-range`); None for one k.
    pub scale: Option<Ladder>,
    /// `--radius`: neighbourhoods of the point and every point within this distance (the
    /// nearest `k` of them when more are); None for the k nearest.
    pub radius: Option<Length>,
    /// The curvature estimator.
    pub estimator: EstimatorKind,
    /// Estimator parameters.
    pub params: EstimatorParams,
    /// Orientation of PCA normals (file normals are used as they are when present).
    pub orientation: OrientMode,
    /// Ignore NormalX/Y/Z stored in the input and estimate normals.
    pub ignore_file_normals: bool,
    /// The new columns written (`--columns`, with `--directions` and `--features` added; the
    /// VCM's feature columns only with the `vcm` estimator).
    pub columns: ColumnChoice,
    /// How a LAS/LAZ output stores the new columns (scaled integers, f32 or f64).
    pub column_type: ColumnType,
    /// Worker threads.
    pub threads: usize,
    /// Points per read chunk.
    pub chunk_points: usize,
    /// Work directory for buckets and per-tile results (default: beside the output); kept after
    /// an interruption so that the same command resumes.
    pub work_dir: Option<PathBuf>,
    /// Process this many points sampled on the faces of each (mesh) input instead of its
    /// vertices (`--sample-faces`).
    pub sample_faces: Option<u64>,
    /// Write a LAS/LAZ output in its input's LAS version (default: LAS 1.4, so that PDAL reads
    /// the extra-bytes columns of LAS 1.0-1.3 inputs).
    pub keep_version: bool,
    /// Name a PLY output's new columns as in LAS (`NormalX`, `H`) instead of CloudCompare's
    /// `nx`, `scalar_H`.
    pub ply_las_names: bool,
    /// Which points are computed (`--classes`, `--skip-classes`, `--skip-withheld`).
    pub select: ClassFilter,
}

impl Default for Config {
    /// The command line's defaults, with no input and no output.
    fn default() -> Self {
        Config {
            inputs: Vec::new(),
            output: PathBuf::new(),
            memory_bytes: default_memory(),
            dry_run: false,
            progress_json: None,
            tile: Length::Metres(50.0),
            k: 30,
            scale: None,
            radius: None,
            estimator: EstimatorKind::CncAvgHexagram,
            params: EstimatorParams::default(),
            orientation: OrientMode::Up,
            ignore_file_normals: false,
            columns: ColumnChoice::default(),
            column_type: ColumnType::Scaled,
            threads: std::thread::available_parallelism()
                .map(|n| n.get())
                .unwrap_or(1),
            chunk_points: 1_000_000,
            work_dir: None,
            sample_faces: None,
            keep_version: false,
            ply_las_names: false,
            select: ClassFilter::default(),
        }
    }
}

/// One option that changes the output, as `key=value`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Param {
    /// The key, e.g. `k`.
    pub key: &'static str,
    /// The value as the command line would give it, e.g. `30`.
    pub value: String,
}

impl Config {
    /// Every option that changes the output, the inputs first: the one list the work
    /// directory's manifest stores (and its fingerprint hashes), from which every stage of a
    /// run rebuilds its configuration ([`Config::set_param`]). An option missing here would be
    /// lost between the stages, so a new output-changing option is added here and nowhere else
    /// (the provenance lists the same options resolved, see `run::spec::parameters`, checked
    /// against this list by a test).
    pub fn params(&self) -> Vec<Param> {
        let p = |key, value: String| Param { key, value };
        let mut v: Vec<Param> = self
            .inputs
            .iter()
            .map(|i| p("input", i.to_string_lossy().into_owned()))
            .collect();
        v.extend([
            p("estimator", self.estimator.to_string()),
            p("k", self.k.to_string()),
            p(
                "k_range",
                self.scale.map(|l| l.to_string()).unwrap_or_default(),
            ),
            p(
                "radius",
                self.radius.map(|r| r.to_string()).unwrap_or_default(),
            ),
            p("seed", self.params.seed.to_string()),
            p("triangles", self.params.triangles.to_string()),
            p("jet_degree", self.params.jet_degree.to_string()),
            p("orient", self.orientation.to_string()),
            p("ignore_file_normals", self.ignore_file_normals.to_string()),
            p("columns", self.columns.to_string()),
            p("encoding", self.column_type.name().to_string()),
            p("tile", self.tile.to_string()),
            p(
                "sample_faces",
                self.sample_faces.map(|n| n.to_string()).unwrap_or_default(),
            ),
            p("keep_version", self.keep_version.to_string()),
            p("ply_las_names", self.ply_las_names.to_string()),
            p("classes", self.select.only_text("")),
            p("skip_classes", Classes(&self.select.skip).to_string()),
            p("skip_withheld", self.select.skip_withheld.to_string()),
        ]);
        v
    }

    /// Sets the option `key` from its [`Config::params`] value (`input` adds an input).
    pub fn set_param(&mut self, key: &str, value: &str) -> std::result::Result<(), String> {
        let num = |v: &str| {
            v.parse::<u64>()
                .map_err(|_| format!("{key}={v}: not a count"))
        };
        let flag = |v: &str| {
            v.parse::<bool>()
                .map_err(|_| format!("{key}={v}: not true/false"))
        };
        match key {
            "input" => self.inputs.push(PathBuf::from(value)),
            "estimator" => {
                self.estimator = EstimatorKind::from_name(value)
                    .ok_or_else(|| format!("estimator={value}: unknown"))?
            }
            "k" => self.k = num(value)? as usize,
            "k_range" => {
                self.scale = (!value.is_empty())
                    .then(|| Ladder::parse(value))
                    .transpose()?
            }
            "radius" => {
                self.radius = (!value.is_empty())
                    .then(|| Length::parse(value))
                    .transpose()?
            }
            "seed" => self.params.seed = num(value)?,
            "triangles" => self.params.triangles = num(value)? as usize,
            "jet_degree" => self.params.jet_degree = num(value)? as usize,
            "orient" => self.orientation = OrientMode::parse(value)?,
            "ignore_file_normals" => self.ignore_file_normals = flag(value)?,
            "columns" => self.columns = ColumnChoice::parse(value)?,
            "encoding" => {
                self.column_type = ColumnType::from_name(value)
                    .ok_or_else(|| format!("encoding={value}: unknown"))?
            }
            "tile" => self.tile = Length::parse(value)?,
            "keep_version" => self.keep_version = flag(value)?,
            "ply_las_names" => self.ply_las_names = flag(value)?,
            "classes" => {
                self.select.only = (!value.is_empty())
                    .then(|| parse_classes(value))
                    .transpose()?
            }
            "skip_classes" => self.select.skip = parse_classes(value)?,
            "skip_withheld" => self.select.skip_withheld = flag(value)?,
            "sample_faces" => {
                self.sample_faces = (!value.is_empty()).then(|| num(value)).transpose()?
            }
            other => return Err(format!("unknown option {other:?}")),
        }
        Ok(())
    }

    /// Checks `-k auto` against the options it cannot be combined with (yet).
    fn validate_scale(&self) -> Result<()> {
        let Some(ladder) = self.scale else {
            if self.columns.has(Group::Scale) {
                return Err(Error::Usage("the column group `scale` (ScaleK, ScaleFlags) is the scale -k auto chose per point: add -k auto, or drop `scale` from --columns".into()));
            }
            return Ok(());
        };
        if self.k != ladder.max {
            return Err(Error::Usage(format!(
                "--k-range {ladder} chooses K per point (-k auto): it cannot go with -k {}; drop one of them",
                self.k
            )));
        }
        if self.radius.is_some() {
            return Err(Error::Usage("-k auto chooses the number of neighbours per point, --radius sets their distance: give one of them".into()));
        }
        if self.orientation == OrientMode::Propagate {
            return Err(Error::Usage("-k auto with --orient propagate is not supported yet (each rung would need its own propagation): use --orient up (aerial scans) or outward, or a fixed -k".into()));
        }
        Ok(())
    }

    /// Checks the values that do not depend on the input file.
    pub fn validate(&self) -> Result<()> {
        if self.k < 6 {
            return Err(Error::Usage(format!("-k {} is too small: curvature needs at least 6 neighbours (the point itself included); 20 to 50 is typical", self.k)));
        }
        if self.k > 10_000 {
            return Err(Error::Usage(format!(
                "-k {} is too large (at most 10000)",
                self.k
            )));
        }
        self.validate_scale()?;
        if self.threads == 0 {
            return Err(Error::Usage("--threads must be at least 1".into()));
        }
        if self.inputs.is_empty() {
            return Err(Error::Usage("no input file given".into()));
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
        if self.columns.has(Group::Features)
            && self
                .estimator
                .build(&self.params)
                .extra_columns()
                .is_empty()
        {
            let with: Vec<String> = EstimatorKind::ALL
                .into_iter()
                .filter(|e| !e.build(&self.params).extra_columns().is_empty())
                .map(|e| format!("--estimator {e}"))
                .collect();
            return Err(Error::Usage(format!(
                "--features (the column group `features`) writes the values an estimator computes besides the curvature (the VCM's sharp-feature score and normal), which only {} computes (got --estimator {}); add {} or drop --features",
                with.join(" or "),
                self.estimator,
                with.join(" or ")
            )));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fifty_metres_in_international_feet() {
        let ft = LengthUnit {
            name: "foot".into(),
            metres: 0.3048,
        };
        let v = Length::parse("50m")
            .expect("length")
            .in_file_units(Some(&ft));
        assert!((v - 164.041_994_75).abs() < 1e-6, "{v}");
        assert_eq!(
            Length::parse("150ft")
                .expect("length")
                .in_file_units(Some(&ft)),
            150.0
        );
        assert_eq!(
            Length::parse("12.5").expect("length"),
            Length::FileUnits(12.5)
        );
        assert!(
            Length::parse("-3m").is_err()
                && Length::parse("5 parsecs").is_err()
                && Length::parse("m").is_err()
        );
    }

    /// `--features` needs the VCM estimator; the usage error names the flag.
    #[test]
    fn features_only_with_vcm() {
        let mut cfg = Config {
            inputs: vec!["in.las".into()],
            output: "out.las".into(),
            columns: ColumnChoice::default().with(Group::Features),
            ..Config::default()
        };
        let e = cfg
            .validate()
            .expect_err("features without vcm")
            .to_string();
        assert!(
            e.contains("--features") && e.contains("--estimator vcm"),
            "{e}"
        );
        cfg.estimator = EstimatorKind::Vcm;
        cfg.validate().expect("features with vcm");
    }

    #[test]
    fn byte_sizes() {
        assert_eq!(parse_bytes("2G"), Ok(2 << 30));
        assert_eq!(parse_bytes("1.5GiB"), Ok(3 << 29));
        assert_eq!(parse_bytes("512m"), Ok(512 << 20));
        assert!(
            parse_bytes("lots").is_err() && parse_bytes("3X").is_err() && parse_bytes("0").is_err()
        );
    }
}
