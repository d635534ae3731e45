#version 460
// Outlier detection and replacement (spec §4.4 steps 1-3). Per valid pixel o:
// the (count, mean, M2) of grey over Ω_o(R) \ {o} merged from outlier_rows'
// row summaries (the row of o without o: EXCL-CENTRE) of the keys that
// outlier_clip's rounds kept (OUTLIER-CLIP; all valid keys without them);
// o is an outlier when
// count >= min_n (OUTLIER-MIN-N), grey_o - m > k sd (SPIKE-SIDE, population
// sd) and grey_o - m <= k se_o (OUTLIER-NOISE, se from the pixel's
// variances) and no 8-neighbour is above m + k sd (OUTLIER-ISOLATED, on
// outlier_grey's keys; OUTLIER-RIM, with push.mode = DETECT_RIM and o's
// excess within RIM_LONE se_o: not a steady neighbour with RIM_SHARE of
// o's excess or more, a light, nor a rare path with less). A detected
// pixel is appended to the queue, whose entries outlier_median replaces by
// the median pixel (and, in its second mode, writes back): nothing else is
// written. The median lives in its own kernel because on lavapipe a kernel
// that merely contains its scans of the window runs much slower
// (PERF-HISTORY), and because a queue keeps all SIMD lanes of the median
// busy.
// Scalar twin: src/reference/outlier_detect.rs.
#include "lib/common.glsl"
#include "lib/outliers.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

PLANE_IN(0, cr)
PLANE_IN(1, cg)
PLANE_IN(2, cb)
PLANE_IN(3, vr)
PLANE_IN(4, vg)
PLANE_IN(5, vb)
PLANE_IN(6, spp)
layout(std430, set = 0, binding = 7) readonly buffer keys_blk { uint keys[]; };
PLANE_IN(8, wn)
PLANE_IN(9, wm)
PLANE_IN(10, wq)
PLANE_IN(11, xn)
PLANE_IN(12, xm)
PLANE_IN(13, xq)
// [0..3): indirect dispatch arguments of outlier_median (x counts started
// groups of 64 entries; y = z = 1, set by the host), [3]: entries, then the
// detected pixels. The host zeroes x and the count before the dispatch.
layout(std430, set = 0, binding = 14) buffer queue_blk { uint queue[]; };

// OUTLIER-RIM: for a pixel whose excess is at most RIM_LONE of its standard
// errors (one or two rare paths), a bright neighbour within its own noise
// keeps it from detection only with at least RIM_SHARE of its excess, a
// steady one only with less (reference::outliers::RIM_LONE, RIM_SHARE).
const real RIM_LONE = real(1.5);
const real RIM_SHARE = real(0.5);

real grey_at(uint i) { return (real(cr[i]) + real(cg[i]) + real(cb[i])) / real(3); }

#include "lib/outlier_window.glsl"

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    uint o = y * push.width + x;
    if (valid_at(spp[o])) {
        Summary s = window_summary(x, y);
        real sd = summary_sd(s);
        // OUTLIER-NOISE: the excess must also be within k standard errors of
        // the pixel's own mean (a directly seen small light is not noise).
        real se = grey_se(o);
        real excess = grey_at(o) - s.mean;
        bool outlier = s.n >= real(push.min_n) && excess > real(push.k_sigma) * sd
            && excess <= real(push.k_sigma) * se;
        // OUTLIER-ISOLATED: a bright 8-neighbour makes o part of a feature;
        // with OUTLIER-RIM (mode DETECT_RIM), when o is one or two rare
        // paths, not a light or a fainter rare path beside it.
        bool rim = push.mode == DETECT_RIM && excess <= RIM_LONE * se;
        for (int qy = max(int(y) - 1, 0); outlier && qy <= min(int(y) + 1, int(push.height) - 1); ++qy) {
            for (int qx = max(int(x) - 1, 0); qx <= min(int(x) + 1, int(push.width) - 1); ++qx) {
                uint j = uint(qy) * push.width + uint(qx);
                real gj;
                if (j != o && key_grey(keys[j], gj)) {
                    real ej = gj - s.mean;
                    // OUTLIER-RIM: a rare path (within its own noise)
                    // shields o when it has RIM_SHARE of o's excess (a
                    // cluster), a steady pixel when it has less (a lit
                    // surface, not a light).
                    if (ej > real(push.k_sigma) * sd
                        && (!rim || (ej <= real(push.k_sigma) * grey_se(j)) == (ej >= RIM_SHARE * excess))) {
                        outlier = false;
                    }
                }
            }
        }
        if (outlier) {
            // Queue o for outlier_median (dispatched indirectly: one
            // workgroup of 64 per 64 entries; the order of the queue does
            // not matter, each entry is replaced on its own).
            QUEUE_APPEND(queue, o, 64u, queue_capacity())
        }
    }
}
