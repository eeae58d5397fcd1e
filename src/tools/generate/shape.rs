//! `tilecurv generate torus` and `tilecurv generate goursat`: the CNC paper's two test shapes
//! (algorithms.md 13.4, 13.5 and 14.1: the torus R = 6, r = 2 and the goursat surface
//! 0.03 (x^4 + y^4 + z^4) - 2 (x^2 + y^2 + z^2) - 8 = 0), sampled uniformly in area by the
//! library's samplers ([`crate::core::sampling`], the test kit's too) and written in the layout of
//! `generate terrain`: LAS 1.4 point format 1 with the closed-form `TrueH`, `TrueK`, `Truek1`,
//! `Truek2` of every point ([`crate::core::surface`]), outward normals, coordinates in metres.
//!
//! Noise is isotropic: centred Gaussian of standard deviation sigma on each coordinate
//! ([`crate::core::sampling::Noise`], as the CNC paper perturbs positions), from its own stream;
//! the truth columns are those of the clean sample point. Points stream to the writer: memory
//! does not grow with `--points`.

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use crate::core::geometry::{SurfacePoint, V3};
use crate::core::sampling::{GoursatSampler, Noise, TorusSampler};
use crate::core::surface::{goursat_curvature, torus_curvature_at, TrueCurvature, PAPER_TORUS};
use crate::error::{Error, Result};

use super::flight::IntBounds;
use super::{FileLayout, Record, Truth, RECORD_LENGTH};

/// Coordinate scale of a shape's file (1 micrometre: the quantisation moves a point by at most
/// 0.9e-6, far below any neighbourhood's noise; the shapes reach 9.7 m from the origin).
pub const SHAPE_SCALE: f64 = 1e-6;
/// Points encoded per write.
const BATCH_POINTS: usize = 100_000;
/// Salt of the noise stream, so that it differs from the sampling stream of the same seed.
const NOISE_SALT: u64 = 0x6e6f_6973_6521;
/// ProjectedCSTypeGeoKey of the shapes' CRS: user-defined (a local frame), in metres.
const LOCAL_CRS: u16 = 32767;

/// Which closed-form shape to sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shape {
    /// The paper torus, R = 6 m around the z axis, tube r = 2 m (algorithms.md 13.4).
    Torus,
    /// The goursat surface of algorithms.md 13.5 (within [-9.67, 9.67] m on each axis).
    Goursat,
}

impl Shape {
    /// The command's name: `torus` or `goursat`.
    pub fn name(self) -> &'static str {
        match self {
            Shape::Torus => "torus",
            Shape::Goursat => "goursat",
        }
    }

    /// The endless stream of clean sample points (position, outward unit normal) for `seed`.
    fn sampler(self, seed: u64) -> Box<dyn Iterator<Item = SurfacePoint>> {
        match self {
            Shape::Torus => Box::new(TorusSampler::new(PAPER_TORUS.0, PAPER_TORUS.1, seed)),
            Shape::Goursat => Box::new(GoursatSampler::new(seed)),
        }
    }

    /// The closed-form curvature at the surface point `p` (outward normal): the torus's from
    /// the angles of `p`, the goursat's from its implicit function (NaN if its gradient
    /// vanished, which it does nowhere on the surface).
    fn truth(self, p: V3) -> [f64; 4] {
        let t = match self {
            Shape::Torus => Some(torus_curvature_at(PAPER_TORUS.0, PAPER_TORUS.1, p)),
            Shape::Goursat => goursat_curvature(p),
        };
        t.map_or([f64::NAN; 4], |t: TrueCurvature| [t.h, t.k, t.k1, t.k2])
    }
}

/// What `generate torus` or `generate goursat` is asked for.
#[derive(Debug, Clone, PartialEq)]
pub struct ShapeOptions {
    /// The shape.
    pub shape: Shape,
    /// Number of points to write.
    pub points: u64,
    /// Standard deviation of the isotropic Gaussian noise on each coordinate, metres.
    pub noise_m: f64,
    /// Seed of the sampling and of the noise.
    pub seed: u64,
}

impl ShapeOptions {
    /// Checks the options, with a message saying what to change.
    pub fn validate(&self) -> Result<()> {
        if self.points == 0 || self.points > u64::from(u32::MAX) {
            return Err(Error::Usage(format!(
                "--points {}: give 1 to {} points (point format 1's 32-bit count), e.g. --points 80k",
                self.points,
                u32::MAX
            )));
        }
        if !(self.noise_m.is_finite() && self.noise_m >= 0.0) {
            return Err(Error::Usage(format!(
                "--noise {}: the noise must be a standard deviation in metres, 0 or more (e.g. 0.02)",
                self.noise_m
            )));
        }
        Ok(())
    }
}

/// What a finished shape generation reports.
#[derive(Debug, Clone, PartialEq)]
pub struct ShapeSummary {
    /// Points written.
    pub points: u64,
    /// Smallest and largest x, y, z written, metres.
    pub bounds_m: [[f64; 3]; 2],
    /// Wall time in seconds.
    pub seconds: f64,
}

/// The text of the provenance VLR: the options and the units of the truth columns.
fn provenance(opts: &ShapeOptions) -> String {
    format!(
        "tilecurv {} generate {}\npoints={}\nseed={}\nnoise={} (isotropic, per coordinate; truth at the clean point)\nunits=metres; TrueH, Truek1, Truek2 in 1/m, TrueK in 1/m^2; outward normal, positive on a sphere\n",
        env!("CARGO_PKG_VERSION"),
        opts.shape.name(),
        opts.points,
        opts.seed,
        opts.noise_m
    )
}

/// Writes the shape of `opts` to `output` (.las or .laz; the extension decides), checking
/// `cancel` between batches. The output appears complete or not at all. Coordinates are metres
/// in a local frame centred on the shape, at 1 micrometre resolution.
pub fn generate_shape(
    opts: &ShapeOptions,
    output: &Path,
    cancel: &AtomicBool,
) -> Result<ShapeSummary> {
    let started = Instant::now();
    opts.validate()?;
    let layout = FileLayout {
        system: if opts.shape == Shape::Torus {
            "SYNTHETIC TORUS"
        } else {
            "SYNTHETIC GOURSAT"
        },
        epsg: LOCAL_CRS,
        scale: SHAPE_SCALE,
        offset: [0.0; 3],
        points: opts.points,
        provenance: provenance(opts),
        truth: Truth::Curvature,
    };
    let bounds = layout.write(output, |writer| {
        let mut samples = opts.shape.sampler(opts.seed);
        let mut noise = Noise::new(opts.noise_m, 0.0, opts.seed ^ NOISE_SALT);
        let mut bounds = IntBounds::empty();
        let mut buf = Vec::with_capacity(BATCH_POINTS * RECORD_LENGTH);
        let mut written = 0u64;
        while written < opts.points {
            if cancel.load(Ordering::Relaxed) {
                return Err(Error::Interrupted);
            }
            buf.clear();
            let batch = (opts.points - written).min(BATCH_POINTS as u64);
            for point in samples.by_ref().take(batch as usize) {
                let (p, noisy) = (point.position, noise.apply(point).position);
                let xyz = noisy.map(|c| (c / SHAPE_SCALE).round() as i32);
                bounds.add(xyz);
                Record {
                    xyz,
                    intensity: 0,
                    return_bits: 0x09, // return 1 of 1
                    class: 1,          // unclassified
                    scan_angle: 0,
                    source: 1,
                    gps: (written + buf.len() as u64 / RECORD_LENGTH as u64) as f64 * 1e-5,
                    truth: &opts.shape.truth(p),
                }
                .encode(&mut buf);
            }
            writer.write_records(&buf)?;
            written += batch;
        }
        Ok(bounds)
    })?;
    let m = |v: [i32; 3]| v.map(|c| f64::from(c) * SHAPE_SCALE);
    Ok(ShapeSummary {
        points: opts.points,
        bounds_m: [m(bounds.lo), m(bounds.hi)],
        seconds: started.elapsed().as_secs_f64(),
    })
}
