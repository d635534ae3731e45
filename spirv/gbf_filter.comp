#version 460
// G-buffer prefilter (spec §6) steps 9-10 per pixel: the 7x7 weights with
// h = hbar (H0: hbar < 1e-3 passes the pixel through, as does an invalid
// pixel), and for each of `count` (<= 4) feature planes the filtered value
// sum w g / W and its propagated variance sum w^2 var(g) / W^2 (GBF-VAR).
// Unused slots write 0. Scalar twin: src/reference/gbf_filter.rs.
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::GbfPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint count;
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
PLANE_IN(11, f0)
PLANE_IN(12, f1)
PLANE_IN(13, f2)
PLANE_IN(14, f3)
PLANE_IN(15, v0)
PLANE_IN(16, v1)
PLANE_IN(17, v2)
PLANE_IN(18, v3)
PLANE_OUT(19, g0)
PLANE_OUT(20, g1)
PLANE_OUT(21, g2)
PLANE_OUT(22, g3)
PLANE_OUT(23, gv0)
PLANE_OUT(24, gv1)
PLANE_OUT(25, gv2)
PLANE_OUT(26, gv3)

real3 gbf_position(uint q) { return real3(px[q], py[q], pz[q]); }
bool gbf_valid(uint q) { return spp_of(spp[q]) >= 1.0; }

#include "lib/gbf.glsl"

// S~^-1 of pixel q (gbf_prepare).
realmat3 gbf_inv_cov(uint q)
{
    return gbf_sym(real3(sxx[q], sxy[q], sxz[q]), real3(syy[q], syz[q], szz[q]));
}

real4 feat4(uint q) { return real4(f0[q], f1[q], f2[q], f3[q]); }
real4 var4(uint q) { return real4(v0[q], v1[q], v2[q], v3[q]); }

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    uint c = y * push.width + x;
    bvec4 used = lessThan(uvec4(0, 1, 2, 3), uvec4(push.count));
    real h = real(hbar[c]);
    real4 g = feat4(c);
    real4 gv = var4(c);
    if (gbf_valid(c) && h >= real(GBF_H0)) {
        real3 pc = gbf_position(c);
        realmat3 inv_c = gbf_inv_cov(c);
        real W = real(0);
        real4 sg = real4(0);
        real4 sv = real4(0);
        int x0 = max(int(x) - GBF_RADIUS, 0), x1 = min(int(x) + GBF_RADIUS, int(push.width) - 1);
        int y0 = max(int(y) - GBF_RADIUS, 0), y1 = min(int(y) + GBF_RADIUS, int(push.height) - 1);
        for (int qy = y0; qy <= y1; ++qy) {
            for (int qx = x0; qx <= x1; ++qx) {
                uint q = uint(qy) * push.width + uint(qx);
                if (!gbf_valid(q)) {
                    continue;
                }
                real w = real(1);
                if (q != c) {
                    real3 dlt = gbf_position(q) - pc;
                    real d = dot(dlt, (inv_c + gbf_inv_cov(q)) * dlt);
                    w = gbf_exp(-d / (real(2) * h * h));
                }
                W += w;
                sg += w * feat4(q);
                sv += w * w * var4(q);
            }
        }
        g = sg / W;
        gv = sv / (W * W);
    }
    g = mix(real4(0), g, used);
    gv = mix(real4(0), gv, used);
    g0[c] = float(g.x);
    g1[c] = float(g.y);
    g2[c] = float(g.z);
    g3[c] = float(g.w);
    gv0[c] = float(gv.x);
    gv1[c] = float(gv.y);
    gv2[c] = float(gv.z);
    gv3[c] = float(gv.w);
}
