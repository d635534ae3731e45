#version 460
// AOS feature prefilter (spec §5.2): variance-aware NL-means of one buffer
// of 1 or 3 channels, 11x11 search, 7x7 patches (NLM-PARAMS), k = 1
// (NLM-K). Output: the filtered channels, then their propagated variances
// var = sum_q (w_pq / sum w)^2 vg_q, as planes of `dst` (stride
// push.stride). An invalid pixel (§0.2) keeps its input.
// Scalar twin: src/reference/aos_nlm.rs. Built a second time as
// `aos_nlm_vis` with WLR_VIS (WLR's visibility, WLR-VIS): one channel, its
// 3x3 means first.
//
// Decision NLM-BOX (ours): offset by offset. For a candidate offset
// (dx, dy) the patch distance of every pixel p is a 7x7 box sum, over patch centres
// a = p + o, of the one term t(a) = sum_ch [(g_a - g_{a+d})^2 - ...] / ...
// (and of the count of valid pairs). A workgroup computes t once per
// offset for its 8x8 pixels' 14x14 patch centres, sums it in columns, then
// in rows, so a pixel costs ~3 term evaluations per candidate instead of
// 49, from its 24x24 neighbourhood of g, v and validity staged in shared
// memory once. The sums run in another order than the twin's raster order
// (rounding only); candidates are accumulated in raster order, as there.
#include "lib/common.glsl"
#extension GL_EXT_control_flow_attributes : require

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
// Mirror mcdenoise::shared::AOS_NLM_CLAMP and NLM_CLAMP_Z.
#define AOS_NLM_CLAMP 128u
#define NLM_CLAMP_Z 2.0
// The staged region (search + patch halo) and the patch centres' region.
#define NLM_RG (8 + 2 * NLM_SEARCH + 2 * NLM_PATCH)
#define NLM_TA (8 + 2 * NLM_PATCH)
#define NLM_PD (2 * NLM_PATCH + 1)
#define NLM_SD (2 * NLM_SEARCH + 1)
#define NLM_OFFSETS (NLM_SD * NLM_SD)
// Candidate offsets handled between two barriers (shared memory: 32 KiB).
#ifdef MC_F64
#define NLM_NB 4
#else
#define NLM_NB 9
#endif

real3 g_at(uint i) { return real3(g0[i], g1[i], g2[i]); }

#ifdef WLR_VIS
// WLR-VIS (the `_vis` build, for WLR's visibility; one channel, g0): the
// buffer is first replaced by its mean over the valid pixels of the 3x3
// window (clipped), with variance sum(max(vg, 0)) / n^2, then filtered;
// valid pixels only. Summed in raster order, as the twin sums it; staged
// as f32 like the plain input. Returns the mean; `v` the variance. Only
// g0, vg0 and spp are loaded (lavapipe pays per load).
real box3_at(ivec2 q, int w, int h, out float v)
{
    real s = real(0);
    real sv = real(0);
    real n = real(0);
    for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
            ivec2 t = q + ivec2(dx, dy);
            if (t.x >= 0 && t.y >= 0 && t.x < w && t.y < h) {
                uint j = uint(t.y * w + t.x);
                if (spp_of(spp[j]) >= 1.0) {
                    s += real(g0[j]);
                    sv += max(real(vg0[j]), real(0));
                    n += real(1);
                }
            }
        }
    }
    v = float(sv / (n * n));
    return s / n;
}
#endif

shared vec4 s_g[NLM_RG * NLM_RG];           // g (3 channels), 1 if valid (0: invalid or outside)
shared vec4 s_v[NLM_RG * NLM_RG];           // max(vg, 0)
// Per offset of the batch, t of the 14x14 patch centres; then, in place,
// its sums over 7 rows (rows 0..7), then over 7 columns of those (columns
// 0..7 of rows 0..7): the box sum of every pixel of the tile.
shared real s_t[NLM_NB * NLM_TA * NLM_TA];
// The same of the count of valid pairs (1 where both pixels are valid).
shared real s_n[NLM_NB * NLM_TA * NLM_TA];

// The sums of 7 consecutive entries of s_t and s_n along one line of 14
// (entries base + j stride), written in place over the line's first 8:
// summed directly, not as running differences (a huge t next to small ones
// would leave its rounding in sums that do not hold it). Every index into
// the unrolled register windows is a constant.
void nlm_box7(uint base, uint stride)
{
    real ct[NLM_TA];
    real cn[NLM_TA];
    [[unroll]] for (int j = 0; j < NLM_TA; ++j) {
        ct[j] = s_t[base + uint(j) * stride];
        cn[j] = s_n[base + uint(j) * stride];
    }
    [[unroll]] for (int j = 0; j < 8; ++j) {
        real a = ct[j];
        real m = cn[j];
        [[unroll]] for (int o = 1; o < NLM_PD; ++o) {
            a += ct[j + o];
            m += cn[j + o];
        }
        s_t[base + uint(j) * stride] = a;
        s_n[base + uint(j) * stride] = m;
    }
}

// Offset o (raster order over the search window) in the staged region.
int nlm_offset(uint o)
{
    return (int(o / uint(NLM_SD)) - NLM_SEARCH) * NLM_RG + int(o % uint(NLM_SD)) - NLM_SEARCH;
}

void main()
{
    int w = int(push.width);
    int h = int(push.height);
    ivec2 tile = ivec2(gl_WorkGroupID.x * 8u, push.base_row + push.row0 + gl_WorkGroupID.y * 8u);
    ivec2 org = tile - (NLM_SEARCH + NLM_PATCH);
    uint lid = gl_LocalInvocationIndex;
    for (uint k = lid; k < uint(NLM_RG * NLM_RG); k += 64u) {
        ivec2 q = org + ivec2(k % uint(NLM_RG), k / uint(NLM_RG));
        vec4 g = vec4(0);
        vec4 v = vec4(0);
        if (q.x >= 0 && q.y >= 0 && q.x < w && q.y < h) {
            uint i = uint(q.y * w + q.x);
#ifdef WLR_VIS
            g = vec4(g0[i], 0.0, 0.0, spp_of(spp[i]) >= 1.0 ? 1.0 : 0.0);
            v = vec4(max(vg0[i], 0.0), 0.0, 0.0, 0.0);
            if (g.w > 0.0) {
                g.x = float(box3_at(q, w, h, v.x));
            }
#else
            g = vec4(g0[i], g1[i], g2[i], spp_of(spp[i]) >= 1.0 ? 1.0 : 0.0);
            v = vec4(max(vec3(vg0[i], vg1[i], vg2[i]), vec3(0)), 0.0);
#endif
        }
        s_g[k] = g;
        s_v[k] = v;
    }
    barrier();

    ivec2 l = ivec2(gl_LocalInvocationID.xy);
    ivec2 p = tile + l;
    bool inside = p.x < w && p.y < h;
    uint i = inside ? uint(p.y * w + p.x) : 0u;
    int nc = int(push.channels);
    // Channels beyond nc read as 0 and drop out of the distance.
    real3 cm = real3(1, nc >= 2 ? 1 : 0, nc >= 3 ? 1 : 0);
    // This pixel's place in the staged region.
    int rp = (l.y + NLM_SEARCH + NLM_PATCH) * NLM_RG + l.x + NLM_SEARCH + NLM_PATCH;
    bool valid = inside && s_g[rp].w > 0.0;
    real wsum = real(0);
    real3 acc = real3(0);
    real3 vacc = real3(0);
    for (uint o0 = 0u; o0 < uint(NLM_OFFSETS); o0 += uint(NLM_NB)) {
        // t at the 14x14 patch centres a of the tile, paired with a + d,
        // for the batch's offsets d.
        for (uint kk = lid; kk < uint(NLM_TA * NLM_TA); kk += 64u) {
            int ra = (int(kk / uint(NLM_TA)) + NLM_SEARCH) * NLM_RG + int(kk % uint(NLM_TA)) + NLM_SEARCH;
            vec4 ga = s_g[ra];
            real3 va = real3(s_v[ra].xyz);
            for (uint b = 0u; b < uint(NLM_NB); ++b) {
                int rb = ra + nlm_offset(min(o0 + b, uint(NLM_OFFSETS - 1)));
                vec4 gb = s_g[rb];
                real3 vb = real3(s_v[rb].xyz);
                real t = real(0);
                real n = real(0);
                if (ga.w * gb.w > 0.0) {
                    real3 d = real3(ga.xyz) - real3(gb.xyz);
                    real3 tt = (d * d - (va + min(va, vb))) / (real(1e-10) + real(NLM_K2) * (va + vb));
                    t = dot(tt, cm);
                    n = real(1);
                }
                s_t[b * uint(NLM_TA * NLM_TA) + kk] = t;
                s_n[b * uint(NLM_TA * NLM_TA) + kk] = n;
            }
        }
        barrier();
        // The 7x7 box sums, in place: sums over 7 rows, one lane per offset
        // and column, then over 7 columns of those, one lane per offset and
        // tile row (nlm_box7).
        for (uint k = lid; k < uint(NLM_NB * NLM_TA); k += 64u) {
            nlm_box7((k / uint(NLM_TA)) * uint(NLM_TA * NLM_TA) + k % uint(NLM_TA), uint(NLM_TA));
        }
        barrier();
        for (uint k = lid; k < uint(NLM_NB * 8); k += 64u) {
            nlm_box7((k / 8u) * uint(NLM_TA * NLM_TA) + (k % 8u) * uint(NLM_TA), 1u);
        }
        barrier();
        // The candidates q = p + d of the batch, in raster order: inside
        // the image and valid.
        for (uint b = 0u; b < uint(NLM_NB); ++b) {
            uint o = o0 + b;
            int rq = rp + nlm_offset(min(o, uint(NLM_OFFSETS - 1)));
            vec4 gq = s_g[rq];
            if (o < uint(NLM_OFFSETS) && valid && gq.w > 0.0) {
                uint at = b * uint(NLM_TA * NLM_TA) + uint(l.y * NLM_TA + l.x);
                real sum = s_t[at];
                real count = s_n[at];
                real wq = real(1);
                if (count > real(0)) {
                    real dist = sum / (real(nc) * count);
                    wq = real(exp(float(-max(dist, real(0)))));
                }
                wsum += wq;
                acc += wq * real3(gq.xyz);
                vacc += wq * wq * real3(s_v[rq].xyz);
            }
        }
        // The next batch's terms overwrite the box sums.
        barrier();
    }
    if (!inside) {
        return;
    }
    real3 out_g = g_at(i) * cm;
    real3 out_v = real3(vg0[i], vg1[i], vg2[i]) * cm;
    if (valid) {
        out_g = acc / wsum * cm;
        out_v = vacc / (wsum * wsum) * cm;
        if ((push.flags & AOS_NLM_CLAMP) != 0u) {
            real3 g = g_at(i) * cm;
            real3 se = real(NLM_CLAMP_Z) * sqrt(max(real3(vg0[i], vg1[i], vg2[i]), real3(0))) * cm;
            out_g = clamp(out_g, g - se, g + se);
        }
    }
    uint s = push.stride;
    for (int c = 0; c < 3; ++c) {
        if (c < nc) {
            dst[uint(c) * s + i] = float(out_g[c]);
            dst[uint(nc + c) * s + i] = float(out_v[c]);
        }
    }
}
