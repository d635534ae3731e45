#version 460
// AOS feature prefilter (spec §5.2): variance-aware NL-means of one buffer
// of 1 or 3 channels, 11x11 search, 7x7 patches (NLM-PARAMS), k = 1
// (NLM-K). Output: the filtered channels, then their propagated variances
// var = sum_q (w_pq / sum w)^2 vg_q, as planes of `dst` (stride
// push.stride). An invalid pixel (§0.2) keeps its input.
// Scalar twin: src/reference/aos_nlm.rs.
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::AosPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint radius;
    uint channels;
    uint flags;
    uint base_row;
    uint stride;
} push;

PLANE_IN(0, g0)
PLANE_IN(1, g1)
PLANE_IN(2, g2)
PLANE_IN(3, vg0)
PLANE_IN(4, vg1)
PLANE_IN(5, vg2)
PLANE_IN(6, spp)
PLANE_OUT(7, dst)

#define NLM_SEARCH 5
#define NLM_PATCH 3
#define NLM_K2 1.0

bool valid_at(uint i) { return spp_of(spp[i]) >= 1.0; }

real3 g_at(uint i) { return real3(g0[i], g1[i], g2[i]); }

real3 v_at(uint i) { return max(real3(vg0[i], vg1[i], vg2[i]), real3(0)); }

void main()
{
    int w = int(push.width);
    int h = int(push.height);
    ivec2 p = ivec2(gl_GlobalInvocationID.x, push.base_row + push.row0 + gl_GlobalInvocationID.y);
    if (p.x >= w || p.y >= h) {
        return;
    }
    uint i = uint(p.y * w + p.x);
    int nc = int(push.channels);
    // Channels beyond nc read as 0 and drop out of the distance.
    real3 cm = real3(1, nc >= 2 ? 1 : 0, nc >= 3 ? 1 : 0);
    real3 out_g = g_at(i) * cm;
    real3 out_v = real3(vg0[i], vg1[i], vg2[i]) * cm;
    if (valid_at(i)) {
        real wsum = real(0);
        real3 acc = real3(0);
        real3 vacc = real3(0);
        for (int qy = max(p.y - NLM_SEARCH, 0); qy <= min(p.y + NLM_SEARCH, h - 1); ++qy) {
            for (int qx = max(p.x - NLM_SEARCH, 0); qx <= min(p.x + NLM_SEARCH, w - 1); ++qx) {
                uint q = uint(qy * w + qx);
                if (!valid_at(q)) {
                    continue;
                }
                real sum = real(0);
                int count = 0;
                for (int oy = -NLM_PATCH; oy <= NLM_PATCH; ++oy) {
                    int ay = p.y + oy;
                    int by = qy + oy;
                    if (ay < 0 || by < 0 || ay >= h || by >= h) {
                        continue;
                    }
                    for (int ox = -NLM_PATCH; ox <= NLM_PATCH; ++ox) {
                        int ax = p.x + ox;
                        int bx = qx + ox;
                        if (ax < 0 || bx < 0 || ax >= w || bx >= w) {
                            continue;
                        }
                        uint a = uint(ay * w + ax);
                        uint b = uint(by * w + bx);
                        if (!valid_at(a) || !valid_at(b)) {
                            continue;
                        }
                        ++count;
                        real3 va = v_at(a);
                        real3 vb = v_at(b);
                        real3 d = g_at(a) - g_at(b);
                        real3 t = (d * d - (va + min(va, vb))) / (real(1e-10) + real(NLM_K2) * (va + vb));
                        sum += dot(t, cm);
                    }
                }
                real wq = real(1);
                if (count > 0) {
                    real dist = sum / real(nc * count);
                    wq = real(exp(float(-max(dist, real(0)))));
                }
                wsum += wq;
                acc += wq * g_at(q);
                vacc += wq * wq * v_at(q);
            }
        }
        out_g = acc / wsum * cm;
        out_v = vacc / (wsum * wsum) * cm;
    }
    uint s = push.stride;
    for (int c = 0; c < 3; ++c) {
        if (c < nc) {
            dst[uint(c) * s + i] = float(out_g[c]);
            dst[uint(nc + c) * s + i] = float(out_v[c]);
        }
    }
}
