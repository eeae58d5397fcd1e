//! The `tilecurv` binary: everything happens in the library; this only maps the outcome to the
//! process exit code.

fn main() {
    std::process::exit(tilecurv::cli::main_with_args());
}
