//! Formats and files: reading point sources, writing outputs atomically, the work directory
//! (lock, manifest, buckets, the tile results journal). No curvature is computed here.

pub(crate) mod columns;
pub mod crs;
pub mod crs_summary;
pub(crate) mod direct;
pub(crate) mod durable;
pub mod info;
pub mod las;
pub(crate) mod las_output;
pub(crate) mod limits;
pub(crate) mod output;
pub(crate) mod pack;
pub mod ply;
pub(crate) mod prefetch;
pub(crate) mod quicklook_png;
pub(crate) mod raster;
pub(crate) mod sink;
pub mod source;
pub(crate) mod workdir;
