#version 460
// LP's output (spec §3.5), by gathering (§0.3 GATHER): every pixel scans the
// clipped 19x19 neighbourhood of the centre state in raster order (skipping
// the rows whose lp_reach value cannot cover it) and
// averages, over the centres c with |i - c|_inf <= r_opt(c), the prediction
// beta_c[ch] + u_c[ch] . (x_i - x_c), max(xi_c,ch, 0) (the error estimate)
// and max(xi_c,ch, 0) n_i^(-4/(k_c+4)) (Delta-MSE for sampling).
// Colour outputs are clamped >= 0 (§0.4 step 5). An invalid pixel gets the
// mean colour of its valid 3x3 neighbours (§0.2), error 0, coverage 0.
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
    uint pad0;
    uint pad1;
} push;

PLANE_IN(0, nx)
PLANE_IN(1, ny)
PLANE_IN(2, nz)
PLANE_IN(3, dep)
PLANE_IN(4, ar)
PLANE_IN(5, ag)
PLANE_IN(6, ab)
PLANE_IN(7, col_r)
PLANE_IN(8, col_g)
PLANE_IN(9, col_b)
PLANE_IN(10, spp)
PLANE_IN(11, reach)
layout(std430, set = 0, binding = 12) readonly buffer st0_blk { vec4 st0[]; };
layout(std430, set = 0, binding = 13) readonly buffer st1_blk { vec4 st1[]; };
layout(std430, set = 0, binding = 14) readonly buffer st2_blk { vec4 st2[]; };
layout(std430, set = 0, binding = 15) readonly buffer st3_blk { vec4 st3[]; };
layout(std430, set = 0, binding = 16) readonly buffer st4_blk { vec4 st4[]; };
layout(std430, set = 0, binding = 17) readonly buffer st5_blk { vec4 st5[]; };
layout(std430, set = 0, binding = 18) readonly buffer st6_blk { vec4 st6[]; };
layout(std430, set = 0, binding = 19) readonly buffer st7_blk { vec4 st7[]; };
layout(std430, set = 0, binding = 20) readonly buffer st8_blk { vec4 st8[]; };
PLANE_OUT(21, out_r)
PLANE_OUT(22, out_g)
PLANE_OUT(23, out_b)
PLANE_OUT(24, err_r)
PLANE_OUT(25, err_g)
PLANE_OUT(26, err_b)
PLANE_OUT(27, dmse_r)
PLANE_OUT(28, dmse_g)
PLANE_OUT(29, dmse_b)
PLANE_OUT(30, coverage)

#define LP_RADIUS 9

// Raw features (px, py, nrm xyz, dep, albedo rgb) as lanes f0, f1, f8.
void features(ivec2 p, out real4 f0, out real4 f1, out real f8)
{
    uint i = uint(p.y) * push.width + uint(p.x);
    f0 = real4(p.x, p.y, nx[i], ny[i]);
    f1 = real4(nz[i], dep[i], ar[i], ag[i]);
    f8 = real(ab[i]);
}

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    uint i = y * push.width + x;
    ivec2 p = ivec2(x, y);
    ivec2 size = ivec2(push.width, push.height);
    float o[10];
    for (int j = 0; j < 10; ++j) {
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
        real3 dmse = real3(0);
        int count = 0;
        for (int qy = max(p.y - LP_RADIUS, 0); qy <= min(p.y + LP_RADIUS, size.y - 1); ++qy) {
            // Rows whose reach cannot cover p hold no covering centre.
            if (reach[uint(qy) * push.width + x] < float(abs(qy - p.y))) {
                continue;
            }
            for (int qx = max(p.x - LP_RADIUS, 0); qx <= min(p.x + LP_RADIUS, size.x - 1); ++qx) {
                uint q = uint(qy) * push.width + uint(qx);
                vec4 s0 = st0[q];
                if (s0.x <= 0.0 || float(max(abs(qx - p.x), abs(qy - p.y))) > s0.y) {
                    continue;
                }
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
                real3 f;
                f.r = beta0.r + dot(real4(s2.yzw, s3.x), d0) + dot(real4(s3.yzw, s4.x), d1) + real(s4.y) * d8;
                f.g = beta0.g + dot(real4(s4.zw, s5.xy), d0) + dot(real4(s5.zw, s6.xy), d1) + real(s6.z) * d8;
                f.b = beta0.b + dot(real4(s6.w, s7.xyz), d0) + dot(real4(s7.w, s8.xyz), d1) + real(s8.w) * d8;
                if (count == 0) {
                    first = f;
                }
                pred += f - first;
                err += xi;
                dmse += xi * real(pow(float(n_i), -4.0 / (s0.z + 4.0)));
                ++count;
            }
        }
        if (count == 0) {
            o[0] = max(col_r[i], 0.0);
            o[1] = max(col_g[i], 0.0);
            o[2] = max(col_b[i], 0.0);
        } else {
            real n = real(count);
            real3 m = max(first + pred / n, real3(0));
            o[0] = float(m.r);
            o[1] = float(m.g);
            o[2] = float(m.b);
            o[3] = float(err.r / n);
            o[4] = float(err.g / n);
            o[5] = float(err.b / n);
            o[6] = float(dmse.r / n);
            o[7] = float(dmse.g / n);
            o[8] = float(dmse.b / n);
            o[9] = float(count);
        }
    }
    out_r[i] = o[0];
    out_g[i] = o[1];
    out_b[i] = o[2];
    err_r[i] = o[3];
    err_g[i] = o[4];
    err_b[i] = o[5];
    dmse_r[i] = o[6];
    dmse_g[i] = o[7];
    dmse_b[i] = o[8];
    coverage[i] = o[9];
}
