//! Writing a quick look ([`crate::core::quicklook::Picture`]) as a PNG: RGBA, 8 bits per
//! channel, encoded in memory by the `png` crate and written durably (a temporary name, then a
//! rename), so a reader never sees half a picture.

use std::path::Path;

use crate::core::quicklook::Picture;
use crate::error::{Error, Result};
use crate::io::durable::write_durably;

/// Writes `picture` to `path` as an RGBA PNG, replacing any file there only once it is whole.
pub(crate) fn write_png(path: &Path, picture: &Picture) -> Result<()> {
    let bytes = encode(picture).map_err(|e| Error::write(path, e))?;
    write_durably(path, &bytes)
}

/// The PNG file of `picture`. The only failures are a picture whose pixel count does not
/// match its size or one too large for PNG: a bug upstream, reported as invalid data.
fn encode(picture: &Picture) -> std::io::Result<Vec<u8>> {
    let invalid = |e: png::EncodingError| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!(
                "cannot encode a {}x{} picture as PNG: {e}",
                picture.width, picture.height
            ),
        )
    };
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, picture.width, picture.height);
    encoder.set_color(png::ColorType::Rgba);
    encoder.set_depth(png::BitDepth::Eight);
    // A quick look is written once per raster and read by eye: the fastest compression (the
    // Up filter and fdeflate) costs a fraction of the default's time; against `Fast` (every
    // filter tried on every row) it takes 50M instructions fewer over the eight pictures of a
    // 2M-point terrain at 1 m, for files 6% larger.
    encoder.set_compression(png::Compression::Fastest);
    let mut writer = encoder.write_header().map_err(invalid)?;
    writer.write_image_data(&picture.rgba).map_err(invalid)?;
    writer.finish().map_err(invalid)?;
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The picture read back by the `png` crate's decoder: size, colour type and pixels.
    fn read_back(path: &Path) -> (u32, u32, png::ColorType, Vec<u8>) {
        let file = std::fs::File::open(path).expect("written");
        let decoder = png::Decoder::new(std::io::BufReader::new(file));
        let mut reader = decoder.read_info().expect("a PNG header");
        let mut pixels = vec![0; reader.output_buffer_size().expect("a size")];
        let info = reader.next_frame(&mut pixels).expect("a frame");
        pixels.truncate(info.buffer_size());
        (info.width, info.height, info.color_type, pixels)
    }

    #[test]
    fn a_picture_reads_back_pixel_for_pixel() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("H.png");
        let rgba: Vec<u8> = (0..3 * 2 * 4).map(|i| (i * 37 % 256) as u8).collect();
        let picture = Picture {
            width: 3,
            height: 2,
            rgba: rgba.clone(),
        };
        write_png(&path, &picture).expect("written");
        assert_eq!(read_back(&path), (3, 2, png::ColorType::Rgba, rgba));
        let names: Vec<_> = std::fs::read_dir(dir.path()).expect("dir").collect();
        assert_eq!(names.len(), 1, "no temporary file is left behind");
    }

    #[test]
    fn failures_name_the_file_and_leave_nothing() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("missing").join("H.png");
        let picture = Picture {
            width: 1,
            height: 1,
            rgba: vec![0; 4],
        };
        let e = write_png(&path, &picture).expect_err("no such directory");
        assert!(matches!(e, Error::WriteIo { .. }), "{e}");
        assert!(
            e.to_string().contains("missing/") && e.to_string().contains("H.png"),
            "{e}"
        );
        let path = dir.path().join("H.png");
        let short = Picture {
            width: 2,
            height: 2,
            rgba: vec![0; 4],
        };
        let e = write_png(&path, &short).expect_err("too few pixels");
        assert!(e.to_string().contains("2x2"), "{e}");
        assert_eq!(std::fs::read_dir(dir.path()).expect("dir").count(), 0);
    }

    /// A synthetic survey, `width` x `height` cells of `cell` m: a dome, a bowl and a saddle
    /// on a gentle tilt with ripples, a lake and the corner outside the survey as no data, a
    /// few spikes; the elevations, the mean curvature (convex positive, from the Laplacian by
    /// central differences) and the slope in degrees, row by row from the north.
    fn terrain(width: u32, height: u32, cell: f64, row: u32) -> [Vec<f32>; 3] {
        let z = |x: f64, y: f64| {
            let bump = |cx: f64, cy: f64, s: f64| {
                (-((x - cx).powi(2) + (y - cy).powi(2)) / (2.0 * s * s)).exp()
            };
            0.02 * x + 60.0 * bump(450.0, 500.0, 120.0) - 40.0 * bump(1100.0, 350.0, 100.0)
                + 4e-4 * ((x - 1050.0).powi(2) - (y - 750.0).powi(2)) * bump(1050.0, 750.0, 170.0)
                + 0.05 * (x / 14.0).sin() * (y / 19.0).cos()
        };
        let y = f64::from(height - row) * cell;
        let mut out = [Vec::new(), Vec::new(), Vec::new()];
        for col in 0..width {
            let x = f64::from(col) * cell;
            let h = 0.5;
            let (zc, ze, zw, zn, zs) =
                (z(x, y), z(x + h, y), z(x - h, y), z(x, y + h), z(x, y - h));
            let laplacian = (ze + zw + zn + zs - 4.0 * zc) / (h * h);
            let (gx, gy) = ((ze - zw) / (2.0 * h), (zn - zs) / (2.0 * h));
            let slope = gx.hypot(gy).atan().to_degrees();
            let lake = (x - 300.0).powi(2) + (y - 150.0).powi(2) < 60.0f64.powi(2);
            let outside = x + (1000.0 - y) > 2300.0;
            // A scattered one cell in 4096 (a hash, so no pattern shows).
            let hash = (u64::from(col) << 32 | u64::from(row)).wrapping_mul(0x9e37_79b9_7f4a_7c15);
            let spike = hash >> 52 == 0;
            let (elev, mean, slope) = match (lake || outside, spike) {
                (true, _) => (f64::NAN, f64::NAN, f64::NAN),
                (false, true) => (zc, if col % 2 == 0 { 3.0 } else { -3.0 }, slope),
                (false, false) => (zc, -laplacian / 2.0, slope),
            };
            for (o, v) in out.iter_mut().zip([elev, mean, slope]) {
                o.push(v as f32);
            }
        }
        out
    }

    /// Renders the synthetic survey's quick looks to /tmp/quicklook_*.png, streamed through
    /// thumbnails as the raster stage does, for a person to look at:
    /// `cargo test --lib quicklook_png -- --ignored`.
    #[test]
    #[ignore = "writes pictures to /tmp for a person to look at"]
    fn look_at_the_synthetic_survey() {
        use crate::core::quicklook::{render, Legend, Ramp, Shade, Thumbnail, DEFAULT_MAX_SIDE};
        let (width, height, cell) = (3_000, 2_000, 0.5);
        let mut thumbs: [Thumbnail; 3] =
            std::array::from_fn(|_| Thumbnail::new(width, height, DEFAULT_MAX_SIDE));
        let mut strip = [Vec::new(), Vec::new(), Vec::new()];
        for row in 0..height {
            for (s, v) in strip.iter_mut().zip(terrain(width, height, cell, row)) {
                s.extend(v);
            }
            if row % 64 == 63 || row + 1 == height {
                let first = row + 1 - (strip[0].len() as u32 / width);
                for (t, s) in thumbs.iter_mut().zip(&mut strip) {
                    t.push_rows(first, s);
                    s.clear();
                }
            }
        }
        let factor = thumbs[0].factor();
        let [elevation, mean, slope] = thumbs.map(Thumbnail::finish);
        let shade = Shade::of(&elevation, cell * f64::from(factor));
        let legend = |title, unit| Legend {
            title,
            unit,
            clip_percentile: 98.0,
            fixed: None,
            statistic: "cell mean of the points",
        };
        let looks = [
            (
                "mean_curvature",
                render(
                    &mean,
                    Ramp::Diverging,
                    &legend("MeanCurvature", "1/m"),
                    Some(&shade),
                ),
            ),
            (
                "slope",
                render(
                    &slope,
                    Ramp::Sequential,
                    &legend("Slope", "degrees"),
                    Some(&shade),
                ),
            ),
            (
                "unshaded",
                render(
                    &mean,
                    Ramp::Diverging,
                    &legend("MeanCurvature", "1/m"),
                    None,
                ),
            ),
        ];
        for (name, picture) in looks {
            write_png(Path::new(&format!("/tmp/quicklook_{name}.png")), &picture).expect("written");
        }
        let small = crate::core::quicklook::Grid {
            width: 40,
            height: 25,
            values: (0..1000)
                .map(|i| ((i % 40) as f32 - 20.0) * 1e-4 * ((i / 40) as f32 - 12.0))
                .collect(),
        };
        let none = crate::core::quicklook::Grid {
            width: 30,
            height: 20,
            values: vec![f32::NAN; 600],
        };
        let tiny = render(&small, Ramp::Diverging, &legend("ShapeIndex", ""), None);
        write_png(Path::new("/tmp/quicklook_small.png"), &tiny).expect("written");
        let empty = render(
            &none,
            Ramp::Sequential,
            &legend("PointCount", "points"),
            None,
        );
        write_png(Path::new("/tmp/quicklook_empty.png"), &empty).expect("written");
    }
}
