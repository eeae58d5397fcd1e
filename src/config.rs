//! Validated run configuration: what the command line asked for, with units parsed. Plain data;
//! `cli` builds it, the engine reads it.

use std::path::PathBuf;

use crate::crs::LengthUnit;
use crate::error::{Error, Result};
use crate::estimate::EstimatorParams;
use crate::normals::Orientation;

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

/// Storage type of the new columns.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ColumnType {
    /// 32-bit floats (default).
    F32,
    /// 64-bit floats.
    F64,
}

/// Everything a `process` run needs.
#[derive(Debug, Clone)]
pub struct Config {
    /// The input file.
    pub input: PathBuf,
    /// The output file (.las or .laz).
    pub output: PathBuf,
    /// Tile edge length.
    pub tile: Length,
    /// Neighbours per point, the point itself included.
    pub k: usize,
    /// Estimator name (see `estimate::NAMES`).
    pub estimator: String,
    /// Estimator parameters.
    pub params: EstimatorParams,
    /// Orientation of PCA normals (file normals are used as they are when present).
    pub orientation: Orientation,
    /// Ignore NormalX/Y/Z stored in the input and estimate normals.
    pub ignore_file_normals: bool,
    /// Also write the principal directions.
    pub directions: bool,
    /// Storage type of the new columns.
    pub column_type: ColumnType,
    /// Worker threads.
    pub threads: usize,
    /// Points per read chunk.
    pub chunk_points: usize,
    /// Where temporary per-tile results go (default: beside the output).
    pub work_dir: Option<PathBuf>,
}

impl Config {
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
        if self.threads == 0 {
            return Err(Error::Usage("--threads must be at least 1".into()));
        }
        if self.chunk_points == 0 {
            return Err(Error::Usage("--chunk-size must be at least 1 point".into()));
        }
        if crate::estimate::build(&self.estimator, &self.params).is_none() {
            return Err(Error::Usage(format!(
                "unknown estimator {:?}; choose one of: {}",
                self.estimator,
                crate::estimate::NAMES.join(", ")
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
}
