//! Test support, not part of the algorithm: exact synthetic inputs for tests, benches,
//! examples and the README.
//!
//! - [`step`]: one UpdateMask step of touching box tops ([`SyntheticStep`]).
//! - [`flow`]: image pairs with exact flow for the optical flow's tests.
//! - [`segment`]: synthetic RGB-D frames for the segmenter's tests.
//! - [`png`]: PNG files whose header lies about their size, for the readers' tests.

pub mod flow;
pub mod png;
pub mod segment;
pub mod step;

pub use step::SyntheticStep;
