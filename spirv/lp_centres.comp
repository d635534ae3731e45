#version 460
// One sparse-centre pass of LP (spec §3.5) on the candidate grid of
// granularity g: thread (gx, gy) <-> candidate pixel (phi + g gx, phi + g gy). A valid
// candidate no centre of an earlier pass covers (read from the `reach` plane
// of the state before this pass: PASS-SNAPSHOT) becomes a centre:
// TSVD on the 19x19 window (§0.6), RLS ring by ring with the recursive error
// estimate (§3.3-3.4), r_opt; its 36-value state (reference::lp::StateLayout)
// goes to its own pixel of the 9 vec4 state planes. Nothing else is written.
// Scalar twin: src/reference/lp_centres.rs (routines: src/reference/lp.rs).
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

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
} push;

PLANE_IN(0, nx)
PLANE_IN(1, ny)
PLANE_IN(2, nz)
PLANE_IN(3, dep)
PLANE_IN(4, ar)
PLANE_IN(5, ag)
PLANE_IN(6, ab)
PLANE_IN(7, v_nx)
PLANE_IN(8, v_ny)
PLANE_IN(9, v_nz)
PLANE_IN(10, v_dep)
PLANE_IN(11, v_ar)
PLANE_IN(12, v_ag)
PLANE_IN(13, v_ab)
PLANE_IN(14, col_r)
PLANE_IN(15, col_g)
PLANE_IN(16, col_b)
PLANE_IN(17, var_r)
PLANE_IN(18, var_g)
PLANE_IN(19, var_b)
PLANE_IN(20, spp)
PLANE_IN(21, reach)
layout(std430, set = 0, binding = 22) buffer st0_blk { vec4 st0[]; };
layout(std430, set = 0, binding = 23) buffer st1_blk { vec4 st1[]; };
layout(std430, set = 0, binding = 24) buffer st2_blk { vec4 st2[]; };
layout(std430, set = 0, binding = 25) buffer st3_blk { vec4 st3[]; };
layout(std430, set = 0, binding = 26) buffer st4_blk { vec4 st4[]; };
layout(std430, set = 0, binding = 27) buffer st5_blk { vec4 st5[]; };
layout(std430, set = 0, binding = 28) buffer st6_blk { vec4 st6[]; };
layout(std430, set = 0, binding = 29) buffer st7_blk { vec4 st7[]; };
layout(std430, set = 0, binding = 30) buffer st8_blk { vec4 st8[]; };

#define NONE 1

// Features (px, py, nrm xyz, dep, albedo rgb), variances (0, 0, vn xyz, vd,
// va rgb); valid iff spp_of >= 1 (spec §0.2, §2.1).
bool load_features(ivec2 p, out real x[9], out real e2[9])
{
    uint i = uint(p.y) * push.width + uint(p.x);
    x[0] = real(p.x);
    x[1] = real(p.y);
    x[2] = real(nx[i]);
    x[3] = real(ny[i]);
    x[4] = real(nz[i]);
    x[5] = real(dep[i]);
    x[6] = real(ar[i]);
    x[7] = real(ag[i]);
    x[8] = real(ab[i]);
    e2[0] = real(0);
    e2[1] = real(0);
    e2[2] = real(v_nx[i]);
    e2[3] = real(v_ny[i]);
    e2[4] = real(v_nz[i]);
    e2[5] = real(v_dep[i]);
    e2[6] = real(v_ar[i]);
    e2[7] = real(v_ag[i]);
    e2[8] = real(v_ab[i]);
    return spp_of(spp[i]) >= 1.0;
}

void load_colour(ivec2 p, out real3 y, out real3 v)
{
    uint i = uint(p.y) * push.width + uint(p.x);
    y = real3(col_r[i], col_g[i], col_b[i]);
    v = real3(var_r[i], var_g[i], var_b[i]);
}

#include "lib/lp.glsl"

// Covered by a centre of an earlier pass (|p - c|_inf <= r_opt(c), §3.5):
// some row y' within 9 has reach(p.x, y') >= |p.y - y'| (lp_reach.comp,
// computed from the state before this pass: PASS-SNAPSHOT).
bool covered(ivec2 p, ivec2 size)
{
    for (int qy = max(p.y - LP_RADIUS, 0); qy <= min(p.y + LP_RADIUS, size.y - 1); ++qy) {
        if (reach[qy * size.x + p.x] >= float(abs(qy - p.y))) {
            return true;
        }
    }
    return false;
}

// Workgroup compaction: the candidates of a pass that become centres are few
// and scattered (a few %), and a SIMD vector costs as much as its busiest
// lane. So every invocation first tests its candidate, invocation 0 lists the
// centres of the workgroup in invocation order, and the first m invocations
// fit one centre each. Each centre writes only its own pixel, so the result
// does not depend on this assignment.
shared uint s_pixel[64];
shared uint s_count;

void main()
{
    uint lid = gl_LocalInvocationIndex;
    uint g = max(push.granularity, 1u);
    // The candidate grid's phase (LpPush::phase): image coordinates mod g.
    uint x = (push.phase & 0xffffu) + gl_GlobalInvocationID.x * g;
    uint y = (push.phase >> 16) + (push.row0 + gl_GlobalInvocationID.y) * g;
    ivec2 size = ivec2(push.width, push.height);
    bool centre = x < push.width && y < push.height
        && spp_of(spp[y * push.width + x]) >= 1.0 && !covered(ivec2(x, y), size);
    s_pixel[lid] = centre ? y * push.width + x : 0xffffffffu;
    barrier();
    if (lid == 0u) {
        uint m = 0u;
        for (uint j = 0u; j < 64u; ++j) {
            uint q = s_pixel[j];
            if (q != 0xffffffffu) {
                s_pixel[m] = q;
                ++m;
            }
        }
        s_count = m;
    }
    barrier();
    if (lid >= s_count) {
        return;
    }
    uint i = s_pixel[lid];
    x = i % push.width;
    y = i / push.width;
    ivec2 c = ivec2(x, y);
    LocalSpace ls = tsvd_local_space(c, LP_RADIUS, size);
    TsvdProj pr = tsvd_projection(ls);
    real s = (push.options & LP_VARSUB) != 0u ? real(1) : real(0);
    LpFit f = lp_centre_fit(c, size, pr, s);

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
    st1[i] = vec4(o[4], o[5], o[6], o[7]);
    st2[i] = vec4(o[8], o[9], o[10], o[11]);
    st3[i] = vec4(o[12], o[13], o[14], o[15]);
    st4[i] = vec4(o[16], o[17], o[18], o[19]);
    st5[i] = vec4(o[20], o[21], o[22], o[23]);
    st6[i] = vec4(o[24], o[25], o[26], o[27]);
    st7[i] = vec4(o[28], o[29], o[30], o[31]);
    st8[i] = vec4(o[32], o[33], o[34], o[35]);
}
