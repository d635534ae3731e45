//! Compute pipelines, built once per (kernel, precision) and cached.

use std::collections::HashMap;

use ash::vk;

use super::context::GpuContext;
use super::reflect::{spirv, KernelDecl, Precision};
use crate::error::{Error, Result};

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
    map: HashMap<(String, Precision), Pipeline>,
}

impl PipelineCache {
    pub(crate) fn destroy(&mut self, device: &ash::Device) {
        for (_, p) in self.map.drain() {
            // SAFETY: called at teardown after the device is idle.
            unsafe {
                device.destroy_pipeline(p.pipeline, None);
                device.destroy_pipeline_layout(p.layout, None);
                device.destroy_descriptor_set_layout(p.set_layout, None);
            }
        }
    }
}

impl GpuContext {
    /// The pipeline of `decl` in `precision`, built (and checked against its
    /// SPIR-V by reflection) on first use.
    pub fn pipeline(&self, decl: &KernelDecl, precision: Precision) -> Result<Pipeline> {
        let key = (decl.name.to_owned(), precision);
        if let Some(p) = self.pipelines.lock().unwrap().map.get(&key) {
            return Ok(p.clone());
        }
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
        let reflection = decl.check(precision)?;
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
        let words = spirv(decl.name, precision).expect("checked above");
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
        // SAFETY: create infos reference live locals; objects are destroyed by
        // the cache at teardown.
        unsafe {
            let set_layout = dev
                .create_descriptor_set_layout(
                    &vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings),
                    None,
                )
                .map_err(Error::vk("vkCreateDescriptorSetLayout"))?;
            let ranges = [vk::PushConstantRange::default()
                .stage_flags(vk::ShaderStageFlags::COMPUTE)
                .offset(0)
                .size(decl.push_size)];
            let layouts = [set_layout];
            let mut layout_info = vk::PipelineLayoutCreateInfo::default().set_layouts(&layouts);
            if decl.push_size > 0 {
                layout_info = layout_info.push_constant_ranges(&ranges);
            }
            let layout = dev
                .create_pipeline_layout(&layout_info, None)
                .map_err(Error::vk("vkCreatePipelineLayout"))?;
            let module = dev
                .create_shader_module(&vk::ShaderModuleCreateInfo::default().code(words), None)
                .map_err(Error::vk("vkCreateShaderModule"))?;
            let stage = vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::COMPUTE)
                .module(module)
                .name(c"main");
            let info = [vk::ComputePipelineCreateInfo::default()
                .stage(stage)
                .layout(layout)];
            let pipeline = dev
                .create_compute_pipelines(vk::PipelineCache::null(), &info, None)
                .map_err(|(_, e)| Error::vk("vkCreateComputePipelines")(e));
            dev.destroy_shader_module(module, None);
            let pipeline = pipeline?[0];
            self.name_object(pipeline, &label);
            let p = Pipeline {
                name: label,
                set_layout,
                layout,
                pipeline,
                workgroup: reflection.workgroup_size,
                binding_count: n,
                push_size: decl.push_size,
            };
            self.pipelines.lock().unwrap().map.insert(key, p.clone());
            Ok(p)
        }
    }
}
