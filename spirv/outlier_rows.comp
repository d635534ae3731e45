#version 460
// Outlier detection, row part (spec §4.4 step 1): per pixel (x, y), the
// (count, mean, M2) of grey over the valid pixels of the row segment
// [x - R, x + R] (R = push.radius, clipped), once with (x) itself and once
// without (o): outlier_detect merges 2R + 1 rows of these into the
// statistics of Ω(R) \ {o} without a sum of squares, the row of o without
// it (EXCL-CENTRE). Each is merged from the one-pass summaries of the left
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
// (count, mean, M2) of row y over [a, b], in one pass (ROWS-ONE-PASS):
// the sums of d = g - s and d^2 with s the segment's first valid grey, M2 =
// sum d^2 - (sum d)^2 / n. Shifting by a member of the set bounds the
// cancellation: (s - mean)^2 <= M2, so both terms are at most (n + 1) M2
// and M2 keeps a relative error of order n^2 eps (~2e-5 in f32 for the
// 14-pixel half-rows), inside §0.3's 1e-3; a bright spike in the segment
// only makes M2 large. One pass over the keys instead of two: the loads,
// not the arithmetic, are what a lane pays on lavapipe.
Summary segment(uint y, int a, int b)
{
    Summary s;
    s.n = real(0);
    s.mean = real(0);
    s.m2 = real(0);
    real sum = real(0);
    real sq = real(0);
    real shift = real(0);
    for (int qx = a; qx <= b; ++qx) {
        real g;
        if (key_grey(keys[y * push.width + uint(qx)], g)) {
            if (s.n == real(0)) {
                shift = g;
            }
            s.n += real(1);
            real d = g - shift;
            sum += d;
            sq += d * d;
        }
    }
    if (s.n == real(0)) {
        return s;
    }
    s.mean = shift + sum / s.n;
    s.m2 = max(sq - sum * sum / s.n, real(0));
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
    Summary c;
    c.n = real(0);
    c.mean = real(0);
    c.m2 = real(0);
    real g;
    if (key_grey(keys[i], g)) {
        c.n = real(1);
        c.mean = g;
    }
    Summary with_x = merge(merge(l, c), rt);
    Summary without = merge(l, rt);
    wn[i] = float(with_x.n);
    wm[i] = float(with_x.mean);
    wq[i] = float(with_x.m2);
    xn[i] = float(without.n);
    xm[i] = float(without.mean);
    xq[i] = float(without.m2);
}
