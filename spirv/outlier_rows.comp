#version 460
// Outlier detection, row part (spec §4.4 step 1): per pixel (x, y), the
// (count, mean, M2) of grey over the valid pixels of the row segments
// [x - R, x - 1] (left) and [x + 1, x + R] (right), R = push.radius, clipped.
// outlier_detect merges 2R + 1 rows of these into the statistics of
// Ω(R) \ {o} without a sum of squares; and per pixel the order-preserving
// bits of grey (keys) its median selection scans. Scalar twin:
// src/reference/outlier_rows.rs.
#include "lib/common.glsl"
#include "lib/outliers.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

PLANE_IN(0, cr)
PLANE_IN(1, cg)
PLANE_IN(2, cb)
PLANE_IN(3, spp)
PLANE_OUT(4, ln)
PLANE_OUT(5, lm)
PLANE_OUT(6, lq)
PLANE_OUT(7, rn)
PLANE_OUT(8, rm)
PLANE_OUT(9, rq)
layout(std430, set = 0, binding = 10) buffer keys_blk { uint keys[]; };

real grey_at(uint i) { return (real(cr[i]) + real(cg[i]) + real(cb[i])) / real(3); }

// Two-pass (count, mean, M2) of row y over [a, b].
Summary segment(uint y, int a, int b)
{
    Summary s;
    s.n = real(0);
    s.mean = real(0);
    s.m2 = real(0);
    real sum = real(0);
    for (int qx = a; qx <= b; ++qx) {
        uint q = y * push.width + uint(qx);
        if (valid_at(spp[q])) {
            s.n += real(1);
            sum += grey_at(q);
        }
    }
    if (s.n == real(0)) {
        return s;
    }
    s.mean = sum / s.n;
    for (int qx = a; qx <= b; ++qx) {
        uint q = y * push.width + uint(qx);
        if (valid_at(spp[q])) {
            real d = grey_at(q) - s.mean;
            s.m2 += d * d;
        }
    }
    return s;
}

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    uint i = y * push.width + x;
    int r = int(push.radius);
    Summary l = segment(y, max(int(x) - r, 0), int(x) - 1);
    Summary rt = segment(y, int(x) + 1, min(int(x) + r, int(push.width) - 1));
    ln[i] = float(l.n);
    lm[i] = float(l.mean);
    lq[i] = float(l.m2);
    rn[i] = float(rt.n);
    rm[i] = float(rt.mean);
    rq[i] = float(rt.m2);
    // Order-preserving bits of the f32 grey, for outlier_detect's median.
    uint b = floatBitsToUint(float(grey_at(i)));
    keys[i] = (b & 0x80000000u) != 0u ? ~b : (b | 0x80000000u);
}
