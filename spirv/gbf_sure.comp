#version 460
// G-buffer prefilter (spec §6) steps 2-7 per pixel: distances with the
// inverse regularised smoothed covariances (gbf_prepare), the filtered position and its divergence
// at h = 0.4 .. 2.0, SURE, and h_opt (ties to the smaller h; SURE(0) = vbar
// of the position variances). Out: h_opt (0 for an invalid pixel).
// One pass over the 7x7 window accumulates, per h, W, sum w D, sum w d and
// sum w M D (D = p_i - p_c), from which p^ - p_c = sum w D / W and the
// divergence's sum w (M D)^T (p_i - p^) = sum w d - (sum w M D) . (p^ - p_c).
// Scalar twin: src/reference/gbf_sure.rs (routines: src/reference/gbf.rs).
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
PLANE_IN(3, vx)
PLANE_IN(4, vy)
PLANE_IN(5, vz)
PLANE_IN(6, sxx)
PLANE_IN(7, sxy)
PLANE_IN(8, sxz)
PLANE_IN(9, syy)
PLANE_IN(10, syz)
PLANE_IN(11, szz)
PLANE_IN(12, spp)
PLANE_OUT(13, h_opt)

real3 gbf_position(uint q) { return real3(px[q], py[q], pz[q]); }
bool gbf_valid(uint q) { return spp_of(spp[q]) >= 1.0; }

#include "lib/gbf.glsl"

// S~^-1 of pixel q (gbf_prepare).
realmat3 gbf_inv_cov(uint q)
{
    return gbf_sym(real3(sxx[q], sxy[q], sxz[q]), real3(syy[q], syz[q], szz[q]));
}

// Register blocking: an invocation computes SURE for SURE_PX consecutive
// pixels of a row (a workgroup: 8 * SURE_PX x 8 pixels). Each neighbour of
// their joint 7-row window (SURE_PX + 6 wide) is read from the staged tile
// once and accumulated into every pixel whose 7x7 window holds it: lavapipe
// pays per lane and float loaded from shared memory (the loads, not the
// arithmetic, were ~3/4 of this kernel's time), so a pixel costs
// (SURE_PX + 6) / SURE_PX tile reads per window row instead of 7. Each pixel
// still sums its neighbours in raster order (dy, then dx), the centre with
// its weight 1 only, as one invocation per pixel did.
#extension GL_EXT_control_flow_attributes : require
#define SURE_PX 2
#define TILE_W (8 * SURE_PX + 2 * GBF_RADIUS)
#define TILE_H (8 + 2 * GBF_RADIUS)
shared vec4 t_pos[TILE_W * TILE_H];  // position, valid (1) or not (0, also outside)
shared vec4 t_ia[TILE_W * TILE_H];   // S~^-1 XX XY XZ YY
shared vec2 t_ib[TILE_W * TILE_H];   // S~^-1 YZ ZZ

void main()
{
    // The workgroup's 8 SURE_PX x 8 pixels and their 3-pixel halo, staged once.
    ivec2 org = ivec2(gl_WorkGroupID.x * uint(8 * SURE_PX), push.row0 + gl_WorkGroupID.y * 8u) - GBF_RADIUS;
    for (uint k = gl_LocalInvocationIndex; k < uint(TILE_W * TILE_H); k += 64u) {
        ivec2 t = org + ivec2(k % uint(TILE_W), k / uint(TILE_W));
        vec4 pv = vec4(0);
        vec4 ia = vec4(0);
        vec2 ib = vec2(0);
        if (t.x >= 0 && t.y >= 0 && t.x < int(push.width) && t.y < int(push.height)) {
            uint q = uint(t.y) * push.width + uint(t.x);
            if (gbf_valid(q)) {
                pv = vec4(px[q], py[q], pz[q], 1.0);
                ia = vec4(sxx[q], sxy[q], sxz[q], syy[q]);
                ib = vec2(syz[q], szz[q]);
            }
        }
        t_pos[k] = pv;
        t_ia[k] = ia;
        t_ib[k] = ib;
    }
    barrier();
    uint x0 = gl_GlobalInvocationID.x * uint(SURE_PX);
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x0 >= push.width || y >= push.height) {
        return;
    }
    bool act[SURE_PX];
    real3 pc[SURE_PX];
    realmat3 inv_c[SURE_PX];
    real W[SURE_PX][5];
    real3 sw_d[SURE_PX][5];
    real sw_dd[SURE_PX][5];
    real3 sw_md[SURE_PX][5];
    [[unroll]] for (int p = 0; p < SURE_PX; ++p) {
        uint c = y * push.width + x0 + uint(p);
        act[p] = x0 + uint(p) < push.width && gbf_valid(c);
        pc[p] = real3(0);
        inv_c[p] = realmat3(0);
        if (act[p]) {
            pc[p] = gbf_position(c);
            inv_c[p] = gbf_inv_cov(c);
        }
        [[unroll]] for (int s = 0; s < 5; ++s) {
            W[p][s] = real(0);
            sw_d[p][s] = real3(0);
            sw_dd[p][s] = real(0);
            sw_md[p][s] = real3(0);
        }
    }
    // Tile column of the joint window's first neighbour.
    uint lx = gl_LocalInvocationID.x * uint(SURE_PX);
    for (int dy = -GBF_RADIUS; dy <= GBF_RADIUS; ++dy) {
        uint row = (gl_LocalInvocationID.y + uint(GBF_RADIUS + dy)) * uint(TILE_W) + lx;
        [[unroll]] for (int u = 0; u < SURE_PX + 2 * GBF_RADIUS; ++u) {
            vec4 tp = t_pos[row + uint(u)];
            if (tp.w == 0.0) {
                continue;
            }
            vec4 ia = t_ia[row + uint(u)];
            vec2 ib = t_ib[row + uint(u)];
            realmat3 inv_q = gbf_sym(real3(ia.xyz), real3(ia.w, ib));
            [[unroll]] for (int p = 0; p < SURE_PX; ++p) {
                int dx = u - GBF_RADIUS - p;
                if (dx < -GBF_RADIUS || dx > GBF_RADIUS) {
                    continue;
                }
                real3 dlt = real3(tp.xyz) - pc[p];
                real3 md = (inv_c[p] + inv_q) * dlt;
                real d = dot(dlt, md);
                // w_s = exp(-d / (2 h_s^2)) = 2^(-b / (s+1)^2), b = d log2(e) / 0.32,
                // with each constant folded: three exp2 and no division; w_1 =
                // w_4^4 and w_0 = w_1^4 by squaring (relative error ~16 ulp of
                // f32, far below tolerance). The centre's weights are 1.
                real w3 = gbf_exp2(d * real(-GBF_LOG2E / (0.32 * 16.0)));
                real t = w3 * w3;
                real w1 = t * t;
                t = w1 * w1;
                real wv[5] = real[5](t * t, w1, gbf_exp2(d * real(-GBF_LOG2E / (0.32 * 9.0))), w3,
                                     gbf_exp2(d * real(-GBF_LOG2E / (0.32 * 25.0))));
                // The centre adds its weight only (its difference is 0 for a
                // finite position; a select keeps a non-finite one out).
                bool centre = dx == 0 && dy == 0;
                [[unroll]] for (int s = 0; s < 5; ++s) {
                    real w = centre ? real(1) : wv[s];
                    W[p][s] += w;
                    sw_d[p][s] += centre ? real3(0) : w * dlt;
                    sw_dd[p][s] += centre ? real(0) : w * d;
                    sw_md[p][s] += centre ? real3(0) : w * md;
                }
            }
        }
    }
    [[unroll]] for (int p = 0; p < SURE_PX; ++p) {
        uint c = y * push.width + x0 + uint(p);
        if (x0 + uint(p) >= push.width) {
            continue;
        }
        real vbar = (real(vx[c]) + real(vy[c]) + real(vz[c])) / real(3);
        real best = vbar;  // SURE(0)
        real hbest = real(0);
        [[unroll]] for (int s = 0; s < 5; ++s) {
            real h = real(0.4) * real(s + 1);
            real3 dhat = sw_d[p][s] / W[p][s];
            real div = real(3) / W[p][s] + (sw_dd[p][s] - dot(sw_md[p][s], dhat)) / (W[p][s] * h * h);
            real sure = dot(dhat, dhat) / real(3) - vbar + real(2) * vbar / real(3) * div;
            if (sure < best) {
                best = sure;
                hbest = h;
            }
        }
        h_opt[c] = act[p] ? float(hbest) : 0.0;
    }
}
