//! tilecurv: per-point mean, Gaussian and principal curvature for point clouds larger than
//! memory. The data flow (see docs/architecture.md):
//!
//! ```text
//! source -> plan -> bucket -> tile (core + halo) -> neighbours -> normals -> estimate -> results -> assemble
//! ```

pub mod crs;
pub mod error;
pub mod estimate;
pub mod geometry;
pub mod las;
pub mod source;
