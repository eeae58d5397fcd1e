//! The cells of the integer columns: each cell's [`Tally`] of every such column kept in a hash
//! table as its points arrive, so that no point is stored or sorted (a raster of a column of
//! integers: tilecurv's scaled columns, by default). Past the memory budget the table's cells
//! go to sorted run files ([`Bins`] of the tallies' words) and the table starts again; at the
//! end the partial tallies of a cell are merged, exactly, whatever the budget. The cells come
//! back in key order, as the point bins' do.

use std::path::Path;

use super::bins::{from_words, words_of, Bins, Cells};
use crate::core::radix::sort_by_key;
#[cfg(test)]
use crate::core::raster::UNDEFINED;
use crate::core::raster::{Cell, Stat, Tally, MAX_CELL_POINTS};
use crate::error::{Error, Result};

/// The key of an empty slot: no block has it (a key's row and column stay below 2^32 - 1).
const EMPTY: u64 = u64::MAX;

/// Words of a tally in a run file: the sum's low and high halves, and the count.
const TALLY_WORDS: usize = 3;

/// Cells a side of a block: the table holds blocks of 16 x 16 cells, so that the points of a
/// scan line, which cross a cell every few points, find their cells in the block of the last
/// point (looked up once for 16 cells), and their tallies side by side in memory. Cells one
/// at a time, the lookups and tallies scattered over the table cost a third of the rasters.
const SIDE_BITS: u32 = 4;
const SIDE: u64 = 1 << SIDE_BITS;
pub(super) const BLOCK: usize = 1 << (2 * SIDE_BITS);

/// The key of the block of the cell `key` (its row and column, each divided by [`SIDE`]).
fn block_of(key: u64) -> u64 {
    let (row, col) = (key >> 32, key & 0xffff_ffff);
    (row >> SIDE_BITS) << 32 | col >> SIDE_BITS
}

/// The place of the cell `key` in its block: row then column within the block.
fn within(key: u64) -> usize {
    (((key >> 32) & (SIDE - 1)) << SIDE_BITS | (key & (SIDE - 1))) as usize
}

/// The tallies of the cells seen so far.
pub(crate) struct CellSums {
    /// The statistic of the columns but the last, whose tally is a mean (the elevation).
    stat: Stat,
    /// Tallies a cell: the columns, then the elevation.
    columns: usize,
    /// Open addressing with linear probing: the key of a block and its index, or [`EMPTY`].
    slots: Vec<(u64, u32)>,
    /// Per block of the table, by index: its key.
    blocks: Vec<u64>,
    /// Per cell of each block ([`BLOCK`] a block, by [`within`]): its points, its tallies (a
    /// column each).
    points: Vec<u32>,
    tallies: Vec<Tally>,
    /// Blocks the table holds before it spills.
    capacity: usize,
    /// The block the last point went to.
    last: Option<(u64, u32)>,
    /// The spilled cells, a record each: its points, then each tally's words.
    runs: Bins,
    spilled: bool,
}

/// Bytes a block of cells of `columns` tallies takes in the table: its key and slots (at most
/// a quarter full after they double), its cells' points and tallies, and their place in the
/// list of cells in key order that a spill or the end makes.
pub(super) fn block_bytes(columns: usize) -> usize {
    let slots = 4 * std::mem::size_of::<(u64, u32)>();
    let cell = 4 + std::mem::size_of::<Tally>() * columns + std::mem::size_of::<(u64, u32)>();
    8 + slots + BLOCK * cell
}

/// Makes room in `v` for `add` more items, doubling its capacity but to at most `cap` items
/// (the budget's): a table that fills its share does not take twice it.
fn room<T>(v: &mut Vec<T>, add: usize, cap: usize) {
    let need = v.len() + add;
    if need > v.capacity() {
        let want = (2 * v.capacity()).clamp(need, cap.max(need));
        v.reserve_exact(want - v.len());
    }
}

impl CellSums {
    /// Tallies by `stat` of `columns - 1` columns, then a mean of one more (the elevation),
    /// keeping at most `budget` bytes in memory; spilled cells go to run files in `dir`. Half
    /// the budget is the table's (whose vectors, while they grow, briefly hold their old
    /// items beside the new), a quarter the spilled cells' on their way to a run file.
    pub(crate) fn new(dir: &Path, stat: Stat, columns: usize, budget: u64) -> CellSums {
        let table = budget as usize / 2;
        let capacity = (table / block_bytes(columns)).clamp(4, u32::MAX as usize / BLOCK / 2);
        let words = 1 + TALLY_WORDS * columns;
        CellSums {
            runs: Bins::new(dir, "cells", words, budget / 4, 0),
            stat,
            columns,
            slots: vec![(EMPTY, 0); 16],
            blocks: Vec::new(),
            points: Vec::new(),
            tallies: Vec::new(),
            capacity,
            last: None,
            spilled: false,
        }
    }

    /// Adds a point of the cell `key` whose oriented integers are `raws`, a column each
    /// ([`crate::core::raster::UNDEFINED`] where it has none). `what` names the cell in the error when it would
    /// hold more points than a tally does.
    pub(crate) fn add(&mut self, key: u64, raws: &[i64], what: &dyn Fn() -> String) -> Result<()> {
        let b = block_of(key);
        let block = match self.last {
            Some((k, i)) if k == b => i,
            _ => self.block(b)?,
        };
        self.last = Some((b, block));
        let i = block as usize * BLOCK + within(key);
        if self.points[i] >= MAX_CELL_POINTS {
            return Err(too_many(format!("the cell of {}", what())));
        }
        self.points[i] += 1;
        let n = self.columns;
        let (tallies, z) = self.tallies[i * n..(i + 1) * n].split_at_mut(n - 1);
        let (raws, z_raw) = raws.split_at(n - 1);
        self.stat.add_all(tallies, raws);
        Stat::Mean.add_all(z, z_raw);
        Ok(())
    }

    /// The index of the block `key` in the table, added if new (after a spill when full).
    fn block(&mut self, key: u64) -> Result<u32> {
        if let Some(i) = self.find(key) {
            return Ok(i);
        }
        if self.blocks.len() >= self.capacity {
            self.spill()?;
        }
        if 2 * (self.blocks.len() + 1) > self.slots.len() {
            self.grow();
        }
        let i = self.blocks.len() as u32;
        self.place(key, i);
        self.blocks.push(key);
        let n = self.columns;
        room(&mut self.points, BLOCK, self.capacity * BLOCK);
        room(&mut self.tallies, BLOCK * n, self.capacity * BLOCK * n);
        self.points.resize(self.points.len() + BLOCK, 0);
        let empty: Vec<Tally> = self.stats().into_iter().map(Stat::empty).collect();
        for _ in 0..BLOCK {
            self.tallies.extend_from_slice(&empty);
        }
        Ok(i)
    }

    fn find(&self, key: u64) -> Option<u32> {
        let mask = self.slots.len() - 1;
        let mut h = hash(key, mask);
        loop {
            match self.slots[h] {
                (k, i) if k == key => return Some(i),
                (EMPTY, _) => return None,
                _ => h = (h + 1) & mask,
            }
        }
    }

    /// Puts the block `key` of index `i` in the first free slot from its own.
    fn place(&mut self, key: u64, i: u32) {
        let mask = self.slots.len() - 1;
        let mut h = hash(key, mask);
        while self.slots[h].0 != EMPTY {
            h = (h + 1) & mask;
        }
        self.slots[h] = (key, i);
    }

    /// Doubles the slots and places every block again.
    fn grow(&mut self) {
        self.slots = vec![(EMPTY, 0); 2 * self.slots.len()];
        for i in 0..self.blocks.len() {
            self.place(self.blocks[i], i as u32);
        }
    }

    /// The table's cells that hold points, in key order: (key, index in `points`). Row by
    /// row of cells: the blocks sorted by key, and for each row of blocks, each row of cells
    /// across its blocks.
    fn sorted(&self) -> Vec<(u64, u32)> {
        let mut blocks: Vec<(u64, u32)> = (self.blocks.iter().enumerate())
            .map(|(i, &k)| (k, i as u32))
            .collect();
        sort_by_key(&mut blocks, &mut Vec::new());
        let mut cells = Vec::new();
        for row in blocks.chunk_by(|a, b| a.0 >> 32 == b.0 >> 32) {
            for r in 0..SIDE {
                for &(key, b) in row {
                    let first_row = (key >> 32) << SIDE_BITS | r;
                    let first_col = (key & 0xffff_ffff) << SIDE_BITS;
                    let at = b as usize * BLOCK + (r << SIDE_BITS) as usize;
                    for c in 0..SIDE {
                        let i = at + c as usize;
                        if self.points[i] > 0 {
                            cells.push((first_row << 32 | (first_col + c), i as u32));
                        }
                    }
                }
            }
        }
        cells
    }

    /// Writes the table's cells to a run file in key order and empties the table.
    fn spill(&mut self) -> Result<()> {
        let n = self.columns;
        let mut words = Vec::with_capacity(1 + TALLY_WORDS * n);
        for (key, i) in self.sorted() {
            let i = i as usize;
            words.clear();
            words.push(self.points[i]);
            for t in &self.tallies[i * n..(i + 1) * n] {
                words.extend(words_of(t.acc));
                words.push(t.count);
            }
            self.runs.push(key, &words)?;
        }
        self.runs.spill()?;
        self.slots.fill((EMPTY, 0));
        self.blocks.clear();
        self.points.clear();
        self.tallies.clear();
        self.last = None;
        self.spilled = true;
        Ok(())
    }

    fn stats(&self) -> Vec<Stat> {
        tally_stats(self.stat, self.columns)
    }

    /// The cells in key order with their merged tallies.
    pub(crate) fn into_cells(mut self) -> Result<SumCells> {
        let stats = self.stats();
        if !self.spilled {
            let order = self.sorted();
            return Ok(SumCells {
                stats,
                source: Source::Table {
                    order,
                    next: 0,
                    sums: self,
                },
            });
        }
        self.spill()?;
        Ok(SumCells {
            stats,
            source: Source::Runs {
                cells: self.runs.into_cells()?,
                words: Vec::new(),
            },
        })
    }
}

/// The slot of `key` in a table of `mask + 1` slots (a power of two): the top bits of a
/// multiplicative hash, which spreads the neighbouring cells of a row.
fn hash(key: u64, mask: usize) -> usize {
    let bits = mask.count_ones();
    (key.wrapping_mul(0x9e37_79b9_7f4a_7c15) >> (64 - bits)) as usize & mask
}

/// Each tally's statistic for `columns` tallies: `stat` for the columns, then the mean of the
/// last one (the elevation, which shades the quick looks).
pub(super) fn tally_stats(stat: Stat, columns: usize) -> Vec<Stat> {
    let each = (1..columns).map(|_| stat);
    each.chain([Stat::Mean]).collect()
}

/// The error of a cell with more points than a tally counts: `cell` names it.
fn too_many(cell: String) -> Error {
    Error::Usage(format!(
        "{cell} holds more than {MAX_CELL_POINTS} points, more than a cell's tally counts; use a smaller --cell"
    ))
}

/// [`too_many`] for the cell `key`, named by its indices.
pub(super) fn too_many_in(key: u64) -> Error {
    let c = Cell::from_key(key);
    too_many(format!(
        "the cell ({}, {}) (floor(x / cell), floor(y / cell))",
        c.ix, c.iy
    ))
}

enum Source {
    Table {
        sums: CellSums,
        order: Vec<(u64, u32)>,
        next: usize,
    },
    Runs {
        cells: Cells,
        /// A cell's records, word by word.
        words: Vec<Vec<u32>>,
    },
}

/// The cells of [`CellSums`] in key order.
pub(crate) struct SumCells {
    stats: Vec<Stat>,
    source: Source,
}

impl SumCells {
    /// The next cell's key and points, its tallies in `out` (a column each); None after the
    /// last cell.
    pub(crate) fn next_cell(&mut self, out: &mut [Tally]) -> Result<Option<(u64, u32)>> {
        let n = self.stats.len();
        match &mut self.source {
            Source::Table { sums, order, next } => {
                let Some(&(key, i)) = order.get(*next) else {
                    return Ok(None);
                };
                *next += 1;
                let i = i as usize;
                out.copy_from_slice(&sums.tallies[i * n..(i + 1) * n]);
                Ok(Some((key, sums.points[i])))
            }
            Source::Runs { cells, words } => {
                let Some(key) = cells.next_cell(words)? else {
                    return Ok(None);
                };
                let points: u64 = words[0].iter().map(|&p| u64::from(p)).sum();
                if points > u64::from(MAX_CELL_POINTS) {
                    return Err(too_many_in(key));
                }
                for (j, (t, &stat)) in out.iter_mut().zip(&self.stats).enumerate() {
                    *t = stat.empty();
                    let w = |k: usize| &words[1 + TALLY_WORDS * j + k];
                    for ((&lo, &hi), &count) in w(0).iter().zip(w(1)).zip(w(2)) {
                        let acc = from_words(lo, hi);
                        stat.merge(t, Tally { acc, count });
                    }
                }
                Ok(Some((key, points as u32)))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Tallies through the table alone and through spilled runs are each cell's sum (for the
    /// mean and the count), least or greatest integer and count of defined integers, as
    /// computed from all the cell's integers at once; the last column is always a mean.
    #[test]
    fn tallies_are_the_cells_whether_or_not_they_spill() {
        let tmp = tempfile::tempdir().expect("temp dir");
        let n = 60_000u64;
        // Point p in one of 2003 cells over 43 rows, with integers that grow past 32 bits when
        // summed, undefined for every fifth point in column 1.
        let point = |p: u64| {
            let raw =
                |c: u64| ((p * 2_654_435_761 + c * 97) % 4_000_000_000) as i64 - 2_000_000_000;
            let raws: Vec<i64> = (0..4)
                .map(|c| {
                    if c == 1 && p.is_multiple_of(5) {
                        UNDEFINED
                    } else {
                        raw(c)
                    }
                })
                .collect();
            let cell = (p * 7919) % 2003;
            ((cell / 47) << 32 | (cell % 47), raws)
        };
        let mut cells = std::collections::BTreeMap::<u64, Vec<Vec<i64>>>::new();
        for p in 0..n {
            let (key, raws) = point(p);
            cells.entry(key).or_default().push(raws);
        }
        for stat in [Stat::Mean, Stat::Min, Stat::Max, Stat::Count] {
            let want: Vec<(u64, (u32, Vec<Tally>))> = (cells.iter())
                .map(|(&key, points)| {
                    let tallies = (0..4)
                        .map(|c| {
                            let v: Vec<i64> = (points.iter().map(|r| r[c]))
                                .filter(|&r| r != UNDEFINED)
                                .collect();
                            let acc = match (stat, c) {
                                (Stat::Min, 0..3) => *v.iter().min().expect("some"),
                                (Stat::Max, 0..3) => *v.iter().max().expect("some"),
                                _ => v.iter().map(|&r| r as i128).sum::<i128>() as i64,
                            };
                            Tally {
                                acc,
                                count: v.len() as u32,
                            }
                        })
                        .collect();
                    (key, (points.len() as u32, tallies))
                })
                .collect();
            for (budget, spills) in [(1u64 << 30, false), (40_000, true)] {
                let dir = tmp.path().join(format!("s{budget}{stat}"));
                let mut sums = CellSums::new(&dir, stat, 4, budget);
                for p in 0..n {
                    let (key, raws) = point(p);
                    sums.add(key, &raws, &|| "test".into()).expect("add");
                }
                assert_eq!(sums.spilled, spills);
                let mut cells = sums.into_cells().expect("cells");
                let mut out = vec![Stat::Mean.empty(); 4];
                let mut got = Vec::new();
                while let Some((key, points)) = cells.next_cell(&mut out).expect("cell") {
                    got.push((key, (points, out.clone())));
                }
                assert!(got == want, "{stat}, budget {budget}");
                drop(cells);
                assert!(!dir.exists(), "run files removed");
            }
        }
    }
}
