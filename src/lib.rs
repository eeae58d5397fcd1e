//! tilecurv: per-point mean, Gaussian and principal curvature for point clouds larger than
//! memory. The data flow:
//!
//! ```text
//! source -> plan -> bucket -> tile (core + halo) -> neighbors -> normals -> estimate -> results -> assemble
//!                                     \______________ compute (per tile) ______________/
//! ```
//! `core` is the pure computation, `io` the formats and files, `run` the stages over the work
//! directory (`process` runs them in one process), `cli` the command line, `tools` generators.

#![warn(missing_docs)]

pub mod cli;
pub mod config;
pub mod core;
pub mod error;
pub mod io;
pub mod progress;
pub mod run;
pub mod tools;

// The library's unit tests use the test kit of tests/kit, which names the library `tilecurv`.
#[cfg(test)]
extern crate self as tilecurv;
#[cfg(test)]
#[path = "../tests/kit/mod.rs"]
mod kit;
