//! # mcdenoise
//!
//! A Vulkan compute denoiser and adaptive-sampling engine for Monte Carlo path
//! tracing. The algorithms are specified in `../shared/docs/algorithms.md`
//! ("the spec"); section numbers below refer to it.
//!
//! ## Layout
//! - [`gpu`]: Vulkan plumbing (the only module that calls `ash`).
//! - [`kernels`]: one file per GPU kernel: its binding declaration and dispatch.
//! - [`reference`]: one file per kernel: the scalar f64 twin, shader-shaped.
//! - [`methods`]: sequences of kernels (statistics, sanitation, ...).
//! - [`io`]: EXR and PNG in and out; [`metrics`]: image error metrics.
//!
//! ## Object model
//! A [`gpu::GpuContext`] (own device, or a host's via the `unsafe`
//! [`gpu::GpuContext::from_raw`]) → buffers ([`gpu::GpuBuffer`],
//! [`gpu::PlaneSet`], or host buffers as [`gpu::BufferSlice`]) → passes
//! recorded into a [`gpu::Batch`] that either submits itself or records into
//! the host's command buffer.

pub mod accum;
pub mod bench;
pub mod error;
pub mod gpu;
pub mod image;
pub mod io;
pub mod kernels;
pub mod methods;
pub mod metrics;
pub mod options;
pub mod reference;
pub mod shared;

pub use error::{Error, Result};
