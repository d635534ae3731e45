#version 460
// Outlier replacement (spec §4.4 step 2-3) for the pixels outlier_detect
// queued: o takes the colour and variance of q*, the pixel of median grey
// in Ω_o(R) with o (lower median of an even count, lowest raster index
// among equal greys: OUTLIER-MEDIAN), found by a 32-step radix selection on
// the order-preserving bits of grey from outlier_rows (no local array);
// e = y_o - y_q* per channel. Every read is of the original planes, so the
// entries are independent and the queue's order does not matter.
// Dispatched indirectly, one invocation per entry.
// Scalar twin: src/reference/outlier_median.rs.
#include "lib/common.glsl"
#include "lib/outliers.glsl"

layout(local_size_x = 64) in;

PLANE_IN(0, cr)
PLANE_IN(1, cg)
PLANE_IN(2, cb)
PLANE_IN(3, vr)
PLANE_IN(4, vg)
PLANE_IN(5, vb)
PLANE_IN(6, spp)
layout(std430, set = 0, binding = 7) readonly buffer keys_blk { uint keys[]; };
layout(std430, set = 0, binding = 8) readonly buffer queue_blk { uint queue[]; };
PLANE_OUT(9, out_r)
PLANE_OUT(10, out_g)
PLANE_OUT(11, out_b)
PLANE_OUT(12, out_vr)
PLANE_OUT(13, out_vg)
PLANE_OUT(14, out_vb)
PLANE_OUT(15, er)
PLANE_OUT(16, eg)
PLANE_OUT(17, eb)

void main()
{
    uint at = gl_GlobalInvocationID.x;
    if (at >= queue[3]) {
        return;
    }
    uint o = queue[4u + at];
    int x = int(o % push.width), y = int(o / push.width);
    int r = int(push.radius);
    int x0 = max(x - r, 0), x1 = min(x + r, int(push.width) - 1);
    int y0 = max(y - r, 0), y1 = min(y + r, int(push.height) - 1);
    // Rank of the median among the valid pixels of the window, o included.
    uint n = 0u;
    for (int qy = y0; qy <= y1; ++qy) {
        for (int qx = x0; qx <= x1; ++qx) {
            n += valid_at(spp[uint(qy) * push.width + uint(qx)]) ? 1u : 0u;
        }
    }
    uint k = (n - 1u) / 2u;
    uint prefix = 0u;
    for (int bit = 31; bit >= 0; --bit) {
        uint hi = bit == 31 ? 0u : (0xFFFFFFFFu << uint(bit + 1));
        uint zeros = 0u;
        for (int qy = y0; qy <= y1; ++qy) {
            for (int qx = x0; qx <= x1; ++qx) {
                uint j = uint(qy) * push.width + uint(qx);
                if (valid_at(spp[j])) {
                    uint kj = keys[j];
                    zeros += ((kj & hi) == prefix && (kj & (1u << uint(bit))) == 0u) ? 1u : 0u;
                }
            }
        }
        if (k >= zeros) {
            k -= zeros;
            prefix |= 1u << uint(bit);
        }
    }
    // The lowest raster index holding the median key.
    uint q = o;
    bool found = false;
    for (int qy = y0; qy <= y1 && !found; ++qy) {
        for (int qx = x0; qx <= x1 && !found; ++qx) {
            uint j = uint(qy) * push.width + uint(qx);
            if (valid_at(spp[j]) && keys[j] == prefix) {
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
