#version 460
// Outlier replacement (spec §4.4 step 2-3) for the pixels outlier_detect
// queued: o takes the colour and variance of q* (written to o's pixel of
// the replacement planes; the OUTLIER_APPLY mode below puts them into the
// statistics), q* the pixel of median grey in Ω_o(R) with o (lower median
// of an even count, lowest raster index among equal greys:
// OUTLIER-MEDIAN), found by a radix selection of at most 8 steps (4-bit
// digits, stopping once one key carries the digits chosen: MEDIAN-EARLY)
// on the order-preserving bits of grey from outlier_grey (0: invalid; no
// local array); e = y_o - y_q* per channel. Every read is of the original planes, so the
// entries are independent and the queue's order does not matter.
// Dispatched indirectly, one invocation per entry (striding past 65535
// workgroups).
// A second dispatch over the same queue with push.mode = OUTLIER_APPLY
// writes the replacements into the statistics, in place (this one cannot:
// the median pixel of one entry may be another entry). One pipeline for
// both: each pipeline costs resident memory on lavapipe (PERF-HISTORY).
// Scalar twin: src/reference/outlier_median.rs.
#include "lib/common.glsl"
#include "lib/outliers.glsl"

layout(local_size_x = 64) in;

// Read by the median; written by OUTLIER_APPLY.
PLANE_OUT(0, cr)
PLANE_OUT(1, cg)
PLANE_OUT(2, cb)
PLANE_OUT(3, vr)
PLANE_OUT(4, vg)
PLANE_OUT(5, vb)
layout(std430, set = 0, binding = 6) readonly buffer keys_blk { uint keys[]; };
layout(std430, set = 0, binding = 7) readonly buffer queue_blk { uint queue[]; };
PLANE_OUT(8, out_r)
PLANE_OUT(9, out_g)
PLANE_OUT(10, out_b)
PLANE_OUT(11, out_vr)
PLANE_OUT(12, out_vg)
PLANE_OUT(13, out_vb)
PLANE_OUT(14, er)
PLANE_OUT(15, eg)
PLANE_OUT(16, eb)

// Moves rank k past the counts of c (digits base..base+3) until it falls
// inside one: that digit, and the number of keys in it.
void walk(uvec4 c, uint base, inout uint k, inout uint digit, inout uint in_digit, inout bool found)
{
    for (int t = 0; t < 4; ++t) {
        if (!found) {
            if (k >= c[t]) {
                k -= c[t];
            } else {
                digit = base + uint(t);
                in_digit = c[t];
                found = true;
            }
        }
    }
}

// The replacement of the queued pixel o.
void replace(uint o)
{
    int x = int(o % push.width), y = int(o / push.width);
    int r = int(push.radius);
    int x0 = max(x - r, 0), x1 = min(x + r, int(push.width) - 1);
    int y0 = max(y - r, 0), y1 = min(y + r, int(push.height) - 1);
    // k: the rank of the median among the valid pixels of the window, o
    // included, from the first digit's counts (every valid key).
    uint k = 0u;
    // Eight 4-bit digits, most significant first: per digit one scan counts
    // the keys under the prefix by digit value (16 counters as four uvec4,
    // constant-indexed), and the digit is where rank k falls. A quarter of
    // the scans (and loads) of a bit-by-bit selection, the same result.
    // MEDIAN-EARLY: once a single key carries the digits chosen so far, it
    // is the median; the remaining digits' scans are skipped (a SIMD vector
    // stops when all its lanes have), and the last scan finds the first
    // pixel whose key carries them (the same pixel: the key is unique).
    uint prefix = 0u;
    uint mask = 0u;  // the bits of the digits chosen so far
    bool unique = false;
    for (int shift = 28; shift >= 0 && !unique; shift -= 4) {
        uint hi = mask;
        uvec4 c0 = uvec4(0), c1 = uvec4(0), c2 = uvec4(0), c3 = uvec4(0);
        for (int qy = y0; qy <= y1; ++qy) {
            for (int qx = x0; qx <= x1; ++qx) {
                uint kj = keys[uint(qy) * push.width + uint(qx)];
                if (kj != 0u) {
                    if ((kj & hi) == prefix) {
                        uvec4 d = uvec4((kj >> uint(shift)) & 15u);
                        c0 += uvec4(equal(d, uvec4(0u, 1u, 2u, 3u)));
                        c1 += uvec4(equal(d, uvec4(4u, 5u, 6u, 7u)));
                        c2 += uvec4(equal(d, uvec4(8u, 9u, 10u, 11u)));
                        c3 += uvec4(equal(d, uvec4(12u, 13u, 14u, 15u)));
                    }
                }
            }
        }
        if (shift == 28) {
            uvec4 all4 = c0 + c1 + c2 + c3;
            k = (all4.x + all4.y + all4.z + all4.w - 1u) / 2u;
        }
        uint digit = 15u;
        uint in_digit = 0u;
        bool found = false;
        walk(c0, 0u, k, digit, in_digit, found);
        walk(c1, 4u, k, digit, in_digit, found);
        walk(c2, 8u, k, digit, in_digit, found);
        walk(c3, 12u, k, digit, in_digit, found);
        prefix |= digit << uint(shift);
        mask |= 15u << uint(shift);
        unique = in_digit == 1u;
    }
    // The lowest raster index holding the median key.
    uint q = o;
    bool found = false;
    for (int qy = y0; qy <= y1 && !found; ++qy) {
        for (int qx = x0; qx <= x1 && !found; ++qx) {
            uint j = uint(qy) * push.width + uint(qx);
            uint kj = keys[j];
            if (kj != 0u && (kj & mask) == prefix) {
                q = j;
                found = true;
            }
        }
    }
    out_r[o] = cr[q];
    out_g[o] = cg[q];
    out_b[o] = cb[q];
    out_vr[o] = vr[q];
    out_vg[o] = vg[q];
    out_vb[o] = vb[q];
    er[o] = float(real(cr[o]) - real(cr[q]));
    eg[o] = float(real(cg[o]) - real(cg[q]));
    eb[o] = float(real(cb[o]) - real(cb[q]));
}

// mcdenoise::shared::OUTLIER_APPLY.
#define OUTLIER_APPLY 1u

// The replacement of the queued pixel o, from the replacement planes into
// the statistics.
void apply(uint o)
{
    cr[o] = out_r[o];
    cg[o] = out_g[o];
    cb[o] = out_b[o];
    vr[o] = out_vr[o];
    vg[o] = out_vg[o];
    vb[o] = out_vb[o];
}

void main()
{
    uint entries = min(queue[3], queue_capacity());
    uint stride = gl_NumWorkGroups.x * 64u;
    // One loop per mode, the other's range empty (llvmpipe would run both
    // sides of a branch).
    bool applying = push.mode == OUTLIER_APPLY;
    for (uint at = gl_GlobalInvocationID.x; at < (applying ? 0u : entries); at += stride) {
        replace(queue[4u + at]);
    }
    for (uint at = gl_GlobalInvocationID.x; at < (applying ? entries : 0u); at += stride) {
        apply(queue[4u + at]);
    }
}
