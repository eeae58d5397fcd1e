//! tilecurv: per-point mean, Gaussian and principal curvature for point clouds larger than
//! memory. The data flow:
//!
//! ```text
//! source -> plan -> bucket -> tile (core + halo) -> neighbors -> normals -> estimate -> results -> assemble
//!                                     \______________ compute (per tile) ______________/
//! ```
//!
//! The public API is what the binary, the Python package and other crates use:
//!
//! - [`core`]: the pure engine (neighbours, normals, estimators, the tile plan), numbers in and
//!   numbers out;
//! - [`config`]: the options that change the output ([`config::RunOptions`], one table of them),
//!   validated into [`config::RunParams`], and [`config::ExecOptions`];
//! - [`run`]: [`run::process`] (the whole run) and the cluster stages ([`run::cluster`]);
//! - [`io`]: the readers of point clouds ([`io::source`]) and what they report (LAS headers and
//!   records, CRS units, `info`);
//! - [`progress`] (the [`progress::Reporter`] a run reports through), [`error`], [`tools`] (the
//!   generators of clouds with closed-form curvature), [`main_with_args`] (the command line) and
//!   [`info_json`] (what `info --json` prints), and [`missing_cpu_features`] (the processor
//!   check the binary and the Python package make before anything else).
//!
//! Everything else (the work directory's formats, the writers, the stages' insides) is
//! `pub(crate)`: `unreachable_pub` keeps it so.

#![warn(missing_docs, unreachable_pub)]

mod cli;
pub mod config;
pub mod core;
mod cpu;
pub mod error;
pub mod io;
pub mod progress;
pub mod run;
pub mod tools;

pub use cli::{info_json, main_with_args};
pub use cpu::missing_cpu_features;

// The library's unit tests use the test kit of tests/kit, which names the library `tilecurv`.
#[cfg(test)]
extern crate self as tilecurv;
// The kit is shared with the integration tests, which need its items public.
#[cfg(test)]
#[allow(unreachable_pub)]
#[path = "../tests/kit/mod.rs"]
mod kit;
