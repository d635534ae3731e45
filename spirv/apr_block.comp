#version 460
// One APR block (spec §4.2) of channel push.channel at one stage: the
// accepted set A_c (confidence-interval test), the feature spreads, the
// moments M = sum K x x^T, V = sum K^2 s2prev x x^T and X^T W of yprev, y
// and s = sqrt(v) over the 29x29 window (K = K_h, times 1/max(v, 1) with
// APR_CLAMPED in push.flags: APR-OUTLIER-W) (mat4 blocks, constant indices),
// one ridge Cholesky of the largest order (APR-RIDGE-BLOCK, SOLVE-FAIL
// retries), L^-1, G = L^-1 V L^-T and E = L^-1 M0 L^-T, then for K = 0..3
// (the leading 9, 11, 14, 18 columns): beta of yprev,
// sum K var = sum_{a,b<p} G_ab E_ab, tr H = sum_{a<p} E_aa; a last pass over the window sums the
// squared bias of the four orders; the order of least error wins (ties to
// the smaller K). beta_y (and beta_s when push.last == 0) of that order.
//
// push.mode 0 (sparse): thread (x, y) of a grid 8 wide <-> block
// b = 8 y + x, centre (14 gx, 14 gy) with (gx, gy) = (b mod gw, b / gw)
// (APR-LINEAR-BLOCKS: every SIMD lane and workgroup holds a block, whatever
// the block grid's shape); the block's 52-float state
// (reference::apr_block::Block::state) goes to
// state[(channel * blocks + gy * gw + gx) * 52]; an invalid centre writes
// zeros. push.mode 1 (extra, COVER, selection): thread <-> pixel of the
// band; a valid pixel no sparse centre accepts is appended to the queue
// (binding 15). push.mode 2 (extra, fits; dispatched indirectly on the
// queue, one invocation per entry): each such pixel becomes a block whose
// values at its own pixel (beta_y[0], beta_s[0], xi, tr H) go to the extra
// planes 4 * channel + k (k * stride floats apart).
// Scalar twin: src/reference/apr_block.rs.
#extension GL_EXT_control_flow_attributes : require
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::AprPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint channel;
    uint mode;
    uint last;
    uint flags;
    uint stride;
    uint window;
} push;

PLANE_IN(0, ych)
PLANE_IN(1, vch)
PLANE_IN(2, yprev)
PLANE_IN(3, s2prev)
// The features packed by apr_pack (APR-PACKED): normal xyz, albedo r;
// albedo g b, depth, visibility.
layout(std430, set = 0, binding = 4) readonly buffer fa_blk { vec4 fa[]; };
layout(std430, set = 0, binding = 5) readonly buffer fb_blk { vec4 fb[]; };
PLANE_IN(6, spp)
PLANE_OUT(7, state)
PLANE_OUT(8, extra)
// Modes 1 and 2: the band's extra blocks, [workgroups x, 1, 1, count,
// pixel indices...] (the caller resets the header before the band).
layout(std430, set = 0, binding = 9) buffer queue_blk { uint queue[]; };
// spp_total's words (APR-COUNT-CAP).
layout(std430, set = 0, binding = 10) readonly buffer sppt_blk { uint sppt[]; };

#include "lib/apr.glsl"

#ifdef MC_F64
#define aprmat4 dmat4
#else
#define aprmat4 mat4
#endif

// The moments as 4x4 blocks: block (a, b), a <= b, entry (4a + r, 4b + c)
// at [c][r].
aprmat4 M00, M01, M02, M03, M04, M11, M12, M13, M14, M22, M23, M24, M33, M34, M44;
aprmat4 V00, V01, V02, V03, V04, V11, V12, V13, V14, V22, V23, V24, V33, V34, V44;

#include "lib/apr_solve.glsl"

void acc(real4 x0, real4 x1, real4 x2, real4 x3, real4 x4, real k, real kv)
{
    real4 w0 = k * x0, w1 = k * x1, w2 = k * x2, w3 = k * x3, w4 = k * x4;
    M00 += outerProduct(w0, x0); M01 += outerProduct(w0, x1); M02 += outerProduct(w0, x2);
    M03 += outerProduct(w0, x3); M04 += outerProduct(w0, x4); M11 += outerProduct(w1, x1);
    M12 += outerProduct(w1, x2); M13 += outerProduct(w1, x3); M14 += outerProduct(w1, x4);
    M22 += outerProduct(w2, x2); M23 += outerProduct(w2, x3); M24 += outerProduct(w2, x4);
    M33 += outerProduct(w3, x3); M34 += outerProduct(w3, x4); M44 += outerProduct(w4, x4);
    real4 v0 = kv * x0, v1 = kv * x1, v2 = kv * x2, v3 = kv * x3, v4 = kv * x4;
    V00 += outerProduct(v0, x0); V01 += outerProduct(v0, x1); V02 += outerProduct(v0, x2);
    V03 += outerProduct(v0, x3); V04 += outerProduct(v0, x4); V11 += outerProduct(v1, x1);
    V12 += outerProduct(v1, x2); V13 += outerProduct(v1, x3); V14 += outerProduct(v1, x4);
    V22 += outerProduct(v2, x2); V23 += outerProduct(v2, x3); V24 += outerProduct(v2, x4);
    V33 += outerProduct(v3, x3); V34 += outerProduct(v3, x4); V44 += outerProduct(v4, x4);
}

void zero_moments_m()
{
    aprmat4 z = aprmat4(real(0));
    M00 = z; M01 = z; M02 = z; M03 = z; M04 = z; M11 = z; M12 = z; M13 = z;
    M14 = z; M22 = z; M23 = z; M24 = z; M33 = z; M34 = z; M44 = z;
}

void zero_moments()
{
    aprmat4 z = aprmat4(real(0));
    M00 = z; M01 = z; M02 = z; M03 = z; M04 = z; M11 = z; M12 = z; M13 = z;
    M14 = z; M22 = z; M23 = z; M24 = z; M33 = z; M34 = z; M44 = z;
    V00 = z; V01 = z; V02 = z; V03 = z; V04 = z; V11 = z; V12 = z; V13 = z;
    V14 = z; V22 = z; V23 = z; V24 = z; V33 = z; V34 = z; V44 = z;
}

struct Result {
    int order;
    real xi;
    real trace;
    bool degenerate;
    real4 sa;
    real4 sb;
    real4 by0, by1, by2, by3, by4;
    real4 bs0, bs1, bs2, bs3, bs4;
};

// Adds k x x^T to the moments M only (the slice's M0 of the temporal
// window, SLICE).
void acc_m(real4 x0, real4 x1, real4 x2, real4 x3, real4 x4, real k)
{
    real4 w0 = k * x0, w1 = k * x1, w2 = k * x2, w3 = k * x3, w4 = k * x4;
    M00 += outerProduct(w0, x0); M01 += outerProduct(w0, x1); M02 += outerProduct(w0, x2);
    M03 += outerProduct(w0, x3); M04 += outerProduct(w0, x4); M11 += outerProduct(w1, x1);
    M12 += outerProduct(w1, x2); M13 += outerProduct(w1, x3); M14 += outerProduct(w1, x4);
    M22 += outerProduct(w2, x2); M23 += outerProduct(w2, x3); M24 += outerProduct(w2, x4);
    M33 += outerProduct(w3, x3); M34 += outerProduct(w3, x4); M44 += outerProduct(w4, x4);
}

// The block of centre c (a pixel of the centre frame, window index 2) over
// the window's frames (one without APR_TEMPORAL). nbar: the centre frame's
// mean count; a neighbour frame's pixels are tested on their own frame's.
Result block(ivec2 c, ivec2 size, bool with_s, float nbar)
{
    bool temporal = apr_temporal();
    uint bc = apr_base(2);
    uint ci = bc + uint(c.y * size.x + c.x);
    real yc = real(ych[ci]);
    real vc = real(vch[ci]);
    real vtc = apr_test_var(vc, ci, nbar);
    real4 fca = apr_fa(ci);
    real4 fcb = apr_fb(ci);
    int y0 = max(c.y - APR_R, 0), y1 = min(c.y + APR_R, size.y - 1);
    int x0 = max(c.x - APR_R, 0), x1 = min(c.x + APR_R, size.x - 1);
    int k0 = temporal ? 0 : 2, k1 = temporal ? 4 : 2;
    // Pass 1: A_c and the feature spreads.
    real4 ma = real4(0), mb = real4(0);
    uint count = 0u;
    bool others = false;
    for (int k = k0; k <= k1; ++k) {
        if (!apr_present(k)) {
            continue;
        }
        uint bk = apr_base(k);
        float nk = k == 2 ? nbar : apr_nbar_of(k);
        for (int qy = y0; qy <= y1; ++qy) {
            for (int qx = x0; qx <= x1; ++qx) {
                uint q = bk + uint(qy * size.x + qx);
                if (!apr_valid(q)
                    || (q != ci && !apr_accepts(yc, vtc, real(ych[q]), apr_test_var(real(vch[q]), q, nk)))) {
                    continue;
                }
                ma = max(ma, abs(apr_fa(q) - fca));
                mb = max(mb, abs(apr_fb(q) - fcb));
                ++count;
                others = others || k != 2;
            }
        }
    }
    Result r;
    r.sa = mix(real4(0), ma, greaterThan(ma, real4(APR_FEATURE_EPS)));
    r.sb = mix(real4(0), mb, greaterThan(mb, real4(APR_FEATURE_EPS)));
    real4 isa = mix(real4(0), real4(1) / max(ma, real4(1e-30)), greaterThan(ma, real4(APR_FEATURE_EPS)));
    real4 isb = mix(real4(0), real4(1) / max(mb, real4(1e-30)), greaterThan(mb, real4(APR_FEATURE_EPS)));
    // Columns 0 and 9..17 (and 18 in the temporal window, whose tau column
    // 11 is zero without another frame: dropped).
    uint kept = temporal ? 0x7fe01u : 0x3fe01u;
    real tau = temporal && !others ? real(0) : real(1);
    if (temporal && !others) {
        kept &= ~(1u << 11);
    }
    kept |= (r.sa.x > 0 ? 1u : 0u) << 1 | (r.sa.y > 0 ? 1u : 0u) << 2 | (r.sa.z > 0 ? 1u : 0u) << 3
        | (r.sa.w > 0 ? 1u : 0u) << 4 | (r.sb.x > 0 ? 1u : 0u) << 5 | (r.sb.y > 0 ? 1u : 0u) << 6
        | (r.sb.z > 0 ? 1u : 0u) << 7 | (r.sb.w > 0 ? 1u : 0u) << 8;
    r.degenerate = true;
    r.order = 0;
    r.xi = vc;
    r.trace = real(1);
    r.by0 = real4(yc, 0, 0, 0);
    r.bs0 = real4(with_s ? sqrt(max(vc, real(0))) : real(0), 0, 0, 0);
    r.by1 = real4(0); r.by2 = real4(0); r.by3 = real4(0); r.by4 = real4(0);
    r.bs1 = real4(0); r.bs2 = real4(0); r.bs3 = real4(0); r.bs4 = real4(0);
    if (count <= 1u) {
        return r;
    }
    // Pass 2: the moments.
    zero_moments();
    real4 bp0 = real4(0), bp1 = real4(0), bp2 = real4(0), bp3 = real4(0), bp4 = real4(0);
    real4 by0 = real4(0), by1 = real4(0), by2 = real4(0), by3 = real4(0), by4 = real4(0);
    real4 bs0 = real4(0), bs1 = real4(0), bs2 = real4(0), bs3 = real4(0), bs4 = real4(0);
    real wsum = real(0), wslice = real(0);
    for (int k = k0; k <= k1; ++k) {
        if (!apr_present(k)) {
            continue;
        }
        uint bk = apr_base(k);
        float nk = k == 2 ? nbar : apr_nbar_of(k);
        for (int qy = y0; qy <= y1; ++qy) {
            for (int qx = x0; qx <= x1; ++qx) {
                uint q = bk + uint(qy * size.x + qx);
                real yq = real(ych[q]);
                real vq = real(vch[q]);
                if (!apr_valid(q) || (q != ci && !apr_accepts(yc, vtc, yq, apr_test_var(vq, q, nk)))) {
                    continue;
                }
                real4 a0, a1, a2, a3, a4;
                apr_row(ivec2(qx, qy) - c, k - 2, apr_fa(q), apr_fb(q), fca, fcb, isa, isb, a0, a1, a2, a3, a4);
                real kw = apr_fit_weight(apr_weight_dt(qx - c.x, qy - c.y, k - 2), vq);
                acc(a0, a1, a2, a3, a4, kw, kw * kw * real(s2prev[q]));
                real kp = kw * real(yprev[q]);
                real ky = kw * yq;
                real ks = kw * sqrt(max(vq, real(0)));
                bp0 += kp * a0; bp1 += kp * a1; bp2 += kp * a2; bp3 += kp * a3; bp4 += kp * a4;
                by0 += ky * a0; by1 += ky * a1; by2 += ky * a2; by3 += ky * a3; by4 += ky * a4;
                bs0 += ks * a0; bs1 += ks * a1; bs2 += ks * a2; bs3 += ks * a3; bs4 += ks * a4;
                wsum += kw;
                if (k == 2) {
                    wslice += kw;
                }
            }
        }
    }
    // The factorisation (APR-RIDGE-BLOCK) with SOLVE-FAIL's retries; the
    // threshold and the retry floor from the kept columns' diagonal.
    real4 kd0 = real4(M00[0][0], M00[1][1], M00[2][2], M00[3][3]);
    real4 kd1 = real4(M11[0][0], M11[1][1], M11[2][2], M11[3][3]);
    real4 kd2 = real4(M22[0][0], M22[1][1], M22[2][2], M22[3][3]);
    real4 kd3 = real4(M33[0][0], M33[1][1], M33[2][2], M33[3][3]);
    real t18 = temporal ? real(1) : real(0);
    real4 kd4 = real4(M44[0][0], M44[1][1], t18 * M44[2][2], 0);
    real4 k0v = real4(1, r.sa.x > 0 ? 1 : 0, r.sa.y > 0 ? 1 : 0, r.sa.z > 0 ? 1 : 0);
    real4 k1v = real4(r.sa.w > 0 ? 1 : 0, r.sb.x > 0 ? 1 : 0, r.sb.y > 0 ? 1 : 0, r.sb.z > 0 ? 1 : 0);
    real4 k2v = real4(r.sb.w > 0 ? 1 : 0, 1, 1, tau);
    real4 k3v = real4(1);
    real4 k4v = real4(1, 1, t18, 0);
    real mean_diag = (dot(kd0, k0v) + dot(kd1, k1v) + dot(kd2, k2v) + dot(kd3, k3v) + dot(kd4, k4v))
        / (dot(k0v, real4(1)) + dot(k1v, real4(1)) + dot(k2v, real4(1)) + dot(k3v, real4(1)) + dot(k4v, real4(1)));
    real4 kmax0 = kd0 * k0v, kmax1 = kd1 * k1v, kmax2 = kd2 * k2v, kmax3 = kd3 * k3v, kmax4 = kd4 * k4v;
    real lambda = real(APR_RIDGE) * wsum;
    bool ok = false;
    [[dont_unroll]] for (int attempt = 0; attempt <= APR_RETRIES && !ok; ++attempt) {
        if (attempt > 0) {
            lambda = max(real(10) * lambda, real(APR_RIDGE_FLOOR) * mean_diag);
        }
        // Diagonals with the ridge (not on the intercept).
        real4 lam = real4(lambda);
        real4 mx = max(max(max(kmax0 + k0v * real4(0, lambda, lambda, lambda), kmax1 + k1v * lam),
                           max(kmax2 + k2v * lam, kmax3 + k3v * lam)), kmax4 + k4v * lam);
        real thresh = real(EPS_PIVOT) * max(max(mx.x, mx.y), max(mx.z, mx.w));
        ok = apr_factor(lambda, kept, thresh);
    }
    if (!ok) {
        return r;
    }
    if (temporal) {
        // SLICE: the error and the trace are the centre frame's, E from its
        // moments M0 (the factor no longer needs M).
        zero_moments_m();
        uint b2 = apr_base(2);
        for (int qy = y0; qy <= y1; ++qy) {
            for (int qx = x0; qx <= x1; ++qx) {
                uint q = b2 + uint(qy * size.x + qx);
                real vq = real(vch[q]);
                if (!apr_valid(q) || (q != ci && !apr_accepts(yc, vtc, real(ych[q]), apr_test_var(vq, q, nbar)))) {
                    continue;
                }
                real4 a0, a1, a2, a3, a4;
                apr_row(ivec2(qx, qy) - c, 0, apr_fa(q), apr_fb(q), fca, fcb, isa, isb, a0, a1, a2, a3, a4);
                acc_m(a0, a1, a2, a3, a4, apr_fit_weight(apr_weight_dt(qx - c.x, qy - c.y, 0), vq));
            }
        }
    }
    apr_products();
    real4 xi = real4(0);
    real4 trace = real4(0);
    real4 B00, B01, B02, B03, B04, B10, B11, B12, B13, B14;
    real4 B20, B21, B22, B23, B24, B30, B31, B32, B33, B34;
    // The orders' column counts: 9, 11, 14, 18, or 9, 12, 15, 19 in the
    // temporal window.
    ivec4 pk = temporal ? ivec4(9, 12, 15, 19) : ivec4(9, 11, 14, 18);
    apr_order_sums(pk.x, trace.x, xi.x);
    apr_order_sums(pk.y, trace.y, xi.y);
    apr_order_sums(pk.z, trace.z, xi.z);
    apr_order_sums(pk.w, trace.w, xi.w);
    apr_solve(pk.x, bp0, bp1, bp2, bp3, bp4, B00, B01, B02, B03, B04);
    apr_solve(pk.y, bp0, bp1, bp2, bp3, bp4, B10, B11, B12, B13, B14);
    apr_solve(pk.z, bp0, bp1, bp2, bp3, bp4, B20, B21, B22, B23, B24);
    apr_solve(pk.w, bp0, bp1, bp2, bp3, bp4, B30, B31, B32, B33, B34);
    // Pass 3: the squared bias of each order, over the centre frame.
    real4 rss = real4(0);
    uint b2 = apr_base(2);
    for (int qy = y0; qy <= y1; ++qy) {
        for (int qx = x0; qx <= x1; ++qx) {
            uint q = b2 + uint(qy * size.x + qx);
            real vq = real(vch[q]);
            if (!apr_valid(q) || (q != ci && !apr_accepts(yc, vtc, real(ych[q]), apr_test_var(vq, q, nbar)))) {
                continue;
            }
            real4 a0, a1, a2, a3, a4;
            apr_row(ivec2(qx, qy) - c, 0, apr_fa(q), apr_fb(q), fca, fcb, isa, isb, a0, a1, a2, a3, a4);
            real yp = real(yprev[q]);
            real4 e = real4(
                dot(a0, B00) + dot(a1, B01) + dot(a2, B02) + dot(a3, B03) + dot(a4, B04),
                dot(a0, B10) + dot(a1, B11) + dot(a2, B12) + dot(a3, B13) + dot(a4, B14),
                dot(a0, B20) + dot(a1, B21) + dot(a2, B22) + dot(a3, B23) + dot(a4, B24),
                dot(a0, B30) + dot(a1, B31) + dot(a2, B32) + dot(a3, B33) + dot(a4, B34)) - yp;
            rss += apr_fit_weight(apr_weight_dt(qx - c.x, qy - c.y, 0), vq) * e * e;
        }
    }
    xi = (rss + xi) / (temporal ? wslice : wsum);
    int best = 0;
    real bx = xi.x;
    real bt = trace.x;
    if (xi.y < bx) { best = 1; bx = xi.y; bt = trace.y; }
    if (xi.z < bx) { best = 2; bx = xi.z; bt = trace.z; }
    if (xi.w < bx) { best = 3; bx = xi.w; bt = trace.w; }
    int p = best == 0 ? pk.x : (best == 1 ? pk.y : (best == 2 ? pk.z : pk.w));
    apr_solve(p, by0, by1, by2, by3, by4, r.by0, r.by1, r.by2, r.by3, r.by4);
    if (with_s) {
        apr_solve(p, bs0, bs1, bs2, bs3, bs4, r.bs0, r.bs1, r.bs2, r.bs3, r.bs4);
    }
    r.degenerate = false;
    r.order = best;
    r.xi = bx;
    r.trace = bt;
    return r;
}

// Whether some valid sparse centre within 14 accepts pixel p.
bool covered(ivec2 p, ivec2 size, float nbar)
{
    uint b2 = apr_base(2);
    uint i = b2 + uint(p.y * size.x + p.x);
    real yi = real(ych[i]);
    real vi = apr_test_var(real(vch[i]), i, nbar);
    for (int cy = apr_first_centre(p.y); cy <= min(p.y + APR_R, size.y - 1); cy += APR_R) {
        for (int cx = apr_first_centre(p.x); cx <= min(p.x + APR_R, size.x - 1); cx += APR_R) {
            uint c = b2 + uint(cy * size.x + cx);
            if (apr_valid(c) && (c == i || apr_accepts(real(ych[c]), apr_test_var(real(vch[c]), c, nbar), yi, vi))) {
                return true;
            }
        }
    }
    return false;
}

void main()
{
    ivec2 size = ivec2(push.width, push.height);
    bool with_s = push.last == 0u;
    float nbar = apr_nbar_of(2);
    int gw = (size.x + APR_R - 1) / APR_R;
    int gh = (size.y + APR_R - 1) / APR_R;
    if (push.mode == 0u) {
        uint b = (push.row0 + gl_GlobalInvocationID.y) * 8u + gl_GlobalInvocationID.x;
        ivec2 g = ivec2(int(b % uint(gw)), int(b / uint(gw)));
        if (g.y >= gh) {
            return;
        }
        ivec2 c = g * APR_R;
        uint base = (push.channel * uint(gw * gh) + uint(g.y * gw + g.x)) * uint(APR_STATE);
        if (!apr_valid(apr_base(2) + uint(c.y * size.x + c.x))) {
            for (int k = 0; k < APR_STATE; ++k) {
                state[base + uint(k)] = 0.0;
            }
            return;
        }
        Result r = block(c, size, with_s, nbar);
        state[base] = float(r.order);
        state[base + 1u] = float(r.xi);
        state[base + 2u] = float(r.trace);
        state[base + 3u] = r.degenerate ? 1.0 : 0.0;
        real4 by[5] = real4[5](r.by0, r.by1, r.by2, r.by3, r.by4);
        real4 bs[5] = real4[5](r.bs0, r.bs1, r.bs2, r.bs3, r.bs4);
        // beta_y and beta_s each fill 5 vec4 slots (0 past the chosen
        // order's columns).
        for (int k = 0; k < 5; ++k) {
            for (int t = 0; t < 4; ++t) {
                state[base + uint(APR_ST_BETA_Y + 4 * k + t)] = float(by[k][t]);
                state[base + uint(APR_ST_BETA_S + 4 * k + t)] = float(bs[k][t]);
            }
        }
        real s8[8] = real[8](r.sa.x, r.sa.y, r.sa.z, r.sa.w, r.sb.x, r.sb.y, r.sb.z, r.sb.w);
        for (int j = 0; j < 8; ++j) {
            state[base + uint(APR_ST_SCALES + j)] = float(s8[j]);
        }
        return;
    }
    if (push.mode == 1u) {
        // Extra blocks, selection: a valid pixel no sparse centre accepts
        // is appended to the queue, in workgroups of 64 for mode 2.
        uint x = gl_GlobalInvocationID.x;
        uint y = push.row0 + gl_GlobalInvocationID.y;
        if (x < push.width && y < push.height && apr_valid(apr_base(2) + y * push.width + x)
            && !covered(ivec2(x, y), size, nbar)) {
            QUEUE_APPEND(queue, y * push.width + x, 64u, QUEUE_ROOM(queue))
        }
        return;
    }
    // Extra blocks, fits (mode 2, dispatched indirectly on the queue): every
    // SIMD lane holds one (APR-EXTRA-QUEUE; compacted per 8x8 workgroup, a
    // tile's one or two extra pixels left most lanes of their vector idle).
    uint count = min(queue[3], QUEUE_ROOM(queue));
    uint stride = gl_NumWorkGroups.x * 64u;
    for (uint e = gl_WorkGroupID.x * 64u + gl_LocalInvocationIndex; e < count; e += stride) {
        uint i = queue[4u + e];
        Result r = block(ivec2(i % push.width, i / push.width), size, with_s, nbar);
        uint o = 4u * push.channel * push.stride + i;
        extra[o] = float(r.by0.x);
        extra[o + push.stride] = float(r.bs0.x);
        extra[o + 2u * push.stride] = float(r.xi);
        extra[o + 3u * push.stride] = float(r.trace);
    }
}
