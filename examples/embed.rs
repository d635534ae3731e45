//! A renderer-shaped host written with raw `ash`: its own instance, device,
//! queue, command buffer and accumulation buffer, which its own compute
//! shader fills (`examples/c/accumulate.comp`, shared with the C example: a
//! noisy gradient with an edge, added with `include/mcdenoise_accum.glsl`).
//! It hands the buffer to mcdenoise, which records its whole chain into the
//! host's command buffer; the host submits, reads colour, error and the next
//! pass's sample map, then renders a second pass where the map says (its
//! shader binds the map where it lies on the GPU) and denoises again.
//!
//! `cargo run --release --example embed` (CI runs it through `tests/examples.rs`).
//! Exits non-zero if the result is wrong: the sample map must spend exactly
//! the budget, and each reconstruction must be closer to the noise-free
//! image than the input.

use ash::vk;

const W: usize = 64;
const H: usize = 48;
const SPP: usize = 8;
const BUDGET: u32 = (W * H * 4) as u32;

/// The noise-free radiance of the scene at pixel (x, y).
fn truth(x: usize, y: usize) -> f32 {
    (if x < W / 2 { 0.2 } else { 1.0 }) * (0.5 + y as f32 / H as f32)
}

/// Validation-layer messages (errors and warnings) seen by the host.
static MESSAGES: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

unsafe extern "system" fn on_message(
    _severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _types: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    _user: *mut std::ffi::c_void,
) -> vk::Bool32 {
    let msg = unsafe { data.as_ref().and_then(|d| d.message_as_c_str()) };
    eprintln!("validation: {msg:?}");
    MESSAGES.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
    vk::FALSE
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // ---- The host renderer's own Vulkan objects (no mcdenoise involved). ----
    // With MCDENOISE_EMBED_VALIDATION=1 the host enables the Khronos
    // validation layer and fails on any message (CI does).
    let entry = unsafe { ash::Entry::load()? };
    let app = vk::ApplicationInfo::default().api_version(vk::API_VERSION_1_1);
    let validate = std::env::var("MCDENOISE_EMBED_VALIDATION").is_ok_and(|v| v == "1");
    let layers = [c"VK_LAYER_KHRONOS_validation".as_ptr()];
    let exts = [ash::ext::debug_utils::NAME.as_ptr()];
    let mut info = vk::InstanceCreateInfo::default().application_info(&app);
    if validate {
        info = info
            .enabled_layer_names(&layers)
            .enabled_extension_names(&exts);
    }
    let instance = unsafe { entry.create_instance(&info, None)? };
    let debug_utils = ash::ext::debug_utils::Instance::new(&entry, &instance);
    let messenger = if validate {
        let severity = vk::DebugUtilsMessageSeverityFlagsEXT::ERROR
            | vk::DebugUtilsMessageSeverityFlagsEXT::WARNING;
        let types = vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
            | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION;
        let info = vk::DebugUtilsMessengerCreateInfoEXT::default()
            .message_severity(severity)
            .message_type(types)
            .pfn_user_callback(Some(on_message));
        Some(unsafe { debug_utils.create_debug_utils_messenger(&info, None)? })
    } else {
        None
    };
    let physical = unsafe { instance.enumerate_physical_devices()? }[0];
    let family = unsafe { instance.get_physical_device_queue_family_properties(physical) }
        .iter()
        .position(|q| q.queue_flags.contains(vk::QueueFlags::COMPUTE))
        .ok_or("no compute queue")? as u32;
    let supported = unsafe { instance.get_physical_device_features(physical) };
    let features = vk::PhysicalDeviceFeatures::default()
        .shader_float64(supported.shader_float64 == vk::TRUE)
        .shader_int64(supported.shader_int64 == vk::TRUE);
    let prio = [1.0];
    let queues = [vk::DeviceQueueCreateInfo::default()
        .queue_family_index(family)
        .queue_priorities(&prio)];
    let device = unsafe {
        instance.create_device(
            physical,
            &vk::DeviceCreateInfo::default()
                .queue_create_infos(&queues)
                .enabled_features(&features),
            None,
        )?
    };
    let queue = unsafe { device.get_device_queue(family, 0) };

    // The renderer's accumulation buffer (layout: include/mcdenoise_accum.glsl,
    // mcdenoise::accum), filled by its own shader.
    let layout = mcdenoise::AccumLayout::new(W, H, false, false);
    let (buffer, memory) = device_buffer(&instance, physical, &device, layout.bytes())?;
    let host = Host::new(&device, family)?;

    // ---- mcdenoise-facing code. ----
    let ctx = std::sync::Arc::new(unsafe {
        mcdenoise::GpuContext::from_raw(mcdenoise::ImportedDevice {
            entry: entry.clone(),
            instance: instance.clone(),
            physical_device: physical,
            device: device.clone(),
            queue,
            queue_family_index: family,
            shader_float64_enabled: supported.shader_float64 == vk::TRUE,
            shader_int64_enabled: supported.shader_int64 == vk::TRUE,
        })?
    });
    let mut config = mcdenoise::Config::new(mcdenoise::Method::Wlr);
    config.low_spp = false; // every pixel gets 0 or at least 2 samples
    let denoiser = mcdenoise::Denoiser::new(&ctx, mcdenoise::Source::Accum(layout), config)?;
    let accum = unsafe { mcdenoise::BufferSlice::from_raw(buffer, 0, layout.bytes()) };
    // The host's shader reads mcdenoise's sample map where it lies.
    let map = denoiser.outputs()?.samples.ok_or("no sample map")?;
    host.bind(&device, buffer, layout.bytes(), map);

    let mut first = 0.0;
    let mut total = 0;
    for pass in 0..2u32 {
        let cmd = host.cmd;
        unsafe { device.begin_command_buffer(cmd, &vk::CommandBufferBeginInfo::default())? };
        if pass == 0 {
            host.clear(&device, buffer);
        }
        // The host's own pass: this pass's samples into the accumulation.
        host.accumulate(&device, pass, layout.plane_stride() as u32 / 4);
        // Then mcdenoise's chain (it brings its own barriers); a sample map
        // for the next pass after pass 0.
        let budget = (pass == 0).then_some(BUDGET);
        let recorded = unsafe { denoiser.record_into(cmd, family, Some(accum), budget)? };
        unsafe {
            device.end_command_buffer(cmd)?;
            device.queue_submit(
                queue,
                &[vk::SubmitInfo::default().command_buffers(&[cmd])],
                host.fence,
            )?;
            device.wait_for_fences(&[host.fence], true, u64::MAX)?;
            device.reset_fences(&[host.fence])?;
            device.reset_command_buffer(cmd, vk::CommandBufferResetFlags::empty())?;
        }
        drop(recorded); // the work has completed
        let frame = denoiser.read()?;

        // ---- Checks a renderer would care about. ----
        let rmse = rel_mse(&frame.color);
        // The input's expected relative MSE: variance truth²/3 per sample.
        let input = 1.0 / (3.0 * SPP as f64);
        println!("pass {pass}: rMSE {rmse:.5} (input about {input:.5})");
        println!(
            "mean estimated error {:.5}",
            frame.error.planes[0].iter().sum::<f32>() / (W * H) as f32
        );
        if pass == 0 {
            let samples = frame.samples.as_ref().ok_or("no sample map")?;
            total = samples.iter().map(|&s| s as u64).sum::<u64>();
            println!(
                "sample map: {total} samples for a budget of {BUDGET}, max {} per pixel",
                samples.iter().max().unwrap()
            );
            first = rmse;
        } else if rmse >= first {
            return Err("the second pass did not lower the error".into());
        }
        if rmse >= 0.5 * input {
            return Err("the reconstruction is not better than its input".into());
        }
    }
    println!("device: {}", ctx.info().name);

    drop(denoiser);
    drop(ctx);
    host.destroy(&device);
    unsafe {
        device.destroy_buffer(buffer, None);
        device.free_memory(memory, None);
        device.destroy_device(None);
        if let Some(m) = messenger {
            debug_utils.destroy_debug_utils_messenger(m, None);
        }
        instance.destroy_instance(None);
    }
    let messages = MESSAGES.load(std::sync::atomic::Ordering::SeqCst);
    println!(
        "validation layer: {}, {messages} messages",
        if validate { "on" } else { "off" }
    );
    if total != BUDGET as u64 || messages > 0 {
        return Err("wrong result".into());
    }
    Ok(())
}

/// Relative MSE of an image against `truth`.
fn rel_mse(img: &mcdenoise::RgbImage) -> f64 {
    let mut sum = 0.0;
    for plane in &img.planes {
        for (p, &v) in plane.iter().enumerate() {
            let t = truth(p % W, p / W) as f64;
            sum += (v as f64 - t).powi(2) / (t * t + 0.01);
        }
    }
    sum / (3 * W * H) as f64
}

/// A device-local storage buffer (the host's own allocation code).
fn device_buffer(
    instance: &ash::Instance,
    physical: vk::PhysicalDevice,
    device: &ash::Device,
    size: u64,
) -> Result<(vk::Buffer, vk::DeviceMemory), vk::Result> {
    unsafe {
        // mcdenoise copies the count plane out of it: TRANSFER_SRC.
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER
            | vk::BufferUsageFlags::TRANSFER_SRC
            | vk::BufferUsageFlags::TRANSFER_DST;
        let buffer = device.create_buffer(
            &vk::BufferCreateInfo::default().size(size).usage(usage),
            None,
        )?;
        let req = device.get_buffer_memory_requirements(buffer);
        let props = instance.get_physical_device_memory_properties(physical);
        let fits = |i: u32, want: vk::MemoryPropertyFlags| {
            req.memory_type_bits & (1 << i) != 0
                && props.memory_types[i as usize].property_flags.contains(want)
        };
        let ty = (0..props.memory_type_count)
            .find(|&i| fits(i, vk::MemoryPropertyFlags::DEVICE_LOCAL))
            .or_else(|| {
                (0..props.memory_type_count).find(|&i| fits(i, vk::MemoryPropertyFlags::empty()))
            })
            .ok_or(vk::Result::ERROR_FEATURE_NOT_PRESENT)?;
        let memory = device.allocate_memory(
            &vk::MemoryAllocateInfo::default()
                .allocation_size(req.size)
                .memory_type_index(ty),
            None,
        )?;
        device.bind_buffer_memory(buffer, memory, 0)?;
        Ok((buffer, memory))
    }
}

/// The host renderer's accumulation pass: `examples/c/accumulate.comp`
/// (binding 0 the accumulation buffer, binding 1 the sample map), its
/// command buffer and fence.
struct Host {
    module: vk::ShaderModule,
    set_layout: vk::DescriptorSetLayout,
    pipeline_layout: vk::PipelineLayout,
    pipeline: vk::Pipeline,
    pool: vk::DescriptorPool,
    set: vk::DescriptorSet,
    cmd_pool: vk::CommandPool,
    cmd: vk::CommandBuffer,
    fence: vk::Fence,
}

/// The shader's push constants.
#[repr(C)]
#[derive(Copy, Clone, bytemuck::Pod, bytemuck::Zeroable)]
struct Push {
    width: u32,
    height: u32,
    pass_index: u32,
    uniform_spp: u32,
    stride: u32,
    /// A sequence's frame (fresh noise); 0 here, a single image.
    frame: u32,
}

impl Host {
    fn new(device: &ash::Device, family: u32) -> Result<Host, vk::Result> {
        let spv = include_bytes!(concat!(env!("OUT_DIR"), "/accumulate.spv"));
        let words: Vec<u32> = spv
            .chunks_exact(4)
            .map(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]))
            .collect();
        unsafe {
            let module = device
                .create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&words), None)?;
            let bindings = [0, 1].map(|b| {
                vk::DescriptorSetLayoutBinding::default()
                    .binding(b)
                    .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                    .descriptor_count(1)
                    .stage_flags(vk::ShaderStageFlags::COMPUTE)
            });
            let set_layout = device.create_descriptor_set_layout(
                &vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings),
                None,
            )?;
            let ranges = [vk::PushConstantRange::default()
                .stage_flags(vk::ShaderStageFlags::COMPUTE)
                .size(std::mem::size_of::<Push>() as u32)];
            let layouts = [set_layout];
            let pipeline_layout = device.create_pipeline_layout(
                &vk::PipelineLayoutCreateInfo::default()
                    .set_layouts(&layouts)
                    .push_constant_ranges(&ranges),
                None,
            )?;
            let stage = vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::COMPUTE)
                .module(module)
                .name(c"main");
            let pipeline = device
                .create_compute_pipelines(
                    vk::PipelineCache::null(),
                    &[vk::ComputePipelineCreateInfo::default()
                        .stage(stage)
                        .layout(pipeline_layout)],
                    None,
                )
                .map_err(|(_, e)| e)?[0];
            let sizes = [vk::DescriptorPoolSize::default()
                .ty(vk::DescriptorType::STORAGE_BUFFER)
                .descriptor_count(2)];
            let pool = device.create_descriptor_pool(
                &vk::DescriptorPoolCreateInfo::default()
                    .max_sets(1)
                    .pool_sizes(&sizes),
                None,
            )?;
            let set = device.allocate_descriptor_sets(
                &vk::DescriptorSetAllocateInfo::default()
                    .descriptor_pool(pool)
                    .set_layouts(&layouts),
            )?[0];
            let cmd_pool = device.create_command_pool(
                &vk::CommandPoolCreateInfo::default()
                    .queue_family_index(family)
                    .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER),
                None,
            )?;
            let cmd = device.allocate_command_buffers(
                &vk::CommandBufferAllocateInfo::default()
                    .command_pool(cmd_pool)
                    .command_buffer_count(1),
            )?[0];
            let fence = device.create_fence(&vk::FenceCreateInfo::default(), None)?;
            Ok(Host {
                module,
                set_layout,
                pipeline_layout,
                pipeline,
                pool,
                set,
                cmd_pool,
                cmd,
                fence,
            })
        }
    }

    /// Binds the accumulation buffer and mcdenoise's sample map.
    fn bind(
        &self,
        device: &ash::Device,
        accum: vk::Buffer,
        bytes: u64,
        map: mcdenoise::BufferSlice,
    ) {
        let infos = [
            [vk::DescriptorBufferInfo::default()
                .buffer(accum)
                .range(bytes)],
            [vk::DescriptorBufferInfo::default()
                .buffer(map.buffer())
                .offset(map.offset())
                .range(map.size())],
        ];
        let writes = [0, 1].map(|b| {
            vk::WriteDescriptorSet::default()
                .dst_set(self.set)
                .dst_binding(b as u32)
                .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                .buffer_info(&infos[b])
        });
        unsafe { device.update_descriptor_sets(&writes, &[]) };
    }

    /// Records zeroing the accumulation buffer.
    fn clear(&self, device: &ash::Device, accum: vk::Buffer) {
        let barrier = vk::MemoryBarrier::default()
            .src_access_mask(vk::AccessFlags::TRANSFER_WRITE)
            .dst_access_mask(vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE);
        unsafe {
            device.cmd_fill_buffer(self.cmd, accum, 0, vk::WHOLE_SIZE, 0);
            device.cmd_pipeline_barrier(
                self.cmd,
                vk::PipelineStageFlags::TRANSFER,
                vk::PipelineStageFlags::COMPUTE_SHADER,
                vk::DependencyFlags::empty(),
                &[barrier],
                &[],
                &[],
            );
        }
    }

    /// Records the accumulation of pass `pass` (0: SPP per pixel; then the
    /// sample map's counts).
    fn accumulate(&self, device: &ash::Device, pass: u32, stride: u32) {
        let push = Push {
            width: W as u32,
            height: H as u32,
            pass_index: pass,
            uniform_spp: SPP as u32,
            stride,
            frame: 0,
        };
        unsafe {
            device.cmd_bind_pipeline(self.cmd, vk::PipelineBindPoint::COMPUTE, self.pipeline);
            device.cmd_bind_descriptor_sets(
                self.cmd,
                vk::PipelineBindPoint::COMPUTE,
                self.pipeline_layout,
                0,
                &[self.set],
                &[],
            );
            device.cmd_push_constants(
                self.cmd,
                self.pipeline_layout,
                vk::ShaderStageFlags::COMPUTE,
                0,
                bytemuck::bytes_of(&push),
            );
            device.cmd_dispatch(self.cmd, (W * H).div_ceil(64) as u32, 1, 1);
        }
    }

    /// Destroys the host's objects (after its work completed).
    fn destroy(&self, device: &ash::Device) {
        unsafe {
            device.destroy_fence(self.fence, None);
            device.destroy_command_pool(self.cmd_pool, None);
            device.destroy_descriptor_pool(self.pool, None);
            device.destroy_pipeline(self.pipeline, None);
            device.destroy_pipeline_layout(self.pipeline_layout, None);
            device.destroy_descriptor_set_layout(self.set_layout, None);
            device.destroy_shader_module(self.module, None);
        }
    }
}
