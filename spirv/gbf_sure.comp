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

#define TILE (8 + 2 * GBF_RADIUS)
shared vec4 t_pos[TILE * TILE];  // position, valid (1) or not (0, also outside)
shared vec4 t_ia[TILE * TILE];   // S~^-1 XX XY XZ YY
shared vec2 t_ib[TILE * TILE];   // S~^-1 YZ ZZ

void main()
{
    // The workgroup's 8x8 pixels and their 3-pixel halo, staged once.
    ivec2 org = ivec2(gl_WorkGroupID.x * 8u, push.row0 + gl_WorkGroupID.y * 8u) - GBF_RADIUS;
    for (uint k = gl_LocalInvocationIndex; k < uint(TILE * TILE); k += 64u) {
        ivec2 t = org + ivec2(k % uint(TILE), k / uint(TILE));
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
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    uint c = y * push.width + x;
    if (!gbf_valid(c)) {
        h_opt[c] = 0.0;
        return;
    }
    real3 pc = gbf_position(c);
    realmat3 inv_c = gbf_inv_cov(c);
    real vbar = (real(vx[c]) + real(vy[c]) + real(vz[c])) / real(3);
    real W[5];
    real3 sw_d[5];
    real sw_dd[5];
    real3 sw_md[5];
    for (int s = 0; s < 5; ++s) {
        W[s] = real(0);
        sw_d[s] = real3(0);
        sw_dd[s] = real(0);
        sw_md[s] = real3(0);
    }
    uint lc = (gl_LocalInvocationID.y + uint(GBF_RADIUS)) * uint(TILE) + gl_LocalInvocationID.x + uint(GBF_RADIUS);
    for (int dy = -GBF_RADIUS; dy <= GBF_RADIUS; ++dy) {
        for (int dx = -GBF_RADIUS; dx <= GBF_RADIUS; ++dx) {
            uint lq = uint(int(lc) + dy * TILE + dx);
            vec4 tp = t_pos[lq];
            if (tp.w == 0.0) {
                continue;
            }
            if (lq == lc) {
                for (int s = 0; s < 5; ++s) {
                    W[s] += real(1);
                }
                continue;
            }
            vec4 ia = t_ia[lq];
            vec2 ib = t_ib[lq];
            real3 dlt = real3(tp.xyz) - pc;
            real3 md = (inv_c + gbf_sym(real3(ia.xyz), real3(ia.w, ib))) * dlt;
            real d = dot(dlt, md);
            // w_s = exp(-d / (2 h_s^2)) = exp(-a / (s+1)^2), a = d / 0.32:
            // three exps; w_1 = w_4^4 and w_0 = w_1^4 by squaring (relative
            // error ~16 ulp of f32, far below tolerance).
            real a = d / real(0.32);
            real w3 = gbf_exp(-a / real(16));
            real t = w3 * w3;
            real w1 = t * t;
            t = w1 * w1;
            real wv[5] = real[5](t * t, w1, gbf_exp(-a / real(9)), w3, gbf_exp(-a / real(25)));
            for (int s = 0; s < 5; ++s) {
                real w = wv[s];
                W[s] += w;
                sw_d[s] += w * dlt;
                sw_dd[s] += w * d;
                sw_md[s] += w * md;
            }
        }
    }
    real best = vbar;  // SURE(0)
    real hbest = real(0);
    for (int s = 0; s < 5; ++s) {
        real h = real(0.4) * real(s + 1);
        real3 dhat = sw_d[s] / W[s];
        real div = real(3) / W[s] + (sw_dd[s] - dot(sw_md[s], dhat)) / (W[s] * h * h);
        real sure = dot(dhat, dhat) / real(3) - vbar + real(2) * vbar / real(3) * div;
        if (sure < best) {
            best = sure;
            hbest = h;
        }
    }
    h_opt[c] = float(hbest);
}
