#version 460
// Outlier redistribution, applied (spec §4.4 step 4): per valid pixel i,
// ŷ_final = max(0, ŷ (1 + Σ rho_o) + Σ add_o) over the outliers o whose
// Ω_o(R) holds i (the same as o ∈ Ω_i(R): the window is symmetric), from
// box_rows' row sums of rho and add; OUTLIER-CLAMP. In place on the method's
// colour planes; invalid pixels keep their value. Scalar twin:
// src/reference/outlier_spread.rs.
#include "lib/common.glsl"
#include "lib/outliers.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

PLANE_IN(0, rho_r)
PLANE_IN(1, rho_g)
PLANE_IN(2, rho_b)
PLANE_IN(3, add_r)
PLANE_IN(4, add_g)
PLANE_IN(5, add_b)
PLANE_IN(6, spp)
PLANE_OUT(7, yr)
PLANE_OUT(8, yg)
PLANE_OUT(9, yb)

// Each invocation covers SPAN consecutive rows of one column: one full
// column sum, then a running sum (add the entering row, drop the leaving
// one), both kept exactly as pairs (TWO_SUM_ADD, lib/outliers.glsl), so a
// large weight that has left the window leaves no rounding behind.
// Dispatched over width x ceil(height/SPAN).
#define SPAN 32

// The row qy's weights, times sign, into the pairs (rows outside the image
// add nothing).
#define LOAD_ROW(qy, sign)                                                      \
    if ((qy) >= 0 && (qy) < int(push.height)) {                                 \
        uint q_ = uint(qy) * push.width + x;                                    \
        TWO_SUM_ADD(real3, rho_hi, rho_lo, (sign) * real3(rho_r[q_], rho_g[q_], rho_b[q_])) \
        TWO_SUM_ADD(real3, add_hi, add_lo, (sign) * real3(add_r[q_], add_g[q_], add_b[q_])) \
    }

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y0 = (push.row0 + gl_GlobalInvocationID.y) * SPAN;
    if (x >= push.width || y0 >= push.height) {
        return;
    }
    int r = int(push.radius);
    precise real3 rho_hi = real3(0);
    precise real3 rho_lo = real3(0);
    precise real3 add_hi = real3(0);
    precise real3 add_lo = real3(0);
    for (int qy = int(y0) - r; qy <= int(y0) + r; ++qy) {
        LOAD_ROW(qy, real(1))
    }
    uint y1 = min(y0 + SPAN, push.height);
    for (uint y = y0; y < y1; ++y) {
        uint i = y * push.width + x;
        real3 rho = rho_hi + rho_lo;
        real3 add = add_hi + add_lo;
        if (valid_at(spp[i]) && (rho != real3(0) || add != real3(0))) {
            real3 v = real3(yr[i], yg[i], yb[i]) * (real3(1) + rho) + add;
            v = max(v, real3(0));
            yr[i] = float(v.x);
            yg[i] = float(v.y);
            yb[i] = float(v.z);
        }
        LOAD_ROW(int(y) + r + 1, real(1))
        LOAD_ROW(int(y) - r, real(-1))
    }
}
