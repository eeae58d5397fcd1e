//! The rasters being written: the strips of every raster filled cell by cell in row order and
//! handed to their GeoTIFF writers, with a thumbnail of each kept for its quick look, and the
//! quick-look PNGs drawn from those thumbnails.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use crate::core::quicklook::{
    render, Grid, Legend, Ramp, Shade, Thumbnail, DEFAULT_CLIP_PERCENTILE, DEFAULT_MAX_SIDE,
};
use crate::core::raster::CellGrid;
use crate::error::{Error, Result};
use crate::io::quicklook_png::write_png;

use super::geotiff::{rows_per_strip, GeoTiff};
use super::RasterColumn;

/// Writes a PNG quick look of each raster of `columns` from its thumbnail (`looks`: one per
/// column, then the elevation's, whose pixels are `pixel` CRS units wide), shaded by the
/// elevation; returns the files.
pub(super) fn quick_looks(
    dir: &Path,
    columns: &[(RasterColumn, String)],
    mut looks: Vec<Grid>,
    pixel: f64,
) -> Result<Vec<PathBuf>> {
    let Some(elevation) = looks.pop() else {
        return Ok(Vec::new());
    };
    let shade = Shade::of(&elevation, pixel);
    let mut files = Vec::new();
    for ((c, statistic), g) in columns.iter().zip(&looks) {
        let ramp = match (c.angle, c.signed) {
            (true, _) => Ramp::Cyclic,
            (false, true) => Ramp::Diverging,
            (false, false) => Ramp::Sequential,
        };
        let legend = Legend {
            title: &c.name,
            unit: &c.unit,
            clip_percentile: DEFAULT_CLIP_PERCENTILE,
            fixed: c.scale,
            statistic,
        };
        let path = dir.join(format!("{}.png", c.name));
        write_png(&path, &render(g, ramp, &legend, Some(&shade)))?;
        files.push(path);
    }
    Ok(files)
}

/// The strips of every raster being filled, cell by cell in row order.
pub(super) struct Rows<'a> {
    width: usize,
    height: u32,
    per_strip: u32,
    /// The first row of the strips being filled.
    first: u32,
    strips: Vec<Vec<f32>>,
    /// The GeoTIFFs of the first strips (the last strip, the elevation, has none).
    writers: Vec<GeoTiff>,
    /// A quick-look thumbnail of every strip's raster.
    thumbs: Vec<Thumbnail>,
    /// Set to stop: checked at every strip, since rows without a point come between cells.
    cancel: &'a AtomicBool,
}

impl<'a> Rows<'a> {
    /// The rows of `writers`' rasters of `grid` (and of one more, without a file: the
    /// elevation), whose thumbnails suit `points` points.
    pub(super) fn new(
        grid: &CellGrid,
        (writers, points): (Vec<GeoTiff>, u64),
        cancel: &'a AtomicBool,
    ) -> Rows<'a> {
        let mut r = Rows {
            cancel,
            width: grid.width as usize,
            height: grid.height,
            per_strip: rows_per_strip(grid.width),
            first: 0,
            strips: Vec::new(),
            thumbs: (0..=writers.len())
                .map(|_| Thumbnail::for_points(grid.width, grid.height, DEFAULT_MAX_SIDE, points))
                .collect(),
            writers,
        };
        r.strips = (0..r.thumbs.len()).map(|_| r.blank(0)).collect();
        r
    }

    /// Cells of the strip starting at row `first`, all without data.
    fn blank(&self, first: u32) -> Vec<f32> {
        let rows = self.per_strip.min(self.height.saturating_sub(first)) as usize;
        vec![f32::NAN; rows * self.width]
    }

    /// Sets the cell at `row`, `col` of every raster (rows never go back).
    pub(super) fn put(&mut self, row: u32, col: u32, values: &[f32]) -> Result<()> {
        while row >= self.first + self.per_strip {
            self.flush()?;
        }
        let at = (row - self.first) as usize * self.width + col as usize;
        for (s, &v) in self.strips.iter_mut().zip(values) {
            s[at] = v;
        }
        Ok(())
    }

    /// Hands the full strips to their writers and starts the next ones.
    fn flush(&mut self) -> Result<()> {
        if self.cancel.load(Ordering::Relaxed) {
            return Err(Error::Interrupted);
        }
        let next = self.first + self.per_strip;
        for i in 0..self.strips.len() {
            let blank = self.blank(next);
            let strip = std::mem::replace(&mut self.strips[i], blank);
            self.thumbs[i].push_rows(self.first, &strip);
            if let Some(w) = self.writers.get(i) {
                w.strip(strip)?;
            }
        }
        self.first = next;
        Ok(())
    }

    /// Writes the remaining strips and waits for every raster to be complete. Returns the
    /// thumbnails and how many cells a side each of their pixels covers.
    pub(super) fn finish(mut self) -> Result<(Vec<Grid>, u32)> {
        while self.first < self.height {
            self.flush()?;
        }
        for w in self.writers {
            w.finish()?;
        }
        let factor = self.thumbs.first().map_or(1, Thumbnail::factor);
        Ok((
            self.thumbs.into_iter().map(Thumbnail::finish).collect(),
            factor,
        ))
    }
}
