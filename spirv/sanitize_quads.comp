#version 460
// Stage 0 of the input sanitation (spec §0.4 steps 1-2), `sanitize` for an
// image whose width is a multiple of 4: one invocation per 4 pixels of a
// row, read and written as vec4. Invocation (gid.x, gid.y) handles pixels
// 4 gid.x .. 4 gid.x + 3 of row row0 + gid.y (a grid wider than width / 4
// leaves the rest idle). Where the four values and variances need no
// repair (the common case) the outputs are the inputs; otherwise each
// pixel takes `sanitize`'s path (lib/sanitize_repair.glsl), so the result
// is `sanitize`'s bit for bit. Why: llvmpipe pays per storage-buffer
// access, not per byte, so a quarter of the accesses makes the stage about
// 3x faster (SANITIZE-QUADS).
// Scalar twin: src/reference/sanitize_quads.rs (= sanitize's stage 0).
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::SanitizePush (stage is 0).
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint stage;
    uint has_var;  // var_in is read only when 1
    uint skip_lo;  // margins not counted: left | top << 16
    uint skip_hi;  // right | bottom << 16
    uint in_place; // 1: the outputs already hold the inputs (clean quads not written)
} push;

layout(std430, set = 0, binding = 0) readonly buffer value_in_blk { vec4 value_in[]; };
layout(std430, set = 0, binding = 1) readonly buffer var_in_blk { vec4 var_in[]; };
layout(std430, set = 0, binding = 2) readonly buffer spp_blk { vec4 spp[]; };
layout(std430, set = 0, binding = 3) buffer value_out_blk { vec4 value_out[]; };
layout(std430, set = 0, binding = 4) buffer var_out_blk { vec4 var_out[]; };
layout(std430, set = 0, binding = 5) buffer Counters { uint counters[]; };

float san_value_in(uint i) { return value_in[i >> 2u][i & 3u]; }
float san_var_in(uint i) { return var_in[i >> 2u][i & 3u]; }
float san_spp(uint i) { return spp[i >> 2u][i & 3u]; }
void san_store(uint i, float value, float var)
{
    value_out[i >> 2u][i & 3u] = value;
    var_out[i >> 2u][i & 3u] = var;
}

#include "lib/sanitize_repair.glsl"

bool all_finite(vec4 v) { return !any(isnan(v)) && !any(isinf(v)); }

void main()
{
    uint x4 = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    uint w4 = push.width >> 2u;
    if (x4 >= w4 || y >= push.height) {
        return;
    }
    uint q = y * w4 + x4;
    vec4 b = value_in[q];
    bool clean = all_finite(b);
    vec4 v = vec4(0.0);
    if (push.has_var != 0u) {
        v = var_in[q];
        clean = clean && all_finite(v) && all(greaterThanEqual(v, vec4(0.0)));
    }
    if (clean) {
        // In place (push.in_place), the outputs hold these values already.
        if (push.in_place == 0u) {
            value_out[q] = b;
            var_out[q] = v;
        }
        return;
    }
    ivec2 size = ivec2(push.width, push.height);
    for (uint k = 0u; k < 4u; ++k) {
        ivec2 p = ivec2(4u * x4 + k, y);
        stage_repair(p, size, pix(p));
    }
}
