#version 460
// One round of OUTLIER-CLIP (ours; spec §4.4 step 1): per pixel o still kept
// (key != 0), the (count, mean, M2) of grey over Ω_o(R) \ {o} from
// outlier_rows' summaries of the kept keys; o leaves the statistics (its key
// becomes 0) when count >= min_n, grey_o - m > k sd (the spec's test) and
// either grey_o - m > k se_o (signal by OUTLIER-NOISE: a light) or
// grey_o - m > CLIP_FAR sd (a spike so far out that it is no part of the
// window's noise; spikes nearer stay in the statistics as the spec has
// them). After the rounds, outlier_rows and outlier_detect read the kept
// keys, so a light beside a firefly no longer inflates the firefly's sd;
// OUTLIER-NOISE, OUTLIER-ISOLATED and the median read the original keys.
// Each invocation reads and writes only its own key (the summaries were
// computed before), so the round runs in place.
// Scalar twin: src/reference/outlier_clip.rs.
#include "lib/common.glsl"
#include "lib/outliers.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::reference::outliers::CLIP_FAR.
#define CLIP_FAR 50.0

layout(std430, set = 0, binding = 0) buffer keys_blk { uint keys[]; };
PLANE_IN(1, wn)
PLANE_IN(2, wm)
PLANE_IN(3, wq)
PLANE_IN(4, xn)
PLANE_IN(5, xm)
PLANE_IN(6, xq)
PLANE_IN(7, vr)
PLANE_IN(8, vg)
PLANE_IN(9, vb)

#include "lib/outlier_window.glsl"

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    uint o = y * push.width + x;
    real g;
    if (key_grey(keys[o], g)) {
        Summary s = window_summary(x, y);
        real se = grey_se(o);
        real excess = g - s.mean;
        real k = real(push.k_sigma);
        real sd = summary_sd(s);
        if (s.n >= real(push.min_n) && excess > k * sd
            && (excess > k * se || excess > real(CLIP_FAR) * sd)) {
            keys[o] = 0u;
        }
    }
}
