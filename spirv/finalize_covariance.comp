#version 460
// Position sums -> covariance of the position *samples* divided by n
// (input-format.md: S = sum_k (p_k - pbar)(p_k - pbar)^T / n, "divided by spp").
// Cancellation guard: diagonal clamped to >= 0, each off-diagonal clamped to
// |S_ab| <= sqrt(S_aa S_bb) (Cauchy-Schwarz), so S stays a valid covariance.
// Always finite: what f32 cannot hold is 0 (see kept).
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
layout(push_constant) uniform Push { uint width; uint height; uint row0; uint _pad; } push;

PLANE_IN(0, sum_x)
PLANE_IN(1, sum_y)
PLANE_IN(2, sum_z)
PLANE_IN(3, sumsq_x)
PLANE_IN(4, sumsq_y)
PLANE_IN(5, sumsq_z)
PLANE_IN(6, sum_xy)
PLANE_IN(7, sum_xz)
PLANE_IN(8, sum_yz)
PLANE_IN(9, count_in)
PLANE_OUT(10, cov_xx)
PLANE_OUT(11, cov_xy)
PLANE_OUT(12, cov_xz)
PLANE_OUT(13, cov_yy)
PLANE_OUT(14, cov_yz)
PLANE_OUT(15, cov_zz)

// A value the f32 output cannot hold (NaN, +-inf, beyond the f32 range: from
// non-finite or overflowing sums) is 0; the diagonal is kept before the
// off-diagonals are clamped to it, so a zeroed variance zeroes its
// covariances. Twin: reference::finalize_covariance::kept.
real kept(real v) {
    return (isnan(v) || isinf(v) || abs(v) > real(3.4028234663852886e38)) ? real(0.0) : v;
}

real off_diag(real sab, real ma, real mb, real n, real daa, real dbb) {
    real c = (sab - n * ma * mb) / n;
    real bound = sqrt(daa * dbb);
    return clamp(kept(c), -bound, bound);
}

void main() {
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) return;
    uint i = y * push.width + x;
    real n = real(spp_of(count_in[i]));
    real xx = real(0.0), xy = real(0.0), xz = real(0.0), yy = real(0.0), yz = real(0.0), zz = real(0.0);
    if (n >= real(1.0)) {
        real mx = real(sum_x[i]) / n;
        real my = real(sum_y[i]) / n;
        real mz = real(sum_z[i]) / n;
        xx = kept(max((real(sumsq_x[i]) - n * mx * mx) / n, real(0.0)));
        yy = kept(max((real(sumsq_y[i]) - n * my * my) / n, real(0.0)));
        zz = kept(max((real(sumsq_z[i]) - n * mz * mz) / n, real(0.0)));
        xy = off_diag(real(sum_xy[i]), mx, my, n, xx, yy);
        xz = off_diag(real(sum_xz[i]), mx, mz, n, xx, zz);
        yz = off_diag(real(sum_yz[i]), my, mz, n, yy, zz);
    }
    cov_xx[i] = float(xx);
    cov_xy[i] = float(xy);
    cov_xz[i] = float(xz);
    cov_yy[i] = float(yy);
    cov_yz[i] = float(yz);
    cov_zz[i] = float(zz);
}
