//! The sampling plan of `generate terrain`: points are laid out as an airborne scanner lays
//! them, north-south flight strips flown alternately north and south, each strip cut into scan
//! rows 1 m long along the track, each row holding its share of the points at uniform random
//! positions, ordered across the track in a zig-zag. Every row is generated from its own seeded
//! stream, so the file is a pure function of the options (bit-identical across runs and thread
//! counts), and rows are generated in batches of about a million points: memory stays bounded
//! (one batch, about 60 MB) whatever the number of points. Records only; writing is the
//! command's job.

use crate::core::rng::Rng;
use crate::core::surface::HeightField;

use super::terrain::Terrain;
use super::truth::terrain_truth;
use super::{Record, TerrainOptions, Truth, MAX_TRUTH, SCALE_M};

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

/// How the square is flown: `strips` north-south strips, each cut into `rows` scan rows; row
/// `c` (in flight order) holds points floor((c+1) N / C) - floor(c N / C) of the N points.
#[derive(Debug, Clone, Copy)]
pub(super) struct FlightPlan {
    side_m: f64,
    /// North-south strips.
    pub(super) strips: u64,
    /// Scan rows per strip.
    rows: u64,
    points: u64,
}

impl FlightPlan {
    /// The plan of `points` points over a square of side `side_m` metres.
    pub(super) fn new(side_m: f64, points: u64) -> Self {
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
    pub(super) fn rows_per_batch(&self) -> u64 {
        (BATCH_POINTS * self.cells() / self.points.max(1)).max(1)
    }

    /// Rows in all (strips times rows per strip).
    pub(super) fn cells(&self) -> u64 {
        self.strips * self.rows
    }

    /// Index of the first point of row `c` (in flight order).
    pub(super) fn first_point(&self, c: u64) -> u64 {
        (u128::from(c) * u128::from(self.points) / u128::from(self.cells())) as u64
    }
}

/// Coordinate bounds (min, max) of the records written so far, in the file's integer units.
#[derive(Debug, Clone, Copy)]
pub(super) struct IntBounds {
    /// Minimum x, y, z.
    pub(super) lo: [i32; 3],
    /// Maximum x, y, z.
    pub(super) hi: [i32; 3],
}

impl IntBounds {
    /// No record yet.
    pub(super) fn empty() -> Self {
        IntBounds {
            lo: [i32::MAX; 3],
            hi: [i32::MIN; 3],
        }
    }

    /// Extends the bounds by one record.
    pub(super) fn add(&mut self, q: [i32; 3]) {
        self.merge(&IntBounds { lo: q, hi: q });
    }

    /// Extends the bounds by those of other records.
    pub(super) fn merge(&mut self, o: &IntBounds) {
        for a in 0..3 {
            self.lo[a] = self.lo[a].min(o.lo[a]);
            self.hi[a] = self.hi[a].max(o.hi[a]);
        }
    }
}

/// Generates the records of scan row `c` (flight order) into `out`, and returns their bounds.
pub(super) fn generate_row(
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
    let columns = opts.truth.columns();
    for (i, (x, y)) in xy.into_iter().enumerate() {
        // Quantise x and y first, so that the stored position lies on the surface exactly in
        // x, y and the truth is the truth at the stored point (z is off by at most 0.5 mm).
        let qx = (x / SCALE_M).round();
        let qy = (y / SCALE_M).round();
        let (xs, ys) = (qx * SCALE_M, qy * SCALE_M);
        let jet = terrain.jet(xs, ys);
        let sigma = opts.noise.at(xs, plan.side_m);
        let noise = if sigma > 0.0 {
            sigma * rng.normal()
        } else {
            0.0
        };
        let qz = ((jet.h + noise) / SCALE_M).round();
        let q = [qx as i32, qy as i32, qz as i32];
        bounds.add(q);
        let mut truth = [f64::NAN; MAX_TRUTH];
        if columns > 0 {
            let t = jet.curvature();
            truth[..4].copy_from_slice(&[t.h, t.k, t.k1, t.k2]);
        }
        if opts.truth == Truth::Terrain {
            truth[4..].copy_from_slice(&terrain_truth(&jet));
        }
        let nz = jet.normal()[2];
        let scan_angle = ((x - centre) / FLYING_HEIGHT_M).atan().to_degrees().round() as i8;
        let gps = strip as f64 * STRIP_INTERVAL_S
            + (first + i as u64 - strip_first) as f64 / PULSE_RATE_HZ;
        // Return 1 of 1, scan direction by row, edge-of-flight-line on the first and last point.
        let mut return_bits = 0x09u8;
        if in_strip.is_multiple_of(2) {
            return_bits |= 0x40;
        }
        if i == 0 || i + 1 == n {
            return_bits |= 0x80;
        }
        Record {
            xyz: q,
            // Intensity: a Lambertian return from a sun-less sensor overhead.
            intensity: (nz * 40_000.0) as u16,
            return_bits,
            class: 2, // ground
            scan_angle,
            source: (strip + 1) as u16,
            gps,
            truth: &truth[..columns],
        }
        .encode(out);
    }
    bounds
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
