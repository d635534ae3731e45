//! Recording dispatches: descriptor sets, push constants, barriers, row bands,
//! submits and timestamp queries.
//!
//! A [`Batch`] either owns its command buffer and submits it ([`Batch::new`],
//! [`Batch::finish`]), splitting long work into several submits so no single
//! submit runs longer than about a second on lavapipe, or records into a
//! host's command buffer ([`Batch::record_into`]) and never submits.
//!
//! Faults: every fence wait has the context's timeout
//! ([`GpuContext::fence_timeout`], 60 s per submit by default). A failed
//! submit or wait names the work it held ([`Error::Gpu`], or
//! [`Error::DeviceLost`] / [`Error::Timeout`], which also mark the context
//! lost). A batch dropped after a failed wait waits again (up to the
//! timeout) before it destroys its command pool and fence; if the device
//! still does not answer, it leaks them rather than destroy objects the
//! device may be using.

use std::collections::HashSet;
use std::sync::Arc;

use ash::vk;

use super::buffer::BufferSlice;
use super::context::{GpuContext, Lost};
use super::pipeline::Pipeline;
use super::reflect::{Extent, KernelDecl, Precision};
use crate::error::{Error, Result};
use crate::fault::{self, Call, Object};

/// Estimated work one submit may hold, in floating-point operations: a few
/// milliseconds on a discrete GPU, far from any watchdog, and tens of
/// milliseconds on lavapipe (two cores); the renderer's estimate
/// (`render::flops_per_sample`) is calibrated so that its submits take
/// about a second there. Larger submits did not make LP faster
/// (PERF-HISTORY).
pub const DEFAULT_FLOPS_PER_SUBMIT: f64 = 2.0e9;

/// Words of the header of a work queue that kernels fill on the device for
/// an indirect dispatch: workgroups x, y, z (as `vkCmdDispatchIndirect`
/// reads them), then the entry count; the entries follow
/// (`QUEUE_APPEND` in `spirv/lib/common.glsl`).
pub const QUEUE_HEADER_WORDS: usize = 4;

/// GPU time of one dispatch (one band of one kernel), from timestamp queries.
#[derive(Clone, Debug, PartialEq)]
pub struct KernelTiming {
    /// The kernel's name (with `_f64` for the f64 variant).
    pub kernel: String,
    /// The band of grid rows the dispatch covered, `[first, end)`: image
    /// rows, except for a kernel whose invocations compute blocks of rows
    /// (`gbf_prepare`, `gbf_filter`), where a grid row is one block.
    pub rows: (u32, u32),
    /// GPU time between the dispatch's two timestamps, in nanoseconds.
    pub nanoseconds: f64,
    /// The floating-point operations the kernel's cost function counts for
    /// this band (`flops_per_pixel × width × rows`, see each kernel's host
    /// file); with `nanoseconds`, the achieved rate of `mcdenoise bench`.
    pub flops: f64,
    /// The compulsory memory traffic of the band: every bound range read or
    /// written once, in proportion to the band's rows (for an indirect
    /// dispatch, the caller's estimate). With `nanoseconds`, the achieved
    /// bandwidth of `mcdenoise bench`'s roofline.
    pub bytes: f64,
}

/// Sums timings per kernel name, in first-seen order.
pub fn timings_per_kernel(t: &[KernelTiming]) -> Vec<(String, f64, usize)> {
    let mut out: Vec<(String, f64, usize)> = Vec::new();
    for k in t {
        match out.iter_mut().find(|o| o.0 == k.kernel) {
            Some(o) => {
                o.1 += k.nanoseconds;
                o.2 += 1;
            }
            None => out.push((k.kernel.clone(), k.nanoseconds, 1)),
        }
    }
    out
}

/// A timed dispatch waiting for its timestamps: (label, rows, query index of
/// the start stamp, flops, bytes).
type Stamp = (String, (u32, u32), u32, f64, f64);

/// The first `used` timestamps of `pools` ([`QUERIES_PER_POOL`] each), in
/// order.
///
/// # Safety
/// The work that wrote them must have completed.
unsafe fn query_results(ctx: &GpuContext, pools: &[vk::QueryPool], used: u32) -> Result<Vec<u64>> {
    let mut values = vec![0u64; used as usize];
    for (pi, pool) in pools.iter().enumerate() {
        let first = pi as u32 * QUERIES_PER_POOL;
        if first >= used {
            break;
        }
        let count = (used - first).min(QUERIES_PER_POOL);
        // SAFETY: queries [0, count) of the pool were written by completed
        // work (the caller's contract).
        unsafe {
            ctx.device.get_query_pool_results(
                *pool,
                0,
                &mut values[first as usize..(first + count) as usize],
                vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
            )
        }
        .map_err(Error::vk("vkGetQueryPoolResults"))?;
    }
    Ok(values)
}

/// A stamp's time from the timestamps it indexes (`period` ns per tick).
fn timing((kernel, rows, q, flops, bytes): Stamp, values: &[u64], period: f64) -> KernelTiming {
    let dt = values[q as usize + 1].wrapping_sub(values[q as usize]);
    KernelTiming {
        kernel,
        rows,
        nanoseconds: dt as f64 * period,
        flops,
        bytes,
    }
}

/// A dispatch's band of rows: (first row, end row, height).
type Band = (u32, u32, u32);

const SETS_PER_POOL: u32 = 64;
const DESCRIPTORS_PER_POOL: u32 = 64 * 32;
const QUERIES_PER_POOL: u32 = 256;

enum Mode {
    Execute {
        fence: vk::Fence,
    },
    Record,
    /// Records nothing: sums the estimated work (for progress totals).
    Count,
}

/// Progress of a batch in execute mode, reported after each submit completes.
#[derive(Clone, Debug)]
pub struct Progress {
    /// Estimated floating-point operations completed so far.
    pub done_flops: f64,
    /// The kernel of the last completed band.
    pub kernel: String,
}

/// Receives [`Progress`] reports (see [`Batch::on_progress`]).
pub type ProgressFn = std::sync::Arc<dyn Fn(&Progress) + Send + Sync>;

/// A sequence of dispatches. See the module documentation.
pub struct Batch {
    ctx: Arc<GpuContext>,
    /// Execute mode: a pool of the batch's own (command pools need external
    /// synchronisation, so batches on different threads never share one).
    pool: vk::CommandPool,
    cmd: vk::CommandBuffer,
    mode: Mode,
    desc_pools: Vec<vk::DescriptorPool>,
    sets_left: u32,
    query_pools: Vec<vk::QueryPool>,
    queries_used: u32,
    /// The timed dispatches whose timestamps are not read yet.
    stamps: Vec<Stamp>,
    timings: Vec<KernelTiming>,
    timestamps: bool,
    flops_in_submit: f64,
    /// Inside [`unit`](Self::unit): its dispatches were charged up front.
    in_unit: bool,
    /// Estimated floating-point operations per submit before it is split.
    pub max_flops_per_submit: f64,
    /// Number of submits so far (execute mode).
    pub submits: u32,
    /// Print progress on stderr at submit boundaries once the batch has run
    /// for more than a second (execute mode).
    pub progress: bool,
    started: std::time::Instant,
    /// The kernel of the last recorded dispatch, with (first row, end row,
    /// height) of its band (none for an indirect dispatch).
    last_band: Option<(String, Option<Band>)>,
    /// Every buffer bound or copied so far, retained in the context until
    /// the work is known to be complete.
    used: HashSet<vk::Buffer>,
    /// The first error of a `fill` or `copy` (which record nothing then),
    /// returned by `finish` / `finish_recording`.
    deferred: Option<Error>,
    /// Estimated work recorded so far, and completed so far (execute mode).
    flops_recorded: f64,
    flops_done: f64,
    /// Called after each submit has completed (execute mode).
    pub on_progress: Option<ProgressFn>,
    /// A submit whose completion was not seen (its wait failed).
    pending: bool,
    /// The dispatches recorded since the last submit, for error messages:
    /// kernel names with their bands (none for an indirect dispatch).
    work: Vec<(String, Option<Band>)>,
    /// Descriptions of the other work since the last submit (transfers).
    notes: Vec<String>,
    /// The pipelines recorded since the last submit that no completed
    /// submit on the context has run (execute mode): each adds
    /// [`FIRST_DISPATCH_ALLOWANCE`](super::context::FIRST_DISPATCH_ALLOWANCE)
    /// to the wait.
    fresh: Vec<vk::Pipeline>,
}

impl Batch {
    /// A batch with a command buffer of its own, submitted to the context's
    /// queue. Dropping it without [`finish`](Self::finish) waits for what was
    /// submitted and discards the rest.
    pub fn new(ctx: &Arc<GpuContext>) -> Result<Batch> {
        ctx.check_alive()?;
        let dev = &ctx.device;
        // SAFETY: device alive; pool destroyed (with its buffer) in Drop.
        let pool = fault::vk(Call::CreateCommandPool)
            .and_then(|()| unsafe {
                dev.create_command_pool(
                    &vk::CommandPoolCreateInfo::default()
                        .queue_family_index(ctx.queue_family)
                        .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER),
                    None,
                )
            })
            .map_err(Error::vk("vkCreateCommandPool"))?;
        fault::created(Object::CommandPool);
        // From here on the batch's Drop destroys the pool and the fence (a
        // null fence is skipped) if a later step fails.
        let mut b = Batch::empty(
            ctx,
            pool,
            vk::CommandBuffer::null(),
            Mode::Execute {
                fence: vk::Fence::null(),
            },
        );
        b.cmd = fault::vk(Call::AllocateCommandBuffer)
            .and_then(|()| unsafe {
                dev.allocate_command_buffers(
                    &vk::CommandBufferAllocateInfo::default()
                        .command_pool(pool)
                        .level(vk::CommandBufferLevel::PRIMARY)
                        .command_buffer_count(1),
                )
            })
            .map_err(Error::vk("vkAllocateCommandBuffers"))?[0];
        let fence = fault::vk(Call::CreateFence)
            .and_then(|()| unsafe { dev.create_fence(&vk::FenceCreateInfo::default(), None) })
            .map_err(Error::vk("vkCreateFence"))?;
        fault::created(Object::Fence);
        b.mode = Mode::Execute { fence };
        b.begin()?;
        Ok(b)
    }

    /// Records into the host's command buffer `cmd`, which must be in the
    /// recording state. Nothing is submitted, ever;
    /// [`finish_recording`](Self::finish_recording) returns a [`Recorded`]
    /// that must be kept alive until the host's submission of `cmd` has
    /// completed (it owns the descriptor sets and query pools and keeps
    /// mcdenoise's buffers bound by the work alive).
    ///
    /// Synchronisation contract: the recording starts with a memory barrier
    /// from every earlier command of `cmd` (any stage, any write) to compute
    /// and transfer reads and writes, and `finish_recording` ends it with a
    /// barrier from mcdenoise's compute and transfer writes to every later
    /// command (any stage, any access). Host writes to host-visible memory made
    /// before the host's `vkQueueSubmit` are visible through the submit's
    /// implicit host dependency; to read results on the host, the host waits
    /// for its fence and (for non-coherent memory) invalidates, as for any
    /// Vulkan work.
    ///
    /// # Safety
    /// `cmd` was allocated from the context's device, from a pool of a queue
    /// family with compute capability, is recording, and is outside a render
    /// pass. Host buffers bound through [`BufferSlice::from_raw`] stay alive
    /// until the work completes; the [`Recorded`] is dropped only after that
    /// (or the recording is abandoned and never submitted).
    pub unsafe fn record_into(ctx: &Arc<GpuContext>, cmd: vk::CommandBuffer) -> Batch {
        let b = Batch::empty(ctx, vk::CommandPool::null(), cmd, Mode::Record);
        b.global_barrier(
            vk::PipelineStageFlags::ALL_COMMANDS,
            vk::AccessFlags::MEMORY_WRITE,
            vk::PipelineStageFlags::COMPUTE_SHADER | vk::PipelineStageFlags::TRANSFER,
            vk::AccessFlags::SHADER_READ
                | vk::AccessFlags::SHADER_WRITE
                | vk::AccessFlags::TRANSFER_READ
                | vk::AccessFlags::TRANSFER_WRITE,
        );
        b
    }

    fn global_barrier(
        &self,
        src_stage: vk::PipelineStageFlags,
        src: vk::AccessFlags,
        dst_stage: vk::PipelineStageFlags,
        dst: vk::AccessFlags,
    ) {
        if matches!(self.mode, Mode::Count) {
            return;
        }
        let mb = [vk::MemoryBarrier::default()
            .src_access_mask(src)
            .dst_access_mask(dst)];
        // SAFETY: cmd is recording (both modes' invariant between calls).
        unsafe {
            self.ctx.device.cmd_pipeline_barrier(
                self.cmd,
                src_stage,
                dst_stage,
                vk::DependencyFlags::empty(),
                &mb,
                &[],
                &[],
            )
        };
    }

    /// Retains the buffers of `slices` until this batch's work is complete.
    /// Checks that `slices` are alive ([`GpuContext::check_live`]) and
    /// retains their buffers until the batch's work is done.
    fn track(&mut self, slices: &[BufferSlice]) -> Result<()> {
        self.ctx.check_live(slices)?;
        let new: Vec<vk::Buffer> = slices
            .iter()
            .map(|s| s.buffer)
            .filter(|b| self.used.insert(*b))
            .collect();
        if !new.is_empty() {
            self.ctx.retain(&new);
        }
        Ok(())
    }

    fn empty(
        ctx: &Arc<GpuContext>,
        pool: vk::CommandPool,
        cmd: vk::CommandBuffer,
        mode: Mode,
    ) -> Batch {
        Batch {
            ctx: ctx.clone(),
            pool,
            cmd,
            mode,
            desc_pools: Vec::new(),
            sets_left: 0,
            query_pools: Vec::new(),
            queries_used: 0,
            deferred: None,
            stamps: Vec::new(),
            timings: Vec::new(),
            timestamps: ctx.info.timestamp_period_ns > 0.0,
            flops_in_submit: 0.0,
            in_unit: false,
            max_flops_per_submit: DEFAULT_FLOPS_PER_SUBMIT,
            submits: 0,
            progress: false,
            started: std::time::Instant::now(),
            last_band: None,
            used: HashSet::new(),
            flops_recorded: 0.0,
            flops_done: 0.0,
            on_progress: None,
            pending: false,
            work: Vec::new(),
            notes: Vec::new(),
            fresh: Vec::new(),
        }
    }

    /// Names the work recorded since the last submit (for error messages;
    /// dispatches name themselves).
    pub(crate) fn note(&mut self, what: String) {
        self.notes.push(what);
    }

    /// What the current submit holds, for error messages: "kernels a ×3,
    /// b (rows 0..32 of 64)" (each kernel once, in recording order, with its
    /// number of dispatches, or its band when that is part of the image), or
    /// a transfer's description.
    fn describe_work(&self) -> String {
        let mut kernels: Vec<(&str, usize, Option<Band>)> = Vec::new();
        for (name, band) in &self.work {
            match kernels.iter_mut().find(|k| k.0 == name) {
                Some(k) => k.1 += 1,
                None => kernels.push((name, 1, *band)),
            }
        }
        const SHOWN: usize = 8;
        let mut parts: Vec<String> = kernels
            .iter()
            .take(SHOWN)
            .map(|&(name, n, band)| match band {
                _ if n > 1 => format!("{name} ×{n}"),
                Some((a, b, h)) if (a, b) != (0, h) => format!("{name} (rows {a}..{b} of {h})"),
                _ => name.to_owned(),
            })
            .collect();
        if kernels.len() > SHOWN {
            parts.push(format!("{} more", kernels.len() - SHOWN));
        }
        let mut described: Vec<String> = self.notes.clone();
        if !parts.is_empty() {
            described.insert(0, format!("kernels {}", parts.join(", ")));
        }
        if described.is_empty() {
            return "recorded transfers".into();
        }
        described.join("; ")
    }

    /// The error of a failed submit or wait: a device loss marks the
    /// context lost.
    fn failed(&self, call: &'static str, result: vk::Result, during: String) -> Error {
        match result {
            vk::Result::ERROR_DEVICE_LOST => self.ctx.mark_lost(Lost::Device(during)),
            result => Error::Gpu {
                during,
                call,
                result,
            },
        }
    }

    /// A batch that records nothing and submits nothing: recording a chain
    /// into it only sums the work estimates ([`flops`](Self::flops)), so a
    /// caller can show progress against a known total.
    pub fn counting(ctx: &Arc<GpuContext>) -> Batch {
        Batch::empty(
            ctx,
            vk::CommandPool::null(),
            vk::CommandBuffer::null(),
            Mode::Count,
        )
    }

    /// Whether this batch only counts work ([`Batch::counting`]): nothing it
    /// records will run.
    pub fn is_counting(&self) -> bool {
        matches!(self.mode, Mode::Count)
    }

    /// The context the batch records for.
    pub fn context(&self) -> &Arc<GpuContext> {
        &self.ctx
    }

    /// Estimated floating-point operations recorded so far.
    pub fn flops(&self) -> f64 {
        self.flops_recorded
    }

    fn begin(&mut self) -> Result<()> {
        // SAFETY: command buffer is in the initial state.
        unsafe {
            self.ctx.device.begin_command_buffer(
                self.cmd,
                &vk::CommandBufferBeginInfo::default()
                    .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
            )
        }
        .map_err(Error::vk("vkBeginCommandBuffer"))
    }

    /// Ends, submits and waits for the current command buffer, collects its
    /// timestamps, and starts a new one (execute mode; no-op in record mode).
    pub fn flush(&mut self) -> Result<()> {
        let Mode::Execute { fence } = self.mode else {
            return Ok(());
        };
        // Results are read through mapped memory after the fence: make the
        // device's writes available to the host.
        self.global_barrier(
            vk::PipelineStageFlags::COMPUTE_SHADER | vk::PipelineStageFlags::TRANSFER,
            vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::TRANSFER_WRITE,
            vk::PipelineStageFlags::HOST,
            vk::AccessFlags::HOST_READ,
        );
        self.ctx.check_alive()?;
        let dev = self.ctx.device.clone();
        let during = self.describe_work();
        // SAFETY: cmd is recording; fence unsignalled; queue used by us only.
        unsafe {
            dev.end_command_buffer(self.cmd)
                .map_err(Error::vk("vkEndCommandBuffer"))?;
            let cmds = [self.cmd];
            let submit = [vk::SubmitInfo::default().command_buffers(&cmds)];
            {
                let _queue = self.ctx.queue_lock.lock().unwrap();
                if let Err(r) = fault::vk(Call::QueueSubmit)
                    .and_then(|()| dev.queue_submit(self.ctx.queue, &submit, fence))
                {
                    return Err(self.failed("vkQueueSubmit", r, during));
                }
                self.ctx.count_submit();
            }
            self.pending = true;
            let timeout = self.ctx.submit_timeout(self.fresh.len());
            let ns = u64::try_from(timeout.as_nanos()).unwrap_or(u64::MAX);
            match fault::vk(Call::WaitForFences)
                .and_then(|()| dev.wait_for_fences(&[fence], true, ns))
            {
                Ok(()) => {
                    self.pending = false;
                    self.ctx.mark_ran(&self.fresh);
                    self.fresh.clear();
                }
                Err(vk::Result::TIMEOUT) => {
                    return Err(self
                        .ctx
                        .mark_lost(Lost::Timeout(during, timeout.as_secs_f64())))
                }
                Err(r) => return Err(self.failed("vkWaitForFences", r, during)),
            }
            self.work.clear();
            self.notes.clear();
            dev.reset_fences(&[fence])
                .map_err(Error::vk("vkResetFences"))?;
            dev.reset_command_buffer(self.cmd, vk::CommandBufferResetFlags::empty())
                .map_err(Error::vk("vkResetCommandBuffer"))?;
        }
        self.submits += 1;
        self.flops_done = self.flops_recorded;
        if let (Some(f), Some((k, ..))) = (&self.on_progress, &self.last_band) {
            f(&Progress {
                done_flops: self.flops_done,
                kernel: k.clone(),
            });
        }
        if self.progress {
            let t = self.started.elapsed().as_secs_f64();
            match (t > 1.0, &self.last_band) {
                (true, Some((k, Some((a, b, h))))) => {
                    log::debug!("{k} rows {a}..{b} of {h} done ({t:.1} s)")
                }
                (true, Some((k, None))) => log::debug!("{k} done ({t:.1} s)"),
                _ => {}
            }
        }
        self.collect_timestamps()?;
        self.flops_in_submit = 0.0;
        self.begin()
    }

    fn collect_timestamps(&mut self) -> Result<()> {
        if self.stamps.is_empty() {
            return Ok(());
        }
        // SAFETY: the submit that wrote the queries has completed.
        let values = unsafe { query_results(&self.ctx, &self.query_pools, self.queries_used)? };
        let period = self.ctx.info.timestamp_period_ns as f64;
        self.timings
            .extend(self.stamps.drain(..).map(|s| timing(s, &values, period)));
        // Reuse the pools from the start for the next submit.
        self.queries_used = 0;
        Ok(())
    }

    fn descriptor_set(&mut self, layout: vk::DescriptorSetLayout) -> Result<vk::DescriptorSet> {
        let dev = &self.ctx.device;
        if self.sets_left == 0 {
            if let Some(pool) = self.ctx.take_desc_pool() {
                self.desc_pools.push(pool);
                self.sets_left = SETS_PER_POOL;
            }
        }
        if self.sets_left == 0 {
            let sizes = [vk::DescriptorPoolSize::default()
                .ty(vk::DescriptorType::STORAGE_BUFFER)
                .descriptor_count(DESCRIPTORS_PER_POOL)];
            // SAFETY: recycled into the context by Drop / Recorded, which
            // destroys it.
            let pool = fault::vk(Call::CreateDescriptorPool)
                .and_then(|()| unsafe {
                    dev.create_descriptor_pool(
                        &vk::DescriptorPoolCreateInfo::default()
                            .max_sets(SETS_PER_POOL)
                            .pool_sizes(&sizes),
                        None,
                    )
                })
                .map_err(Error::vk("vkCreateDescriptorPool"))?;
            fault::created(Object::DescriptorPool);
            self.desc_pools.push(pool);
            self.sets_left = SETS_PER_POOL;
        }
        let layouts = [layout];
        // SAFETY: pool has room (counted), layout alive in the cache.
        let set = unsafe {
            dev.allocate_descriptor_sets(
                &vk::DescriptorSetAllocateInfo::default()
                    .descriptor_pool(*self.desc_pools.last().unwrap())
                    .set_layouts(&layouts),
            )
        }
        .map_err(Error::vk("vkAllocateDescriptorSets"))?[0];
        self.sets_left -= 1;
        Ok(set)
    }

    fn query_pair(&mut self) -> Result<Option<(vk::QueryPool, u32, u32)>> {
        if !self.timestamps {
            return Ok(None);
        }
        let idx = self.queries_used;
        let pool_idx = (idx / QUERIES_PER_POOL) as usize;
        // A pair never straddles two pools: QUERIES_PER_POOL is even.
        if pool_idx >= self.query_pools.len() {
            if let Some(pool) = self.ctx.take_query_pool() {
                self.query_pools.push(pool);
            }
        }
        if pool_idx >= self.query_pools.len() {
            // SAFETY: recycled into the context by Drop / Recorded.
            let pool = unsafe {
                self.ctx.device.create_query_pool(
                    &vk::QueryPoolCreateInfo::default()
                        .query_type(vk::QueryType::TIMESTAMP)
                        .query_count(QUERIES_PER_POOL),
                    None,
                )
            }
            .map_err(Error::vk("vkCreateQueryPool"))?;
            fault::created(Object::QueryPool);
            self.query_pools.push(pool);
        }
        let pool = self.query_pools[pool_idx];
        let local = idx % QUERIES_PER_POOL;
        // SAFETY: resetting two queries of a pool we own, outside a render pass.
        unsafe {
            self.ctx
                .device
                .cmd_reset_query_pool(self.cmd, pool, local, 2)
        };
        self.queries_used += 2;
        Ok(Some((pool, local, idx)))
    }

    /// A compute→compute/transfer memory barrier (recorded after every dispatch).
    pub fn barrier(&mut self) {
        if matches!(self.mode, Mode::Count) {
            return;
        }
        let mb = [vk::MemoryBarrier::default()
            .src_access_mask(vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::TRANSFER_WRITE)
            .dst_access_mask(
                vk::AccessFlags::SHADER_READ
                    | vk::AccessFlags::SHADER_WRITE
                    | vk::AccessFlags::TRANSFER_READ
                    | vk::AccessFlags::TRANSFER_WRITE
                    | vk::AccessFlags::INDIRECT_COMMAND_READ,
            )];
        // SAFETY: cmd is recording.
        unsafe {
            self.ctx.device.cmd_pipeline_barrier(
                self.cmd,
                vk::PipelineStageFlags::COMPUTE_SHADER | vk::PipelineStageFlags::TRANSFER,
                vk::PipelineStageFlags::COMPUTE_SHADER
                    | vk::PipelineStageFlags::TRANSFER
                    | vk::PipelineStageFlags::DRAW_INDIRECT,
                vk::DependencyFlags::empty(),
                &mb,
                &[],
                &[],
            )
        };
    }

    /// Fills a range with a 32-bit pattern (e.g. zeroes counters). A slice
    /// of a dropped buffer records nothing, and [`finish`](Self::finish) or
    /// [`finish_recording`](Self::finish_recording) returns the error.
    pub fn fill(&mut self, slice: BufferSlice, value: u32) {
        if matches!(self.mode, Mode::Count) {
            return;
        }
        if let Err(e) = self.track(&[slice]) {
            self.defer(e);
            return;
        }
        // SAFETY: cmd is recording; range inside the buffer (BufferSlice invariant).
        unsafe {
            self.ctx.device.cmd_fill_buffer(
                self.cmd,
                slice.buffer,
                slice.offset,
                slice.size & !3,
                value,
            )
        };
        self.barrier();
    }

    /// Copies `src` into `dst`. Ranges of different sizes, or of a dropped
    /// buffer, record nothing, and [`finish`](Self::finish) or
    /// [`finish_recording`](Self::finish_recording) returns the error.
    pub fn copy(&mut self, src: BufferSlice, dst: BufferSlice) {
        if src.size != dst.size {
            self.defer(Error::InvalidArgument(format!(
                "copy between ranges of {} and {} bytes",
                src.size, dst.size
            )));
            return;
        }
        if matches!(self.mode, Mode::Count) {
            return;
        }
        if let Err(e) = self.track(&[src, dst]) {
            self.defer(e);
            return;
        }
        let region = [vk::BufferCopy::default()
            .src_offset(src.offset)
            .dst_offset(dst.offset)
            .size(src.size)];
        // SAFETY: cmd recording; ranges inside their buffers (BufferSlice invariant).
        unsafe {
            self.ctx
                .device
                .cmd_copy_buffer(self.cmd, src.buffer, dst.buffer, &region)
        };
        self.barrier();
    }

    /// Records `decl` over a `width` x `height` pixel grid, split into bands of
    /// rows so that one band holds at most `max_flops_per_submit` estimated
    /// operations (`flops_per_pixel` is the kernel's estimate). The push
    /// constants' third u32 (`row0`, by convention of every kernel) is set per
    /// band. In execute mode a submit is made whenever the estimate is reached.
    pub fn dispatch(
        &mut self,
        decl: &KernelDecl,
        precision: Precision,
        bindings: &[BufferSlice],
        push: &[u8],
        width: u32,
        height: u32,
        flops_per_pixel: f64,
    ) -> Result<()> {
        self.dispatch_rows(
            decl,
            precision,
            bindings,
            push,
            width,
            ((0, height), height),
            flops_per_pixel,
        )
    }

    /// [`dispatch`](Self::dispatch) over the rows `[first, end)` of the grid
    /// only (`first` a multiple of the workgroup height). `grid_rows`: how
    /// many grid rows the bindings cover, for the traffic estimate (each
    /// bound range counts once over that many rows): the grid's height when
    /// they hold the whole image, `end - first` when they hold this chunk.
    #[allow(clippy::too_many_arguments)]
    pub fn dispatch_rows(
        &mut self,
        decl: &KernelDecl,
        precision: Precision,
        bindings: &[BufferSlice],
        push: &[u8],
        width: u32,
        ((first, height), grid_rows): ((u32, u32), u32),
        flops_per_pixel: f64,
    ) -> Result<()> {
        // (`pipeline` fails on a lost context.)
        let p = self.ctx.pipeline(decl, precision)?;
        check_bindings(&self.ctx, decl, p.binding_count, bindings, push)?;
        if width == 0 || height <= first {
            return Ok(());
        }
        let [wx, wy, _] = p.workgroup;
        if first % wy != 0 {
            return Err(Error::InvalidArgument(format!(
                "kernel {}: first row {first} is not a multiple of the workgroup height {wy}",
                decl.name
            )));
        }
        let row_flops = flops_per_pixel.max(1.0) * width as f64;
        if matches!(self.mode, Mode::Count) {
            self.flops_recorded += row_flops * (height - first) as f64;
            return Ok(());
        }
        let set = self.bind_set(&p, bindings).map_err(recording(&p.name))?;
        // A range bound twice (unused slots of a kernel) is traffic once.
        let mut ranges: Vec<(vk::Buffer, u64, u64)> = bindings
            .iter()
            .map(|b| (b.buffer, b.offset, b.size))
            .collect();
        ranges.sort_unstable();
        ranges.dedup();
        let row_bytes =
            ranges.iter().map(|r| r.2 as f64).sum::<f64>() / grid_rows.max(height - first) as f64;
        let band = self.band_rows(row_flops, wy);
        let mut push = push.to_vec();
        let mut row0 = first;
        while row0 < height {
            let rows = band.min(height - row0);
            push[8..12].copy_from_slice(&row0.to_le_bytes());
            self.record_one(
                &p,
                set,
                &push,
                Some((row0, row0 + rows, height)),
                (row_flops * rows as f64, row_bytes * rows as f64),
                |dev, cmd| {
                    // SAFETY: cmd recording, the pipeline bound by record_one.
                    unsafe { dev.cmd_dispatch(cmd, width.div_ceil(wx), rows.div_ceil(wy), 1) }
                },
            )?;
            row0 += rows;
        }
        Ok(())
    }

    /// Rows per band of work estimated at `row_flops` per row: as many as
    /// fit in [`max_flops_per_submit`](Self::max_flops_per_submit), at
    /// least one, rounded up to a multiple of `multiple` (a workgroup's
    /// height, or the rows a queue's band is selected in), and at most the
    /// largest such multiple a `u32` holds (a budget without bound is one
    /// band).
    pub fn band_rows(&self, row_flops: f64, multiple: u32) -> u32 {
        let multiple = multiple.max(1);
        let most = u32::MAX / multiple * multiple;
        let rows = (self.max_flops_per_submit / row_flops).floor();
        // `as` saturates (NaN to 0); the ceiling cannot pass `most`.
        (rows.min(most as f64) as u32).max(1).div_ceil(multiple) * multiple
    }

    /// Records the reset of a work queue's header ([`QUEUE_HEADER_WORDS`]):
    /// no workgroups (x = 0, y = z = 1) and no entries.
    pub fn reset_queue(&mut self, queue: BufferSlice) -> Result<()> {
        self.fill(queue.sub(0, 16)?, 0);
        self.fill(queue.sub(4, 8)?, 1);
        Ok(())
    }

    /// Records what `record` records as one unit of at most `flops`
    /// estimated operations: a new submit starts before it if the unit would
    /// pass [`max_flops_per_submit`](Self::max_flops_per_submit), and none
    /// inside it. For dispatches whose bound holds only together, such as a
    /// queue one kernel fills and the next consume (LP's `lp_select` and
    /// `lp_centres`): checked one by one, the small first kernel was flushed
    /// in a submit of its own before each bounded dispatch. The dispatches
    /// keep their own estimates for the timings and the progress.
    pub fn unit<T>(
        &mut self,
        flops: f64,
        record: impl FnOnce(&mut Batch) -> Result<T>,
    ) -> Result<T> {
        if self.in_unit {
            return Err(Error::InvalidArgument("Batch::unit inside a unit".into()));
        }
        if self.flops_in_submit > 0.0 && self.flops_in_submit + flops > self.max_flops_per_submit {
            self.flush()?;
        }
        self.flops_in_submit += flops;
        self.in_unit = true;
        let out = record(self);
        self.in_unit = false;
        out
    }

    /// Records `decl` once with its workgroup count read on the device from
    /// `args` (three u32: x, y, z, as `vkCmdDispatchIndirect` takes them),
    /// which an earlier kernel of the batch wrote. For work whose size only
    /// the data knows (the outlier stage's detected pixels); it cannot be
    /// split into bands, so `flops` (the caller's bound on the work) must
    /// stay far below a watchdog on any device. The push constants' `row0`
    /// is 0. `bytes` estimates its memory traffic (for the roofline).
    #[allow(clippy::too_many_arguments)]
    pub fn dispatch_indirect(
        &mut self,
        decl: &KernelDecl,
        precision: Precision,
        bindings: &[BufferSlice],
        push: &[u8],
        args: BufferSlice,
        flops: f64,
        bytes: f64,
    ) -> Result<()> {
        let p = self.ctx.pipeline(decl, precision)?;
        check_bindings(&self.ctx, decl, p.binding_count, bindings, push)?;
        if args.size < 12 || args.offset % 4 != 0 {
            return Err(Error::InvalidArgument(format!(
                "kernel {}: indirect arguments need 12 bytes at a 4-byte offset",
                decl.name
            )));
        }
        if matches!(self.mode, Mode::Count) {
            self.flops_recorded += flops;
            return Ok(());
        }
        self.track(&[args])?;
        let set = self.bind_set(&p, bindings).map_err(recording(&p.name))?;
        let mut push = push.to_vec();
        push[8..12].copy_from_slice(&0u32.to_le_bytes());
        self.record_one(&p, set, &push, None, (flops, bytes), |dev, cmd| {
            // SAFETY: cmd recording; args inside its buffer (BufferSlice
            // invariant), created with INDIRECT_BUFFER usage.
            unsafe { dev.cmd_dispatch_indirect(cmd, args.buffer, args.offset) }
        })
    }

    /// Allocates and writes the descriptor set of one dispatch and retains
    /// its buffers.
    fn bind_set(&mut self, p: &Pipeline, bindings: &[BufferSlice]) -> Result<vk::DescriptorSet> {
        self.track(bindings)?;
        let set = self.descriptor_set(p.set_layout)?;
        let infos: Vec<[vk::DescriptorBufferInfo; 1]> = bindings
            .iter()
            .map(|b| {
                [vk::DescriptorBufferInfo::default()
                    .buffer(b.buffer)
                    .offset(b.offset)
                    .range(b.size)]
            })
            .collect();
        let writes: Vec<vk::WriteDescriptorSet> = infos
            .iter()
            .enumerate()
            .map(|(i, info)| {
                vk::WriteDescriptorSet::default()
                    .dst_set(set)
                    .dst_binding(i as u32)
                    .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                    .buffer_info(info)
            })
            .collect();
        // SAFETY: set freshly allocated, buffers valid (caller's contract).
        unsafe { self.ctx.device.update_descriptor_sets(&writes, &[]) };
        Ok(set)
    }

    /// Records one dispatch (`dispatch` records the command itself) with its
    /// pipeline, set and push constants, between two timestamps, then a
    /// barrier; submits first when the batch's work would pass
    /// `max_flops_per_submit`. `band` is (first row, end row, height), none
    /// for an indirect dispatch; `work`
    /// the estimated (flops, bytes).
    fn record_one(
        &mut self,
        p: &Pipeline,
        set: vk::DescriptorSet,
        push: &[u8],
        band: Option<Band>,
        work: (f64, f64),
        dispatch: impl FnOnce(&ash::Device, vk::CommandBuffer),
    ) -> Result<()> {
        let (flops, bytes) = work;
        if !self.in_unit
            && self.flops_in_submit > 0.0
            && self.flops_in_submit + flops > self.max_flops_per_submit
        {
            self.flush()?;
        }
        if matches!(self.mode, Mode::Execute { .. })
            && !self.fresh.contains(&p.pipeline)
            && self.ctx.first_run(p.pipeline)
        {
            self.fresh.push(p.pipeline);
        }
        let dev = self.ctx.device.clone();
        let q = self.query_pair().map_err(recording(&p.name))?;
        // SAFETY: cmd recording; pipeline/layout/set compatible.
        unsafe {
            if let Some((pool, local, _)) = q {
                dev.cmd_write_timestamp(self.cmd, vk::PipelineStageFlags::TOP_OF_PIPE, pool, local);
            }
            dev.cmd_bind_pipeline(self.cmd, vk::PipelineBindPoint::COMPUTE, p.pipeline);
            dev.cmd_bind_descriptor_sets(
                self.cmd,
                vk::PipelineBindPoint::COMPUTE,
                p.layout,
                0,
                &[set],
                &[],
            );
            dev.cmd_push_constants(self.cmd, p.layout, vk::ShaderStageFlags::COMPUTE, 0, push);
        }
        dispatch(&dev, self.cmd);
        if let Some((pool, local, idx)) = q {
            // SAFETY: as above.
            unsafe {
                dev.cmd_write_timestamp(
                    self.cmd,
                    vk::PipelineStageFlags::BOTTOM_OF_PIPE,
                    pool,
                    local + 1,
                )
            };
            self.stamps.push((
                p.name.clone(),
                band.map_or((0, 0), |b| (b.0, b.1)),
                idx,
                flops,
                bytes,
            ));
        }
        self.last_band = Some((p.name.clone(), band));
        match (self.work.last_mut(), band) {
            // Bands of one dispatch in one submit: one entry.
            (Some((name, Some(last))), Some(b)) if *name == p.name && last.1 == b.0 => last.1 = b.1,
            _ => self.work.push((p.name.clone(), band)),
        }
        self.barrier();
        if !self.in_unit {
            self.flops_in_submit += flops;
        }
        self.flops_recorded += flops;
        Ok(())
    }

    /// Submits the remaining work and waits (execute mode), and returns the
    /// per-dispatch GPU times. In record mode returns a [`Recorded`] holder.
    pub fn finish(mut self) -> Result<Vec<KernelTiming>> {
        if let Some(e) = self.deferred.take() {
            return Err(e);
        }
        match self.mode {
            Mode::Execute { .. } => {
                self.flush()?;
                Ok(std::mem::take(&mut self.timings))
            }
            Mode::Record => Err(Error::InvalidArgument(
                "a recording batch ends with finish_recording()".into(),
            )),
            Mode::Count => Ok(Vec::new()),
        }
    }

    /// Ends a [`record_into`](Self::record_into) batch. The returned holder
    /// must live until the host's submission has completed.
    pub fn finish_recording(mut self) -> Result<Recorded> {
        if let Some(e) = self.deferred.take() {
            return Err(e);
        }
        // To every later command, and to the host: after the host's fence,
        // mcdenoise reads its outputs through mapped memory (`read_slice`),
        // which a fence wait alone does not make visible.
        self.global_barrier(
            vk::PipelineStageFlags::COMPUTE_SHADER | vk::PipelineStageFlags::TRANSFER,
            vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::TRANSFER_WRITE,
            vk::PipelineStageFlags::ALL_COMMANDS | vk::PipelineStageFlags::HOST,
            vk::AccessFlags::MEMORY_READ
                | vk::AccessFlags::MEMORY_WRITE
                | vk::AccessFlags::HOST_READ,
        );
        Ok(Recorded {
            ctx: self.ctx.clone(),
            used: self.used.drain().collect(),
            desc_pools: std::mem::take(&mut self.desc_pools),
            query_pools: std::mem::take(&mut self.query_pools),
            stamps: std::mem::take(&mut self.stamps),
            queries_used: self.queries_used,
        })
    }

    /// Keeps the first error of a call that returns nothing (`fill`,
    /// `copy`) for `finish` / `finish_recording`.
    fn defer(&mut self, e: Error) {
        self.deferred.get_or_insert(e);
    }
}

/// A failed Vulkan call while recording `kernel` (a descriptor or query
/// pool that cannot be made): an [`Error::Gpu`] naming the kernel.
fn recording(kernel: &str) -> impl FnOnce(Error) -> Error + '_ {
    move |e| match e {
        Error::Vulkan { call, result } => Error::Gpu {
            during: format!("the recording of kernel {kernel}"),
            call,
            result,
        },
        e => e,
    }
}

/// The checks every dispatch makes before recording: the binding count and
/// push size of the kernel's reflection, no binding above
/// `maxStorageBufferRange`, offsets aligned.
fn check_bindings(
    ctx: &GpuContext,
    decl: &KernelDecl,
    binding_count: u32,
    bindings: &[BufferSlice],
    push: &[u8],
) -> Result<()> {
    if bindings.len() as u32 != binding_count {
        return Err(Error::InvalidArgument(format!(
            "kernel {} takes {} bindings, got {}",
            decl.name,
            binding_count,
            bindings.len()
        )));
    }
    if push.len() as u32 != decl.push_size || push.len() < 12 {
        return Err(Error::InvalidArgument(format!(
            "kernel {}: push constants of {} bytes, expected {}",
            decl.name,
            push.len(),
            decl.push_size
        )));
    }
    let limit = ctx.info.max_storage_buffer_range as u64;
    let align = ctx.info.min_storage_buffer_offset_alignment.max(1);
    let word = |at: usize| u32::from_le_bytes(push[at..at + 4].try_into().unwrap()) as u64;
    let (width, height) = (word(0), word(4));
    for (i, (b, d)) in bindings.iter().zip(decl.bindings).enumerate() {
        if let Extent::Planes(n) = d.extent {
            let need = 4 * n as u64 * width * height;
            if b.size < need {
                return Err(Error::InvalidArgument(format!(
                    "kernel {} binding {i} ({}) holds {} bytes; {n} plane(s) of {width}×{height} \
                     need {need}",
                    decl.name, d.name, b.size
                )));
            }
        }
        if b.size > limit {
            return Err(Error::Limit(format!(
                "kernel {} binding {i} ({}) is {} bytes; maxStorageBufferRange is {limit}",
                decl.name, decl.bindings[i].name, b.size
            )));
        }
        if b.offset % align != 0 {
            return Err(Error::InvalidArgument(format!(
                "kernel {} binding {i} ({}) offset {} is not a multiple of {align}",
                decl.name, decl.bindings[i].name, b.offset
            )));
        }
    }
    Ok(())
}

impl Drop for Batch {
    fn drop(&mut self) {
        let dev = &self.ctx.device;
        if let Mode::Execute { fence } = self.mode {
            if self.pending {
                // A wait failed: wait again before destroying anything the
                // device may still use. A lost device runs nothing any more.
                let ns = u64::try_from(self.ctx.fence_timeout().as_nanos()).unwrap_or(u64::MAX);
                // SAFETY: the fence belongs to this device.
                match unsafe { dev.wait_for_fences(&[fence], true, ns) } {
                    Ok(()) | Err(vk::Result::ERROR_DEVICE_LOST) => self.pending = false,
                    Err(r) => {
                        log::error!(
                            "the device did not finish a submit ({r:?}): leaking its command pool, \
                             fence, descriptor sets and buffers rather than destroying them in use"
                        );
                        return;
                    }
                }
            }
            // SAFETY: every submit has completed (waited for in `flush` or
            // above), so nothing in flight uses these objects; null handles
            // (a constructor that failed half-way) are skipped.
            unsafe {
                if fence != vk::Fence::null() {
                    dev.destroy_fence(fence, None);
                    fault::destroyed(Object::Fence);
                }
                dev.destroy_command_pool(self.pool, None);
                fault::destroyed(Object::CommandPool);
            }
        }
        // Record mode: the pools were moved to `Recorded` (finish_recording),
        // or the host abandons the recording and must not submit it.
        self.ctx
            .recycle_query_pools(std::mem::take(&mut self.query_pools));
        self.ctx
            .recycle_desc_pools(std::mem::take(&mut self.desc_pools));
        let used: Vec<vk::Buffer> = self.used.drain().collect();
        self.ctx.release(&used);
    }
}

/// What a recording batch leaves behind: descriptor sets and timestamp
/// queries used by the host's command buffer. Keep it until that work has
/// completed; then read [`timings`](Self::timings) and drop it.
#[must_use = "dropping Recorded before the host's submission completed frees what its commands use"]
pub struct Recorded {
    ctx: Arc<GpuContext>,
    used: Vec<vk::Buffer>,
    desc_pools: Vec<vk::DescriptorPool>,
    query_pools: Vec<vk::QueryPool>,
    stamps: Vec<Stamp>,
    queries_used: u32,
}

impl Recorded {
    /// Per-dispatch GPU times. Call only after the host's submission completed.
    pub fn timings(&self) -> Result<Vec<KernelTiming>> {
        // SAFETY: the caller guarantees the work has completed.
        let values = unsafe { query_results(&self.ctx, &self.query_pools, self.queries_used)? };
        let period = self.ctx.info.timestamp_period_ns as f64;
        Ok(self
            .stamps
            .iter()
            .map(|s| timing(s.clone(), &values, period))
            .collect())
    }
}

impl Drop for Recorded {
    fn drop(&mut self) {
        // The host's work using these pools has completed (contract).
        self.ctx
            .recycle_query_pools(std::mem::take(&mut self.query_pools));
        self.ctx
            .recycle_desc_pools(std::mem::take(&mut self.desc_pools));
        self.ctx.release(&self.used);
    }
}

/// Copies `size` bytes between buffers and waits (used for staging).
pub(crate) fn copy_regions(
    ctx: &Arc<GpuContext>,
    what: String,
    src: vk::Buffer,
    dst: vk::Buffer,
    regions: &[vk::BufferCopy],
) -> Result<()> {
    let mut b = Batch::new(ctx)?;
    b.note(what);
    // SAFETY: cmd recording; ranges checked by the callers.
    unsafe { ctx.device.cmd_copy_buffer(b.cmd, src, dst, regions) };
    b.barrier();
    b.finish().map(|_| ())
}
