// Stage 0 of the input sanitation (spec §0.4 steps 1-2) for one pixel,
// shared by `sanitize` (one pixel per invocation, scalar planes) and
// `sanitize_quads` (four pixels per invocation, vec4 planes). Scalar twin:
// src/reference/sanitize.rs.
//
// Hook: the kernel declares the push block `push` (SanitizePush), the
// `counters` buffer, and defines, before including this file,
//     float san_value_in(uint i);  // the channel value of flat pixel i
//     float san_var_in(uint i);    // its variance (read only when has_var)
//     float san_spp(uint i);       // its raw sample count
//     void san_store(uint i, float value, float var);  // the outputs

#ifndef MC_SANITIZE_REPAIR_GLSL
#define MC_SANITIZE_REPAIR_GLSL

// Whether a repair at p is counted: outside the margins SanitizePush::skip_lo
// and skip_hi leave out (a tile's halo; 0 counts every pixel).
bool san_counts(ivec2 p)
{
    uvec2 lo = uvec2(push.skip_lo & 0xffffu, push.skip_lo >> 16);
    uvec2 hi = uvec2(push.skip_hi & 0xffffu, push.skip_hi >> 16);
    return all(greaterThanEqual(uvec2(p), lo)) && uint(p.x) + hi.x < push.width
        && uint(p.y) + hi.y < push.height;
}

uint pix(ivec2 q)
{
    return uint(q.y) * push.width + uint(q.x);
}

bool san_valid(ivec2 q)
{
    return spp_of(san_spp(pix(q))) >= 1.0;
}

// A neighbour that step 1 takes its median from: valid, finite, not p.
bool repair_source(ivec2 q, ivec2 p)
{
    return q != p && san_valid(q) && is_finite(san_value_in(pix(q)));
}

// Step 1's median of the finite values of the valid 3x3 neighbours of p
// (centre excluded; the mean of the two middle values for an even count), or
// 0 if there are none, by rank selection: the value whose rank range
// [#smaller, #smaller + #equal) holds the middle index. No local array: on
// lavapipe a kernel that merely contains san_median's 49-entry array runs
// every invocation ~5x slower, and repairs are rare.
real median_neighbours(ivec2 p, ivec2 size)
{
    ivec2 lo = max(p - ivec2(1), ivec2(0));
    ivec2 up = min(p + ivec2(1), size - ivec2(1));
    int m = 0;
    for (int qy = lo.y; qy <= up.y; ++qy) {
        for (int qx = lo.x; qx <= up.x; ++qx) {
            m += repair_source(ivec2(qx, qy), p) ? 1 : 0;
        }
    }
    if (m == 0) {
        return real(0);
    }
    int i0 = (m - 1) / 2;
    int i1 = m / 2;
    real a = real(0);
    real b = real(0);
    for (int jy = lo.y; jy <= up.y; ++jy) {
        for (int jx = lo.x; jx <= up.x; ++jx) {
            if (!repair_source(ivec2(jx, jy), p)) {
                continue;
            }
            real vj = real(san_value_in(pix(ivec2(jx, jy))));
            int less = 0;
            int same = 0;
            for (int ky = lo.y; ky <= up.y; ++ky) {
                for (int kx = lo.x; kx <= up.x; ++kx) {
                    if (repair_source(ivec2(kx, ky), p)) {
                        real vk = real(san_value_in(pix(ivec2(kx, ky))));
                        less += vk < vj ? 1 : 0;
                        same += vk == vj ? 1 : 0;
                    }
                }
            }
            if (less <= i0 && i0 < less + same) {
                a = vj;
            }
            if (less <= i1 && i1 < less + same) {
                b = vj;
            }
        }
    }
    return real(0.5) * (a + b);
}

// Spec §0.4 steps 1-2.
void stage_repair(ivec2 p, ivec2 size, uint i)
{
    // Step 1: a non-finite value becomes the median of the finite values of
    // the valid 3x3 neighbours (centre excluded), or 0.
    float b = san_value_in(i);
    bool repaired = !is_finite(b);
    if (repaired) {
        b = float(median_neighbours(p, size));
        atomicAdd(counters[0], san_counts(p) ? 1u : 0u);
    }

    // Step 1 (variance of a repaired value: the largest finite variance of the
    // valid 3x3 pixels, centre included), then step 2 (negative or
    // non-finite -> 0). No variance layer: 0.
    float v = 0.0;
    if (push.has_var != 0u) {
        v = san_var_in(i);
        if (!is_finite(v) || v < 0.0) {
            atomicAdd(counters[1], san_counts(p) ? 1u : 0u);
        }
        if (repaired) {
            bool found = false;
            float best = 0.0;
            for (int qy = max(p.y - 1, 0); qy <= min(p.y + 1, size.y - 1); ++qy) {
                for (int qx = max(p.x - 1, 0); qx <= min(p.x + 1, size.x - 1); ++qx) {
                    ivec2 q = ivec2(qx, qy);
                    float vq = san_var_in(pix(q));
                    if (san_valid(q) && is_finite(vq)) {
                        best = found ? max(best, vq) : vq;
                        found = true;
                    }
                }
            }
            v = found ? best : 0.0;
        }
        if (!is_finite(v) || v < 0.0) {
            v = 0.0;
        }
    }
    san_store(i, b, v);
}

#endif // MC_SANITIZE_REPAIR_GLSL
