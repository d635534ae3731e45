//! The embedding path: a "host renderer" creates its own Vulkan instance,
//! device, queue, buffers and command buffer with ash; mcdenoise wraps the
//! device (`GpuContext::from_raw`) and records its passes into the host's
//! command buffer, which the host submits. No CPU round trip inside.

mod common;
use common::*;

use std::sync::Arc;

use ash::vk;
use mcdenoise::gpu::Batch;
use mcdenoise::methods::stats::{finalize_cpu, finalized_layers, record_finalize, GpuStats};
use mcdenoise::{
    AccumLayout, Accumulator, BufferSlice, Config, Denoiser, Frame, GpuContext, ImportedDevice,
    Layer, Method, Precision, Source,
};

/// Messages of the validation layer on the host's own instance (the host
/// owns the messenger; mcdenoise's imported context does not see them).
static HOST_VALIDATION: std::sync::Mutex<Vec<String>> = std::sync::Mutex::new(Vec::new());

unsafe extern "system" fn host_callback(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _types: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    _user: *mut std::ffi::c_void,
) -> vk::Bool32 {
    if severity.intersects(
        vk::DebugUtilsMessageSeverityFlagsEXT::ERROR
            | vk::DebugUtilsMessageSeverityFlagsEXT::WARNING,
    ) {
        let msg = unsafe { data.as_ref() }
            .and_then(|d| unsafe { d.message_as_c_str() })
            .map(|m| m.to_string_lossy().into_owned())
            .unwrap_or_default();
        eprintln!("[host validation] {msg}");
        HOST_VALIDATION.lock().unwrap().push(msg);
    }
    vk::FALSE
}

/// Fails if the host's validation layer reported anything.
fn check_host_validation() {
    let m = HOST_VALIDATION.lock().unwrap();
    assert!(m.is_empty(), "host validation messages: {m:#?}");
}

struct Host {
    entry: ash::Entry,
    instance: ash::Instance,
    physical: vk::PhysicalDevice,
    device: ash::Device,
    queue: vk::Queue,
    family: u32,
    f64: bool,
    int64: bool,
    messenger: Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
}

/// A host renderer's instance and device, with the validation layer when it
/// is installed (as every test context has).
fn host() -> Host {
    unsafe {
        let entry = ash::Entry::load().unwrap();
        let app = vk::ApplicationInfo::default().api_version(vk::API_VERSION_1_1);
        let layer = c"VK_LAYER_KHRONOS_validation";
        let validation = entry
            .enumerate_instance_layer_properties()
            .unwrap()
            .iter()
            .any(|l| l.layer_name_as_c_str() == Ok(layer));
        let layers = if validation {
            vec![layer.as_ptr()]
        } else {
            vec![]
        };
        let exts = if validation {
            vec![ash::ext::debug_utils::NAME.as_ptr()]
        } else {
            vec![]
        };
        let instance = entry
            .create_instance(
                &vk::InstanceCreateInfo::default()
                    .application_info(&app)
                    .enabled_layer_names(&layers)
                    .enabled_extension_names(&exts),
                None,
            )
            .unwrap();
        let messenger = validation.then(|| {
            let du = ash::ext::debug_utils::Instance::new(&entry, &instance);
            let m = du
                .create_debug_utils_messenger(
                    &vk::DebugUtilsMessengerCreateInfoEXT::default()
                        .message_severity(
                            vk::DebugUtilsMessageSeverityFlagsEXT::ERROR
                                | vk::DebugUtilsMessageSeverityFlagsEXT::WARNING,
                        )
                        .message_type(
                            vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                                | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION,
                        )
                        .pfn_user_callback(Some(host_callback)),
                    None,
                )
                .unwrap();
            (du, m)
        });
        eprintln!(
            "host validation layer: {}",
            if validation { "on" } else { "not installed" }
        );
        let physical = instance.enumerate_physical_devices().unwrap()[0];
        let family = instance
            .get_physical_device_queue_family_properties(physical)
            .iter()
            .position(|q| q.queue_flags.contains(vk::QueueFlags::COMPUTE))
            .unwrap() as u32;
        let f64 = instance
            .get_physical_device_features(physical)
            .shader_float64
            == vk::TRUE;
        let prio = [1.0];
        let qi = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(family)
            .queue_priorities(&prio)];
        let int64 = instance.get_physical_device_features(physical).shader_int64 == vk::TRUE;
        let features = vk::PhysicalDeviceFeatures::default()
            .shader_float64(f64)
            .shader_int64(int64);
        let device = instance
            .create_device(
                physical,
                &vk::DeviceCreateInfo::default()
                    .queue_create_infos(&qi)
                    .enabled_features(&features),
                None,
            )
            .unwrap();
        let queue = device.get_device_queue(family, 0);
        Host {
            entry,
            instance,
            physical,
            device,
            queue,
            family,
            f64,
            int64,
            messenger,
        }
    }
}

/// A host-owned, host-visible buffer (the host's own allocation code).
fn host_buffer(h: &Host, size: u64) -> (vk::Buffer, vk::DeviceMemory, *mut u8) {
    unsafe {
        let buffer = h
            .device
            .create_buffer(
                &vk::BufferCreateInfo::default().size(size).usage(
                    vk::BufferUsageFlags::STORAGE_BUFFER
                        | vk::BufferUsageFlags::TRANSFER_SRC
                        | vk::BufferUsageFlags::TRANSFER_DST,
                ),
                None,
            )
            .unwrap();
        let req = h.device.get_buffer_memory_requirements(buffer);
        let props = h.instance.get_physical_device_memory_properties(h.physical);
        let want = vk::MemoryPropertyFlags::HOST_VISIBLE | vk::MemoryPropertyFlags::HOST_COHERENT;
        let ty = (0..props.memory_type_count)
            .find(|&i| {
                req.memory_type_bits & (1 << i) != 0
                    && props.memory_types[i as usize].property_flags.contains(want)
            })
            .unwrap();
        let mem = h
            .device
            .allocate_memory(
                &vk::MemoryAllocateInfo::default()
                    .allocation_size(req.size)
                    .memory_type_index(ty),
                None,
            )
            .unwrap();
        h.device.bind_buffer_memory(buffer, mem, 0).unwrap();
        let ptr = h
            .device
            .map_memory(mem, 0, size, vk::MemoryMapFlags::empty())
            .unwrap() as *mut u8;
        (buffer, mem, ptr)
    }
}

/// Wraps the host's device (the documented unsafe import).
fn import(h: &Host) -> Arc<GpuContext> {
    Arc::new(
        unsafe {
            GpuContext::from_raw(ImportedDevice {
                entry: h.entry.clone(),
                instance: h.instance.clone(),
                physical_device: h.physical,
                device: h.device.clone(),
                queue: h.queue,
                queue_family_index: h.family,
                shader_float64_enabled: h.f64,
                shader_int64_enabled: h.int64,
            })
        }
        .unwrap(),
    )
}

/// The host's own command pool and buffer: `record` records mcdenoise's
/// work into it (returning what must live until completion); the host
/// submits and waits. Returns the per-dispatch timings.
/// A command pool of the host's compute family and one primary command
/// buffer from it, recording.
fn host_begin(h: &Host) -> (vk::CommandPool, vk::CommandBuffer) {
    unsafe {
        let pool = h
            .device
            .create_command_pool(
                &vk::CommandPoolCreateInfo::default().queue_family_index(h.family),
                None,
            )
            .unwrap();
        let cmd = h
            .device
            .allocate_command_buffers(
                &vk::CommandBufferAllocateInfo::default()
                    .command_pool(pool)
                    .level(vk::CommandBufferLevel::PRIMARY)
                    .command_buffer_count(1),
            )
            .unwrap()[0];
        h.device
            .begin_command_buffer(cmd, &vk::CommandBufferBeginInfo::default())
            .unwrap();
        (pool, cmd)
    }
}

fn host_submit_recorded(
    h: &Host,
    record: impl FnOnce(vk::CommandBuffer) -> Vec<mcdenoise::Recorded>,
) -> Vec<mcdenoise::KernelTiming> {
    let (pool, cmd) = host_begin(h);
    unsafe {
        let recorded = record(cmd);
        h.device.end_command_buffer(cmd).unwrap();
        let fence = h
            .device
            .create_fence(&vk::FenceCreateInfo::default(), None)
            .unwrap();
        let cmds = [cmd];
        h.device
            .queue_submit(
                h.queue,
                &[vk::SubmitInfo::default().command_buffers(&cmds)],
                fence,
            )
            .unwrap();
        h.device.wait_for_fences(&[fence], true, u64::MAX).unwrap();
        h.device.destroy_fence(fence, None);
        let timings = recorded.iter().flat_map(|r| r.timings().unwrap()).collect();
        drop(recorded);
        h.device.destroy_command_pool(pool, None);
        timings
    }
}

/// [`host_submit_recorded`] with the recording done through
/// `Batch::record_into` (the lower-level path under the facade).
fn host_submit(
    h: &Host,
    ctx: &Arc<GpuContext>,
    record: impl FnOnce(&mut Batch),
) -> Vec<mcdenoise::gpu::KernelTiming> {
    host_submit_recorded(h, |cmd| {
        // SAFETY: `cmd` is the host's recording command buffer of ctx's device.
        let mut batch = unsafe { Batch::record_into(ctx, cmd) };
        record(&mut batch);
        vec![batch.finish_recording().unwrap()]
    })
}

/// A host-visible buffer holding `planes` at the accumulation layout's stride.
fn host_accum(
    h: &Host,
    layout: &AccumLayout,
    planes: &[Vec<f32>],
) -> (vk::Buffer, vk::DeviceMemory) {
    let stride = layout.plane_stride() as usize;
    let (buf, mem, ptr) = host_buffer(h, layout.bytes());
    unsafe {
        for (i, p) in planes.iter().enumerate() {
            std::ptr::copy_nonoverlapping(
                p.as_ptr() as *const u8,
                ptr.add(i * stride),
                p.len() * 4,
            );
        }
    }
    (buf, mem)
}

/// Host teardown, after every mcdenoise object is dropped (documented order).
fn host_teardown(h: Host, buf: vk::Buffer, mem: vk::DeviceMemory) {
    unsafe {
        h.device.unmap_memory(mem);
        h.device.destroy_buffer(buf, None);
        h.device.free_memory(mem, None);
        h.device.destroy_device(None);
        if let Some((du, m)) = &h.messenger {
            du.destroy_debug_utils_messenger(*m, None);
        }
        h.instance.destroy_instance(None);
    }
    check_host_validation();
}

#[test]
fn host_device_and_command_buffer() {
    let h = host();
    let (w, hgt) = (37usize, 23usize);
    let layout = AccumLayout::new(w, hgt, true, false);
    let mut acc = Accumulator::new(layout);
    let nch = layout.channels().len();
    let mut rng = Rng(5);
    for p in 0..w * hgt {
        for _ in 0..(p % 9) {
            let v: Vec<f64> = (0..nch).map(|_| rng.uniform()).collect();
            acc.add(p, &v);
        }
    }
    let planes = acc.planes();
    let (accum_buf, accum_mem) = host_accum(&h, &layout, &planes);
    let ctx = import(&h);
    let out = GpuStats::new(&ctx, "embedded_stats", w, hgt, &finalized_layers(&layout)).unwrap();
    // SAFETY: the host's live storage buffer of layout.bytes() bytes,
    // destroyed after the work completes (host_teardown).
    let accum = unsafe { BufferSlice::from_raw(accum_buf, 0, layout.bytes()) };
    let timings = host_submit(&h, &ctx, |batch| {
        record_finalize(batch, Precision::F32, &layout, accum, &out).unwrap();
    });
    assert!(timings.iter().any(|t| t.kernel == "finalize_stats"));

    let g = out.download().unwrap();
    let c = finalize_cpu(&layout, &planes);
    for layer in [
        Layer::Color,
        Layer::ColorVariance,
        Layer::Normal,
        Layer::PositionCovariance,
        Layer::Spp,
    ] {
        for (a, b) in g.get(layer).unwrap().iter().zip(c.get(layer).unwrap()) {
            assert_close(layer.name(), a, b, 0.99);
        }
    }

    // Teardown in the documented order: mcdenoise's objects, then the host's.
    drop(out);
    drop(ctx);
    host_teardown(h, accum_buf, accum_mem);
}

/// A renderer's accumulation of a 24×20 image with an edge at x = 12:
/// colour, albedo, normal, depth, 8 samples per pixel.
fn edge_scene(w: usize, hgt: usize, seed: u64) -> (AccumLayout, Vec<Vec<f32>>) {
    let layout = AccumLayout::new(w, hgt, false, false);
    let mut acc = Accumulator::new(layout);
    let nch = layout.channels().len();
    let mut rng = Rng(seed);
    for p in 0..w * hgt {
        let (x, y) = ((p % w) as f64, (p / w) as f64);
        for _ in 0..8 {
            let mut v: Vec<f64> = vec![0.0; nch];
            let edge = if x > 11.0 { 1.0 } else { 0.2 };
            for c in 0..3 {
                v[c] = (edge * (0.5 + 0.02 * y) + 0.2 * rng.normal()).max(0.0); // colour
                v[3 + c] = edge; // albedo
            }
            v[6] = 0.0;
            v[7] = 1.0;
            v[8] = 0.0; // normal
            v[9] = 3.0 + 0.1 * y + 0.01 * rng.normal(); // depth
            acc.add(p, &v);
        }
    }
    (layout, acc.planes())
}

/// The CPU twin chain on the same statistics.
fn cpu_frame(layout: &AccumLayout, planes: &[Vec<f32>], config: &Config, budget: u32) -> Frame {
    let finalized = finalize_cpu(layout, planes);
    Denoiser::new_cpu(Source::of_image(&finalized), config.clone())
        .unwrap()
        .denoise(&finalized, Some(budget))
        .unwrap()
}

/// The whole library path of a renderer through the facade: its
/// accumulation buffer → finalize → sanitation → WLR or LP, recorded into
/// the host's command buffer and submitted by the host; mcdenoise submits
/// nothing. The result equals the CPU chain (twins) within the spec's
/// tolerances, and the reconstruction is smoother than the input.
fn host_records_a_method_chain(method: Method) {
    let h = host();
    let (w, hgt) = (24usize, 20usize);
    let (layout, planes) = edge_scene(w, hgt, 9);
    let (accum_buf, accum_mem) = host_accum(&h, &layout, &planes);
    let ctx = import(&h);
    let config = Config::new(method);
    let budget = (4 * w * hgt) as u32;
    let denoiser = Denoiser::new(&ctx, Source::Accum(layout), config.clone()).unwrap();
    // SAFETY: the host's live storage buffer of layout.bytes() bytes,
    // destroyed after the work completes (host_teardown).
    let accum = unsafe { BufferSlice::from_raw(accum_buf, 0, layout.bytes()) };
    let submits = ctx.submit_count();
    let timings = host_submit_recorded(&h, |cmd| unsafe {
        vec![denoiser
            .record_into(cmd, h.family, Some(accum), Some(budget))
            .unwrap()]
    });
    assert_eq!(ctx.submit_count(), submits, "recording must not submit");
    let kernels: &[&str] = match method {
        Method::Wlr => &[
            "finalize_stats",
            "sanitize",
            "wlr_fit",
            "gauss_smooth",
            "wlr_final",
        ],
        _ => &[
            "finalize_stats",
            "sanitize",
            "lp_reach",
            "lp_centres",
            "lp_gather",
        ],
    };
    for k in kernels {
        // Sanitation's stage 0 runs as `sanitize_quads` at widths that are
        // a multiple of 4.
        let found = |name: &str| timings.iter().any(|t| t.kernel == name);
        assert!(
            found(k) || (*k == "sanitize" && found("sanitize_quads")),
            "no timing for {k}"
        );
    }
    let gpu = denoiser.read().unwrap();
    let cpu = cpu_frame(&layout, &planes, &config, budget);
    assert_maps_agree(
        gpu.samples.as_ref().unwrap(),
        cpu.samples.as_ref().unwrap(),
        budget,
    );
    for c in 0..3 {
        assert_close(
            &format!("colour {c}"),
            &gpu.color.planes[c],
            &cpu.color.planes[c],
            0.99,
        );
        assert_close(
            &format!("error {c}"),
            &gpu.error.planes[c],
            &cpu.error.planes[c],
            0.99,
        );
    }
    let same = gpu.dim.iter().zip(&cpu.dim).filter(|(a, b)| a == b).count();
    assert!(
        same as f64 >= 0.98 * (w * hgt) as f64,
        "d_i equal on {same} pixels"
    );
    // The reconstruction actually denoised: smoother than the input.
    let input = &finalize_cpu(&layout, &planes).get(Layer::Color).unwrap()[0].clone();
    let rough = |p: &[f32]| {
        (1..p.len())
            .filter(|i| i % w != 0 && i % w != 12)
            .map(|i| (p[i] - p[i - 1]).powi(2) as f64)
            .sum::<f64>()
    };
    assert!(rough(&gpu.color.planes[0]) < 0.5 * rough(input));

    drop(denoiser);
    drop(ctx);
    host_teardown(h, accum_buf, accum_mem);
}

#[test]
fn host_records_the_whole_wlr_chain() {
    host_records_a_method_chain(Method::Wlr);
}

#[test]
fn host_records_the_whole_lp_chain() {
    host_records_a_method_chain(Method::Lp);
}

/// Two configurations (WLR, and LP without prefilter at f64 where the device
/// has it) recorded into one host command buffer, reading the same host
/// buffer: both results equal their CPU twins.
#[test]
fn two_configurations_in_one_command_buffer() {
    let h = host();
    let (w, hgt) = (24usize, 20usize);
    let (layout, planes) = edge_scene(w, hgt, 11);
    let (accum_buf, accum_mem) = host_accum(&h, &layout, &planes);
    let ctx = import(&h);
    let a_cfg = Config::new(Method::Wlr);
    let mut b_cfg = Config::new(Method::Lp);
    b_cfg.precision = if ctx.supports_f64() {
        Precision::F64
    } else {
        Precision::F32
    };
    let a = Denoiser::new(&ctx, Source::Accum(layout), a_cfg.clone()).unwrap();
    let b = Denoiser::new(&ctx, Source::Accum(layout), b_cfg.clone()).unwrap();
    let accum = unsafe { BufferSlice::from_raw(accum_buf, 0, layout.bytes()) };
    host_submit_recorded(&h, |cmd| unsafe {
        vec![
            a.record_into(cmd, h.family, Some(accum), Some(1000))
                .unwrap(),
            b.record_into(cmd, h.family, Some(accum), Some(5000))
                .unwrap(),
        ]
    });
    for (d, cfg, budget) in [(&a, &a_cfg, 1000), (&b, &b_cfg, 5000)] {
        let gpu = d.read().unwrap();
        let cpu = cpu_frame(&layout, &planes, cfg, budget);
        assert_maps_agree(
            gpu.samples.as_ref().unwrap(),
            cpu.samples.as_ref().unwrap(),
            budget,
        );
        for c in 0..3 {
            assert_close("colour", &gpu.color.planes[c], &cpu.color.planes[c], 0.99);
        }
    }
    drop((a, b));
    drop(ctx);
    host_teardown(h, accum_buf, accum_mem);
}

/// Dropping the denoiser after recording and before the host submits is not
/// a use-after-free: its buffers live until the `Recorded` is dropped (the
/// validation layer would report a destroyed buffer in the submission).
#[test]
fn buffers_outlive_a_dropped_denoiser_until_the_work_completes() {
    let h = host();
    let (layout, planes) = edge_scene(16, 12, 3);
    let (accum_buf, accum_mem) = host_accum(&h, &layout, &planes);
    let ctx = import(&h);
    let accum = unsafe { BufferSlice::from_raw(accum_buf, 0, layout.bytes()) };
    host_submit_recorded(&h, |cmd| unsafe {
        let d = Denoiser::new(&ctx, Source::Accum(layout), Config::new(Method::Wlr)).unwrap();
        let r = d
            .record_into(cmd, h.family, Some(accum), Some(100))
            .unwrap();
        drop(d); // before the host's submit
        vec![r]
    });
    drop(ctx);
    host_teardown(h, accum_buf, accum_mem);
}

/// Records into a fresh command buffer of the host and then discards it
/// (frees its pool) without ever submitting it: what a host does after
/// `record_into` returned an error.
fn host_discard_recorded(h: &Host, record: impl FnOnce(vk::CommandBuffer)) {
    let (pool, cmd) = host_begin(h);
    record(cmd);
    unsafe { h.device.destroy_command_pool(pool, None) };
}

/// An error from `record_into` (a wrongly sized host range, a command buffer
/// of another queue family, or an output slice of a dropped denoiser bound
/// in a later batch) is an error, never an out-of-bounds or destroyed
/// binding; the host discards its command buffer and the denoiser and
/// context stay usable.
#[test]
fn a_failed_recording_is_discarded_and_the_context_stays_usable() {
    let h = host();
    let (layout, planes) = edge_scene(16, 12, 3);
    let (accum_buf, accum_mem) = host_accum(&h, &layout, &planes);
    let ctx = import(&h);
    let d = Denoiser::new(&ctx, Source::Accum(layout), Config::new(Method::Wlr)).unwrap();
    let short = unsafe { BufferSlice::from_raw(accum_buf, 0, layout.bytes() - 4) };
    host_discard_recorded(&h, |cmd| unsafe {
        assert!(d.record_into(cmd, h.family, Some(short), None).is_err());
    });
    // A command buffer of another queue family than the context's, whose
    // buffers it owns, is refused before anything is recorded.
    let accum = unsafe { BufferSlice::from_raw(accum_buf, 0, layout.bytes()) };
    host_discard_recorded(&h, |cmd| unsafe {
        let e = d
            .record_into(cmd, h.family + 1, Some(accum), None)
            .err()
            .unwrap();
        assert!(e.to_string().contains("queue family"), "{e}");
    });
    // The same denoiser records and runs afterwards.
    host_submit_recorded(&h, |cmd| unsafe {
        vec![d
            .record_into(cmd, h.family, Some(accum), Some(100))
            .unwrap()]
    });
    assert_eq!(d.read().unwrap().samples.unwrap().iter().sum::<u32>(), 100);

    // Outputs of a dropped denoiser: a later use fails, it binds nothing.
    let stale = d.outputs().unwrap().color[0];
    drop(d);
    let other = Denoiser::new(&ctx, Source::Accum(layout), Config::new(Method::None)).unwrap();
    let fresh = other.outputs().unwrap().color[0];
    let mut batch = mcdenoise::Batch::new(&ctx).unwrap();
    batch.copy(stale, fresh);
    let err = batch.finish().unwrap_err();
    assert!(err.to_string().contains("outlived its buffer"), "{err}");
    let mut batch = mcdenoise::Batch::new(&ctx).unwrap();
    batch.fill(stale, 0);
    assert!(batch.finish().is_err());
    // Ranges of different sizes are an error too, not a panic.
    let mut batch = mcdenoise::Batch::new(&ctx).unwrap();
    batch.copy(fresh, fresh.sub(0, 4).unwrap());
    assert!(batch.finish().is_err());
    // Offsets that would wrap around are refused, not wrapped.
    let buf = mcdenoise::gpu::GpuBuffer::new(&ctx, "wrap", 64).unwrap();
    assert!(buf.upload(u64::MAX - 3, &[0u8; 8]).is_err());
    assert!(buf.download(u64::MAX - 3, &mut [0u8; 8]).is_err());
    assert!(fresh.sub(u64::MAX, 2).is_err());
    // vkDeviceWaitIdle would touch the host's queues.
    assert!(ctx.wait_idle().is_err());
    assert_eq!(
        ctx.validation_errors(),
        0,
        "{:?}",
        ctx.validation_messages()
    );
    drop((buf, other));
    drop(ctx);
    host_teardown(h, accum_buf, accum_mem);
}

/// Every public kernel `record` checks its bindings' sizes against the
/// dispatch before anything is recorded: a plane of the image one value
/// short (checked by the batch from the declaration), and sizes only the
/// kernel knows (a queue, a counter block, a state ring), are errors that
/// name the kernel and the binding.
#[test]
fn short_bindings_are_refused_before_recording() {
    use mcdenoise::gpu::{GpuBuffer, Precision};
    use mcdenoise::kernels::{channel_mean, lp_select, sanitize, wlr_fit};
    use mcdenoise::shared::{LpPush, SanitizePush};
    let ctx = common::gpu();
    let (w, h) = (16u32, 8u32);
    let bytes = 4 * (w * h) as u64;
    let buf = |n: u64| GpuBuffer::new(&ctx, "short", n).unwrap();
    let (a, b, c) = (buf(bytes), buf(bytes), buf(bytes));
    let (full, short) = (buf(bytes), buf(bytes - 4));
    let fails = |r: mcdenoise::Result<()>, what: &str| {
        let e = r.err().unwrap_or_else(|| panic!("{what}: no error"));
        assert!(e.to_string().contains(what), "{what}: {e}");
    };
    let mut batch = Batch::new(&ctx).unwrap();
    let planes = [a.slice(), b.slice(), c.slice()];
    channel_mean::record(&mut batch, Precision::F32, w, h, planes, full.slice()).unwrap();
    let r = channel_mean::record(&mut batch, Precision::F32, w, h, planes, short.slice());
    fails(r, "channel_mean binding 3 (out)");
    // Sanitation's four counters.
    let push = SanitizePush {
        width: w,
        height: h,
        ..Default::default()
    };
    let five = [a.slice(), b.slice(), c.slice(), full.slice(), a.slice()];
    let counters = buf(12);
    let r = sanitize::record(&mut batch, Precision::F32, push, five, counters.slice());
    fails(r, "binding 5 (counters)");
    // LP's selection queue: a header and one entry per candidate.
    let push = LpPush {
        width: w,
        height: h,
        granularity: 1,
        ..Default::default()
    };
    let reach = buf(bytes);
    let queue = buf(4 * (4 + (w * h) as u64) - 4);
    let r = lp_select::record(
        &mut batch,
        Precision::F32,
        &push,
        a.slice(),
        reach.slice(),
        queue.slice(),
        (0, h),
    );
    fails(r, "lp_select binding 2 (queue)");
    // WLR's centre state ring: `ring_rows` rows of STATE_WORDS per pixel.
    let packed = [0; 4].map(|_| buf(4 * bytes));
    let out = [0; 8].map(|_| buf(bytes));
    let ring = 8;
    let words = |features| ring as u64 * w as u64 * wlr_fit::state_words(features) as u64 * 4;
    // One word short; and (WLR-VIS) a ring sized for nine features is short
    // for ten.
    let cases = [
        (buf(words(9) - 4), None, "wlr_fit binding 17 (state)"),
        (
            buf(words(9)),
            Some([a.slice(), b.slice()]),
            "wlr_fit_vis binding 17 (state)",
        ),
    ];
    for (state, vis, what) in &cases {
        let r = wlr_fit::record(
            &mut batch,
            Precision::F32,
            (w, h),
            (0, h),
            (2, 0),
            packed.each_ref().map(|p| p.slice()),
            planes,
            a.slice(),
            b.slice(),
            out.each_ref().map(|p| p.slice()),
            (state.slice(), ring),
            *vis,
        );
        fails(r, what);
    }
    batch.finish().unwrap();
    common::check_validation(&ctx);
}

/// `planes` as the bytes of a device accumulation buffer of `layout`.
fn accum_bytes(layout: &AccumLayout, planes: &[Vec<f32>]) -> Vec<u8> {
    let mut bytes = vec![0u8; layout.bytes() as usize];
    let stride = layout.plane_stride() as usize;
    for (i, p) in planes.iter().enumerate() {
        let src: &[u8] = bytemuck::cast_slice(p);
        bytes[i * stride..i * stride + src.len()].copy_from_slice(src);
    }
    bytes
}

/// A renderer that accumulates on the CPU hands its sums over in host
/// memory (`Denoiser::run_host_accum`, the C API's
/// `mcd_denoiser_run_host`): the results are bit-identical to the same
/// bytes in a device buffer, also on a second call (the denoiser keeps its
/// device copy), and sums of another length are refused.
#[test]
fn sums_in_host_memory_denoise_as_a_device_buffer() {
    let ctx = gpu();
    let (w, hgt) = (24usize, 20usize);
    let budget = (4 * w * hgt) as u32;
    let config = Config::new(Method::Wlr);
    let host = Denoiser::new(
        &ctx,
        Source::Accum(AccumLayout::new(w, hgt, false, false)),
        config.clone(),
    )
    .unwrap();
    let device = Denoiser::new(
        &ctx,
        Source::Accum(AccumLayout::new(w, hgt, false, false)),
        config,
    )
    .unwrap();
    for seed in [9, 10] {
        let (layout, planes) = edge_scene(w, hgt, seed);
        let bytes = accum_bytes(&layout, &planes);
        host.run_host_accum(&bytes, Some(budget)).unwrap();
        let a = host.read().unwrap();
        let buf = mcdenoise::gpu::GpuBuffer::from_slice(&ctx, "test.accum", &bytes).unwrap();
        device.run(Some(buf.slice()), Some(budget)).unwrap();
        let b = device.read().unwrap();
        assert_eq!(a.color.planes, b.color.planes, "seed {seed}: colour");
        assert_eq!(a.error.planes, b.error.planes, "seed {seed}: error");
        assert_eq!(a.samples, b.samples, "seed {seed}: sample map");
        assert_eq!(
            a.samples
                .as_ref()
                .unwrap()
                .iter()
                .map(|&n| n as u64)
                .sum::<u64>(),
            budget as u64
        );
    }
    let (layout, planes) = edge_scene(w, hgt, 11);
    let bytes = accum_bytes(&layout, &planes);
    let err = host
        .run_host_accum(&bytes[4..], None)
        .unwrap_err()
        .to_string();
    assert!(err.contains("bytes"), "{err}");
    let stats = Denoiser::new(
        &ctx,
        Source::of_image(&finalize_cpu(&layout, &planes)),
        Config::new(Method::Wlr),
    )
    .unwrap();
    let err = stats.run_host_accum(&bytes, None).unwrap_err().to_string();
    assert!(err.contains("Source::Accum"), "{err}");
}
