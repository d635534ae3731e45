//! A renderer-shaped host written with raw `ash`: its own instance, device,
//! queue, command buffer and accumulation buffer, which it fills itself (here
//! on the CPU: a noisy gradient with an edge, 8 samples per pixel). It hands
//! the buffer to mcdenoise, which records its whole chain into the host's
//! command buffer; the host submits, then reads colour, error and the next
//! pass's sample map.
//!
//! `cargo run --release --example embed` (CI runs it through `tests/examples.rs`).
//! Exits non-zero if the result is wrong: the sample map must spend exactly
//! the budget, and the reconstruction must be closer to the noise-free image
//! than the input.

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

    // The renderer's accumulation buffer: per scalar channel Σx and Σx², the
    // sample count (layout in mcdenoise::accum), in host-visible memory.
    let layout = mcdenoise::AccumLayout::new(W, H, false, false);
    let (buffer, memory, ptr) = host_buffer(&instance, physical, &device, layout.bytes())?;
    let mut rng = 0x9e3779b97f4a7c15u64;
    let mut acc = mcdenoise::Accumulator::new(layout);
    for p in 0..W * H {
        let t = truth(p % W, p / W) as f64;
        for _ in 0..SPP {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            let noise = (rng >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
            let c = (t * (1.0 + 1.5 * noise)).max(0.0);
            let a = if p % W < W / 2 { 0.2 } else { 1.0 };
            acc.add(p, &[c, c, c, a, a, a, 0.0, 0.0, 1.0, 2.0]);
        }
    }
    for (i, plane) in acc.planes().iter().enumerate() {
        let at = i * layout.plane_stride() as usize;
        unsafe {
            std::ptr::copy_nonoverlapping(plane.as_ptr(), ptr.add(at) as *mut f32, plane.len())
        };
    }

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
    let config = mcdenoise::Config::new(mcdenoise::Method::Wlr);
    let denoiser = mcdenoise::Denoiser::new(&ctx, mcdenoise::Source::Accum(layout), config)?;
    let accum = unsafe { mcdenoise::BufferSlice::from_raw(buffer, 0, layout.bytes()) };

    let pool = unsafe {
        device.create_command_pool(
            &vk::CommandPoolCreateInfo::default().queue_family_index(family),
            None,
        )?
    };
    let cmd = unsafe {
        device.allocate_command_buffers(
            &vk::CommandBufferAllocateInfo::default()
                .command_pool(pool)
                .command_buffer_count(1),
        )?
    }[0];
    unsafe { device.begin_command_buffer(cmd, &vk::CommandBufferBeginInfo::default())? };
    // The host's own passes would be recorded here; then mcdenoise's:
    let recorded = unsafe { denoiser.record_into(cmd, Some(accum), Some(BUDGET))? };
    unsafe {
        device.end_command_buffer(cmd)?;
        let fence = device.create_fence(&vk::FenceCreateInfo::default(), None)?;
        device.queue_submit(
            queue,
            &[vk::SubmitInfo::default().command_buffers(&[cmd])],
            fence,
        )?;
        device.wait_for_fences(&[fence], true, u64::MAX)?;
        device.destroy_fence(fence, None);
    }
    drop(recorded); // the work has completed
    let frame = denoiser.read()?;
    let samples = frame.samples.as_ref().ok_or("no sample map")?;

    // ---- Checks a renderer would care about. ----
    let total: u64 = samples.iter().map(|&s| s as u64).sum();
    let mse = |img: &[f32]| -> f64 {
        let e: f64 = (0..W * H)
            .map(|p| (img[p] - truth(p % W, p / W)).powi(2) as f64)
            .sum();
        e / (W * H) as f64
    };
    let input: Vec<f32> = {
        let s = &acc.planes();
        (0..W * H)
            .map(|p| s[0][p] / s[layout.count_plane()][p])
            .collect()
    };
    let (mse_in, mse_out) = (mse(&input), mse(&frame.color.planes[0]));
    println!("device: {}", ctx.info().name);
    println!("MSE of the red channel: input {mse_in:.5}, WLR {mse_out:.5}");
    println!(
        "mean estimated error {:.5}",
        frame.error.planes[0].iter().sum::<f32>() / (W * H) as f32
    );
    println!(
        "sample map: {total} samples for a budget of {BUDGET}, max {} per pixel",
        samples.iter().max().unwrap()
    );

    drop(denoiser);
    drop(ctx);
    unsafe {
        device.destroy_command_pool(pool, None);
        device.unmap_memory(memory);
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
    if total != BUDGET as u64 || mse_out >= mse_in || messages > 0 {
        return Err("wrong result".into());
    }
    Ok(())
}

/// A host-visible, host-coherent storage buffer, mapped (the host's own
/// allocation code).
fn host_buffer(
    instance: &ash::Instance,
    physical: vk::PhysicalDevice,
    device: &ash::Device,
    size: u64,
) -> Result<(vk::Buffer, vk::DeviceMemory, *mut u8), vk::Result> {
    unsafe {
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER
            | vk::BufferUsageFlags::TRANSFER_SRC
            | vk::BufferUsageFlags::TRANSFER_DST;
        let buffer = device.create_buffer(
            &vk::BufferCreateInfo::default().size(size).usage(usage),
            None,
        )?;
        let req = device.get_buffer_memory_requirements(buffer);
        let props = instance.get_physical_device_memory_properties(physical);
        let want = vk::MemoryPropertyFlags::HOST_VISIBLE | vk::MemoryPropertyFlags::HOST_COHERENT;
        let ty = (0..props.memory_type_count)
            .find(|&i| {
                req.memory_type_bits & (1 << i) != 0
                    && props.memory_types[i as usize].property_flags.contains(want)
            })
            .ok_or(vk::Result::ERROR_FEATURE_NOT_PRESENT)?;
        let memory = device.allocate_memory(
            &vk::MemoryAllocateInfo::default()
                .allocation_size(req.size)
                .memory_type_index(ty),
            None,
        )?;
        device.bind_buffer_memory(buffer, memory, 0)?;
        let ptr = device.map_memory(memory, 0, size, vk::MemoryMapFlags::empty())? as *mut u8;
        Ok((buffer, memory, ptr))
    }
}
