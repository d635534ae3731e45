/* mcdenoise: C API. Generated from capi/src/lib.rs by cbindgen (capi/build.rs); do not edit. */

#ifndef MCDENOISE_H
#define MCDENOISE_H

#include <stdint.h>
#include <vulkan/vulkan.h>

// The version of this API; a host checks [`mcd_api_version`] against the
// header's `MCDENOISE_API_VERSION` at run time.
#define MCDENOISE_API_VERSION 1

// Flag of [`McdDenoiserDesc::flags`]: every pixel has 0 or at least 2
// samples, which skips the one-sample variance repair (§0.4 step 3).
#define MCD_FLAG_NO_SINGLE_SAMPLE_PIXELS 1

// Flag of [`McdDenoiserDesc::flags`]: the adaptive pass's smaller windows
// (§9.3) instead of the final reconstruction's. For a final image by LP,
// APR, AOS or `auto`, the built-in loop makes its adaptive passes with
// WLR, whose maps served them better than their own on its scenes, or
// as well for less time (decision records MAP-WLR, AUTO-MAPS).
#define MCD_FLAG_ADAPTIVE_PASS 2

// Flag of [`McdDenoiserDesc::flags`]: the LP temporal filter (§10.1)
// after the method. Each recording is the next frame of a sequence: the
// filter's state stays in the denoiser's buffers from one to the next
// ([`mcd_denoiser_reset`] at a cut). Needs the layout's position sums.
#define MCD_FLAG_TEMPORAL_LP 4

// Flag of [`McdDenoiserDesc::flags`]: the pyramid's low band after the
// method (PYRAMID-LOWBAND): the method also reconstructs the statistics
// pooled 2×2, and the output takes its low band from that
// half-resolution reconstruction where the error estimates favour it.
// Not for `MCD_METHOD_NONE` or images under 16×16 pixels. Without this
// flag or [`MCD_FLAG_NO_PYRAMID`], the stage runs after `MCD_METHOD_AUTO`
// on images of at least 16×16 pixels and after no other method.
#define MCD_FLAG_PYRAMID 8

// Flag of [`McdDenoiserDesc::flags`]: never the pyramid's low band (see
// [`MCD_FLAG_PYRAMID`]); both flags together are an error.
#define MCD_FLAG_NO_PYRAMID 16

// Flag of [`McdDenoiserDesc::flags`]: the input blend after the method
// (INPUT-BLEND): each pixel's output is the method's and the input's,
// weighed by the method's error estimate (read as at least what the
// residual shows, BLEND-RESIDUAL) and the input's variance. Not for
// `MCD_METHOD_NONE`. Without this flag or [`MCD_FLAG_NO_INPUT_BLEND`], the
// stage runs in a final reconstruction after every method but
// `MCD_METHOD_AUTO`.
#define MCD_FLAG_INPUT_BLEND 32

// Flag of [`McdDenoiserDesc::flags`]: never the input blend (see
// [`MCD_FLAG_INPUT_BLEND`]); both flags together are an error.
#define MCD_FLAG_NO_INPUT_BLEND 64

// Flag of [`McdDenoiserDesc::flags`], with [`MCD_FLAG_ADAPTIVE_PASS`]: the
// sample map from a half-resolution reconstruction (MAP-COARSE). The
// method runs on the statistics pooled over 2×2 blocks only, about a
// quarter of its work, and each pixel takes its block's priority; the
// denoiser's colour and error outputs are then the input's mean and
// variance. Not for `MCD_METHOD_NONE`, images under 16×16 pixels, the
// temporal filter, or with [`MCD_FLAG_PYRAMID`] or
// [`MCD_FLAG_INPUT_BLEND`].
#define MCD_FLAG_COARSE_MAP 128

// What a call returned.
typedef enum McdStatus {
  // Success.
  MCD_STATUS_OK = 0,
  // A null pointer, a size that does not match, an unknown method or
  // option, a call that does not apply (a sample map that was not made).
  MCD_STATUS_INVALID_ARGUMENT = 1,
  // Device or host memory ran out; the context stays usable.
  MCD_STATUS_OUT_OF_MEMORY = 2,
  // The device was lost or a submission timed out: make a new context.
  MCD_STATUS_DEVICE_LOST = 3,
  // The device lacks a feature, or a limit is exceeded.
  MCD_STATUS_UNSUPPORTED = 4,
  // A Vulkan call failed.
  MCD_STATUS_VULKAN = 5,
  // Anything else, including a panic caught at the boundary (a bug).
  MCD_STATUS_INTERNAL = 6,
} McdStatus;

// The reconstruction method (spec sections in `docs/algorithms.md`).
typedef enum McdMethod {
  // Weighted local regression (§2); the default.
  MCD_METHOD_WLR = 0,
  // Linear predictions (§3).
  MCD_METHOD_LP = 1,
  // Adaptive polynomial rendering (§4).
  MCD_METHOD_APR = 2,
  // Adaptive-order polynomial fitting (§5).
  MCD_METHOD_AOS = 3,
  // No reconstruction: the sanitised mean.
  MCD_METHOD_NONE = 4,
  // WLR, LP and APR (and AOS with the option `auto.aos=on`) blended per
  // pixel by their error estimates.
  MCD_METHOD_AUTO = 5,
} McdMethod;

// A context: mcdenoise's allocator, pipelines and command pool on the
// host's device.
typedef struct McdContext McdContext;

// A denoiser for one image size and configuration.
typedef struct McdDenoiser McdDenoiser;

// Work recorded into a host command buffer: keeps the denoiser's buffers
// alive until the host releases it after its submission completed.
typedef struct McdRecording McdRecording;

// The two-way temporal filter (TEMPORAL-SMOOTH) for offline sequences: the
// frames of a denoiser with [`MCD_FLAG_TEMPORAL_LP`], kept one by one, are
// filtered again in reverse order at the end and the two directions
// combined per pixel, so every frame's reconstruction sees the frames
// before and after it.
typedef struct McdSmoother McdSmoother;

// The accumulation layout the host's shaders write
// (`include/mcdenoise_accum.glsl`).
typedef struct McdAccumLayout {
  // Image width in pixels.
  uint32_t width;
  // Image height in pixels.
  uint32_t height;
  // Non-zero if positions are accumulated (`MCDENOISE_ACCUM_POSITION`).
  uint32_t position;
  // Non-zero if visibility is accumulated (`MCDENOISE_ACCUM_VISIBILITY`).
  uint32_t visibility;
  // The point positions are accumulated relative to (finite). A
  // denoiser finalises every frame with the origin it was made with:
  // keep one for all the frames a temporal denoiser filters.
  float position_origin[3];
} McdAccumLayout;

// The host's Vulkan objects. mcdenoise creates and destroys only its own
// objects on `device`; the host destroys the device and the instance after
// every mcdenoise object.
typedef struct McdVulkanDevice {
  // The host's instance.
  VkInstance instance;
  // The physical device `device` was created from.
  VkPhysicalDevice physical_device;
  // The host's logical device.
  VkDevice device;
  // A queue of `queue_family_index` (used only by calls that submit, none
  // of this API's today).
  VkQueue queue;
  // A queue family with compute; the host's command buffers handed to
  // [`mcd_denoiser_record`] come from a pool of this family.
  uint32_t queue_family_index;
  // The loader's `vkGetInstanceProcAddr` the instance was made with.
  PFN_vkGetInstanceProcAddr get_instance_proc_addr;
  // Non-zero if the host enabled `shaderFloat64` on `device`.
  uint32_t shader_float64_enabled;
  // Non-zero if the host enabled `shaderInt64` on `device` (no kernel
  // needs it today).
  uint32_t shader_int64_enabled;
} McdVulkanDevice;

// One denoiser's configuration: fixed for its life.
typedef struct McdDenoiserDesc {
  // The accumulation buffer's layout (and so the image size).
  struct McdAccumLayout layout;
  // The method: an [`McdMethod`] value (an unknown one is an error).
  uint32_t method;
  // `MCD_FLAG_*` bits.
  uint32_t flags;
  // Method options, `key=value` separated by spaces as
  // `mcdenoise denoise --help` lists them; NULL or "" for none.
  const char *options;
} McdDenoiserDesc;

// The denoiser's GPU-resident outputs: planes of `width × height` values in
// row-major order, each a range of a `VkBuffer` the denoiser owns, valid
// until the denoiser is destroyed and overwritten by each recording.
typedef struct McdOutputs {
  // Reconstructed colour R, G, B (f32 planes).
  VkBuffer color_buffer[3];
  // Byte offsets of the colour planes in their buffers.
  uint64_t color_offset[3];
  // Estimated mean squared error per channel (f32 planes).
  VkBuffer error_buffer[3];
  // Byte offsets of the error planes.
  uint64_t error_offset[3];
  // Bytes of one f32 plane (`4 × width × height`).
  uint64_t plane_bytes;
  // The next pass's samples per pixel (u32), after a recording with a
  // budget (every device makes it).
  VkBuffer samples_buffer;
  // Byte offset of the sample map.
  uint64_t samples_offset;
} McdOutputs;

// Receives one frame of [`mcd_smoother_finish`]: `user` as given, the
// frame's index in the sequence (0 for the first kept), its
// reconstruction as `pixels` RGB triples (interleaved f32, row-major,
// valid during the call only). Returns 0 to go on; anything else stops
// the finish with `MCD_STATUS_INVALID_ARGUMENT`.
typedef int32_t (*McdFrameFn)(void *user, uint64_t frame, const float *color, uint64_t pixels);

#ifdef __cplusplus
extern "C" {
#endif // __cplusplus

// The version of the library: compare with `MCDENOISE_API_VERSION`.
uint32_t mcd_api_version(void);

// The message of the last failed call on this thread ("" after a
// success). Valid until the next mcdenoise call on this thread.
const char *mcd_last_error(void);

// Bytes of the accumulation buffer for `layout` (0 for an invalid layout).
//
// # Safety
// `layout` is null or points to a valid [`McdAccumLayout`].
uint64_t mcd_accum_bytes(const struct McdAccumLayout *layout);

// Bytes from one accumulation plane's start to the next (the GLSL header's
// `4 * mcd_plane_stride(width * height)`); 0 for an invalid layout.
//
// # Safety
// `layout` is null or points to a valid [`McdAccumLayout`].
uint64_t mcd_accum_plane_stride(const struct McdAccumLayout *layout);

// Number of planes of the accumulation layout; 0 for an invalid layout.
//
// # Safety
// `layout` is null or points to a valid [`McdAccumLayout`].
uint32_t mcd_accum_plane_count(const struct McdAccumLayout *layout);

// Creates a context on the host's device.
//
// # Safety
// `device` points to a valid [`McdVulkanDevice`] whose handles satisfy its
// field documentation: `device` was created from `physical_device` of
// `instance`, `queue` belongs to `queue_family_index`, which supports
// compute, the 64-bit flags are non-zero only if those features were
// enabled, and the instance and device outlive every mcdenoise object made
// from this context. `out` is valid for a write.
enum McdStatus mcd_context_create(const struct McdVulkanDevice *device, struct McdContext **out);

// Destroys a context (NULL is ignored). Its objects on the device live
// until the last denoiser made from it is destroyed too.
//
// # Safety
// `ctx` is NULL or a context from [`mcd_context_create`] not destroyed yet.
void mcd_context_destroy(struct McdContext *ctx);

// Builds the context's pipelines through a `VkPipelineCache` kept in the
// file `path` (UTF-8, NUL-terminated): loaded now (a missing file, or one
// of another device or driver, starts empty) and written back atomically
// when the context is destroyed if pipelines were built meanwhile, or by
// [`mcd_context_save_pipeline_cache`]. Call before creating denoisers.
// `loaded_bytes` (may be NULL) receives the bytes loaded.
//
// # Safety
// `ctx` is live, `path` a NUL-terminated string, `loaded_bytes` NULL or
// valid for a write.
enum McdStatus mcd_context_use_pipeline_cache(const struct McdContext *ctx, const char *path, uint64_t *loaded_bytes);

// Writes the context's pipeline cache to its file now; `saved_bytes` (may
// be NULL) receives the bytes written (0 without a cache).
//
// # Safety
// `ctx` is live, `saved_bytes` NULL or valid for a write.
enum McdStatus mcd_context_save_pipeline_cache(const struct McdContext *ctx, uint64_t *saved_bytes);

// Creates a denoiser: builds its pipelines and allocates its buffers.
//
// # Safety
// `ctx` is a live context, `desc` points to a valid [`McdDenoiserDesc`]
// (its `options` NULL or a NUL-terminated string), `out` is valid for a
// write.
enum McdStatus mcd_denoiser_create(const struct McdContext *ctx, const struct McdDenoiserDesc *desc, struct McdDenoiser **out);

// Forgets the temporal filter's history ([`MCD_FLAG_TEMPORAL_LP`]): the
// next recording reinitialises every pixel, as at a sequence's first
// frame. Call it at a cut. Nothing for a denoiser without the filter.
//
// # Safety
// `denoiser` is a live denoiser from [`mcd_denoiser_create`].
enum McdStatus mcd_denoiser_reset(const struct McdDenoiser *denoiser);

// Destroys a denoiser (NULL is ignored). Buffers that recordings not yet
// released still bind stay alive until those are released.
//
// # Safety
// `denoiser` is NULL or a live denoiser from [`mcd_denoiser_create`].
void mcd_denoiser_destroy(struct McdDenoiser *denoiser);

// Records the whole chain into the host's command buffer `cmd`:
// finalisation of the accumulation buffer (`accum` from byte
// `accum_offset`, [`mcd_accum_bytes`] long), sanitation, prefilter, the
// method, its error estimate and, when `sample_budget` > 0, the next
// pass's sample map spending exactly `sample_budget` samples. Nothing is
// submitted. The work starts with a barrier after every earlier command of
// `cmd` and ends with one before every later command.
//
// `queue_family` is the family of the pool `cmd` came from; one other than
// the context's is `MCD_STATUS_INVALID_ARGUMENT` before anything is recorded (the
// denoiser's buffers belong to the context's family).
//
// On success `*out` holds a recording the host releases
// ([`mcd_recording_release`]) once the submission of `cmd` completed (or
// if `cmd` is never submitted). On failure the host must discard `cmd`
// (reset or free it without submitting): part of the chain may be in it.
//
// # Safety
// `denoiser` is live; `cmd` belongs to the context's device, comes from a
// pool of queue family `queue_family`, is recording and outside a render
// pass; `accum` is a buffer of that device with storage-buffer and
// transfer-source usage (finalisation copies its count plane) and at least `accum_offset + mcd_accum_bytes(layout)` bytes, not written by
// other work while this work runs; `out` is valid for a write. No other
// recording of this denoiser runs on the GPU at the same time.
enum McdStatus mcd_denoiser_record(const struct McdDenoiser *denoiser, VkCommandBuffer cmd, uint32_t queue_family, VkBuffer accum, uint64_t accum_offset, uint32_t sample_budget, struct McdRecording **out);

// Denoises accumulation sums in host memory, for a renderer that
// accumulates on the CPU: `sums` holds `bytes` = [`mcd_accum_bytes`] of
// the denoiser's layout, the planes exactly as `include/mcdenoise_accum.glsl`
// lays them out in a device buffer ([`mcd_accum_plane_stride`] apart).
// mcdenoise copies them to a device buffer of its own (kept for the next
// call), submits the whole chain to the context's queue and waits; then
// [`mcd_denoiser_read`] copies the results to host memory. `sample_budget`
// as for [`mcd_denoiser_record`]. The results are those of
// [`mcd_denoiser_record`] on a device buffer holding the same bytes.
//
// # Safety
// `denoiser` is live; `sums` is valid for reads of `bytes` bytes. The
// context's queue is not used by the host during the call.
enum McdStatus mcd_denoiser_run_host(const struct McdDenoiser *denoiser, const void *sums, uint64_t bytes, uint32_t sample_budget);

// Releases a recording (NULL is ignored), after the submission of its
// command buffer completed or once the buffer was discarded.
//
// # Safety
// `recording` is NULL or a live recording from [`mcd_denoiser_record`].
void mcd_recording_release(struct McdRecording *recording);

// The denoiser's GPU-resident outputs, for binding in the host's shaders
// (its next pass reads the sample map).
//
// # Safety
// `denoiser` is live and `out` valid for a write.
enum McdStatus mcd_denoiser_outputs(const struct McdDenoiser *denoiser, struct McdOutputs *out);

// Copies the outputs of the last completed recording to host memory:
// `color` and `error` get `width × height` RGB triples (interleaved f32,
// row-major), `samples` the next pass's samples per pixel. Any of them may
// be NULL (not copied); `pixels` is the length in pixels of those given
// and must equal `width × height`. Call only after the submission of the
// recording completed. A non-NULL `samples` after a recording without a
// budget is an error.
//
// # Safety
// `denoiser` is live; each non-NULL pointer is valid for writes of
// `pixels` (`samples`) or `3 * pixels` (`color`, `error`) values.
enum McdStatus mcd_denoiser_read(const struct McdDenoiser *denoiser, float *color, float *error, uint32_t *samples, uint64_t pixels);

// Creates the two-way filter for the frames of `denoiser`, which must have
// [`MCD_FLAG_TEMPORAL_LP`] and not [`MCD_FLAG_ADAPTIVE_PASS`]. The kept
// frames go to an unnamed temporary file in `$TMPDIR` (72 bytes per pixel
// and frame), not to the host's memory.
//
// # Safety
// `ctx` is the live context of `denoiser`, a live denoiser; `out` is
// valid for a write.
enum McdStatus mcd_smoother_create(const struct McdContext *ctx, const struct McdDenoiser *denoiser, struct McdSmoother **out);

// Keeps the frame `denoiser` (the smoother's) just reconstructed: call it
// after the submission of each recording of the sequence completed, every
// frame in order, the first right after [`mcd_denoiser_reset`] (or the
// denoiser's first recording). A frame skipped, or a reset within the
// sequence, is `MCD_STATUS_INVALID_ARGUMENT` and keeps nothing.
//
// # Safety
// `smoother` and `denoiser` are live; no recording of `denoiser` is
// running on the GPU.
enum McdStatus mcd_smoother_keep(struct McdSmoother *smoother, const struct McdDenoiser *denoiser);

// Ends the sequence: hands every kept frame's two-way reconstruction to
// `each`, last frame first, one at a time. The kept frames are dropped
// (also on an error or when `each` stops); the next keep starts a new
// sequence, after [`mcd_denoiser_reset`]. `*frames`, if `frames` is not
// NULL, gets the number of frames handed over.
//
// # Safety
// `smoother` is live; `each` is safe to call with `user`; `frames` is NULL
// or valid for a write.
enum McdStatus mcd_smoother_finish(struct McdSmoother *smoother, McdFrameFn each, void *user, uint64_t *frames);

// Destroys a smoother (NULL is ignored), with its kept frames.
//
// # Safety
// `smoother` is NULL or a live smoother from [`mcd_smoother_create`].
void mcd_smoother_destroy(struct McdSmoother *smoother);

#ifdef __cplusplus
}  // extern "C"
#endif  // __cplusplus

#endif  /* MCDENOISE_H */
