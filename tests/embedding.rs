//! The embedding path: a "host renderer" creates its own Vulkan instance,
//! device, queue, buffers and command buffer with ash; mcdenoise wraps the
//! device (`GpuContext::from_raw`) and records its passes into the host's
//! command buffer, which the host submits. No CPU round trip inside.

mod common;
use common::*;

use std::sync::Arc;

use ash::vk;
use mcdenoise::accum::{AccumLayout, Accumulator};
use mcdenoise::gpu::{Batch, BufferSlice, GpuContext, ImportedDevice, Precision};
use mcdenoise::image::Layer;
use mcdenoise::methods::stats::{finalize_cpu, finalized_layers, record_finalize, GpuStats};

struct Host {
    entry: ash::Entry,
    instance: ash::Instance,
    physical: vk::PhysicalDevice,
    device: ash::Device,
    queue: vk::Queue,
    family: u32,
    f64: bool,
}

fn host() -> Host {
    unsafe {
        let entry = ash::Entry::load().unwrap();
        let app = vk::ApplicationInfo::default().api_version(vk::API_VERSION_1_1);
        let instance = entry
            .create_instance(
                &vk::InstanceCreateInfo::default().application_info(&app),
                None,
            )
            .unwrap();
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
        let features = vk::PhysicalDeviceFeatures::default().shader_float64(f64);
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
            })
        }
        .unwrap(),
    )
}

/// The host's own command pool and buffer: `record` fills it through
/// `Batch::record_into`, then the host submits and waits. Returns mcdenoise's
/// per-dispatch timings, read after completion.
fn host_submit(
    h: &Host,
    ctx: &Arc<GpuContext>,
    record: impl FnOnce(&mut Batch),
) -> Vec<mcdenoise::gpu::KernelTiming> {
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
        let mut batch = Batch::record_into(ctx, cmd);
        record(&mut batch);
        let recorded = batch.finish_recording();
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
        let timings = recorded.timings().unwrap();
        drop(recorded);
        h.device.destroy_command_pool(pool, None);
        timings
    }
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
        h.instance.destroy_instance(None);
    }
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

/// The whole library path of a renderer: its accumulation buffer → finalize →
/// sanitation → WLR or LP, recorded into the host's command buffer and
/// submitted by the host; colour and error stay on the GPU until the test
/// reads them. The result equals the CPU chain (twins) within the spec's
/// tolerances.
fn host_records_a_method_chain(method: mcdenoise::methods::Method) {
    use mcdenoise::methods::{lp, prepare, wlr, Method};
    let h = host();
    let (w, hgt) = (24usize, 20usize);
    let layout = AccumLayout::new(w, hgt, false, false);
    let mut acc = Accumulator::new(layout);
    let nch = layout.channels().len();
    let mut rng = Rng(9);
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
    let planes = acc.planes();
    let (accum_buf, accum_mem) = host_accum(&h, &layout, &planes);
    let ctx = import(&h);
    let stats = GpuStats::new(&ctx, "stats", w, hgt, &finalized_layers(&layout)).unwrap();
    let layers: Vec<Layer> = finalized_layers(&layout);
    let clean = GpuStats::new(&ctx, "clean", w, hgt, &prepare::output_layers(&layers)).unwrap();
    let scratch = prepare::PrepareScratch::new(&ctx, &stats).unwrap();
    let planes_wlr = wlr::WlrPlanes::new(&ctx, w, hgt).unwrap();
    let planes_lp = lp::LpPlanes::new(&ctx, w, hgt).unwrap();
    let params = wlr::WlrParams::new(mcdenoise::methods::Pass::Final, &Default::default()).unwrap();
    let params_lp = lp::LpParams::new(&Default::default()).unwrap();

    // SAFETY: the host's live storage buffer of layout.bytes() bytes,
    // destroyed after the work completes (host_teardown).
    let accum = unsafe { BufferSlice::from_raw(accum_buf, 0, layout.bytes()) };
    let timings = host_submit(&h, &ctx, |batch| {
        record_finalize(batch, Precision::F32, &layout, accum, &stats).unwrap();
        prepare::record_prepare(batch, Precision::F32, &stats, &clean, &scratch, true).unwrap();
        match method {
            Method::Wlr => {
                wlr::record_wlr(batch, Precision::F32, &clean, &planes_wlr, params).unwrap()
            }
            Method::Lp => {
                lp::record_lp(batch, Precision::F32, &clean, &planes_lp, params_lp).unwrap()
            }
            _ => unreachable!(),
        }
    });
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
        assert!(timings.iter().any(|t| t.kernel == *k), "no timing for {k}");
    }
    let finalized = finalize_cpu(&layout, &planes);
    let (clean_cpu, _) = prepare::prepare_cpu(&finalized);
    let (gpu_colour, cpu_colour) = match method {
        Method::Wlr => {
            let gpu = wlr::download(&planes_wlr, w, hgt).unwrap();
            let cpu = wlr::run_cpu(&clean_cpu, params).unwrap();
            assert_close("mse", &gpu.mse, &cpu.mse, 0.99);
            (gpu.color, cpu.color)
        }
        _ => {
            let gpu = lp::download(&planes_lp, w, hgt).unwrap();
            let cpu = lp::run_cpu(&clean_cpu, params_lp, false).unwrap();
            for c in 0..3 {
                assert_close("error", &gpu.error.planes[c], &cpu.error.planes[c], 0.99);
            }
            assert_eq!(gpu.centre_pass, cpu.centre_pass);
            (gpu.color, cpu.color)
        }
    };
    for c in 0..3 {
        assert_close(
            &format!("colour {c}"),
            &gpu_colour.planes[c],
            &cpu_colour.planes[c],
            0.99,
        );
    }
    // The reconstruction actually denoised: smoother than the input.
    let input = &finalized.get(Layer::Color).unwrap()[0];
    let rough = |p: &[f32]| {
        (1..p.len())
            .filter(|i| i % w != 0 && i % w != 12)
            .map(|i| (p[i] - p[i - 1]).powi(2) as f64)
            .sum::<f64>()
    };
    assert!(rough(&gpu_colour.planes[0]) < 0.5 * rough(input));

    drop((stats, clean, scratch, planes_wlr, planes_lp));
    drop(ctx);
    host_teardown(h, accum_buf, accum_mem);
}

#[test]
fn host_records_the_whole_wlr_chain() {
    host_records_a_method_chain(mcdenoise::methods::Method::Wlr);
}

#[test]
fn host_records_the_whole_lp_chain() {
    host_records_a_method_chain(mcdenoise::methods::Method::Lp);
}
