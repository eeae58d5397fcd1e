//! The run spec: everything the stages need to know about a run once its inputs are open and
//! checked. Its [`Param`] list is the one place where a parameter that changes the output is
//! named: the work directory's fingerprint and the output's provenance record are both derived
//! from it, so a new option cannot reach one and not the other.

use std::path::PathBuf;

use crate::config::{Config, OrientMode};
use crate::core::estimate::Estimator;
use crate::core::plan::TileGrid;
use crate::core::select::{ClassFilter, Classes};
use crate::io::columns::{ColumnSet, ColumnType};
use crate::io::sink::OutputOptions;
use crate::io::source::PointSource;
use crate::io::workdir::Fingerprint;

/// One parameter that changes the output, as `key=value` in the provenance and the manifest.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Param {
    /// The key, e.g. `estimator`.
    pub key: &'static str,
    /// The value in words, e.g. `cnc-avg-hexagram`.
    pub value: String,
}

/// A checked run: open inputs, their outputs, and every resolved parameter.
pub struct RunSpec {
    /// The open inputs, one scene, in command-line order.
    pub sources: Vec<Box<dyn PointSource>>,
    /// Global id of each input's point 0 (the sum of the earlier inputs' counts).
    pub first_ids: Vec<u64>,
    /// One output per input.
    pub outputs: Vec<PathBuf>,
    /// Points in all inputs.
    pub total_points: u64,
    /// The tile grid, in file units.
    pub grid: TileGrid,
    /// The horizontal unit's symbol ("m", "ft", or "unit" without a CRS).
    pub unit_name: String,
    /// Factor from the inputs' z unit to their horizontal unit (1 unless the CRS declares
    /// another vertical unit): applied to z when the points are read, before any geometry.
    pub z_scale: f64,
    /// Whether the inputs' normals are used instead of PCA.
    pub file_normals: bool,
    /// The columns written.
    pub cols: ColumnSet,
    /// How LAS/LAZ outputs store them.
    pub column_type: ColumnType,
    /// Neighbours per point (with `radius`, the cap on them; with `ladder`, its top rung).
    pub k: usize,
    /// `-k auto`: the ladder the scale is chosen from per point.
    pub ladder: Option<crate::core::scale::Ladder>,
    /// `--radius` in file units: neighbourhoods of the points within it.
    pub radius: Option<f64>,
    /// How PCA normals are oriented.
    pub orientation: OrientMode,
    /// The estimator, built once.
    pub estimator: Box<dyn Estimator>,
    /// The parameters that change the output, resolved, in provenance order.
    pub params: Vec<Param>,
    /// Every output-changing option as given ([`Config::params`]): the manifest stores them.
    pub config: Vec<crate::config::Param>,
    /// Which points are computed.
    pub select: ClassFilter,
    /// How the outputs are written besides their columns.
    pub output_options: OutputOptions,
}

/// The parameters of `cfg` that change the output, with the resolved tile size and radius
/// (`sizes`, file units), unit and normal source, in the order the provenance lists them.
pub fn parameters(
    cfg: &Config,
    sizes: (f64, Option<f64>),
    unit: &str,
    file_normals: bool,
) -> Vec<Param> {
    let (tile_size, radius) = sizes;
    let p = |key, value: String| Param { key, value };
    let mut v = vec![
        p("estimator", cfg.estimator.to_string()),
        p("k", cfg.k.to_string()),
        p(
            "k_range",
            match cfg.scale {
                Some(l) => format!("{l} (-k auto: the scale chosen per point, ScaleK)"),
                None => "none (one k)".into(),
            },
        ),
        p(
            "radius",
            match (cfg.radius, radius) {
                (Some(r), Some(size)) => {
                    format!("{r} ({size} {unit}; at most k neighbours within it)")
                }
                _ => "none (k nearest neighbours)".into(),
            },
        ),
        p("seed", cfg.params.seed.to_string()),
        p("triangles", cfg.params.triangles.to_string()),
        p("normals", if file_normals { "file" } else { "pca" }.into()),
        p("orientation", cfg.orientation.to_string()),
        p("tile", format!("{} ({tile_size} {unit})", cfg.tile)),
        p("columns", cfg.columns.to_string()),
        p(
            "encoding",
            match cfg.column_type {
                ColumnType::Scaled => "scaled (LAS/LAZ; f32 in PLY), column.* lines below",
                ColumnType::F32 => "f32",
                ColumnType::F64 => "f64",
            }
            .into(),
        ),
        p("keep_version", cfg.keep_version.to_string()),
        p("ply_las_names", cfg.ply_las_names.to_string()),
        p("classes", cfg.select.only_text("all")),
        p("skip_classes", Classes(&cfg.select.skip).to_string()),
        p("skip_withheld", cfg.select.skip_withheld.to_string()),
    ];
    if let Some(n) = cfg.sample_faces {
        v.push(p(
            "sample_faces",
            format!("{n} (points sampled on the mesh faces)"),
        ));
    }
    v
}

impl RunSpec {
    /// The provenance text stored in every output: tool version, input names and every
    /// parameter, then the sign convention and unit.
    pub fn provenance(&self) -> String {
        let inputs: Vec<String> = self
            .sources
            .iter()
            .map(|s| {
                s.path()
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default()
            })
            .collect();
        let mut t = format!(
            "tilecurv {}\ninputs={}\n",
            env!("CARGO_PKG_VERSION"),
            inputs.join(",")
        );
        for p in &self.params {
            t.push_str(&format!("{}={}\n", p.key, p.value));
        }
        t.push_str(&format!(
            "sign=positive where the surface bends away from its normal; curvature in 1/{}\n",
            self.unit_name
        ));
        t
    }

    /// The work directory's manifest: a fingerprint of the inputs (path, size, modification
    /// time, point count) and of every output-changing option, then the same in words for a
    /// person and the options as `param key=value` lines, from which every stage rebuilds the
    /// run ([`manifest_params`]). Work left by a run with another manifest is discarded, never
    /// mixed in; how the run is executed (threads, memory, tasks) is not in it.
    pub fn manifest(&self) -> String {
        let mut fp = Fingerprint::default();
        let mut text = String::new();
        fp.text(env!("CARGO_PKG_VERSION"));
        let format = format!("work format {}\n", crate::io::workdir::FORMAT_VERSION);
        fp.text(&format);
        text.push_str(&format);
        for s in &self.sources {
            let p = s.path();
            let meta = std::fs::metadata(p).ok();
            let size = meta.as_ref().map(|m| m.len()).unwrap_or(0);
            let mtime = meta
                .and_then(|m| m.modified().ok())
                .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
                .map(|d| d.as_nanos())
                .unwrap_or(0);
            let canon = p.canonicalize().unwrap_or_else(|_| p.to_path_buf());
            fp.text(&canon.to_string_lossy())
                .text(&size.to_string())
                .text(&mtime.to_string())
                .text(&s.len().to_string());
            text.push_str(&format!(
                "input {} ({size} bytes, {} points)\n",
                canon.display(),
                s.len()
            ));
        }
        // The tile size in file units exactly: buckets depend on it bit for bit.
        fp.text(&self.grid.size.to_bits().to_string());
        for p in &self.params {
            text.push_str(&format!("{}={}\n", p.key, p.value));
        }
        for p in &self.config {
            let line = format!("param {}={}", p.key, p.value);
            fp.text(&line);
            text.push_str(&line);
            text.push('\n');
        }
        format!(
            "tilecurv work directory, fingerprint {:016x}\n{text}",
            fp.value()
        )
    }
}

/// The `param key=value` lines of a manifest, in order.
pub fn manifest_params(manifest: &str) -> Vec<(String, String)> {
    manifest
        .lines()
        .filter_map(|l| l.strip_prefix("param "))
        .filter_map(|l| l.split_once('='))
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every output-changing option reaches the provenance (under its provenance name), except
    /// the jet degree, which no command-line option sets.
    #[test]
    fn every_option_is_in_the_provenance() {
        let cfg = Config {
            sample_faces: Some(1000),
            radius: Some(crate::config::Length::Metres(1.5)),
            ..Config::default()
        };
        let names: Vec<&str> = parameters(&cfg, (50.0, Some(1.5)), "m", false)
            .iter()
            .map(|p| p.key)
            .collect();
        for p in cfg.params() {
            let in_provenance = match p.key {
                "input" => "inputs",
                "orient" => "orientation",
                "ignore_file_normals" => "normals",
                "jet_degree" => continue,
                k => k,
            };
            assert!(
                in_provenance == "inputs" || names.contains(&in_provenance),
                "option {} is not in the provenance",
                p.key
            );
        }
    }
}
