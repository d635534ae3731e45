#version 460
// One sparse-centre pass of LP (spec §3.5), for the centres lp_select queued
// (one band of the candidate grid; dispatched indirectly, one invocation per
// entry, so every SIMD lane fits a centre): TSVD on the 19x19 window
// (§0.6), RLS ring by ring with the recursive error estimate (§3.3-3.4),
// r_opt; its 36-value state (reference::lp::StateLayout) goes to its own
// pixel of the 9 vec4 state planes (planes 1..8 a ring of rows,
// LpPush::ring_rows). Nothing else is written.
// Scalar twin: src/reference/lp_centres.rs (routines: src/reference/lp.rs).
#include "lib/common.glsl"

layout(local_size_x = LP_CENTRES_GROUP) in;

// Mirrors mcdenoise::shared::LpPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint granularity;
    uint pass;
    uint options;
    uint out_stride;
    uint phase;
    uint ring_rows;
} push;

// The features and their variances packed by gbf_pack (PACKED-LP): fa =
// normal xyz, depth; fb = albedo rgb, spp (PACKED-SPP: a pixel's validity
// comes with its features); va, vb the variances of fa and fb.xyz.
layout(std430, set = 0, binding = 0) readonly buffer fa_blk { vec4 fa[]; };
layout(std430, set = 0, binding = 1) readonly buffer fb_blk { vec4 fb[]; };
layout(std430, set = 0, binding = 2) readonly buffer va_blk { vec4 va[]; };
layout(std430, set = 0, binding = 3) readonly buffer vb_blk { vec4 vb[]; };
PLANE_IN(4, col_r)
PLANE_IN(5, col_g)
PLANE_IN(6, col_b)
PLANE_IN(7, var_r)
PLANE_IN(8, var_g)
PLANE_IN(9, var_b)
layout(std430, set = 0, binding = 10) readonly buffer queue_blk { uint queue[]; };
layout(std430, set = 0, binding = 11) buffer st0_blk { vec4 st0[]; };
layout(std430, set = 0, binding = 12) buffer st1_blk { vec4 st1[]; };
layout(std430, set = 0, binding = 13) buffer st2_blk { vec4 st2[]; };
layout(std430, set = 0, binding = 14) buffer st3_blk { vec4 st3[]; };
layout(std430, set = 0, binding = 15) buffer st4_blk { vec4 st4[]; };
layout(std430, set = 0, binding = 16) buffer st5_blk { vec4 st5[]; };
layout(std430, set = 0, binding = 17) buffer st6_blk { vec4 st6[]; };
layout(std430, set = 0, binding = 18) buffer st7_blk { vec4 st7[]; };
layout(std430, set = 0, binding = 19) buffer st8_blk { vec4 st8[]; };

#define NONE 1

// Features (px, py, normal xyz, depth, albedo rgb), variances (0, 0, then
// those of the normal, depth and albedo); valid iff spp_of >= 1 (spec §0.2,
// §2.1).
bool load_features(ivec2 p, out real x[9], out real e2[9])
{
    uint i = uint(p.y) * push.width + uint(p.x);
    vec4 a = fa[i];
    vec4 b = fb[i];
    x[0] = real(p.x);
    x[1] = real(p.y);
    x[2] = real(a.x);
    x[3] = real(a.y);
    x[4] = real(a.z);
    x[5] = real(a.w);
    x[6] = real(b.x);
    x[7] = real(b.y);
    x[8] = real(b.z);
    vec4 u = va[i];
    vec4 v = vb[i];
    e2[0] = real(0);
    e2[1] = real(0);
    e2[2] = real(u.x);
    e2[3] = real(u.y);
    e2[4] = real(u.z);
    e2[5] = real(u.w);
    e2[6] = real(v.x);
    e2[7] = real(v.y);
    e2[8] = real(v.z);
    return spp_of(b.w) >= 1.0;
}

// Whether pixel i is valid (PACKED-SPP; its features' load, which follows,
// is the same one).
bool lp_valid(uint i)
{
    return spp_of(fb[i].w) >= 1.0;
}

void load_colour(ivec2 p, out real3 y, out real3 v)
{
    uint i = uint(p.y) * push.width + uint(p.x);
    y = real3(col_r[i], col_g[i], col_b[i]);
    v = real3(var_r[i], var_g[i], var_b[i]);
}

#include "lib/lp.glsl"

// The fit of the centre at pixel i, written to its pixel of the state.
void fit(uint i, ivec2 size)
{
    uint x = i % push.width;
    uint y = i / push.width;
    ivec2 c = ivec2(x, y);
    LocalSpace ls = tsvd_local_space(c, LP_RADIUS, size);
    TsvdProj pr = tsvd_projection(ls);
    real s = (push.options & LP_VARSUB) != 0u ? real(1) : real(0);
    LpFit f = lp_centre_fit(c, size, pr, s, (push.options & LP_CENTRE_TEST) != 0u,
                            (push.options & LP_OUTLIER_W) != 0u);

    // The state (StateLayout): pass + 1, r_opt, k, beta0 RGB, xi RGB, u[ch][j].
    float o[36];
    o[0] = float(push.pass + 1u);
    o[1] = float(f.r_opt);
    o[2] = float(f.k);
    for (int ch = 0; ch < 3; ++ch) {
        o[3 + ch] = float(f.B[3 * ch].x);
        o[6 + ch] = float(f.xi[ch]);
        for (int j = 0; j < 9; ++j) {
            o[9 + 9 * ch + j] = float(lp_u(pr, f, ch, j));
        }
    }
    st0[i] = vec4(o[0], o[1], o[2], o[3]);
    // Planes 1..8 are a ring of push.ring_rows rows (LpPush::ring_rows).
    uint ring = push.ring_rows == 0u ? push.height : push.ring_rows;
    uint r = (y % ring) * push.width + x;
    st1[r] = vec4(o[4], o[5], o[6], o[7]);
    st2[r] = vec4(o[8], o[9], o[10], o[11]);
    st3[r] = vec4(o[12], o[13], o[14], o[15]);
    st4[r] = vec4(o[16], o[17], o[18], o[19]);
    st5[r] = vec4(o[20], o[21], o[22], o[23]);
    st6[r] = vec4(o[24], o[25], o[26], o[27]);
    st7[r] = vec4(o[28], o[29], o[30], o[31]);
    st8[r] = vec4(o[32], o[33], o[34], o[35]);
}

void main()
{
    ivec2 size = ivec2(push.width, push.height);
    uint count = min(queue[3], QUEUE_ROOM(queue));
    uint stride = gl_NumWorkGroups.x * LP_CENTRES_GROUP;
    for (uint e = gl_GlobalInvocationID.x; e < count; e += stride) {
        fit(queue[4u + e], size);
    }
}
