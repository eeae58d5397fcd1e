//! Integration tests: the `tilecurv` binary on real and synthetic files.

mod auto;
mod bad_input;
mod classes;
mod closed_form;
mod cluster;
mod common;
mod compact;
mod damaged;
mod faults;
mod features;
mod formats;
mod hostile;
mod info;
mod interop;
mod invariance;
#[path = "../kit/mod.rs"]
mod kit;
mod kit_checks;
mod layout;
mod memory;
mod offsets;
mod order;
mod orientation;
mod outofcore;
mod radius;
mod raster;
mod raster_refusals;
mod real_files;
mod reference;
mod rerun;
mod sample;
mod sampled;
mod scan_split;
mod shapes;
mod terrain;
mod units;
