//! How a run is split into tasks that a scheduler (a Slurm job array, AWS Batch, a Kubernetes
//! Indexed Job) runs independently: bucket tasks (each scans some of the inputs) and tile tasks
//! (each computes the tiles of a range of the tile grid). Pure: the layout is decided by `plan`
//! from the inputs' bounds, stored as text in the work directory, and read back by every task.
//! How a run is split never changes its output.

use std::ops::Range;

use crate::core::plan::TileKey;

/// The task layout of a run.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TaskLayout {
    /// Per bucket task, the range of inputs (command-line order) it scans.
    pub bucket_tasks: Vec<Range<usize>>,
    /// The tile grid planned from the inputs' bounds: the lowest and highest tile keys.
    pub grid_lo: TileKey,
    /// See `grid_lo`.
    pub grid_hi: TileKey,
    /// Tiles of the grid per tile task (the last task may have fewer).
    pub tiles_per_task: u64,
}

/// The Slurm default `MaxArraySize` (1001) allows indices 0..1000: the default layout keeps
/// the tile tasks within 1000.
pub const DEFAULT_MAX_TASKS: u64 = 1000;

impl TaskLayout {
    /// A layout over the tiles from `lo` to `hi` (inclusive) with `tiles_per_task` tiles per
    /// task (None: as few as keep the tasks within [`DEFAULT_MAX_TASKS`]).
    pub fn new(
        bucket_tasks: Vec<Range<usize>>,
        lo: TileKey,
        hi: TileKey,
        tiles_per_task: Option<u64>,
    ) -> Self {
        let mut l = TaskLayout {
            bucket_tasks,
            grid_lo: lo,
            grid_hi: (hi.0.max(lo.0), hi.1.max(lo.1)),
            tiles_per_task: 1,
        };
        l.tiles_per_task = tiles_per_task
            .unwrap_or_else(|| l.grid_tiles().div_ceil(DEFAULT_MAX_TASKS))
            .max(1);
        l
    }

    /// The layout of `process`: one bucket task over all `inputs`, every tile in one task.
    pub fn single(inputs: usize) -> Self {
        TaskLayout::new(
            std::iter::once(0..inputs).collect(),
            (0, 0),
            (0, 0),
            Some(1),
        )
    }

    /// Tiles in the planned grid.
    pub fn grid_tiles(&self) -> u64 {
        let w = (self.grid_hi.0 - self.grid_lo.0) as u64 + 1;
        let h = (self.grid_hi.1 - self.grid_lo.1) as u64 + 1;
        w.saturating_mul(h)
    }

    /// Number of tile tasks: ceil(grid tiles / tiles per task).
    pub fn tile_tasks(&self) -> u64 {
        self.grid_tiles().div_ceil(self.tiles_per_task)
    }

    /// The tile task that computes tile `key`: its position in the grid (row by row), the key
    /// clamped into the grid first, so that a point outside the bounds the plan was made from
    /// (a header whose bounds are wrong) still belongs to exactly one task.
    pub fn task_of(&self, key: TileKey) -> u64 {
        let x = key.0.clamp(self.grid_lo.0, self.grid_hi.0) - self.grid_lo.0;
        let y = key.1.clamp(self.grid_lo.1, self.grid_hi.1) - self.grid_lo.1;
        let w = (self.grid_hi.0 - self.grid_lo.0) as u64 + 1;
        (y as u64 * w + x as u64) / self.tiles_per_task
    }

    /// The layout as text, one fact per line.
    pub fn to_text(&self) -> String {
        let mut t = format!(
            "tiles_per_task {}\ngrid {} {} {} {}\n",
            self.tiles_per_task, self.grid_lo.0, self.grid_lo.1, self.grid_hi.0, self.grid_hi.1
        );
        for r in &self.bucket_tasks {
            t.push_str(&format!("bucket_task {} {}\n", r.start, r.end));
        }
        t
    }

    /// Parses [`TaskLayout::to_text`].
    pub fn parse(text: &str) -> Option<Self> {
        let mut per = None;
        let mut grid = None;
        let mut bucket_tasks = Vec::new();
        for line in text.lines() {
            let w: Vec<&str> = line.split_whitespace().collect();
            match w.as_slice() {
                ["tiles_per_task", n] => per = n.parse().ok(),
                ["grid", a, b, c, d] => {
                    grid = Some((
                        (a.parse().ok()?, b.parse().ok()?),
                        (c.parse().ok()?, d.parse().ok()?),
                    ))
                }
                ["bucket_task", a, b] => bucket_tasks.push(a.parse().ok()?..b.parse().ok()?),
                _ => return None,
            }
        }
        let (lo, hi): (TileKey, TileKey) = grid?;
        // The file is read back by every task: a grid upside down (which `clamp` in
        // [`Self::task_of`] would panic on) or too wide for its width to be computed, or an
        // input range backwards, is damage.
        let spans = hi.0.checked_sub(lo.0).zip(hi.1.checked_sub(lo.1));
        if spans.is_none_or(|(w, h)| w < 0 || h < 0) || bucket_tasks.iter().any(|r| r.start > r.end)
        {
            return None;
        }
        Some(TaskLayout {
            bucket_tasks,
            grid_lo: lo,
            grid_hi: hi,
            tiles_per_task: per.filter(|&n| n > 0)?,
        })
    }
}

/// Task indices in Slurm `--array=` syntax: `3,7-9` (sorted, ranges merged); empty for none.
pub fn array_syntax(tasks: &[u64]) -> String {
    let mut v = tasks.to_vec();
    v.sort_unstable();
    v.dedup();
    let mut parts = Vec::new();
    let mut i = 0;
    while i < v.len() {
        let mut j = i;
        while j + 1 < v.len() && v[j + 1] == v[j] + 1 {
            j += 1;
        }
        parts.push(if i == j {
            v[i].to_string()
        } else {
            format!("{}-{}", v[i], v[j])
        });
        i = j + 1;
    }
    parts.join(",")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tasks_cover_the_grid_once_and_clamp_strays() {
        let l = TaskLayout::new(vec![0..1, 1..2], (-2, 3), (2, 5), Some(4));
        assert_eq!((l.grid_tiles(), l.tile_tasks()), (15, 4));
        let mut per_task = vec![0; 4];
        for y in 3..=5 {
            for x in -2..=2 {
                per_task[l.task_of((x, y)) as usize] += 1;
            }
        }
        assert_eq!(per_task, [4, 4, 4, 3]);
        // Keys outside the planned grid go to the task of the nearest grid tile.
        assert_eq!(l.task_of((-100, -100)), l.task_of((-2, 3)));
        assert_eq!(l.task_of((9, 9)), 3);
        assert_eq!(TaskLayout::parse(&l.to_text()), Some(l));
        // The default keeps a large grid within 1000 tasks.
        let big = TaskLayout::single(1);
        let big = TaskLayout::new(big.bucket_tasks, (0, 0), (99, 99), None);
        assert_eq!((big.tiles_per_task, big.tile_tasks()), (10, 1000));
        assert!(TaskLayout::parse("tiles_per_task 0\ngrid 0 0 1 1\n").is_none());
    }

    #[test]
    fn slurm_array_syntax() {
        assert_eq!(array_syntax(&[9, 3, 7, 8, 3]), "3,7-9");
        assert_eq!(array_syntax(&[0, 1, 2, 5]), "0-2,5");
        assert_eq!(array_syntax(&[]), "");
    }

    #[test]
    fn a_damaged_layout_is_refused_not_panicked_on() {
        let good = "tiles_per_task 2\ngrid -2 3 2 5\nbucket_task 0 1\n";
        assert!(TaskLayout::parse(good).is_some());
        for bad in [
            "tiles_per_task 2\ngrid 2 3 -2 5\n",
            "tiles_per_task 2\ngrid -2 5 2 3\n",
            "tiles_per_task 2\ngrid -9223372036854775808 0 9223372036854775807 0\n",
            "tiles_per_task 2\ngrid 0 0 0 0\nbucket_task 3 1\n",
        ] {
            assert_eq!(TaskLayout::parse(bad), None, "{bad}");
        }
    }
}
