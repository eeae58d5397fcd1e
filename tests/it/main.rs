//! Integration tests: the `tilecurv` binary on real and synthetic files.

mod bad_input;
mod closed_form;
mod cluster;
mod common;
mod compact;
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
mod orientation;
mod outofcore;
mod real_files;
mod reference;
mod sample;
mod sampled;
