//! Issue #14's Vulkan faults, through the test-only hook `mcdenoise::fault`:
//! a failed create in a constructor leaks nothing (the hook's live-object
//! counts return to where they were, and the validation layer reports
//! nothing, teardown included); two threads building one pipeline build it
//! once; out of memory is an error naming what, after which the same work
//! succeeds with identical output; a lost device or a fence wait past the
//! timeout is an error naming the kernels, and every later call on the
//! context returns that same error.
//!
//! Every test here makes its own contexts and compares process-wide
//! live-object counts, so the tests of this binary hold one lock and never
//! run beside each other (faults themselves are per thread).

mod common;

use std::sync::{Arc, Barrier, Mutex, MutexGuard};
use std::time::Duration;

use ash::vk;
use mcdenoise::fault::{self, Call, Failure, Object, Plan};
use mcdenoise::gpu::context::ValidationLog;
use mcdenoise::gpu::{Batch, ContextOptions, GpuBuffer, GpuContext, Precision, Validation};
use mcdenoise::{Config, Denoiser, Error, Frame, Method, Source, StatsImage};

fn serial() -> MutexGuard<'static, ()> {
    static LOCK: Mutex<()> = Mutex::new(());
    LOCK.lock().unwrap_or_else(|e| e.into_inner())
}

fn options() -> ContextOptions {
    let required = std::env::var(common::REQUIRE_VALIDATION).is_ok_and(|v| v == "1");
    ContextOptions {
        device: None,
        validation: if required {
            Validation::Required
        } else {
            Validation::IfInstalled
        },
        ..Default::default()
    }
}

/// A fresh context and its validation log (readable after the context is gone).
fn context() -> (Arc<GpuContext>, Arc<ValidationLog>) {
    let ctx = GpuContext::new(&options()).expect("a Vulkan device");
    let log = ctx.validation_log();
    (Arc::new(ctx), log)
}

/// Drops the last handle of `ctx`, then checks that the validation layer
/// reported nothing (its teardown included) and that every Vulkan object
/// made since `baseline` was destroyed.
fn close(ctx: Arc<GpuContext>, log: Arc<ValidationLog>, baseline: &[(Object, i64)]) {
    let ctx = Arc::try_unwrap(ctx).unwrap_or_else(|_| panic!("the context is still shared"));
    drop(ctx);
    assert_eq!(
        log.errors.load(std::sync::atomic::Ordering::SeqCst),
        0,
        "validation errors: {:#?}",
        log.messages.lock().unwrap()
    );
    assert_eq!(
        fault::live(),
        baseline,
        "live Vulkan objects after teardown"
    );
}

fn fixture() -> StatsImage {
    mcdenoise::io::read_stats(std::path::Path::new(
        "tests/fixtures/dof_checker_64_spp16.exr",
    ))
    .unwrap()
}

fn bits(f: &Frame) -> Vec<u32> {
    f.color
        .planes
        .iter()
        .chain(&f.error.planes)
        .flatten()
        .map(|v| v.to_bits())
        .collect()
}

fn kernel_named(during: &str) -> bool {
    mcdenoise::kernels::ALL
        .iter()
        .any(|k| during.contains(k.name))
}

#[test]
fn context_creation_failures_leak_nothing() {
    let _serial = serial();
    let baseline = fault::live();
    let cases = [
        (Call::CreateInstance, "vkCreateInstance"),
        (Call::CreateDebugMessenger, "vkCreateDebugUtilsMessengerEXT"),
        (Call::CreateDevice, "vkCreateDevice"),
        (Call::CreateAllocator, "allocator"),
    ];
    let validation = context().0.validation_enabled();
    for (call, named) in cases {
        let plan = Plan::new().fail(
            call,
            1,
            Failure::Vk(vk::Result::ERROR_INITIALIZATION_FAILED),
        );
        let result = GpuContext::new(&options());
        if call == Call::CreateDebugMessenger && !validation {
            assert!(result.is_ok() && plan.calls(call) == 0);
            continue;
        }
        let err = result.err().unwrap_or_else(|| panic!("{call:?}: no error"));
        eprintln!("GpuContext::new, {call:?} fails: {err}");
        assert!(plan.all_fired(), "{call:?}");
        assert!(err.to_string().contains(named), "{call:?}: {err}");
        drop(plan);
        assert_eq!(fault::live(), baseline, "{call:?} failed: objects leaked");
    }
    // Out of host memory on the instance is the driver's own error, as is.
    let _plan = Plan::new().fail(
        Call::CreateInstance,
        1,
        Failure::Vk(vk::Result::ERROR_OUT_OF_HOST_MEMORY),
    );
    let err = GpuContext::new(&options()).err().unwrap();
    assert!(err.is_out_of_memory(), "{err}");
    drop(_plan);
    let (ctx, log) = context();
    close(ctx, log, &baseline);
}

#[test]
fn pipeline_build_failures_leak_nothing_and_the_next_build_works() {
    let _serial = serial();
    let baseline = fault::live();
    let (ctx, log) = context();
    let decl = &mcdenoise::kernels::channel_mean::DECL;
    for (call, named) in [
        (
            Call::CreateDescriptorSetLayout,
            "vkCreateDescriptorSetLayout",
        ),
        (Call::CreatePipelineLayout, "vkCreatePipelineLayout"),
        (Call::CreateShaderModule, "vkCreateShaderModule"),
        (Call::CreateComputePipeline, "vkCreateComputePipelines"),
    ] {
        let before = fault::live();
        let plan = Plan::new().fail(call, 1, Failure::Vk(vk::Result::ERROR_OUT_OF_DEVICE_MEMORY));
        let err = ctx.pipeline(decl, Precision::F32).unwrap_err();
        eprintln!("pipeline, {call:?} fails: {err}");
        assert!(plan.all_fired(), "{call:?}");
        match &err {
            Error::Gpu {
                during,
                call: c,
                result,
            } => {
                assert!(during.contains("channel_mean"), "{err}");
                assert_eq!(*c, named);
                assert_eq!(*result, vk::Result::ERROR_OUT_OF_DEVICE_MEMORY);
            }
            other => panic!("{call:?}: {other:?}"),
        }
        assert!(err.is_out_of_memory() && !ctx.is_lost());
        drop(plan);
        assert_eq!(fault::live(), before, "{call:?} failed: objects leaked");
    }
    // The failed builds left no half-built entry: the next one builds, once.
    let a = ctx.pipeline(decl, Precision::F32).unwrap();
    let b = ctx.pipeline(decl, Precision::F32).unwrap();
    assert_eq!((a.pipeline, a.layout), (b.pipeline, b.layout));
    close(ctx, log, &baseline);
}

#[test]
fn concurrent_builds_of_one_pipeline_build_it_once() {
    let _serial = serial();
    let baseline = fault::live();
    let (ctx, log) = context();
    let count = |kind| {
        fault::live()
            .into_iter()
            .find(|(o, _)| *o == kind)
            .unwrap()
            .1
    };
    let pipelines_before = count(Object::Pipeline);
    let kernels = [
        &mcdenoise::kernels::channel_mean::DECL,
        &mcdenoise::kernels::sanitize::DECL,
        &mcdenoise::kernels::gauss_rows::DECL,
    ];
    const THREADS: usize = 4;
    let barrier = Barrier::new(THREADS * kernels.len());
    let handles: Vec<Vec<vk::Pipeline>> = std::thread::scope(|s| {
        let workers: Vec<_> = kernels
            .iter()
            .flat_map(|decl| std::iter::repeat(*decl).take(THREADS))
            .map(|decl| {
                let (ctx, barrier) = (&ctx, &barrier);
                s.spawn(move || {
                    barrier.wait();
                    ctx.pipeline(decl, Precision::F32).unwrap().pipeline
                })
            })
            .collect();
        workers
            .into_iter()
            .map(|w| w.join().unwrap())
            .collect::<Vec<_>>()
            .chunks(THREADS)
            .map(<[_]>::to_vec)
            .collect()
    });
    for (decl, h) in kernels.iter().zip(&handles) {
        assert!(
            h.iter().all(|p| *p == h[0]),
            "{}: threads got different pipelines {h:?}",
            decl.name
        );
    }
    assert_ne!(handles[0][0], handles[1][0]);
    assert_eq!(
        count(Object::Pipeline) - pipelines_before,
        kernels.len() as i64,
        "each kernel built exactly once"
    );
    close(ctx, log, &baseline);
}

/// `Denoiser::warm_up` builds, on its own thread (the caller's thread
/// creates no pipeline while it waits), every pipeline a denoiser of that
/// source and configuration then uses, the sample map's included: the
/// denoiser's thread creates none (it does without the warm-up). A denoiser
/// made while the warm-up is still building gives the same output; nothing
/// leaks.
#[test]
fn warm_up_builds_every_pipeline_the_denoiser_uses() {
    let _serial = serial();
    let baseline = fault::live();
    let img = fixture();
    let source = Source::of_image(&img);
    for method in [Method::Lp, Method::Wlr] {
        let config = Config::new(method);
        let mut runs = Vec::new();
        for mode in ["cold", "warmed", "concurrent"] {
            let (ctx, log) = context();
            let plan = Plan::new();
            let warm = (mode != "cold").then(|| Denoiser::warm_up(&ctx, &source, &config, true));
            let warm = match mode {
                "warmed" => {
                    warm.unwrap().wait();
                    let built = plan.calls(Call::CreateComputePipeline);
                    assert_eq!(
                        built, 0,
                        "{method:?}: the warm-up built on the caller's thread"
                    );
                    None
                }
                _ => warm,
            };
            let before = plan.calls(Call::CreateComputePipeline);
            let d = Denoiser::new(&ctx, source.clone(), config.clone()).unwrap();
            let frame = d.denoise(&img, Some(4096)).unwrap();
            let built = plan.calls(Call::CreateComputePipeline) - before;
            match mode {
                "cold" => assert!(built >= 8, "{method:?}: only {built} pipelines built"),
                "warmed" => assert_eq!(built, 0, "{method:?}: pipelines built after the warm-up"),
                _ => {}
            }
            drop(warm);
            runs.push((bits(&frame), frame.samples.clone()));
            drop((plan, d));
            close(ctx, log, &baseline);
        }
        assert!(
            runs[0] == runs[1],
            "{method:?}: the warm-up changed the output"
        );
        assert!(
            runs[0] == runs[2],
            "{method:?}: a concurrent warm-up changed the output"
        );
    }
    // An accumulation source: its finalisation kernels too.
    let layout = mcdenoise::AccumLayout::new(64, 48, true, false);
    let config = Config::new(Method::Lp);
    for warmed in [false, true] {
        let (ctx, log) = context();
        if warmed {
            Denoiser::warm_up(&ctx, &Source::Accum(layout), &config, true).wait();
        }
        // No samples anywhere: every pixel invalid, every kernel recorded.
        let accum = GpuBuffer::new(&ctx, "test.accum", layout.bytes()).unwrap();
        let plan = Plan::new();
        let d = Denoiser::new(&ctx, Source::Accum(layout), config.clone()).unwrap();
        d.run(Some(accum.slice()), Some(1000)).unwrap();
        let built = plan.calls(Call::CreateComputePipeline);
        if warmed {
            assert_eq!(
                built, 0,
                "accumulation source: pipelines built after the warm-up"
            );
        } else {
            assert!(
                built >= 8,
                "accumulation source: only {built} pipelines built"
            );
        }
        drop((plan, d, accum));
        close(ctx, log, &baseline);
    }
    // Without the sample map: a call without a budget then builds nothing,
    // and the map's kernels (sample_priority, sample_reduce, sample_scan)
    // were left for a call with a budget.
    let config = Config::new(Method::Lp);
    let (ctx, log) = context();
    Denoiser::warm_up(&ctx, &source, &config, false).wait();
    let plan = Plan::new();
    let d = Denoiser::new(&ctx, source.clone(), config).unwrap();
    d.denoise(&img, None).unwrap();
    assert_eq!(
        plan.calls(Call::CreateComputePipeline),
        0,
        "pipelines built after a warm-up without the sample map"
    );
    if ctx.supports_int64() {
        d.denoise(&img, Some(4096)).unwrap();
        assert_eq!(
            plan.calls(Call::CreateComputePipeline),
            3,
            "the sample map's three kernels, built by the first call with a budget"
        );
    }
    drop((plan, d));
    close(ctx, log, &baseline);
}

#[test]
fn batch_and_buffer_creation_failures_leak_nothing() {
    let _serial = serial();
    let baseline = fault::live();
    let (ctx, log) = context();
    for call in [
        Call::CreateCommandPool,
        Call::AllocateCommandBuffer,
        Call::CreateFence,
    ] {
        let before = fault::live();
        let plan = Plan::new().fail(call, 1, Failure::Vk(vk::Result::ERROR_OUT_OF_HOST_MEMORY));
        let err = Batch::new(&ctx).err().expect("an error");
        eprintln!("Batch::new, {call:?} fails: {err}");
        assert!(
            plan.all_fired() && err.is_out_of_memory(),
            "{call:?}: {err}"
        );
        drop(plan);
        assert_eq!(fault::live(), before, "{call:?} failed: objects leaked");
    }
    for call in [Call::CreateBuffer, Call::Allocate] {
        let before = fault::live();
        let plan = Plan::new().fail(call, 1, Failure::Vk(vk::Result::ERROR_OUT_OF_DEVICE_MEMORY));
        let err = GpuBuffer::new(&ctx, "test.planes", 1 << 20).unwrap_err();
        eprintln!("GpuBuffer::new, {call:?} fails: {err}");
        assert!(
            plan.all_fired() && err.is_out_of_memory(),
            "{call:?}: {err}"
        );
        if call == Call::Allocate {
            assert!(
                err.to_string().contains("test.planes"),
                "names the buffer: {err}"
            );
        }
        drop(plan);
        assert_eq!(fault::live(), before, "{call:?} failed: objects leaked");
    }
    // A descriptor pool that cannot be made fails the dispatch; the batch
    // and its buffers go cleanly.
    let before = fault::live();
    {
        let img = fixture();
        let denoiser =
            Denoiser::new(&ctx, Source::of_image(&img), Config::new(Method::None)).unwrap();
        denoiser.upload(&img).unwrap();
        let plan = Plan::new().fail(
            Call::CreateDescriptorPool,
            1,
            Failure::Vk(vk::Result::ERROR_OUT_OF_DEVICE_MEMORY),
        );
        let err = denoiser.run(None, None).unwrap_err();
        eprintln!("Denoiser::run, CreateDescriptorPool 1 fails: {err}");
        assert!(plan.all_fired() && err.is_out_of_memory(), "{err}");
        assert!(
            matches!(&err, Error::Gpu { during, .. } if kernel_named(during)),
            "names the kernel: {err}"
        );
    }
    // (The pipelines it built and the descriptor pools it recycles stay
    // with the context until `close`.)
    let per_call = |live: &[(Object, i64)]| {
        live.iter()
            .filter(|(o, _)| {
                matches!(
                    o,
                    Object::CommandPool | Object::Fence | Object::Buffer | Object::Allocation
                )
            })
            .copied()
            .collect::<Vec<_>>()
    };
    assert_eq!(per_call(&fault::live()), per_call(&before));
    close(ctx, log, &baseline);
}

#[test]
fn out_of_memory_is_named_and_the_next_call_recovers() {
    let _serial = serial();
    let baseline = fault::live();
    let (ctx, log) = context();
    let img = fixture();
    let make = || Denoiser::new(&ctx, Source::of_image(&img), Config::new(Method::Lp));
    let reference = {
        let plan = Plan::new();
        let d = make().unwrap();
        let allocations = plan.calls(Call::Allocate);
        drop(plan);
        assert!(allocations >= 5, "{allocations} allocations");
        let frame = d.denoise(&img, None).unwrap();
        drop(d);
        let before = fault::live();
        // Out of memory at the first, a middle and the last allocation of
        // the constructor: an error naming the buffer, nothing left over.
        for n in [1, allocations / 2, allocations] {
            let plan = Plan::new().fail(
                Call::Allocate,
                n,
                Failure::Vk(vk::Result::ERROR_OUT_OF_DEVICE_MEMORY),
            );
            let err = make().unwrap_err();
            eprintln!("Denoiser::new, allocation {n} of {allocations} fails: {err}");
            assert!(plan.all_fired());
            drop(plan);
            match &err {
                Error::Allocation { name, .. } => assert!(!name.is_empty()),
                other => panic!("allocation {n}: {other:?}"),
            }
            assert!(err.is_out_of_memory(), "{err}");
            assert!(err.to_string().contains("Out of memory"), "{err}");
            assert!(!ctx.is_lost());
            assert_eq!(fault::live(), before, "allocation {n} failed: leaked");
        }
        frame
    };
    // A fresh denoiser after the failures gives the uninjected output.
    let d = make().unwrap();
    assert_eq!(bits(&d.denoise(&img, None).unwrap()), bits(&reference));
    // Out of memory during a call: on a download's staging buffer (reads
    // staged as on a device whose memory the host cannot map; lavapipe's
    // is read directly), then on a submit of the chain; each time the same
    // denoiser's next call works and gives the same output.
    let plan = Plan::new().staged_reads().fail(
        Call::Allocate,
        1,
        Failure::Vk(vk::Result::ERROR_OUT_OF_DEVICE_MEMORY),
    );
    let err = d.denoise(&img, None).unwrap_err();
    eprintln!("Denoiser::denoise, its first allocation fails: {err}");
    drop(plan);
    assert!(
        err.is_out_of_memory() && err.to_string().contains("staging"),
        "{err}"
    );
    assert_eq!(bits(&d.denoise(&img, None).unwrap()), bits(&reference));
    let plan = Plan::new().fail(
        Call::QueueSubmit,
        2,
        Failure::Vk(vk::Result::ERROR_OUT_OF_DEVICE_MEMORY),
    );
    let err = d.denoise(&img, None).unwrap_err();
    eprintln!("Denoiser::denoise, submit 2 fails with ERROR_OUT_OF_DEVICE_MEMORY: {err}");
    drop(plan);
    match &err {
        Error::Gpu { during, call, .. } => {
            assert_eq!(*call, "vkQueueSubmit");
            assert!(kernel_named(during), "names the kernels: {err}");
        }
        other => panic!("{other:?}"),
    }
    assert!(err.is_out_of_memory() && !ctx.is_lost(), "{err}");
    assert_eq!(bits(&d.denoise(&img, None).unwrap()), bits(&reference));
    drop(d);
    close(ctx, log, &baseline);
}

/// Every call after a loss returns `expected` (the first error, again).
fn assert_stays_lost(ctx: &Arc<GpuContext>, d: &Denoiser, img: &StatsImage, expected: &str) {
    assert!(ctx.is_lost());
    let same = |what: &str, e: Error| {
        assert!(e.is_device_lost(), "{what}: {e}");
        assert_eq!(e.to_string(), expected, "{what}");
    };
    same("denoise", d.denoise(img, None).unwrap_err());
    same("run", d.run(None, None).unwrap_err());
    same("read", d.read().unwrap_err());
    same(
        "Denoiser::new",
        Denoiser::new(ctx, Source::of_image(img), Config::new(Method::None)).unwrap_err(),
    );
    same("GpuBuffer::new", GpuBuffer::new(ctx, "x", 16).unwrap_err());
    same("Batch::new", Batch::new(ctx).err().unwrap());
    same(
        "pipeline",
        ctx.pipeline(&mcdenoise::kernels::channel_mean::DECL, Precision::F32)
            .unwrap_err(),
    );
    same("wait_idle", ctx.wait_idle().unwrap_err());
}

#[test]
fn device_loss_names_the_kernels_and_every_later_call_fails_the_same() {
    let _serial = serial();
    let baseline = fault::live();
    let img = fixture();
    for call in [Call::QueueSubmit, Call::WaitForFences] {
        let (ctx, log) = context();
        let d = Denoiser::new(&ctx, Source::of_image(&img), Config::new(Method::Lp)).unwrap();
        // Submit 2 of the call: one of the chain's (on lavapipe the upload
        // is a copy into mapped memory, and the first submit holds the
        // preparation kernels).
        let plan = Plan::new().fail(call, 2, Failure::Vk(vk::Result::ERROR_DEVICE_LOST));
        let err = d.denoise(&img, None).unwrap_err();
        eprintln!("Denoiser::denoise, {call:?} 2 fails with ERROR_DEVICE_LOST: {err}");
        assert!(plan.all_fired());
        drop(plan);
        let message = err.to_string();
        match &err {
            Error::DeviceLost { during } => {
                assert!(kernel_named(during), "{call:?}: names the kernels: {err}")
            }
            other => panic!("{call:?}: {other:?}"),
        }
        assert!(message.contains("cannot continue"), "{message}");
        assert_stays_lost(&ctx, &d, &img, &message);
        drop(d);
        close(ctx, log, &baseline);
    }
}

#[test]
fn a_fence_wait_past_the_timeout_is_an_error_not_a_hang() {
    let _serial = serial();
    let baseline = fault::live();
    let img = fixture();
    let (ctx, log) = context();
    assert_eq!(ctx.fence_timeout(), Duration::from_secs(60));
    let d = Denoiser::new(&ctx, Source::of_image(&img), Config::new(Method::Lp)).unwrap();
    let reference = d.denoise(&img, None).unwrap();
    // A real timeout: LP's kernels take far longer than a nanosecond on any
    // device.
    d.upload(&img).unwrap();
    let mut batch = Batch::new(&ctx).unwrap();
    d.record(&mut batch, None, None).unwrap();
    ctx.set_fence_timeout(Duration::from_nanos(1));
    let err = batch.flush().unwrap_err();
    eprintln!("a real fence timeout of 1 ns: {err}");
    match &err {
        Error::Timeout { during, seconds } => {
            assert!(kernel_named(during), "names the kernels: {err}");
            assert_eq!(*seconds, 1e-9);
        }
        other => panic!("{other:?}"),
    }
    // The batch waits for its work (up to the timeout) before it destroys
    // its command buffer: give it the time.
    ctx.set_fence_timeout(Duration::from_secs(60));
    drop(batch);
    assert_stays_lost(&ctx, &d, &img, &err.to_string());
    drop(d);
    close(ctx, log, &baseline);

    // An injected timeout on a fresh context: the same error, and a fresh
    // context afterwards works as before.
    let (ctx, log) = context();
    let d = Denoiser::new(&ctx, Source::of_image(&img), Config::new(Method::Lp)).unwrap();
    let plan = Plan::new().fail(Call::WaitForFences, 2, Failure::Vk(vk::Result::TIMEOUT));
    let err = d.denoise(&img, None).unwrap_err();
    eprintln!("Denoiser::denoise, WaitForFences 2 returns TIMEOUT: {err}");
    drop(plan);
    assert!(matches!(err, Error::Timeout { .. }), "{err}");
    assert_stays_lost(&ctx, &d, &img, &err.to_string());
    drop(d);
    close(ctx, log, &baseline);
    let (ctx, log) = context();
    let d = Denoiser::new(&ctx, Source::of_image(&img), Config::new(Method::Lp)).unwrap();
    assert_eq!(bits(&d.denoise(&img, None).unwrap()), bits(&reference));
    drop(d);
    close(ctx, log, &baseline);
}

/// A submit that is the first on its context to run a pipeline may take
/// [`FIRST_DISPATCH_ALLOWANCE`] more per such pipeline (llvmpipe compiles a
/// pipeline at its first dispatch, inside the submit): on a fresh context
/// LP's whole chain in one submit completes under a fence timeout of 1 ns;
/// run again, the same submit times out at 1 ns.
#[test]
fn a_first_dispatch_is_given_time_to_compile() {
    use mcdenoise::gpu::context::{FIRST_DISPATCH_ALLOWANCE, FIRST_DISPATCH_ALLOWANCE_MAX};
    let _serial = serial();
    let baseline = fault::live();
    let img = fixture();
    let (ctx, log) = context();
    let ns = Duration::from_nanos(1);
    let d = Denoiser::new(&ctx, Source::of_image(&img), Config::new(Method::Lp)).unwrap();
    d.upload(&img).unwrap();
    let mut batch = Batch::new(&ctx).unwrap();
    // One submit: a budget this large is one band per dispatch.
    batch.max_flops_per_submit = f64::INFINITY;
    assert_eq!(batch.band_rows(64.0, 8), u32::MAX / 8 * 8);
    assert_eq!(batch.band_rows(1e-30, 3), u32::MAX / 3 * 3);
    d.record(&mut batch, None, None).unwrap();
    ctx.set_fence_timeout(ns);
    assert_eq!(ctx.submit_timeout(0), ns);
    assert_eq!(ctx.submit_timeout(3), ns + 3 * FIRST_DISPATCH_ALLOWANCE);
    assert_eq!(ctx.submit_timeout(1000), ns + FIRST_DISPATCH_ALLOWANCE_MAX);
    batch.flush().unwrap();
    assert_eq!(batch.submits, 1);
    ctx.set_fence_timeout(Duration::from_secs(60));
    batch.finish().unwrap();
    let first = d.read().unwrap();
    assert_eq!(bits(&first), bits(&d.denoise(&img, None).unwrap()));

    // Every pipeline has run: no allowance any more.
    d.upload(&img).unwrap();
    let mut batch = Batch::new(&ctx).unwrap();
    batch.max_flops_per_submit = f64::INFINITY;
    d.record(&mut batch, None, None).unwrap();
    ctx.set_fence_timeout(ns);
    let err = batch.flush().unwrap_err();
    match &err {
        Error::Timeout { seconds, .. } => assert_eq!(*seconds, 1e-9),
        other => panic!("{other:?}"),
    }
    ctx.set_fence_timeout(Duration::from_secs(60));
    drop(batch);
    assert_stays_lost(&ctx, &d, &img, &err.to_string());
    drop(d);
    close(ctx, log, &baseline);
}

/// A plane read straight from mapped memory (lavapipe's) equals the same
/// read through a staging copy (the path of device-local memory), at an
/// offset inside the buffer; a range past the end is an error on both paths.
#[test]
fn mapped_and_staged_reads_agree() {
    let _guard = serial();
    let baseline = fault::live();
    let (ctx, log) = context();
    let data: Vec<f32> = (0..4096).map(|i| (i as f32 * 0.37).sin() * 1e3).collect();
    let buffer = GpuBuffer::from_slice(&ctx, "reads", &data).unwrap();
    let slice = buffer.range(1024, 8192);
    let submits = ctx.submit_count();
    let direct = mcdenoise::gpu::buffer::read_slice(&ctx, slice, 2048).unwrap();
    // lavapipe's memory is host memory, mapped and coherent: no copy.
    assert_eq!(
        ctx.submit_count(),
        submits,
        "the direct read submitted work"
    );
    let plan = Plan::new().staged_reads();
    let staged = mcdenoise::gpu::buffer::read_slice(&ctx, slice, 2048).unwrap();
    assert!(
        plan.calls(Call::QueueSubmit) >= 1,
        "the staged read copies on the GPU"
    );
    drop(plan);
    assert_eq!(direct, data[256..2304]);
    assert_eq!(staged, direct);
    for staged in [false, true] {
        let plan = staged.then(|| Plan::new().staged_reads());
        assert!(mcdenoise::gpu::buffer::read_slice(&ctx, slice, 2049).is_err());
        drop(plan);
    }
    drop(buffer);
    close(ctx, log, &baseline);
}
