#version 460
// AOS step 1 (spec §5.3, §0.6): the TSVD local space of the 10 features of
// §5.1 over Omega_c(R), stored per pixel as the projection
// dz = P (x - x_c), P[m][j] = V_jm / rho_j (m < k, non-constant j; else 0),
// then k: SPACE = 101 floats per pixel, pixel (x, y) at
// ((y - base_row) * width + x) * SPACE. Invalid centre: all 0.
// Scalar twin: src/reference/aos_space.rs.
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::AosPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint radius;
    uint channels;
    uint flags;
    uint base_row;
    uint stride;
} push;

// depth, albedo rgb, normal xyz, visibility (a zero plane when absent).
PLANE_IN(0, f0)
PLANE_IN(1, f1)
PLANE_IN(2, f2)
PLANE_IN(3, f3)
PLANE_IN(4, f4)
PLANE_IN(5, f5)
PLANE_IN(6, f6)
PLANE_IN(7, f7)
PLANE_IN(8, v0)
PLANE_IN(9, v1)
PLANE_IN(10, v2)
PLANE_IN(11, v3)
PLANE_IN(12, v4)
PLANE_IN(13, v5)
PLANE_IN(14, v6)
PLANE_IN(15, v7)
PLANE_IN(16, spp)
PLANE_OUT(17, space)

#define MAX_D 10
#define TSVD_D 10
#define SPACE 101

bool load_features(ivec2 p, out real x[MAX_D], out real e2[MAX_D])
{
    uint i = uint(p.y) * push.width + uint(p.x);
    x[0] = real(p.x);
    x[1] = real(p.y);
    x[2] = real(f0[i]);
    x[3] = real(f1[i]);
    x[4] = real(f2[i]);
    x[5] = real(f3[i]);
    x[6] = real(f4[i]);
    x[7] = real(f5[i]);
    x[8] = real(f6[i]);
    x[9] = real(f7[i]);
    e2[0] = real(0);
    e2[1] = real(0);
    e2[2] = real(v0[i]);
    e2[3] = real(v1[i]);
    e2[4] = real(v2[i]);
    e2[5] = real(v3[i]);
    e2[6] = real(v4[i]);
    e2[7] = real(v5[i]);
    e2[8] = real(v6[i]);
    e2[9] = real(v7[i]);
    return spp_of(spp[i]) >= 1.0;
}

#include "lib/tsvd.glsl"

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.base_row + push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    uint o = ((y - push.base_row) * push.width + x) * uint(SPACE);
    if (spp_of(spp[y * push.width + x]) < 1.0) {
        for (int e = 0; e < SPACE; ++e) {
            space[o + uint(e)] = 0.0;
        }
        return;
    }
    LocalSpace ls = tsvd_local_space(ivec2(x, y), int(push.radius), ivec2(push.width, push.height));
    for (int j = 0; j < TSVD_D; ++j) {
        real inv = ls.range[j] > real(TSVD_RANGE_EPS) ? real(1) / ls.range[j] : real(0);
        for (int m = 0; m < TSVD_D; ++m) {
            real v = m < ls.k ? ls.V[j * TSVD_D + m] * inv : real(0);
            space[o + uint(m * TSVD_D + j)] = float(v);
        }
    }
    space[o + uint(TSVD_D * TSVD_D)] = float(ls.k);
}
