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
        if (w, h) == (1, 1) {
            // One pixel (a map's value at 480 pixels or more): set directly, without slicing
            // rows, which was most of painting a map.
            if x < self.width && y < self.height {
                let i = (y as usize * self.width as usize + x as usize) * 4;
                self.rgba[i..i + 4].copy_from_slice(&colour);
            }
            return;
        }
        let (from, to) = (
            x.min(self.width) as usize,
            x.saturating_add(w).min(self.width),
        );
        let width = self.width as usize;
        for row in y..y.saturating_add(h).min(self.height) {
            let start = row as usize * width;
            let pixels = &mut self.rgba[(start + from) * 4..(start + to as usize) * 4];
            for p in pixels.chunks_exact_mut(4) {
                p.copy_from_slice(&colour);
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
        // The rectangle's transparency as one flag a pixel, read once: looking up each
        // neighbour's alpha in the picture took most of a quick look's rendering.
        let mut clear = Vec::with_capacity(w * h);
        for row in self.rgba.chunks_exact(stride * 4).take(h) {
            clear.extend(row.chunks_exact(4).take(w).map(|p| p[3] == 0));
        }
        let reach = reach as usize;
        let mut edge = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                if clear[i] {
                    continue;
                }
                let mut touches = false;
                for d in 1..reach + 1 {
                    touches = (x >= d && clear[i - d])
                        || (x + d < w && clear[i + d])
                        || (y >= d && clear[i - d * w])
                        || (y + d < h && clear[i + d * w]);
                    if touches {
                        break;
                    }
                }
                if touches {
                    edge.push((y * stride + x) * 4);
                }
            }
        }
        for i in edge {
            self.rgba[i..i + 4].copy_from_slice(&colour);
        }
    }
}
