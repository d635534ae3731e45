// APR's shared per-block routines (spec §4.2-4.3), used by apr_block.comp
// and apr_gather.comp. Scalar twins: src/reference/apr_block.rs (design,
// weights, acceptance, coverage) and src/reference/apr_gather.rs.
//
// The including kernel declares, before the include: the push block `push`
// (AprPush: width, height, row0, channel, mode, last, flags, stride), the
// feature planes f0..f7 (normal xyz, albedo rgb, depth, visibility),
// `spp`, and `sppt`, spp_total's three words.
//
// Design row (fixed 18 columns, reference::apr_block): five real4,
// x0 = (1, dnx, dny, dnz), x1 = (dar, dag, dab, ddepth),
// x2 = (dvis, u, v, uu), x3 = (uv, vv, uuu, uuv), x4 = (uvv, vvv, 0, 0),
// with d = (f_i - f_c) / s (0 for a dropped feature) and u, v the offsets
// divided by R = 14. Order K uses the leading 9, 11, 14, 18 columns.
// The temporal window (spec §10.2, APR_TEMPORAL in push.flags;
// APR-TEMPORAL-COLUMNS): x2 = (dvis, u, v, t), x3 = (uu, uv, vv, uuu),
// x4 = (uuv, uvv, vvv, 0), t = dt / 2; orders 0..3 use 9, 12, 15, 19
// columns (the solve's padding column 18 gets the ridge, apr_pad_ridge).
// push.window then holds bit k (k = 0..4, frames t-2..t+2) for a present
// frame and, at bits 8 + 4k, the ring slot of its planes, push.stride
// floats (vec4s in fa, fb) apart; sppt holds APR_SPPT_SLOT words per slot.

#ifndef MC_APR_GLSL
#define MC_APR_GLSL

#define APR_R 14
#define APR_P 18
#define APR_REJECT 3.0
#define APR_RIDGE 1e-6
#define APR_FEATURE_EPS 1e-6
#define APR_STATE 52
// Offsets in a block's state record (mirror reference::apr_block::ST_*):
// beta_y, beta_s and the feature spreads start on multiples of 4, so that
// apr_gather reads them as vec4s (APR-STATE-VEC4).
#define APR_ST_BETA_Y 4
#define APR_ST_BETA_S 24
#define APR_ST_SCALES 44
#define APR_RIDGE_FLOOR 1e-8
#define APR_RETRIES 3
// AprPush.flags bits (mirror mcdenoise::shared::APR_VIS, APR_CLAMPED).
#define APR_VIS 1u
#define APR_CLAMPED 2u
// AprPush.flags bit (mirror mcdenoise::shared::APR_COUNT_CAP), and the
// multiple of the mean count the test's precision stops at (mirror
// reference::apr::COUNT_CAP_K).
#define APR_COUNT_CAP 8u
#define APR_COUNT_CAP_K 2.0
// AprPush.flags bit (mirror mcdenoise::shared::APR_TEMPORAL) and the
// spp_total words per ring slot (mirror shared::APR_SPPT_SLOT).
#define APR_TEMPORAL 16u
#define APR_SPPT_SLOT 64u

bool apr_temporal() { return (push.flags & APR_TEMPORAL) != 0u; }

// Frame k of the window (0..4, the centre 2): whether it is present, and
// the first index of its planes in the bindings (0 for a single frame).
bool apr_present(int k)
{
    return apr_temporal() ? ((push.window >> uint(k)) & 1u) != 0u : k == 2;
}
uint apr_slot(int k) { return apr_temporal() ? (push.window >> (8u + 4u * uint(k))) & 15u : 0u; }
uint apr_base(int k) { return apr_slot(k) * push.stride; }

// The ridge of the design's column 18: a polynomial column in the temporal
// window, padding (1) otherwise (lib/apr_solve.glsl).
real apr_pad_ridge(real lambda) { return apr_temporal() ? lambda : real(1); }

bool apr_valid(uint i) { return spp_of(spp[i]) >= 1.0; }

// Normal xyz and albedo r (apr_pack's plane fa).
real4 apr_fa(uint i) { return real4(fa[i]); }
// Albedo g b, depth, visibility (apr_pack's plane fb: 0 without APR_VIS).
real4 apr_fb(uint i) { return real4(fb[i]); }

// K_h(i) for the offset (dx, dy), h = 14. GLSL has no f64 exp: computed in
// f32 (twin: f64, the difference is within spec §0.3).
real apr_weight(int dx, int dy)
{
    return real(exp(-float(dx * dx + dy * dy) / float(2 * APR_R * APR_R)));
}

// The block's kernel at a pixel with spatial weight k and variance vq:
// K_h * o_q, o_q = 1 / max(vq, 1) with APR_CLAMPED (APR-OUTLIER-W).
real apr_fit_weight(real k, real vq)
{
    return (push.flags & APR_CLAMPED) != 0u ? k / max(vq, real(1)) : k;
}

// The confidence-interval test (§4.2 step 1) of pixel q in the block of c,
// on the variances apr_test_var gives.
bool apr_accepts(real yc, real vc, real yq, real vq)
{
    return abs(yq - yc) <= real(APR_REJECT) * sqrt(max(vq + vc, real(0)));
}

// The image's mean sample count over its valid pixels (spp_total).
float apr_nbar()
{
    return spp_total_mean(sppt[0], sppt[1], sppt[2]);
}

// Frame k's mean count (its own slot's spp_total words).
float apr_nbar_of(int k)
{
    uint o = apr_slot(k) * APR_SPPT_SLOT;
    return spp_total_mean(sppt[o], sppt[o + 1u], sppt[o + 2u]);
}

// K(i) of the temporal window (3D-KERNEL): h = 14 in space, 2 in frames;
// dt = 0 gives apr_weight's value.
real apr_weight_dt(int dx, int dy, int dt)
{
    return real(exp(-float(dx * dx + dy * dy) / float(2 * APR_R * APR_R) - float(dt * dt) / 8.0));
}

// The factor on pixel q's variance in the interval test: with
// APR_COUNT_CAP, max(1, n_q / (K nbar)), so that a pixel with more than
// APR_COUNT_CAP_K times the image's mean count nbar is tested at the
// variance it would have with K nbar (APR-COUNT-CAP); else 1. Twin:
// reference::apr::test_scale.
real apr_test_scale(uint q, float nbar)
{
    if ((push.flags & APR_COUNT_CAP) == 0u || nbar <= 0.0) {
        return real(1);
    }
    return real(max(1.0, spp_of(spp[q]) / (APR_COUNT_CAP_K * nbar)));
}

// The variance v of pixel q as the interval test takes it.
real apr_test_var(real v, uint q, float nbar)
{
    return v * apr_test_scale(q, nbar);
}

// The design row of pixel q (position dq = q - c) for a block with centre
// features (fca, fcb) and inverse spreads (isa, isb; 0 = dropped).
// dt: the pixel's frame minus the centre's (the temporal layout).
void apr_row(ivec2 dq, int dt, real4 fa, real4 fb, real4 fca, real4 fcb, real4 isa, real4 isb,
             out real4 x0, out real4 x1, out real4 x2, out real4 x3, out real4 x4)
{
    real4 d = (fa - fca) * isa;
    real4 e = (fb - fcb) * isb;
    real u = real(dq.x) / real(APR_R);
    real v = real(dq.y) / real(APR_R);
    x0 = real4(1, d.xyz);
    x1 = real4(d.w, e.xyz);
    if (apr_temporal()) {
        real t = real(dt) / real(2);
        x2 = real4(e.w, u, v, t);
        x3 = real4(u * u, u * v, v * v, u * u * u);
        x4 = real4(u * u * v, u * v * v, v * v * v, 0);
        return;
    }
    x2 = real4(e.w, u, v, u * u);
    x3 = real4(u * v, v * v, u * u * u, u * u * v);
    x4 = real4(u * v * v, v * v * v, 0, 0);
}

// The first sparse centre coordinate whose window holds a (|a - c| <= 14).
int apr_first_centre(int a) { return ((max(a - APR_R, 0) + APR_R - 1) / APR_R) * APR_R; }

#endif
