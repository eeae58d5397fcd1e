//! Which points the curvature is computed on: `--classes` (only these),
//! `--skip-classes` (never these; by default the LAS noise classes 7 and 18) and
//! `--skip-withheld`. Neighbourhoods are formed among the selected points only; the others stay
//! in the output with NaN values and the "not computed" flag. Pure: the rule on a class number.

use std::fmt;

/// A point's LAS classification and withheld bit, as its record stores them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PointClass {
    /// The classification (0-31 in point formats 0-5, 0-255 in 6-10).
    pub class: u8,
    /// The withheld flag.
    pub withheld: bool,
}

/// The classification and withheld flag of a LAS point record of `point_format`: formats 0-5
/// keep both in byte 15 (class in bits 0-4, withheld bit 7), formats 6-10 the class in byte 16
/// and withheld as bit 2 of byte 15. None for a record too short.
pub fn las_point_class(point_format: u8, rec: &[u8]) -> Option<PointClass> {
    let (class, withheld) = if point_format < 6 {
        let b = *rec.get(15)?;
        (b & 0x1f, b & 0x80 != 0)
    } else {
        (*rec.get(16)?, rec.get(15)? & 0x04 != 0)
    };
    Some(PointClass { class, withheld })
}

/// The LAS noise classes skipped by default: 7 low point (noise), 18 high noise (LAS 1.4).
pub const NOISE_CLASSES: [u8; 2] = [7, 18];

/// The selection rule.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ClassFilter {
    /// `--classes`: compute on these classes only (None: every class).
    pub only: Option<Vec<u8>>,
    /// `--skip-classes`: never compute on these.
    pub skip: Vec<u8>,
    /// `--skip-withheld`: never compute on points with the withheld flag.
    pub skip_withheld: bool,
}

impl Default for ClassFilter {
    /// Every point except the noise classes 7 and 18.
    fn default() -> Self {
        ClassFilter {
            only: None,
            skip: NOISE_CLASSES.to_vec(),
            skip_withheld: false,
        }
    }
}

impl ClassFilter {
    /// Whether a point of class `c` is computed; a point of a format without classes (`None`:
    /// PLY, XYZ, ...) always is.
    pub fn selects(&self, c: Option<PointClass>) -> bool {
        let Some(c) = c else {
            return true;
        };
        let skipped = self.skip.contains(&c.class) || (self.skip_withheld && c.withheld);
        !skipped && self.only.as_ref().is_none_or(|o| o.contains(&c.class))
    }

    /// `--classes` as [`parse_classes`] reads it, or `all` when it is not given.
    pub fn only_text(&self, all: &str) -> String {
        match &self.only {
            Some(c) => Classes(c).to_string(),
            None => all.to_string(),
        }
    }

    /// The rule in words, for the log: `classes 2,9, skipping 7,18, not withheld`.
    pub fn describe(&self) -> String {
        let mut w = match &self.only {
            Some(c) => format!("classes {}", Classes(c)),
            None => "every class".to_string(),
        };
        if !self.skip.is_empty() {
            w.push_str(&format!(", skipping {}", Classes(&self.skip)));
        }
        if self.skip_withheld {
            w.push_str(", not withheld");
        }
        w
    }

    /// Whether the rule needs classes beyond the default skip of the noise classes (so an
    /// input without classes cannot honour it).
    pub fn needs_classes(&self) -> bool {
        self.only.is_some() || self.skip_withheld || self.skip != NOISE_CLASSES
    }
}

/// Parses a class list: `2,9`, or `none` for the empty list. Classes are 0-255.
pub fn parse_classes(s: &str) -> Result<Vec<u8>, String> {
    if s.trim() == "none" {
        return Ok(Vec::new());
    }
    let mut v: Vec<u8> = s
        .split(',')
        .map(|t| {
            t.trim().parse::<u8>().map_err(|_| {
                format!("{t:?} in {s:?} is not a LAS class (0-255); expected e.g. 2,9 or none")
            })
        })
        .collect::<Result<_, _>>()?;
    v.sort_unstable();
    v.dedup();
    Ok(v)
}

/// A class list as [`parse_classes`] reads it.
pub struct Classes<'a>(pub &'a [u8]);

impl fmt::Display for Classes<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.0.is_empty() {
            return write!(f, "none");
        }
        let parts: Vec<String> = self.0.iter().map(|c| c.to_string()).collect();
        write!(f, "{}", parts.join(","))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pc(class: u8, withheld: bool) -> Option<PointClass> {
        Some(PointClass { class, withheld })
    }

    #[test]
    fn the_rule_and_its_lists() {
        let d = ClassFilter::default();
        assert!(d.selects(pc(2, false)) && d.selects(pc(2, true)) && d.selects(None));
        assert!(!d.selects(pc(7, false)) && !d.selects(pc(18, false)));
        assert!(!d.needs_classes());
        let ground = ClassFilter {
            only: Some(vec![2, 9]),
            skip: Vec::new(),
            skip_withheld: true,
        };
        assert!(ground.selects(pc(9, false)) && !ground.selects(pc(5, false)));
        assert!(!ground.selects(pc(2, true)) && ground.needs_classes());
        assert_eq!(parse_classes("9, 2,2").expect("list"), vec![2, 9]);
        assert_eq!(parse_classes("none").expect("empty"), Vec::<u8>::new());
        assert!(parse_classes("2,256").is_err() && parse_classes("").is_err());
        assert_eq!(Classes(&[7, 18]).to_string(), "7,18");
        assert_eq!(Classes(&[]).to_string(), "none");
    }
}
