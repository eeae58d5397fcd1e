//! Values the user writes with a unit, parsed: lengths (`50m`, `150usft`), byte sizes (`2G`)
//! and point counts (`2M`). Pure parsing; the conversion of a length into file units takes the
//! file's unit as an argument.

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

/// Parses a point count: `2000000`, `2M`, `500k`, `1e6`, `20_000` (k, M, G are powers of 1000).
pub fn parse_count(s: &str) -> std::result::Result<u64, String> {
    let t = s.trim().replace('_', "");
    let (num, mult) = match t.chars().last() {
        Some('k' | 'K') => (&t[..t.len() - 1], 1e3),
        Some('m' | 'M') => (&t[..t.len() - 1], 1e6),
        Some('g' | 'G') => (&t[..t.len() - 1], 1e9),
        _ => (t.as_str(), 1.0),
    };
    let v: f64 = num.parse().map_err(|_| {
        format!("{s:?} is not a point count: expected e.g. 2000000, 2M, 500k or 1e6")
    })?;
    let n = (v * mult).round();
    if !(1.0..1.8e19).contains(&n) {
        return Err(format!("{s:?}: a point count must be at least 1"));
    }
    Ok(n as u64)
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

    #[test]
    fn byte_sizes() {
        assert_eq!(parse_bytes("2G"), Ok(2 << 30));
        assert_eq!(parse_bytes("1.5GiB"), Ok(3 << 29));
        assert_eq!(parse_bytes("512m"), Ok(512 << 20));
        assert!(
            parse_bytes("lots").is_err() && parse_bytes("3X").is_err() && parse_bytes("0").is_err()
        );
    }

    #[test]
    fn point_counts() {
        assert_eq!(parse_count("2M"), Ok(2_000_000));
        assert_eq!(parse_count("1.5k"), Ok(1500));
        assert_eq!(parse_count("1e6"), Ok(1_000_000));
        assert_eq!(parse_count("20_000"), Ok(20_000));
        assert!(parse_count("0").is_err());
        assert!(parse_count("many").is_err());
    }
}
