#version 460
// G-buffer prefilter (spec §6) steps 9-10 per pixel: the 7x7 weights with
// h = hbar (H0: hbar < 1e-3 passes the pixel through, as does an invalid
// pixel), and for each of the seven features gbf_pack packed (normal x y z,
// depth, albedo r g b) the filtered value sum w g / W and its propagated
// variance sum w^2 var(g) / W^2 (GBF-VAR), written to seven + seven planes
// (the feature planes themselves: this kernel reads only the packed copies).
// Scalar twin: src/reference/gbf_filter.rs.
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::GbfPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint base;      // gbf_pack, gbf_filter: first row of the packed bindings
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
PLANE_IN(9, spp)
PLANE_IN(10, hbar)
layout(std430, set = 0, binding = 11) readonly buffer fa_blk { vec4 fa[]; };
layout(std430, set = 0, binding = 12) readonly buffer fb_blk { vec4 fb[]; };
layout(std430, set = 0, binding = 13) readonly buffer va_blk { vec4 va[]; };
layout(std430, set = 0, binding = 14) readonly buffer vb_blk { vec4 vb[]; };
PLANE_OUT(15, g0)
PLANE_OUT(16, g1)
PLANE_OUT(17, g2)
PLANE_OUT(18, g3)
PLANE_OUT(19, g4)
PLANE_OUT(20, g5)
PLANE_OUT(21, g6)
PLANE_OUT(22, gv0)
PLANE_OUT(23, gv1)
PLANE_OUT(24, gv2)
PLANE_OUT(25, gv3)
PLANE_OUT(26, gv4)
PLANE_OUT(27, gv5)
PLANE_OUT(28, gv6)

real3 gbf_position(uint q) { return real3(px[q], py[q], pz[q]); }
bool gbf_valid(uint q) { return spp_of(spp[q]) >= 1.0; }

#include "lib/gbf.glsl"

// S~^-1 of pixel q (gbf_prepare).
realmat3 gbf_inv_cov(uint q)
{
    return gbf_sym(real3(sxx[q], sxy[q], sxz[q]), real3(syy[q], syz[q], szz[q]));
}

// Register blocking: an invocation filters GBF_PX consecutive pixels of a
// row. Each neighbour of their joint window (GBF_PX + 6 wide) is loaded once
// and accumulated into every pixel whose 7x7 window holds it, so a pixel
// costs (GBF_PX + 6) / GBF_PX neighbour loads per window column instead of 7
// (lavapipe pays per lane and float loaded). Each pixel still sums its
// neighbours in raster order (dy, then dx), so the result is the same as one
// invocation per pixel. The loops over the joint window's columns and over
// the pixels are unrolled: every array index is a constant.
#extension GL_EXT_control_flow_attributes : require
#define GBF_PX 8
#define GBF_SPAN (GBF_PX + 2 * GBF_RADIUS)

void main()
{
    uint x0 = gl_GlobalInvocationID.x * uint(GBF_PX);
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x0 >= push.width || y >= push.height) {
        return;
    }
    bool act[GBF_PX];
    real h2[GBF_PX];
    real3 pc[GBF_PX];
    realmat3 inv_c[GBF_PX];
    real W[GBF_PX];
    real4 sa[GBF_PX], sb[GBF_PX], sva[GBF_PX], svb[GBF_PX];
    bool any_act = false;
    [[unroll]] for (int p = 0; p < GBF_PX; ++p) {
        uint x = x0 + uint(p);
        act[p] = false;
        h2[p] = real(1);
        pc[p] = real3(0);
        inv_c[p] = realmat3(0);
        W[p] = real(0);
        sa[p] = real4(0);
        sb[p] = real4(0);
        sva[p] = real4(0);
        svb[p] = real4(0);
        if (x < push.width) {
            uint c = y * push.width + x;
            real h = real(hbar[c]);
            if (gbf_valid(c) && h >= real(GBF_H0)) {
                act[p] = true;
                h2[p] = real(2) * h * h;
                pc[p] = gbf_position(c);
                inv_c[p] = gbf_inv_cov(c);
                any_act = true;
            }
        }
    }
    if (any_act) {
        for (int dy = -GBF_RADIUS; dy <= GBF_RADIUS; ++dy) {
            int qy = int(y) + dy;
            if (qy < 0 || qy >= int(push.height)) {
                continue;
            }
            [[unroll]] for (int u = 0; u < GBF_SPAN; ++u) {
                int qx = int(x0) - GBF_RADIUS + u;
                if (qx < 0 || qx >= int(push.width)) {
                    continue;
                }
                uint q = uint(qy) * push.width + uint(qx);
                if (!gbf_valid(q)) {
                    continue;
                }
                real3 pq = gbf_position(q);
                realmat3 inv_q = gbf_inv_cov(q);
                uint qk = q - push.base * push.width;
                real4 qa = real4(fa[qk]);
                real4 qb = real4(fb[qk]);
                real4 qva = real4(va[qk]);
                real4 qvb = real4(vb[qk]);
                [[unroll]] for (int p = 0; p < GBF_PX; ++p) {
                    int dx = u - GBF_RADIUS - p;
                    if (dx < -GBF_RADIUS || dx > GBF_RADIUS || !act[p]) {
                        continue;
                    }
                    real w = real(1);
                    if (dx != 0 || dy != 0) {
                        real3 dlt = pq - pc[p];
                        real d = dot(dlt, (inv_c[p] + inv_q) * dlt);
                        w = gbf_exp(-d / h2[p]);
                    }
                    W[p] += w;
                    sa[p] += w * qa;
                    sb[p] += w * qb;
                    sva[p] += (w * w) * qva;
                    svb[p] += (w * w) * qvb;
                }
            }
        }
    }
    [[unroll]] for (int p = 0; p < GBF_PX; ++p) {
        uint x = x0 + uint(p);
        if (x >= push.width) {
            continue;
        }
        uint c = y * push.width + x;
        // The packed planes start at row push.base (row chunks, methods/gbf.rs).
        uint ck = c - push.base * push.width;
        real4 ga = real4(fa[ck]);
        real4 gb = real4(fb[ck]);
        real4 gva = real4(va[ck]);
        real4 gvb = real4(vb[ck]);
        if (act[p]) {
            ga = sa[p] / W[p];
            gb = sb[p] / W[p];
            gva = sva[p] / (W[p] * W[p]);
            gvb = svb[p] / (W[p] * W[p]);
        }
        g0[c] = float(ga.x);
        g1[c] = float(ga.y);
        g2[c] = float(ga.z);
        g3[c] = float(ga.w);
        g4[c] = float(gb.x);
        g5[c] = float(gb.y);
        g6[c] = float(gb.z);
        gv0[c] = float(gva.x);
        gv1[c] = float(gva.y);
        gv2[c] = float(gva.z);
        gv3[c] = float(gva.w);
        gv4[c] = float(gvb.x);
        gv5[c] = float(gvb.y);
        gv6[c] = float(gvb.z);
    }
}
