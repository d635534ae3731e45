#version 460
// Outlier stage, first pass (spec §4.4 step 1): per pixel, the
// order-preserving u32 key of grey = (R+G+B)/3 rounded to f32, 0 where the
// pixel is invalid (no grey has key 0: it would be a NaN, and the sanitised
// colours are finite). The window kernels after it (outlier_rows,
// outlier_detect, outlier_median) load this one plane per neighbour instead
// of the three colour planes and the count, and decode grey exactly
// (lib/outliers.glsl, key_grey); validity needs no NaN, which a GPU may
// not preserve. Scalar twin: src/reference/outlier_grey.rs.
#include "lib/common.glsl"
#include "lib/outliers.glsl"
layout(local_size_x = 8, local_size_y = 8) in;
PLANE_IN(0, cr)
PLANE_IN(1, cg)
PLANE_IN(2, cb)
PLANE_IN(3, spp)
layout(std430, set = 0, binding = 4) buffer keys_blk { uint keys[]; };
void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    uint i = y * push.width + x;
    uint k = 0u;
    if (valid_at(spp[i])) {
        uint b = floatBitsToUint(float((real(cr[i]) + real(cg[i]) + real(cb[i])) / real(3)));
        k = (b & 0x80000000u) != 0u ? ~b : (b | 0x80000000u);
    }
    keys[i] = k;
}
