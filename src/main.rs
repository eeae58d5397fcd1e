//! The `tilecurv` binary: everything happens in the library; this only checks that the CPU can
//! run the build and maps the outcome to the process exit code.

fn main() {
    let missing = missing_cpu_features();
    if !missing.is_empty() {
        eprintln!(
            "tilecurv: this processor lacks {}, which this build of tilecurv uses (it was built for x86-64-v3 by the project's .cargo/config.toml); rebuild it for any x86-64 processor with: RUSTFLAGS=\"-C target-cpu=x86-64\" cargo build --release",
            missing.join(", ")
        );
        std::process::exit(4);
    }
    std::process::exit(tilecurv::main_with_args(std::env::args_os()));
}

/// The instruction-set extensions this build was compiled to use that the running CPU lacks:
/// the first of their instructions would kill the process with SIGILL. Not inlined, so that
/// nothing compiled for them runs before the check.
#[inline(never)]
fn missing_cpu_features() -> Vec<&'static str> {
    #[allow(unused_mut)]
    let mut missing = Vec::new();
    #[cfg(target_arch = "x86_64")]
    {
        macro_rules! check {
            ($($f:tt),*) => {$(
                if cfg!(target_feature = $f) && !std::arch::is_x86_feature_detected!($f) {
                    missing.push($f);
                }
            )*};
        }
        check!("avx", "avx2", "fma", "bmi1", "bmi2", "lzcnt", "movbe", "f16c");
    }
    missing
}
