//! Kernel declarations and their check against the compiled SPIR-V.
//!
//! Every kernel's host file declares its bindings and push-constant struct once
//! (a [`KernelDecl`]). [`reflect`] reads the SPIR-V with naga and
//! [`KernelDecl::check`] fails if binding numbers, storage access or the
//! push-constant size disagree. The workgroup size used for dispatch comes from
//! the reflection, never from a second copy of it.

use super::buffer::BufferSlice;
use crate::error::{Error, Result};

/// Storage access of one binding, as the shader declares it.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Access {
    /// `readonly buffer`
    Read,
    /// plain `buffer` (naga rejects glslang's `writeonly`, so outputs are read-write)
    ReadWrite,
}

/// One storage-buffer binding (set 0, binding = its index in [`KernelDecl::bindings`]).
#[derive(Copy, Clone, Debug)]
pub struct BindingDecl {
    /// Name of the binding in error messages (`spp`, `value_out`); not checked
    /// against the shader.
    pub name: &'static str,
    /// Whether the shader only reads the buffer or also writes it.
    pub access: Access,
    /// What the bound range must hold; checked before a dispatch is recorded.
    pub extent: Extent,
}

/// How many bytes a binding must hold for a dispatch. [`Batch`](super::Batch)
/// checks [`Extent::Planes`] itself, before anything is recorded; a kernel's
/// `record` checks [`Extent::Record`] bindings with
/// [`KernelDecl::require`].
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Extent {
    /// `n` planes of 4-byte values (f32 or u32) of the image the push
    /// constants name (their first two u32: width, height): at least
    /// `4·n·width·height` bytes.
    Planes(u32),
    /// Sized by something else (a band of rows, a queue, a tree, a state
    /// ring): the kernel's `record` checks it. The built-in renderer's
    /// bindings, its own buffers sized when it is made, are declared so too.
    Record,
}

impl BindingDecl {
    /// This binding holds `n` planes of the image ([`Extent::Planes`]).
    pub const fn planes(self, n: u32) -> BindingDecl {
        BindingDecl {
            extent: Extent::Planes(n),
            ..self
        }
    }
    /// This binding's size is checked by the kernel's `record`
    /// ([`Extent::Record`]).
    pub const fn sized_by_record(self) -> BindingDecl {
        BindingDecl {
            extent: Extent::Record,
            ..self
        }
    }
}

/// What the host knows about a kernel: its name (= `spirv/<name>.comp`), its
/// bindings in binding order, and its push-constant size in bytes.
#[derive(Copy, Clone, Debug)]
pub struct KernelDecl {
    /// Kernel name: `spirv/<name>.comp`, and the base of the pipeline label and
    /// of the timing rows (plus `_f64` for that variant).
    pub name: &'static str,
    /// Storage-buffer bindings of set 0, in binding order.
    pub bindings: &'static [BindingDecl],
    /// Push-constant size in bytes: `size_of` the `crate::shared` struct the
    /// kernel's block mirrors (0 if it has none).
    pub push_size: u32,
}

/// A [`BindingDecl`] the kernel only reads ([`Access::Read`]), one plane of
/// the image; with [`fn@write`], the shorthand of the binding tables.
pub const fn read(name: &'static str) -> BindingDecl {
    BindingDecl {
        name,
        access: Access::Read,
        extent: Extent::Planes(1),
    }
}
/// A [`BindingDecl`] the kernel writes ([`Access::ReadWrite`]), one plane
/// of the image.
pub const fn write(name: &'static str) -> BindingDecl {
    BindingDecl {
        name,
        access: Access::ReadWrite,
        extent: Extent::Planes(1),
    }
}

/// Compute precision of a kernel variant (spec §0.3).
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, Default)]
pub enum Precision {
    /// f32 arithmetic, the default on every device.
    #[default]
    F32,
    /// f64 arithmetic (`<kernel>_f64`), where the device supports `shaderFloat64`.
    F64,
}

impl Precision {
    /// Suffix of the kernel variant's name: `""` for f32, `"_f64"` for f64.
    pub fn suffix(self) -> &'static str {
        match self {
            Precision::F32 => "",
            Precision::F64 => "_f64",
        }
    }
}

/// What reflection found in a module.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Reflection {
    /// `(binding, access)` of every storage buffer in set 0, sorted by binding.
    pub bindings: Vec<(u32, Access)>,
    /// Size of the push-constant block, 0 if none.
    pub push_size: u32,
    /// `local_size_x/y/z` of the entry point; dispatch sizes are computed from it.
    pub workgroup_size: [u32; 3],
    /// Bytes of workgroup-shared memory.
    pub shared_bytes: u32,
    /// Whether the module uses 64-bit floats (needs `shaderFloat64`). The
    /// WLR kernels do even in their f32 variant: spec §0.3 keeps the
    /// parametric fits and the h_opt formula in f64.
    pub uses_f64: bool,
    /// Whether the module uses 64-bit integers (needs `shaderInt64`).
    pub uses_int64: bool,
}

/// The SPIR-V words of a compiled kernel variant (`name` + precision suffix).
pub fn spirv(name: &str, precision: Precision) -> Option<&'static [u32]> {
    spirv_named(&format!("{name}{}", precision.suffix()))
}

/// The compiled SPIR-V of the variant named `full` (`<k>`, `<k>_f64` or
/// `<k>_dd`).
pub fn spirv_named(full: &str) -> Option<&'static [u32]> {
    super::shaders::SHADERS
        .iter()
        .find(|(n, _)| *n == full)
        .map(|(_, w)| *w)
}

/// The `<k>_dd` variant of a kernel whose f32 variant uses double (WLR's
/// steps 6-7): double-float arithmetic instead, for a device without
/// `shaderFloat64`. `None` for every other kernel.
pub fn spirv_dd(name: &str) -> Option<&'static [u32]> {
    spirv_named(&format!("{name}_dd"))
}

/// Parses, validates and reflects one SPIR-V module with naga.
pub fn reflect(kernel: &str, words: &[u32]) -> Result<Reflection> {
    let fail = |message: String| Error::Kernel {
        kernel: kernel.to_owned(),
        message,
    };
    let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
    let options = naga::front::spv::Options {
        adjust_coordinate_space: false,
        strict_capabilities: false,
        block_ctx_dump_prefix: None,
    };
    let module = naga::front::spv::parse_u8_slice(&bytes, &options)
        .map_err(|e| fail(format!("naga cannot parse the SPIR-V: {e}")))?;
    let caps = naga::valid::Capabilities::IMMEDIATES
        | naga::valid::Capabilities::FLOAT64
        | naga::valid::Capabilities::SHADER_INT64;
    naga::valid::Validator::new(naga::valid::ValidationFlags::all(), caps)
        .validate(&module)
        .map_err(|e| fail(format!("naga validation failed: {:?}", e.into_inner())))?;

    let mut layouter = naga::proc::Layouter::default();
    layouter
        .update(module.to_ctx())
        .map_err(|e| fail(format!("layout: {e}")))?;

    let mut bindings = Vec::new();
    let mut push_size = 0;
    let mut shared_bytes = 0;
    for (_, var) in module.global_variables.iter() {
        match var.space {
            naga::AddressSpace::Storage { access } => {
                let b = var
                    .binding
                    .as_ref()
                    .ok_or_else(|| fail("storage buffer without binding".into()))?;
                if b.group != 0 {
                    return Err(fail(format!(
                        "binding {} is in set {}, expected 0",
                        b.binding, b.group
                    )));
                }
                let acc = if access.contains(naga::StorageAccess::STORE) {
                    Access::ReadWrite
                } else {
                    Access::Read
                };
                bindings.push((b.binding, acc));
            }
            naga::AddressSpace::Immediate => push_size = layouter[var.ty].size,
            naga::AddressSpace::WorkGroup => shared_bytes += layouter[var.ty].size,
            naga::AddressSpace::Uniform | naga::AddressSpace::Handle => {
                return Err(fail(
                    "only storage buffers and push constants are supported".into(),
                ))
            }
            _ => {}
        }
    }
    bindings.sort_by_key(|b| b.0);
    let uses_f64 = module.types.iter().any(|(_, t)| {
        matches!(
            t.inner,
            naga::TypeInner::Scalar(naga::Scalar {
                kind: naga::ScalarKind::Float,
                width: 8
            }) | naga::TypeInner::Vector {
                scalar: naga::Scalar {
                    kind: naga::ScalarKind::Float,
                    width: 8
                },
                ..
            } | naga::TypeInner::Matrix {
                scalar: naga::Scalar {
                    kind: naga::ScalarKind::Float,
                    width: 8
                },
                ..
            }
        )
    });
    let uses_int64 = module.types.iter().any(|(_, t)| {
        let wide_int = |s: &naga::Scalar| {
            matches!(s.kind, naga::ScalarKind::Uint | naga::ScalarKind::Sint) && s.width == 8
        };
        match &t.inner {
            naga::TypeInner::Scalar(s) => wide_int(s),
            naga::TypeInner::Vector { scalar, .. } => wide_int(scalar),
            _ => false,
        }
    });
    let ep = module
        .entry_points
        .iter()
        .find(|e| e.stage == naga::ShaderStage::Compute)
        .ok_or_else(|| fail("no compute entry point".into()))?;
    Ok(Reflection {
        bindings,
        push_size,
        workgroup_size: ep.workgroup_size,
        shared_bytes,
        uses_f64,
        uses_int64,
    })
}

impl KernelDecl {
    /// `Err` unless `slice`, bound at `index`, holds at least `bytes`: how a
    /// kernel's `record` checks a binding declared [`Extent::Record`]
    /// before anything is recorded.
    pub fn require(&self, index: usize, slice: &BufferSlice, bytes: u64) -> Result<()> {
        if slice.size < bytes {
            return Err(Error::InvalidArgument(format!(
                "kernel {} binding {index} ({}) holds {} bytes; this dispatch needs {bytes}",
                self.name,
                self.bindings.get(index).map_or("?", |b| b.name),
                slice.size
            )));
        }
        Ok(())
    }

    /// Reflects the kernel's `precision` variant and compares it with this
    /// declaration. Returns the reflection (for the workgroup size).
    pub fn check(&self, precision: Precision) -> Result<Reflection> {
        let words = spirv(self.name, precision).ok_or_else(|| Error::Kernel {
            kernel: self.name.to_owned(),
            message: format!("no compiled SPIR-V for variant {precision:?}"),
        })?;
        self.check_words(&format!("{}{}", self.name, precision.suffix()), words)
    }

    /// [`check`](Self::check) of the SPIR-V `words` of variant `label`.
    pub fn check_words(&self, label: &str, words: &[u32]) -> Result<Reflection> {
        let r = reflect(self.name, words)?;
        let fail = |message: String| Error::Kernel {
            kernel: label.to_owned(),
            message,
        };
        let declared: Vec<(u32, Access)> = self
            .bindings
            .iter()
            .enumerate()
            .map(|(i, b)| (i as u32, b.access))
            .collect();
        if declared != r.bindings {
            return Err(fail(format!(
                "bindings disagree: Rust declares {declared:?}, SPIR-V has {:?}",
                r.bindings
            )));
        }
        // The shader's block may be smaller than the Rust struct only by the
        // trailing padding the struct adds for 16-byte alignment.
        if r.push_size > self.push_size || self.push_size - r.push_size >= 16 {
            return Err(fail(format!(
                "push-constant size disagrees: Rust {} bytes, SPIR-V {} bytes",
                self.push_size, r.push_size
            )));
        }
        Ok(r)
    }
}
