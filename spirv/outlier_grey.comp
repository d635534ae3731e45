#version 460
// Outlier stage, first pass (spec §4.4 step 1): per pixel, grey = (R+G+B)/3
// rounded to f32, NaN where the pixel is invalid (no valid pixel's grey is
// NaN: the sanitised colours are finite), and its order-preserving key for
// outlier_median's selection, 0 where invalid (no grey has key 0). The
// window kernels after it read this one plane per neighbour instead of the
// three colour planes and the count. Scalar twin: src/reference/outlier_grey.rs.
#include "lib/common.glsl"
#include "lib/outliers.glsl"
layout(local_size_x = 8, local_size_y = 8) in;
PLANE_IN(0, cr)
PLANE_IN(1, cg)
PLANE_IN(2, cb)
PLANE_IN(3, spp)
PLANE_OUT(4, grey)
layout(std430, set = 0, binding = 5) buffer keys_blk { uint keys[]; };
void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    uint i = y * push.width + x;
    if (valid_at(spp[i])) {
        float g = float((real(cr[i]) + real(cg[i]) + real(cb[i])) / real(3));
        uint b = floatBitsToUint(g);
        grey[i] = g;
        keys[i] = (b & 0x80000000u) != 0u ? ~b : (b | 0x80000000u);
    } else {
        // A quiet NaN built at run time (a NaN constant would fail naga).
        grey[i] = uintBitsToFloat(0x7fc00000u | (i & 0u));
        keys[i] = 0u;
    }
}
