//! The options that change the output, validated and resolved into what the engine reads
//! ([`RunParams`]), whatever built them: the command line, the work directory's manifest or
//! Python's keyword arguments.

use super::values::{KArg, OrientMode};
use super::{Length, RunOptions};
use crate::core::estimate::{EstimatorKind, EstimatorParams};
use crate::core::scale::Ladder;
use crate::core::select::ClassFilter;
use crate::error::{Error, Result};
use crate::io::columns::{ColumnChoice, ColumnType, Group};

/// The cap on neighbours with `--radius` when `-k` is not given.
const RADIUS_CAP: usize = 100;
/// Neighbours per point when `-k` is not given.
const DEFAULT_K: usize = 30;

/// The options that change the output, validated: what the engine reads.
#[derive(Debug, Clone, PartialEq)]
pub struct RunParams {
    /// The options as given: the work directory's manifest stores them.
    pub options: RunOptions,
    /// The curvature estimator.
    pub estimator: EstimatorKind,
    /// Its parameters.
    pub estimator_params: EstimatorParams,
    /// Neighbours per point, the point itself included; with `radius`, the cap on them; with
    /// `ladder`, its top rung.
    pub k: usize,
    /// `-k auto`: the ladder the scale is chosen from per point; None for one k.
    pub ladder: Option<Ladder>,
    /// `--radius` as given (converted to file units once the inputs are open).
    pub radius: Option<Length>,
    /// Orientation of PCA normals.
    pub orientation: OrientMode,
    /// Whether the inputs' NormalX/Y/Z are ignored.
    pub ignore_file_normals: bool,
    /// Tile edge length as given.
    pub tile: Length,
    /// The new columns (`--columns` with `--directions` and `--features` added).
    pub columns: ColumnChoice,
    /// How a LAS/LAZ output stores them.
    pub column_type: ColumnType,
    /// `--sample-faces`: points sampled on a mesh's faces instead of its vertices.
    pub sample_faces: Option<u64>,
    /// Keep a LAS/LAZ input's version in its output.
    pub keep_version: bool,
    /// LAS names for a PLY output's columns.
    pub ply_las_names: bool,
    /// Which points are computed.
    pub select: ClassFilter,
}

impl RunParams {
    /// Validates `options` (everything that does not depend on the inputs) and resolves them.
    pub fn new(options: RunOptions) -> Result<Self> {
        let o = &options;
        let ladder = match o.k {
            Some(KArg::Auto) => Some(o.k_range.unwrap_or_default()),
            _ => o.k_range,
        };
        let k = match (o.k, ladder) {
            (Some(KArg::Count(k)), _) => k,
            (_, Some(l)) => l.max,
            _ if o.radius.is_some() => RADIUS_CAP,
            _ => DEFAULT_K,
        };
        if o.f32 && o.f64 {
            return Err(Error::Usage(
                "--f32 and --f64 both choose how the columns are stored: give one of them".into(),
            ));
        }
        let columns = [
            (o.directions, Group::Directions),
            (o.features, Group::Features),
        ]
        .into_iter()
        .filter(|(on, _)| *on)
        .fold(o.columns, |c, (_, g)| c.with(g));
        let params = RunParams {
            estimator: o.estimator,
            estimator_params: EstimatorParams {
                seed: o.seed,
                triangles: o.triangles,
                jet_degree: o.jet_degree,
            },
            k,
            ladder,
            radius: o.radius,
            orientation: o.orient,
            ignore_file_normals: o.ignore_file_normals,
            tile: o.tile,
            columns,
            column_type: match (o.f32, o.f64) {
                (_, true) => ColumnType::F64,
                (true, false) => ColumnType::F32,
                (false, false) => ColumnType::Scaled,
            },
            sample_faces: o.sample_faces,
            keep_version: o.keep_version,
            ply_las_names: o.ply_las_names,
            select: ClassFilter {
                only: o.classes.clone(),
                skip: o.skip_classes.clone(),
                skip_withheld: o.skip_withheld,
            },
            options,
        };
        params.validate()?;
        Ok(params)
    }

    /// Checks the values that do not depend on the input file.
    fn validate(&self) -> Result<()> {
        if self.k < 6 {
            return Err(Error::Usage(format!("-k {} is too small: curvature needs at least 6 neighbours (the point itself included); 20 to 50 is typical", self.k)));
        }
        if self.k > 10_000 {
            return Err(Error::Usage(format!(
                "-k {} is too large (at most 10000)",
                self.k
            )));
        }
        if !(2..=4).contains(&self.estimator_params.jet_degree) {
            return Err(Error::Usage(format!(
                "--jet-degree {}: the jet's degree is 2, 3 or 4",
                self.estimator_params.jet_degree
            )));
        }
        self.validate_scale()?;
        self.validate_estimator_options()?;
        self.validate_features()
    }

    /// Checks that `--triangles` and `--jet-degree` go with the estimator they set (given to
    /// another one, they would change nothing while the provenance recorded them), and that
    /// principal directions are asked of an estimator that has them.
    fn validate_estimator_options(&self) -> Result<()> {
        let (e, p) = (self.estimator, &self.estimator_params);
        if e == EstimatorKind::Apss && self.columns.has(Group::Directions) {
            return Err(Error::Usage("--directions (the column group `directions`) with --estimator apss: APSS fits a sphere, along which every direction is principal, so it has no principal directions to write (each point's would be zero, flagged 16, umbilic); choose another estimator for them (jet, wme, aso or a CNC), or drop --directions".into()));
        }
        let default = EstimatorParams::default();
        if p.triangles == 0 {
            return Err(Error::Usage(format!(
                "--triangles 0: CNC-Uniform needs at least one triangle per point ({} by default)",
                default.triangles
            )));
        }
        let unused = [
            (
                "--triangles",
                p.triangles,
                default.triangles,
                EstimatorKind::CncUniform,
            ),
            (
                "--jet-degree",
                p.jet_degree,
                default.jet_degree,
                EstimatorKind::Jet,
            ),
        ]
        .into_iter()
        .find(|&(_, v, d, with)| v != d && e != with);
        match unused {
            Some((flag, v, _, with)) => Err(Error::Usage(format!(
                "{flag} {v} sets --estimator {with}, which this run does not use (--estimator {e}): add --estimator {with}, or drop {flag}"
            ))),
            None => Ok(()),
        }
    }

    /// Checks `-k auto` against the options it cannot be combined with (yet).
    fn validate_scale(&self) -> Result<()> {
        let Some(ladder) = self.ladder else {
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

    /// Checks that `--features` goes with an estimator that computes features.
    fn validate_features(&self) -> Result<()> {
        let computes =
            |e: EstimatorKind| !e.build(&self.estimator_params).extra_columns().is_empty();
        if !self.columns.has(Group::Features) || computes(self.estimator) {
            return Ok(());
        }
        let with: Vec<String> = EstimatorKind::ALL
            .into_iter()
            .filter(|&e| computes(e))
            .map(|e| format!("--estimator {e}"))
            .collect();
        Err(Error::Usage(format!(
            "--features (the column group `features`) writes the values an estimator computes besides the curvature (the VCM's sharp-feature score and normal), which only {} computes (got --estimator {}); add {} or drop --features",
            with.join(" or "),
            self.estimator,
            with.join(" or ")
        )))
    }
}

impl Default for RunParams {
    /// The defaults of every option.
    fn default() -> Self {
        // The table's defaults are checked to validate by a test.
        RunParams::new(RunOptions::default()).unwrap_or_else(|e| unreachable!("{e}"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Resolved;

    /// `--features` needs the VCM estimator; the usage error names the flag.
    #[test]
    fn features_only_with_vcm() {
        let mut o = RunOptions {
            features: true,
            ..RunOptions::default()
        };
        let e = RunParams::new(o.clone())
            .expect_err("features without vcm")
            .to_string();
        assert!(
            e.contains("--features") && e.contains("--estimator vcm"),
            "{e}"
        );
        o.estimator = EstimatorKind::Vcm;
        RunParams::new(o).expect("features with vcm");
    }

    /// The parameters of the options `pairs` (key, value) given over the defaults.
    fn params_of(pairs: &[(&str, &str)]) -> Result<RunParams> {
        let mut o = RunOptions::default();
        for (key, v) in pairs {
            o.set(key, v).expect(key);
        }
        RunParams::new(o)
    }

    /// The defaults validate, and k follows -k, --k-range and --radius.
    #[test]
    fn k_is_resolved_from_its_options() {
        let k = |pairs: &[(&str, &str)]| params_of(pairs).map(|p| (p.k, p.ladder.map(|l| l.max)));
        assert_eq!(k(&[]).ok(), Some((30, None)));
        assert_eq!(k(&[("radius", "2m")]).ok(), Some((100, None)));
        assert_eq!(k(&[("radius", "2m"), ("k", "12")]).ok(), Some((12, None)));
        assert_eq!(k(&[("k", "auto")]).ok(), Some((320, Some(320))));
        assert_eq!(k(&[("k_range", "16..256")]).ok(), Some((256, Some(256))));
        assert!(k(&[("k", "5")]).is_err());
        assert!(k(&[("k", "auto"), ("radius", "1")]).is_err());
        assert!(k(&[("f32", "true"), ("f64", "true")]).is_err());
        assert!(k(&[("jet_degree", "5")]).is_err());
    }

    /// Options an estimator does not use are refused with it, and so is `--triangles 0`;
    /// with the estimator they set they are taken.
    #[test]
    fn estimator_options_go_with_their_estimator() {
        let run = |pairs: &[(&str, &str)]| params_of(pairs).map_err(|e| e.to_string());
        let refused = |pairs: &[(&str, &str)], says: &str| {
            let e = run(pairs).expect_err("refused");
            assert!(e.contains(says), "{pairs:?}: {e}");
        };
        refused(
            &[("triangles", "50")],
            "--triangles 50 sets --estimator cnc-uniform",
        );
        refused(
            &[("jet_degree", "3"), ("estimator", "wme")],
            "--jet-degree 3 sets --estimator jet",
        );
        refused(
            &[("triangles", "0"), ("estimator", "cnc-uniform")],
            "at least one triangle",
        );
        refused(
            &[("estimator", "apss"), ("directions", "true")],
            "no principal directions",
        );
        assert!(run(&[("triangles", "50"), ("estimator", "cnc-uniform")]).is_ok());
        assert!(run(&[("jet_degree", "3"), ("estimator", "jet")]).is_ok());
        assert!(run(&[("estimator", "apss")]).is_ok());
    }

    /// The provenance lists the options in the table's order under their provenance keys,
    /// the jet degree only when it is not the default and the triangles only for cnc-uniform.
    #[test]
    fn provenance_keys_in_order() {
        let r = Resolved {
            tile_size: 50.0,
            radius: None,
            unit_name: "m".into(),
            z_scale: 1.0,
            z_words: None,
            file_normals: false,
        };
        let keys: Vec<&str> = RunParams::default()
            .provenance(&r)
            .iter()
            .map(|p| p.key)
            .collect();
        assert_eq!(
            keys,
            [
                "estimator",
                "k",
                "k_range",
                "radius",
                "seed",
                "normals",
                "orientation",
                "tile",
                "columns",
                "encoding",
                "keep_version",
                "ply_las_names",
                "classes",
                "skip_classes",
                "skip_withheld"
            ]
        );
    }
}
