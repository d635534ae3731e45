#version 460
// Outlier detection, row part (spec §4.4 step 1): per pixel (x, y), the
// (count, mean, M2) of grey over the valid pixels of the row segment
// [x - R, x + R] (R = OUTLIER_DETECT_R, clipped), once with (x) itself and
// once without (o): outlier_detect merges 2R + 1 rows of these into the
// statistics of Ω(R) \ {o} without a sum of squares, the row of o without
// it (EXCL-CENTRE). Each is merged from the two-pass summaries of the left
// [x - R, x - 1] and right [x + 1, x + R] half-rows; grey and validity come
// from outlier_grey's keys. Scalar twin: src/reference/outlier_rows.rs.
#include "lib/common.glsl"
#include "lib/outliers.glsl"
layout(local_size_x = 8, local_size_y = 8) in;
layout(std430, set = 0, binding = 0) readonly buffer keys_blk { uint keys[]; };
PLANE_OUT(1, wn)
PLANE_OUT(2, wm)
PLANE_OUT(3, wq)
PLANE_OUT(4, xn)
PLANE_OUT(5, xm)
PLANE_OUT(6, xq)

// Register blocking: an invocation computes ROWS_PX consecutive pixels of a
// row. The keys of their joint segment (ROWS_PX + 2R wide) are loaded and
// decoded once into registers; each pixel's half-rows are then summed from
// them with constant indices (the loops are unrolled), in the order of one
// invocation per pixel, so the result is the same: ~(ROWS_PX + 2R) / ROWS_PX
// loads per pixel instead of 4R + 1 (lavapipe pays per lane and value
// loaded). Dispatched over ceil(width / ROWS_PX) x height invocations.
#extension GL_EXT_control_flow_attributes : require
#define ROWS_PX 8
#define R OUTLIER_DETECT_R
#define ROWS_SPAN (ROWS_PX + 2 * R)

// Two-pass (count, mean, M2) of the valid greys g[a..a + R) (ok), into s.
#define SEGMENT(s, a)                                       \
    {                                                       \
        s.n = real(0);                                      \
        s.mean = real(0);                                   \
        s.m2 = real(0);                                     \
        real sum_ = real(0);                                \
        [[unroll]] for (int u_ = 0; u_ < R; ++u_) {         \
            if (ok[(a) + u_]) {                             \
                s.n += real(1);                             \
                sum_ += g[(a) + u_];                        \
            }                                               \
        }                                                   \
        if (s.n != real(0)) {                               \
            s.mean = sum_ / s.n;                            \
            [[unroll]] for (int u_ = 0; u_ < R; ++u_) {     \
                if (ok[(a) + u_]) {                         \
                    real d_ = g[(a) + u_] - s.mean;         \
                    s.m2 += d_ * d_;                        \
                }                                           \
            }                                               \
        }                                                   \
    }

void main()
{
    uint x0 = gl_GlobalInvocationID.x * uint(ROWS_PX);
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x0 >= push.width || y >= push.height) {
        return;
    }
    // Entry u: column x0 - R + u (invalid outside the image).
    real g[ROWS_SPAN];
    bool ok[ROWS_SPAN];
    [[unroll]] for (int u = 0; u < ROWS_SPAN; ++u) {
        int qx = int(x0) - R + u;
        g[u] = real(0);
        ok[u] = false;
        if (qx >= 0 && qx < int(push.width)) {
            real gv;
            ok[u] = key_grey(keys[y * push.width + uint(qx)], gv);
            g[u] = ok[u] ? gv : real(0);
        }
    }
    [[unroll]] for (int p = 0; p < ROWS_PX; ++p) {
        if (x0 + uint(p) >= push.width) {
            continue;
        }
        uint i = y * push.width + x0 + uint(p);
        // The pixel is entry p + R; its half-rows start at p and p + R + 1.
        Summary l, rt;
        SEGMENT(l, p)
        SEGMENT(rt, p + R + 1)
        Summary c;
        c.n = ok[p + R] ? real(1) : real(0);
        c.mean = ok[p + R] ? g[p + R] : real(0);
        c.m2 = real(0);
        Summary with_x = merge(merge(l, c), rt);
        Summary without = merge(l, rt);
        wn[i] = float(with_x.n);
        wm[i] = float(with_x.mean);
        wq[i] = float(with_x.m2);
        xn[i] = float(without.n);
        xm[i] = float(without.mean);
        xq[i] = float(without.m2);
    }
}
