//! The run spec: everything the stages need to know about a run once its inputs are open and
//! checked: the validated parameters, what the inputs resolved them to, and what follows from
//! both (the tile plan, the per-point compute parameters, the memory plan, the provenance and
//! the manifest), derived here once so that no stage derives them again.

use std::path::PathBuf;

use crate::config::{OrientMode, Param, Resolved, RunParams};
use crate::core::compute::ComputeParams;
use crate::core::estimate::Estimator;
use crate::core::normals::Orientation;
use crate::core::plan::{plan, MemoryPlan, ScanStats, TileGrid, TilePlan};
use crate::io::columns::ColumnSet;
use crate::io::sink::OutputOptions;
use crate::io::source::PointSource;
use crate::io::workdir::manifest::{InputStamp, Manifest};

/// A checked run: open inputs, their outputs, and every resolved parameter.
pub(crate) struct RunSpec {
    /// The inputs as the run was given them (absolute for a cluster run).
    pub inputs: Vec<PathBuf>,
    /// The open inputs, one scene, in command-line order.
    pub sources: Vec<Box<dyn PointSource>>,
    /// Global id of each input's point 0 (the sum of the earlier inputs' counts).
    pub first_ids: Vec<u64>,
    /// One output per input (none for the cluster stages that write none).
    pub outputs: Vec<PathBuf>,
    /// Points in all inputs.
    pub total_points: u64,
    /// The validated options.
    pub params: RunParams,
    /// What the inputs resolved: sizes in file units, unit, vertical scale, normals' source.
    pub resolved: Resolved,
    /// The tile grid, in file units.
    pub grid: TileGrid,
    /// The columns computed and written.
    pub cols: ColumnSet,
    /// The estimator, built once.
    pub estimator: Box<dyn Estimator>,
    /// How the outputs are written besides their columns.
    pub output_options: OutputOptions,
}

impl RunSpec {
    /// The number of points of each input, in command-line order.
    pub(crate) fn input_points(&self) -> Vec<u64> {
        self.sources.iter().map(|s| s.len()).collect()
    }

    /// Whether normals are oriented by propagation (`--orient propagate`).
    pub(crate) fn propagates(&self) -> bool {
        self.params.orientation == OrientMode::Propagate
    }

    /// The tiles over the scanned cloud: their cores from the statistics, halos for `k` (or
    /// the radius).
    pub(crate) fn tile_plan(&self, stats: &ScanStats) -> TilePlan {
        plan(stats, self.grid.size, self.params.k, self.resolved.radius)
    }

    /// What to compute per point, once the scan has seen the cloud's centroid.
    pub(crate) fn compute_params(&self, stats: &ScanStats) -> ComputeParams<'_> {
        ComputeParams {
            k: self.params.k,
            radius: self.resolved.radius,
            // A viewpoint is given in file coordinates: its z converts like the points'.
            orientation: match self.params.orientation.resolve(stats.centroid()) {
                Orientation::Viewpoint([x, y, z]) => {
                    Orientation::Viewpoint([x, y, z * self.resolved.z_scale])
                }
                o => o,
            },
            use_file_normals: self.resolved.file_normals,
            estimator: self.estimator.as_ref(),
            extra: self.cols.extra.len(),
            propagate: self.propagates().then_some(stats.centroid()),
            ladder: self.params.ladder,
            terrain: self.cols.choice.has_terrain(),
        }
    }

    /// How a budget of `budget_bytes` is shared among `threads` for this run: tiles hold `k`
    /// neighbours a point, and every rung of `-k auto`.
    pub(crate) fn memory_plan(&self, budget_bytes: usize, threads: usize) -> MemoryPlan {
        let rungs = self.params.ladder.map_or(1, |l| l.rungs());
        MemoryPlan::new(budget_bytes, self.params.k, rungs, threads)
    }

    /// The provenance's parameter lines.
    pub(crate) fn parameters(&self) -> Vec<Param> {
        self.params.provenance(&self.resolved)
    }

    /// The provenance text stored in every output: tool version, input names and every
    /// parameter, then the sign convention and unit.
    pub(crate) fn provenance(&self) -> String {
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
        for p in self.parameters() {
            t.push_str(&format!("{}={}\n", p.key, p.value));
        }
        t.push_str(&format!(
            "sign=positive where the surface bends away from its normal; curvature in 1/{}\n",
            self.resolved.unit_name
        ));
        t
    }

    /// The work directory's manifest of this run: its inputs, tile size, parameters in words,
    /// and the options every stage rebuilds the run from.
    pub(crate) fn manifest(&self) -> String {
        Manifest {
            inputs: self
                .inputs
                .iter()
                .zip(&self.sources)
                .map(|(path, s)| InputStamp {
                    path: path.clone(),
                    points: s.len(),
                })
                .collect(),
            tile_size: self.grid.size,
            words: self
                .parameters()
                .into_iter()
                .map(|p| (p.key.to_string(), p.value))
                .collect(),
            params: self
                .params
                .options
                .pairs()
                .into_iter()
                .map(|(k, v)| (k.to_string(), v))
                .collect(),
        }
        .text()
    }
}
