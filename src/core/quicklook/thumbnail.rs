//! A raster reduced to a thumbnail while its rows stream past: each thumbnail pixel is the
//! mean of the defined cells of a square block of `factor` x `factor` cells (the blocks of the
//! last column and row are cut by the raster's edge). It holds the thumbnail and one row of
//! accumulators, whatever the raster's size.

use super::Grid;

/// The default bound on the thumbnail's long side, in pixels: detailed on a screen, a PNG of a
/// few megabytes at most.
pub const DEFAULT_MAX_SIDE: u32 = 1600;

/// The least block factor that brings the long side of a `width` x `height` raster within
/// `max_side` pixels (at least 1).
fn fit_factor(width: u32, height: u32, max_side: u32) -> u32 {
    width.max(height).div_ceil(max_side.max(1)).max(1)
}

/// A thumbnail being built from the rows of a north-up raster (see the module doc).
#[derive(Debug, Clone)]
pub struct Thumbnail {
    width: u32,
    height: u32,
    factor: u32,
    out_width: u32,
    out_height: u32,
    /// The raster row expected next (rows arrive in order).
    next_row: u32,
    /// The thumbnail row the accumulators hold.
    block_row: u32,
    sums: Vec<f64>,
    counts: Vec<u32>,
    values: Vec<f32>,
}

impl Thumbnail {
    /// A thumbnail of a `width` x `height` raster whose long side is at most `max_side` pixels
    /// (at least 1): the block factor is the smallest integer that fits it, 1 for a raster that
    /// already does.
    pub fn new(width: u32, height: u32, max_side: u32) -> Thumbnail {
        Thumbnail::with_factor(width, height, fit_factor(width, height, max_side))
    }

    /// [`Thumbnail::new`] of a raster of `points` points, its factor raised where the points
    /// are sparser than the cells: so that a block holds a point with a probability of at
    /// least 99.5% where the points are spread evenly over the raster (`exp(-l b^2) <= 0.005`,
    /// `l` the points a cell: `b >= sqrt(5.3 / l)`). A raster of cells finer than the points'
    /// spacing then shows as a picture, not as scattered cells among no-data. `l` is taken
    /// over the whole raster, so a survey that fills a part of it gets larger blocks than it
    /// needs; where there is a point a cell or more, nothing changes.
    pub fn for_points(width: u32, height: u32, max_side: u32, points: u64) -> Thumbnail {
        let fit = fit_factor(width, height, max_side);
        let per_cell = points as f64 / (width as f64 * height as f64).max(1.0);
        let sparse = (5.3 / per_cell.max(1e-12))
            .sqrt()
            .ceil()
            .min(width.max(height) as f64);
        Thumbnail::with_factor(width, height, fit.max(sparse as u32).max(1))
    }

    /// A thumbnail of blocks of `factor` x `factor` cells (at least 1).
    fn with_factor(width: u32, height: u32, factor: u32) -> Thumbnail {
        let out_width = width.div_ceil(factor);
        let out_height = height.div_ceil(factor);
        Thumbnail {
            width,
            height,
            factor,
            out_width,
            out_height,
            next_row: 0,
            block_row: 0,
            sums: vec![0.0; out_width as usize],
            counts: vec![0; out_width as usize],
            values: vec![f32::NAN; out_width as usize * out_height as usize],
        }
    }

    /// Raster cells per thumbnail pixel along each axis: a thumbnail pixel is `factor` times
    /// the raster's cell size (the `cell` of [`super::Shade::of`]).
    pub fn factor(&self) -> u32 {
        self.factor
    }

    /// Adds whole rows of the raster, `rows.len() / width` of them starting at raster row
    /// `first_row`, row-major, NaN (or any non-finite value) for no data. Rows arrive in order;
    /// skipped rows count as no data, rows past the raster's height and a trailing partial row
    /// are ignored.
    ///
    /// # Panics
    /// If `first_row` is before a row already added: the caller's order is broken, and the
    /// blocks of earlier rows are already final.
    pub fn push_rows(&mut self, first_row: u32, rows: &[f32]) {
        assert!(
            first_row >= self.next_row,
            "thumbnail rows out of order: row {first_row} after row {}",
            self.next_row
        );
        if self.width == 0 {
            return;
        }
        for (i, row) in rows.chunks_exact(self.width as usize).enumerate() {
            let Some(r) = u32::try_from(i).ok().and_then(|i| first_row.checked_add(i)) else {
                break;
            };
            if r >= self.height {
                break;
            }
            let block = r / self.factor;
            if block != self.block_row {
                self.flush();
                self.block_row = block;
            }
            let blocks = row.chunks(self.factor as usize);
            for ((cells, sum), count) in blocks.zip(&mut self.sums).zip(&mut self.counts) {
                for &v in cells.iter().filter(|v| v.is_finite()) {
                    *sum += f64::from(v);
                    *count += 1;
                }
            }
            self.next_row = r + 1;
        }
    }

    /// Writes the accumulated block row into the thumbnail and clears the accumulators.
    fn flush(&mut self) {
        if self.block_row >= self.out_height {
            return;
        }
        let start = self.block_row as usize * self.out_width as usize;
        let out = &mut self.values[start..start + self.out_width as usize];
        for ((v, sum), count) in out.iter_mut().zip(&mut self.sums).zip(&mut self.counts) {
            if *count > 0 {
                *v = (*sum / f64::from(*count)) as f32;
            }
            *sum = 0.0;
            *count = 0;
        }
    }

    /// The thumbnail: rows never added are no data.
    pub fn finish(mut self) -> Grid {
        self.flush();
        Grid {
            width: self.out_width,
            height: self.out_height,
            values: self.values,
        }
    }
}
