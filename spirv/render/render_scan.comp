#version 460
// The work items of a render pass (host side: Renderer::record in
// src/render/mod.rs): an exclusive prefix sum of the pass's per-pixel sample
// counts, so that item i of the pass is sample i - prefix[p] of the last
// pixel p with prefix[p] <= i, and a snapshot of each pixel's count plane
// at the start of the pass (its first sample index in this pass). Exact u32
// arithmetic in a fixed order: the same counts give the same items.
//
// Three dispatches over blocks of push.block consecutive pixels, so no
// invocation loops more than a few hundred times (llvmpipe ends all loops
// of an invocation after 65,535 iterations in total):
//   phase 0: one invocation per block sums its counts into blocks[b];
//   phase 1: one workgroup turns blocks[] into exclusive prefixes (each
//            invocation scans a run of blocks, invocation 0 the runs' sums);
//   phase 2: one invocation per block writes its pixels' scan entries from
//            blocks[b]; the last block also writes scan[pixels] = (total, 0).

layout(local_size_x = 64) in;

// Mirrors mcdenoise::render::ScanPush.
layout(push_constant) uniform Push {
    uint pixels;        // pixels of the image
    uint blocks;        // ceil(pixels / block)
    uint row0;          // first grid row of the band (Batch::dispatch)
    uint phase;         // 0, 1 or 2 (see above)
    uint block;         // pixels per block
    uint uniform_spp;   // samples per pixel when use_map == 0
    uint use_map;       // 1: samples per pixel from spp_map
    uint pad;
} push;

layout(std430, set = 0, binding = 0) readonly buffer SppMap { uint spp_map[]; };
// The count plane of the accumulation layout (plane 31).
layout(std430, set = 0, binding = 1) readonly buffer Count { float count_plane[]; };
// Per pixel: (exclusive prefix of the counts, count plane at the start of
// the pass); entry `pixels` holds (total, 0).
layout(std430, set = 0, binding = 2) buffer Scan { uvec2 scan[]; };
// Per block: its sum (phase 0), then the exclusive prefix of the sums (phase 1).
layout(std430, set = 0, binding = 3) buffer Blocks { uint blocks[]; };

shared uint runs[gl_WorkGroupSize.x];

uint samples_of(uint p)
{
    return push.use_map != 0u ? spp_map[p] : push.uniform_spp;
}

void main()
{
    if (push.phase == 1u) {
        // One workgroup (the host dispatches one; any other would race):
        // invocation t scans blocks [t * per, (t + 1) * per).
        if (gl_WorkGroupID != uvec3(0u)) {
            return;
        }
        uint t = gl_LocalInvocationIndex;
        uint per = (push.blocks + gl_WorkGroupSize.x - 1u) / gl_WorkGroupSize.x;
        uint b0 = min(t * per, push.blocks);
        uint b1 = min(b0 + per, push.blocks);
        uint sum = 0u;
        for (uint b = b0; b < b1; b++) {
            sum += blocks[b];
        }
        runs[t] = sum;
        barrier();
        if (t == 0u) {
            uint run = 0u;
            for (uint k = 0u; k < gl_WorkGroupSize.x; k++) {
                uint s = runs[k];
                runs[k] = run;
                run += s;
            }
        }
        barrier();
        uint run = runs[t];
        for (uint b = b0; b < b1; b++) {
            uint s = blocks[b];
            blocks[b] = run;
            run += s;
        }
        return;
    }
    uint row_items = gl_NumWorkGroups.x * gl_WorkGroupSize.x;
    uint b = (push.row0 + gl_GlobalInvocationID.y) * row_items + gl_GlobalInvocationID.x;
    if (b >= push.blocks) {
        return;
    }
    uint p0 = b * push.block;
    uint p1 = min(p0 + push.block, push.pixels);
    if (push.phase == 0u) {
        uint sum = 0u;
        for (uint p = p0; p < p1; p++) {
            sum += samples_of(p);
        }
        blocks[b] = sum;
        return;
    }
    uint run = blocks[b];
    for (uint p = p0; p < p1; p++) {
        scan[p] = uvec2(run, uint(count_plane[p]));
        run += samples_of(p);
    }
    if (p1 == push.pixels) {
        scan[push.pixels] = uvec2(run, 0u);
    }
}
