//! One GeoTIFF being written: float32 cells in strips, Deflate-compressed, the no-data value
//! declared (GDAL_NODATA), the band's name and unit in GDAL's metadata (QGIS and rasterio show
//! them), georeferenced by a tie point at the grid's north-west corner and the cell size
//! (PixelIsArea), with the CRS's GeoTIFF keys. The file is laid out by the `tiff`
//! crate (image-rs: maintained, pure Rust, arbitrary tags, BigTIFF) and the strips compressed
//! by `flate2`, on a thread of its own
//! that takes strips as they are filled, so that the compression of several rasters runs in
//! parallel and a raster is never whole in memory. Written under a temporary name and renamed
//! when complete.

use std::io::{BufWriter, Seek, Write};
use std::path::{Path, PathBuf};
use std::thread::JoinHandle;

use crossbeam_channel::{bounded, Sender};
use flate2::write::ZlibEncoder;
use tiff::encoder::{TiffEncoder, TiffKind};
use tiff::tags::Tag;

use crate::core::raster::CellGrid;
use crate::error::{Error, Result};
use crate::io::durable::TempFile;
use crate::io::raster::geokeys::RasterCrs;
use crate::io::raster::sidecar::xml_text;

/// The value of a cell without data: the most negative f32, as GDAL writes float rasters.
pub(crate) const NO_DATA: f32 = f32::MIN;

/// Uncompressed size past which a raster is written as BigTIFF (a classic TIFF's offsets end
/// at 4 GiB; compression may not shrink it).
const BIG: u64 = 3 << 30;

/// Strips a writer may have waiting.
const QUEUE: usize = 2;

/// ModelPixelScaleTag, ModelTiepointTag, GeoKeyDirectoryTag, GeoDoubleParamsTag,
/// GeoAsciiParamsTag, GDAL_METADATA, GDAL_NODATA.
const PIXEL_SCALE: u16 = 33550;
const TIEPOINT: u16 = 33922;
const KEY_DIRECTORY: u16 = 34735;
const DOUBLE_PARAMS: u16 = 34736;
const ASCII_PARAMS: u16 = 34737;
const GDAL_METADATA: u16 = 42112;
const GDAL_NODATA: u16 = 42113;

/// GDAL's metadata of a band named `name` whose values are in `unit` (none if empty): its
/// description and unit type, as GDAL writes them.
fn gdal_metadata(name: &str, unit: &str) -> String {
    let item = |key: &str, role: &str, v: &str| {
        format!(
            "<Item name=\"{key}\" sample=\"0\" role=\"{role}\">{}</Item>",
            xml_text(v)
        )
    };
    let mut m = format!("<GDALMetadata>{}", item("DESCRIPTION", "description", name));
    if !unit.is_empty() {
        m.push_str(&item("UNITTYPE", "unittype", unit));
    }
    m + "</GDALMetadata>"
}

/// Rows per strip for rasters `width` cells wide: strips of about 256 KiB.
pub(crate) fn rows_per_strip(width: u32) -> u32 {
    ((1u32 << 16) / width.max(1)).clamp(1, 1024)
}

/// A GeoTIFF being written.
pub(crate) struct GeoTiff {
    path: PathBuf,
    strips: Option<Sender<Vec<f32>>>,
    writer: Option<JoinHandle<Result<()>>>,
}

impl GeoTiff {
    /// Starts writing `path` for `grid` in `crs`, its band named `name` and in `unit` (`band`).
    pub(crate) fn create(
        path: &Path,
        grid: &CellGrid,
        crs: &RasterCrs,
        (name, unit): (&str, &str),
    ) -> Result<GeoTiff> {
        let (tmp, file) = TempFile::create(path)?;
        let (tx, rx) = bounded::<Vec<f32>>(QUEUE);
        let (grid, crs) = (*grid, crs.clone());
        let meta = gdal_metadata(name, unit);
        let big = grid.width as u64 * grid.height as u64 * 4 > BIG;
        let writer = std::thread::Builder::new()
            .name("geotiff".into())
            .spawn(move || {
                let mut w = BufWriter::with_capacity(1 << 20, &file);
                let strips = rx.iter();
                let written = match big {
                    true => encode(TiffEncoder::new_big(&mut w), (&grid, &crs, &meta), strips),
                    false => encode(TiffEncoder::new(&mut w), (&grid, &crs, &meta), strips),
                };
                written
                    .and_then(|()| w.flush())
                    .map_err(|e| tmp.error(e))?;
                drop(w);
                tmp.commit(file)
            })
            .map_err(|e| Error::Resource(format!("cannot start a thread to write {}: {e}; lower --threads or raise the limits on processes (ulimit -u) or memory (ulimit -v)", path.display())))?;
        Ok(GeoTiff {
            path: path.to_path_buf(),
            strips: Some(tx),
            writer: Some(writer),
        })
    }

    /// Hands over the next strip: [`rows_per_strip`] rows (fewer for the last), row by row,
    /// NaN where a cell has no data.
    pub(crate) fn strip(&self, rows: Vec<f32>) -> Result<()> {
        match &self.strips {
            Some(tx) if tx.send(rows).is_ok() => Ok(()),
            // The writer stopped: its error is reported by finish.
            _ => Ok(()),
        }
    }

    /// Waits for the last strip to be written and the file renamed into place.
    pub(crate) fn finish(mut self) -> Result<()> {
        drop(self.strips.take());
        match self.writer.take().map(JoinHandle::join) {
            Some(Ok(r)) => r,
            Some(Err(p)) => std::panic::resume_unwind(p),
            None => Err(Error::Internal(format!(
                "{} finished twice",
                self.path.display()
            ))),
        }
    }
}

impl Drop for GeoTiff {
    /// An unfinished raster (an error elsewhere) is abandoned: the writer sees the end of its
    /// strips, fails on the missing rows, and its temporary file is removed.
    fn drop(&mut self) {
        drop(self.strips.take());
        if let Some(w) = self.writer.take() {
            let _ = w.join();
        }
    }
}

/// Writes the image of `grid` from `strips` (NaN as [`NO_DATA`]) with its georeferencing in
/// `crs` and GDAL's metadata `meta`.
/// The strips are compressed here (zlib, TIFF's Deflate, compression 8): the `tiff` crate's
/// strip-by-strip writer (0.11) writes strips as given while declaring the compression.
fn encode<W: Write + Seek, K: TiffKind>(
    encoder: tiff::TiffResult<TiffEncoder<W, K>>,
    (grid, crs, meta): (&CellGrid, &RasterCrs, &str),
    strips: impl Iterator<Item = Vec<f32>>,
) -> std::io::Result<()> {
    let mut encoder = encoder.map_err(tiff_err)?;
    let mut dir = encoder.image_directory().map_err(tiff_err)?;
    let (mut offsets, mut counts) = (Vec::new(), Vec::new());
    let mut rows = 0u64;
    let (mut raw, mut packed) = (Vec::new(), Vec::new());
    for strip in strips {
        rows += strip.len() as u64 / grid.width as u64;
        raw.clear();
        for v in strip {
            let v = if v.is_nan() { NO_DATA } else { v };
            raw.extend_from_slice(&v.to_le_bytes());
        }
        // One write of the whole strip: the encoder prepares its output per write.
        let mut z = ZlibEncoder::new(std::mem::take(&mut packed), flate2::Compression::fast());
        z.write_all(&raw)?;
        packed = z.finish()?;
        let at = dir.write_data(&packed[..]).map_err(tiff_err)?;
        offsets.push(K::convert_offset(at).map_err(tiff_err)?);
        counts.push(K::convert_offset(packed.len() as u64).map_err(tiff_err)?);
        packed.clear();
    }
    if rows != grid.height as u64 {
        return Err(std::io::Error::other(
            "the raster ended before its last row",
        ));
    }
    let (west, north) = grid.corner();
    let tag = |t| Tag::Unknown(t);
    let mut put = || -> tiff::TiffResult<()> {
        dir.write_tag(Tag::ImageWidth, grid.width)?;
        dir.write_tag(Tag::ImageLength, grid.height)?;
        dir.write_tag(Tag::BitsPerSample, 32u16)?;
        dir.write_tag(Tag::Compression, 8u16)?;
        dir.write_tag(Tag::PhotometricInterpretation, 1u16)?;
        dir.write_tag(Tag::StripOffsets, K::convert_slice(&offsets))?;
        dir.write_tag(Tag::SamplesPerPixel, 1u16)?;
        dir.write_tag(Tag::RowsPerStrip, rows_per_strip(grid.width))?;
        dir.write_tag(Tag::StripByteCounts, K::convert_slice(&counts))?;
        dir.write_tag(Tag::PlanarConfiguration, 1u16)?;
        dir.write_tag(Tag::SampleFormat, 3u16)?;
        dir.write_tag(tag(PIXEL_SCALE), &[grid.cell, grid.cell, 0.0][..])?;
        dir.write_tag(tag(TIEPOINT), &[0.0, 0.0, 0.0, west, north, 0.0][..])?;
        if !crs.directory.is_empty() {
            dir.write_tag(tag(KEY_DIRECTORY), &crs.directory[..])?;
        }
        if !crs.doubles.is_empty() {
            dir.write_tag(tag(DOUBLE_PARAMS), &crs.doubles[..])?;
        }
        if !crs.ascii.is_empty() {
            dir.write_tag(tag(ASCII_PARAMS), crs.ascii.as_str())?;
        }
        dir.write_tag(tag(GDAL_METADATA), meta)?;
        dir.write_tag(tag(GDAL_NODATA), format!("{:e}", NO_DATA as f64).as_str())
    };
    put().map_err(tiff_err)?;
    dir.finish().map_err(tiff_err)
}

/// A `tiff` error as an io error (the file's write error names the file).
fn tiff_err(e: tiff::TiffError) -> std::io::Error {
    match e {
        tiff::TiffError::IoError(e) => e,
        e => std::io::Error::other(e.to_string()),
    }
}
