//! Drawing on a [`Picture`]: filled rectangles and text in the module's bitmap font. Whatever
//! falls outside the picture is clipped, so layout arithmetic cannot index out of bounds.

use super::font::{self, ADVANCE, GLYPH_H, GLYPH_W};
use super::Picture;

/// An RGBA colour.
pub(super) type Rgba = [u8; 4];

impl Picture {
    /// A transparent picture.
    pub(super) fn blank(width: u32, height: u32) -> Picture {
        Picture {
            width,
            height,
            rgba: vec![0; width as usize * height as usize * 4],
        }
    }

    /// Fills the rectangle at (`x`, `y`) of `w` x `h` pixels with `colour`.
    pub(super) fn fill(&mut self, x: u32, y: u32, w: u32, h: u32, colour: Rgba) {
        let x_end = x.saturating_add(w).min(self.width);
        for row in y..y.saturating_add(h).min(self.height) {
            for col in x..x_end {
                let i = (row as usize * self.width as usize + col as usize) * 4;
                self.rgba[i..i + 4].copy_from_slice(&colour);
            }
        }
    }

    /// The outline of the rectangle at (`x`, `y`) of `w` x `h` pixels, one pixel wide.
    pub(super) fn frame(&mut self, x: u32, y: u32, w: u32, h: u32, colour: Rgba) {
        self.fill(x, y, w, 1, colour);
        self.fill(x, y + h.saturating_sub(1), w, 1, colour);
        self.fill(x, y, 1, h, colour);
        self.fill(x + w.saturating_sub(1), y, 1, h, colour);
    }

    /// Draws `text` with the top of its cells at (`x`, `y`), each font pixel a square of
    /// `scale` pixels.
    pub(super) fn text(&mut self, x: u32, y: u32, text: &str, scale: u32, colour: Rgba) {
        for (i, c) in text.chars().enumerate() {
            let gx = x.saturating_add(i as u32 * ADVANCE * scale);
            for (r, bits) in font::glyph(c).iter().enumerate().take(GLYPH_H as usize) {
                for col in 0..GLYPH_W {
                    if bits & (1 << (GLYPH_W - 1 - col)) != 0 {
                        let px = gx.saturating_add(col * scale);
                        let py = y.saturating_add(r as u32 * scale);
                        self.fill(px, py, scale, scale, colour);
                    }
                }
            }
        }
    }

    /// Sets to `colour` every opaque pixel of the `w` x `h` rectangle at the top left that has
    /// a transparent one of it within `reach` pixels left, right, above or below: the edge of
    /// no data, `reach` pixels wide.
    pub(super) fn outline_transparent(&mut self, w: u32, h: u32, reach: u32, colour: Rgba) {
        let (w, h) = (w.min(self.width) as usize, h.min(self.height) as usize);
        let stride = self.width as usize;
        let clear = |x: usize, y: usize| self.rgba[(y * stride + x) * 4 + 3] == 0;
        let mut edge = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let touches = (1..=reach as usize).any(|d| {
                    (x >= d && clear(x - d, y))
                        || (x + d < w && clear(x + d, y))
                        || (y >= d && clear(x, y - d))
                        || (y + d < h && clear(x, y + d))
                });
                if !clear(x, y) && touches {
                    edge.push((y * stride + x) * 4);
                }
            }
        }
        for i in edge {
            self.rgba[i..i + 4].copy_from_slice(&colour);
        }
    }
}
