//! How a run is split into tasks that a scheduler (a Slurm job array, AWS Batch, a Kubernetes
//! Indexed Job) runs independently: bucket tasks (each scans a range of points of one or more
//! inputs) and tile tasks (each computes the tiles of a range of the tile grid). Pure: the
//! layout is decided by `plan` from the inputs' sizes and bounds, stored as text in the work
//! directory, and read back by every task. How a run is split never changes its output.

use std::ops::Range;

use crate::core::plan::TileKey;

/// Points per bucket task that `plan` aims at by default: a 1e10-point file scans as 200
/// tasks (a few hundred, and within Slurm's default MaxArraySize up to 5e10 points), a
/// 1e9-point file as 20, while a delivered survey tile (1-30M points) stays one task. LAZ
/// decodes at about 1M points/s a core (measured on the project's 2-core machine), so a task
/// of 50M points is about a minute on one core: long enough that starting a task is
/// negligible, short enough that a retried one costs little.
pub const DEFAULT_POINTS_PER_SCAN_TASK: u64 = 50_000_000;

/// Part of a bucket task: the points `points` (indices in the file, end excluded) of input
/// `input` (command-line order).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ScanRange {
    /// The input's index.
    pub input: usize,
    /// Its points scanned by the task.
    pub points: Range<u64>,
}

/// Where an input's points may be split between bucket tasks.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Cuts {
    /// Before any point (fixed-length records read in place: uncompressed LAS).
    Anywhere,
    /// Only before these points (LAZ chunk starts, ascending); none: the input is one task.
    At(Vec<u64>),
}

/// Splits the points `0..len` of one input into ranges of about `per_task` points (the last
/// ones within one cut of it), cut only where `cuts` allows: `ceil(len / per_task)` ranges of
/// equal size where any cut is allowed, else the allowed cut nearest each equal share's end
/// (so a range may hold more than `per_task` points when the cuts are far apart). Never an
/// empty range; one range `0..len` for `len <= per_task`.
pub fn split_points(len: u64, per_task: u64, cuts: &Cuts) -> Vec<Range<u64>> {
    let n = len.div_ceil(per_task.max(1)).max(1);
    let mut ends: Vec<u64> = (1..n)
        .map(|i| (i as u128 * len as u128 / n as u128) as u64)
        .filter_map(|target| match cuts {
            Cuts::Anywhere => Some(target),
            Cuts::At(at) => nearest(at, target),
        })
        .filter(|&e| e > 0 && e < len)
        .collect();
    ends.dedup();
    ends.push(len);
    let mut start = 0;
    ends.into_iter()
        .map(|end| {
            let r = start..end;
            start = end;
            r
        })
        .collect()
}

/// The value of the ascending `at` nearest `target` (the lower one on a tie), None if empty.
fn nearest(at: &[u64], target: u64) -> Option<u64> {
    let i = at.partition_point(|&c| c < target);
    let above = at.get(i).copied();
    let below = i.checked_sub(1).map(|j| at[j]);
    match (below, above) {
        (Some(b), Some(a)) => Some(if target - b <= a - target { b } else { a }),
        (b, a) => b.or(a),
    }
}

/// The task layout of a run.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TaskLayout {
    /// Per bucket task, the points it scans: ranges of points of inputs, in scan order.
    pub bucket_tasks: Vec<Vec<ScanRange>>,
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
        bucket_tasks: Vec<Vec<ScanRange>>,
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

    /// The layout of `process`: one bucket task over every point of the inputs, which hold
    /// `lens` points each; every tile in one task.
    pub fn single(lens: &[u64]) -> Self {
        let all = lens
            .iter()
            .enumerate()
            .map(|(input, &n)| ScanRange {
                input,
                points: 0..n,
            })
            .collect();
        TaskLayout::new(vec![all], (0, 0), (0, 0), Some(1))
    }

    /// Whether the bucket tasks, in order, scan every point of inputs of `lens` points
    /// exactly once and in file order (as one task does): a layout that does not is damaged,
    /// since a point scanned twice or never would change the output.
    pub fn covers(&self, lens: &[u64]) -> bool {
        // The next point of each input to scan; inputs are scanned in command-line order.
        let mut next = vec![0u64; lens.len()];
        let mut current = 0;
        for r in self.bucket_tasks.iter().flatten() {
            let Some(&n) = lens.get(r.input) else {
                return false;
            };
            let (a, b) = (r.points.start, r.points.end);
            if r.input < current || a != next[r.input] || b <= a || b > n {
                return false;
            }
            current = r.input;
            next[r.input] = b;
        }
        next == lens
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

    /// The layout as text, one fact per line: a bucket task is a line of
    /// `input:first..end` ranges of points (`bucket_task 0:0..25000000`).
    pub fn to_text(&self) -> String {
        let mut t = format!(
            "tiles_per_task {}\ngrid {} {} {} {}\n",
            self.tiles_per_task, self.grid_lo.0, self.grid_lo.1, self.grid_hi.0, self.grid_hi.1
        );
        for task in &self.bucket_tasks {
            t.push_str("bucket_task");
            for r in task {
                t.push_str(&format!(
                    " {}:{}..{}",
                    r.input, r.points.start, r.points.end
                ));
            }
            t.push('\n');
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
                ["bucket_task", ranges @ ..] => bucket_tasks.push(
                    ranges
                        .iter()
                        .map(|r| parse_range(r))
                        .collect::<Option<Vec<_>>>()?,
                ),
                _ => return None,
            }
        }
        let (lo, hi): (TileKey, TileKey) = grid?;
        // The file is read back by every task: a grid upside down (which `clamp` in
        // [`Self::task_of`] would panic on) or too wide for its width to be computed, or a
        // bucket task scanning nothing, is damage.
        let spans = hi.0.checked_sub(lo.0).zip(hi.1.checked_sub(lo.1));
        if spans.is_none_or(|(w, h)| w < 0 || h < 0) || bucket_tasks.iter().any(Vec::is_empty) {
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

/// Parses `input:first..end`; None for anything else or a range backwards.
fn parse_range(text: &str) -> Option<ScanRange> {
    let (input, points) = text.split_once(':')?;
    let (a, b) = points.split_once("..")?;
    let points = a.parse().ok()?..b.parse().ok()?;
    (points.start <= points.end).then_some(ScanRange {
        input: input.parse().ok()?,
        points,
    })
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

    /// One bucket task per input, each whole: inputs of `lens` points.
    fn per_input(lens: &[u64]) -> Vec<Vec<ScanRange>> {
        let r = |input, n| ScanRange {
            input,
            points: 0..n,
        };
        lens.iter()
            .enumerate()
            .map(|(i, &n)| vec![r(i, n)])
            .collect()
    }

    #[test]
    fn tasks_cover_the_grid_once_and_clamp_strays() {
        let l = TaskLayout::new(per_input(&[5, 7]), (-2, 3), (2, 5), Some(4));
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
        let big = TaskLayout::single(&[1]);
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
        let good = "tiles_per_task 2\ngrid -2 3 2 5\nbucket_task 0:0..10\n";
        assert!(TaskLayout::parse(good).is_some());
        for bad in [
            "tiles_per_task 2\ngrid 2 3 -2 5\n",
            "tiles_per_task 2\ngrid -2 5 2 3\n",
            "tiles_per_task 2\ngrid -9223372036854775808 0 9223372036854775807 0\n",
            "tiles_per_task 2\ngrid 0 0 0 0\nbucket_task 0:3..1\n",
            "tiles_per_task 2\ngrid 0 0 0 0\nbucket_task\n",
            "tiles_per_task 2\ngrid 0 0 0 0\nbucket_task 0:0-5\n",
            // The layout of a tilecurv before split scans (a range of whole inputs).
            "tiles_per_task 2\ngrid 0 0 0 0\nbucket_task 0 1\n",
        ] {
            assert_eq!(TaskLayout::parse(bad), None, "{bad}");
        }
    }

    #[test]
    fn split_layout_round_trips_through_its_text() {
        let r = |input, points| ScanRange { input, points };
        let tasks = vec![
            vec![r(0, 0..40), r(1, 0..7)],
            vec![r(2, 0..3_000_000_000)],
            vec![r(2, 3_000_000_000..10_000_000_000)],
        ];
        let l = TaskLayout::new(tasks, (0, 0), (3, 3), Some(2));
        let text = l.to_text();
        assert!(text.contains("\nbucket_task 0:0..40 1:0..7\n"), "{text}");
        assert!(
            text.ends_with("\nbucket_task 2:3000000000..10000000000\n"),
            "{text}"
        );
        assert_eq!(TaskLayout::parse(&text), Some(l.clone()));
        assert!(l.covers(&[40, 7, 10_000_000_000]));
        // A point scanned twice, never, out of order, or past the input's end.
        for lens in [
            [40, 7, 10_000_000_001],
            [40, 8, 10_000_000_000],
            [39, 7, 10_000_000_000],
        ] {
            assert!(!l.covers(&lens), "{lens:?}");
        }
        let mut overlap = l.clone();
        overlap.bucket_tasks[2][0].points.start -= 1;
        let mut backwards = l.clone();
        backwards.bucket_tasks.swap(1, 2);
        let mut reordered = l.clone();
        reordered.bucket_tasks[0].swap(0, 1);
        for bad in [overlap, backwards, reordered] {
            assert!(!bad.covers(&[40, 7, 10_000_000_000]), "{}", bad.to_text());
        }
        assert!(TaskLayout::single(&[5, 9]).covers(&[5, 9]));
    }

    #[test]
    fn splitting_arithmetic() {
        // Anywhere: ceil(len / per) ranges, ends at floor(i * len / n).
        assert_eq!(
            split_points(10, 3, &Cuts::Anywhere),
            [0..2, 2..5, 5..7, 7..10]
        );
        assert_eq!(split_points(10, 10, &Cuts::Anywhere), vec![0..10]);
        // LAZ chunks of 50 points: shares end near 76.7 and 153.3; the nearest chunk starts
        // are 100 (24 away, 50 is 26) and 150.
        let chunks = [0, 50, 100, 150, 200];
        assert_eq!(
            split_points(230, 100, &Cuts::At(chunks.to_vec())),
            [0..100, 100..150, 150..230]
        );
        // Two cuts nearest the same chunk start give one range, never an empty one.
        assert_eq!(
            split_points(230, 10, &Cuts::At(vec![0, 200])),
            [0..200, 200..230]
        );
        // No cut allowed: one task.
        assert_eq!(split_points(1_000, 10, &Cuts::At(vec![])), vec![0..1_000]);
        // The default: a 1e10-point file in 200 tasks of 5e7, a survey tile in one.
        let huge = split_points(
            10_000_000_000,
            DEFAULT_POINTS_PER_SCAN_TASK,
            &Cuts::Anywhere,
        );
        assert_eq!(huge.len(), 200);
        assert!(huge.iter().all(|r| r.end - r.start == 50_000_000));
        assert_eq!(
            split_points(30_000_000, DEFAULT_POINTS_PER_SCAN_TASK, &Cuts::Anywhere).len(),
            1
        );
    }
}
