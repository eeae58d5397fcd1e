//! The first stage: opens the inputs and runs every check that can fail before any work is
//! done (output paths, inputs that would be overwritten, units, normals, column names: a
//! tilecurv output's own columns are replaced, see `run::rerun`), then resolves the
//! configuration against the inputs into a [`RunSpec`].

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use crate::config::{Resolved, RunParams};
use crate::core::plan::TileGrid;
use crate::error::{Error, Result};
use crate::io::columns::{ColumnSet, Group};
use crate::io::crs::UnitSource;
use crate::io::sink::{file_id, same_file, OutputOptions};
use crate::io::source::{PointSource, SourceLayout};
use crate::progress::Reporter;
use crate::run::one_map::{check_one_map, Joined};
use crate::run::spec::RunSpec;

/// The output path of each input: `output` itself for one input (or a file in it if it is a
/// directory), `<output dir>/<input file name>` for several.
pub(crate) fn output_paths(inputs: &[PathBuf], output: &Path) -> Result<Vec<PathBuf>> {
    let is_dir = output.is_dir() || output.as_os_str().to_string_lossy().ends_with('/');
    if inputs.len() == 1 && !is_dir {
        return Ok(vec![output.to_path_buf()]);
    }
    if !is_dir {
        return Err(Error::Usage(format!(
            "{}: with {} inputs the output must be a directory (one output per input, same file name); end it with / to create it",
            output.display(),
            inputs.len()
        )));
    }
    check_input_names(inputs)?;
    std::fs::create_dir_all(output).map_err(|e| Error::write(output, e))?;
    Ok(inputs
        .iter()
        .filter_map(|i| i.file_name())
        .map(|name| output.join(name))
        .collect())
}

/// Refuses the same file named twice among `inputs`, whose points would count twice (a link is
/// the file it names: [`file_id`]).
pub(crate) fn check_distinct_files(inputs: &[PathBuf]) -> Result<()> {
    let mut seen = HashMap::new();
    for input in inputs {
        let Some(id) = file_id(input) else { continue };
        if let Some(twin) = seen.insert(id, input) {
            return Err(Error::Usage(format!(
                "{} is named twice (also as {}): its points would count twice; name each file once",
                input.display(),
                twin.display()
            )));
        }
    }
    Ok(())
}

/// Refuses inputs whose outputs would collide, since the outputs of several inputs take their
/// inputs' file names: the same file named twice ([`check_distinct_files`]), or two files of
/// one name in different folders. Checked by `process` and by the cluster's `plan`, so that
/// `plan` refuses what `assemble` would.
pub(crate) fn check_input_names(inputs: &[PathBuf]) -> Result<()> {
    check_distinct_files(inputs)?;
    let mut seen = HashMap::new();
    for input in inputs {
        let name = input
            .file_name()
            .ok_or_else(|| Error::Usage(format!("{}: not a file name", input.display())))?;
        if let Some(twin) = seen.insert(name, input) {
            return Err(Error::Usage(format!(
                "two inputs are named {} ({} and {}): the outputs of several inputs take their inputs' file names, so theirs would collide; rename one, or process them apart",
                name.to_string_lossy(),
                twin.display(),
                input.display()
            )));
        }
    }
    Ok(())
}

/// Checks the outputs: a supported extension, and never one of the inputs.
pub(crate) fn check_outputs(inputs: &[PathBuf], outputs: &[PathBuf]) -> Result<()> {
    for output in outputs {
        crate::io::sink::check_output_path(output)?;
        if inputs.iter().any(|i| same_file(i, output)) {
            return Err(Error::Usage(format!(
                "{}: the output would overwrite an input; choose another output path",
                output.display()
            )));
        }
    }
    Ok(())
}

/// The horizontal unit shared by the inputs.
struct CommonUnit {
    /// Its symbol ("unit" without a CRS).
    symbol: String,
    /// With a CRS, the unit and its length in metres.
    unit: Option<crate::io::crs::LengthUnit>,
    /// Its words for the log ("unit m", or "no length unit (why)").
    words: String,
}

/// A unit's symbol for a message, "no length unit" without one.
fn unit_words(u: &UnitSource) -> String {
    u.unit()
        .map_or_else(|| "no length unit".into(), |u| u.symbol())
}

/// The horizontal unit shared by every input (the first one decides; another unit is an
/// error).
fn common_unit(
    cfg: &RunParams,
    sources: &[Box<dyn PointSource>],
    reporter: &dyn Reporter,
) -> Result<CommonUnit> {
    let unit = sources[0].unit();
    for s in &sources[1..] {
        let u = s.unit();
        if u.unit().map(|u| u.metres) != unit.unit().map(|u| u.metres) {
            return Err(Error::Usage(format!(
                "{} and {} have different horizontal units ({} and {}); process them separately",
                sources[0].path().display(),
                s.path().display(),
                unit_words(&unit),
                unit_words(&u)
            )));
        }
    }
    Ok(match unit {
        UnitSource::Wkt(u) | UnitSource::GeoTiff(u) => {
            let symbol = u.symbol();
            CommonUnit {
                words: format!("unit {symbol}"),
                symbol,
                unit: Some(u),
            }
        }
        UnitSource::Unknown(why) => {
            if cfg.tile.has_unit() {
                reporter.warn(&format!(
                    "{}: {why}; --tile {} is taken in file units",
                    sources[0].path().display(),
                    cfg.tile
                ));
            }
            if let Some(r) = cfg.radius.filter(|r| r.has_unit()) {
                reporter.warn(&format!(
                    "{}: {why}; --radius {r} is taken in file units",
                    sources[0].path().display(),
                ));
            }
            CommonUnit {
                symbol: "unit".to_string(),
                unit: None,
                words: format!("no length unit ({why})"),
            }
        }
    })
}

/// The factor from the inputs' z unit to their horizontal unit.
struct VerticalScale {
    /// The factor (1 unless the CRS declares another vertical unit).
    factor: f64,
    /// Its words for the provenance when it is not 1.
    words: Option<String>,
}

/// The factor from the inputs' z unit to their horizontal unit, with its words for the
/// provenance when it is not 1 (unconverted, heights in US survey feet under a compound CRS in
/// metres make H 2.5x and K 5.1x too large). Without a horizontal unit there is nothing to
/// convert to; a vertical CRS whose unit cannot be read is warned about; inputs whose factors
/// differ are refused, as for the horizontal unit.
fn vertical_scale(
    sources: &[Box<dyn PointSource>],
    horizontal: Option<&crate::io::crs::LengthUnit>,
    reporter: &dyn Reporter,
) -> Result<VerticalScale> {
    use crate::io::crs_summary::VerticalUnit;
    let one = VerticalScale {
        factor: 1.0,
        words: None,
    };
    let Some(h) = horizontal else {
        return Ok(one);
    };
    let mut found: Option<(f64, String)> = None;
    for s in sources {
        let (scale, words) = match s.vertical_unit() {
            VerticalUnit::Declared(v) => (
                v.metres / h.metres,
                format!("z in {} converted to {}", v.name, h.name),
            ),
            VerticalUnit::Undeclared(_) => (1.0, String::new()),
            VerticalUnit::Unreadable(why) => {
                reporter.warn(&format!(
                    "{}: {why}; z is taken in {}, like x and y: if the heights are in another unit, H and K are wrong",
                    s.path().display(),
                    h.symbol()
                ));
                (1.0, String::new())
            }
        };
        // Units within a part in 1e12 of each other (ftUS written two ways) are the same.
        let scale = if (scale - 1.0).abs() < 1e-12 {
            1.0
        } else {
            scale
        };
        match &found {
            Some((f, _)) if *f != scale => {
                return Err(Error::Usage(format!(
                    "{}: its heights need the factor {scale} to {}, the first input's {f}; process them separately",
                    s.path().display(),
                    h.symbol()
                )))
            }
            Some(_) => {}
            None => found = Some((scale, words)),
        }
    }
    Ok(match found {
        Some((f, words)) if f != 1.0 => {
            let words = format!("{f} ({words})");
            reporter.info(&format!("{}: z x {words}", sources[0].path().display()));
            VerticalScale {
                factor: f,
                words: Some(words),
            }
        }
        _ => one,
    })
}

/// Refuses a class filter beyond the default on an input without LAS classes (PLY, XYZ, ...):
/// it would silently compute on every point.
fn check_classes(cfg: &RunParams, sources: &[Box<dyn PointSource>]) -> Result<()> {
    if !cfg.select.needs_classes() {
        return Ok(());
    }
    match sources.iter().find(|s| !s.has_classes()) {
        Some(s) => Err(Error::Usage(format!(
            "{}: its points ({}) have no LAS classes or withheld flags, so --classes, --skip-classes and --skip-withheld cannot select them; drop those options, or give points with a classification (a LAS/LAZ file; in Python, a laspy LasData)",
            s.path().display(),
            s.describe()
        ))),
        None => Ok(()),
    }
}

/// Whether an input already has columns named NormalX/Y/Z (a LAS file's normals; a tilecurv
/// output's own are dropped when it is opened, so these are someone else's).
fn named_normals(s: &dyn PointSource) -> bool {
    s.properties()
        .iter()
        .any(|p| p.name.eq_ignore_ascii_case("NormalX"))
}

/// Whether the file's normals are used: all inputs have them (and --ignore-file-normals is not
/// given) or none has; a mix is an error, and so is ignoring normals whose names the estimated
/// ones would need.
fn use_file_normals(cfg: &RunParams, sources: &[Box<dyn PointSource>]) -> Result<bool> {
    let with_normals = sources.iter().filter(|s| s.has_normals()).count();
    if with_normals != 0 && with_normals != sources.len() && !cfg.ignore_file_normals {
        return Err(Error::Usage(
            "some inputs have normals and others do not; process them separately (or use --ignore-file-normals)".into(),
        ));
    }
    if cfg.ignore_file_normals {
        if let Some(s) = sources.iter().find(|s| named_normals(s.as_ref())) {
            return Err(Error::Usage(format!(
                "{}: --ignore-file-normals: the input already has NormalX/Y/Z columns, and the estimated normals cannot be written under the same names; drop the option to use the file's normals",
                s.path().display()
            )));
        }
    }
    Ok(with_normals > 0 && !cfg.ignore_file_normals)
}

/// The checks of the new columns against each output (among `outputs`, one per source), before
/// any work: PLY names an input property already has ([`check_ply_names`]), extra-bytes
/// descriptors that need an EVLR (`check_extra_bytes`); returns the warnings to give.
///
/// [`check_ply_names`]: crate::run::rerun::check_ply_names
pub(crate) fn check_output_columns(
    cfg: &RunParams,
    sources: &[Box<dyn PointSource>],
    outputs: &[PathBuf],
    cols: &ColumnSet,
    ply_names: crate::io::ply::PlyNames,
) -> Result<Vec<String>> {
    crate::run::rerun::check_ply_names(cfg, sources, outputs, cols, ply_names)?;
    check_extra_bytes(cfg, sources, outputs, cols)
}

/// Refuses, before any work, a LAS/LAZ output (among `outputs`, one per source, with the new
/// columns `cols`) whose extra-bytes descriptors do not fit a VLR (65535 bytes) when it keeps a
/// LAS version before 1.4, which has no EVLRs to hold them. Returns the warnings for the LAS
/// 1.4 outputs that get them as an EVLR instead, which some readers ignore.
fn check_extra_bytes(
    cfg: &RunParams,
    sources: &[Box<dyn PointSource>],
    outputs: &[PathBuf],
    cols: &ColumnSet,
) -> Result<Vec<String>> {
    use crate::io::sink::{extra_bytes_payload, output_format, OutputFormat};
    // The number of descriptors does not depend on the encoding, chosen later from the data.
    let new = crate::io::columns::output::OutputColumns::new(
        cols,
        crate::io::columns::output::Encoding::F32,
    );
    let mut notes = Vec::new();
    for (s, output) in sources.iter().zip(outputs) {
        if matches!(output_format(output)?, OutputFormat::Ply { .. }) {
            continue;
        }
        let bytes = extra_bytes_payload(s.as_ref(), &new)?.len();
        if bytes <= u16::MAX as usize {
            continue;
        }
        if let SourceLayout::Las(p) = s.layout() {
            if cfg.keep_version && p.header.version.1 < 4 {
                let why = crate::io::las::writer::too_many_descriptors(bytes, p.header.version);
                return Err(Error::Usage(format!("{}: {why}", s.path().display())));
            }
        }
        notes.push(format!(
            "{}: the {} extra-bytes descriptors of {} do not fit a VLR (65535 bytes): they are written as an extra-bytes EVLR, as LAS 1.4 allows; PDAL reads it, but laspy (2.7) and CloudCompare read extra dimensions from VLRs only",
            s.path().display(),
            bytes / crate::io::las::extra_bytes::DESCRIPTOR_SIZE,
            output.display()
        ));
    }
    Ok(notes)
}

/// Refuses, before any work, inputs whose declared bounds (a LAS header's, when finite) reach
/// past the tile grid: the tile is too small for the extent. Inputs without declared bounds,
/// and headers whose bounds are wrong, are checked point by point by the scan.
fn check_extent(sources: &[Box<dyn PointSource>], grid: TileGrid) -> Result<()> {
    for s in sources {
        let Some([min, max]) = crate::io::source::declared_bounds(s.as_ref()) else {
            continue;
        };
        for (x, y) in [(min[0], min[1]), (max[0], max[1])] {
            if !grid.holds(x, y) {
                let what = format!("{}: the header's bounds say a point", s.path().display());
                return Err(Error::Usage(grid.outside(&what, x, y)));
            }
        }
    }
    Ok(())
}

/// Opens and checks `inputs`, checks the outputs `output` names, and resolves the run with
/// `params`. Nothing is written except the output directory of a multi-input run.
pub(crate) fn prepare(
    inputs: &[PathBuf],
    output: &Path,
    params: RunParams,
    reporter: &dyn Reporter,
) -> Result<RunSpec> {
    let outputs = output_paths(inputs, output)?;
    check_outputs(inputs, &outputs)?;
    open_checked(inputs, params, outputs, reporter)
}

/// Opens and checks `inputs` and resolves the run with `params`, without outputs (the stages
/// of a cluster run that write none).
pub(crate) fn open_inputs(
    inputs: &[PathBuf],
    params: RunParams,
    reporter: &dyn Reporter,
) -> Result<RunSpec> {
    // The outputs `assemble` will name after the inputs, refused now rather than after the work.
    check_input_names(inputs)?;
    open_checked(inputs, params, Vec::new(), reporter)
}

/// The log line's words for `--radius` (`radius`: in file units, named `units`), empty without.
fn radius_words(cfg: &RunParams, radius: Option<f64>, units: &str) -> String {
    match (cfg.radius, radius) {
        (Some(r), Some(size)) => format!(
            "; radius {r} = {size:.3} {units}, at most {} neighbours",
            cfg.k
        ),
        _ => match cfg.ladder {
            Some(l) => format!("; k auto, chosen per point among {l}"),
            None => String::new(),
        },
    }
}

/// Opens `inputs` (a tilecurv output without its own columns, `run::rerun`), adding to
/// `notes` the warnings to give once every check passed.
fn open_sources(
    inputs: &[PathBuf],
    cfg: &RunParams,
    notes: &mut Vec<String>,
) -> Result<Vec<Box<dyn PointSource>>> {
    inputs
        .iter()
        .map(|p| match cfg.sample_faces {
            Some(n) => crate::io::source::open_sampled(p, n, cfg.estimator_params.seed),
            None => crate::run::rerun::open_input(p).map(|o| {
                notes.extend(o.note);
                o.source
            }),
        })
        .collect()
}

/// How `cfg` writes its outputs besides their columns.
fn output_options(cfg: &RunParams) -> OutputOptions {
    OutputOptions {
        keep_las_version: cfg.keep_version,
        ply_names: if cfg.ply_las_names {
            crate::io::ply::PlyNames::Las
        } else {
            crate::io::ply::PlyNames::CloudCompare
        },
    }
}

/// [`open_inputs`] with the `outputs` of the inputs (none for the stages that write none).
fn open_checked(
    inputs: &[PathBuf],
    cfg: RunParams,
    outputs: Vec<PathBuf>,
    reporter: &dyn Reporter,
) -> Result<RunSpec> {
    let mut notes = Vec::new();
    let sources = open_sources(inputs, &cfg, &mut notes)?;
    resolve(inputs, sources, notes, cfg, outputs, reporter)
}

/// Checks the open `sources` (of `inputs`, with the warnings `notes` their opening gave) and
/// resolves the run with `cfg`: what [`open_inputs`] does once the files are open, and what a
/// run over points in memory (`run::memory`) does with its source.
pub(crate) fn resolve(
    inputs: &[PathBuf],
    sources: Vec<Box<dyn PointSource>>,
    mut notes: Vec<String>,
    cfg: RunParams,
    outputs: Vec<PathBuf>,
    reporter: &dyn Reporter,
) -> Result<RunSpec> {
    // First: inputs in two CRSs differ in more than their units.
    let (_, crs_notes) = check_one_map(&sources, Joined::Scene)?;
    notes.extend(crs_notes);
    notes.extend(sources.iter().flat_map(|s| s.warnings()));
    let CommonUnit {
        symbol: unit_name,
        unit,
        words: unit_words,
    } = common_unit(&cfg, &sources, reporter)?;
    let tile_units = match unit {
        Some(_) => unit_name.clone(),
        None => "file units".to_string(),
    };
    let tile_size = cfg.tile.in_file_units(unit.as_ref());
    let radius = cfg.radius.map(|r| r.in_file_units(unit.as_ref()));
    let VerticalScale {
        factor: z_scale,
        words: z_words,
    } = vertical_scale(&sources, unit.as_ref(), reporter)?;
    check_extent(&sources, TileGrid { size: tile_size })?;
    check_classes(&cfg, &sources)?;
    let file_normals = use_file_normals(&cfg, &sources)?;
    let estimator = cfg.estimator.build(&cfg.estimator_params);
    let cols = column_set(
        &cfg,
        &sources,
        file_normals,
        estimator.extra_columns(),
        &unit_name,
    );
    let output_options = output_options(&cfg);
    crate::run::rerun::check_new_names(&cfg, &sources, &cols)?;
    let ply = output_options.ply_names;
    notes.extend(check_output_columns(&cfg, &sources, &outputs, &cols, ply)?);
    for note in &notes {
        reporter.warn(note);
    }
    let radius_words = radius_words(&cfg, radius, &tile_units);
    for s in &sources {
        reporter.info(&format!(
            "{}: {} points, {}, {unit_words}; tile {} = {tile_size:.3} {tile_units}{radius_words}; normals {}",
            s.path().display(),
            s.len(),
            s.describe(),
            cfg.tile,
            if file_normals {
                "from the file (NormalX/Y/Z)"
            } else {
                "by PCA"
            },
        ));
    }
    let first_ids: Vec<u64> = sources
        .iter()
        .scan(0u64, |acc, s| {
            let f = *acc;
            *acc += s.len();
            Some(f)
        })
        .collect();
    Ok(RunSpec {
        inputs: inputs.to_vec(),
        total_points: sources.iter().map(|s| s.len()).sum(),
        first_ids,
        outputs,
        grid: TileGrid { size: tile_size },
        resolved: Resolved {
            tile_size,
            radius,
            unit_name,
            z_scale,
            z_words,
            file_normals,
        },
        params: cfg,
        output_options,
        cols,
        estimator,
        sources,
    })
}

/// The columns a run computes: those asked for, less the normals when the inputs keep their
/// own (used, or ignored but named so), plus the scale `-k auto` chose, and the estimator's
/// extra columns with `--features`.
fn column_set(
    cfg: &RunParams,
    sources: &[Box<dyn PointSource>],
    file_normals: bool,
    extra: &[crate::core::estimate::ExtraColumn],
    unit_name: &str,
) -> ColumnSet {
    let keeps_normals = file_normals || sources.iter().any(|s| named_normals(s.as_ref()));
    ColumnSet {
        choice: if keeps_normals {
            cfg.columns.without(Group::Normals)
        } else {
            cfg.columns
        }
        .with_if(cfg.ladder.is_some(), Group::Scale),
        extra: if cfg.columns.has(Group::Features) {
            extra.to_vec()
        } else {
            Vec::new()
        },
        unit: unit_name.to_string(),
        wide: cfg.column_type == crate::io::columns::ColumnType::F64,
    }
}
