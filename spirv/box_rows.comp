#version 460
// Row part of a box sum over valid pixels (spec §0.2 windows, clipped): per
// pixel (x, y), the sum of `value` (mode 0) or the number of valid pixels
// (mode 1) over row y, |qx - x| <= push.radius. A column pass over 2R + 1
// rows of this gives the sum over the square window Ω(R); used by the outlier
// redistribution (§4.4 step 4, R = 43). Scalar twin: src/reference/box_rows.rs.
#include "lib/common.glsl"
#include "lib/outliers.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

PLANE_IN(0, value)
PLANE_IN(1, spp)
PLANE_OUT(2, out_p)

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    int r = int(push.radius);
    real s = real(0);
    for (int qx = max(int(x) - r, 0); qx <= min(int(x) + r, int(push.width) - 1); ++qx) {
        uint q = y * push.width + uint(qx);
        if (valid_at(spp[q])) {
            s += push.mode == 1u ? real(1) : real(value[q]);
        }
    }
    out_p[y * push.width + x] = float(s);
}
