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
// one), restarted every SPAN rows. Dispatched over width x ceil(height/SPAN).
#define SPAN 16

void load_row(int qy, uint x, inout real3 rho, inout real3 add, real sign)
{
    if (qy < 0 || qy >= int(push.height)) {
        return;
    }
    uint q = uint(qy) * push.width + x;
    rho += sign * real3(rho_r[q], rho_g[q], rho_b[q]);
    add += sign * real3(add_r[q], add_g[q], add_b[q]);
}

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y0 = (push.row0 + gl_GlobalInvocationID.y) * SPAN;
    if (x >= push.width || y0 >= push.height) {
        return;
    }
    int r = int(push.radius);
    real3 rho = real3(0);
    real3 add = real3(0);
    for (int qy = int(y0) - r; qy <= int(y0) + r; ++qy) {
        load_row(qy, x, rho, add, real(1));
    }
    uint y1 = min(y0 + SPAN, push.height);
    for (uint y = y0; y < y1; ++y) {
        uint i = y * push.width + x;
        if (valid_at(spp[i]) && (rho != real3(0) || add != real3(0))) {
            real3 v = real3(yr[i], yg[i], yb[i]) * (real3(1) + rho) + add;
            v = max(v, real3(0));
            yr[i] = float(v.x);
            yg[i] = float(v.y);
            yb[i] = float(v.z);
        }
        load_row(int(y) + r + 1, x, rho, add, real(1));
        load_row(int(y) - r, x, rho, add, real(-1));
    }
}
