//! The one definition of every option that changes the output: `OPTIONS`, a table with one
//! row per command-line flag. Each row names the flag, its default and help, how its value is
//! set from text and printed back, and what it records in the output's provenance. Everything
//! else is derived from the table: the clap arguments of `process` and `plan` (defaults and
//! help), [`RunOptions::default`], the work directory's `param key=value` lines and their
//! re-reading by the cluster stages ([`RunOptions::set`]), the Python keyword arguments, and
//! the provenance record. A new option is one new row and one field of [`RunOptions`].
//!
//! [`RunOptions`] is what the user chose, flag by flag, unvalidated; [`super::RunParams::new`]
//! validates it. How a run executes (threads, memory, chunk size) is not here: it never changes
//! a byte of the output ([`super::ExecOptions`]).

use super::table::OPTIONS;
use super::values::OrientMode;
use super::{Length, OptionDef, Param, Resolved, RunOptions, RunParams};
use crate::core::estimate::EstimatorKind;
use crate::io::columns::ColumnChoice;

/// The row of `key`.
pub fn option(key: &str) -> Option<&'static OptionDef> {
    OPTIONS.iter().find(|o| o.key == key)
}

impl Default for RunOptions {
    /// Every row's default, and "not given" for the rows without one.
    fn default() -> Self {
        let mut o = RunOptions {
            estimator: EstimatorKind::CncAvgHexagram,
            k: None,
            k_range: None,
            radius: None,
            seed: 0,
            triangles: 0,
            jet_degree: 0,
            ignore_file_normals: false,
            orient: OrientMode::Up,
            tile: Length::FileUnits(1.0),
            columns: ColumnChoice::default(),
            directions: false,
            features: false,
            f32: false,
            f64: false,
            keep_version: false,
            ply_las_names: false,
            classes: None,
            skip_classes: Vec::new(),
            skip_withheld: false,
            sample_faces: None,
        };
        for row in OPTIONS {
            if let Some(d) = row.default {
                // A default that does not parse is caught by the table's test.
                let _ = (row.set)(&mut o, d);
            }
        }
        o
    }
}

impl RunOptions {
    /// Sets the option `key` (a row's key) from text, as the command line would give it: a
    /// switch from `true` or `false`, an option without a default unset by the empty text.
    pub fn set(&mut self, key: &str, value: &str) -> Result<(), String> {
        let row = option(key).ok_or_else(|| {
            let keys: Vec<&str> = OPTIONS.iter().map(|o| o.key).collect();
            format!(
                "unknown option {key:?}; the options are {}",
                keys.join(", ")
            )
        })?;
        (row.set)(self, value).map_err(|e| format!("{}: {e}", row.flag()))
    }

    /// Every option as `(key, value)`, in the table's order: [`RunOptions::set`] rebuilds
    /// these options from them.
    pub fn pairs(&self) -> Vec<(&'static str, String)> {
        OPTIONS.iter().map(|o| (o.key, (o.get)(self))).collect()
    }
}

impl RunParams {
    /// The provenance's parameter lines, from the option table, in its order, then the
    /// vertical scale when the inputs needed one.
    pub fn provenance(&self, resolved: &Resolved) -> Vec<Param> {
        let mut v: Vec<Param> = OPTIONS
            .iter()
            .filter_map(|row| row.provenance.as_ref())
            .filter_map(|line| {
                (line.value)(self, resolved).map(|value| Param {
                    key: line.key,
                    value,
                })
            })
            .collect();
        v.extend(resolved.z_words.clone().map(|value| Param {
            key: "z_scale",
            value,
        }));
        v
    }
}

impl OptionDef {
    /// The flag as a user writes it: `--k-range`, `-k`.
    pub fn flag(&self) -> String {
        match self.short {
            Some(c) => format!("-{c}"),
            None => format!("--{}", self.long),
        }
    }

    /// The clap argument of this row.
    fn arg(&'static self) -> clap::Arg {
        let (short, long) = match self.help.split_once("\n\n") {
            Some((first, _)) => (first, Some(self.help)),
            None => (self.help, None),
        };
        let mut a = clap::Arg::new(self.key)
            .long(self.long)
            .help(short)
            .visible_aliases(self.aliases.iter().copied());
        if let Some(l) = long {
            a = a.long_help(l);
        }
        if let Some(c) = self.short {
            a = a.short(c);
        }
        let Some(name) = self.value_name else {
            return a.action(clap::ArgAction::SetTrue);
        };
        a = a.value_name(name).action(clap::ArgAction::Set);
        if let Some(d) = self.default {
            a = a.default_value(d);
        }
        if let Some(choices) = self.choices {
            let values = choices()
                .into_iter()
                .map(|c| clap::builder::PossibleValue::new(c.name).help(c.help));
            return a.value_parser(clap::builder::PossibleValuesParser::new(values));
        }
        let set = self.set;
        a.value_parser(move |v: &str| -> Result<String, String> {
            set(&mut RunOptions::default(), v).map(|_| v.to_string())
        })
    }
}

impl clap::Args for RunOptions {
    fn augment_args(cmd: clap::Command) -> clap::Command {
        cmd.args(OPTIONS.iter().map(OptionDef::arg))
    }

    fn augment_args_for_update(cmd: clap::Command) -> clap::Command {
        Self::augment_args(cmd)
    }
}

impl clap::FromArgMatches for RunOptions {
    fn from_arg_matches(m: &clap::ArgMatches) -> Result<Self, clap::Error> {
        let mut o = RunOptions::default();
        o.update_from_arg_matches(m)?;
        Ok(o)
    }

    fn update_from_arg_matches(&mut self, m: &clap::ArgMatches) -> Result<(), clap::Error> {
        for row in OPTIONS {
            let value = match row.value_name {
                None => m.get_flag(row.key).then(|| "true".to_string()),
                Some(_) => m.get_one::<String>(row.key).cloned(),
            };
            if let Some(v) = value {
                (row.set)(self, &v)
                    .map_err(|e| clap::Error::raw(clap::error::ErrorKind::InvalidValue, e))?;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every default parses, and every option's text reads back to the same value, so the
    /// manifest rebuilds exactly the options it was written from.
    #[test]
    fn every_option_round_trips_through_its_text() {
        for row in OPTIONS {
            if let Some(d) = row.default {
                (row.set)(&mut RunOptions::default(), d)
                    .unwrap_or_else(|e| panic!("{}: default {d:?}: {e}", row.key));
            }
        }
        let mut given = RunOptions::default();
        for (k, v) in [
            ("estimator", "jet"),
            ("k", "auto"),
            ("k_range", "16..256"),
            ("radius", "1.5m"),
            ("seed", "7"),
            ("triangles", "40"),
            ("jet_degree", "3"),
            ("ignore_file_normals", "true"),
            ("orient", "viewpoint:1,2.5,-3"),
            ("tile", "150usft"),
            ("columns", "normals,k1,k2"),
            ("directions", "true"),
            ("features", "true"),
            ("f32", "true"),
            ("f64", "true"),
            ("keep_version", "true"),
            ("ply_las_names", "true"),
            ("classes", "2,9"),
            ("skip_classes", "none"),
            ("skip_withheld", "true"),
            ("sample_faces", "200k"),
        ] {
            given.set(k, v).expect(k);
        }
        assert_eq!(
            given.pairs().len(),
            OPTIONS.len(),
            "one pair per row, every row set above"
        );
        for start in [RunOptions::default(), given] {
            let mut back = RunOptions::default();
            for (k, v) in start.pairs() {
                back.set(k, &v).expect(k);
            }
            assert_eq!(back, start);
        }
        // Each set above changed its field away from the default: no row sets another's.
        let defaults = RunOptions::default().pairs();
        let mut changed = RunOptions::default();
        for (i, row) in OPTIONS.iter().enumerate() {
            let before = changed.pairs();
            let v = match row.value_name {
                None => "true".to_string(),
                Some(_) => given_text(row.key),
            };
            changed.set(row.key, &v).expect(row.key);
            let after = changed.pairs();
            for (j, (b, a)) in before.iter().zip(&after).enumerate() {
                assert_eq!(
                    i == j,
                    b != a,
                    "setting {} changed {} ({:?} -> {:?})",
                    row.key,
                    a.0,
                    b.1,
                    a.1
                );
            }
            assert_ne!(after[i], defaults[i]);
        }
    }

    fn given_text(key: &str) -> String {
        match key {
            "estimator" => "vcm",
            "k" => "40",
            "k_range" => "32..512",
            "radius" => "2",
            "seed" => "3",
            "triangles" => "10",
            "jet_degree" => "4",
            "orient" => "outward",
            "tile" => "10m",
            "columns" => "H",
            "classes" => "2",
            "skip_classes" => "7",
            "sample_faces" => "1000",
            other => panic!("no test value for {other}"),
        }
        .to_string()
    }

    /// The command line's default for the noise classes is the selection's own.
    #[test]
    fn the_skipped_classes_default_to_the_noise_classes() {
        assert_eq!(
            RunOptions::default().skip_classes,
            crate::core::select::NOISE_CLASSES
        );
    }
}
