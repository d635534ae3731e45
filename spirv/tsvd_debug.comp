#version 460
// TSVD debug outputs (spec §0.6): rank k, tau, ||E||_2 (exact) and
// sigma_1..sigma_9 of the 9-D WLR feature set (spec §2.1) over Omega_c(R),
// per pixel; and the rank as the methods compute it (||E||_2 exact only
// where the bounds of tsvd_lmax_bounds cannot decide it), which must equal k.
// Scalar twin: src/reference/tsvd_debug.rs.
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::TsvdPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint radius;
} push;

PLANE_IN(0, nx)
PLANE_IN(1, ny)
PLANE_IN(2, nz)
PLANE_IN(3, dep)
PLANE_IN(4, ar)
PLANE_IN(5, ag)
PLANE_IN(6, ab)
PLANE_IN(7, v_nx)
PLANE_IN(8, v_ny)
PLANE_IN(9, v_nz)
PLANE_IN(10, v_dep)
PLANE_IN(11, v_ar)
PLANE_IN(12, v_ag)
PLANE_IN(13, v_ab)
PLANE_IN(14, spp)
PLANE_OUT(15, rank_out)
PLANE_OUT(16, tau_out)
PLANE_OUT(17, specnorm_out)
PLANE_OUT(18, sigma1_out)
PLANE_OUT(19, sigma2_out)
PLANE_OUT(20, sigma3_out)
PLANE_OUT(21, sigma4_out)
PLANE_OUT(22, sigma5_out)
PLANE_OUT(23, sigma6_out)
PLANE_OUT(24, sigma7_out)
PLANE_OUT(25, sigma8_out)
PLANE_OUT(26, sigma9_out)
PLANE_OUT(27, rank_methods_out)

#define MAX_D 9
#define TSVD_D 9

// Features (px, py, nrm xyz, dep, albedo rgb), variances (0, 0, vn xyz, vd,
// va rgb); valid iff spp_of >= 1 (spec §0.2).
bool load_features(ivec2 p, out real x[MAX_D], out real e2[MAX_D])
{
    uint i = uint(p.y) * push.width + uint(p.x);
    x[0] = real(p.x);
    x[1] = real(p.y);
    x[2] = real(nx[i]);
    x[3] = real(ny[i]);
    x[4] = real(nz[i]);
    x[5] = real(dep[i]);
    x[6] = real(ar[i]);
    x[7] = real(ag[i]);
    x[8] = real(ab[i]);
    e2[0] = real(0);
    e2[1] = real(0);
    e2[2] = real(v_nx[i]);
    e2[3] = real(v_ny[i]);
    e2[4] = real(v_nz[i]);
    e2[5] = real(v_dep[i]);
    e2[6] = real(v_ar[i]);
    e2[7] = real(v_ag[i]);
    e2[8] = real(v_ab[i]);
    return spp_of(spp[i]) >= 1.0;
}

#include "lib/tsvd.glsl"

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    uint i = y * push.width + x;
    float o[13];
    for (int j = 0; j < 13; ++j) {
        o[j] = 0.0;
    }
    // §0.2: an invalid centre gets 0 everywhere.
    if (spp_of(spp[i]) >= 1.0) {
        // §0.6 steps 1-6 over Omega_c(R).
        ivec2 size = ivec2(push.width, push.height);
        LocalSpace ls = tsvd_local_space_with(ivec2(x, y), int(push.radius), size, true);
        o[12] = float(tsvd_local_space(ivec2(x, y), int(push.radius), size).k);
        o[0] = float(ls.k);
        o[1] = float(ls.tau);
        o[2] = float(ls.specnorm);
        for (int m = 0; m < 9; ++m) {
            o[3 + m] = float(ls.sigma[m]);
        }
    }
    rank_out[i] = o[0];
    tau_out[i] = o[1];
    specnorm_out[i] = o[2];
    sigma1_out[i] = o[3];
    sigma2_out[i] = o[4];
    sigma3_out[i] = o[5];
    sigma4_out[i] = o[6];
    sigma5_out[i] = o[7];
    sigma6_out[i] = o[8];
    sigma7_out[i] = o[9];
    sigma8_out[i] = o[10];
    sigma9_out[i] = o[11];
    rank_methods_out[i] = o[12];
}
