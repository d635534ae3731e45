//! Named storage buffers, upload and download.

use std::sync::Arc;

use ash::vk;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};
use gpu_allocator::MemoryLocation;

use super::context::GpuContext;
use crate::error::{Error, Result};
use crate::fault::{self, Call, Object};

/// A range of a storage buffer, as a kernel binding sees it. Host-owned
/// buffers (the embedding path) are passed this way too.
///
/// Made by [`GpuBuffer::slice`], [`GpuBuffer::range`] and
/// [`PlaneSet::plane`] (checked against the buffer), by [`BufferSlice::sub`]
/// (checked against the parent range), or for a host's buffer by the `unsafe`
/// [`BufferSlice::from_raw`]. Safe code therefore cannot name a range outside
/// its buffer. A slice is a copyable handle, so it can outlive the
/// [`GpuBuffer`] it came from (or the [`Denoiser`](crate::Denoiser) whose
/// [`outputs`](crate::Denoiser::outputs) it is): every use checks that its
/// buffer is still alive (a [`Batch`](super::Batch) binding, fill or copy,
/// a read) and fails with [`Error::InvalidArgument`] instead of touching a
/// destroyed buffer.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct BufferSlice {
    pub(crate) buffer: vk::Buffer,
    /// Byte offset; a multiple of the device's `minStorageBufferOffsetAlignment`.
    pub(crate) offset: u64,
    /// Byte size of the range.
    pub(crate) size: u64,
    /// The [`GpuBuffer`]'s unique id (never reused), checked against the
    /// context's live buffers at every use; 0 for a host's buffer
    /// ([`BufferSlice::from_raw`], whose contract covers its life).
    pub(crate) id: u64,
}

/// Ids of [`GpuBuffer`]s, unique in the process (0 is a host's buffer).
static NEXT_BUFFER_ID: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);

impl BufferSlice {
    /// A range of a buffer mcdenoise does not own (a host renderer's).
    ///
    /// # Safety
    /// `buffer` is a buffer of the device of the context the slice is used
    /// with, created with `STORAGE_BUFFER` usage (plus `TRANSFER_SRC` /
    /// `TRANSFER_DST` where mcdenoise copies from or fills it: an
    /// accumulation buffer needs `TRANSFER_SRC`, finalisation copies its
    /// count plane), bound to
    /// memory; `offset + size` does not exceed its size; and it stays alive
    /// until every piece of work recorded with the slice has completed.
    pub unsafe fn from_raw(buffer: vk::Buffer, offset: u64, size: u64) -> BufferSlice {
        BufferSlice {
            buffer,
            offset,
            size,
            id: 0,
        }
    }

    /// A stand-in of `size` bytes for recording into a counting
    /// [`Batch`](super::Batch), which binds nothing; any real use of it is
    /// refused (its id is never live).
    pub(crate) fn placeholder(size: u64) -> BufferSlice {
        BufferSlice {
            buffer: vk::Buffer::null(),
            offset: 0,
            size,
            id: u64::MAX,
        }
    }

    /// The raw buffer handle.
    pub fn buffer(&self) -> vk::Buffer {
        self.buffer
    }

    /// Byte offset of the range in its buffer.
    pub fn offset(&self) -> u64 {
        self.offset
    }

    /// Byte size of the range.
    pub fn size(&self) -> u64 {
        self.size
    }

    /// The sub-range `[offset, offset + size)` of this range; an error if it
    /// does not fit.
    pub fn sub(&self, offset: u64, size: u64) -> Result<BufferSlice> {
        match offset.checked_add(size) {
            Some(end) if end <= self.size => Ok(BufferSlice {
                buffer: self.buffer,
                offset: self.offset + offset,
                size,
                id: self.id,
            }),
            _ => Err(Error::InvalidArgument(format!(
                "range [{offset}, {offset}+{size}) does not fit a buffer range of {} bytes",
                self.size
            ))),
        }
    }
}

/// A storage buffer owned by mcdenoise, freed on drop.
pub struct GpuBuffer {
    ctx: Arc<GpuContext>,
    name: String,
    buffer: vk::Buffer,
    allocation: Option<Allocation>,
    size: u64,
    /// Unique in the process; registered in the context's live set while
    /// the buffer lives (see [`BufferSlice`]).
    id: u64,
}

impl std::fmt::Debug for GpuBuffer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "GpuBuffer({:?}, {} bytes)", self.name, self.size)
    }
}

impl GpuBuffer {
    /// A device-local storage buffer of `size` bytes (at least 4), named for
    /// debuggers and leak reports. Its contents are undefined until written.
    pub fn new(ctx: &Arc<GpuContext>, name: &str, size: u64) -> Result<GpuBuffer> {
        Self::with_location(ctx, name, size, MemoryLocation::GpuOnly)
    }

    fn with_location(
        ctx: &Arc<GpuContext>,
        name: &str,
        size: u64,
        location: MemoryLocation,
    ) -> Result<GpuBuffer> {
        ctx.check_alive()?;
        let size = size.max(4);
        let info = vk::BufferCreateInfo::default()
            .size(size)
            .usage(
                vk::BufferUsageFlags::STORAGE_BUFFER
                    | vk::BufferUsageFlags::TRANSFER_SRC
                    | vk::BufferUsageFlags::TRANSFER_DST
                    | vk::BufferUsageFlags::INDIRECT_BUFFER,
            )
            .sharing_mode(vk::SharingMode::EXCLUSIVE);
        // SAFETY: valid create info on a live device; destroyed in Drop.
        let buffer = fault::vk(Call::CreateBuffer)
            .and_then(|()| unsafe { ctx.device.create_buffer(&info, None) })
            .map_err(Error::vk("vkCreateBuffer"))?;
        fault::created(Object::Buffer);
        let reqs = unsafe { ctx.device.get_buffer_memory_requirements(buffer) };
        let alloc = match fault::vk(Call::Allocate) {
            Err(r) => Err(super::context::allocation_error(r)),
            Ok(()) => ctx
                .allocator
                .lock()
                .unwrap()
                .as_mut()
                .expect("allocator alive while the context is")
                .allocate(&AllocationCreateDesc {
                    name,
                    requirements: reqs,
                    location,
                    linear: true,
                    allocation_scheme: AllocationScheme::GpuAllocatorManaged,
                }),
        };
        let allocation = match alloc {
            Ok(a) => a,
            Err(source) => {
                ctx.retire_buffer(buffer, None);
                return Err(Error::Allocation {
                    name: name.to_owned(),
                    bytes: size,
                    source,
                });
            }
        };
        fault::created(Object::Allocation);
        // SAFETY: memory comes from this device and fits the requirements.
        if let Err(e) = unsafe {
            ctx.device
                .bind_buffer_memory(buffer, allocation.memory(), allocation.offset())
        } {
            ctx.retire_buffer(buffer, Some(allocation));
            return Err(Error::vk("vkBindBufferMemory")(e));
        }
        ctx.name_object(buffer, name);
        ctx.count_allocation(size);
        let id = NEXT_BUFFER_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        ctx.live.lock().unwrap().insert(id);
        let b = GpuBuffer {
            ctx: ctx.clone(),
            name: name.to_owned(),
            buffer,
            allocation: Some(allocation),
            size,
            id,
        };
        // Only coherent mappings: a direct read then needs no invalidation.
        if let Some(ptr) = b.coherent_mapping() {
            ctx.mapped
                .lock()
                .unwrap()
                .insert(buffer, (ptr.as_ptr() as usize, size));
        }
        Ok(b)
    }

    /// A buffer holding `data`.
    pub fn from_slice<T: bytemuck::Pod>(
        ctx: &Arc<GpuContext>,
        name: &str,
        data: &[T],
    ) -> Result<GpuBuffer> {
        let b = Self::new(ctx, name, std::mem::size_of_val(data) as u64)?;
        b.upload(0, bytemuck::cast_slice(data))?;
        Ok(b)
    }

    /// The host address of the buffer's memory when it is mapped and
    /// coherent: then uploads and downloads copy directly, with no flush or
    /// invalidation. Otherwise they go through a staging buffer.
    fn coherent_mapping(&self) -> Option<std::ptr::NonNull<std::ffi::c_void>> {
        let a = self.allocation.as_ref()?;
        let coherent = a
            .memory_properties()
            .contains(vk::MemoryPropertyFlags::HOST_COHERENT);
        a.mapped_ptr().filter(|_| coherent)
    }

    /// A staging buffer must be coherently mapped: its own transfers are
    /// direct (else they would stage again).
    fn check_staging(&self) -> Result<()> {
        match self.coherent_mapping() {
            Some(_) => Ok(()),
            None => Err(Error::Limit(format!(
                "{}: the device offers no host-visible, host-coherent memory for staging",
                self.name
            ))),
        }
    }

    /// The debug name given at creation (also the Vulkan object name).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Size in bytes (at least 4: an empty buffer is given one word).
    pub fn size(&self) -> u64 {
        self.size
    }

    /// The raw `vk::Buffer`, for binding it in a host's own work; the handle stays
    /// owned by this `GpuBuffer`.
    pub fn raw(&self) -> vk::Buffer {
        self.buffer
    }

    /// The whole buffer as a binding.
    pub fn slice(&self) -> BufferSlice {
        BufferSlice {
            buffer: self.buffer,
            offset: 0,
            size: self.size,
            id: self.id,
        }
    }

    /// A byte range of the buffer as a binding.
    pub fn range(&self, offset: u64, size: u64) -> BufferSlice {
        assert!(
            offset.checked_add(size).is_some_and(|end| end <= self.size),
            "{}: range out of bounds",
            self.name
        );
        BufferSlice {
            buffer: self.buffer,
            offset,
            size,
            id: self.id,
        }
    }

    /// Writes `bytes` at byte `offset` (blocking; the GPU must not be using the
    /// buffer). Direct copy when the memory is mapped, else through a staging
    /// buffer of at most [`STAGING_CHUNK`] bytes.
    pub fn upload(&self, offset: u64, bytes: &[u8]) -> Result<()> {
        self.upload_regions(&[(offset, bytes)])
    }

    /// Writes each `(byte offset, bytes)` region (blocking; the GPU must not be
    /// using the buffer): direct copies when the memory is mapped, else
    /// through one staging buffer of at most [`STAGING_CHUNK`] bytes, filled
    /// and copied chunk by chunk. No region is copied on the host first.
    pub fn upload_regions(&self, regions: &[(u64, &[u8])]) -> Result<()> {
        for &(offset, bytes) in regions {
            if !fits(offset, bytes.len(), self.size) {
                return Err(Error::InvalidArgument(format!(
                    "upload of {} bytes at {offset} exceeds buffer {} ({} bytes)",
                    bytes.len(),
                    self.name,
                    self.size
                )));
            }
        }
        if let Some(ptr) = self.coherent_mapping() {
            for &(offset, bytes) in regions {
                // SAFETY: the mapping covers the allocation; range checked above.
                unsafe {
                    std::ptr::copy_nonoverlapping(
                        bytes.as_ptr(),
                        (ptr.as_ptr() as *mut u8).add(offset as usize),
                        bytes.len(),
                    )
                };
            }
            return Ok(());
        }
        let chunks = staging_chunks(regions.iter().map(|r| r.1.len()));
        let Some(size) = chunks.iter().map(|c| c.bytes()).max() else {
            return Ok(());
        };
        let staging = Self::with_location(
            &self.ctx,
            &format!("{}.staging_up", self.name),
            size,
            MemoryLocation::CpuToGpu,
        )?;
        staging.check_staging()?;
        let what = format!("the upload to {}", self.name);
        for chunk in &chunks {
            for p in &chunk.0 {
                staging.upload(p.staging, &regions[p.region].1[p.at..p.at + p.len])?;
            }
            let copies = chunk.copies(|p| (p.staging, regions[p.region].0 + p.at as u64));
            super::batch::copy_regions(
                &self.ctx,
                what.clone(),
                staging.buffer,
                self.buffer,
                &copies,
            )?;
        }
        Ok(())
    }

    /// Reads `out.len()` bytes from byte `offset` (blocking).
    pub fn download(&self, offset: u64, out: &mut [u8]) -> Result<()> {
        self.download_regions(&mut [(offset, out)])
    }

    /// Reads each `(byte offset, destination)` region (blocking): direct
    /// copies when the memory is mapped, else through one staging buffer of
    /// at most [`STAGING_CHUNK`] bytes, chunk by chunk.
    pub fn download_regions(&self, regions: &mut [(u64, &mut [u8])]) -> Result<()> {
        for (offset, out) in regions.iter() {
            if !fits(*offset, out.len(), self.size) {
                return Err(Error::InvalidArgument(format!(
                    "download of {} bytes at {offset} exceeds buffer {}",
                    out.len(),
                    self.name
                )));
            }
        }
        if let Some(ptr) = self.coherent_mapping() {
            for (offset, out) in regions.iter_mut() {
                // SAFETY: see upload_regions.
                unsafe {
                    std::ptr::copy_nonoverlapping(
                        (ptr.as_ptr() as *const u8).add(*offset as usize),
                        out.as_mut_ptr(),
                        out.len(),
                    )
                };
            }
            return Ok(());
        }
        staged_download(&self.ctx, &self.name, self.buffer, regions)
    }

    /// The whole buffer (or its first `count` elements) as a vector.
    pub fn read_vec<T: bytemuck::Pod + Default + Clone>(&self, count: usize) -> Result<Vec<T>> {
        let mut v = vec![T::default(); count];
        self.download(0, bytemuck::cast_slice_mut(&mut v))?;
        Ok(v)
    }
}

/// Reads `count` f32 values from `slice` (blocking). The GPU must not be
/// writing it. A range of a mapped [`GpuBuffer`] of this context is copied
/// directly; any other (device-local memory, a host's buffer) through a
/// host-visible staging buffer, waiting for the copy.
pub fn read_slice(ctx: &Arc<GpuContext>, slice: BufferSlice, count: usize) -> Result<Vec<f32>> {
    ctx.check_live(&[slice])?;
    let bytes = (count as u64).saturating_mul(4);
    if bytes > slice.size {
        return Err(Error::InvalidArgument(format!(
            "reading {count} values from a range of {} bytes",
            slice.size
        )));
    }
    let mut v = vec![0.0f32; count];
    // A lost device's memory holds nothing to read.
    ctx.check_alive()?;
    if fault::mapped_reads() {
        let mapped = ctx.mapped.lock().unwrap();
        if let Some(&(base, size)) = mapped.get(&slice.buffer) {
            if slice.offset + bytes <= size {
                // SAFETY: the buffer is alive while it is registered (its
                // Drop unregisters it under this lock before the memory
                // can be freed), the range lies inside its mapping, and
                // only coherent mappings are registered.
                unsafe {
                    std::ptr::copy_nonoverlapping(
                        (base as *const u8).add(slice.offset as usize),
                        v.as_mut_ptr() as *mut u8,
                        bytes as usize,
                    )
                };
                return Ok(v);
            }
        }
    }
    staged_download(
        ctx,
        "read_slice",
        slice.buffer,
        &mut [(slice.offset, bytemuck::cast_slice_mut(&mut v))],
    )?;
    Ok(v)
}

/// Largest staging buffer one upload or download allocates: bigger transfers
/// go through it in chunks, so a transfer never needs a second copy of its
/// data in memory.
pub const STAGING_CHUNK: u64 = 32 << 20;

/// Copies each `(byte offset in src, destination)` region of the device
/// buffer `src` to the host through one staging buffer of at most
/// [`STAGING_CHUNK`] bytes (`name` names it).
fn staged_download(
    ctx: &Arc<GpuContext>,
    name: &str,
    src: vk::Buffer,
    regions: &mut [(u64, &mut [u8])],
) -> Result<()> {
    let chunks = staging_chunks(regions.iter().map(|r| r.1.len()));
    let Some(size) = chunks.iter().map(|c| c.bytes()).max() else {
        return Ok(());
    };
    let staging = GpuBuffer::with_location(
        ctx,
        &format!("{name}.staging_down"),
        size,
        MemoryLocation::GpuToCpu,
    )?;
    staging.check_staging()?;
    let what = format!("the download from {name}");
    for chunk in &chunks {
        let copies = chunk.copies(|p| (regions[p.region].0 + p.at as u64, p.staging));
        super::batch::copy_regions(ctx, what.clone(), src, staging.buffer, &copies)?;
        for p in &chunk.0 {
            staging.download(p.staging, &mut regions[p.region].1[p.at..p.at + p.len])?;
        }
    }
    Ok(())
}

/// A piece of a staged transfer: bytes `[at, at + len)` of region `region`,
/// at byte `staging` of the staging buffer.
struct Piece {
    region: usize,
    at: usize,
    staging: u64,
    len: usize,
}

/// The pieces that fill the staging buffer once.
struct Chunk(Vec<Piece>);

impl Chunk {
    /// Bytes of the staging buffer the chunk uses.
    fn bytes(&self) -> u64 {
        self.0.last().map_or(0, |p| p.staging + p.len as u64)
    }

    /// One copy per piece, `(src, dst)` offsets from `ends`.
    fn copies(&self, ends: impl Fn(&Piece) -> (u64, u64)) -> Vec<vk::BufferCopy> {
        self.0
            .iter()
            .map(|p| {
                let (src, dst) = ends(p);
                vk::BufferCopy::default()
                    .src_offset(src)
                    .dst_offset(dst)
                    .size(p.len as u64)
            })
            .collect()
    }
}

/// Regions of `lens` bytes, in order, cut into chunks of at most
/// [`STAGING_CHUNK`] bytes (a region may span chunks); empty regions are
/// skipped, so no bytes give no chunk.
fn staging_chunks(lens: impl Iterator<Item = usize>) -> Vec<Chunk> {
    let mut chunks = Vec::new();
    let mut cur = Vec::new();
    let mut used = 0u64;
    for (region, len) in lens.enumerate() {
        let mut at = 0usize;
        while at < len {
            let n = (len - at).min((STAGING_CHUNK - used) as usize);
            cur.push(Piece {
                region,
                at,
                staging: used,
                len: n,
            });
            used += n as u64;
            at += n;
            if used == STAGING_CHUNK {
                chunks.push(Chunk(std::mem::take(&mut cur)));
                used = 0;
            }
        }
    }
    if !cur.is_empty() {
        chunks.push(Chunk(cur));
    }
    chunks
}

/// Whether `len` bytes at byte `offset` lie inside `size` bytes (no
/// overflow).
fn fits(offset: u64, len: usize, size: u64) -> bool {
    offset
        .checked_add(len as u64)
        .is_some_and(|end| end <= size)
}

impl Drop for GpuBuffer {
    fn drop(&mut self) {
        // No new use from here on: slices of this buffer fail their check.
        self.ctx.live.lock().unwrap().remove(&self.id);
        // Destroyed now, or when the last batch or `Recorded` that binds it
        // is done (see `GpuContext::retire_buffer`).
        self.ctx.count_free(self.size);
        // Unregistered before the memory can go: a read_slice holding the
        // lock finishes its copy first.
        self.ctx.mapped.lock().unwrap().remove(&self.buffer);
        self.ctx.retire_buffer(self.buffer, self.allocation.take());
    }
}

/// Planes of `width * height` f32 values packed in one buffer, each starting
/// at a multiple of [`PLANE_ALIGN`] bytes, so every plane can be bound on its
/// own (no binding grows with the number of channels). The buffer is the
/// set's own ([`PlaneSet::new`]) or shared with other sets whose lifetimes
/// within a recording do not overlap ([`PlaneSet::view`] of an arena).
#[derive(Debug)]
pub struct PlaneSet {
    buffer: Arc<GpuBuffer>,
    /// Where the first plane starts in the buffer (bytes).
    base: u64,
    /// Values per plane: the image's `width * height` pixels.
    pub pixels: usize,
    /// Number of planes.
    pub count: usize,
    /// Bytes from one plane's start to the next.
    pub stride: u64,
}

/// Alignment of planes inside a [`PlaneSet`] and of the accumulation layout:
/// 256 bytes, the largest `minStorageBufferOffsetAlignment` Vulkan allows.
pub const PLANE_ALIGN: u64 = 256;

/// Byte stride of a plane of `pixels` f32 values.
pub fn plane_stride(pixels: usize) -> u64 {
    ((pixels as u64 * 4).max(4)).div_ceil(PLANE_ALIGN) * PLANE_ALIGN
}

fn check_plane(ctx: &GpuContext, pixels: usize) -> Result<()> {
    let limit = ctx.info.max_storage_buffer_range as u64;
    if pixels as u64 * 4 > limit {
        return Err(Error::Limit(format!(
            "one plane of {pixels} pixels ({} bytes) exceeds maxStorageBufferRange ({limit} bytes)",
            pixels * 4
        )));
    }
    Ok(())
}

impl PlaneSet {
    /// `count` planes of `pixels` f32 values in one GPU-only buffer named `name`
    /// (`stride * count` bytes). Fails with [`Error::Limit`]
    /// if one plane exceeds `maxStorageBufferRange`.
    pub fn new(ctx: &Arc<GpuContext>, name: &str, pixels: usize, count: usize) -> Result<PlaneSet> {
        check_plane(ctx, pixels)?;
        let stride = plane_stride(pixels);
        let buffer = GpuBuffer::new(ctx, name, stride * count.max(1) as u64)?;
        Ok(PlaneSet {
            buffer: Arc::new(buffer),
            base: 0,
            pixels,
            count,
            stride,
        })
    }

    /// `count` planes of `pixels` f32 values inside `arena`, from byte
    /// `offset` (a multiple of [`PLANE_ALIGN`]): storage shared with other
    /// views whose contents are dead while this one is in use (the chain's
    /// stage scratch). Fails if they do not fit the arena.
    pub fn view(
        arena: &Arc<GpuBuffer>,
        offset: u64,
        pixels: usize,
        count: usize,
    ) -> Result<PlaneSet> {
        check_plane(&arena.ctx, pixels)?;
        let stride = plane_stride(pixels);
        let bytes = stride * count.max(1) as u64;
        if offset % PLANE_ALIGN != 0 || offset + bytes > arena.size() {
            return Err(Error::InvalidArgument(format!(
                "{}: {count} planes of {pixels} pixels at {offset} do not fit its {} bytes",
                arena.name(),
                arena.size()
            )));
        }
        Ok(PlaneSet {
            buffer: arena.clone(),
            base: offset,
            pixels,
            count,
            stride,
        })
    }

    /// Bytes of `count` planes of `pixels` values (what [`PlaneSet::view`]
    /// needs in an arena).
    pub fn bytes(pixels: usize, count: usize) -> u64 {
        plane_stride(pixels) * count.max(1) as u64
    }

    /// The name of the buffer the planes live in.
    pub fn name(&self) -> &str {
        self.buffer.name()
    }

    /// Every plane, as one binding (`stride * count` bytes).
    pub fn all(&self) -> BufferSlice {
        self.range(0, self.stride * self.count.max(1) as u64)
    }

    /// `size` bytes from byte `offset` of the set, as a binding.
    pub fn range(&self, offset: u64, size: u64) -> BufferSlice {
        assert!(
            offset + size <= self.stride * self.count.max(1) as u64,
            "{}: range {offset}+{size} outside the set",
            self.buffer.name()
        );
        self.buffer.range(self.base + offset, size)
    }

    /// Byte offset of plane `i` in the buffer.
    fn offset(&self, i: usize) -> u64 {
        self.base + i as u64 * self.stride
    }

    /// Plane `i` as a binding.
    pub fn plane(&self, i: usize) -> BufferSlice {
        assert!(
            i < self.count,
            "{}: plane {i} of {}",
            self.buffer.name(),
            self.count
        );
        self.buffer
            .range(self.offset(i), (self.pixels as u64 * 4).max(4))
    }

    /// Plane `i` as a binding of whole vec4s: its range rounded up to a
    /// multiple of 16 bytes (inside its stride), for a kernel that reads it
    /// four values at a time (`gbf_pack`); the values past `pixels` are not
    /// the plane's.
    pub fn plane_quads(&self, i: usize) -> BufferSlice {
        let p = self.plane(i);
        self.buffer.range(p.offset, p.size.div_ceil(16) * 16)
    }

    /// Writes plane `i` from `data`: `pixels` values of a 4-byte type (f32, u32).
    /// Blocking; the GPU must not be using the buffer. Panics on a wrong length.
    pub fn upload_plane<T: bytemuck::Pod>(&self, i: usize, data: &[T]) -> Result<()> {
        assert!(i < self.count);
        assert_eq!(std::mem::size_of_val(data), self.pixels * 4);
        self.buffer
            .upload(self.offset(i), bytemuck::cast_slice(data))
    }

    /// Reads plane `i` back as `pixels` values of a 4-byte type (f32, u32);
    /// blocking.
    pub fn download_plane<T: bytemuck::Pod + Default + Clone>(&self, i: usize) -> Result<Vec<T>> {
        assert!(i < self.count);
        let mut v = vec![T::default(); self.pixels];
        self.buffer
            .download(self.offset(i), bytemuck::cast_slice_mut(&mut v))?;
        Ok(v)
    }

    /// Every `step`-th f32 of plane `i` (values `0, step, 2·step, …`): the
    /// first component of a vec4 plane with `step = 4`. Read in chunks of at
    /// most 256 KiB, so the host never holds a copy of the whole plane.
    pub fn download_strided(&self, i: usize, step: usize) -> Result<Vec<f32>> {
        let mut out = Vec::with_capacity(self.pixels.div_ceil(step));
        self.for_each_strided(i, step, |v| out.push(v))?;
        Ok(out)
    }

    /// Calls `f` on every `step`-th f32 of plane `i`, in order, reading the
    /// plane in chunks of at most 256 KiB.
    fn for_each_strided(&self, i: usize, step: usize, mut f: impl FnMut(f32)) -> Result<()> {
        self.for_each_group(i, step, |g| f(g[0]))
    }

    /// Calls `f` on each group of `step` consecutive f32 of plane `i` (the
    /// last one possibly shorter), in order, reading the plane in chunks of
    /// at most 256 KiB: a vec4 plane's texels with `step` 4, no host copy
    /// of the plane.
    pub fn for_each_group(&self, i: usize, step: usize, mut f: impl FnMut(&[f32])) -> Result<()> {
        const CHUNK: usize = 1 << 16;
        // (A chunk holds whole steps.)
        assert!(i < self.count && step > 0 && step <= CHUNK);
        let mut buf = vec![0.0f32; CHUNK.min(self.pixels)];
        let mut start = 0;
        while start < self.pixels {
            // Chunks start at multiples of `step`.
            let len = (CHUNK - CHUNK % step).min(self.pixels - start);
            let b = &mut buf[..len];
            self.buffer.download(
                self.offset(i) + start as u64 * 4,
                bytemuck::cast_slice_mut(b),
            )?;
            b.chunks(step).for_each(&mut f);
            start += len;
        }
        Ok(())
    }

    /// Uploads all planes at once, each straight from its slice (no host
    /// copy of the set; see [`GpuBuffer::upload_regions`]).
    pub fn upload_all(&self, planes: &[&[f32]]) -> Result<()> {
        assert_eq!(planes.len(), self.count);
        let planes: Vec<(usize, &[f32])> = planes.iter().copied().enumerate().collect();
        self.upload_some(&planes)
    }

    /// Uploads plane `i` from `data` for each `(i, data)` (as
    /// [`upload_all`](Self::upload_all), for some of the planes).
    pub fn upload_some(&self, planes: &[(usize, &[f32])]) -> Result<()> {
        let regions: Vec<(u64, &[u8])> = planes
            .iter()
            .map(|&(i, p)| {
                assert!(i < self.count);
                assert_eq!(p.len(), self.pixels);
                (self.offset(i), bytemuck::cast_slice(p))
            })
            .collect();
        self.buffer.upload_regions(&regions)
    }

    /// Downloads all planes at once, each straight into its vector.
    pub fn download_all(&self) -> Result<Vec<Vec<f32>>> {
        let mut out = vec![vec![0.0f32; self.pixels]; self.count];
        let mut regions: Vec<(u64, &mut [u8])> = out
            .iter_mut()
            .enumerate()
            .map(|(i, p)| (self.offset(i), bytemuck::cast_slice_mut(p.as_mut_slice())))
            .collect();
        self.buffer.download_regions(&mut regions)?;
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::{staging_chunks, STAGING_CHUNK};

    /// Every byte of every region lands once, in order, in chunks that fill
    /// the staging buffer from 0 and never pass it.
    #[test]
    fn staging_chunks_cover_every_region_once() {
        let c = STAGING_CHUNK as usize;
        let lens = [c / 2 + 3, 0, c + c / 3, 5, c - 8];
        let chunks = staging_chunks(lens.iter().copied());
        let mut next = vec![0usize; lens.len()];
        let mut region = 0;
        for chunk in &chunks {
            let mut staging = 0u64;
            for p in &chunk.0 {
                assert_eq!(p.staging, staging);
                assert!(p.len > 0);
                while next[region] == lens[region] {
                    region += 1;
                }
                assert_eq!((p.region, p.at), (region, next[region]));
                next[region] += p.len;
                staging += p.len as u64;
            }
            assert!(chunk.bytes() <= STAGING_CHUNK && chunk.bytes() == staging);
        }
        assert_eq!(next, lens);
        let total: usize = lens.iter().sum();
        assert_eq!(chunks.len(), total.div_ceil(c));
        assert!(staging_chunks([0usize, 0].into_iter()).is_empty());
    }
}
