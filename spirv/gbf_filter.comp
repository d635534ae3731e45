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

#define TILE (8 + 2 * GBF_RADIUS)
// The workgroup's 8x8 pixels and their 3-pixel halo, staged once: a shared
// load costs lavapipe much less than a storage-buffer load. 20,384 bytes:
// above Vulkan's guaranteed 16 KiB, within every desktop GPU's 32-64 KiB;
// a device with less gets a clear error when the pipeline is built.
shared vec4 t_pos[TILE * TILE];  // position, valid (1) or not (0, also outside)
shared vec4 t_ia[TILE * TILE];   // S~^-1 XX XY XZ YY
shared vec2 t_ib[TILE * TILE];   // S~^-1 YZ ZZ
shared vec4 t_fa[TILE * TILE];
shared vec4 t_fb[TILE * TILE];
shared vec4 t_va[TILE * TILE];
shared vec4 t_vb[TILE * TILE];

void main()
{
    ivec2 org = ivec2(gl_WorkGroupID.x * 8u, push.row0 + gl_WorkGroupID.y * 8u) - GBF_RADIUS;
    for (uint k = gl_LocalInvocationIndex; k < uint(TILE * TILE); k += 64u) {
        ivec2 t = org + ivec2(k % uint(TILE), k / uint(TILE));
        t_pos[k] = vec4(0);
        if (t.x >= 0 && t.y >= 0 && t.x < int(push.width) && t.y < int(push.height)) {
            uint q = uint(t.y) * push.width + uint(t.x);
            if (gbf_valid(q)) {
                t_pos[k] = vec4(px[q], py[q], pz[q], 1.0);
                t_ia[k] = vec4(sxx[q], sxy[q], sxz[q], syy[q]);
                t_ib[k] = vec2(syz[q], szz[q]);
                uint qk = q - push.base * push.width;
                t_fa[k] = fa[qk];
                t_fb[k] = fb[qk];
                t_va[k] = va[qk];
                t_vb[k] = vb[qk];
            }
        }
    }
    barrier();
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    uint c = y * push.width + x;
    real h = real(hbar[c]);
    // The packed planes start at row push.base (row chunks, methods/gbf.rs).
    uint ck = c - push.base * push.width;
    real4 ga = real4(fa[ck]);
    real4 gb = real4(fb[ck]);
    real4 gva = real4(va[ck]);
    real4 gvb = real4(vb[ck]);
    if (gbf_valid(c) && h >= real(GBF_H0)) {
        real3 pc = gbf_position(c);
        realmat3 inv_c = gbf_inv_cov(c);
        real W = real(0);
        real4 sa = real4(0), sb = real4(0), sva = real4(0), svb = real4(0);
        uint lc = (gl_LocalInvocationID.y + uint(GBF_RADIUS)) * uint(TILE)
            + gl_LocalInvocationID.x + uint(GBF_RADIUS);
        for (int dy = -GBF_RADIUS; dy <= GBF_RADIUS; ++dy) {
            for (int dx = -GBF_RADIUS; dx <= GBF_RADIUS; ++dx) {
                uint lq = uint(int(lc) + dy * TILE + dx);
                vec4 tp = t_pos[lq];
                if (tp.w == 0.0) {
                    continue;
                }
                real w = real(1);
                if (lq != lc) {
                    vec4 ia = t_ia[lq];
                    real3 dlt = real3(tp.xyz) - pc;
                    real d = dot(dlt, (inv_c + gbf_sym(real3(ia.xyz), real3(ia.w, t_ib[lq]))) * dlt);
                    w = gbf_exp(-d / (real(2) * h * h));
                }
                W += w;
                sa += w * real4(t_fa[lq]);
                sb += w * real4(t_fb[lq]);
                sva += (w * w) * real4(t_va[lq]);
                svb += (w * w) * real4(t_vb[lq]);
            }
        }
        ga = sa / W;
        gb = sb / W;
        gva = sva / (W * W);
        gvb = svb / (W * W);
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
