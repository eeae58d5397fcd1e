//! Formats and files: reading point sources, writing outputs atomically, the work directory
//! (lock, manifest, buckets, the tile results journal). No curvature is computed here.

pub mod columns;
pub mod crs;
pub mod crs_summary;
pub mod direct;
pub mod durable;
pub mod info;
pub mod las;
pub mod las_output;
pub mod limits;
pub mod output;
pub mod pack;
pub mod ply;
pub mod sink;
pub mod source;
pub mod workdir;
