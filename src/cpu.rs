//! The processor check of the binary and the Python package: this build may use instructions
//! (x86-64-v3: AVX2, FMA, BMI2) the running processor lacks, and the first of them would kill
//! the process with SIGILL instead of saying what to do.

/// The instruction-set extensions this build was compiled to use that the running CPU lacks:
/// the first of their instructions would kill the process with SIGILL. Not inlined, so that
/// nothing compiled for them runs before the check.
#[inline(never)]
pub fn missing_cpu_features() -> Vec<&'static str> {
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
