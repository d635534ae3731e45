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
    uint count;
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

void main()
{
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
    int x0 = max(int(x) - GBF_RADIUS, 0), x1 = min(int(x) + GBF_RADIUS, int(push.width) - 1);
    int y0 = max(int(y) - GBF_RADIUS, 0), y1 = min(int(y) + GBF_RADIUS, int(push.height) - 1);
    for (int qy = y0; qy <= y1; ++qy) {
        for (int qx = x0; qx <= x1; ++qx) {
            uint q = uint(qy) * push.width + uint(qx);
            if (!gbf_valid(q)) {
                continue;
            }
            if (q == c) {
                for (int s = 0; s < 5; ++s) {
                    W[s] += real(1);
                }
                continue;
            }
            real3 dlt = gbf_position(q) - pc;
            real3 md = (inv_c + gbf_inv_cov(q)) * dlt;
            real d = dot(dlt, md);
            for (int s = 0; s < 5; ++s) {
                real h = real(0.4) * real(s + 1);
                real w = gbf_exp(-d / (real(2) * h * h));
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
