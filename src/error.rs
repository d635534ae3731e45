//! The library's one error type. `vk::Result` is mapped in exactly one place,
//! [`Error::vk`]; everything a user can get wrong in a file names the file,
//! the layer and, where it applies, the pixel.

use std::path::PathBuf;

use ash::vk;

/// Everything that can go wrong in mcdenoise.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// No Vulkan loader (`libvulkan.so.1`) could be opened.
    #[error(
        "no Vulkan loader found ({0}); install one: apt-get install libvulkan1 mesa-vulkan-drivers"
    )]
    NoLoader(String),

    /// The loader works but no device supports compute, or the requested one is missing.
    #[error("no usable Vulkan device: {0}; for the software device: apt-get install mesa-vulkan-drivers")]
    NoDevice(String),

    /// A Vulkan call failed.
    #[error("Vulkan call {call} failed: {result:?}")]
    Vulkan {
        /// The Vulkan entry point.
        call: &'static str,
        /// What it returned.
        result: vk::Result,
    },

    /// Recorded GPU work failed to run (not a device loss): `vkQueueSubmit`
    /// returned an error such as `ERROR_OUT_OF_DEVICE_MEMORY`, or building a
    /// kernel's pipeline failed. The context stays usable; after an
    /// out-of-memory error ([`Error::is_out_of_memory`]) smaller work may
    /// succeed.
    #[error("{call} failed with {result:?} during {during}")]
    Gpu {
        /// What was running or being built: the kernels of the failed
        /// submit (with their rows), a buffer copy, or a pipeline.
        during: String,
        /// The Vulkan entry point.
        call: &'static str,
        /// What it returned.
        result: vk::Result,
    },

    /// The device was lost (`ERROR_DEVICE_LOST`) while running `during`.
    /// The context cannot continue: every later call on it returns this same
    /// error; create a new [`GpuContext`](crate::GpuContext).
    #[error(
        "the GPU device was lost during {during}; this context cannot continue (create a new one)"
    )]
    DeviceLost {
        /// The kernels (with their rows) or copy of the submit that was
        /// running when the loss was reported.
        during: String,
    },

    /// Waiting for submitted work took longer than the context's fence
    /// timeout ([`GpuContext::set_fence_timeout`](crate::GpuContext::set_fence_timeout)).
    /// The device is treated as hung, as if lost: every later call on the
    /// context returns this same error.
    #[error("the GPU did not finish {during} within {seconds} s (the fence timeout); this context cannot continue (create a new one, or raise the timeout)")]
    Timeout {
        /// The kernels (with their rows) or copy of the submit waited for.
        during: String,
        /// The timeout in seconds.
        seconds: f64,
    },

    /// GPU memory allocation failed.
    #[error("GPU allocation of {name} ({bytes} bytes) failed: {source}")]
    Allocation {
        /// The buffer's name.
        name: String,
        /// Its size.
        bytes: u64,
        /// The allocator's error.
        #[source]
        source: gpu_allocator::AllocationError,
    },

    /// A SPIR-V module does not match what the Rust side declares for it
    /// (found by reflection with naga), or naga cannot read it.
    #[error("kernel {kernel}: {message}")]
    Kernel {
        /// The kernel's name.
        kernel: String,
        /// What disagrees.
        message: String,
    },

    /// The device lacks a feature or a limit is exceeded.
    #[error("device limit: {0}")]
    Limit(String),

    /// A buffer handed to a dispatch has the wrong size or usage.
    #[error("invalid argument: {0}")]
    InvalidArgument(String),

    /// Reading or writing a file failed at the OS level.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },

    /// A file is not a valid input: not an EXR, truncated, unsupported
    /// compression, a missing or ill-sized layer, an unreadable value.
    #[error("{}: {message}", path.display())]
    BadInput {
        /// The file.
        path: PathBuf,
        /// What is wrong, naming the layer and pixel where it applies.
        message: String,
    },

    /// Values that cannot be processed even after sanitation.
    #[error("{0}")]
    BadData(String),

    /// The work was stopped on request (Ctrl-C) between two passes; no
    /// output was written.
    #[error("interrupted")]
    Interrupted,
}

/// The library's result type.
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// The one place a `vk::Result` becomes an [`Error`].
    pub fn vk(call: &'static str) -> impl FnOnce(vk::Result) -> Error {
        move |result| Error::Vulkan { call, result }
    }

    /// Whether this is an out-of-memory error (device or host, from an
    /// allocation, a submit or a pipeline build): the context is still
    /// usable and smaller work may succeed.
    pub fn is_out_of_memory(&self) -> bool {
        let oom = |r: &vk::Result| {
            matches!(
                *r,
                vk::Result::ERROR_OUT_OF_DEVICE_MEMORY | vk::Result::ERROR_OUT_OF_HOST_MEMORY
            )
        };
        match self {
            Error::Allocation { source, .. } => {
                matches!(source, gpu_allocator::AllocationError::OutOfMemory)
            }
            Error::Vulkan { result, .. } | Error::Gpu { result, .. } => oom(result),
            _ => false,
        }
    }

    /// Whether the context this error came from can no longer be used
    /// ([`Error::DeviceLost`] or [`Error::Timeout`]).
    pub fn is_device_lost(&self) -> bool {
        matches!(self, Error::DeviceLost { .. } | Error::Timeout { .. })
    }

    /// A [`Error::BadInput`] for `path`.
    pub fn bad_input(path: impl Into<PathBuf>, message: impl Into<String>) -> Error {
        Error::BadInput {
            path: path.into(),
            message: message.into(),
        }
    }
}
