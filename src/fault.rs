//! Test-only fault injection, and a count of live Vulkan objects (issue #14).
//!
//! lavapipe cannot run out of memory or lose its device on demand, and a
//! disk cannot be filled on demand, so the error paths of `gpu` and of the
//! file writer ([`crate::io::write_atomic`]) are reached through this hook:
//! a test arms a [`Plan`] on its thread and says "the `n`-th call of kind
//! [`Call`] fails with this [`Failure`]". The call then returns the failure
//! instead of calling Vulkan or the OS, exactly as if the driver or the
//! kernel had returned it.
//!
//! - **Scope.** A plan applies only to calls made on the thread that armed
//!   it, from its creation until it is dropped, so tests running in parallel
//!   in one process do not see each other's faults. mcdenoise makes every
//!   Vulkan and file call of an operation on the caller's thread, except the
//!   pipeline builds of [`crate::Denoiser::warm_up`], which run on a thread
//!   of their own (a plan armed by the caller does not see them).
//! - **Cost.** Unarmed, each hooked call loads one atomic (the number of
//!   threads with a plan) and goes on; an armed plan costs a thread-local
//!   lookup per hooked call.
//! - **Live objects.** [`live`] counts the Vulkan objects mcdenoise has
//!   created and not yet destroyed, per [`Object`] kind, across the whole
//!   process (always on: one relaxed atomic add per create or destroy). A
//!   test compares the counts before and after a failed constructor to show
//!   that nothing leaked; tests that do so must not run beside other GPU
//!   tests in the same process (`tests/faults.rs` holds a lock).
//!
//! This module is not part of the stable API (hidden from the docs); it
//! exists for the crate's own tests. `docs/robustness.md` lists the faults
//! the tests inject and what each produced.

use std::cell::RefCell;
use std::sync::atomic::{AtomicI64, AtomicUsize, Ordering};

use ash::vk;

/// A hooked call: where a fault can be injected.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Call {
    /// `vkCreateInstance` (also for `mcdenoise info`'s enumeration).
    CreateInstance,
    /// `vkCreateDebugUtilsMessengerEXT` (with validation only).
    CreateDebugMessenger,
    /// `vkCreateDevice`.
    CreateDevice,
    /// Creating the memory allocator (gpu-allocator) on a new context.
    CreateAllocator,
    /// `vkCreateDescriptorSetLayout` (building a pipeline).
    CreateDescriptorSetLayout,
    /// `vkCreatePipelineLayout` (building a pipeline).
    CreatePipelineLayout,
    /// `vkCreateShaderModule` (building a pipeline).
    CreateShaderModule,
    /// `vkCreateComputePipelines`.
    CreateComputePipeline,
    /// `vkCreateCommandPool` (every execute-mode batch).
    CreateCommandPool,
    /// `vkAllocateCommandBuffers` (every execute-mode batch).
    AllocateCommandBuffer,
    /// `vkCreateFence` (every execute-mode batch).
    CreateFence,
    /// `vkCreateDescriptorPool`.
    CreateDescriptorPool,
    /// `vkCreateBuffer` (every [`crate::gpu::GpuBuffer`], staging included).
    CreateBuffer,
    /// A memory allocation for a buffer (gpu-allocator). A failure with
    /// `ERROR_OUT_OF_DEVICE_MEMORY` or `ERROR_OUT_OF_HOST_MEMORY` is the
    /// allocator's out-of-memory error.
    Allocate,
    /// `vkQueueSubmit`.
    QueueSubmit,
    /// `vkWaitForFences` after a submit (`TIMEOUT` simulates a hung device).
    WaitForFences,
    /// Creating the temporary file of an atomic write.
    FileCreate,
    /// Writing to the temporary file: with [`Failure::Os`] the write that
    /// reaches the `n`-th byte fails after the bytes before it were written
    /// (see [`Plan::fail_write_after`]).
    FileWrite,
    /// Renaming the temporary file over the destination.
    FileRename,
}

/// What a failing call returns.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Failure {
    /// A Vulkan result code (GPU calls).
    Vk(vk::Result),
    /// An OS error number, e.g. `libc::ENOSPC` (file calls).
    Os(i32),
}

/// Vulkan objects counted by [`live`].
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Object {
    /// `VkInstance`.
    Instance,
    /// `VkDebugUtilsMessengerEXT`.
    DebugMessenger,
    /// `VkDevice` (only those mcdenoise created).
    Device,
    /// The memory allocator of a context.
    Allocator,
    /// `VkDescriptorSetLayout`.
    DescriptorSetLayout,
    /// `VkPipelineLayout`.
    PipelineLayout,
    /// `VkShaderModule`.
    ShaderModule,
    /// `VkPipeline`.
    Pipeline,
    /// `VkCommandPool`.
    CommandPool,
    /// `VkFence`.
    Fence,
    /// `VkDescriptorPool`.
    DescriptorPool,
    /// `VkQueryPool`.
    QueryPool,
    /// `VkBuffer`.
    Buffer,
    /// A buffer's memory allocation.
    Allocation,
}

/// Every [`Object`] kind, in declaration order (the order of [`live`]).
pub const OBJECTS: [Object; 14] = [
    Object::Instance,
    Object::DebugMessenger,
    Object::Device,
    Object::Allocator,
    Object::DescriptorSetLayout,
    Object::PipelineLayout,
    Object::ShaderModule,
    Object::Pipeline,
    Object::CommandPool,
    Object::Fence,
    Object::DescriptorPool,
    Object::QueryPool,
    Object::Buffer,
    Object::Allocation,
];

static LIVE: [AtomicI64; 14] = [const { AtomicI64::new(0) }; 14];

/// Number of threads with an armed [`Plan`]: the fast path of every hook.
static ARMED: AtomicUsize = AtomicUsize::new(0);

/// The live-object counts, one per kind of [`OBJECTS`], process-wide.
pub fn live() -> Vec<(Object, i64)> {
    OBJECTS
        .iter()
        .zip(&LIVE)
        .map(|(o, n)| (*o, n.load(Ordering::SeqCst)))
        .collect()
}

/// Records that an object of `kind` was created.
pub(crate) fn created(kind: Object) {
    LIVE[kind as usize].fetch_add(1, Ordering::Relaxed);
}

/// Records that an object of `kind` was destroyed.
pub(crate) fn destroyed(kind: Object) {
    LIVE[kind as usize].fetch_sub(1, Ordering::Relaxed);
}

#[derive(Default)]
struct State {
    /// Calls per kind since the plan was armed.
    calls: Vec<(Call, u64)>,
    /// Armed faults: (call, 1-based index of the failing call, failure).
    faults: Vec<(Call, u64, Failure)>,
    /// Byte limit of [`Call::FileWrite`] and its error.
    write_limit: Option<(u64, i32)>,
    /// Bytes written through hooked writers since the plan was armed.
    written: u64,
    /// `read_slice` goes through a staging copy even where the memory is
    /// mapped ([`Plan::staged_reads`]).
    staged_reads: bool,
}

thread_local! {
    static PLAN: RefCell<Option<State>> = const { RefCell::new(None) };
}

/// The faults armed on this thread; they are disarmed when it is dropped.
/// At most one plan per thread at a time (arming a second one panics).
#[must_use = "the plan is disarmed when dropped"]
pub struct Plan {
    /// A plan belongs to its thread (`!Send`).
    _thread: std::marker::PhantomData<*const ()>,
}

impl std::fmt::Debug for Plan {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("fault::Plan")
    }
}

impl Plan {
    /// Arms a plan with no faults yet: hooked calls on this thread are
    /// counted ([`calls`](Self::calls)) and succeed.
    pub fn new() -> Plan {
        PLAN.with(|p| {
            let mut p = p.borrow_mut();
            assert!(p.is_none(), "a fault plan is already armed on this thread");
            *p = Some(State::default());
        });
        ARMED.fetch_add(1, Ordering::SeqCst);
        Plan {
            _thread: std::marker::PhantomData,
        }
    }

    /// The `nth` call of `call` from now on (1: the next one; counted from
    /// this call, not from the plan's creation) fails with `failure`, once.
    pub fn fail(self, call: Call, nth: u64, failure: Failure) -> Plan {
        assert!(nth >= 1, "calls are counted from 1");
        with_state(|s| {
            let base = count(s, call);
            s.faults.push((call, base + nth, failure));
        });
        self
    }

    /// Writes through the file writer fail with OS error `errno` (e.g.
    /// `libc::ENOSPC`) once `bytes` bytes have been written from now on: the
    /// write that would pass the limit writes the bytes below it and then
    /// fails, like a disk that fills up.
    pub fn fail_write_after(self, bytes: u64, errno: i32) -> Plan {
        with_state(|s| s.write_limit = Some((s.written + bytes, errno)));
        self
    }

    /// Plane reads through `gpu::buffer::read_slice` (a chain's outputs) on
    /// this thread take the path of a device whose memory the host cannot
    /// map (a staging buffer, a copy, a submit), as on a discrete GPU,
    /// instead of reading lavapipe's mapped memory directly: so that faults
    /// can be injected into that path. `GpuBuffer`'s own downloads are not
    /// affected (a staging buffer is read through its mapping).
    pub fn staged_reads(self) -> Plan {
        with_state(|s| s.staged_reads = true);
        self
    }

    /// How many times `call` was reached on this thread since the plan was
    /// armed (including failed ones).
    pub fn calls(&self, call: Call) -> u64 {
        with_state(|s| count(s, call))
    }

    /// Bytes written through the file writer on this thread since the plan
    /// was armed (those a failing write wrote before failing included).
    pub fn bytes_written(&self) -> u64 {
        with_state(|s| s.written)
    }

    /// Whether every armed fault has fired.
    pub fn all_fired(&self) -> bool {
        with_state(|s| s.faults.is_empty())
    }
}

impl Default for Plan {
    fn default() -> Self {
        Plan::new()
    }
}

impl Drop for Plan {
    fn drop(&mut self) {
        PLAN.with(|p| p.borrow_mut().take());
        ARMED.fetch_sub(1, Ordering::SeqCst);
    }
}

fn with_state<T>(f: impl FnOnce(&mut State) -> T) -> T {
    PLAN.with(|p| f(p.borrow_mut().as_mut().expect("the plan is armed")))
}

fn count(s: &State, call: Call) -> u64 {
    s.calls
        .iter()
        .find(|(c, _)| *c == call)
        .map_or(0, |(_, n)| *n)
}

/// Whether `read_slice` may use a buffer's mapping ([`Plan::staged_reads`]).
pub(crate) fn mapped_reads() -> bool {
    if ARMED.load(Ordering::Relaxed) == 0 {
        return true;
    }
    PLAN.with(|p| !p.borrow().as_ref().is_some_and(|s| s.staged_reads))
}

/// Counts a call of `call` and returns the failure armed for it, if any.
pub(crate) fn hit(call: Call) -> Option<Failure> {
    if ARMED.load(Ordering::Relaxed) == 0 {
        return None;
    }
    PLAN.with(|p| p.borrow_mut().as_mut().and_then(|s| hit_in(s, call)))
}

fn hit_in(s: &mut State, call: Call) -> Option<Failure> {
    let n = match s.calls.iter_mut().find(|(c, _)| *c == call) {
        Some((_, n)) => {
            *n += 1;
            *n
        }
        None => {
            s.calls.push((call, 1));
            1
        }
    };
    let i = s.faults.iter().position(|f| f.0 == call && f.1 == n)?;
    Some(s.faults.swap_remove(i).2)
}

/// [`hit`] for a Vulkan call: `Err(result)` when a fault is armed for it.
pub(crate) fn vk(call: Call) -> Result<(), vk::Result> {
    match hit(call) {
        None => Ok(()),
        Some(Failure::Vk(r)) => Err(r),
        Some(Failure::Os(e)) => {
            panic!("fault plan: {call:?} fails with a Vulkan result, not OS error {e}")
        }
    }
}

/// [`hit`] for a file call: `Err(os error)` when a fault is armed for it.
pub(crate) fn os(call: Call) -> std::io::Result<()> {
    match hit(call) {
        None => Ok(()),
        Some(Failure::Os(e)) => Err(std::io::Error::from_raw_os_error(e)),
        Some(Failure::Vk(r)) => panic!("fault plan: {call:?} fails with an OS error, not {r:?}"),
    }
}

/// How many of `len` bytes a hooked write may write before it fails, and
/// the error it fails with: `None` when it may write them all. A
/// [`Call::FileWrite`] fault armed with [`Plan::fail`] fails the write
/// before its first byte.
pub(crate) fn write_budget(len: usize) -> Option<(usize, std::io::Error)> {
    if ARMED.load(Ordering::Relaxed) == 0 {
        return None;
    }
    PLAN.with(|p| {
        let mut p = p.borrow_mut();
        let s = p.as_mut()?;
        match hit_in(s, Call::FileWrite) {
            Some(Failure::Os(e)) => return Some((0, std::io::Error::from_raw_os_error(e))),
            Some(Failure::Vk(r)) => {
                panic!("fault plan: FileWrite fails with an OS error, not {r:?}")
            }
            None => {}
        }
        match s.write_limit {
            Some((limit, errno)) if s.written + len as u64 > limit => {
                let allowed = limit.saturating_sub(s.written) as usize;
                s.written += allowed as u64;
                Some((allowed, std::io::Error::from_raw_os_error(errno)))
            }
            _ => {
                s.written += len as u64;
                None
            }
        }
    })
}
