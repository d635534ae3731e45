// Shared conventions of every mcdenoise kernel.
//
// * `real` is the compute precision: f32 by default, f64 when the build
//   defines MC_F64 (the `<kernel>_f64` variant). Storage is always f32.
// * Planes are one scalar channel each: `float v[]`, pixel (x, y) at y*W + x.
// * Kernels run on an 8x8 grid over a band of rows: pixel = (gid.x, row0 + gid.y).
// * Inputs are `readonly`; outputs are plain `buffer` (naga rejects `writeonly`).
// * No NaN literals (naga rejects them): build NaN/Inf with uintBitsToFloat.

#extension GL_EXT_shader_explicit_arithmetic_types_float64 : enable

#ifdef MC_F64
#define real double
#define real2 dvec2
#define real3 dvec3
#define real4 dvec4
#define EPS_PIVOT 1e-12
#define JACOBI_TOL 1e-12
#define JACOBI_SWEEPS 30
#else
#define real float
#define real2 vec2
#define real3 vec3
#define real4 vec4
#define EPS_PIVOT 1e-6
#define JACOBI_TOL 1e-6
#define JACOBI_SWEEPS 10
#endif

// Runs the following statement only for invocations where `cond` holds, as
// a loop of 0 or 1 iterations: llvmpipe runs both sides of an `if` under a
// mask in every SIMD vector, and leaves a loop at the end of the first
// iteration in which no lane of the vector is active, so the vectors
// without such an invocation pass through the body once under an all-off
// mask (gallivm branches into a loop unconditionally) and through each loop
// inside it once: cheap for a body made of loops, not for a long straight
// one. The same holds for any loop: a heavy body inside a loop that is
// entered often with no trips costs one pass per entry (lp_gather before
// LP-GATHER-FLAT; LP-GATHER-UNION keeps its single loop).
#define ONLY(cond) for (int once_ = ((cond) ? 0 : 1); once_ < 1; ++once_)

#define PLANE_IN(b, name) layout(std430, set = 0, binding = b) readonly buffer name##_blk { float name[]; };
#define PLANE_OUT(b, name) layout(std430, set = 0, binding = b) buffer name##_blk { float name[]; };

bool is_finite(float x) { return !isnan(x) && !isinf(x); }

// Sample count as used everywhere (spec §0.2): a pixel is valid when n >= 1.
// A non-finite or negative count is treated as 0 (invalid).
float spp_of(float s) { return (is_finite(s) && s >= 1.0) ? s : 0.0; }

// APR-COUNT-CAP's sample total (spp_total.comp; twin reference::spp_total):
// a pixel counts at most this many samples, so that a workgroup's 64 pixels
// of 16 n each fit in 32 bits.
#define SPP_TOTAL_MAX 2097152.0

// The mean sample count of the valid pixels from spp_total's three words
// (0 when there are none), in this order of f32 operations (the twin and the
// tile driver compute it alike).
float spp_total_mean(uint lo, uint hi, uint count)
{
    if (count == 0u) {
        return 0.0;
    }
    float sum = float(hi) * 4294967296.0 + float(lo);
    return sum / (16.0 * float(count));
}

// A 3-sigma test's threshold for a mean whose variance is estimated from its
// own n samples: the one-sided Phi(-3) quantile of Student's t with
// nu = max(n - 1, 1) degrees of freedom, by its Cornish-Fisher expansion to
// nu^-3 (8.5 at 4 samples, 3.6 at 16, 3.1 at 64). AOS-RESIDUAL and
// LP-PIXEL-TEST. Twin: reference::t_threshold3.
real t_threshold3(real n)
{
    real nu = max(n - real(1), real(1));
    real z = real(3);
    real z3 = z * z * z;
    real z5 = z3 * z * z;
    real z7 = z5 * z * z;
    return z + (z3 + z) / (real(4) * nu) + (real(5) * z5 + real(16) * z3 + real(3) * z) / (real(96) * nu * nu)
        + (real(3) * z7 + real(19) * z5 + real(17) * z3 - real(15) * z) / (real(384) * nu * nu * nu);
}

// LP-PIXEL-TEST and APR-PIXEL-TEST (twin: reference::pixel_test_limit): the
// limit on a prediction's squared miss at a valid pixel of variance v_i, from
// t2 = pixel_test_t2(n_i) and the sum, largest value and count of the
// variances over the neighbours of its valid 3x3 neighbourhood (i included)
// that agree with it (pixel_test_agrees, PIXEL-TEST-AGREE): t2 times the
// larger of v_i and their mean without the largest value.
#define PIXEL_TEST_VAR_FLOOR 1e-20

// Invocations per workgroup of lp_centres (mirror
// kernels::lp_centres::GROUP), the unit in which lp_select counts its
// indirect dispatch: one SIMD vector on lavapipe (256-bit, 8 lanes). A band
// of a late pass queues a few dozen to a few hundred centres whose cost
// differs from lane to lane (rank, image border); lavapipe hands whole
// workgroups to its threads, so 8-centre groups keep both cores busy to the
// end of the dispatch where 64-centre groups left one idle.
#define LP_CENTRES_GROUP 8u

// Work queues that kernels fill for an indirect dispatch (Batch::reset_queue
// clears the header): [workgroups x, y, z, count, entries...]. The order of
// the entries is whatever the atomics give, so each consumer must handle an
// entry on its own.
// Workgroups an indirect dispatch may have (maxComputeWorkGroupCount is at
// least 65535); the consumers stride over the entries beyond.
#define QUEUE_MAX_GROUPS 65535u
// Entries a queue buffer q has room for.
#define QUEUE_ROOM(q) (uint(q.length()) - 4u)
// Appends `value` to queue q unless `capacity` entries are there, counting
// the consumer's workgroups of `group` entries.
#define QUEUE_APPEND(q, value, group, capacity) \
    { \
        uint at_ = atomicAdd(q[3], 1u); \
        if (at_ < (capacity)) { \
            q[4u + at_] = (value); \
            if (at_ % (group) == 0u && at_ / (group) < QUEUE_MAX_GROUPS) { \
                atomicAdd(q[0], 1u); \
            } \
        } \
    }
real pixel_test_t2(real n)
{
    real t = t_threshold3(n);
    return t * t;
}

// Whether a neighbour at squared distance dist2 from pixel i (summed over
// the channels the variances are summed over) with variance v_q counts in
// i's neighbourhood variance: its level differs from i's by at most
// t_threshold3(n_i) standard errors of the difference.
bool pixel_test_agrees(real t2, real dist2, real v_q, real v_i)
{
    return dist2 <= t2 * (v_q + v_i);
}

real pixel_test_limit(real t2, real v_i, real vsum, real vmax, int count)
{
    real vbar = count > 1 ? (vsum - vmax) / real(count - 1) : vsum;
    return t2 * max(max(v_i, vbar), real(PIXEL_TEST_VAR_FLOOR));
}
