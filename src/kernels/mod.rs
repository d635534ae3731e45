//! One file per GPU kernel (`spirv/<name>.comp`): its binding declaration
//! ([`KernelDecl`]), its cost estimate and a function that records it into a
//! [`Batch`](crate::gpu::Batch). The scalar twin of each is
//! `crate::reference::<name>`.

use crate::gpu::KernelDecl;

pub mod finalize_covariance;
pub mod finalize_stats;
pub mod sanitize;
pub mod tsvd_debug;

/// Every kernel, for the reflection test and `mcdenoise bench`.
pub const ALL: &[&KernelDecl] = &[
    &finalize_stats::DECL,
    &finalize_covariance::DECL,
    &sanitize::DECL,
    &tsvd_debug::DECL,
];
