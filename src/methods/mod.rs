//! Sequences of kernels. Each method runs either on the GPU (the kernels) or
//! on the CPU (their scalar twins), selected by [`Backend`].

pub mod prepare;
pub mod stats;

/// Where a method runs.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Default)]
pub enum Backend {
    /// GPU kernels through Vulkan.
    #[default]
    Gpu,
    /// The scalar f64 twins (`crate::reference`).
    Cpu,
}
