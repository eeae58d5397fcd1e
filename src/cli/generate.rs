//! `tilecurv generate terrain|torus|goursat`: the arguments and the command, which writes a
//! synthetic cloud with its closed-form curvature (`crate::tools::generate`).

use std::path::PathBuf;

use crate::config::parse_count;
use crate::progress::say;
use crate::tools::generate::{
    generate_shape, generate_terrain, Noise, Shape, ShapeOptions, TerrainOptions, Truth,
};

use super::{exit, fail, CANCEL, EXIT_HELP};

#[derive(clap::Args, Debug)]
pub(super) struct GenerateArgs {
    #[command(subcommand)]
    pub kind: GenerateKind,
}

#[derive(clap::Subcommand, Debug)]
pub(super) enum GenerateKind {
    /// Aerial-LIDAR-like terrain (hills and hollows on a gentle slope) of any size, with the
    /// closed-form curvature of every point. Streams: memory does not grow with --points.
    ///
    /// Units: coordinates in metres (WGS 84 / UTM zone 10N, EPSG:32610, declared by GeoTIFF
    /// keys with metre units; scale 0.001 m) around easting 500000, northing 4100000. Points
    /// are LAS 1.4 point format 1 (GPS time), ordered by flight strip (north-south, 250 m wide)
    /// and scan row, classified as ground. Extra-bytes columns (f64): TrueH (mean curvature,
    /// 1/m), TrueK (Gaussian curvature, 1/m^2), Truek1 <= Truek2 (principal curvatures, 1/m),
    /// with the upward normal: positive on hilltops, the sign of `process`'s H, K, k1, k2.
    #[command(after_help = EXIT_HELP)]
    Terrain(TerrainArgs),
    /// The CNC paper's torus (algorithms.md 13.4): major radius R = 6 m around the z axis, tube
    /// radius r = 2 m, points uniform in area, with the closed-form curvature of every point.
    ///
    /// Units: metres in a local frame centred on the torus (GeoTIFF keys: user-defined
    /// projected CRS, metre units; scale 1e-6 m). LAS 1.4 point format 1, unclassified, no
    /// normals stored. Extra-bytes columns (f64): TrueH (1/m, in [0.125, 0.3125]), TrueK
    /// (1/m^2, in [-0.125, 0.0625]), Truek1 <= Truek2 (1/m), with the outward normal (a sphere
    /// is positive), at the clean sample point. Process it with --orient propagate: the
    /// normals of the inner half point towards the axis, so `outward` gets them wrong.
    #[command(after_help = EXIT_HELP)]
    Torus(ShapeArgs),
    /// The goursat surface of the CNC paper (algorithms.md 13.5): 0.03 (x^4 + y^4 + z^4) - 2
    /// (x^2 + y^2 + z^2) - 8 = 0, a rounded cube within [-9.67, 9.67] m on each axis (a
    /// coordinate reaches 9.661 where the other two are +-5.77; 8.39 on the axes), points
    /// uniform in area, with the closed-form curvature of every point.
    ///
    /// Units and columns as for `generate torus`: metres in a local frame (scale 1e-6 m),
    /// TrueH in [-0.107, 0.345] 1/m, TrueK in [-0.034, 0.119] 1/m^2, outward normal. The
    /// surface is star-shaped around the origin: --orient outward orients its normals.
    #[command(after_help = EXIT_HELP)]
    Goursat(ShapeArgs),
}

/// The options every generator has.
#[derive(clap::Args, Debug)]
pub(super) struct CommonArgs {
    /// Output file; the extension chooses the format: .las or .laz. Written to a temporary file
    /// and renamed when complete.
    #[arg(short, long)]
    pub output: PathBuf,

    /// Number of points: 2000000, 2M, 500k, 1e6 (k, M, G = powers of ten). At most 4294967295
    /// (point format 1's 32-bit legacy count).
    #[arg(long, value_parser = parse_count)]
    pub points: u64,

    /// Seed of the random sampling (and of the terrain, or of the noise): the same options give
    /// the same file.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,

    /// Print nothing on success.
    #[arg(short, long)]
    pub quiet: bool,
}

#[derive(clap::Args, Debug)]
pub(super) struct TerrainArgs {
    #[command(flatten)]
    pub common: CommonArgs,

    /// Points per square metre; the terrain covers a square of points/density square metres.
    #[arg(long, default_value_t = 10.0)]
    pub density: f64,

    /// Standard deviation of Gaussian noise added to z, in metres: one value (0.02), or
    /// WEST:EAST for the square's two halves (0:0.05: clean west of the middle, 5 cm of noise
    /// east of it). The truth columns stay those of the noise-free surface at the point's x, y.
    #[arg(long, default_value = "0", value_parser = Noise::parse)]
    pub noise: Noise,

    /// Also write the true terrain values (f64, from the surface's derivatives p, q, r, s, t by
    /// Florinsky's formulas, docs/algorithms.md 10): TrueProfileCurvature,
    /// TrueTangentialCurvature, TruePlanCurvature (1/m), TrueShapeIndex, TrueCurvedness (1/m),
    /// TrueSlope, TrueAspect (degrees); NaN where undefined (slope under 0.1 degree: profile,
    /// tangential, plan, aspect). 56 more bytes a point.
    #[arg(long)]
    pub terrain_truth: bool,

    /// Write no truth columns at all: plain point format 1 records (28 bytes a point instead of
    /// 60), for inputs that must fit a disk (a billion points).
    #[arg(long, conflicts_with = "terrain_truth")]
    pub no_truth: bool,
}

#[derive(clap::Args, Debug)]
pub(super) struct ShapeArgs {
    #[command(flatten)]
    pub common: CommonArgs,

    /// Standard deviation of isotropic Gaussian noise, in metres: added to each of x, y and z
    /// independently (not along the normal), as the CNC paper perturbs its clouds. The truth
    /// columns stay those of the clean sample point. The torus at 80k points is spaced about
    /// 0.077 m, the goursat about 0.15 m.
    #[arg(long, default_value_t = 0.0)]
    pub noise: f64,
}

/// `tilecurv generate ...`.
pub(super) fn generate(args: GenerateArgs) -> Result<i32, i32> {
    match args.kind {
        GenerateKind::Terrain(a) => terrain(a),
        GenerateKind::Torus(a) => shape(Shape::Torus, a),
        GenerateKind::Goursat(a) => shape(Shape::Goursat, a),
    }
}

/// `tilecurv generate terrain`.
fn terrain(args: TerrainArgs) -> Result<i32, i32> {
    let opts = TerrainOptions {
        points: args.common.points,
        density_per_m2: args.density,
        seed: args.common.seed,
        noise: args.noise,
        truth: match (args.no_truth, args.terrain_truth) {
            (true, _) => Truth::None,
            (false, true) => Truth::Terrain,
            (false, false) => Truth::Curvature,
        },
    };
    let s = generate_terrain(&opts, &args.common.output, &CANCEL).map_err(|e| fail(&e))?;
    if !args.common.quiet {
        say!(
            "done: {} points over {:.0} m x {:.0} m ({} strips, {} bumps, z {:.1}..{:.1} m) in {:.1} s ({:.0} points/s) -> {}",
            s.points,
            s.side_m,
            s.side_m,
            s.strips,
            s.bumps,
            s.z_range_m[0],
            s.z_range_m[1],
            s.seconds,
            s.points as f64 / s.seconds.max(1e-9),
            args.common.output.display()
        );
    }
    Ok(exit::OK)
}

/// `tilecurv generate torus` and `tilecurv generate goursat`.
fn shape(shape: Shape, args: ShapeArgs) -> Result<i32, i32> {
    let opts = ShapeOptions {
        shape,
        points: args.common.points,
        noise_m: args.noise,
        seed: args.common.seed,
    };
    let s = generate_shape(&opts, &args.common.output, &CANCEL).map_err(|e| fail(&e))?;
    if !args.common.quiet {
        let [lo, hi] = s.bounds_m;
        say!(
            "done: {} points of the {} (x {:.2}..{:.2}, y {:.2}..{:.2}, z {:.2}..{:.2} m, noise {} m) in {:.1} s -> {}",
            s.points,
            shape.name(),
            lo[0],
            hi[0],
            lo[1],
            hi[1],
            lo[2],
            hi[2],
            opts.noise_m,
            s.seconds,
            args.common.output.display()
        );
    }
    Ok(exit::OK)
}
