#version 460
// LP's output (spec §3.5), by gathering (§0.3 GATHER): every pixel visits
// the centres of its clipped 19x19 neighbourhood in raster order (from its
// workgroup's list, LP-GATHER-UNION below) and averages, over the
// centres c with |i - c|_inf <= r_opt(c), the prediction
// beta_c + u_c . (x_i - x_c), max(xi_c,ch, 0), the collapsed map u_c and k_c.
// Error estimate (LP-FEATNOISE): E_i[ch] = mean_c max(xi_c,ch, 0)
// + (sum_j |ubar[ch][j]| sd(x_ij))^2, the model error of the centres plus
// the variance the averaged linear map (ubar = mean_c u_c) passes on from
// pixel i's own noisy features: the largest value ubar^T Cov(x_i) ubar can
// take when only the variances are known (fully correlated feature noise).
// Local dimension d_i = mean_c k_c, and
// Delta-MSE = E_i n_i^(-4/(d_i+4)) (§9.1).
// Decision LP-PIXEL-TEST (ours): with LpPush.options bit LP_PIXEL_TEST, a
// centre whose prediction at pixel i misses i's mean by more than
// t_threshold3(n_i) standard errors is left out of i's average; if every centre is, i keeps
// its input with E_i = v_i, Delta-MSE = v_i / n_i, d_i = 0 and coverage 0.
// Colour outputs are clamped >= 0 (§0.4 step 5). An invalid pixel gets the
// mean colour of its valid 3x3 neighbours (§0.2), error, Delta-MSE,
// coverage and d 0. The 11 outputs go to one binding, plane k at
// k * push.out_stride.
// Scalar twin: src/reference/lp_gather.rs.
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::LpPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint granularity;
    uint pass;
    uint options;
    uint out_stride;
    uint pad1;
    uint ring_rows;
} push;

// The features and their variances packed by gbf_pack (PACKED-LP): fa =
// normal xyz, depth; fb = albedo rgb, 0; va, vb the same of the variances.
layout(std430, set = 0, binding = 0) readonly buffer fa_blk { vec4 fa[]; };
layout(std430, set = 0, binding = 1) readonly buffer fb_blk { vec4 fb[]; };
layout(std430, set = 0, binding = 2) readonly buffer va_blk { vec4 va[]; };
layout(std430, set = 0, binding = 3) readonly buffer vb_blk { vec4 vb[]; };
PLANE_IN(4, col_r)
PLANE_IN(5, col_g)
PLANE_IN(6, col_b)
PLANE_IN(7, cv_r)
PLANE_IN(8, cv_g)
PLANE_IN(9, cv_b)
PLANE_IN(10, spp)
layout(std430, set = 0, binding = 11) readonly buffer st0_blk { vec4 st0[]; };
layout(std430, set = 0, binding = 12) readonly buffer st1_blk { vec4 st1[]; };
layout(std430, set = 0, binding = 13) readonly buffer st2_blk { vec4 st2[]; };
layout(std430, set = 0, binding = 14) readonly buffer st3_blk { vec4 st3[]; };
layout(std430, set = 0, binding = 15) readonly buffer st4_blk { vec4 st4[]; };
layout(std430, set = 0, binding = 16) readonly buffer st5_blk { vec4 st5[]; };
layout(std430, set = 0, binding = 17) readonly buffer st6_blk { vec4 st6[]; };
layout(std430, set = 0, binding = 18) readonly buffer st7_blk { vec4 st7[]; };
layout(std430, set = 0, binding = 19) readonly buffer st8_blk { vec4 st8[]; };
// Outputs (kernels::lp_gather::OUTPUTS): colour RGB, error RGB, Delta-MSE RGB,
// coverage, d; plane k at k * out_stride.
layout(std430, set = 0, binding = 20) buffer out_blk { float outp[]; };

#define LP_RADIUS 9
// mcdenoise::shared::LP_SKIP_*.
#define LP_SKIP_ERROR 2u
#define LP_SKIP_DMSE 4u
#define LP_SKIP_COVERAGE 8u
#define LP_PIXEL_TEST 32u

// Raw features (px, py, nrm xyz, dep, albedo rgb) as lanes f0, f1, f8.
void features(ivec2 p, out real4 f0, out real4 f1, out real f8)
{
    uint i = uint(p.y) * push.width + uint(p.x);
    vec4 a = fa[i];
    vec4 b = fb[i];
    f0 = real4(p.x, p.y, a.x, a.y);
    f1 = real4(a.z, a.w, b.x, b.y);
    f8 = real(b.z);
}

// The workgroup's 8x8 pixels and their 9-pixel halo (LP-GATHER-UNION): the
// list of the centres that cover at least one pixel of the tile, in raster
// order. Every pixel walks the same list, one centre per iteration, and
// tests its own coverage. A pixel's covering centres are a subset of the
// list in the same raster order, so its sums take the same terms in the same
// order as a scan of its window. The list is found by all 64 lanes, each
// scanning its share of the 26x26 tile of the centre map and appending what
// it finds (in any order), then put in raster order by counting, for each
// entry, the entries before it: n^2 work per workgroup for a list of n,
// which is short (7.8 entries on average, 73 at most, on a 1 MP render;
// up to 676 only on a centre map far denser than LP makes, which the
// tests also run).
#define TILE (8 + 2 * LP_RADIUS)
// The tile indices found, in the order found, and their number.
shared uint t_found[TILE * TILE];
shared uint t_n;
// In raster order: per centre its tile index (as a float, exact), r_opt, k
// and beta0 R (state plane 0 without its centre flag), and its index in the
// state rings.
shared vec4 t_c[TILE * TILE];
shared uint t_ring[TILE * TILE];
// LP-PIXEL-TEST's inputs over the workgroup's pixels and a 1-pixel halo:
// per pixel its colour, the sum of its three colour variances, and whether
// it is valid (outside the image: not). Staged once: 4 loads per tile pixel instead of
// 4 per pixel of each of the 9 neighbourhoods that hold it.
#define VT 10
shared real t_v[VT * VT];
shared real3 t_y[VT * VT];
shared bool t_vok[VT * VT];

// The distance from tile coordinate t to the workgroup's pixels (tile
// coordinates LP_RADIUS .. LP_RADIUS + 7) along one axis.
int to_tile(int t)
{
    return max(max(LP_RADIUS - t, t - (LP_RADIUS + 7)), 0);
}

void main()
{
    ivec2 org = ivec2(gl_WorkGroupID.x * 8u, push.row0 + gl_WorkGroupID.y * 8u) - LP_RADIUS;
    uint lid = gl_LocalInvocationIndex;
    if (lid == 0u) {
        t_n = 0u;
    }
    for (uint k = lid; k < uint(VT * VT); k += 64u) {
        ivec2 t = org + (LP_RADIUS - 1) + ivec2(k % uint(VT), k / uint(VT));
        real v = real(0);
        real3 yq = real3(0);
        bool ok = false;
        if (t.x >= 0 && t.y >= 0 && t.x < int(push.width) && t.y < int(push.height)) {
            uint q = uint(t.y) * push.width + uint(t.x);
            ok = spp_of(spp[q]) >= 1.0;
            if (ok) {
                v = real(cv_r[q]) + real(cv_g[q]) + real(cv_b[q]);
                yq = real3(col_r[q], col_g[q], col_b[q]);
            }
        }
        t_v[k] = v;
        t_y[k] = yq;
        t_vok[k] = ok;
    }
    barrier();
    for (uint k = lid; k < uint(TILE * TILE); k += 64u) {
        ivec2 t = org + ivec2(k % uint(TILE), k / uint(TILE));
        if (t.x >= 0 && t.y >= 0 && t.x < int(push.width) && t.y < int(push.height)) {
            vec4 s = st0[uint(t.y) * push.width + uint(t.x)];
            int d = max(to_tile(int(k % uint(TILE))), to_tile(int(k / uint(TILE))));
            if (s.x > 0.0 && float(d) <= s.y) {
                t_found[atomicAdd(t_n, 1u)] = k;
            }
        }
    }
    barrier();
    // State planes 1..8 are rings of push.ring_rows rows (LpPush::ring_rows).
    uint ring = push.ring_rows == 0u ? push.height : push.ring_rows;
    uint n_list = t_n;
    for (uint e = lid; e < n_list; e += 64u) {
        uint k = t_found[e];
        uint at = 0u;
        for (uint f = 0u; f < n_list; ++f) {
            at += t_found[f] < k ? 1u : 0u;
        }
        ivec2 t = org + ivec2(k % uint(TILE), k / uint(TILE));
        vec4 s = st0[uint(t.y) * push.width + uint(t.x)];
        t_c[at] = vec4(float(k), s.yzw);
        t_ring[at] = (uint(t.y) % ring) * push.width + uint(t.x);
    }
    barrier();
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    uint i = y * push.width + x;
    ivec2 p = ivec2(x, y);
    ivec2 size = ivec2(push.width, push.height);
    float o[11];
    for (int j = 0; j < 11; ++j) {
        o[j] = 0.0;
    }
    real n_i = real(spp_of(spp[i]));
    if (n_i < real(1)) {
        // Mean shifted by the first valid neighbour: exact when they are equal.
        real3 first = real3(0);
        real3 sum = real3(0);
        int n = 0;
        for (int qy = max(p.y - 1, 0); qy <= min(p.y + 1, size.y - 1); ++qy) {
            for (int qx = max(p.x - 1, 0); qx <= min(p.x + 1, size.x - 1); ++qx) {
                uint q = uint(qy) * push.width + uint(qx);
                if (spp_of(spp[q]) >= 1.0) {
                    real3 c = real3(col_r[q], col_g[q], col_b[q]);
                    if (n == 0) {
                        first = c;
                    }
                    sum += c - first;
                    ++n;
                }
            }
        }
        if (n > 0) {
            real3 m = max(first + sum / real(n), real3(0));
            o[0] = float(m.r);
            o[1] = float(m.g);
            o[2] = float(m.b);
        }
    } else {
        real4 f0, f1;
        real f8;
        features(p, f0, f1, f8);
        // Predictions are summed relative to the first one, so that equal
        // predictions average exactly (a constant image is returned exactly).
        real3 first = real3(0);
        real3 pred = real3(0);
        real3 err = real3(0);
        real dim = real(0);
        // Sums of u_c[ch] (lanes as d0, d1, d8 below).
        real4 ur0 = real4(0), ur1 = real4(0), ug0 = real4(0), ug1 = real4(0);
        real4 ub0 = real4(0), ub1 = real4(0);
        real3 u8 = real3(0);
        int count = 0;
        // LP-PIXEL-TEST: a centre whose prediction misses pixel i's own mean
        // by more than t_threshold3(n_i) standard errors (all channels
        // together) does not predict i. The variance is the larger of i's
        // and the mean over the neighbours of its valid 3x3 neighbourhood
        // (raster order, i included) that agree with it, without the largest
        // value: a pixel whose few samples all agree has a variance estimate
        // far below its true one, and the local noise says so; a neighbour on
        // a bright light, many standard errors from i, does not
        // (PIXEL-TEST-AGREE).
        real3 y_i = real3(col_r[i], col_g[i], col_b[i]);
        real lim = real(-1);
        if ((push.options & LP_PIXEL_TEST) != 0u) {
            real vn = real(0);
            real vmax = real(0);
            int nn = 0;
            // Raster order; the staged tile (halo included) holds them.
            uint c = (gl_LocalInvocationID.y + 1u) * uint(VT) + gl_LocalInvocationID.x + 1u;
            real v_i = t_v[c];
            real t2 = pixel_test_t2(n_i);
            for (int dy = -1; dy <= 1; ++dy) {
                for (int dx = -1; dx <= 1; ++dx) {
                    uint t = uint(int(c) + dy * VT + dx);
                    real3 d = t_y[t] - y_i;
                    if (t_vok[t] && (t == c || pixel_test_agrees(t2, dot(d, d), t_v[t], v_i))) {
                        real vq = t_v[t];
                        vn += vq;
                        vmax = max(vmax, vq);
                        ++nn;
                    }
                }
            }
            lim = pixel_test_limit(t2, v_i, vn, vmax, nn);
        }
        // The tile's list, one centre per iteration (the same number of
        // iterations for every lane: llvmpipe runs a loop's body while any
        // lane is in it), each pixel keeping the centres that cover it.
        for (uint k = 0u; k < n_list; ++k) {
            vec4 s0 = t_c[k];
            uint t = uint(s0.x);
            int qx = org.x + int(t % uint(TILE));
            int qy = org.y + int(t / uint(TILE));
            if (float(max(abs(qx - p.x), abs(qy - p.y))) > s0.y) {
                continue;
            }
            uint q = t_ring[k];
            real4 c0, c1;
            real c8;
            features(ivec2(qx, qy), c0, c1, c8);
            real4 d0 = f0 - c0;
            real4 d1 = f1 - c1;
            real d8 = f8 - c8;
            // State values 3..35 (StateLayout): beta0 RGB, xi RGB, u[ch][0..9).
            vec4 s1 = st1[q], s2 = st2[q], s3 = st3[q], s4 = st4[q];
            vec4 s5 = st5[q], s6 = st6[q], s7 = st7[q], s8 = st8[q];
            real3 beta0 = real3(s0.w, s1.x, s1.y);
            real3 xi = max(real3(s1.z, s1.w, s2.x), real3(0));
            // u_R = s2.yzw s3 s4.xy; u_G = s4.zw s5 s6.xyz; u_B = s6.w s7 s8.
            real4 cr0 = real4(s2.yzw, s3.x), cr1 = real4(s3.yzw, s4.x);
            real4 cg0 = real4(s4.zw, s5.xy), cg1 = real4(s5.zw, s6.xy);
            real4 cb0 = real4(s6.w, s7.xyz), cb1 = real4(s7.w, s8.xyz);
            real3 uc8 = real3(s4.y, s6.z, s8.w);
            real3 f;
            f.r = beta0.r + dot(cr0, d0) + dot(cr1, d1) + uc8.r * d8;
            f.g = beta0.g + dot(cg0, d0) + dot(cg1, d1) + uc8.g * d8;
            f.b = beta0.b + dot(cb0, d0) + dot(cb1, d1) + uc8.b * d8;
            real3 res = f - y_i;
            if (lim >= real(0) && dot(res, res) > lim) {
                continue;
            }
            ur0 += cr0;
            ur1 += cr1;
            ug0 += cg0;
            ug1 += cg1;
            ub0 += cb0;
            ub1 += cb1;
            u8 += uc8;
            if (count == 0) {
                first = f;
            }
            pred += f - first;
            err += xi;
            dim += real(s0.z);
            ++count;
        }
        if (count == 0) {
            // No centre predicts i (LP-PIXEL-TEST rejected them all): the
            // input, whose error is its variance of the mean, falling as
            // 1/n (d = 0).
            o[0] = max(col_r[i], 0.0);
            o[1] = max(col_g[i], 0.0);
            o[2] = max(col_b[i], 0.0);
            o[3] = cv_r[i];
            o[4] = cv_g[i];
            o[5] = cv_b[i];
            o[6] = float(real(cv_r[i]) / n_i);
            o[7] = float(real(cv_g[i]) / n_i);
            o[8] = float(real(cv_b[i]) / n_i);
        } else {
            real n = real(count);
            real3 m = max(first + pred / n, real3(0));
            o[0] = float(m.r);
            o[1] = float(m.g);
            o[2] = float(m.b);
            // Standard deviations of pixel i's features, lanes as d0, d1, d8
            // (the positions are exact).
            vec4 u = va[i];
            vec4 v = vb[i];
            real4 w0 = sqrt(max(real4(0, 0, u.x, u.y), real4(0)));
            real4 w1 = sqrt(max(real4(u.z, u.w, v.x, v.y), real4(0)));
            real w8 = sqrt(max(real(v.z), real(0)));
            real3 sd;
            sd.r = dot(abs(ur0), w0) + dot(abs(ur1), w1) + abs(u8.r) * w8;
            sd.g = dot(abs(ug0), w0) + dot(abs(ug1), w1) + abs(u8.g) * w8;
            sd.b = dot(abs(ub0), w0) + dot(abs(ub1), w1) + abs(u8.b) * w8;
            real3 fv = sd * sd / (n * n);
            real3 e = err / n + fv;
            real d = dim / n;
            real rate = real(pow(float(n_i), float(-4.0 / (d + 4.0))));
            o[3] = float(e.r);
            o[4] = float(e.g);
            o[5] = float(e.b);
            o[6] = float(e.r * rate);
            o[7] = float(e.g * rate);
            o[8] = float(e.b * rate);
            o[9] = float(count);
            o[10] = float(d);
        }
    }
    // Planes nobody reads back are not written (LpPush::options, LP_SKIP_*).
    outp[0u * push.out_stride + i] = o[0];
    outp[1u * push.out_stride + i] = o[1];
    outp[2u * push.out_stride + i] = o[2];
    if ((push.options & LP_SKIP_ERROR) == 0u) {
        outp[3u * push.out_stride + i] = o[3];
        outp[4u * push.out_stride + i] = o[4];
        outp[5u * push.out_stride + i] = o[5];
    }
    if ((push.options & LP_SKIP_DMSE) == 0u) {
        outp[6u * push.out_stride + i] = o[6];
        outp[7u * push.out_stride + i] = o[7];
        outp[8u * push.out_stride + i] = o[8];
    }
    if ((push.options & LP_SKIP_COVERAGE) == 0u) {
        outp[9u * push.out_stride + i] = o[9];
    }
    outp[10u * push.out_stride + i] = o[10];
}
