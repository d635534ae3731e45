#version 460
// WLR steps 9-10 (spec §2.3) per pixel: the local space and the curvature
// bandwidths b_j that wlr_fit stored (`state`, lib/wlr.glsl WLR_STATE_IN), the
// final local linear fit at h = hbar_c (FEW, NONNEG, rejection per options), output
// clamped >= 0 (§0.4 step 5), and MSE_c from the model wlr_fit stored (with
// the stored k; hbar clamped to [0.01, 1], a no-op for consistent input).
// Scalar twin: src/reference/wlr_final.rs (routines: src/reference/wlr.rs).
//
// flags = wlr_fit's flags | bit 1 FEW in the final fit | bit 0 SOLVE-FAIL
// (then output y_c and MSE = vbar_c). Invalid centre (§0.2): the mean colour
// of its valid 3x3 neighbours (or 0), clamped >= 0 like every final output
// (§0.4 step 5), mse 0, flags bit 5.
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::WlrPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint radius;
    uint options;
    uint ring_rows;
    uint pad1;
    uint pad2;
} push;

// The features packed by gbf_pack, as in wlr_fit.comp (the variances are
// not read: only the TSVD reads them, and wlr_fit's is reused).
layout(std430, set = 0, binding = 0) readonly buffer fa_blk { vec4 fa[]; };
layout(std430, set = 0, binding = 1) readonly buffer fb_blk { vec4 fb[]; };
PLANE_IN(2, col_r)
PLANE_IN(3, col_g)
PLANE_IN(4, col_b)
PLANE_IN(5, vbar_p)
PLANE_IN(6, spp)
PLANE_IN(7, hbar_p)
PLANE_IN(8, lambda1_p)
PLANE_IN(9, kappa0_p)
PLANE_IN(10, kappa1_p)
PLANE_IN(11, kflags_p)
layout(std430, set = 0, binding = 12) readonly buffer state_blk { real4 state[]; };
#define WLR_STATE_IN
PLANE_OUT(13, out_r)
PLANE_OUT(14, out_g)
PLANE_OUT(15, out_b)
PLANE_OUT(16, mse_out)
PLANE_OUT(17, flags_out)
#ifdef WLR_VIS
// WLR-VIS (the `_vis` kernels): the prefiltered visibility.
PLANE_IN(18, vis_p)
#endif

#define WLR_NFIT 1
#include "lib/wlr.glsl"

// The features as in wlr_fit.comp; the fits do not read the variances (only
// the TSVD does, and wlr_fit's is reused).
bool load_features(ivec2 p, out real x[MAX_D], out real e2[MAX_D])
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
#ifdef WLR_VIS
    x[9] = real(vis_p[i]);
#endif
    for (int j = 0; j < MAX_D; ++j) {
        e2[j] = real(0);
    }
    return spp_of(b.w) >= 1.0;  // PACKED-SPP
}

void load_colour(ivec2 p, out real3 y, out real vbar)
{
    uint i = uint(p.y) * push.width + uint(p.x);
    y = real3(col_r[i], col_g[i], col_b[i]);
    vbar = real(vbar_p[i]);
}

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    uint i = y * push.width + x;
    ivec2 c = ivec2(x, y);
    ivec2 size = ivec2(push.width, push.height);
    float n = spp_of(spp[i]);
    real3 f = real3(0);
    float mse = 0.0;
    int flags = 0;
    if (n < 1.0) {
        // §0.2: mean of the valid 3x3 neighbours.
        real3 sum = real3(0);
        int cnt = 0;
        for (int qy = max(c.y - 1, 0); qy <= min(c.y + 1, size.y - 1); ++qy) {
            for (int qx = max(c.x - 1, 0); qx <= min(c.x + 1, size.x - 1); ++qx) {
                uint q = uint(qy) * push.width + uint(qx);
                if (spp_of(spp[q]) >= 1.0) {
                    sum += real3(col_r[q], col_g[q], col_b[q]);
                    ++cnt;
                }
            }
        }
        f = cnt > 0 ? max(sum / real(cnt), real3(0)) : real3(0);
        flags = WLR_F_INVALID;
    } else {
        int R = int(push.radius);
        int kf = int(kflags_p[i] + 0.5);
        int k_st = kf % 16;
        flags = kf / 16;
#ifdef MC_DD
        dd h = dd_clamp(dd_from(hbar_p[i]), wlr_h_min_dd(), wlr_h_max_dd());
#else
        double h = clamp(double(hbar_p[i]), WLR_H_MIN, WLR_H_MAX);
#endif
        WlrCentre cc = wlr_centre(c, real(n));
        f = cc.y;
        bool failed = false;
        if (k_st == 0) {
            flags |= WLR_F_K0;
        } else {
            TsvdProj pr;
            real b[MAX_D];
            if (!wlr_state_load(c, k_st, pr, b)) {
                flags |= WLR_F_SOLVE_FAIL;
                failed = true;
            } else {
                // Step 9: step 5's fit at h = hbar_c.
                real hs[1];
#ifdef MC_DD
                hs[0] = real(dd_to_float(h));
#else
                hs[0] = real(h);
#endif
                WlrFit fit[1];
                wlr_fits(pr, cc, b, hs, R, size, push.options, real(WLR_FIT_LAMBDA), fit);
                f = fit[0].f;
                flags |= fit[0].flags;
                failed = (fit[0].flags & WLR_F_SOLVE_FAIL) != 0;
            }
        }
        // Step 10 (SOLVE-FAIL: the error of the pass-through, vbar_c).
#ifdef MC_DD
        mse = failed ? float(max(cc.vbar, real(0)))
                     : dd_to_float(wlr_mse_model_dd(dd_from(lambda1_p[i]), dd_from(kappa0_p[i]),
                                                    dd_from(kappa1_p[i]), k_st, dd_from(n), h));
#else
        mse = failed ? float(max(cc.vbar, real(0)))
                     : float(wlr_mse_model(double(lambda1_p[i]), double(kappa0_p[i]),
                                           double(kappa1_p[i]), k_st, double(n), h));
#endif
        f = max(f, real3(0));
    }
    out_r[i] = float(f.r);
    out_g[i] = float(f.g);
    out_b[i] = float(f.b);
    // Planes nobody reads back are not written (WlrPush::options).
    if ((push.options & WLR_SKIP_MSE) == 0u) {
        mse_out[i] = mse;
    }
    if ((push.options & WLR_SKIP_DEBUG) == 0u) {
        flags_out[i] = float(flags);
    }
}
