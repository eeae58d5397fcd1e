//! Quick looks: a raster reduced to a thumbnail while its rows stream past ([`Thumbnail`]),
//! coloured with a ramp that reads at a glance, optionally over a hillshade ([`Shade`]), beside
//! a legend naming the column, its unit and the range of its values ([`render`]). The result is
//! RGBA pixels in memory; writing the PNG is `io`'s job. Pure: no file, no thread.
//!
//! The colours: a diverging ramp (blue, white at 0, red for positive = convex) for signed
//! quantities, clipped at ±(a percentile of |value|), a sequential ramp (dark violet to
//! light yellow, lightness rising evenly) for unsigned ones, clipped between two percentiles,
//! and a cyclic one (a wheel of hues) for directions; a quantity with natural bounds (shape
//! index) may keep them instead of percentiles.
//! Percentiles are exact: selected from a copy of the thumbnail's defined values (a few
//! million at most), interpolating between ranks. Values beyond the clip limits saturate, and
//! no data is transparent.

mod canvas;
mod colour;
mod font;
mod legend;
mod shade;
mod thumbnail;

pub use shade::{Shade, SUN_ALTITUDE_DEG, SUN_AZIMUTH_DEG};
pub use thumbnail::{Thumbnail, DEFAULT_MAX_SIDE};

use colour::Stretch;

/// The default clip percentile: 2% of the values saturate, so a few spikes do not wash the
/// rest of the picture out.
pub const DEFAULT_CLIP_PERCENTILE: f64 = 98.0;

/// Maps smaller than this on their long side are magnified by a whole factor (each value a
/// square of pixels) so that a small raster is not a speck beside its legend.
const MIN_MAP_SIDE: u32 = 480;

/// A north-up raster of values, row-major, NaN for no data.
#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// `width * height` values, row by row from the north.
    pub values: Vec<f32>,
}

impl Grid {
    /// The value at column `col`, row `row`; NaN outside the grid.
    pub fn get(&self, col: i64, row: i64) -> f32 {
        if col < 0 || row < 0 || col >= i64::from(self.width) || row >= i64::from(self.height) {
            return f32::NAN;
        }
        let i = row as usize * self.width as usize + col as usize;
        self.values.get(i).copied().unwrap_or(f32::NAN)
    }
}

/// The colour ramp of a quick look.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ramp {
    /// For signed quantities (curvatures): blue for negative, white at 0, red for positive,
    /// symmetric around 0 and clipped at ±(the clip percentile of |value|).
    Diverging,
    /// For unsigned quantities (slope, curvedness, counts): dark violet to light yellow,
    /// clipped between the `100 - clip` and `clip` percentiles.
    Sequential,
    /// For directions in degrees (aspect): a wheel of hues at one lightness over 0 to 360,
    /// whose ends meet, so that north reads alike on both sides of 0.
    Cyclic,
}

/// What the legend says.
#[derive(Debug, Clone, Copy)]
pub struct Legend<'a> {
    /// The quantity's name (the raster's column name, `ProfileCurvature`).
    pub title: &'a str,
    /// Its unit (`1/m`, `degrees`); empty for a dimensionless one. Both are drawn in printable
    /// ASCII: any other character shows as `?`.
    pub unit: &'a str,
    /// The clip percentile ([`DEFAULT_CLIP_PERCENTILE`] by default): of |value| for a
    /// diverging ramp (0 to 100), the upper one for a sequential ramp (50 to 100, the lower
    /// being 100 minus it). Out of range it is bounded; NaN means the default.
    pub clip_percentile: f64,
    /// A fixed scale (low, high) instead of the percentiles, for quantities with natural bounds
    /// (shape index -1 to 1); a cyclic ramp always spans 0 to 360.
    pub fixed: Option<(f64, f64)>,
    /// How a cell's value was formed ("cell mean"), a line of its own; empty for none.
    pub statistic: &'a str,
}

/// An RGBA image, 8 bits per channel, row-major from the top, not premultiplied.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Picture {
    /// Pixels across.
    pub width: u32,
    /// Pixels down.
    pub height: u32,
    /// `width * height * 4` bytes: red, green, blue, alpha.
    pub rgba: Vec<u8>,
}

/// The quick look of `values`: the map coloured with `ramp` (no data transparent, its edge
/// outlined in grey so that holes read on a white page too), shaded by `shade` if given, and
/// the legend panel to its right. A map under 480 pixels on its long side is magnified by a
/// whole factor, each value a square of pixels; the legend's text grows with the map. A
/// `shade` on a grid of another size than `values` is a caller's mistake and is left out.
pub fn render(values: &Grid, ramp: Ramp, legend: &Legend<'_>, shade: Option<&Shade>) -> Picture {
    let stretch = Stretch::of(values, ramp, legend.clip_percentile, legend.fixed);
    let lut = colour::lut(ramp);
    let shading = shade
        .filter(|s| {
            debug_assert_eq!((s.width, s.height), (values.width, values.height));
            (s.width, s.height) == (values.width, values.height)
        })
        .map(|s| s.levels.as_slice());
    let long = values.width.max(values.height).max(1);
    let magnify = (MIN_MAP_SIDE / long).max(1);
    let (map_w, map_h) = (values.width * magnify, values.height * magnify);
    let any_missing = values.values.iter().any(|v| !v.is_finite())
        || values.values.len() < values.width as usize * values.height as usize;
    let notes = legend::Notes {
        stretch: &stretch,
        shaded: shading.is_some(),
        any_missing,
    };
    // The legend grows with the map, so that it stays legible when the picture is shrunk to fit
    // a screen: a font pixel is 2 image pixels beside maps under 1200 pixels, 4 from 1600.
    let scale = (map_w.max(map_h) / 400).clamp(2, 4);
    let panel = legend::Panel::new(legend, &notes, scale);
    let mut picture = Picture::blank(map_w + panel.width(), map_h.max(panel.height()));
    let paint = Paint {
        stretch: &stretch,
        lut: &lut,
        shading,
        magnify,
    };
    paint.map(&mut picture, values);
    picture.outline_transparent(map_w, map_h, scale / 2, NO_DATA_EDGE);
    panel.draw(&mut picture, map_w, &lut);
    picture
}

/// The grey of the edge of no data on the map.
const NO_DATA_EDGE: canvas::Rgba = [96, 96, 96, 255];

/// How the map's pixels are coloured.
struct Paint<'a> {
    stretch: &'a Stretch,
    lut: &'a [colour::Rgb],
    /// The hillshade of each value, 0 to 1.
    shading: Option<&'a [f32]>,
    /// Image pixels per value along each axis.
    magnify: u32,
}

impl Paint<'_> {
    /// Paints `values` from the picture's top left corner; no data stays transparent.
    fn map(&self, picture: &mut Picture, values: &Grid) {
        let level = 0.6 + 0.4 * shade::level_ground();
        let width = values.width as usize;
        for row in 0..values.height {
            // The row's values as one slice (a value looked up by column and row checked both
            // against the grid every time); NaN past the grid's values, as `Grid::get` reads.
            let from = (row as usize * width).min(values.values.len());
            let row_values = &values.values[from..];
            for col in 0..values.width {
                let v = row_values.get(col as usize).copied().unwrap_or(f32::NAN);
                let Some(u) = self.stretch.position(v) else {
                    continue;
                };
                let mut rgb = colour::at(self.lut, u);
                if let Some(s) = self.shading {
                    // Multiplied, not replaced, and at most by 40%, so the colours still read;
                    // divided by the factor of flat ground so that level terrain keeps the
                    // legend's colours exactly (0 stays white), sunlit slopes a little lighter.
                    let i = row as usize * values.width as usize + col as usize;
                    let k = (0.6 + 0.4 * s[i]) / level;
                    // Rounded half up by truncation (the products are not negative): the
                    // library's `round` was a third of the quick looks' time.
                    rgb = rgb.map(|c| (f32::from(c) * k + 0.5).min(255.0) as u8);
                }
                let (x, y, m) = (col * self.magnify, row * self.magnify, self.magnify);
                picture.fill(x, y, m, m, [rgb[0], rgb[1], rgb[2], 255]);
            }
        }
    }
}

#[cfg(test)]
mod tests;
