//! Fuzz target: the Xyz reader on bytes in memory (see common.rs).
#![no_main]

#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    common::run(tilecurv::io::source::Format::Xyz, data);
});
