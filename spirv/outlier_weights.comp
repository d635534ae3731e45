#version 460
// Outlier redistribution weights (spec §4.4 step 4) at each pixel o with an
// excess e_o (0 elsewhere): S = Σ ŷ and |Ω_o| over the valid pixels of
// Ω_o(R), R = 43 (215 in OUTLIER-WIDE's second run), from box_rows' row
// sums; rho = e/S, or, when S <=
// dark |Ω_o| (DARK-WINDOW), add = e/|Ω_o|. Only the pixels outlier_detect
// queued can have an excess: dispatched indirectly over that queue, one
// invocation per entry (striding past 65535 workgroups), on outputs the
// host has zeroed, so every SIMD lane sums a window (a per-pixel grid ran
// each window's 87 rows for the whole vector of a detected pixel).
// OUTLIER-WIDE: mode WEIGHTS_NARROW weighs only the outliers whose grey
// excess is at most push.wide of the window's grey sum and marks the others
// in their queue entry (QUEUE_WIDE); mode WEIGHTS_WIDE, over the wide
// window, weighs only the marked ones; mode 0 weighs every one.
// Scalar twin: src/reference/outlier_weights.rs.
#include "lib/common.glsl"
#include "lib/outliers.glsl"

layout(local_size_x = 64) in;

PLANE_IN(0, er)
PLANE_IN(1, eg)
PLANE_IN(2, eb)
PLANE_IN(3, sr)
PLANE_IN(4, sg)
PLANE_IN(5, sb)
PLANE_IN(6, cnt)
PLANE_OUT(7, rho_r)
PLANE_OUT(8, rho_g)
PLANE_OUT(9, rho_b)
PLANE_OUT(10, add_r)
PLANE_OUT(11, add_g)
PLANE_OUT(12, add_b)
layout(std430, set = 0, binding = 13) buffer queue_blk { uint queue[]; };

// The weights of the queue's entry at.
void weigh(uint at)
{
    uint entry = queue[4u + at];
    uint o = entry & ~QUEUE_WIDE;
    uint x = o % push.width;
    uint y = o / push.width;
    real3 e = real3(er[o], eg[o], eb[o]);
    real3 rho = real3(0);
    real3 add = real3(0);
    if (e != real3(0)) {
        int r = int(push.radius);
        real3 s = real3(0);
        real n = real(0);
        for (int qy = max(int(y) - r, 0); qy <= min(int(y) + r, int(push.height) - 1); ++qy) {
            uint q = uint(qy) * push.width + x;
            s += real3(sr[q], sg[q], sb[q]);
            n += real(cnt[q]);
        }
        bool weighs = n > real(0);
        if (weighs && push.mode == WEIGHTS_NARROW) {
            bool wide = e.x + e.y + e.z > real(push.wide) * (s.x + s.y + s.z);
            queue[4u + at] = wide ? (o | QUEUE_WIDE) : o;
            weighs = !wide;
        } else if (push.mode == WEIGHTS_WIDE) {
            weighs = weighs && (entry & QUEUE_WIDE) != 0u;
        }
        if (weighs) {
            for (int ch = 0; ch < 3; ++ch) {
                if (s[ch] <= real(push.dark) * n) {
                    add[ch] = e[ch] / n;
                } else {
                    rho[ch] = e[ch] / s[ch];
                }
            }
        }
    }
    rho_r[o] = float(rho.x);
    rho_g[o] = float(rho.y);
    rho_b[o] = float(rho.z);
    add_r[o] = float(add.x);
    add_g[o] = float(add.y);
    add_b[o] = float(add.z);
}

void main()
{
    uint entries = min(queue[3], queue_capacity());
    for (uint at = gl_GlobalInvocationID.x; at < entries; at += gl_NumWorkGroups.x * 64u) {
        weigh(at);
    }
}
