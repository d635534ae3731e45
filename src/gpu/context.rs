//! Instance, physical-device choice, logical device, queue and allocator.

use std::collections::{HashMap, HashSet};
use std::ffi::{c_void, CStr, CString};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use ash::vk;
use gpu_allocator::vulkan::{Allocation, Allocator, AllocatorCreateDesc};

use crate::error::{Error, Result};
use crate::fault::{self, Call, Object};

const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";

/// Whether to enable `VK_LAYER_KHRONOS_validation`.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Default)]
pub enum Validation {
    /// Never (the CLI default).
    #[default]
    Off,
    /// When the layer is installed (what the tests use).
    IfInstalled,
    /// Always; creating the context fails if the layer is missing.
    Required,
}

/// How to create a [`GpuContext`].
#[derive(Clone, Debug, Default)]
pub struct ContextOptions {
    /// Device by index (as `mcdenoise info` lists them) or by a case-insensitive
    /// substring of its name. `None`: the `MCDENOISE_DEVICE` environment
    /// variable, else the best device (discrete > integrated > virtual > CPU).
    pub device: Option<String>,
    /// Whether to enable the Khronos validation layer (default [`Validation::Off`]).
    pub validation: Validation,
    /// Leave `shaderFloat64` and `shaderInt64` disabled even where the
    /// device has them: the context then runs what a GPU without 64-bit
    /// types runs (for testing portability on any machine).
    pub no_64bit: bool,
}

/// What `mcdenoise info` prints about a device.
#[derive(Clone, Debug)]
pub struct DeviceInfo {
    /// Index in the loader's enumeration order (one of the forms
    /// [`ContextOptions::device`] and `MCDENOISE_DEVICE` accept).
    pub index: usize,
    /// Device name as the driver reports it.
    pub name: String,
    /// Discrete, integrated, virtual GPU or CPU (software, e.g. lavapipe); the
    /// default choice prefers them in that order.
    pub kind: vk::PhysicalDeviceType,
    /// Vulkan API version the device supports, `(major, minor, patch)`.
    pub api_version: (u32, u32, u32),
    /// Driver information string (`VkPhysicalDeviceDriverProperties`; may be empty).
    pub driver: String,
    /// `maxStorageBufferRange` in bytes: the largest binding; one f32 plane
    /// holds at most a quarter of it in pixels.
    pub max_storage_buffer_range: u32,
    /// `maxPerStageDescriptorStorageBuffers`: the most buffers one kernel may bind.
    pub max_per_stage_storage_buffers: u32,
    /// `maxPushConstantsSize` in bytes.
    pub max_push_constants_size: u32,
    /// `maxComputeSharedMemorySize` in bytes.
    pub max_shared_memory: u32,
    /// `minStorageBufferOffsetAlignment` in bytes: every binding's offset is a
    /// multiple of it.
    pub min_storage_buffer_offset_alignment: u64,
    /// Whether the device supports `shaderFloat64` (the `_f64` kernels).
    pub shader_float64: bool,
    /// Whether the device supports `shaderInt64` (no kernel needs it).
    pub shader_int64: bool,
    /// Default subgroup size in invocations (informational).
    pub subgroup_size: u32,
    /// Nanoseconds per timestamp tick (`timestampPeriod`); 0 disables GPU timing.
    pub timestamp_period_ns: f32,
    /// Whether some queue family supports compute; devices without one are never chosen.
    pub has_compute_queue: bool,
    /// Size in bytes of the largest `DEVICE_LOCAL` memory heap (on lavapipe,
    /// host memory): what the default memory cap of a tiled run is taken
    /// from (`methods::tiles`).
    pub device_local_heap: u64,
}

/// Messages of the validation layer: every error is counted and kept.
#[derive(Debug, Default)]
pub struct ValidationLog {
    /// Validation errors reported so far.
    pub errors: AtomicUsize,
    /// Validation warnings reported so far.
    pub warnings: AtomicUsize,
    /// The text of every error and warning, in arrival order.
    pub messages: Mutex<Vec<String>>,
}

unsafe extern "system" fn debug_callback(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _types: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user: *mut c_void,
) -> vk::Bool32 {
    // SAFETY: `user` is the `ValidationLog` kept alive by the context that
    // registered this callback; `data` is valid for the call (Vulkan spec).
    let log = unsafe { &*(user as *const ValidationLog) };
    let msg = unsafe {
        data.as_ref()
            .and_then(|d| d.message_as_c_str())
            .map(|m| m.to_string_lossy().into_owned())
            .unwrap_or_default()
    };
    if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR) {
        log.errors.fetch_add(1, Ordering::SeqCst);
        log::error!("vulkan validation: {msg}");
        log.messages.lock().unwrap().push(msg);
    } else if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::WARNING) {
        log.warnings.fetch_add(1, Ordering::SeqCst);
        log::warn!("vulkan validation: {msg}");
        log.messages.lock().unwrap().push(msg);
    }
    vk::FALSE
}

/// A device that mcdenoise runs on, either created by mcdenoise or imported
/// from a host renderer ([`GpuContext::from_raw`]).
///
/// Faults: a device loss (`ERROR_DEVICE_LOST` from a submit or a fence
/// wait) or a fence wait longer than [`fence_timeout`](Self::fence_timeout)
/// marks the context lost ([`is_lost`](Self::is_lost)); from then on every
/// call that would touch the device (a batch, a buffer, a pipeline, a
/// dispatch) returns the same [`Error::DeviceLost`] or [`Error::Timeout`].
/// An out-of-memory error does not: the context stays usable.
///
/// Teardown order (on drop): wait for the device to be idle (only a device
/// this context created: an imported device is the host's, and every
/// submission mcdenoise made itself has already been waited for), destroy
/// the pipelines, the recycled descriptor pools and any buffer whose
/// destruction was deferred, free the allocator's memory blocks, then — only
/// if this context created them — the device, the debug messenger and the
/// instance.
///
/// Buffers in use by recorded work outlive their [`GpuBuffer`](super::GpuBuffer)
/// handle: every [`Batch`](super::Batch) retains the buffers it binds until
/// its work has completed (execute mode) or its [`Recorded`](super::Recorded)
/// is dropped (record mode); a buffer dropped earlier is destroyed then.
pub struct GpuContext {
    pub(crate) entry: ash::Entry,
    pub(crate) instance: ash::Instance,
    pub(crate) physical: vk::PhysicalDevice,
    pub(crate) device: ash::Device,
    pub(crate) queue: vk::Queue,
    pub(crate) queue_family: u32,
    pub(crate) allocator: Mutex<Option<Allocator>>,
    pub(crate) info: DeviceInfo,
    pub(crate) f64_enabled: bool,
    pub(crate) int64_enabled: bool,
    owns_device: bool,
    debug: Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
    validation_log: Arc<ValidationLog>,
    pub(crate) pipelines: Mutex<super::pipeline::PipelineCache>,
    /// The on-disk `VkPipelineCache` pipelines are built through, if any.
    disk_cache: Mutex<Option<super::pipeline::DiskCache>>,
    /// Ids of the live [`super::GpuBuffer`]s of this context: a
    /// [`super::BufferSlice`] of any other is refused at use.
    pub(crate) live: Mutex<HashSet<u64>>,
    /// Vulkan requires external synchronisation of a queue: every submit
    /// from this context holds this lock.
    pub(crate) queue_lock: Mutex<()>,
    /// Buffers bound by work not known to be complete, and buffers dropped
    /// while bound (destroyed when their count reaches 0).
    in_flight: Mutex<InFlight>,
    /// Descriptor pools of finished batches, reset and ready for reuse.
    free_desc_pools: Mutex<Vec<vk::DescriptorPool>>,
    /// Timestamp query pools of finished batches (queries are reset in the
    /// command buffer before each use).
    free_query_pools: Mutex<Vec<vk::QueryPool>>,
    /// Queue submissions made by this context (the embedding tests check
    /// that recording into a host's command buffer submits nothing).
    submits: AtomicU64,
    /// The host address and size of every live [`super::GpuBuffer`] whose
    /// memory is mapped (all of them on a device whose memory is host
    /// memory, as lavapipe's): [`super::buffer::read_slice`] reads those
    /// directly instead of through a staging copy.
    pub(crate) mapped: Mutex<HashMap<vk::Buffer, (usize, u64)>>,
    /// Bytes of the live [`super::GpuBuffer`]s made on this context, and
    /// the most there have been at once.
    pub(crate) allocated: AtomicU64,
    pub(crate) peak_allocated: AtomicU64,
    /// Set once the device is lost or hung (the fast check of `lost`).
    lost_flag: AtomicBool,
    /// Why the context cannot continue: the first loss or timeout.
    lost: Mutex<Option<Lost>>,
    /// How long a fence wait may take, in nanoseconds.
    fence_timeout_ns: AtomicU64,
    /// The pipelines a completed submit has run: a submit with another
    /// gets [`FIRST_DISPATCH_ALLOWANCE`] more to wait.
    ran: Mutex<HashSet<vk::Pipeline>>,
}

/// The default of [`GpuContext::fence_timeout`]: 60 s for one submit. A
/// submit holds about a second of estimated work on lavapipe (see
/// [`DEFAULT_FLOPS_PER_SUBMIT`](super::batch::DEFAULT_FLOPS_PER_SUBMIT)), a
/// few milliseconds on a discrete GPU.
pub const DEFAULT_FENCE_TIMEOUT: Duration = Duration::from_secs(60);

/// What a submit may take beyond [`GpuContext::fence_timeout`] for each
/// pipeline it is the first on this context to run, up to
/// [`FIRST_DISPATCH_ALLOWANCE_MAX`]: llvmpipe compiles a compute pipeline at
/// its first dispatch, inside the submit, and with a cold shader cache on a
/// busy machine one compile can take about a minute.
pub const FIRST_DISPATCH_ALLOWANCE: Duration = Duration::from_secs(60);

/// The most [`FIRST_DISPATCH_ALLOWANCE`] adds to one submit.
pub const FIRST_DISPATCH_ALLOWANCE_MAX: Duration = Duration::from_secs(600);

/// Why a context cannot continue.
#[derive(Clone, Debug)]
pub(crate) enum Lost {
    /// `ERROR_DEVICE_LOST` while running the described work.
    Device(String),
    /// A fence wait passed the timeout (seconds) while running the described work.
    Timeout(String, f64),
}

impl Lost {
    fn error(&self) -> Error {
        match self {
            Lost::Device(during) => Error::DeviceLost {
                during: during.clone(),
            },
            Lost::Timeout(during, seconds) => Error::Timeout {
                during: during.clone(),
                seconds: *seconds,
            },
        }
    }
}

/// What [`GpuContext::new`] has created so far: destroyed on drop, in
/// reverse order, unless moved into the context. A failure after the
/// instance (the messenger, the device, the allocator) leaks nothing.
struct Partial {
    instance: Option<ash::Instance>,
    debug: Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
    device: Option<ash::Device>,
}

impl Drop for Partial {
    fn drop(&mut self) {
        // SAFETY: nothing else was created from these objects (the allocator
        // is made last, and a failed one holds no memory).
        unsafe {
            if let Some(d) = self.device.take() {
                d.destroy_device(None);
                fault::destroyed(Object::Device);
            }
            if let Some((du, m)) = self.debug.take() {
                du.destroy_debug_utils_messenger(m, None);
                fault::destroyed(Object::DebugMessenger);
            }
            if let Some(i) = self.instance.take() {
                i.destroy_instance(None);
                fault::destroyed(Object::Instance);
            }
        }
    }
}

#[derive(Default)]
struct InFlight {
    refs: HashMap<vk::Buffer, u32>,
    deferred: Vec<(vk::Buffer, Option<Allocation>)>,
}

fn load_entry() -> Result<ash::Entry> {
    // SAFETY: loading the system Vulkan loader; it is not unloaded while the
    // returned Entry (kept in the context) lives.
    unsafe { ash::Entry::load() }.map_err(|e| Error::NoLoader(e.to_string()))
}

fn make_instance(entry: &ash::Entry, layers: &[*const i8], debug: bool) -> Result<ash::Instance> {
    let app_name = c"mcdenoise";
    let app = vk::ApplicationInfo::default()
        .application_name(app_name)
        .engine_name(app_name)
        .api_version(vk::API_VERSION_1_1);
    let mut exts = Vec::new();
    if debug {
        exts.push(ash::ext::debug_utils::NAME.as_ptr());
    }
    let info = vk::InstanceCreateInfo::default()
        .application_info(&app)
        .enabled_layer_names(layers)
        .enabled_extension_names(&exts);
    // SAFETY: all pointers in `info` outlive the call.
    let instance = fault::vk(Call::CreateInstance)
        .and_then(|()| unsafe { entry.create_instance(&info, None) })
        .map_err(|e| match e {
            vk::Result::ERROR_INCOMPATIBLE_DRIVER => {
                Error::NoDevice("no Vulkan driver (ICD) is installed".into())
            }
            e => Error::vk("vkCreateInstance")(e),
        })?;
    fault::created(Object::Instance);
    Ok(instance)
}

fn layer_available(entry: &ash::Entry, name: &CStr) -> bool {
    // SAFETY: plain enumeration.
    unsafe { entry.enumerate_instance_layer_properties() }
        .map(|ls| {
            ls.iter()
                .any(|l| l.layer_name_as_c_str().is_ok_and(|n| n == name))
        })
        .unwrap_or(false)
}

fn describe(instance: &ash::Instance, pd: vk::PhysicalDevice, index: usize) -> DeviceInfo {
    // SAFETY: `pd` was enumerated from `instance`.
    unsafe {
        let mut subgroup = vk::PhysicalDeviceSubgroupProperties::default();
        let mut driver = vk::PhysicalDeviceDriverProperties::default();
        let mut props2 = vk::PhysicalDeviceProperties2::default()
            .push_next(&mut subgroup)
            .push_next(&mut driver);
        instance.get_physical_device_properties2(pd, &mut props2);
        let p = props2.properties;
        let features = instance.get_physical_device_features(pd);
        let queues = instance.get_physical_device_queue_family_properties(pd);
        let l = p.limits;
        DeviceInfo {
            index,
            name: p
                .device_name_as_c_str()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default(),
            kind: p.device_type,
            api_version: (
                vk::api_version_major(p.api_version),
                vk::api_version_minor(p.api_version),
                vk::api_version_patch(p.api_version),
            ),
            driver: driver
                .driver_info_as_c_str()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default(),
            max_storage_buffer_range: l.max_storage_buffer_range,
            max_per_stage_storage_buffers: l.max_per_stage_descriptor_storage_buffers,
            max_push_constants_size: l.max_push_constants_size,
            max_shared_memory: l.max_compute_shared_memory_size,
            min_storage_buffer_offset_alignment: l.min_storage_buffer_offset_alignment,
            shader_float64: features.shader_float64 == vk::TRUE,
            shader_int64: features.shader_int64 == vk::TRUE,
            subgroup_size: subgroup.subgroup_size,
            timestamp_period_ns: l.timestamp_period,
            has_compute_queue: queues
                .iter()
                .any(|q| q.queue_flags.contains(vk::QueueFlags::COMPUTE)),
            device_local_heap: {
                let mem = instance.get_physical_device_memory_properties(pd);
                mem.memory_heaps[..mem.memory_heap_count as usize]
                    .iter()
                    .filter(|h| h.flags.contains(vk::MemoryHeapFlags::DEVICE_LOCAL))
                    .map(|h| h.size)
                    .max()
                    .unwrap_or(0)
            },
        }
    }
}

fn rank(kind: vk::PhysicalDeviceType) -> u32 {
    match kind {
        vk::PhysicalDeviceType::DISCRETE_GPU => 0,
        vk::PhysicalDeviceType::INTEGRATED_GPU => 1,
        vk::PhysicalDeviceType::VIRTUAL_GPU => 2,
        vk::PhysicalDeviceType::CPU => 3,
        _ => 4,
    }
}

/// Picks a device from `infos` by the rule of [`ContextOptions::device`].
pub fn choose_device(infos: &[DeviceInfo], wanted: Option<&str>) -> Result<usize> {
    let usable: Vec<&DeviceInfo> = infos.iter().filter(|d| d.has_compute_queue).collect();
    if usable.is_empty() {
        return Err(Error::NoDevice(if infos.is_empty() {
            "the Vulkan loader found no device".into()
        } else {
            "no device has a compute queue".into()
        }));
    }
    let env = std::env::var("MCDENOISE_DEVICE").ok();
    match wanted.map(str::to_owned).or(env).filter(|s| !s.is_empty()) {
        Some(w) => {
            if let Ok(i) = w.parse::<usize>() {
                return usable
                    .iter()
                    .find(|d| d.index == i)
                    .map(|d| d.index)
                    .ok_or_else(|| Error::NoDevice(format!("no device with index {i}")));
            }
            let lw = w.to_lowercase();
            usable
                .iter()
                .find(|d| d.name.to_lowercase().contains(&lw))
                .map(|d| d.index)
                .ok_or_else(|| {
                    let names: Vec<_> = usable.iter().map(|d| d.name.as_str()).collect();
                    Error::NoDevice(format!(
                        "no device matches {w:?} (have: {})",
                        names.join(", ")
                    ))
                })
        }
        None => Ok(usable
            .iter()
            .min_by_key(|d| (rank(d.kind), d.index))
            .unwrap()
            .index),
    }
}

/// Lists the Vulkan devices (for `mcdenoise info`) without creating a device.
pub fn enumerate_devices() -> Result<Vec<DeviceInfo>> {
    let entry = load_entry()?;
    let instance = make_instance(&entry, &[], false)?;
    // SAFETY: the instance is destroyed below and not used after.
    let result = unsafe { instance.enumerate_physical_devices() }
        .map_err(Error::vk("vkEnumeratePhysicalDevices"))
        .map(|pds| {
            pds.iter()
                .enumerate()
                .map(|(i, &pd)| describe(&instance, pd, i))
                .collect()
        });
    unsafe { instance.destroy_instance(None) };
    fault::destroyed(Object::Instance);
    result
}

/// A host renderer's Vulkan objects, handed to [`GpuContext::from_raw`].
///
/// mcdenoise's own device enables `robustBufferAccess`, so that a wrongly
/// sized binding given to a public kernel `record` cannot touch memory
/// outside it; a host that wants the same guarantee for its device enables
/// that feature itself (every Vulkan device supports it).
#[derive(Clone)]
pub struct ImportedDevice {
    /// The Vulkan loader the host loaded `instance` with.
    pub entry: ash::Entry,
    /// The host's instance; it outlives the context and is never destroyed by it.
    pub instance: ash::Instance,
    /// The physical device `device` was created from.
    pub physical_device: vk::PhysicalDevice,
    /// The host's logical device; mcdenoise creates and destroys only its own
    /// objects on it.
    pub device: ash::Device,
    /// A queue with compute capability.
    pub queue: vk::Queue,
    /// Queue family of `queue`; it must support compute.
    pub queue_family_index: u32,
    /// Whether the host enabled `shaderFloat64` on `device` (f64 kernels are
    /// only used then).
    pub shader_float64_enabled: bool,
    /// Whether the host enabled `shaderInt64` on `device` (no kernel needs
    /// it today: the sample map's 64-bit sums are pairs of 32-bit words).
    pub shader_int64_enabled: bool,
}

/// The context's memory allocator on `device`.
fn make_allocator(
    instance: &ash::Instance,
    device: &ash::Device,
    physical: vk::PhysicalDevice,
) -> Result<Allocator> {
    let err = |source| Error::Allocation {
        name: "allocator".into(),
        bytes: 0,
        source,
    };
    if let Err(r) = fault::vk(Call::CreateAllocator) {
        return Err(err(allocation_error(r)));
    }
    let allocator = Allocator::new(&AllocatorCreateDesc {
        instance: instance.clone(),
        device: device.clone(),
        physical_device: physical,
        debug_settings: gpu_allocator::AllocatorDebugSettings {
            log_leaks_on_shutdown: cfg!(debug_assertions),
            ..Default::default()
        },
        buffer_device_address: false,
        allocation_sizes: Default::default(),
    })
    .map_err(err)?;
    fault::created(Object::Allocator);
    Ok(allocator)
}

/// The allocator's error for an injected Vulkan result (out-of-memory codes
/// become its out-of-memory error, as a real exhaustion does).
pub(crate) fn allocation_error(r: vk::Result) -> gpu_allocator::AllocationError {
    match r {
        vk::Result::ERROR_OUT_OF_DEVICE_MEMORY | vk::Result::ERROR_OUT_OF_HOST_MEMORY => {
            gpu_allocator::AllocationError::OutOfMemory
        }
        r => gpu_allocator::AllocationError::Internal(format!("{r:?}")),
    }
}

impl GpuContext {
    /// Creates an instance and a device of its own.
    pub fn new(options: &ContextOptions) -> Result<GpuContext> {
        let entry = load_entry()?;
        let want_layer = match options.validation {
            Validation::Off => false,
            Validation::IfInstalled => layer_available(&entry, VALIDATION_LAYER),
            Validation::Required => {
                if !layer_available(&entry, VALIDATION_LAYER) {
                    return Err(Error::NoDevice(
                        "validation requested but VK_LAYER_KHRONOS_validation is not installed \
                         (apt-get install vulkan-validationlayers)"
                            .into(),
                    ));
                }
                true
            }
        };
        let layers: Vec<*const i8> = if want_layer {
            vec![VALIDATION_LAYER.as_ptr()]
        } else {
            vec![]
        };
        // Declared before `partial`, so that it outlives the messenger that
        // points at it when `partial` destroys what it holds.
        let validation_log = Arc::new(ValidationLog::default());
        let mut partial = Partial {
            instance: Some(make_instance(&entry, &layers, want_layer)?),
            debug: None,
            device: None,
        };
        let instance = partial.instance.clone().expect("just created");
        if want_layer {
            let du = ash::ext::debug_utils::Instance::new(&entry, &instance);
            let info = vk::DebugUtilsMessengerCreateInfoEXT::default()
                .message_severity(
                    vk::DebugUtilsMessageSeverityFlagsEXT::ERROR
                        | vk::DebugUtilsMessageSeverityFlagsEXT::WARNING,
                )
                .message_type(
                    vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                        | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                        | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
                )
                .pfn_user_callback(Some(debug_callback))
                .user_data(Arc::as_ptr(&validation_log) as *mut c_void);
            // SAFETY: the log outlives the messenger (both owned by the context,
            // messenger destroyed first).
            let m = fault::vk(Call::CreateDebugMessenger)
                .and_then(|()| unsafe { du.create_debug_utils_messenger(&info, None) })
                .map_err(Error::vk("vkCreateDebugUtilsMessengerEXT"))?;
            fault::created(Object::DebugMessenger);
            partial.debug = Some((du, m));
        }

        // SAFETY: plain enumeration on a live instance.
        let pds = unsafe { instance.enumerate_physical_devices() }
            .map_err(Error::vk("vkEnumeratePhysicalDevices"))?;
        let infos: Vec<DeviceInfo> = pds
            .iter()
            .enumerate()
            .map(|(i, &pd)| describe(&instance, pd, i))
            .collect();
        let chosen = choose_device(&infos, options.device.as_deref())?;
        let physical = pds[chosen];
        let info = infos[chosen].clone();
        // SAFETY: `physical` comes from this instance.
        let families = unsafe { instance.get_physical_device_queue_family_properties(physical) };
        let queue_family = families
            .iter()
            .position(|q| q.queue_flags.contains(vk::QueueFlags::COMPUTE))
            .unwrap() as u32;
        let priorities = [1.0f32];
        let queue_info = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(queue_family)
            .queue_priorities(&priorities)];
        let f64_enabled = info.shader_float64 && !options.no_64bit;
        let int64_enabled = info.shader_int64 && !options.no_64bit;
        // robustBufferAccess (every Vulkan device has it): a kernel that
        // indexes past a binding reads zeros or in-range values and cannot
        // write outside it, so a wrongly sized binding handed to a safe
        // `record` is a wrong image, not memory corruption.
        let features = vk::PhysicalDeviceFeatures::default()
            .robust_buffer_access(true)
            .shader_float64(f64_enabled)
            .shader_int64(int64_enabled);
        let dinfo = vk::DeviceCreateInfo::default()
            .queue_create_infos(&queue_info)
            .enabled_features(&features);
        // SAFETY: valid create info; the device is destroyed by `partial` or
        // by the context.
        let device = fault::vk(Call::CreateDevice)
            .and_then(|()| unsafe { instance.create_device(physical, &dinfo, None) })
            .map_err(Error::vk("vkCreateDevice"))?;
        fault::created(Object::Device);
        partial.device = Some(device.clone());
        // SAFETY: family/index exist (created above).
        let queue = unsafe { device.get_device_queue(queue_family, 0) };
        let allocator = make_allocator(&instance, &device, physical)?;

        // Everything exists: the context owns it from here on.
        partial.device = None;
        partial.instance = None;
        let debug = partial.debug.take();
        Ok(Self::assemble(
            entry,
            instance,
            physical,
            device,
            queue,
            queue_family,
            allocator,
            info,
            f64_enabled,
            int64_enabled,
            true,
            debug,
            validation_log,
        ))
    }

    /// Wraps a host renderer's existing instance, device and queue: the
    /// embedding path. mcdenoise creates its own allocator, command pool,
    /// pipelines and buffers on `device` and destroys only those.
    ///
    /// # Safety
    /// The caller guarantees that:
    /// - `device` was created from `physical_device` of `instance`, and the
    ///   queue `queue` belongs to `queue_family_index`, which supports compute;
    /// - `shader_float64_enabled` / `shader_int64_enabled` are true only if
    ///   those features were enabled;
    /// - the instance and device outlive this context (they are not destroyed
    ///   by it), and the context is dropped before them;
    /// - the queue is not used by another thread while mcdenoise submits to it
    ///   (`execute` paths; `record` paths only record into the host's command
    ///   buffers and never submit).
    pub unsafe fn from_raw(host: ImportedDevice) -> Result<GpuContext> {
        let info = describe(&host.instance, host.physical_device, 0);
        let allocator = make_allocator(&host.instance, &host.device, host.physical_device)?;
        Ok(Self::assemble(
            host.entry,
            host.instance,
            host.physical_device,
            host.device,
            host.queue,
            host.queue_family_index,
            allocator,
            info,
            host.shader_float64_enabled,
            host.shader_int64_enabled,
            false,
            None,
            Arc::new(ValidationLog::default()),
        ))
    }

    fn assemble(
        entry: ash::Entry,
        instance: ash::Instance,
        physical: vk::PhysicalDevice,
        device: ash::Device,
        queue: vk::Queue,
        queue_family: u32,
        allocator: Allocator,
        info: DeviceInfo,
        f64_enabled: bool,
        int64_enabled: bool,
        owns_device: bool,
        debug: Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
        validation_log: Arc<ValidationLog>,
    ) -> GpuContext {
        GpuContext {
            entry,
            instance,
            physical,
            device,
            queue,
            queue_family,
            allocator: Mutex::new(Some(allocator)),
            info,
            f64_enabled,
            int64_enabled,
            owns_device,
            debug,
            validation_log,
            pipelines: Mutex::new(Default::default()),
            disk_cache: Mutex::new(None),
            live: Mutex::new(Default::default()),
            queue_lock: Mutex::new(()),
            in_flight: Mutex::new(InFlight::default()),
            free_desc_pools: Mutex::new(Vec::new()),
            free_query_pools: Mutex::new(Vec::new()),
            mapped: Mutex::new(HashMap::new()),
            submits: AtomicU64::new(0),
            allocated: AtomicU64::new(0),
            peak_allocated: AtomicU64::new(0),
            lost_flag: AtomicBool::new(false),
            lost: Mutex::new(None),
            fence_timeout_ns: AtomicU64::new(DEFAULT_FENCE_TIMEOUT.as_nanos() as u64),
            ran: Mutex::new(HashSet::new()),
        }
    }

    /// The chosen device's properties and limits.
    pub fn info(&self) -> &DeviceInfo {
        &self.info
    }

    /// Whether the `_f64` kernel variants can run here.
    pub fn supports_f64(&self) -> bool {
        self.f64_enabled
    }

    /// Whether kernels with 64-bit integers (the sample map) can run here.
    pub fn supports_int64(&self) -> bool {
        self.int64_enabled
    }

    /// Number of validation-layer errors seen so far (0 without the layer).
    pub fn validation_errors(&self) -> usize {
        self.validation_log.errors.load(Ordering::SeqCst)
    }

    /// Whether the validation layer is active on this context.
    pub fn validation_enabled(&self) -> bool {
        self.debug.is_some()
    }

    /// All validation messages so far (errors and warnings).
    pub fn validation_messages(&self) -> Vec<String> {
        self.validation_log.messages.lock().unwrap().clone()
    }

    /// The raw device, for hosts that record mcdenoise's work.
    pub fn raw_device(&self) -> &ash::Device {
        &self.device
    }

    /// The physical device this context runs on.
    pub fn raw_physical_device(&self) -> vk::PhysicalDevice {
        self.physical
    }

    /// The instance (mcdenoise's own, or the host's for an imported device).
    pub fn raw_instance(&self) -> &ash::Instance {
        &self.instance
    }

    /// The Vulkan loader entry points.
    pub fn raw_entry(&self) -> &ash::Entry {
        &self.entry
    }

    /// Queue family index of the queue mcdenoise submits to and of the command
    /// pools it creates.
    pub fn queue_family(&self) -> u32 {
        self.queue_family
    }

    /// Number of queue submissions this context has made so far.
    pub fn submit_count(&self) -> u64 {
        self.submits.load(Ordering::SeqCst)
    }

    pub(crate) fn count_submit(&self) {
        self.submits.fetch_add(1, Ordering::SeqCst);
    }

    /// Bytes of device memory held by the live buffers made on this context
    /// (requested sizes; the allocator's block rounding not included).
    pub fn allocated_bytes(&self) -> u64 {
        self.allocated.load(Ordering::SeqCst)
    }

    /// The most [`allocated_bytes`](Self::allocated_bytes) has been since
    /// the context was made or since [`reset_peak`](Self::reset_peak).
    pub fn peak_allocated_bytes(&self) -> u64 {
        self.peak_allocated.load(Ordering::SeqCst)
    }

    /// Restarts [`peak_allocated_bytes`](Self::peak_allocated_bytes) from the
    /// bytes allocated now.
    pub fn reset_peak(&self) {
        self.peak_allocated
            .store(self.allocated_bytes(), Ordering::SeqCst);
    }

    pub(crate) fn count_allocation(&self, bytes: u64) {
        let now = self.allocated.fetch_add(bytes, Ordering::SeqCst) + bytes;
        self.peak_allocated.fetch_max(now, Ordering::SeqCst);
    }

    pub(crate) fn count_free(&self, bytes: u64) {
        self.allocated.fetch_sub(bytes, Ordering::SeqCst);
    }

    /// Marks `buffers` as bound by work in flight.
    pub(crate) fn retain(&self, buffers: &[vk::Buffer]) {
        let mut f = self.in_flight.lock().unwrap();
        for b in buffers {
            *f.refs.entry(*b).or_insert(0) += 1;
        }
    }

    /// The work binding `buffers` has completed: destroys those of them that
    /// were dropped meanwhile and are no longer bound anywhere.
    pub(crate) fn release(&self, buffers: &[vk::Buffer]) {
        let mut dead = Vec::new();
        {
            let mut f = self.in_flight.lock().unwrap();
            for b in buffers {
                if let Some(n) = f.refs.get_mut(b) {
                    *n -= 1;
                    if *n == 0 {
                        f.refs.remove(b);
                        if let Some(i) = f.deferred.iter().position(|(d, _)| d == b) {
                            dead.push(f.deferred.swap_remove(i));
                        }
                    }
                }
            }
        }
        for (b, a) in dead {
            self.destroy_buffer(b, a);
        }
    }

    /// Destroys `buffer` now, or once no recorded work binds it.
    pub(crate) fn retire_buffer(&self, buffer: vk::Buffer, allocation: Option<Allocation>) {
        {
            let mut f = self.in_flight.lock().unwrap();
            if f.refs.contains_key(&buffer) {
                f.deferred.push((buffer, allocation));
                return;
            }
        }
        self.destroy_buffer(buffer, allocation);
    }

    fn destroy_buffer(&self, buffer: vk::Buffer, allocation: Option<Allocation>) {
        // SAFETY: no recorded work that may still execute binds the buffer
        // (its in-flight count is 0), and it belongs to this device.
        unsafe { self.device.destroy_buffer(buffer, None) };
        fault::destroyed(Object::Buffer);
        if let Some(a) = allocation {
            if let Some(alloc) = self.allocator.lock().unwrap().as_mut() {
                let _ = alloc.free(a);
            }
            fault::destroyed(Object::Allocation);
        }
    }

    /// A descriptor pool from the free list, if any.
    pub(crate) fn take_desc_pool(&self) -> Option<vk::DescriptorPool> {
        self.free_desc_pools.lock().unwrap().pop()
    }

    /// Resets `pools` (their sets are no longer used by any pending work) and
    /// keeps them for the next batch.
    pub(crate) fn recycle_desc_pools(&self, pools: Vec<vk::DescriptorPool>) {
        for p in &pools {
            // SAFETY: the caller guarantees no pending work uses the sets.
            let _ = unsafe {
                self.device
                    .reset_descriptor_pool(*p, vk::DescriptorPoolResetFlags::empty())
            };
        }
        self.free_desc_pools.lock().unwrap().extend(pools);
    }

    /// A timestamp query pool from the free list, if any.
    pub(crate) fn take_query_pool(&self) -> Option<vk::QueryPool> {
        self.free_query_pools.lock().unwrap().pop()
    }

    /// Keeps `pools` (no pending work uses them) for the next batch.
    pub(crate) fn recycle_query_pools(&self, pools: Vec<vk::QueryPool>) {
        self.free_query_pools.lock().unwrap().extend(pools);
    }

    /// Waits until the device has finished all work: only on mcdenoise's
    /// own device. On a host's device ([`GpuContext::from_raw`]) it is an
    /// [`Error::InvalidArgument`]: `vkDeviceWaitIdle` needs every queue of
    /// the device externally synchronised, and the host's queues are the
    /// host's; wait on the host's fences instead.
    pub fn wait_idle(&self) -> Result<()> {
        if !self.owns_device {
            return Err(Error::InvalidArgument(
                "wait_idle on a host's device: wait on the host's own fences".into(),
            ));
        }
        self.check_alive()?;
        // Submits from other threads hold the queue lock.
        let _queue = self.queue_lock.lock().unwrap_or_else(|e| e.into_inner());
        // SAFETY: device is alive; its only queue is held.
        unsafe { self.device.device_wait_idle() }.map_err(|r| match r {
            vk::Result::ERROR_DEVICE_LOST => {
                self.mark_lost(Lost::Device("vkDeviceWaitIdle".into()))
            }
            r => Error::vk("vkDeviceWaitIdle")(r),
        })
    }

    /// Whether the device was lost or hung (see the type's documentation):
    /// every later call on this context fails.
    pub fn is_lost(&self) -> bool {
        self.lost_flag.load(Ordering::Acquire)
    }

    /// The error of a lost context, `Ok` while it is usable. Checked before
    /// any work that touches the device.
    pub(crate) fn check_alive(&self) -> Result<()> {
        if !self.is_lost() {
            return Ok(());
        }
        Err(self
            .lost
            .lock()
            .unwrap()
            .as_ref()
            .expect("set before the flag")
            .error())
    }

    /// Marks the context lost (the first reason is kept) and returns the
    /// error every call now gets.
    pub(crate) fn mark_lost(&self, why: Lost) -> Error {
        let mut lost = self.lost.lock().unwrap();
        let first = lost.get_or_insert(why).clone();
        self.lost_flag.store(true, Ordering::Release);
        log::error!("{}", first.error());
        first.error()
    }

    /// How long mcdenoise waits for one submit before it treats the device
    /// as hung: [`Error::Timeout`], and the context is lost. Default
    /// [`DEFAULT_FENCE_TIMEOUT`] (60 s; a submit holds about a second of work
    /// on lavapipe).
    pub fn fence_timeout(&self) -> Duration {
        Duration::from_nanos(self.fence_timeout_ns.load(Ordering::Relaxed))
    }

    /// Sets [`fence_timeout`](Self::fence_timeout) for later waits (any
    /// thread). Raise it for devices far slower than lavapipe on two cores.
    pub fn set_fence_timeout(&self, timeout: Duration) {
        let ns = u64::try_from(timeout.as_nanos()).unwrap_or(u64::MAX);
        self.fence_timeout_ns.store(ns, Ordering::Relaxed);
    }

    /// How long a submit that is the first to run `fresh` of its pipelines
    /// may take: [`fence_timeout`](Self::fence_timeout) plus
    /// [`FIRST_DISPATCH_ALLOWANCE`] for each, at most
    /// [`FIRST_DISPATCH_ALLOWANCE_MAX`] in all.
    pub fn submit_timeout(&self, fresh: usize) -> Duration {
        let allowance = FIRST_DISPATCH_ALLOWANCE
            .saturating_mul(u32::try_from(fresh).unwrap_or(u32::MAX))
            .min(FIRST_DISPATCH_ALLOWANCE_MAX);
        self.fence_timeout().saturating_add(allowance)
    }

    /// Whether no completed submit has run `pipeline` yet.
    pub(crate) fn first_run(&self, pipeline: vk::Pipeline) -> bool {
        !self.ran.lock().unwrap().contains(&pipeline)
    }

    /// Records that a completed submit ran `pipelines`.
    pub(crate) fn mark_ran(&self, pipelines: &[vk::Pipeline]) {
        self.ran.lock().unwrap().extend(pipelines.iter().copied());
    }

    /// The validation messages' log, shared: it stays readable after the
    /// context is dropped, so a test can check that the teardown itself was
    /// valid.
    pub fn validation_log(&self) -> Arc<ValidationLog> {
        self.validation_log.clone()
    }

    /// Debug label for a Vulkan object (no-op without the debug extension).
    pub(crate) fn name_object<H: vk::Handle>(&self, handle: H, name: &str) {
        if self.debug.is_none() {
            return;
        }
        let Ok(cname) = CString::new(name) else {
            return;
        };
        let du = ash::ext::debug_utils::Device::new(&self.instance, &self.device);
        let info = vk::DebugUtilsObjectNameInfoEXT::default()
            .object_handle(handle)
            .object_name(&cname);
        // SAFETY: handle belongs to this device; naming failures are harmless.
        let _ = unsafe { du.set_debug_utils_object_name(&info) };
    }
}

impl GpuContext {
    /// Builds every later pipeline of this context through a
    /// `VkPipelineCache` loaded from `path` (a missing file, or one made by
    /// another device or driver, starts an empty cache), and writes the
    /// cache back to `path` when the context is dropped if a pipeline was
    /// built meanwhile (or at [`save_pipeline_cache`](Self::save_pipeline_cache)).
    /// A driver that keeps compiled pipelines in its cache then skips the
    /// compilation in the next process. Returns the bytes loaded (0: an
    /// empty cache). An error if the context already has a cache, or if
    /// `path` exists but cannot be read or is not a pipeline cache (a
    /// header of version one): a file of anything else is never written
    /// over.
    pub fn use_pipeline_cache(&self, path: &std::path::Path) -> Result<usize> {
        let mut slot = self.disk_cache.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(c) = slot.as_ref() {
            return Err(Error::InvalidArgument(format!(
                "the context already builds through the pipeline cache {}",
                c.path.display()
            )));
        }
        let data = match std::fs::read(path) {
            Ok(d) => d,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Vec::new(),
            Err(source) => {
                return Err(Error::Io {
                    path: path.to_path_buf(),
                    source,
                })
            }
        };
        // SAFETY: a valid physical device of this instance.
        let props = unsafe { self.instance.get_physical_device_properties(self.physical) };
        if !data.is_empty() && !super::pipeline::is_pipeline_cache(&data) {
            return Err(Error::InvalidArgument(format!(
                "{} is not a Vulkan pipeline cache: refusing to use it (the cache would be written over it)",
                path.display()
            )));
        }
        let data = if super::pipeline::cache_matches(&data, &props) {
            data
        } else {
            if !data.is_empty() {
                log::info!(
                    "pipeline cache {} was made by another device or driver: starting empty",
                    path.display()
                );
            }
            Vec::new()
        };
        let info = vk::PipelineCacheCreateInfo::default().initial_data(&data);
        // SAFETY: the create info references a live local.
        let handle =
            unsafe { self.device.create_pipeline_cache(&info, None) }.map_err(|result| {
                Error::Vulkan {
                    call: "vkCreatePipelineCache",
                    result,
                }
            })?;
        *slot = Some(super::pipeline::DiskCache {
            handle,
            path: path.to_path_buf(),
            dirty: false,
        });
        Ok(data.len())
    }

    /// Writes the pipeline cache ([`use_pipeline_cache`](Self::use_pipeline_cache))
    /// to its file now (atomically: a reader sees the old file or the new
    /// one). Returns the bytes written; `Ok(0)` when the context has no
    /// cache.
    pub fn save_pipeline_cache(&self) -> Result<usize> {
        let mut slot = self.disk_cache.lock().unwrap_or_else(|e| e.into_inner());
        let Some(c) = slot.as_mut() else {
            return Ok(0);
        };
        // SAFETY: the cache belongs to this device; VkPipelineCache is
        // internally synchronised.
        let data = unsafe { self.device.get_pipeline_cache_data(c.handle) }.map_err(|result| {
            Error::Vulkan {
                call: "vkGetPipelineCacheData",
                result,
            }
        })?;
        super::pipeline::write_cache_file(&c.path, &data)?;
        c.dirty = false;
        Ok(data.len())
    }

    /// An error if a slice belongs to a buffer of this context that was
    /// dropped, or to a buffer of another context (host buffers, id 0, are
    /// the caller's responsibility under `BufferSlice::from_raw`).
    pub(crate) fn check_live(&self, slices: &[super::BufferSlice]) -> Result<()> {
        let live = self.live.lock().unwrap_or_else(|e| e.into_inner());
        match slices.iter().find(|s| s.id != 0 && !live.contains(&s.id)) {
            None => Ok(()),
            Some(s) => Err(Error::InvalidArgument(format!(
                "a buffer slice ({} bytes at {}) outlived its buffer, or belongs to another context",
                s.size, s.offset
            ))),
        }
    }

    /// The `VkPipelineCache` to build through (null: none).
    pub(crate) fn disk_cache_handle(&self) -> vk::PipelineCache {
        let slot = self.disk_cache.lock().unwrap_or_else(|e| e.into_inner());
        slot.as_ref()
            .map_or(vk::PipelineCache::null(), |c| c.handle)
    }

    /// Notes that a pipeline was built through the cache.
    pub(crate) fn mark_disk_cache_dirty(&self) {
        let mut slot = self.disk_cache.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(c) = slot.as_mut() {
            c.dirty = true;
        }
    }
}

impl Drop for GpuContext {
    fn drop(&mut self) {
        let dirty = self
            .disk_cache
            .get_mut()
            .ok()
            .and_then(|c| c.as_ref())
            .is_some_and(|c| c.dirty);
        if dirty {
            if let Err(e) = self.save_pipeline_cache() {
                log::warn!("the pipeline cache was not saved: {e}");
            }
        }
        // SAFETY: teardown in dependency order; nothing is used afterwards.
        unsafe {
            if self.owns_device {
                let _ = self.device.device_wait_idle();
            }
            self.pipelines.lock().unwrap().destroy(&self.device);
            if let Some(c) = self.disk_cache.lock().unwrap().take() {
                self.device.destroy_pipeline_cache(c.handle, None);
            }
            for p in self.free_desc_pools.lock().unwrap().drain(..) {
                self.device.destroy_descriptor_pool(p, None);
                fault::destroyed(Object::DescriptorPool);
            }
            for p in self.free_query_pools.lock().unwrap().drain(..) {
                self.device.destroy_query_pool(p, None);
                fault::destroyed(Object::QueryPool);
            }
            let deferred = std::mem::take(&mut self.in_flight.lock().unwrap().deferred);
            for (b, a) in deferred {
                self.destroy_buffer(b, a);
            }
            if self.allocator.lock().unwrap().take().is_some() {
                fault::destroyed(Object::Allocator);
            }
            if self.owns_device {
                self.device.destroy_device(None);
                fault::destroyed(Object::Device);
                if let Some((du, m)) = self.debug.take() {
                    du.destroy_debug_utils_messenger(m, None);
                    fault::destroyed(Object::DebugMessenger);
                }
                self.instance.destroy_instance(None);
                fault::destroyed(Object::Instance);
            }
        }
    }
}
