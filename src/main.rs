//! The `tilecurv` binary: everything happens in the library; this only checks that the CPU can
//! run the build and maps the outcome to the process exit code.

fn main() {
    let missing = tilecurv::missing_cpu_features();
    if !missing.is_empty() {
        eprintln!(
            "tilecurv: this processor lacks {}, which this build of tilecurv uses (it was built for x86-64-v3 by the project's .cargo/config.toml); rebuild it for any x86-64 processor with: RUSTFLAGS=\"-C target-cpu=x86-64\" cargo build --release",
            missing.join(", ")
        );
        std::process::exit(4);
    }
    std::process::exit(tilecurv::main_with_args(std::env::args_os()));
}
