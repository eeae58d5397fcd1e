//! `tilecurv generate terrain`: synthetic aerial-LIDAR-like terrain of any size with closed-form
//! curvature, written as LAS 1.4 / LAZ (point format 1) with the true H, K, k1, k2 of every point
//! as f64 extra bytes `TrueH`, `TrueK`, `Truek1`, `Truek2`, so that the accuracy of `process` can
//! be checked on clouds as large as the engine must handle. `generate torus` and `generate
//! goursat` ([`shape`]) write the CNC paper's two test shapes in the same layout.
//!
//! The surface is [`terrain`]'s, the sampling plan (flight strips, scan rows, batches)
//! `flight`'s; this module is the command: options, the file's header and VLRs (`FileLayout`,
//! shared with [`shape`]), the record layout (`Record`), and the loop that generates batches
//! of rows in parallel and writes them in order.
//!
//! This module must not hold the cloud: it writes as it generates. It produces the records and
//! its own VLRs (GeoTIFF keys, the truth columns' descriptors); the file is written by the
//! library's one LAS/LAZ writer ([`LasFileWriter`]: header, LAZ, temporary file and rename).

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::io::las::header::{NewHeader, POINT_FORMAT_SIZES};
use crate::io::las::vlr::Vlr;
use crate::io::las::writer::{HeaderStart, LasFileSpec, LasFileWriter};

use flight::{generate_row, FlightPlan, IntBounds};
use terrain::Terrain;
use truth::truth_descriptors;
pub use truth::{Truth, MAX_TRUTH, TERRAIN_TRUTH_COLUMNS};

mod flight;
pub mod shape;
pub mod terrain;
mod truth;

pub use shape::{generate_shape, Shape, ShapeOptions, ShapeSummary};

/// Coordinate scale of the output (1 mm).
pub const SCALE_M: f64 = 0.001;
/// Easting and northing of the south-west corner of the generated square (UTM zone 10N, inside
/// the zone's valid range), and the header offsets of x and y.
pub const ORIGIN_M: [f64; 2] = [500_000.0, 4_100_000.0];
/// The header offsets of x, y and z.
const OFFSETS_M: [f64; 3] = [ORIGIN_M[0], ORIGIN_M[1], 0.0];
/// EPSG code of the CRS declared in the GeoTIFF keys (WGS 84 / UTM zone 10N, metres).
pub const EPSG: u16 = 32610;
/// Point data record format of the output (format 1: format 0 plus GPS time).
pub const POINT_FORMAT: u8 = 1;
/// Names of the truth columns, in record order.
pub const TRUTH_COLUMNS: [&str; 4] = ["TrueH", "TrueK", "Truek1", "Truek2"];

/// Bytes per output record: point format 1 plus the four f64 truth columns (without
/// `--terrain-truth`, whose columns add 8 bytes each: [`record_length`]).
pub const RECORD_LENGTH: usize = record_length(TRUTH_COLUMNS.len());

/// Bytes per record of a file with `truth` f64 truth columns.
pub const fn record_length(truth: usize) -> usize {
    POINT_FORMAT_SIZES[POINT_FORMAT as usize] as usize + 8 * truth
}

/// What `generate terrain` is asked for.
#[derive(Debug, Clone, PartialEq)]
pub struct TerrainOptions {
    /// Number of points to write.
    pub points: u64,
    /// Points per square metre (the square's area is points / density).
    pub density_per_m2: f64,
    /// Seed of the terrain and of the sampling.
    pub seed: u64,
    /// Gaussian noise added to z (the truth columns are those of the noise-free surface at
    /// the point's x, y).
    pub noise: Noise,
    /// Which truth columns the records carry.
    pub truth: Truth,
}

/// The standard deviation of the noise added to z, in metres: one value, or one for the west
/// half of the square and one for the east half (`--noise 0:0.05`: a survey clean on one side
/// and noisy on the other, which no single K suits: the case `-k auto` is for).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Noise {
    /// Sigma west of the square's middle (x < side / 2), metres.
    pub west_m: f64,
    /// Sigma east of it, metres.
    pub east_m: f64,
}

impl Noise {
    /// No noise.
    pub const NONE: Noise = Noise {
        west_m: 0.0,
        east_m: 0.0,
    };

    /// Parses `SIGMA` or `WEST:EAST` (metres, each 0 or more).
    pub fn parse(s: &str) -> std::result::Result<Noise, String> {
        let num = |t: &str| {
            t.trim()
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite() && *v >= 0.0)
                .ok_or_else(|| format!("--noise {s:?}: expected a standard deviation in metres, 0 or more (e.g. 0.02), or WEST:EAST for the two halves (e.g. 0:0.05)"))
        };
        match s.split_once(':') {
            Some((w, e)) => Ok(Noise {
                west_m: num(w)?,
                east_m: num(e)?,
            }),
            None => {
                let v = num(s)?;
                Ok(Noise {
                    west_m: v,
                    east_m: v,
                })
            }
        }
    }

    /// The sigma at `x` metres from the square's west edge, whose side is `side_m`.
    pub fn at(&self, x: f64, side_m: f64) -> f64 {
        if x < 0.5 * side_m {
            self.west_m
        } else {
            self.east_m
        }
    }
}

impl std::fmt::Display for Noise {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.west_m == self.east_m {
            write!(f, "{}", self.west_m)
        } else {
            write!(f, "{}:{}", self.west_m, self.east_m)
        }
    }
}

impl TerrainOptions {
    /// Checks the options, with a message saying what to change.
    pub fn validate(&self) -> Result<()> {
        if self.points == 0 {
            return Err(Error::Usage(
                "--points must be at least 1 (e.g. --points 2M)".into(),
            ));
        }
        if self.points > u64::from(u32::MAX) {
            return Err(Error::Usage(format!(
                "--points {}: a point format 1 file holds at most {} points (its legacy 32-bit count); generate several files with different --seed",
                self.points,
                u32::MAX
            )));
        }
        if !(self.density_per_m2.is_finite() && self.density_per_m2 > 0.0) {
            return Err(Error::Usage(format!(
                "--density {}: the density must be a positive number of points per square metre (aerial LIDAR: 1 to 100)",
                self.density_per_m2
            )));
        }
        for v in [self.noise.west_m, self.noise.east_m] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::Usage(format!(
                    "--noise {}: the noise must be a standard deviation in metres, 0 or more",
                    self.noise
                )));
            }
        }
        // The square's side in millimetres must fit the i32 coordinates of a LAS record.
        if self.side_m() / SCALE_M >= f64::from(i32::MAX) {
            return Err(Error::Usage(format!(
                "--points {} at --density {}: the square would be {:.0} km wide, more than LAS coordinates at 1 mm reach (2147 km); raise --density",
                self.points,
                self.density_per_m2,
                self.side_m() / 1000.0
            )));
        }
        Ok(())
    }

    /// Side of the generated square in metres: sqrt(points / density).
    pub fn side_m(&self) -> f64 {
        (self.points as f64 / self.density_per_m2).sqrt()
    }
}

/// What a finished generation reports.
#[derive(Debug, Clone, PartialEq)]
pub struct TerrainSummary {
    /// Points written.
    pub points: u64,
    /// Side of the square in metres.
    pub side_m: f64,
    /// Flight strips.
    pub strips: u64,
    /// Bumps in the terrain.
    pub bumps: usize,
    /// Smallest and largest elevation written, in metres.
    pub z_range_m: [f64; 2],
    /// Wall time in seconds.
    pub seconds: f64,
}

/// The GeoTIFF key directory of the projected CRS `epsg` (32767: user-defined) in metres: model
/// type projected, raster type pixel-is-area, ProjectedCSTypeGeoKey `epsg`, ProjLinearUnitsGeoKey
/// and VerticalUnitsGeoKey 9001 (metre), sorted by key id as GeoTIFF requires.
fn geotiff_keys(epsg: u16) -> Vec<u8> {
    let keys: [[u16; 4]; 5] = [
        [1024, 0, 1, 1],
        [1025, 0, 1, 1],
        [3072, 0, 1, epsg],
        [3076, 0, 1, 9001],
        [4099, 0, 1, 9001],
    ];
    let mut w = vec![1u16, 1, 0, keys.len() as u16];
    w.extend(keys.iter().flatten());
    w.iter().flat_map(|v| v.to_le_bytes()).collect()
}

/// The text of the provenance VLR: the options and the units of the truth columns.
fn provenance(opts: &TerrainOptions) -> String {
    format!(
        "tilecurv {} generate terrain\npoints={}\ndensity={}\nseed={}\nnoise={}\ntruth={}\nunits=metres; TrueH, Truek1, Truek2 in 1/m, TrueK in 1/m^2; upward normal, positive on hilltops\n",
        env!("CARGO_PKG_VERSION"),
        opts.points,
        opts.density_per_m2,
        opts.seed,
        opts.noise,
        opts.truth.name()
    )
}

/// Writes the terrain of `opts` to `output` (.las or .laz; the extension decides), checking
/// `cancel` between batches of rows. The output appears complete or not at all. The
/// coordinates are UTM zone 10N metres around [`ORIGIN_M`], at 1 mm resolution.
pub fn generate_terrain(
    opts: &TerrainOptions,
    output: &Path,
    cancel: &AtomicBool,
) -> Result<TerrainSummary> {
    let started = Instant::now();
    opts.validate()?;
    let layout = FileLayout {
        system: "SYNTHETIC TERRAIN",
        epsg: EPSG,
        scale: SCALE_M,
        offset: OFFSETS_M,
        points: opts.points,
        provenance: provenance(opts),
        truth: opts.truth,
    };
    let side_m = opts.side_m();
    let terrain = Terrain::new(side_m, opts.seed);
    let plan = FlightPlan::new(side_m, opts.points);
    let bounds = layout.write(output, |writer| {
        write_rows(&terrain, &plan, opts, writer, cancel)
    })?;
    Ok(TerrainSummary {
        points: opts.points,
        side_m,
        strips: plan.strips,
        bumps: terrain.bump_count(),
        z_range_m: [
            f64::from(bounds.lo[2]) * SCALE_M,
            f64::from(bounds.hi[2]) * SCALE_M,
        ],
        seconds: started.elapsed().as_secs_f64(),
    })
}

/// The header fields and VLRs of a generated file (terrain or shape): LAS 1.4 point format 1
/// with the truth columns, GeoTIFF keys in metres, the provenance text.
struct FileLayout<'a> {
    /// System identifier of the header.
    system: &'a str,
    /// ProjectedCSTypeGeoKey (32767: user-defined, metres).
    epsg: u16,
    /// Coordinate scale of x, y and z.
    scale: f64,
    /// Header offsets of x, y and z.
    offset: [f64; 3],
    /// Number of records the file will hold.
    points: u64,
    /// The provenance VLR's text.
    provenance: String,
    /// Which truth columns the records carry.
    truth: Truth,
}

impl FileLayout<'_> {
    /// Creates `output`, lets `fill` write every record and return their integer bounds, then
    /// sets the header's bounds and renames the file into place; on any error the temporary
    /// file is removed and nothing appears.
    fn write(
        &self,
        output: &Path,
        fill: impl FnOnce(&mut LasFileWriter) -> Result<IntBounds>,
    ) -> Result<IntBounds> {
        let software = format!("tilecurv {} generate", env!("CARGO_PKG_VERSION"));
        let record_length = record_length(self.truth.columns()) as u16;
        let geotiff = [Vlr::new(
            "LASF_Projection",
            34735,
            "GeoKeyDirectoryTag",
            geotiff_keys(self.epsg),
        )];
        // LAS 1.4 (375-byte header), so that PDAL shows the truth columns from the extra-bytes
        // VLR as it does for `process` outputs; the layout fields are the writer's. The bounds
        // are known only once every point is written: until `set_bounds` they are the offsets.
        let header = NewHeader {
            minor: 4,
            system: self.system,
            software: &software,
            point_format: POINT_FORMAT,
            record_length,
            points: self.points,
            scale: [self.scale; 3],
            offset: self.offset,
            min: self.offset,
            max: self.offset,
        };
        let spec = LasFileSpec {
            origin: None,
            header: HeaderStart::New(header),
            record_length,
            vlrs: &geotiff,
            evlrs: &[],
            extra_bytes: truth_descriptors(self.truth),
            provenance: &self.provenance,
        };
        let mut writer = LasFileWriter::create(output, spec)?;
        let bounds = match fill(&mut writer) {
            Ok(b) => b,
            Err(e) => {
                writer.abandon();
                return Err(e);
            }
        };
        let at = |a: usize, v: i32| self.offset[a] + f64::from(v) * self.scale;
        writer.set_bounds(
            [0, 1, 2].map(|a| at(a, bounds.lo[a])),
            [0, 1, 2].map(|a| at(a, bounds.hi[a])),
        );
        writer.finish()?;
        Ok(bounds)
    }
}

/// One generated record: point format 1 followed by the f64 truth columns
/// ([`record_length`] bytes).
#[derive(Debug, Clone, Copy)]
struct Record<'a> {
    /// Integer coordinates (the header's scale and offset).
    xyz: [i32; 3],
    /// Intensity.
    intensity: u16,
    /// Return number and count, scan direction, edge of flight line (LAS bit layout).
    return_bits: u8,
    /// Classification.
    class: u8,
    /// Scan angle rank in degrees.
    scan_angle: i8,
    /// Point source ID.
    source: u16,
    /// GPS time in seconds.
    gps: f64,
    /// TrueH, TrueK, Truek1, Truek2, then with `--terrain-truth` [`TERRAIN_TRUTH_COLUMNS`].
    truth: &'a [f64],
}

impl Record<'_> {
    /// Appends the record's bytes to `out`.
    fn encode(&self, out: &mut Vec<u8>) {
        for v in self.xyz {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&self.intensity.to_le_bytes());
        out.push(self.return_bits);
        out.push(self.class);
        out.push(self.scan_angle as u8);
        out.push(0); // user data
        out.extend_from_slice(&self.source.to_le_bytes());
        out.extend_from_slice(&self.gps.to_le_bytes());
        for v in self.truth.iter() {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
}

/// Generates the rows of `plan` in batches (in parallel within a batch) and writes them in
/// flight order, checking `cancel` between batches; returns the bounds of every record.
fn write_rows(
    terrain: &Terrain,
    plan: &FlightPlan,
    opts: &TerrainOptions,
    writer: &mut LasFileWriter,
    cancel: &AtomicBool,
) -> Result<IntBounds> {
    let mut bounds = IntBounds::empty();
    let cells = plan.cells();
    let mut c = 0u64;
    while c < cells {
        if cancel.load(Ordering::Relaxed) {
            return Err(Error::Interrupted);
        }
        let end = (c + plan.rows_per_batch()).min(cells);
        let rows: Vec<(Vec<u8>, IntBounds)> = (c..end)
            .into_par_iter()
            .map(|row| {
                let n = (plan.first_point(row + 1) - plan.first_point(row)) as usize;
                let mut buf = Vec::with_capacity(n * record_length(MAX_TRUTH));
                let b = generate_row(terrain, plan, opts, row, &mut buf);
                (buf, b)
            })
            .collect();
        for (buf, b) in &rows {
            bounds.merge(b);
            writer.write_records(buf)?;
        }
        c = end;
    }
    Ok(bounds)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::surface::HeightField;
    use crate::io::source::{LasSource, PointSource};

    /// `--noise 0:0.05`: the west half lies on the surface (to the 0.5 mm of the z
    /// quantisation), the east half is off it by Gaussian noise of sigma 5 cm (measured within
    /// 10%); the syntax and its errors.
    #[test]
    fn noise_can_differ_between_the_two_halves() {
        let noise = Noise::parse("0:0.05").expect("two halves");
        assert_eq!(
            (noise.west_m, noise.east_m, noise.to_string()),
            (0.0, 0.05, "0:0.05".into())
        );
        assert_eq!(Noise::parse("0.02").expect("one").to_string(), "0.02");
        assert!(Noise::parse("-1").is_err() && Noise::parse("0:x").is_err());
        let dir = tempfile::tempdir().expect("temp dir");
        let opts = TerrainOptions {
            points: 20_000,
            density_per_m2: 10.0,
            seed: 3,
            noise,
            truth: Truth::Curvature,
        };
        let out = dir.path().join("half.las");
        generate_terrain(&opts, &out, &AtomicBool::new(false)).expect("generates");
        let src = LasSource::open(&out).expect("reads back");
        let (side, terrain) = (opts.side_m(), Terrain::new(opts.side_m(), opts.seed));
        let (mut west_max, mut east) = (0f64, Vec::new());
        src.for_each_chunk(5_000, &mut |first, recs| {
            for (i, r) in recs.chunks_exact(RECORD_LENGTH).enumerate() {
                let p = src.decode(first + i as u64, r);
                let (x, y) = (p.xyz[0] - ORIGIN_M[0], p.xyz[1] - ORIGIN_M[1]);
                let dz = p.xyz[2] - terrain.jet(x, y).h;
                if x < 0.5 * side {
                    west_max = west_max.max(dz.abs());
                } else {
                    east.push(dz);
                }
            }
            Ok(())
        })
        .expect("reads");
        assert!(
            west_max <= 0.5e-3 + 1e-9,
            "west half off the surface by {west_max}"
        );
        let sd = (east.iter().map(|d| d * d).sum::<f64>() / east.len() as f64).sqrt();
        assert!(
            east.len() > 8_000 && (sd - 0.05).abs() < 0.005,
            "east sigma {sd}"
        );
    }

    #[test]
    fn written_file_reads_back_with_metres_and_truth() {
        let dir = tempfile::tempdir().expect("temp dir");
        let opts = TerrainOptions {
            points: 30_000,
            density_per_m2: 2.0,
            seed: 9,
            noise: Noise::NONE,
            truth: Truth::Curvature,
        };
        let cancel = AtomicBool::new(false);
        for name in ["t.las", "t.laz"] {
            let out = dir.path().join(name);
            let s = generate_terrain(&opts, &out, &cancel).expect("generates");
            assert_eq!(s.points, 30_000);
            let src = LasSource::open(&out).expect("reads back");
            assert_eq!(src.len(), 30_000);
            assert_eq!(src.unit().unit().map(|u| u.metres), Some(1.0));
            let names: Vec<&str> = src.extra.iter().map(|d| d.name.as_str()).collect();
            assert_eq!(names, TRUTH_COLUMNS);
            let base = POINT_FORMAT_SIZES[POINT_FORMAT as usize] as usize;
            let terrain = Terrain::new(opts.side_m(), opts.seed);
            let mut seen = 0u64;
            let mut last_strip = 0u16;
            src.for_each_chunk(7_000, &mut |first, recs| {
                for (i, r) in recs.chunks_exact(RECORD_LENGTH).enumerate() {
                    let p = src.decode(first + i as u64, r);
                    let (x, y) = (p.xyz[0] - ORIGIN_M[0], p.xyz[1] - ORIGIN_M[1]);
                    let jet = terrain.jet(x, y);
                    assert!(
                        (p.xyz[2] - jet.h).abs() <= 0.5e-3 + 1e-9,
                        "z on the surface"
                    );
                    let h = src.extra[0].read(&r[base..]).expect("TrueH");
                    let want = jet.curvature().h;
                    // x, y went through the file's offset: equal to ~1e-10 m.
                    assert!(
                        (h - want).abs() <= 1e-9 * (1e-3 + want.abs()),
                        "TrueH {h} is the closed form {want}"
                    );
                    let strip = u16::from_le_bytes([r[18], r[19]]);
                    assert!(strip >= last_strip, "points come strip by strip");
                    last_strip = strip;
                }
                seen += (recs.len() / RECORD_LENGTH) as u64;
                Ok(())
            })
            .expect("decodes");
            assert_eq!(seen, 30_000);
        }
        // The same options give the same bytes, LAS and LAZ alike.
        let again = dir.path().join("again.las");
        generate_terrain(&opts, &again, &cancel).expect("generates");
        let a = std::fs::read(dir.path().join("t.las")).expect("read");
        let b = std::fs::read(&again).expect("read");
        assert!(a == b, "generation is deterministic");
    }
}
