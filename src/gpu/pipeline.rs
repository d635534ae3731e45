//! Compute pipelines, built once per (kernel, precision) and cached.
//!
//! Build-once: the cache holds one slot per key, and a thread building a
//! kernel holds that slot's lock (never the whole cache's), so two threads
//! asking for the same pipeline get the same one, built once, while other
//! kernels build in parallel. A failed build leaves the slot empty (the next
//! call tries again) and destroys what it had created.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use ash::vk;

use super::context::GpuContext;
use super::reflect::{spirv, KernelDecl, Precision};
use crate::error::{Error, Result};
use crate::fault::{self, Call, Object};

/// One built kernel variant.
#[derive(Clone, Debug)]
pub struct Pipeline {
    /// Debug label: the kernel name plus the precision suffix (`wlr_fit_f64`);
    /// also the name of the timing rows.
    pub name: String,
    /// Descriptor-set layout: `binding_count` storage buffers in set 0.
    pub set_layout: vk::DescriptorSetLayout,
    /// Pipeline layout: the set layout and one push-constant range of `push_size` bytes.
    pub layout: vk::PipelineLayout,
    /// The compute pipeline.
    pub pipeline: vk::Pipeline,
    /// From reflection (the only source of the workgroup size).
    pub workgroup: [u32; 3],
    /// Number of storage-buffer bindings (= [`KernelDecl::bindings`] length).
    pub binding_count: u32,
    /// Push-constant size in bytes (= [`KernelDecl::push_size`]; 0: no range).
    pub push_size: u32,
}

/// The context's built pipelines, keyed by kernel name and precision; owned
/// by [`GpuContext`] and destroyed with it.
#[derive(Default)]
pub struct PipelineCache {
    map: HashMap<(String, Precision), Slot>,
}

/// One key's pipeline, `None` until built; its lock is held while building.
type Slot = Arc<Mutex<Option<Pipeline>>>;

impl PipelineCache {
    pub(crate) fn destroy(&mut self, device: &ash::Device) {
        for (_, slot) in self.map.drain() {
            let built = slot.lock().unwrap_or_else(|e| e.into_inner()).take();
            if let Some(p) = built {
                drop(Objects {
                    device,
                    set_layout: p.set_layout,
                    layout: p.layout,
                    pipeline: p.pipeline,
                });
            }
        }
    }
}

/// A pipeline's objects, destroyed on drop (null handles are skipped): a
/// build that fails half-way drops what it made; a finished build moves the
/// handles out ([`Objects::keep`]).
struct Objects<'a> {
    device: &'a ash::Device,
    set_layout: vk::DescriptorSetLayout,
    layout: vk::PipelineLayout,
    pipeline: vk::Pipeline,
}

impl Objects<'_> {
    /// The handles, no longer destroyed by this value.
    fn keep(mut self) -> (vk::DescriptorSetLayout, vk::PipelineLayout, vk::Pipeline) {
        (
            std::mem::take(&mut self.set_layout),
            std::mem::take(&mut self.layout),
            std::mem::take(&mut self.pipeline),
        )
    }
}

impl Drop for Objects<'_> {
    fn drop(&mut self) {
        // SAFETY: no recorded work uses them (a failed build was never bound;
        // the cache destroys at teardown after the device is idle); children
        // before parents.
        unsafe {
            if self.pipeline != vk::Pipeline::null() {
                self.device.destroy_pipeline(self.pipeline, None);
                fault::destroyed(Object::Pipeline);
            }
            if self.layout != vk::PipelineLayout::null() {
                self.device.destroy_pipeline_layout(self.layout, None);
                fault::destroyed(Object::PipelineLayout);
            }
            if self.set_layout != vk::DescriptorSetLayout::null() {
                self.device
                    .destroy_descriptor_set_layout(self.set_layout, None);
                fault::destroyed(Object::DescriptorSetLayout);
            }
        }
    }
}

impl GpuContext {
    /// The pipeline of `decl` in `precision`, built (and checked against its
    /// SPIR-V by reflection) on first use; built once even when several
    /// threads ask at the same time (see the module documentation).
    pub fn pipeline(&self, decl: &KernelDecl, precision: Precision) -> Result<Pipeline> {
        self.check_alive()?;
        let key = (decl.name.to_owned(), precision);
        let slot = self
            .pipelines
            .lock()
            .unwrap()
            .map
            .entry(key)
            .or_default()
            .clone();
        // A build that panicked left the slot empty: building again is fine.
        let mut slot = slot.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(p) = slot.as_ref() {
            return Ok(p.clone());
        }
        let p = self.build_pipeline(decl, precision)?;
        *slot = Some(p.clone());
        Ok(p)
    }

    fn build_pipeline(&self, decl: &KernelDecl, precision: Precision) -> Result<Pipeline> {
        if precision == Precision::F64 && !self.f64_enabled {
            return Err(Error::Limit(format!(
                "kernel {}_f64 needs shaderFloat64, which {} does not support",
                decl.name, self.info.name
            )));
        }
        let n = decl.bindings.len() as u32;
        if n > self.info.max_per_stage_storage_buffers {
            return Err(Error::Limit(format!(
                "kernel {} binds {n} storage buffers; the device allows {}",
                decl.name, self.info.max_per_stage_storage_buffers
            )));
        }
        // Without shaderFloat64, a kernel whose f32 variant uses double
        // runs its double-float variant (`<k>_dd`) when it has one.
        let dd = (precision == Precision::F32 && !self.f64_enabled)
            .then(|| super::reflect::spirv_dd(decl.name))
            .flatten();
        let words = match dd {
            Some(w) => w,
            None => spirv(decl.name, precision).ok_or_else(|| Error::Kernel {
                kernel: decl.name.to_owned(),
                message: format!("no compiled SPIR-V for variant {precision:?}"),
            })?,
        };
        let variant = format!(
            "{}{}",
            decl.name,
            if dd.is_some() {
                "_dd"
            } else {
                precision.suffix()
            }
        );
        let reflection = decl.check_words(&variant, words)?;
        if reflection.uses_f64 && !self.f64_enabled {
            return Err(Error::Limit(format!(
                "kernel {}{} uses f64 arithmetic, which needs shaderFloat64; {} does not have it enabled",
                decl.name,
                precision.suffix(),
                self.info.name
            )));
        }
        if reflection.shared_bytes > self.info.max_shared_memory {
            return Err(Error::Limit(format!(
                "kernel {}{} uses {} bytes of shared memory; {} allows {}",
                decl.name,
                precision.suffix(),
                reflection.shared_bytes,
                self.info.name,
                self.info.max_shared_memory
            )));
        }
        if reflection.uses_int64 && !self.int64_enabled {
            return Err(Error::Limit(format!(
                "kernel {}{} uses 64-bit integers, which need shaderInt64; {} does not have it enabled",
                decl.name,
                precision.suffix(),
                self.info.name
            )));
        }
        let label = format!("{}{}", decl.name, precision.suffix());
        let dev = &self.device;

        let bindings: Vec<vk::DescriptorSetLayoutBinding> = (0..n)
            .map(|i| {
                vk::DescriptorSetLayoutBinding::default()
                    .binding(i)
                    .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                    .descriptor_count(1)
                    .stage_flags(vk::ShaderStageFlags::COMPUTE)
            })
            .collect();
        let failed = |call: &'static str| {
            let during = format!("the pipeline build of kernel {label}");
            move |result| Error::Gpu {
                during,
                call,
                result,
            }
        };
        let mut objects = Objects {
            device: dev,
            set_layout: vk::DescriptorSetLayout::null(),
            layout: vk::PipelineLayout::null(),
            pipeline: vk::Pipeline::null(),
        };
        // SAFETY: create infos reference live locals; `objects` destroys what
        // was created if a later step fails, the cache at teardown otherwise.
        unsafe {
            objects.set_layout = fault::vk(Call::CreateDescriptorSetLayout)
                .and_then(|()| {
                    dev.create_descriptor_set_layout(
                        &vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings),
                        None,
                    )
                })
                .map_err(failed("vkCreateDescriptorSetLayout"))?;
            fault::created(Object::DescriptorSetLayout);
            let ranges = [vk::PushConstantRange::default()
                .stage_flags(vk::ShaderStageFlags::COMPUTE)
                .offset(0)
                .size(decl.push_size)];
            let layouts = [objects.set_layout];
            let mut layout_info = vk::PipelineLayoutCreateInfo::default().set_layouts(&layouts);
            if decl.push_size > 0 {
                layout_info = layout_info.push_constant_ranges(&ranges);
            }
            objects.layout = fault::vk(Call::CreatePipelineLayout)
                .and_then(|()| dev.create_pipeline_layout(&layout_info, None))
                .map_err(failed("vkCreatePipelineLayout"))?;
            fault::created(Object::PipelineLayout);
            let module = fault::vk(Call::CreateShaderModule)
                .and_then(|()| {
                    dev.create_shader_module(
                        &vk::ShaderModuleCreateInfo::default().code(words),
                        None,
                    )
                })
                .map_err(failed("vkCreateShaderModule"))?;
            fault::created(Object::ShaderModule);
            let stage = vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::COMPUTE)
                .module(module)
                .name(c"main");
            let info = [vk::ComputePipelineCreateInfo::default()
                .stage(stage)
                .layout(objects.layout)];
            let cache = self.disk_cache_handle();
            let pipeline = fault::vk(Call::CreateComputePipeline)
                .and_then(|()| {
                    dev.create_compute_pipelines(cache, &info, None)
                        .map_err(|(_, e)| e)
                })
                .map_err(failed("vkCreateComputePipelines"));
            if pipeline.is_ok() {
                self.mark_disk_cache_dirty();
            }
            // The module is only needed while the pipeline is created.
            dev.destroy_shader_module(module, None);
            fault::destroyed(Object::ShaderModule);
            release_compiler_heap();
            objects.pipeline = pipeline?[0];
            fault::created(Object::Pipeline);
            self.name_object(objects.pipeline, &label);
            let (set_layout, layout, pipeline) = objects.keep();
            Ok(Pipeline {
                name: label,
                set_layout,
                layout,
                pipeline,
                workgroup: reflection.workgroup_size,
                binding_count: n,
                push_size: decl.push_size,
            })
        }
    }
}

/// Returns the heap pages a pipeline compile freed to the system. lavapipe
/// compiles every pipeline with LLVM on the process heap; glibc keeps what
/// the compiler freed as resident memory (41 MB of LP's 570 MB peak at
/// 1 MP, 68 MB of WLR's 541; decision HEAP-TRIM).
/// `malloc_trim(0)` gives the free pages inside the heap back, once per
/// pipeline (a context builds each once); LP's whole process did not get
/// measurably slower.
fn release_compiler_heap() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only releases free memory of the allocator.
    unsafe {
        libc::malloc_trim(0);
    }
}

/// A `VkPipelineCache` kept on disk ([`GpuContext::use_pipeline_cache`]):
/// every pipeline the context builds afterwards goes through it, and it is
/// written back to `path` by [`GpuContext::save_pipeline_cache`] and when
/// the context is dropped, if a pipeline was built since it was loaded.
pub(crate) struct DiskCache {
    pub(crate) handle: vk::PipelineCache,
    pub(crate) path: std::path::PathBuf,
    /// A pipeline was built through the cache since it was loaded or saved.
    pub(crate) dirty: bool,
}

/// Bytes of the header Vulkan puts before a pipeline cache's data
/// (`VkPipelineCacheHeaderVersionOne`).
const CACHE_HEADER_BYTES: usize = 32;

/// Whether `data` starts as a Vulkan pipeline cache of any device: a
/// header of version one (`VkPipelineCacheHeaderVersionOne`) whose length
/// fits the data.
pub(crate) fn is_pipeline_cache(data: &[u8]) -> bool {
    if data.len() < CACHE_HEADER_BYTES {
        return false;
    }
    let header_len = header_word(data, 0) as usize;
    (CACHE_HEADER_BYTES..=data.len()).contains(&header_len)
        && header_word(data, 1) == vk::PipelineCacheHeaderVersion::ONE.as_raw() as u32
}

/// The `i`th little-endian u32 of a pipeline cache's header (at least
/// [`CACHE_HEADER_BYTES`] long).
fn header_word(data: &[u8], i: usize) -> u32 {
    u32::from_le_bytes(data[4 * i..4 * i + 4].try_into().unwrap())
}

/// Whether `data` is a pipeline cache of this device: header version one,
/// the device's vendor and device IDs and its `pipelineCacheUUID`. Data of
/// another device or driver is not handed to the driver (the spec lets it
/// ignore such data, but not every driver checks it carefully).
pub(crate) fn cache_matches(data: &[u8], props: &vk::PhysicalDeviceProperties) -> bool {
    is_pipeline_cache(data)
        && header_word(data, 2) == props.vendor_id
        && header_word(data, 3) == props.device_id
        && data[16..32] == props.pipeline_cache_uuid
}

/// Writes `bytes` to `path` atomically ([`crate::io::write_atomic`]),
/// creating its folder first.
pub(crate) fn write_cache_file(path: &std::path::Path, bytes: &[u8]) -> Result<()> {
    use std::io::Write as _;
    let io_err = |source| Error::Io {
        path: path.to_path_buf(),
        source,
    };
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(io_err)?;
    }
    crate::io::write_atomic(path, |w| w.write_all(bytes).map_err(io_err))
}
