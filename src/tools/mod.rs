//! Tools around the engine: synthetic test data with closed-form curvature.

pub mod generate;
