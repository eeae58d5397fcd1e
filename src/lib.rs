//! tilecurv: per-point mean, Gaussian and principal curvature for point clouds larger than
//! memory. The data flow:
//!
//! ```text
//! source -> plan -> bucket -> tile (core + halo) -> neighbors -> normals -> estimate -> results -> assemble
//!                                     \______________ compute (per tile) ______________/
//! ```
//! `pipeline` runs it; `las_out` writes the file; `progress` reports.

pub mod assemble;
pub mod bucket;
pub mod cli;
pub mod columns;
pub mod compute;
pub mod config;
pub mod crs;
pub mod error;
pub mod estimate;
pub mod generate;
pub mod geometry;
pub mod las;
pub mod las_out;
pub mod neighbors;
pub mod normals;
pub mod orient;
pub mod pipeline;
pub mod plan;
pub mod ply_out;
pub mod progress;
pub mod results;
pub mod sink;
pub mod source;
pub mod synthetic;
pub mod tile;
pub mod workdir;
