//! # mcdenoise
//!
//! A Vulkan compute denoiser and adaptive-sampling engine for Monte Carlo path
//! tracing. It reconstructs a render by local regression over the colour and
//! the feature buffers, estimates its own error per pixel, and turns that
//! error into the next pass's sample map. The algorithms are specified in
//! `docs/algorithms.md` ("the spec"); section numbers refer to it.
//!
//! ## The front door: [`Denoiser`]
//!
//! ```no_run
//! use std::sync::Arc;
//! use mcdenoise::{AccumLayout, BufferSlice, Config, Denoiser, GpuContext, Method, Source};
//! # fn demo(ctx: Arc<GpuContext>, cmd: ash::vk::CommandBuffer, family: u32,
//! #     host_buffer: ash::vk::Buffer) -> mcdenoise::Result<()> {
//! // Once per image size and configuration:
//! let layout = AccumLayout::new(256, 256, true, false); // position sums, no visibility
//! let denoiser = Denoiser::new(&ctx, Source::Accum(layout), Config::new(Method::Wlr))?;
//! // Every frame, into the host's command buffer (the host submits it):
//! let accum = unsafe { BufferSlice::from_raw(host_buffer, 0, layout.bytes()) };
//! let recorded = unsafe { denoiser.record_into(cmd, family, Some(accum), Some(65536))? };
//! // ... host submits `cmd` and waits for its fence ...
//! drop(recorded);
//! let out = denoiser.outputs()?; // colour, error, sample map: GPU buffers to bind
//! let frame = denoiser.read()?; // or a host copy of them
//! # Ok(()) }
//! ```
//!
//! - [`GpuContext`]: mcdenoise's own device ([`GpuContext::new`]) or a host
//!   renderer's (`unsafe` [`GpuContext::from_raw`], which states who destroys
//!   what).
//! - [`Denoiser`]: one configuration ([`Config`]: method, pass, precision,
//!   prefilter, options) for one input ([`Source`]: a renderer's
//!   accumulation planes of [`AccumLayout`], or statistics of a file). It
//!   owns its scratch and output buffers and records the whole chain —
//!   finalisation, sanitation (§0.4), G-buffer prefilter (§6), the method,
//!   the error estimate, the sample map (§9) — with no CPU round trip.
//! - [`Denoiser::record_into`] records into the host's command buffer;
//!   [`Denoiser::run`] submits on mcdenoise's own; [`Denoiser::denoise`]
//!   takes statistics in host memory (also on the CPU reference backend),
//!   and [`Denoiser::denoise_owned`] frees them once they are uploaded.
//!   Statistics are sanitised and prefiltered in place on the device, so
//!   each call on [`Source::Stats`] consumes its [`Denoiser::upload`].
//! - Sequences: with [`Config::temporal`] set to [`Temporal::Lp`] every
//!   call is the next frame of a sequence, filtered over time (§10.1) with
//!   a state kept on the GPU; [`Denoiser::reset`] at a cut. Offline, a
//!   [`SequenceDenoiser`] runs APR's temporal window (§10.2,
//!   [`Temporal::Apr`]) over the frames `t−2..t+2` of each frame, or the
//!   filter over the whole sequence in both directions
//!   ([`Temporal::LpSmooth`]; [`Smoother`] for a caller's own temporal
//!   denoiser).
//! - Outputs: [`Denoiser::outputs`] (GPU buffers) or [`Denoiser::read`]
//!   ([`Frame`]: colour, per-channel error `E_i`, local dimension `d_i`,
//!   samples, debug maps).
//!
//! ## Features, other languages, other GPUs
//! `default-features = false` leaves the core (this facade, the methods,
//! the kernels, the Vulkan plumbing); the features `io` (EXR and PNG),
//! `render` (the path tracer), `bench` and `cli` (the default) add the
//! rest. C and C++ hosts use `libmcdenoise` and `include/mcdenoise.h` (the
//! `capi/` crate); every host's shaders can add samples with
//! `include/mcdenoise_accum.glsl`. A device without `shaderFloat64` or
//! `shaderInt64` runs every method ([`ContextOptions::no_64bit`] simulates
//! one); what a device cannot run is an error of
//! [`Denoiser::new`], never of a recording.
//!
//! ## Synchronisation contract (embedding)
//! Work recorded into a host's command buffer starts with a memory barrier
//! after every earlier command of that buffer and ends with one before every
//! later command; it never submits to the host's queue. The host keeps the
//! returned [`Recorded`] until its submission completes; buffers the
//! denoiser owns stay alive until then even if the denoiser is dropped.
//! Dropping a context made by [`GpuContext::from_raw`] does not wait on the
//! host's device.
//!
//! ## Faults
//! Every GPU failure is an [`Error`]: out of memory ([`Error::is_out_of_memory`])
//! names the buffer, kernel or submit and leaves the context usable, so the
//! next call (or a smaller one) can succeed; a lost device or a fence wait
//! longer than [`GpuContext::fence_timeout`] (60 s per submit by default,
//! more for a submit that is the first to run a pipeline:
//! [`GpuContext::submit_timeout`])
//! names the kernels that were running and marks the context lost
//! ([`Error::is_device_lost`]): every later call on it returns the same
//! error, and the caller makes a new context. A constructor that fails
//! half-way destroys what it had created. Output files are written
//! atomically; a full disk or an unwritable path is an [`Error::Io`] naming
//! the file, and leaves no partial file. (`docs/robustness.md` lists the
//! faults tested.)
//!
//! ## Layers
//! `src/bin` (CLI) → this facade → [`methods`] (sequences of kernels) →
//! [`kernels`] (one file per GPU kernel) → [`gpu`] (Vulkan plumbing, the
//! only module that calls `ash`). [`mod@reference`] holds the scalar f64 twin of
//! every kernel; [`io`] reads and writes files on the host.

#![warn(missing_docs)]

pub mod accum;
#[cfg(feature = "bench")]
pub mod bench;
pub mod error;
#[doc(hidden)]
pub mod fault;
pub mod gpu;
pub mod image;
pub mod io;
pub mod kernels;
pub mod methods;
pub mod metrics;
pub mod options;
pub mod reference;
/// The built-in path tracer (issue #10): scenes, a BVH, and a Vulkan compute
/// kernel that accumulates exactly the planes a [`Denoiser`] reads.
#[cfg(feature = "render")]
pub mod render;
pub mod sequence;
pub mod shared;
pub mod spill;

mod denoiser;
pub mod schedule;

pub use accum::{AccumLayout, Accumulator};
pub use denoiser::{default_memory_cap, Config, Denoiser, Frame, Outputs, Source, WarmUp};
pub use error::{Error, Result};
pub use gpu::{
    choose_device, enumerate_devices, timings_per_kernel, Batch, BufferSlice, ContextOptions,
    DeviceInfo, GpuContext, ImportedDevice, KernelTiming, Precision, Recorded, Validation,
};
pub use image::{Layer, RgbImage, StatsImage};
pub use methods::prepare::{colour_of, has_low_spp, has_samples, PrepareReport};
pub use methods::{
    available_names, Backend, InputBlend, Method, MethodInfo, Outliers, Pass, Prefilter,
    ProgressCallback, Pyramid, Temporal, TemporalState, REGISTRY,
};
pub use options::{help_table, Options};
pub use schedule::Schedule;
pub use sequence::{SequenceDenoiser, Smoother};
