//! Scalar f64 twins of the GLSL kernels (`spirv/<name>.comp` ↔
//! `reference/<name>.rs`) and of the shared GLSL libraries
//! (`spirv/lib/<name>.glsl` ↔ [`linalg`], [`tsvd`]).
//!
//! A twin takes the same planes (f32 slices) and push constants as its kernel
//! and loops over the same pixel grid, computing in f64 and storing f32, so
//! any kernel can be replaced by its twin and a GPU/CPU mismatch can be
//! bisected kernel by kernel (spec §0.3 gives the tolerances).

pub mod finalize_covariance;
pub mod finalize_stats;
pub mod linalg;
pub mod sanitize;
pub mod tsvd;
pub mod tsvd_debug;

/// The sample count as every kernel reads it (spec §0.2); a pixel is valid iff
/// `spp_of(n) >= 1`. Mirrors `spp_of` in `spirv/lib/common.glsl`.
pub use finalize_stats::spp_of;
