//! The pure computation: numbers in, numbers out. Nothing here touches a file, a thread, a
//! channel or a clock (rayon's data parallelism inside one call is the one exception), and
//! nothing imports from `io` or `run`, so every piece is tested on numbers alone.

pub mod angle;
pub mod compute;
pub mod estimate;
pub mod geometry;
pub mod grid;
pub mod neighbors;
pub mod normals;
pub mod orient;
pub mod plan;
pub mod point;
pub mod quantize;
pub mod quicklook;
pub mod radix;
pub mod raster;
pub mod rng;
pub mod sampling;
pub mod scale;
pub mod select;
pub mod surface;
pub mod tasks;
pub mod terrain;
pub mod tile;
