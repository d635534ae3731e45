#version 460
// G-buffer prefilter (spec §6) steps 9-10 per pixel: the 7x7 weights with
// h = hbar (H0: hbar < 1e-3 passes the pixel through, as does an invalid
// pixel), and for each of the seven features gbf_pack packed (normal x y z,
// depth, albedo r g b) the filtered value sum w g / W and its propagated
// variance sum w^2 var(g) / W^2 (GBF-VAR), written to seven + seven planes
// (the feature planes themselves: this kernel reads only the packed copies).
// With push.second_below > 0 it is GBF-SECOND's second pass over the first
// pass's output: only the pixels with fewer samples than that are filtered,
// and only the features are written (the variances stay the first pass's).
// Scalar twin: src/reference/gbf_filter.rs.
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::GbfPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint base;      // gbf_pack, gbf_filter: first row of the packed bindings
    float second_below;  // gbf_filter: GBF-SECOND's pass when > 0
} push;

PLANE_IN(0, px)
PLANE_IN(1, py)
PLANE_IN(2, pz)
PLANE_IN(3, sxx)
PLANE_IN(4, sxy)
PLANE_IN(5, sxz)
PLANE_IN(6, syy)
PLANE_IN(7, syz)
PLANE_IN(8, szz)
PLANE_IN(9, hbar)
layout(std430, set = 0, binding = 10) readonly buffer fa_blk { vec4 fa[]; };
layout(std430, set = 0, binding = 11) readonly buffer fb_blk { vec4 fb[]; };
layout(std430, set = 0, binding = 12) readonly buffer va_blk { vec4 va[]; };
layout(std430, set = 0, binding = 13) readonly buffer vb_blk { vec4 vb[]; };
PLANE_OUT(14, g0)
PLANE_OUT(15, g1)
PLANE_OUT(16, g2)
PLANE_OUT(17, g3)
PLANE_OUT(18, g4)
PLANE_OUT(19, g5)
PLANE_OUT(20, g6)
PLANE_OUT(21, gv0)
PLANE_OUT(22, gv1)
PLANE_OUT(23, gv2)
PLANE_OUT(24, gv3)
PLANE_OUT(25, gv4)
PLANE_OUT(26, gv5)
PLANE_OUT(27, gv6)

real3 gbf_position(uint q) { return real3(px[q], py[q], pz[q]); }
// PACKED-SPP: the sample count is the fourth lane of the packed albedo
// (index k of the packed bindings, which start at row push.base).
bool gbf_valid(uint k) { return spp_of(fb[k].w) >= 1.0; }

#include "lib/gbf.glsl"

// S~^-1 of pixel q (gbf_prepare).
realmat3 gbf_inv_cov(uint q)
{
    return gbf_sym(real3(sxx[q], sxy[q], sxz[q]), real3(syy[q], syz[q], szz[q]));
}

// Register blocking: an invocation filters GBF_ROWS x GBF_PX pixels (rows
// y0 .. y0 + GBF_ROWS - 1, columns x0 .. x0 + GBF_PX - 1). Each neighbour of
// their joint window (GBF_PX + 6 wide, GBF_ROWS + 6 tall) is loaded once and
// accumulated into every pixel whose 7x7 window holds it, so a pixel costs
// (GBF_PX + 6)(GBF_ROWS + 6) / (GBF_PX GBF_ROWS) neighbour loads instead of
// 49 (lavapipe pays per lane and float loaded, and a storage-buffer load
// more than a shared-memory one). Each pixel still sums its neighbours in
// raster order (dy, then dx), so the result is the same as one invocation
// per pixel. The loops over the joint window's columns and over the pixels
// are unrolled: every array index is a constant; a window row outside a
// pixel's rows is masked off.
#extension GL_EXT_control_flow_attributes : require
#define GBF_PX 8
#define GBF_ROWS 2
#define GBF_N (GBF_PX * GBF_ROWS)
#define GBF_SPAN (GBF_PX + 2 * GBF_RADIUS)

void main()
{
    uint x0 = gl_GlobalInvocationID.x * uint(GBF_PX);
    uint y0 = (push.row0 + gl_GlobalInvocationID.y) * uint(GBF_ROWS);
    if (x0 >= push.width || y0 >= push.height) {
        return;
    }
    bool act[GBF_N];
    real k2[GBF_N];  // -log2(e) / (2 h^2): w = 2^(d k2), no division per neighbour
    real3 pc[GBF_N];
    realmat3 inv_c[GBF_N];
    real W[GBF_N];
    // (albedo r g b and its variances: the packed planes' fourth entry is
    // not read)
    real4 sa[GBF_N], sva[GBF_N];
    real3 sb[GBF_N], svb[GBF_N];
    bool any_act = false;
    [[unroll]] for (int k = 0; k < GBF_N; ++k) {
        uint x = x0 + uint(k % GBF_PX);
        uint y = y0 + uint(k / GBF_PX);
        act[k] = false;
        k2[k] = real(0);
        pc[k] = real3(0);
        inv_c[k] = realmat3(0);
        W[k] = real(0);
        sa[k] = real4(0);
        sb[k] = real3(0);
        sva[k] = real4(0);
        svb[k] = real3(0);
        if (x < push.width && y < push.height) {
            uint c = y * push.width + x;
            real h = real(hbar[c]);
            uint ck = c - push.base * push.width;
            bool second = push.second_below > 0.0;
            if (gbf_valid(ck) && h >= real(GBF_H0)
                && (!second || spp_of(fb[ck].w) < push.second_below)) {
                act[k] = true;
                k2[k] = real(-GBF_LOG2E) / (real(2) * h * h);
                pc[k] = gbf_position(c);
                inv_c[k] = gbf_inv_cov(c);
                any_act = true;
            }
        }
    }
    if (any_act) {
        for (int v = -GBF_RADIUS; v <= GBF_RADIUS + GBF_ROWS - 1; ++v) {
            int qy = int(y0) + v;
            if (qy < 0 || qy >= int(push.height)) {
                continue;
            }
            [[unroll]] for (int u = 0; u < GBF_SPAN; ++u) {
                int qx = int(x0) - GBF_RADIUS + u;
                if (qx < 0 || qx >= int(push.width)) {
                    continue;
                }
                uint q = uint(qy) * push.width + uint(qx);
                uint qk = q - push.base * push.width;
                if (!gbf_valid(qk)) {
                    continue;
                }
                real3 pq = gbf_position(q);
                realmat3 inv_q = gbf_inv_cov(q);
                real4 qa = real4(fa[qk]);
                real3 qb = real3(fb[qk].xyz);
                real4 qva = real4(va[qk]);
                real3 qvb = real3(vb[qk].xyz);
                [[unroll]] for (int k = 0; k < GBF_N; ++k) {
                    int dx = u - GBF_RADIUS - k % GBF_PX;
                    int dy = v - k / GBF_PX;
                    if (dx < -GBF_RADIUS || dx > GBF_RADIUS) {
                        continue;
                    }
                    if (dy < -GBF_RADIUS || dy > GBF_RADIUS || !act[k]) {
                        continue;
                    }
                    real w = real(1);
                    if (dx != 0 || dy != 0) {
                        real3 dlt = pq - pc[k];
                        real d = dot(dlt, (inv_c[k] + inv_q) * dlt);
                        w = gbf_exp2(d * k2[k]);
                    }
                    W[k] += w;
                    sa[k] += w * qa;
                    sb[k] += w * qb;
                    sva[k] += (w * w) * qva;
                    svb[k] += (w * w) * qvb;
                }
            }
        }
    }
    [[unroll]] for (int k = 0; k < GBF_N; ++k) {
        uint x = x0 + uint(k % GBF_PX);
        uint y = y0 + uint(k / GBF_PX);
        if (x >= push.width || y >= push.height) {
            continue;
        }
        uint c = y * push.width + x;
        // The packed planes start at row push.base (row chunks, methods/gbf.rs).
        uint ck = c - push.base * push.width;
        real4 ga = real4(fa[ck]);
        real3 gb = real3(fb[ck].xyz);
        real4 gva = real4(va[ck]);
        real3 gvb = real3(vb[ck].xyz);
        if (act[k]) {
            ga = sa[k] / W[k];
            gb = sb[k] / W[k];
            gva = sva[k] / (W[k] * W[k]);
            gvb = svb[k] / (W[k] * W[k]);
        }
        g0[c] = float(ga.x);
        g1[c] = float(ga.y);
        g2[c] = float(ga.z);
        g3[c] = float(ga.w);
        g4[c] = float(gb.x);
        g5[c] = float(gb.y);
        g6[c] = float(gb.z);
        if (push.second_below > 0.0) {
            continue;
        }
        gv0[c] = float(gva.x);
        gv1[c] = float(gva.y);
        gv2[c] = float(gva.z);
        gv3[c] = float(gva.w);
        gv4[c] = float(gvb.x);
        gv5[c] = float(gvb.y);
        gv6[c] = float(gvb.z);
    }
}
