#version 460
// WLR steps 1-7 (spec §2.3) per pixel: TSVD, curvature bandwidths b_j, the
// five trial fits, the parametric fits (double) and h_opt with H-CASES.
// Scalar twin: src/reference/wlr_fit.rs (routines: src/reference/wlr.rs).
//
// Outputs: h_opt, lambda1, kappa0, kappa1 of the MSE model
// MSE(h) = (lambda1 h^2)^2 + (kappa0 + kappa1 h^-k)/n_c (pass-through and
// kappa1 <= 0 pixels: lambda1 = kappa1 = 0, kappa0 = n_c MSE_fixed),
// kflags = k + 16 flags (§2.5 bits 0, 2, 3, 4), b_1..b_3 (0 for j >= k);
// for k >= 1 the local space and the b_j in `state` (lib/wlr.glsl,
// WLR_STATE_OUT), which wlr_final reads. An invalid centre gets 0 everywhere
// (and no state).
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

// The features and their variances, packed by gbf_pack: (normal xyz,
// depth), (albedo rgb, 0), and the same of the variances; one vec4 load
// instead of four scalar ones (llvmpipe pays per load).
layout(std430, set = 0, binding = 0) readonly buffer fa_blk { vec4 fa[]; };
layout(std430, set = 0, binding = 1) readonly buffer fb_blk { vec4 fb[]; };
layout(std430, set = 0, binding = 2) readonly buffer va_blk { vec4 va[]; };
layout(std430, set = 0, binding = 3) readonly buffer vb_blk { vec4 vb[]; };
PLANE_IN(4, col_r)
PLANE_IN(5, col_g)
PLANE_IN(6, col_b)
PLANE_IN(7, vbar_p)
PLANE_IN(8, spp)
PLANE_OUT(9, h_opt_out)
PLANE_OUT(10, lambda1_out)
PLANE_OUT(11, kappa0_out)
PLANE_OUT(12, kappa1_out)
PLANE_OUT(13, kflags_out)
PLANE_OUT(14, b1_out)
PLANE_OUT(15, b2_out)
PLANE_OUT(16, b3_out)
// The centre state for wlr_final (lib/wlr.glsl, WLR_STATE_OUT).
layout(std430, set = 0, binding = 17) buffer state_blk { real4 state[]; };
#define WLR_STATE_OUT
#ifdef WLR_VIS
// WLR-VIS (the `_vis` kernels): the prefiltered visibility and its variance.
PLANE_IN(18, vis_p)
PLANE_IN(19, vis_var_p)
#endif

#define WLR_NFIT 5
#include "lib/wlr.glsl"



#define NONE 1

// Features (px, py, nrm xyz, dep, albedo rgb), variances (0, 0, vn xyz, vd,
// va rgb); valid iff spp_of >= 1 (spec §0.2, §2.1).
bool load_features(ivec2 p, out real x[MAX_D], out real e2[MAX_D])
{
    uint i = uint(p.y) * push.width + uint(p.x);
    vec4 a = fa[i];
    vec4 b = fb[i];
    vec4 u = va[i];
    vec4 v = vb[i];
    x[0] = real(p.x);
    x[1] = real(p.y);
    x[2] = real(a.x);
    x[3] = real(a.y);
    x[4] = real(a.z);
    x[5] = real(a.w);
    x[6] = real(b.x);
    x[7] = real(b.y);
    x[8] = real(b.z);
    e2[0] = real(0);
    e2[1] = real(0);
    e2[2] = real(u.x);
    e2[3] = real(u.y);
    e2[4] = real(u.z);
    e2[5] = real(u.w);
    e2[6] = real(v.x);
    e2[7] = real(v.y);
    e2[8] = real(v.z);
#ifdef WLR_VIS
    x[9] = real(vis_p[i]);
    e2[9] = real(vis_var_p[i]);
#endif
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
    float o[8];
    for (int j = 0; j < 8; ++j) {
        o[j] = 0.0;
    }
    float n = spp_of(spp[i]);
    if (n >= 1.0) {
        ivec2 c = ivec2(x, y);
        ivec2 size = ivec2(push.width, push.height);
        int R = int(push.radius);
        // Step 1: TSVD (§0.6).
        LocalSpace ls = tsvd_local_space(c, R, size);
        WlrCentre cc = wlr_centre(c, real(n));
        int k = ls.k;
        int flags = 0;
        // Pass-through model: h_opt = 0.2, MSE = vbar_c.
#ifdef MC_DD
        dd model[4];
        model[0] = wlr_trial_h_dd(0);
        model[1] = dd_from(0.0);
        model[2] = dd_mul(dd_from(n), dd_from(float(cc.vbar)));
        model[3] = dd_from(0.0);
#else
        dvec4 model = dvec4(wlr_trial_h(0), 0.0lf, double(n) * double(cc.vbar), 0.0lf);
#endif
        if (k == 0) {
            flags |= WLR_F_K0;
        } else {
            TsvdProj pr = tsvd_projection(ls);
            real b[MAX_D];
            real Hb[MAX_D];
            // Step 4.
            bool curved = wlr_curvature(pr, cc, R, size, push.options, b, Hb);
            if (!curved) {
                for (int j = 0; j < MAX_D; ++j) {
                    b[j] = real(0);
                }
            }
            wlr_state_store(c, pr, b, curved);
            if (!curved) {
                flags |= WLR_F_SOLVE_FAIL;
            } else {
                o[5] = float(b[0]);
                o[6] = float(b[1]);
                o[7] = float(b[2]);
                // Step 5: the five trial fits.
                real hs[WLR_NFIT];
                for (int s = 0; s < WLR_NFIT; ++s) {
                    hs[s] = wlr_trial_h_real(s);
                }
                WlrFit fit[WLR_NFIT];
                wlr_fits(pr, cc, b, hs, R, size, push.options, real(WLR_FIT_LAMBDA), fit);
#ifdef MC_DD
                dd bias[5];
                dd var[5];
                for (int s = 0; s < 5; ++s) {
                    flags |= fit[s].flags & WLR_F_SOLVE_FAIL;
                    bias[s] = dd_from(float(fit[s].bias));
                    var[s] = dd_from(float(fit[s].var));
                }
                // Steps 6-7 in double-float.
                dd par[4];
                wlr_parametric_dd(bias, var, k, dd_from(n), par);
                wlr_choose_h_dd(par, k, dd_from(n), bias[0], var[0], flags, model);
#else
                double bias[5];
                double var[5];
                for (int s = 0; s < 5; ++s) {
                    flags |= fit[s].flags & WLR_F_SOLVE_FAIL;
                    bias[s] = double(fit[s].bias);
                    var[s] = double(fit[s].var);
                }
                // Steps 6-7 in double.
                dvec4 par = wlr_parametric(bias, var, k, double(n));
                model = wlr_choose_h(par, k, double(n), bias[0], var[0], flags);
#endif
            }
        }
#ifdef MC_DD
        o[0] = dd_to_float(model[0]);
        o[1] = dd_to_float(model[1]);
        o[2] = dd_to_float(model[2]);
        o[3] = dd_to_float(model[3]);
#else
        o[0] = float(model.x);
        o[1] = float(model.y);
        o[2] = float(model.z);
        o[3] = float(model.w);
#endif
        o[4] = float(k + 16 * flags);
    }
    h_opt_out[i] = o[0];
    lambda1_out[i] = o[1];
    kappa0_out[i] = o[2];
    kappa1_out[i] = o[3];
    kflags_out[i] = o[4];
    // The bandwidths are debug layers only (wlr_final reads the state).
    if ((push.options & WLR_SKIP_DEBUG) == 0u) {
        b1_out[i] = o[5];
        b2_out[i] = o[6];
        b3_out[i] = o[7];
    }
}
