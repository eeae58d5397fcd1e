//! `tilecurv generate terrain`: synthetic aerial-LIDAR-like terrain of any size with closed-form
//! curvature, written as LAS 1.2 / LAZ (point format 1) with the true H, K, k1, k2 of every point
//! as f64 extra bytes `TrueH`, `TrueK`, `Truek1`, `Truek2`, so that the accuracy of `process` can
//! be checked on clouds as large as the engine must handle.
//!
//! The surface is a height field z = h(x, y) in metres (a gentle regional slope plus a sum of
//! smooth compactly supported bumps, [`Terrain`]); its curvature comes from the Monge formulas
//! of algorithms.md section 6.2 through [`crate::core::surface::height_field_curvature`], in the
//! tool's convention (upward normal, a hilltop has H > 0), in 1/m (K in 1/m^2).
//!
//! Points are laid out as an airborne scanner lays them: north-south flight strips flown
//! alternately north and south, each strip cut into scan rows 1 m long along the track, each
//! row holding its share of the points at uniform random positions, ordered across the track
//! in a zig-zag. Every row is generated from its own seeded stream, so the file is a pure
//! function of the options (bit-identical across runs and thread counts), and rows are
//! generated in parallel batches of about a million points and written in order: memory stays
//! bounded (one batch, about 60 MB) whatever the number of points.
//!
//! This module must not hold the cloud: it writes as it generates. It produces the records and
//! its own VLRs (GeoTIFF keys, the truth columns' descriptors); the file is written by the
//! library's one LAS/LAZ writer ([`LasFileWriter`]: header, LAZ, temporary file and rename).

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use rayon::prelude::*;

use crate::core::rng::Rng;
use crate::core::surface::{HeightField, HeightJet};
use crate::error::{Error, Result};
use crate::io::las::extra_bytes::{encode, NewColumn, ScalarType};
use crate::io::las::header::{NewHeader, POINT_FORMAT_SIZES};
use crate::io::las::vlr::Vlr;
use crate::io::las::writer::{HeaderStart, LasFileSpec, LasFileWriter};

/// Coordinate scale of the output (1 mm).
pub const SCALE_M: f64 = 0.001;
/// Easting and northing of the south-west corner of the generated square (UTM zone 10N, inside
/// the zone's valid range), and the header offsets of x and y.
pub const ORIGIN_M: [f64; 2] = [500_000.0, 4_100_000.0];
/// The header offsets of x, y and z.
const OFFSETS_M: [f64; 3] = [ORIGIN_M[0], ORIGIN_M[1], 0.0];
/// Base elevation of the terrain in metres.
pub const BASE_ELEVATION_M: f64 = 100.0;
/// EPSG code of the CRS declared in the GeoTIFF keys (WGS 84 / UTM zone 10N, metres).
pub const EPSG: u16 = 32610;
/// Point data record format of the output (format 1: format 0 plus GPS time).
pub const POINT_FORMAT: u8 = 1;
/// Names of the truth columns, in record order.
pub const TRUTH_COLUMNS: [&str; 4] = ["TrueH", "TrueK", "Truek1", "Truek2"];
/// Smallest and largest bump support radius in metres.
pub const BUMP_RADIUS_M: (f64, f64) = (20.0, 200.0);
/// Smallest and largest bump height (absolute) in metres; a bump is also at most
/// [`MAX_HEIGHT_PER_RADIUS`] times its radius high, which caps its slope at about 0.57.
pub const BUMP_HEIGHT_M: (f64, f64) = (2.0, 30.0);
/// Largest bump height per metre of radius (the steepest slope of a bump is 1.9 height/radius).
pub const MAX_HEIGHT_PER_RADIUS: f64 = 0.3;
/// Largest width of a flight strip in metres (the square is cut into equal strips).
const STRIP_WIDTH_M: f64 = 250.0;
/// Largest length of a scan row along the track in metres.
const ROW_LENGTH_M: f64 = 1.0;
/// Most points in one scan row (rows get shorter at very high densities).
const MAX_ROW_POINTS: u64 = 50_000;
/// Flying height above the terrain, for the scan angle, in metres.
const FLYING_HEIGHT_M: f64 = 1000.0;
/// Pulses per second, for the GPS time.
const PULSE_RATE_HZ: f64 = 200_000.0;
/// Seconds between the starts of two strips.
const STRIP_INTERVAL_S: f64 = 600.0;
/// Points generated in parallel per batch: the memory of the generator is about one batch of
/// 60-byte records (60 MB), whatever the number of points.
const BATCH_POINTS: u64 = 1_000_000;
/// Salt of the bump streams, so that they differ from the point streams of the same seed.
const BUMP_SALT: u64 = 0x6275_6d70_7321;

/// Bytes per output record: point format 1 plus the four f64 truth columns.
pub const RECORD_LENGTH: usize = POINT_FORMAT_SIZES[POINT_FORMAT as usize] as usize + 32;

/// What `generate terrain` is asked for.
#[derive(Debug, Clone, PartialEq)]
pub struct TerrainOptions {
    /// Number of points to write.
    pub points: u64,
    /// Points per square metre (the square's area is points / density).
    pub density_per_m2: f64,
    /// Seed of the terrain and of the sampling.
    pub seed: u64,
    /// Standard deviation of Gaussian noise added to z, in metres (the truth columns are those
    /// of the noise-free surface at the point's x, y).
    pub noise_m: f64,
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
                "--points {}: a LAS 1.2 file holds at most {} points; generate several files with different --seed",
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
        if !(self.noise_m.is_finite() && self.noise_m >= 0.0) {
            return Err(Error::Usage(format!(
                "--noise {}: the noise must be a standard deviation in metres, 0 or more",
                self.noise_m
            )));
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

/// Parses a point count: `2000000`, `2M`, `1.5M`, `20k`, `1G`, `1e6` (k, M, G are powers of ten).
pub fn parse_count(s: &str) -> std::result::Result<u64, String> {
    let t = s.trim().replace('_', "");
    let (num, mult) = match t.chars().last() {
        Some('k' | 'K') => (&t[..t.len() - 1], 1e3),
        Some('m' | 'M') => (&t[..t.len() - 1], 1e6),
        Some('g' | 'G') => (&t[..t.len() - 1], 1e9),
        _ => (t.as_str(), 1.0),
    };
    let v: f64 = num.parse().map_err(|_| {
        format!("{s:?} is not a point count: expected e.g. 2000000, 2M, 500k or 1e6")
    })?;
    let n = (v * mult).round();
    if !(1.0..1.8e19).contains(&n) {
        return Err(format!("{s:?}: a point count must be at least 1"));
    }
    Ok(n as u64)
}

/// One bump of the terrain: h = height (1 - r^2/radius^2)^4 for r < radius, 0 beyond. The
/// quartic makes h, its slope, its curvature and the curvature's first derivatives vanish at
/// the rim (C3), so the sum is smooth, and a point only sees the few bumps whose support
/// covers it: the evaluation cost does not grow with the area (Gaussians would need a
/// truncation and many more bumps per point).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bump {
    /// Centre easting, relative to the square's south-west corner, in metres.
    pub cx: f64,
    /// Centre northing, relative to the square's south-west corner, in metres.
    pub cy: f64,
    /// Support radius in metres.
    pub radius_m: f64,
    /// Height at the centre in metres (negative for a hollow).
    pub height_m: f64,
}

impl Bump {
    /// Adds this bump's value and derivatives at (x, y) to `j`.
    fn add_to(&self, x: f64, y: f64, j: &mut HeightJet) {
        let (dx, dy) = (x - self.cx, y - self.cy);
        let r2 = self.radius_m * self.radius_m;
        let u = 1.0 - (dx * dx + dy * dy) / r2;
        if u <= 0.0 {
            return;
        }
        let a = self.height_m;
        let (u2, u3) = (u * u, u * u * u);
        // h = a u^4, u = 1 - (dx^2 + dy^2)/R^2, du/dx = -2 dx/R^2:
        // h_x = -8 a u^3 dx / R^2, h_xx = -8 a u^3 / R^2 + 48 a u^2 dx^2 / R^4,
        // h_xy = 48 a u^2 dx dy / R^4.
        let c1 = -8.0 * a * u3 / r2;
        let c2 = 48.0 * a * u2 / (r2 * r2);
        j.h += a * u2 * u2;
        j.hx += c1 * dx;
        j.hy += c1 * dy;
        j.hxx += c1 + c2 * dx * dx;
        j.hxy += c2 * dx * dy;
        j.hyy += c1 + c2 * dy * dy;
    }
}

/// The synthetic terrain: z = base + slope . (x, y) + sum of [`Bump`]s, over local coordinates
/// (metres from the south-west corner of the square). Bumps are placed per cell of a grid of
/// cells as wide as the largest radius, from a stream seeded by (seed, cell), so a point only
/// looks at the 3 x 3 cells around it.
#[derive(Debug, Clone)]
pub struct Terrain {
    /// Elevation at the south-west corner before bumps, in metres.
    pub base_m: f64,
    /// Regional slope (dz/dx, dz/dy).
    pub slope: [f64; 2],
    /// Cells per side of the bump grid (covering one cell beyond the square on every side).
    cells: usize,
    /// Bumps by cell, row-major, cell (i, j) covering local x in [(i-1) C, i C) with C the cell size.
    bumps: Vec<Vec<Bump>>,
}

impl Terrain {
    /// The terrain over a square of side `side_m` metres for `seed`.
    pub fn new(side_m: f64, seed: u64) -> Self {
        let cell = BUMP_RADIUS_M.1;
        // One cell of margin on each side, so that bumps centred outside the square reach in.
        let cells = (side_m / cell).ceil() as usize + 2;
        let mut head = Rng::new(seed ^ BUMP_SALT);
        let slope = [
            0.03 * (2.0 * head.uniform() - 1.0),
            0.03 * (2.0 * head.uniform() - 1.0),
        ];
        let (lo, hi) = BUMP_RADIUS_M;
        let mut bumps = Vec::with_capacity(cells * cells);
        for j in 0..cells {
            for i in 0..cells {
                let mut rng = Rng::for_point(seed ^ BUMP_SALT, (j * cells + i) as u64);
                // 1 to 4 bumps per 200 m cell: with log-uniform radii (mean area 27,000 m^2)
                // a point lies under 1.7 bumps on average, so bumps overlap into saddles.
                let n = 1 + rng.below(4);
                let v = (0..n)
                    .map(|_| {
                        let cx = (i as f64 - 1.0 + rng.uniform()) * cell;
                        let cy = (j as f64 - 1.0 + rng.uniform()) * cell;
                        let radius_m = lo * (hi / lo).powf(rng.uniform());
                        let top = BUMP_HEIGHT_M.1.min(MAX_HEIGHT_PER_RADIUS * radius_m);
                        let size = BUMP_HEIGHT_M.0 + (top - BUMP_HEIGHT_M.0) * rng.uniform();
                        let sign = if rng.uniform() < 0.5 { -1.0 } else { 1.0 };
                        Bump {
                            cx,
                            cy,
                            radius_m,
                            height_m: sign * size,
                        }
                    })
                    .collect();
                bumps.push(v);
            }
        }
        Terrain {
            base_m: BASE_ELEVATION_M,
            slope,
            cells,
            bumps,
        }
    }

    /// Number of bumps.
    pub fn bump_count(&self) -> usize {
        self.bumps.iter().map(Vec::len).sum()
    }
}

impl HeightField for Terrain {
    fn jet(&self, x: f64, y: f64) -> HeightJet {
        let mut j = HeightJet {
            h: self.base_m + self.slope[0] * x + self.slope[1] * y,
            hx: self.slope[0],
            hy: self.slope[1],
            hxx: 0.0,
            hxy: 0.0,
            hyy: 0.0,
        };
        let cell = BUMP_RADIUS_M.1;
        // The grid cell of (x, y), shifted by the margin; the support of a bump (radius at most
        // one cell) reaches at most the neighbouring cells.
        let ci = ((x / cell).floor() + 1.0) as isize;
        let cj = ((y / cell).floor() + 1.0) as isize;
        for j_cell in cj - 1..=cj + 1 {
            for i_cell in ci - 1..=ci + 1 {
                if i_cell < 0
                    || j_cell < 0
                    || i_cell as usize >= self.cells
                    || j_cell as usize >= self.cells
                {
                    continue;
                }
                for b in &self.bumps[j_cell as usize * self.cells + i_cell as usize] {
                    b.add_to(x, y, &mut j);
                }
            }
        }
        j
    }
}

/// How the square is flown: `strips` north-south strips, each cut into `rows` scan rows; row
/// `c` (in flight order) holds points floor((c+1) N / C) - floor(c N / C) of the N points.
#[derive(Debug, Clone, Copy)]
struct FlightPlan {
    side_m: f64,
    strips: u64,
    rows: u64,
    points: u64,
}

impl FlightPlan {
    fn new(side_m: f64, points: u64) -> Self {
        let mut plan = FlightPlan {
            side_m,
            strips: ((side_m / STRIP_WIDTH_M).ceil() as u64).max(1),
            rows: ((side_m / ROW_LENGTH_M).ceil() as u64).max(1),
            points,
        };
        // At very low densities, fewer strips and longer rows (no empty rows to loop over); at
        // very high densities, shorter rows keep each row (one task) small.
        plan.strips = plan.strips.min(points).max(1);
        plan.rows = plan.rows.min(points.div_ceil(plan.strips)).max(1);
        plan.rows = plan.rows.max(points.div_ceil(plan.strips * MAX_ROW_POINTS));
        plan
    }

    /// Rows per batch: about [`BATCH_POINTS`] points.
    fn rows_per_batch(&self) -> u64 {
        (BATCH_POINTS * self.cells() / self.points.max(1)).max(1)
    }

    fn cells(&self) -> u64 {
        self.strips * self.rows
    }

    /// Index of the first point of row `c` (in flight order).
    fn first_point(&self, c: u64) -> u64 {
        (u128::from(c) * u128::from(self.points) / u128::from(self.cells())) as u64
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

/// Coordinate bounds (min, max) of the records written so far, in integer millimetres.
#[derive(Debug, Clone, Copy)]
struct IntBounds {
    lo: [i32; 3],
    hi: [i32; 3],
}

impl IntBounds {
    fn empty() -> Self {
        IntBounds {
            lo: [i32::MAX; 3],
            hi: [i32::MIN; 3],
        }
    }

    fn add(&mut self, q: [i32; 3]) {
        self.merge(&IntBounds { lo: q, hi: q });
    }

    fn merge(&mut self, o: &IntBounds) {
        for a in 0..3 {
            self.lo[a] = self.lo[a].min(o.lo[a]);
            self.hi[a] = self.hi[a].max(o.hi[a]);
        }
    }
}

/// Generates the records of scan row `c` (flight order) into `out`, and returns their bounds.
fn generate_row(
    terrain: &Terrain,
    plan: &FlightPlan,
    opts: &TerrainOptions,
    c: u64,
    out: &mut Vec<u8>,
) -> IntBounds {
    let strip = c / plan.rows;
    let in_strip = c % plan.rows;
    // Even strips fly north (rows in increasing y), odd strips fly south.
    let row = if strip.is_multiple_of(2) {
        in_strip
    } else {
        plan.rows - 1 - in_strip
    };
    let width = plan.side_m / plan.strips as f64;
    let length = plan.side_m / plan.rows as f64;
    let (x0, y0) = (strip as f64 * width, row as f64 * length);
    let first = plan.first_point(c);
    let n = (plan.first_point(c + 1) - first) as usize;
    let mut rng = Rng::for_point(opts.seed, c);
    let mut xy: Vec<(f64, f64)> = (0..n)
        .map(|_| (x0 + width * rng.uniform(), y0 + length * rng.uniform()))
        .collect();
    // The scanner sweeps across the track, alternating direction from row to row.
    if in_strip.is_multiple_of(2) {
        xy.sort_by(|a, b| a.0.total_cmp(&b.0));
    } else {
        xy.sort_by(|a, b| b.0.total_cmp(&a.0));
    }
    let centre = x0 + 0.5 * width;
    let strip_first = plan.first_point(strip * plan.rows);
    let mut bounds = IntBounds::empty();
    for (i, (x, y)) in xy.into_iter().enumerate() {
        // Quantise x and y first, so that the stored position lies on the surface exactly in
        // x, y and the truth is the truth at the stored point (z is off by at most 0.5 mm).
        let qx = (x / SCALE_M).round();
        let qy = (y / SCALE_M).round();
        let (xs, ys) = (qx * SCALE_M, qy * SCALE_M);
        let jet = terrain.jet(xs, ys);
        let noise = if opts.noise_m > 0.0 {
            opts.noise_m * rng.normal()
        } else {
            0.0
        };
        let qz = ((jet.h + noise) / SCALE_M).round();
        let q = [qx as i32, qy as i32, qz as i32];
        bounds.add(q);
        let t = jet.curvature();
        let nz = jet.normal()[2];
        let scan_angle = ((x - centre) / FLYING_HEIGHT_M).atan().to_degrees().round() as i8;
        let gps = strip as f64 * STRIP_INTERVAL_S
            + (first + i as u64 - strip_first) as f64 / PULSE_RATE_HZ;
        for v in q {
            out.extend_from_slice(&v.to_le_bytes());
        }
        // Intensity: a Lambertian return from a sun-less sensor overhead.
        out.extend_from_slice(&((nz * 40_000.0) as u16).to_le_bytes());
        // Return 1 of 1, scan direction by row, edge-of-flight-line on the first and last point.
        let mut bits = 0x09u8;
        if in_strip.is_multiple_of(2) {
            bits |= 0x40;
        }
        if i == 0 || i + 1 == n {
            bits |= 0x80;
        }
        out.push(bits);
        out.push(2); // classification: ground
        out.push(scan_angle as u8);
        out.push(0); // user data
        out.extend_from_slice(&((strip + 1) as u16).to_le_bytes());
        out.extend_from_slice(&gps.to_le_bytes());
        for v in [t.h, t.k, t.k1, t.k2] {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    bounds
}

/// The GeoTIFF key directory of WGS 84 / UTM zone 10N in metres: model type projected, raster
/// type pixel-is-area, ProjectedCSTypeGeoKey 32610, ProjLinearUnitsGeoKey and VerticalUnitsGeoKey
/// 9001 (metre), sorted by key id as GeoTIFF requires.
fn geotiff_keys() -> Vec<u8> {
    let keys: [[u16; 4]; 5] = [
        [1024, 0, 1, 1],
        [1025, 0, 1, 1],
        [3072, 0, 1, EPSG],
        [3076, 0, 1, 9001],
        [4099, 0, 1, 9001],
    ];
    let mut w = vec![1u16, 1, 0, keys.len() as u16];
    w.extend(keys.iter().flatten());
    w.iter().flat_map(|v| v.to_le_bytes()).collect()
}

/// The extra-bytes descriptors of the truth columns.
fn truth_descriptors() -> Vec<u8> {
    let descriptions = [
        "true mean curvature (1/m)",
        "true Gaussian curvature (1/m^2)",
        "true min principal curv. (1/m)",
        "true max principal curv. (1/m)",
    ];
    TRUTH_COLUMNS
        .iter()
        .zip(descriptions)
        .flat_map(|(name, description)| {
            encode(&NewColumn {
                name: (*name).into(),
                ty: ScalarType::F64,
                description: description.into(),
            })
        })
        .collect()
}

/// The LAS 1.2 header of the output (227 bytes; the layout fields are the writer's). The
/// bounds are known only once every point is written: until [`LasFileWriter::set_bounds`] they
/// are those of the origin.
fn new_header(points: u64, software: &str) -> NewHeader<'_> {
    NewHeader {
        minor: 2,
        system: "SYNTHETIC TERRAIN",
        software,
        point_format: POINT_FORMAT,
        record_length: RECORD_LENGTH as u16,
        points,
        scale: [SCALE_M; 3],
        offset: OFFSETS_M,
        min: OFFSETS_M,
        max: OFFSETS_M,
    }
}

/// The text of the provenance VLR: the options and the units of the truth columns.
fn provenance(opts: &TerrainOptions) -> String {
    format!(
        "tilecurv {} generate terrain\npoints={}\ndensity={}\nseed={}\nnoise={}\nunits=metres; TrueH, Truek1, Truek2 in 1/m, TrueK in 1/m^2; upward normal, positive on hilltops\n",
        env!("CARGO_PKG_VERSION"),
        opts.points,
        opts.density_per_m2,
        opts.seed,
        opts.noise_m
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
    let software = format!("tilecurv {} generate", env!("CARGO_PKG_VERSION"));
    let geotiff = [Vlr::new(
        "LASF_Projection",
        34735,
        "GeoKeyDirectoryTag",
        geotiff_keys(),
    )];
    let provenance = provenance(opts);
    let spec = LasFileSpec {
        origin: None,
        header: HeaderStart::New(new_header(opts.points, &software)),
        record_length: RECORD_LENGTH as u16,
        vlrs: &geotiff,
        evlrs: &[],
        extra_bytes: truth_descriptors(),
        provenance: &provenance,
    };
    let mut writer = LasFileWriter::create(output, spec)?;
    let side_m = opts.side_m();
    let terrain = Terrain::new(side_m, opts.seed);
    let plan = FlightPlan::new(side_m, opts.points);
    let bounds = match write_rows(&terrain, &plan, opts, &mut writer, cancel) {
        Ok(b) => b,
        Err(e) => {
            writer.abandon();
            return Err(e);
        }
    };
    let at = |a: usize, v: i32| OFFSETS_M[a] + f64::from(v) * SCALE_M;
    writer.set_bounds(
        [0, 1, 2].map(|a| at(a, bounds.lo[a])),
        [0, 1, 2].map(|a| at(a, bounds.hi[a])),
    );
    writer.finish()?;
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
                let mut buf = Vec::with_capacity(n * RECORD_LENGTH);
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
    use crate::io::source::{LasSource, PointSource};

    #[test]
    fn bump_derivatives_match_finite_differences() {
        let t = Terrain::new(600.0, 3);
        assert!(t.bump_count() > 0);
        let e = 1e-4;
        for &(x, y) in &[(10.0, 20.0), (150.3, 333.7), (420.0, 77.0), (599.0, 1.0)] {
            let j = t.jet(x, y);
            let (px, mx) = (t.jet(x + e, y), t.jet(x - e, y));
            let (py, my) = (t.jet(x, y + e), t.jet(x, y - e));
            let close = |a: f64, b: f64, what: &str| {
                assert!(
                    (a - b).abs() <= 1e-6 * (1.0 + b.abs()),
                    "{what} at ({x}, {y}): {a} vs finite difference {b}"
                )
            };
            close(j.hx, (px.h - mx.h) / (2.0 * e), "h_x");
            close(j.hy, (py.h - my.h) / (2.0 * e), "h_y");
            close(j.hxx, (px.hx - mx.hx) / (2.0 * e), "h_xx");
            close(j.hxy, (py.hx - my.hx) / (2.0 * e), "h_xy");
            close(j.hyy, (py.hy - my.hy) / (2.0 * e), "h_yy");
        }
    }

    #[test]
    fn a_hilltop_has_positive_mean_curvature() {
        let b = Bump {
            cx: 0.0,
            cy: 0.0,
            radius_m: 50.0,
            height_m: 10.0,
        };
        let mut j = HeightJet {
            h: 0.0,
            hx: 0.0,
            hy: 0.0,
            hxx: 0.0,
            hxy: 0.0,
            hyy: 0.0,
        };
        b.add_to(0.0, 0.0, &mut j);
        let c = j.curvature();
        // h_xx = h_yy = -8 a / R^2 at the centre: k1 = k2 = 8 * 10 / 2500 (section 6.2 sign).
        assert!((c.k1 - 0.032).abs() < 1e-12 && (c.k2 - 0.032).abs() < 1e-12);
        assert!(c.h > 0.0);
    }

    #[test]
    fn flight_plan_bounds_rows_and_batches() {
        // 10 points/m^2: 250 m strips, 1 m rows of about 2,500 points.
        let p = FlightPlan::new(1000.0, 10_000_000);
        assert_eq!((p.strips, p.rows), (4, 1000));
        // Sparse: no empty rows to loop over.
        let p = FlightPlan::new(30_000.0, 3);
        assert!(p.cells() <= 3);
        // Dense: rows of at most MAX_ROW_POINTS points, batches of about BATCH_POINTS.
        let p = FlightPlan::new(100.0, 1_000_000_000);
        let per_row = p.first_point(1) - p.first_point(0);
        assert!(per_row <= MAX_ROW_POINTS, "{per_row} points per row");
        assert!(p.rows_per_batch() * per_row <= 2 * BATCH_POINTS);
        // Rows partition the points.
        assert_eq!(p.first_point(p.cells()), 1_000_000_000);
    }

    #[test]
    fn parse_counts() {
        assert_eq!(parse_count("2M"), Ok(2_000_000));
        assert_eq!(parse_count("1.5k"), Ok(1500));
        assert_eq!(parse_count("1e6"), Ok(1_000_000));
        assert_eq!(parse_count("20_000"), Ok(20_000));
        assert!(parse_count("0").is_err());
        assert!(parse_count("many").is_err());
    }

    #[test]
    fn written_file_reads_back_with_metres_and_truth() {
        let dir = tempfile::tempdir().expect("temp dir");
        let opts = TerrainOptions {
            points: 30_000,
            density_per_m2: 2.0,
            seed: 9,
            noise_m: 0.0,
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
