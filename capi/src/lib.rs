//! The C API of mcdenoise (`include/mcdenoise.h`, generated from this file by
//! cbindgen in `build.rs`).
//!
//! A C or C++ renderer hands mcdenoise its Vulkan instance, device and queue,
//! accumulates its samples in its own shaders with the layout of
//! `include/mcdenoise_accum.glsl`, and records mcdenoise's passes into its
//! own command buffers. Objects are opaque handles; every function returns
//! an [`McdStatus`] and, on failure, leaves a message for
//! [`mcd_last_error`]. Nothing panics across the boundary: a panic inside is
//! caught and returned as [`McdStatus::Internal`].

#![allow(non_camel_case_types)]

use std::cell::RefCell;
use std::ffi::{c_char, c_void, CStr, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::Arc;

use ash::vk;
use mcdenoise_core as core;
use mcdenoise_core::{
    AccumLayout, BufferSlice, Config, Denoiser, Error, GpuContext, ImportedDevice, Method, Options,
    Pass, Recorded, Source,
};

/// The version of this API; a host checks [`mcd_api_version`] against the
/// header's `MCDENOISE_API_VERSION` at run time.
pub const MCDENOISE_API_VERSION: u32 = 1;

/// Vulkan's instance handle (`vulkan.h`).
pub type VkInstance = vk::Instance;
/// Vulkan's physical-device handle (`vulkan.h`).
pub type VkPhysicalDevice = vk::PhysicalDevice;
/// Vulkan's device handle (`vulkan.h`).
pub type VkDevice = vk::Device;
/// Vulkan's queue handle (`vulkan.h`).
pub type VkQueue = vk::Queue;
/// Vulkan's command-buffer handle (`vulkan.h`).
pub type VkCommandBuffer = vk::CommandBuffer;
/// Vulkan's buffer handle (`vulkan.h`).
pub type VkBuffer = vk::Buffer;
/// The loader's entry point (`vulkan.h`).
pub type PFN_vkGetInstanceProcAddr = Option<vk::PFN_vkGetInstanceProcAddr>;

/// What a call returned.
#[repr(C)]
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum McdStatus {
    /// Success.
    Ok = 0,
    /// A null pointer, a size that does not match, an unknown method or
    /// option, a call that does not apply (a sample map that was not made).
    InvalidArgument = 1,
    /// Device or host memory ran out; the context stays usable.
    OutOfMemory = 2,
    /// The device was lost or a submission timed out: make a new context.
    DeviceLost = 3,
    /// The device lacks a feature, or a limit is exceeded.
    Unsupported = 4,
    /// A Vulkan call failed.
    Vulkan = 5,
    /// Anything else, including a panic caught at the boundary (a bug).
    Internal = 6,
}

/// The reconstruction method (spec sections in `docs/algorithms.md`).
#[repr(C)]
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum McdMethod {
    /// Weighted local regression (§2); the default.
    Wlr = 0,
    /// Linear predictions (§3).
    Lp = 1,
    /// Adaptive polynomial rendering (§4).
    Apr = 2,
    /// Adaptive-order polynomial fitting (§5).
    Aos = 3,
    /// No reconstruction: the sanitised mean.
    None = 4,
    /// WLR, LP and APR (and AOS with the option `auto.aos=on`) blended per
    /// pixel by their error estimates.
    Auto = 5,
}

/// The accumulation layout the host's shaders write
/// (`include/mcdenoise_accum.glsl`).
#[repr(C)]
#[derive(Copy, Clone, Debug)]
pub struct McdAccumLayout {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Non-zero if positions are accumulated (`MCDENOISE_ACCUM_POSITION`).
    pub position: u32,
    /// Non-zero if visibility is accumulated (`MCDENOISE_ACCUM_VISIBILITY`).
    pub visibility: u32,
    /// The point positions are accumulated relative to (finite). A
    /// denoiser finalises every frame with the origin it was made with:
    /// keep one for all the frames a temporal denoiser filters.
    pub position_origin: [f32; 3],
}

/// The host's Vulkan objects. mcdenoise creates and destroys only its own
/// objects on `device`; the host destroys the device and the instance after
/// every mcdenoise object.
#[repr(C)]
#[derive(Copy, Clone, Debug)]
pub struct McdVulkanDevice {
    /// The host's instance.
    pub instance: VkInstance,
    /// The physical device `device` was created from.
    pub physical_device: VkPhysicalDevice,
    /// The host's logical device.
    pub device: VkDevice,
    /// A queue of `queue_family_index` (used only by calls that submit, none
    /// of this API's today).
    pub queue: VkQueue,
    /// A queue family with compute; the host's command buffers handed to
    /// [`mcd_denoiser_record`] come from a pool of this family.
    pub queue_family_index: u32,
    /// The loader's `vkGetInstanceProcAddr` the instance was made with.
    pub get_instance_proc_addr: PFN_vkGetInstanceProcAddr,
    /// Non-zero if the host enabled `shaderFloat64` on `device`.
    pub shader_float64_enabled: u32,
    /// Non-zero if the host enabled `shaderInt64` on `device` (no kernel
    /// needs it today).
    pub shader_int64_enabled: u32,
}

/// Flag of [`McdDenoiserDesc::flags`]: every pixel has 0 or at least 2
/// samples, which skips the one-sample variance repair (§0.4 step 3).
pub const MCD_FLAG_NO_SINGLE_SAMPLE_PIXELS: u32 = 1;
/// Flag of [`McdDenoiserDesc::flags`]: the adaptive pass's smaller windows
/// (§9.3) instead of the final reconstruction's. For a final image by LP,
/// APR, AOS or `auto`, the built-in loop makes its adaptive passes with
/// WLR, whose maps served them better than their own on its scenes, or
/// as well for less time (decision records MAP-WLR, AUTO-MAPS).
pub const MCD_FLAG_ADAPTIVE_PASS: u32 = 2;
/// Flag of [`McdDenoiserDesc::flags`]: the LP temporal filter (§10.1)
/// after the method. Each recording is the next frame of a sequence: the
/// filter's state stays in the denoiser's buffers from one to the next
/// ([`mcd_denoiser_reset`] at a cut). Needs the layout's position sums.
pub const MCD_FLAG_TEMPORAL_LP: u32 = 4;
/// Flag of [`McdDenoiserDesc::flags`]: the pyramid's low band after the
/// method (PYRAMID-LOWBAND): the method also reconstructs the statistics
/// pooled 2×2, and the output takes its low band from that
/// half-resolution reconstruction where the error estimates favour it.
/// Not for `MCD_METHOD_NONE` or images under 16×16 pixels. Without this
/// flag or [`MCD_FLAG_NO_PYRAMID`], the stage runs after `MCD_METHOD_AUTO`
/// on images of at least 16×16 pixels and after no other method.
pub const MCD_FLAG_PYRAMID: u32 = 8;
/// Flag of [`McdDenoiserDesc::flags`]: never the pyramid's low band (see
/// [`MCD_FLAG_PYRAMID`]); both flags together are an error.
pub const MCD_FLAG_NO_PYRAMID: u32 = 16;
/// Flag of [`McdDenoiserDesc::flags`]: the input blend after the method
/// (INPUT-BLEND): each pixel's output is the method's and the input's,
/// weighed by the method's error estimate (read as at least what the
/// residual shows, BLEND-RESIDUAL) and the input's variance. Not for
/// `MCD_METHOD_NONE`. Without this flag or [`MCD_FLAG_NO_INPUT_BLEND`], the
/// stage runs in a final reconstruction after every method but
/// `MCD_METHOD_AUTO`.
pub const MCD_FLAG_INPUT_BLEND: u32 = 32;
/// Flag of [`McdDenoiserDesc::flags`]: never the input blend (see
/// [`MCD_FLAG_INPUT_BLEND`]); both flags together are an error.
pub const MCD_FLAG_NO_INPUT_BLEND: u32 = 64;
/// Flag of [`McdDenoiserDesc::flags`], with [`MCD_FLAG_ADAPTIVE_PASS`]: the
/// sample map from a half-resolution reconstruction (MAP-COARSE). The
/// method runs on the statistics pooled over 2×2 blocks only, about a
/// quarter of its work, and each pixel takes its block's priority; the
/// denoiser's colour and error outputs are then the input's mean and
/// variance. Not for `MCD_METHOD_NONE`, images under 16×16 pixels, the
/// temporal filter, or with [`MCD_FLAG_PYRAMID`] or
/// [`MCD_FLAG_INPUT_BLEND`].
pub const MCD_FLAG_COARSE_MAP: u32 = 128;

/// One denoiser's configuration: fixed for its life.
#[repr(C)]
#[derive(Copy, Clone, Debug)]
pub struct McdDenoiserDesc {
    /// The accumulation buffer's layout (and so the image size).
    pub layout: McdAccumLayout,
    /// The method: an [`McdMethod`] value (an unknown one is an error).
    pub method: u32,
    /// `MCD_FLAG_*` bits.
    pub flags: u32,
    /// Method options, `key=value` separated by spaces as
    /// `mcdenoise denoise --help` lists them; NULL or "" for none.
    pub options: *const c_char,
}

/// The denoiser's GPU-resident outputs: planes of `width × height` values in
/// row-major order, each a range of a `VkBuffer` the denoiser owns, valid
/// until the denoiser is destroyed and overwritten by each recording.
#[repr(C)]
#[derive(Copy, Clone, Debug)]
pub struct McdOutputs {
    /// Reconstructed colour R, G, B (f32 planes).
    pub color_buffer: [VkBuffer; 3],
    /// Byte offsets of the colour planes in their buffers.
    pub color_offset: [u64; 3],
    /// Estimated mean squared error per channel (f32 planes).
    pub error_buffer: [VkBuffer; 3],
    /// Byte offsets of the error planes.
    pub error_offset: [u64; 3],
    /// Bytes of one f32 plane (`4 × width × height`).
    pub plane_bytes: u64,
    /// The next pass's samples per pixel (u32), after a recording with a
    /// budget (every device makes it).
    pub samples_buffer: VkBuffer,
    /// Byte offset of the sample map.
    pub samples_offset: u64,
}

/// A context: mcdenoise's allocator, pipelines and command pool on the
/// host's device.
pub struct McdContext {
    ctx: Arc<GpuContext>,
}

/// A denoiser for one image size and configuration.
pub struct McdDenoiser {
    denoiser: Denoiser,
    layout: AccumLayout,
}

/// Work recorded into a host command buffer: keeps the denoiser's buffers
/// alive until the host releases it after its submission completed.
pub struct McdRecording {
    _recorded: Recorded,
}

thread_local! {
    static LAST_ERROR: RefCell<CString> = RefCell::new(CString::default());
}

fn set_error(message: &str) {
    let c = CString::new(message.replace('\0', " ")).unwrap_or_default();
    LAST_ERROR.with(|e| *e.borrow_mut() = c);
}

fn status_of(e: &Error) -> McdStatus {
    if e.is_out_of_memory() {
        McdStatus::OutOfMemory
    } else if e.is_device_lost() {
        McdStatus::DeviceLost
    } else {
        match e {
            Error::InvalidArgument(_) | Error::BadData(_) => McdStatus::InvalidArgument,
            Error::Limit(_) | Error::NoDevice(_) | Error::NoLoader(_) => McdStatus::Unsupported,
            Error::Vulkan { .. } | Error::Gpu { .. } => McdStatus::Vulkan,
            _ => McdStatus::Internal,
        }
    }
}

/// Why a call failed: its status and message.
struct Failure(McdStatus, String);

impl From<Error> for Failure {
    fn from(e: Error) -> Failure {
        Failure(status_of(&e), e.to_string())
    }
}

fn invalid(message: impl Into<String>) -> Failure {
    Failure(McdStatus::InvalidArgument, message.into())
}

/// Runs `f` behind the boundary: its error or panic becomes a status and a
/// message for [`mcd_last_error`].
fn guard(f: impl FnOnce() -> Result<(), Failure>) -> McdStatus {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(Ok(())) => {
            set_error("");
            McdStatus::Ok
        }
        Ok(Err(Failure(status, message))) => {
            set_error(&message);
            status
        }
        Err(panic) => {
            let what = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".into());
            set_error(&format!("internal error (a bug in mcdenoise): {what}"));
            McdStatus::Internal
        }
    }
}

/// `ptr` as a reference, or an error naming `what`.
///
/// # Safety
/// `ptr` is null or points to a valid `T`.
unsafe fn non_null<'a, T>(ptr: *const T, what: &str) -> Result<&'a T, Failure> {
    // SAFETY: forwarded to the caller.
    unsafe { ptr.as_ref() }.ok_or_else(|| invalid(format!("{what} is NULL")))
}

/// The out-pointer `out`, checked non-null before any work is done.
fn out_ptr<T>(out: *mut T) -> Result<*mut T, Failure> {
    if out.is_null() {
        return Err(invalid("out is NULL"));
    }
    Ok(out)
}

fn layout_of(l: &McdAccumLayout) -> Result<AccumLayout, Failure> {
    if l.width == 0 || l.height == 0 {
        return Err(invalid(format!(
            "the layout's size {}x{} is empty",
            l.width, l.height
        )));
    }
    if !l.position_origin.iter().all(|v| v.is_finite()) {
        return Err(invalid(format!(
            "the layout's position origin {:?} is not finite",
            l.position_origin
        )));
    }
    Ok(AccumLayout::new(
        l.width as usize,
        l.height as usize,
        l.position != 0,
        l.visibility != 0,
    )
    .with_position_origin(l.position_origin))
}

/// `img`'s planes as RGB triples in `dst` (3 values per pixel).
fn interleave_rgb(img: &core::RgbImage, dst: &mut [f32]) {
    for (c, plane) in img.planes.iter().enumerate() {
        for (i, v) in plane.iter().enumerate() {
            dst[3 * i + c] = *v;
        }
    }
}

/// The layout `ptr` points to, if it is valid.
///
/// # Safety
/// `ptr` is null or points to a valid [`McdAccumLayout`].
unsafe fn valid_layout(ptr: *const McdAccumLayout) -> Option<AccumLayout> {
    // SAFETY: forwarded to the caller.
    unsafe { ptr.as_ref() }.and_then(|l| layout_of(l).ok())
}

/// The version of the library: compare with `MCDENOISE_API_VERSION`.
#[no_mangle]
pub extern "C" fn mcd_api_version() -> u32 {
    MCDENOISE_API_VERSION
}

/// The message of the last failed call on this thread ("" after a
/// success). Valid until the next mcdenoise call on this thread.
#[no_mangle]
pub extern "C" fn mcd_last_error() -> *const c_char {
    LAST_ERROR.with(|e| e.borrow().as_ptr())
}

/// Bytes of the accumulation buffer for `layout` (0 for an invalid layout).
///
/// # Safety
/// `layout` is null or points to a valid [`McdAccumLayout`].
#[no_mangle]
pub unsafe extern "C" fn mcd_accum_bytes(layout: *const McdAccumLayout) -> u64 {
    // SAFETY: forwarded to the caller.
    unsafe { valid_layout(layout) }.map_or(0, |l| l.bytes())
}

/// Bytes from one accumulation plane's start to the next (the GLSL header's
/// `4 * mcd_plane_stride(width * height)`); 0 for an invalid layout.
///
/// # Safety
/// `layout` is null or points to a valid [`McdAccumLayout`].
#[no_mangle]
pub unsafe extern "C" fn mcd_accum_plane_stride(layout: *const McdAccumLayout) -> u64 {
    // SAFETY: forwarded to the caller.
    unsafe { valid_layout(layout) }.map_or(0, |l| l.plane_stride())
}

/// Number of planes of the accumulation layout; 0 for an invalid layout.
///
/// # Safety
/// `layout` is null or points to a valid [`McdAccumLayout`].
#[no_mangle]
pub unsafe extern "C" fn mcd_accum_plane_count(layout: *const McdAccumLayout) -> u32 {
    // SAFETY: forwarded to the caller.
    unsafe { valid_layout(layout) }.map_or(0, |l| l.plane_count() as u32)
}

/// Creates a context on the host's device.
///
/// # Safety
/// `device` points to a valid [`McdVulkanDevice`] whose handles satisfy its
/// field documentation: `device` was created from `physical_device` of
/// `instance`, `queue` belongs to `queue_family_index`, which supports
/// compute, the 64-bit flags are non-zero only if those features were
/// enabled, and the instance and device outlive every mcdenoise object made
/// from this context. `out` is valid for a write.
#[no_mangle]
pub unsafe extern "C" fn mcd_context_create(
    device: *const McdVulkanDevice,
    out: *mut *mut McdContext,
) -> McdStatus {
    guard(|| {
        // SAFETY: forwarded to the caller.
        let d = unsafe { non_null(device, "device") }?;
        let out = out_ptr(out)?;
        let gipa = d
            .get_instance_proc_addr
            .ok_or_else(|| invalid("device->get_instance_proc_addr is NULL"))?;
        if d.instance == vk::Instance::null()
            || d.physical_device == vk::PhysicalDevice::null()
            || d.device == vk::Device::null()
            || d.queue == vk::Queue::null()
        {
            return Err(invalid("a Vulkan handle of device is VK_NULL_HANDLE"));
        }
        // SAFETY: the caller guarantees the handles and the entry point are
        // valid and belong together.
        let ctx = unsafe {
            let entry = ash::Entry::from_static_fn(ash::StaticFn {
                get_instance_proc_addr: gipa,
            });
            let instance = ash::Instance::load(entry.static_fn(), d.instance);
            let device = ash::Device::load(instance.fp_v1_0(), d.device);
            GpuContext::from_raw(ImportedDevice {
                entry,
                instance,
                physical_device: d.physical_device,
                device,
                queue: d.queue,
                queue_family_index: d.queue_family_index,
                shader_float64_enabled: d.shader_float64_enabled != 0,
                shader_int64_enabled: d.shader_int64_enabled != 0,
            })
        }?;
        let handle = Box::into_raw(Box::new(McdContext { ctx: Arc::new(ctx) }));
        // SAFETY: non-null (checked first) and valid for writes by the
        // caller's contract.
        unsafe { out.write(handle) };
        Ok(())
    })
}

/// Destroys a context (NULL is ignored). Its objects on the device live
/// until the last denoiser made from it is destroyed too.
///
/// # Safety
/// `ctx` is NULL or a context from [`mcd_context_create`] not destroyed yet.
#[no_mangle]
pub unsafe extern "C" fn mcd_context_destroy(ctx: *mut McdContext) {
    if !ctx.is_null() {
        let _ = catch_unwind(AssertUnwindSafe(|| {
            // SAFETY: the caller passes a live handle from mcd_context_create.
            drop(unsafe { Box::from_raw(ctx) })
        }));
    }
}

/// Builds the context's pipelines through a `VkPipelineCache` kept in the
/// file `path` (UTF-8, NUL-terminated): loaded now (a missing file, or one
/// of another device or driver, starts empty) and written back atomically
/// when the context is destroyed if pipelines were built meanwhile, or by
/// [`mcd_context_save_pipeline_cache`]. Call before creating denoisers.
/// `loaded_bytes` (may be NULL) receives the bytes loaded.
///
/// # Safety
/// `ctx` is live, `path` a NUL-terminated string, `loaded_bytes` NULL or
/// valid for a write.
#[no_mangle]
pub unsafe extern "C" fn mcd_context_use_pipeline_cache(
    ctx: *const McdContext,
    path: *const c_char,
    loaded_bytes: *mut u64,
) -> McdStatus {
    guard(|| {
        // SAFETY: forwarded to the caller.
        let ctx = unsafe { non_null(ctx, "ctx") }?;
        if path.is_null() {
            return Err(invalid("path is NULL"));
        }
        // SAFETY: the caller passes a NUL-terminated string.
        let path = unsafe { CStr::from_ptr(path) }
            .to_str()
            .map_err(|_| invalid("path is not UTF-8"))?;
        let n = ctx.ctx.use_pipeline_cache(std::path::Path::new(path))?;
        if !loaded_bytes.is_null() {
            // SAFETY: non-null and valid for writes by the caller's contract.
            unsafe { loaded_bytes.write(n as u64) };
        }
        Ok(())
    })
}

/// Writes the context's pipeline cache to its file now; `saved_bytes` (may
/// be NULL) receives the bytes written (0 without a cache).
///
/// # Safety
/// `ctx` is live, `saved_bytes` NULL or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn mcd_context_save_pipeline_cache(
    ctx: *const McdContext,
    saved_bytes: *mut u64,
) -> McdStatus {
    guard(|| {
        // SAFETY: forwarded to the caller.
        let ctx = unsafe { non_null(ctx, "ctx") }?;
        let n = ctx.ctx.save_pipeline_cache()?;
        if !saved_bytes.is_null() {
            // SAFETY: non-null and valid for writes by the caller's contract.
            unsafe { saved_bytes.write(n as u64) };
        }
        Ok(())
    })
}

/// Creates a denoiser: builds its pipelines and allocates its buffers.
///
/// # Safety
/// `ctx` is a live context, `desc` points to a valid [`McdDenoiserDesc`]
/// (its `options` NULL or a NUL-terminated string), `out` is valid for a
/// write.
#[no_mangle]
pub unsafe extern "C" fn mcd_denoiser_create(
    ctx: *const McdContext,
    desc: *const McdDenoiserDesc,
    out: *mut *mut McdDenoiser,
) -> McdStatus {
    guard(|| {
        // SAFETY: forwarded to the caller.
        let (ctx, desc) = unsafe { (non_null(ctx, "ctx")?, non_null(desc, "desc")?) };
        let out = out_ptr(out)?;
        let layout = layout_of(&desc.layout)?;
        let method = match desc.method {
            m if m == McdMethod::Wlr as u32 => Method::Wlr,
            m if m == McdMethod::Lp as u32 => Method::Lp,
            m if m == McdMethod::Apr as u32 => Method::Apr,
            m if m == McdMethod::Aos as u32 => Method::Aos,
            m if m == McdMethod::None as u32 => Method::None,
            m if m == McdMethod::Auto as u32 => Method::Auto,
            m => return Err(invalid(format!("unknown method {m}"))),
        };
        let known = MCD_FLAG_NO_SINGLE_SAMPLE_PIXELS
            | MCD_FLAG_ADAPTIVE_PASS
            | MCD_FLAG_TEMPORAL_LP
            | MCD_FLAG_PYRAMID
            | MCD_FLAG_NO_PYRAMID
            | MCD_FLAG_INPUT_BLEND
            | MCD_FLAG_NO_INPUT_BLEND
            | MCD_FLAG_COARSE_MAP;
        if desc.flags & !known != 0 {
            return Err(invalid(format!("unknown flags {:#x}", desc.flags & !known)));
        }
        let mut config = Config::new(method);
        config.low_spp = desc.flags & MCD_FLAG_NO_SINGLE_SAMPLE_PIXELS == 0;
        if desc.flags & MCD_FLAG_ADAPTIVE_PASS != 0 {
            config.pass = Pass::Intermediate;
        }
        if desc.flags & MCD_FLAG_TEMPORAL_LP != 0 {
            config.temporal = core::Temporal::Lp;
        }
        config.coarse_map = desc.flags & MCD_FLAG_COARSE_MAP != 0;
        config.pyramid = match (
            desc.flags & MCD_FLAG_PYRAMID != 0,
            desc.flags & MCD_FLAG_NO_PYRAMID != 0,
        ) {
            (false, false) => core::Pyramid::Auto,
            (true, false) => core::Pyramid::On,
            (false, true) => core::Pyramid::Off,
            (true, true) => {
                return Err(invalid("MCD_FLAG_PYRAMID and MCD_FLAG_NO_PYRAMID together"))
            }
        };
        config.input_blend = match (
            desc.flags & MCD_FLAG_INPUT_BLEND != 0,
            desc.flags & MCD_FLAG_NO_INPUT_BLEND != 0,
        ) {
            (false, false) => core::InputBlend::Auto,
            (true, false) => core::InputBlend::On,
            (false, true) => core::InputBlend::Off,
            (true, true) => {
                return Err(invalid(
                    "MCD_FLAG_INPUT_BLEND and MCD_FLAG_NO_INPUT_BLEND together",
                ))
            }
        };
        if !desc.options.is_null() {
            // SAFETY: the caller passes a NUL-terminated string.
            let text = unsafe { CStr::from_ptr(desc.options) }
                .to_str()
                .map_err(|_| invalid("options are not UTF-8"))?;
            let pairs: Vec<&str> = text.split_whitespace().collect();
            config.options = Options::parse(&pairs)?;
        }
        let denoiser = Denoiser::new(&ctx.ctx, Source::Accum(layout), config)?;
        let handle = Box::into_raw(Box::new(McdDenoiser { denoiser, layout }));
        // SAFETY: non-null (checked first) and valid for writes by the
        // caller's contract.
        unsafe { out.write(handle) };
        Ok(())
    })
}

/// Forgets the temporal filter's history ([`MCD_FLAG_TEMPORAL_LP`]): the
/// next recording reinitialises every pixel, as at a sequence's first
/// frame. Call it at a cut. Nothing for a denoiser without the filter.
///
/// # Safety
/// `denoiser` is a live denoiser from [`mcd_denoiser_create`].
#[no_mangle]
pub unsafe extern "C" fn mcd_denoiser_reset(denoiser: *const McdDenoiser) -> McdStatus {
    guard(|| {
        // SAFETY: forwarded to the caller.
        let d = unsafe { non_null(denoiser, "denoiser")? };
        d.denoiser.reset();
        Ok(())
    })
}

/// Destroys a denoiser (NULL is ignored). Buffers that recordings not yet
/// released still bind stay alive until those are released.
///
/// # Safety
/// `denoiser` is NULL or a live denoiser from [`mcd_denoiser_create`].
#[no_mangle]
pub unsafe extern "C" fn mcd_denoiser_destroy(denoiser: *mut McdDenoiser) {
    if !denoiser.is_null() {
        let _ = catch_unwind(AssertUnwindSafe(|| {
            // SAFETY: the caller passes a live handle from mcd_denoiser_create.
            drop(unsafe { Box::from_raw(denoiser) })
        }));
    }
}

/// Records the whole chain into the host's command buffer `cmd`:
/// finalisation of the accumulation buffer (`accum` from byte
/// `accum_offset`, [`mcd_accum_bytes`] long), sanitation, prefilter, the
/// method, its error estimate and, when `sample_budget` > 0, the next
/// pass's sample map spending exactly `sample_budget` samples. Nothing is
/// submitted. The work starts with a barrier after every earlier command of
/// `cmd` and ends with one before every later command.
///
/// `queue_family` is the family of the pool `cmd` came from; one other than
/// the context's is `MCD_STATUS_INVALID_ARGUMENT` before anything is recorded (the
/// denoiser's buffers belong to the context's family).
///
/// On success `*out` holds a recording the host releases
/// ([`mcd_recording_release`]) once the submission of `cmd` completed (or
/// if `cmd` is never submitted). On failure the host must discard `cmd`
/// (reset or free it without submitting): part of the chain may be in it.
///
/// # Safety
/// `denoiser` is live; `cmd` belongs to the context's device, comes from a
/// pool of queue family `queue_family`, is recording and outside a render
/// pass; `accum` is a buffer of that device with storage-buffer and
/// transfer-source usage (finalisation copies its count plane) and at least `accum_offset + mcd_accum_bytes(layout)` bytes, not written by
/// other work while this work runs; `out` is valid for a write. No other
/// recording of this denoiser runs on the GPU at the same time.
#[no_mangle]
pub unsafe extern "C" fn mcd_denoiser_record(
    denoiser: *const McdDenoiser,
    cmd: VkCommandBuffer,
    queue_family: u32,
    accum: VkBuffer,
    accum_offset: u64,
    sample_budget: u32,
    out: *mut *mut McdRecording,
) -> McdStatus {
    guard(|| {
        // SAFETY: forwarded to the caller.
        let d = unsafe { non_null(denoiser, "denoiser") }?;
        let out = out_ptr(out)?;
        if cmd == vk::CommandBuffer::null() || accum == vk::Buffer::null() {
            return Err(invalid("cmd or accum is VK_NULL_HANDLE"));
        }
        // SAFETY: the caller guarantees the buffer's size and usage.
        let slice = unsafe { BufferSlice::from_raw(accum, accum_offset, d.layout.bytes()) };
        let budget = (sample_budget > 0).then_some(sample_budget);
        // SAFETY: forwarded to the caller (record_into's contract).
        let recorded = unsafe {
            d.denoiser
                .record_into(cmd, queue_family, Some(slice), budget)
        }?;
        let handle = Box::into_raw(Box::new(McdRecording {
            _recorded: recorded,
        }));
        // SAFETY: checked non-null above; the caller guarantees validity.
        unsafe { out.write(handle) };
        Ok(())
    })
}

/// Denoises accumulation sums in host memory, for a renderer that
/// accumulates on the CPU: `sums` holds `bytes` = [`mcd_accum_bytes`] of
/// the denoiser's layout, the planes exactly as `include/mcdenoise_accum.glsl`
/// lays them out in a device buffer ([`mcd_accum_plane_stride`] apart).
/// mcdenoise copies them to a device buffer of its own (kept for the next
/// call), submits the whole chain to the context's queue and waits; then
/// [`mcd_denoiser_read`] copies the results to host memory. `sample_budget`
/// as for [`mcd_denoiser_record`]. The results are those of
/// [`mcd_denoiser_record`] on a device buffer holding the same bytes.
///
/// # Safety
/// `denoiser` is live; `sums` is valid for reads of `bytes` bytes. The
/// context's queue is not used by the host during the call.
#[no_mangle]
pub unsafe extern "C" fn mcd_denoiser_run_host(
    denoiser: *const McdDenoiser,
    sums: *const c_void,
    bytes: u64,
    sample_budget: u32,
) -> McdStatus {
    guard(|| {
        // SAFETY: forwarded to the caller.
        let d = unsafe { non_null(denoiser, "denoiser") }?;
        if sums.is_null() {
            return Err(invalid("sums is NULL"));
        }
        // The length is checked against the layout by run_host_accum.
        // SAFETY: the caller guarantees `bytes` readable bytes at `sums`.
        let data = unsafe { std::slice::from_raw_parts(sums.cast::<u8>(), bytes as usize) };
        let budget = (sample_budget > 0).then_some(sample_budget);
        d.denoiser.run_host_accum(data, budget)?;
        Ok(())
    })
}

/// Releases a recording (NULL is ignored), after the submission of its
/// command buffer completed or once the buffer was discarded.
///
/// # Safety
/// `recording` is NULL or a live recording from [`mcd_denoiser_record`].
#[no_mangle]
pub unsafe extern "C" fn mcd_recording_release(recording: *mut McdRecording) {
    if !recording.is_null() {
        let _ = catch_unwind(AssertUnwindSafe(|| {
            // SAFETY: the caller passes a live handle from mcd_denoiser_record.
            drop(unsafe { Box::from_raw(recording) })
        }));
    }
}

/// The denoiser's GPU-resident outputs, for binding in the host's shaders
/// (its next pass reads the sample map).
///
/// # Safety
/// `denoiser` is live and `out` valid for a write.
#[no_mangle]
pub unsafe extern "C" fn mcd_denoiser_outputs(
    denoiser: *const McdDenoiser,
    out: *mut McdOutputs,
) -> McdStatus {
    guard(|| {
        // SAFETY: forwarded to the caller.
        let d = unsafe { non_null(denoiser, "denoiser") }?;
        let out = out_ptr(out)?;
        let o = d.denoiser.outputs()?;
        let samples = o.samples;
        let outputs = McdOutputs {
            color_buffer: o.color.map(|s| s.buffer()),
            color_offset: o.color.map(|s| s.offset()),
            error_buffer: o.error.map(|s| s.buffer()),
            error_offset: o.error.map(|s| s.offset()),
            plane_bytes: 4 * d.layout.pixels() as u64,
            samples_buffer: samples.map_or(vk::Buffer::null(), |s| s.buffer()),
            samples_offset: samples.map_or(0, |s| s.offset()),
        };
        // SAFETY: non-null (checked first) and valid for writes by the
        // caller's contract.
        unsafe { out.write(outputs) };
        Ok(())
    })
}

/// Copies the outputs of the last completed recording to host memory:
/// `color` and `error` get `width × height` RGB triples (interleaved f32,
/// row-major), `samples` the next pass's samples per pixel. Any of them may
/// be NULL (not copied); `pixels` is the length in pixels of those given
/// and must equal `width × height`. Call only after the submission of the
/// recording completed. A non-NULL `samples` after a recording without a
/// budget is an error.
///
/// # Safety
/// `denoiser` is live; each non-NULL pointer is valid for writes of
/// `pixels` (`samples`) or `3 * pixels` (`color`, `error`) values.
#[no_mangle]
pub unsafe extern "C" fn mcd_denoiser_read(
    denoiser: *const McdDenoiser,
    color: *mut f32,
    error: *mut f32,
    samples: *mut u32,
    pixels: u64,
) -> McdStatus {
    guard(|| {
        // SAFETY: forwarded to the caller.
        let d = unsafe { non_null(denoiser, "denoiser") }?;
        let n = d.layout.pixels();
        if pixels != n as u64 {
            return Err(invalid(format!(
                "pixels is {pixels}, the denoiser's image has {}",
                n
            )));
        }
        let frame = d.denoiser.read()?;
        let interleave = |img: &core::RgbImage, dst: *mut f32| {
            // SAFETY: the caller guarantees room for 3 * pixels values.
            interleave_rgb(img, unsafe { std::slice::from_raw_parts_mut(dst, 3 * n) });
        };
        if !color.is_null() {
            interleave(&frame.color, color);
        }
        if !error.is_null() {
            if frame.error.planes[0].len() != n {
                return Err(invalid("the denoiser computed no error estimate"));
            }
            interleave(&frame.error, error);
        }
        if !samples.is_null() {
            let map = frame
                .samples
                .ok_or_else(|| invalid("no sample map: the last recording had no sample budget"))?;
            // SAFETY: the caller guarantees room for `pixels` values.
            unsafe { std::slice::from_raw_parts_mut(samples, n) }.copy_from_slice(&map);
        }
        Ok(())
    })
}

/// The two-way temporal filter (TEMPORAL-SMOOTH) for offline sequences: the
/// frames of a denoiser with [`MCD_FLAG_TEMPORAL_LP`], kept one by one, are
/// filtered again in reverse order at the end and the two directions
/// combined per pixel, so every frame's reconstruction sees the frames
/// before and after it.
pub struct McdSmoother {
    smoother: core::Smoother,
}

/// Receives one frame of [`mcd_smoother_finish`]: `user` as given, the
/// frame's index in the sequence (0 for the first kept), its
/// reconstruction as `pixels` RGB triples (interleaved f32, row-major,
/// valid during the call only). Returns 0 to go on; anything else stops
/// the finish with `MCD_STATUS_INVALID_ARGUMENT`.
pub type McdFrameFn = Option<
    unsafe extern "C" fn(user: *mut c_void, frame: u64, color: *const f32, pixels: u64) -> i32,
>;

/// Creates the two-way filter for the frames of `denoiser`, which must have
/// [`MCD_FLAG_TEMPORAL_LP`] and not [`MCD_FLAG_ADAPTIVE_PASS`]. The kept
/// frames go to an unnamed temporary file in `$TMPDIR` (72 bytes per pixel
/// and frame), not to the host's memory.
///
/// # Safety
/// `ctx` is the live context of `denoiser`, a live denoiser; `out` is
/// valid for a write.
#[no_mangle]
pub unsafe extern "C" fn mcd_smoother_create(
    ctx: *const McdContext,
    denoiser: *const McdDenoiser,
    out: *mut *mut McdSmoother,
) -> McdStatus {
    guard(|| {
        // SAFETY: forwarded to the caller.
        let (ctx, d) = unsafe { (non_null(ctx, "ctx")?, non_null(denoiser, "denoiser")?) };
        let out = out_ptr(out)?;
        let smoother = core::Smoother::new(&ctx.ctx, &d.denoiser)?;
        let handle = Box::into_raw(Box::new(McdSmoother { smoother }));
        // SAFETY: non-null (checked first) and valid for writes by the
        // caller's contract.
        unsafe { out.write(handle) };
        Ok(())
    })
}

/// Keeps the frame `denoiser` (the smoother's) just reconstructed: call it
/// after the submission of each recording of the sequence completed, every
/// frame in order, the first right after [`mcd_denoiser_reset`] (or the
/// denoiser's first recording). A frame skipped, or a reset within the
/// sequence, is `MCD_STATUS_INVALID_ARGUMENT` and keeps nothing.
///
/// # Safety
/// `smoother` and `denoiser` are live; no recording of `denoiser` is
/// running on the GPU.
#[no_mangle]
pub unsafe extern "C" fn mcd_smoother_keep(
    smoother: *mut McdSmoother,
    denoiser: *const McdDenoiser,
) -> McdStatus {
    guard(|| {
        // SAFETY: forwarded to the caller.
        let (s, d) = unsafe {
            (
                smoother
                    .as_mut()
                    .ok_or_else(|| invalid("smoother is NULL"))?,
                non_null(denoiser, "denoiser")?,
            )
        };
        let color = d.denoiser.read()?.color;
        s.smoother.keep(&d.denoiser, &color)?;
        Ok(())
    })
}

/// Ends the sequence: hands every kept frame's two-way reconstruction to
/// `each`, last frame first, one at a time. The kept frames are dropped
/// (also on an error or when `each` stops); the next keep starts a new
/// sequence, after [`mcd_denoiser_reset`]. `*frames`, if `frames` is not
/// NULL, gets the number of frames handed over.
///
/// # Safety
/// `smoother` is live; `each` is safe to call with `user`; `frames` is NULL
/// or valid for a write.
#[no_mangle]
pub unsafe extern "C" fn mcd_smoother_finish(
    smoother: *mut McdSmoother,
    each: McdFrameFn,
    user: *mut c_void,
    frames: *mut u64,
) -> McdStatus {
    guard(|| {
        // SAFETY: forwarded to the caller.
        let s = unsafe { smoother.as_mut() }.ok_or_else(|| invalid("smoother is NULL"))?;
        let Some(each) = each else {
            return Err(invalid("each is NULL"));
        };
        let mut handed = 0u64;
        let mut stopped: Option<(u64, i32)> = None;
        let done = s.smoother.finish_each(|t, color, _| {
            let n = color.width * color.height;
            let mut rgb = vec![0f32; 3 * n];
            interleave_rgb(&color, &mut rgb);
            // SAFETY: the caller guarantees `each` may be called with `user`;
            // `rgb` holds `n` triples for the call's duration.
            let r = unsafe { each(user, t as u64, rgb.as_ptr(), n as u64) };
            handed += 1;
            if r != 0 {
                stopped = Some((t as u64, r));
                return Err(Error::InvalidArgument("stopped".into()));
            }
            Ok(())
        });
        if !frames.is_null() {
            // SAFETY: non-null and valid for writes by the caller's contract.
            unsafe { frames.write(handed) };
        }
        match (done, stopped) {
            (_, Some((t, r))) => Err(invalid(format!(
                "the callback returned {r} at frame {t}: the sequence ended there"
            ))),
            (Err(e), None) => Err(e.into()),
            (Ok(()), None) => Ok(()),
        }
    })
}

/// Destroys a smoother (NULL is ignored), with its kept frames.
///
/// # Safety
/// `smoother` is NULL or a live smoother from [`mcd_smoother_create`].
#[no_mangle]
pub unsafe extern "C" fn mcd_smoother_destroy(smoother: *mut McdSmoother) {
    if !smoother.is_null() {
        let _ = catch_unwind(AssertUnwindSafe(|| {
            // SAFETY: the caller passes a live handle from mcd_smoother_create.
            drop(unsafe { Box::from_raw(smoother) })
        }));
    }
}
