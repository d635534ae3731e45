#version 460
// The input blend (INPUT-BLEND, ours): one channel of the reconstruction f
// with error estimate E, blended with the input y (the statistics
// the method read) by inverse error, as two estimates of the same pixel:
//   V  = max(v, mean of v over the valid pixels of the (2r+1)^2 window
//        without its ceil(n/10) largest values, at most BLEND_TRIM_MAX and
//        never all (BLEND-TRIM))
//   B  = mean of (f - y)^2 - v over the valid pixels of the (2s+1)^2
//        window, less z sqrt(2 mean(v^2) / n) (BLEND-RESIDUAL; not read
//        with s = 0, or where a term (f - y)^2 or v^2 is not finite or
//        exceeds f32's largest)
//   M  = max(E, B),  W = max(k E, B)
//   f' = max((V f + W y) / (V + W), 0) = max(f + w_y (y - f), 0)
//   E' = w_f^2 M + w_y^2 V
// with w_y = W / (V + W), w_f = 1 - w_y, computed from V, M and W divided
// by the largest, and the windows' means as running means (no overflow
// where the input is huge). E' is the
// variance of the blend were the two independent. An invalid pixel, one
// with V + W = 0 or not finite, or one whose blend is not finite, keeps
// f and E.
// Scalar twin: src/reference/input_blend.rs.
#extension GL_EXT_control_flow_attributes : require
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// The most values the variance's window drops (mirrors
// mcdenoise::shared::BLEND_TRIM_MAX).
#define BLEND_TRIM_MAX 8

// Mirrors mcdenoise::shared::BlendPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint radius;
    float k;
    uint residual_radius;
    float z;
    uint pad0;
} push;

PLANE_IN(0, f)
PLANE_IN(1, e)
PLANE_IN(2, y)
PLANE_IN(3, v)
PLANE_IN(4, spp)
PLANE_OUT(5, fout)
PLANE_OUT(6, eout)

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint row = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || row >= push.height) {
        return;
    }
    uint i = row * push.width + x;
    float ei_raw = e[i];
    fout[i] = f[i];
    if (spp_of(spp[i]) <= 0.0) {
        eout[i] = ei_raw;
        return;
    }
    // One pass over the larger of the two windows: the variance's (radius
    // r) and the residual's (radius s; BLEND-RESIDUAL, a lower bound on
    // the reconstruction's error that its own estimate cannot miss), each
    // a running mean over its valid pixels in row order.
    int r = int(push.radius);
    int rs = int(push.residual_radius);
    int reach = max(r, rs);
    int x0 = max(int(x) - reach, 0), x1 = min(int(x) + reach, int(push.width) - 1);
    int y0 = max(int(row) - reach, 0), y1 = min(int(row) + reach, int(push.height) - 1);
    real big = real(3.4028234663852886e38);
    real mean = real(0);
    real count = real(0);
    real rest = real(0);
    real top[BLEND_TRIM_MAX];
    [[unroll]] for (int j = 0; j < BLEND_TRIM_MAX; ++j) {
        top[j] = real(-1);
    }
    real n = real(0), md = real(0), mv = real(0), mv2 = real(0);
    bool within = true;
    for (int qy = y0; qy <= y1; ++qy) {
        for (int qx = x0; qx <= x1; ++qx) {
            uint q = uint(qy) * push.width + uint(qx);
            if (spp_of(spp[q]) <= 0.0) {
                continue;
            }
            int dist = max(abs(qx - int(x)), abs(qy - int(row)));
            real vq = max(real(v[q]), real(0));
            if (dist <= r) {
                // The window's largest variances, in descending order
                // (-1: empty); what one pushes out joins the running mean
                // of the rest.
                count += real(1);
                real c = vq;
                [[unroll]] for (int j = 0; j < BLEND_TRIM_MAX; ++j) {
                    real hi = max(c, top[j]);
                    c = min(c, top[j]);
                    top[j] = hi;
                }
                if (c >= real(0)) {
                    rest += real(1);
                    mean += (c - mean) / rest;
                }
            }
            if (dist <= rs) {
                n += real(1);
                real d = real(f[q]) - real(y[q]);
                within = within && d * d <= big && vq * vq <= big;
                md += (d * d - md) / n;
                mv += (vq - mv) / n;
                mv2 += (vq * vq - mv2) / n;
            }
        }
    }
    // BLEND-TRIM: the ceil(n/10) largest stay out (a lamp's few pixels
    // beside a dark one); the others join the mean.
    int drop = min(min((int(count) + 9) / 10, int(count) - 1), BLEND_TRIM_MAX);
    [[unroll]] for (int j = 0; j < BLEND_TRIM_MAX; ++j) {
        if (j >= drop && top[j] >= real(0)) {
            rest += real(1);
            mean += (top[j] - mean) / rest;
        }
    }
    real vi = max(real(v[i]), real(0));
    real big_v = max(vi, mean);
    real ei = ei_raw > 0.0 ? real(ei_raw) : real(0);
    real bias = real(0);
    if (rs > 0 && within) {
        // sqrt(mv2) sqrt(2 / n): 2 mv2 can exceed f32 where mv2 does not.
        bias = md - mv - real(push.z) * (sqrt(mv2) * sqrt(real(2) / n));
    }
    real mi = max(ei, bias);
    real s = max(big_v, mi);
    if (!(s > real(0)) || isinf(s) || isnan(s)) {
        eout[i] = ei_raw;
        return;
    }
    real a = big_v / s;
    real b = max(real(push.k) * (ei / s), bias / s);
    real wy = b / (a + b);
    real wf = a / (a + b);
    real fi = real(f[i]);
    real o = fi + wy * (real(y[i]) - fi);
    real eo = wf * wf * mi + wy * wy * big_v;
    if (isinf(o) || isnan(o) || isinf(eo) || isnan(eo)) {
        eout[i] = ei_raw;
        return;
    }
    fout[i] = float(max(o, real(0)));
    eout[i] = float(eo);
}
