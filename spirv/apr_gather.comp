#version 460
// APR's blend (spec §4.3, Eq. 6), by gathering: for every pixel and
// channel, the K_h-weighted mean, over the valid sparse centres within 14
// (raster order) that accept the pixel, of the block's x_i^T beta_y (and
// x_i^T beta_s before the last stage), xi and tr H; a valid pixel no block
// accepts takes its extra block's values (apr_block.comp, extra mode).
// Decision APR-PIXEL-TEST (ours): with push.flags & APR_PIXEL_TEST, a
// block whose prediction x_i^T beta_y misses y_i by more than t_threshold3(n_i)
// standard errors (variance: the larger of v_i and the channel's 3x3 mean
// of v without its largest value) is left out; a pixel whose accepting
// blocks are all left out keeps y_i, error v_i, dimension 0.
// Last stage (push.last = 1): colour (clamped >= 0), error, the mean over
// the channels of tr H (local dimension d_i), extra mask: 10 planes.
// Earlier stages: y-hat and sigma-hat^2 (the blend of H s, squared): 6
// planes. Planes are push.stride floats apart in the `dst` binding. An
// invalid pixel (§0.2): the mean of its valid 3x3 neighbours (0 if none),
// error v, dimension 1; earlier stages keep y and v.
// Scalar twin: src/reference/apr_gather.rs.
#include "lib/common.glsl"
#extension GL_EXT_control_flow_attributes : require

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

PLANE_IN(0, col_r)
PLANE_IN(1, col_g)
PLANE_IN(2, col_b)
PLANE_IN(3, var_r)
PLANE_IN(4, var_g)
PLANE_IN(5, var_b)
// The features packed by apr_pack (APR-PACKED): normal xyz, albedo r;
// albedo g b, depth, visibility.
layout(std430, set = 0, binding = 6) readonly buffer fa_blk { vec4 fa[]; };
layout(std430, set = 0, binding = 7) readonly buffer fb_blk { vec4 fb[]; };
PLANE_IN(8, spp)
// The blocks' state records (apr_block), read as vec4s (APR-STATE-VEC4:
// beta_y, beta_s and the spreads start on multiples of 4).
layout(std430, set = 0, binding = 9) readonly buffer state_blk { vec4 state[]; };
PLANE_IN(10, extra)
PLANE_OUT(11, dst)
// spp_total's words (APR-COUNT-CAP).
layout(std430, set = 0, binding = 12) readonly buffer sppt_blk { uint sppt[]; };

#include "lib/apr.glsl"

// mcdenoise::shared::APR_PIXEL_TEST.
#define APR_PIXEL_TEST 4u

real yof(int ch, uint i) { return real(ch == 0 ? col_r[i] : (ch == 1 ? col_g[i] : col_b[i])); }

real4 st4(uint b4) { return real4(state[b4]); }

real fill(int ch, ivec2 p, ivec2 size)
{
    real s = real(0);
    int n = 0;
    for (int qy = max(p.y - 1, 0); qy <= min(p.y + 1, size.y - 1); ++qy) {
        for (int qx = max(p.x - 1, 0); qx <= min(p.x + 1, size.x - 1); ++qx) {
            uint q = uint(qy * size.x + qx);
            if (apr_valid(q)) {
                s += yof(ch, q);
                ++n;
            }
        }
    }
    return n > 0 ? s / real(n) : real(0);
}

void main()
{
    ivec2 p = ivec2(gl_GlobalInvocationID.x, push.row0 + gl_GlobalInvocationID.y);
    ivec2 size = ivec2(push.width, push.height);
    if (p.x >= size.x || p.y >= size.y) {
        return;
    }
    uint i = uint(p.y * size.x + p.x);
    bool last = push.last != 0u;
    uint st = push.stride;
    int gw = (size.x + APR_R - 1) / APR_R;
    int gh = (size.y + APR_R - 1) / APR_R;
    bool valid = apr_valid(i);
    real4 fa = apr_fa(i);
    real4 fb = apr_fb(i);
    real3 yi3 = real3(col_r[i], col_g[i], col_b[i]);
    real3 vi3 = real3(var_r[i], var_g[i], var_b[i]);
    // APR-PIXEL-TEST off: no limit (-1). One scan of the 3x3 neighbourhood
    // for the three channels (each channel's sums in the order of a scan of
    // its own).
    real3 lim = real3(-1);
    if (valid && (push.flags & APR_PIXEL_TEST) != 0u) {
        // Per channel, the neighbours that agree with i (PIXEL-TEST-AGREE).
        real3 vs = real3(0), vmax = real3(0);
        ivec3 nn = ivec3(0);
        real t2 = pixel_test_t2(real(spp_of(spp[i])));
        for (int qy = max(p.y - 1, 0); qy <= min(p.y + 1, size.y - 1); ++qy) {
            for (int qx = max(p.x - 1, 0); qx <= min(p.x + 1, size.x - 1); ++qx) {
                uint q = uint(qy * size.x + qx);
                if (apr_valid(q)) {
                    real3 vq = real3(var_r[q], var_g[q], var_b[q]);
                    real3 d = real3(col_r[q], col_g[q], col_b[q]) - yi3;
                    [[unroll]] for (int ch = 0; ch < 3; ++ch) {
                        if (q == i || pixel_test_agrees(t2, d[ch] * d[ch], vq[ch], vi3[ch])) {
                            vs[ch] += vq[ch];
                            vmax[ch] = max(vmax[ch], vq[ch]);
                            ++nn[ch];
                        }
                    }
                }
            }
        }
        [[unroll]] for (int ch = 0; ch < 3; ++ch) {
            lim[ch] = pixel_test_limit(t2, vi3[ch], vs[ch], vmax[ch], nn[ch]);
        }
    }
    // The blend, centre by centre in raster order, the three channels of a
    // centre together (APR-GATHER-CENTRES): its validity, features, colour
    // and spatial weight are loaded and computed once for the three.
    float nbar = apr_nbar();
    real fi = apr_test_scale(i, nbar);
    bvec3 missed = bvec3(false);
    real3 ws = real3(0), ay = real3(0), as_ = real3(0), ae = real3(0), ad = real3(0);
    for (int cy = apr_first_centre(p.y); valid && cy <= min(p.y + APR_R, size.y - 1); cy += APR_R) {
        for (int cx = apr_first_centre(p.x); cx <= min(p.x + APR_R, size.x - 1); cx += APR_R) {
            uint c = uint(cy * size.x + cx);
            if (!apr_valid(c)) {
                continue;
            }
            real4 fca = apr_fa(c);
            real4 fcb = apr_fb(c);
            real3 yc3 = real3(col_r[c], col_g[c], col_b[c]);
            // The interval test's variances (APR-COUNT-CAP).
            real fc = apr_test_scale(c, nbar);
            real3 vc3 = fc * real3(var_r[c], var_g[c], var_b[c]);
            real k = apr_weight(p.x - cx, p.y - cy);
            uint cell = uint((cy / APR_R) * gw + cx / APR_R);
            [[unroll]] for (int ch = 0; ch < 3; ++ch) {
                if (c != i && !apr_accepts(yc3[ch], vc3[ch], yi3[ch], fi * vi3[ch])) {
                    continue;
                }
                // The record's vec4 index (APR_STATE / 4 per block).
                uint b = (uint(ch) * uint(gw * gh) + cell) * uint(APR_STATE / 4);
                uint by = b + uint(APR_ST_BETA_Y / 4);
                uint bs = b + uint(APR_ST_BETA_S / 4);
                real4 x0, x1, x2, x3, x4;
                real4 sa = st4(b + uint(APR_ST_SCALES / 4));
                real4 sb = st4(b + uint(APR_ST_SCALES / 4) + 1u);
                real4 isa = mix(real4(0), real4(1) / max(sa, real4(1e-30)), greaterThan(sa, real4(0)));
                real4 isb = mix(real4(0), real4(1) / max(sb, real4(1e-30)), greaterThan(sb, real4(0)));
                apr_row(p - ivec2(cx, cy), 0, fa, fb, fca, fcb, isa, isb, x0, x1, x2, x3, x4);
                // The records' entries past the chosen order's columns are 0.
                real py = dot(x0, st4(by)) + dot(x1, st4(by + 1u)) + dot(x2, st4(by + 2u))
                    + dot(x3, st4(by + 3u)) + dot(x4, st4(by + 4u));
                if (lim[ch] >= real(0) && (py - yi3[ch]) * (py - yi3[ch]) > lim[ch]) {
                    missed[ch] = true;
                    continue;
                }
                ws[ch] += k;
                ay[ch] += k * py;
                if (!last) {
                    as_[ch] += k * (dot(x0, st4(bs)) + dot(x1, st4(bs + 1u)) + dot(x2, st4(bs + 2u))
                        + dot(x3, st4(bs + 3u)) + dot(x4, st4(bs + 4u)));
                }
                vec4 head = state[b];  // order, xi, tr H, degenerate
                ae[ch] += k * real(head.y);
                ad[ch] += k * real(head.z);
            }
        }
    }
    real dim = real(0);
    [[unroll]] for (int ch = 0; ch < 3; ++ch) {
        real yi = yi3[ch];
        real vi = vi3[ch];
        real oy, os, oe, od, ox;
        if (!valid) {
            oy = last ? fill(ch, p, size) : yi;
            os = sqrt(max(vi, real(0)));
            oe = vi;
            od = real(1);
            ox = real(0);
        } else if (ws[ch] > real(0)) {
            oy = ay[ch] / ws[ch];
            os = as_[ch] / ws[ch];
            oe = ae[ch] / ws[ch];
            od = ad[ch] / ws[ch];
            ox = real(0);
        } else if (missed[ch]) {
            oy = yi;
            os = sqrt(max(vi, real(0)));
            oe = vi;
            od = real(0);
            ox = real(0);
        } else {
            uint e = 4u * uint(ch) * st + i;
            oy = real(extra[e]);
            os = real(extra[e + st]);
            oe = real(extra[e + 2u * st]);
            od = real(extra[e + 3u * st]);
            ox = real(1);
        }
        if (last) {
            dst[uint(ch) * st + i] = float(max(oy, real(0)));
            dst[uint(3 + ch) * st + i] = float(oe);
            dst[uint(7 + ch) * st + i] = float(ox);
            dim += od / real(3);
        } else {
            dst[uint(ch) * st + i] = float(oy);
            dst[uint(3 + ch) * st + i] = float(os * os);
        }
    }
    if (last) {
        dst[6u * st + i] = float(dim);
    }
}
