//! The test kit: synthetic surfaces with closed-form curvature, samplers, an exact k-NN and the
//! shared estimator scenarios. Compiled only into tests and benchmarks (the library includes it
//! under `cfg(test)` for its unit tests), never into the shipped library. Its files name the
//! library as `tilecurv::`, which the library's own tests alias to itself.
#![allow(dead_code, unused_imports)]

pub mod synthetic;
pub mod testkit;
