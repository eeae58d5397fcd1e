//! Fuzz target: the OFF and OBJ readers (mesh vertices) on bytes in memory, the same bytes as
//! both formats (see common.rs).
#![no_main]

#[path = "common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    common::run(tilecurv::io::source::Format::Off, data);
    common::run(tilecurv::io::source::Format::Obj, data);
});
