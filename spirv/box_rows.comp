#version 460
// Row part of a box sum over valid pixels (spec §0.2 windows, clipped): per
// pixel (x, y), the sum of `value` (mode 0) or the number of valid pixels
// (mode 1) over row y, |qx - x| <= push.radius. A column pass over 2R + 1
// rows of this gives the sum over the square window Ω(R); used by the outlier
// redistribution (§4.4 step 4, R = 43). Scalar twin: src/reference/box_rows.rs.
// Dispatched over ceil(width / SPAN) x height invocations.
#include "lib/common.glsl"
#include "lib/outliers.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

PLANE_IN(0, value)
PLANE_IN(1, spp)
PLANE_OUT(2, out_p)

// Each invocation covers SPAN consecutive pixels of a row: one full window
// sum, then a running sum (add the entering tap, drop the leaving one),
// restarted every SPAN pixels so f32 rounding cannot accumulate.
#define SPAN 16

real tap(uint y, int qx)
{
    if (qx < 0 || qx >= int(push.width)) {
        return real(0);
    }
    uint q = y * push.width + uint(qx);
    if (!valid_at(spp[q])) {
        return real(0);
    }
    return push.mode == 1u ? real(1) : real(value[q]);
}

void main()
{
    uint x0 = gl_GlobalInvocationID.x * SPAN;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x0 >= push.width || y >= push.height) {
        return;
    }
    int r = int(push.radius);
    real s = real(0);
    for (int qx = int(x0) - r; qx <= int(x0) + r; ++qx) {
        s += tap(y, qx);
    }
    uint x1 = min(x0 + SPAN, push.width);
    for (uint x = x0; x < x1; ++x) {
        out_p[y * push.width + x] = float(s);
        s += tap(y, int(x) + r + 1) - tap(y, int(x) - r);
    }
}
