// Median, MAD and the step-4 variance estimator of the input sanitation
// (spec §0.4). Scalar twin: `median` and `mad_variance` in
// src/reference/sanitize.rs.
//
// Hook: the kernel defines (before or after the include; the prototypes are
// declared here)
//     bool san_valid(ivec2 q);   // spp_of(spp[q]) >= 1
//     real san_value(ivec2 q);   // the channel value b_q (finite when valid)

#ifndef MC_SANITIZE_GLSL
#define MC_SANITIZE_GLSL

#include "lib/common.glsl"

bool san_valid(ivec2 q);
real san_value(ivec2 q);

// Largest median population: the 7x7 window of step 4.
#define SAN_MAX 49

// Sorts v[0..n) ascending (insertion sort; n <= SAN_MAX, values finite).
void san_sort(inout real v[SAN_MAX], int n)
{
    for (int i = 1; i < n; ++i) {
        real key = v[i];
        int j = i - 1;
        while (j >= 0 && v[j] > key) {
            v[j + 1] = v[j];
            --j;
        }
        v[j + 1] = key;
    }
}

// Median of v[0..n), n >= 1 (v is sorted in place): the middle value, or the
// mean of the two middle values for an even count.
real san_median(inout real v[SAN_MAX], int n)
{
    san_sort(v, n);
    int h = n / 2;
    return (n % 2 == 1) ? v[h] : real(0.5) * (v[h - 1] + v[h]);
}

// Spec §0.4 step 4 at pixel p: for each valid q of the clipped 7x7 window
// with at least one valid pixel in 3x3(q) \ {q}, e_q = b_q - mean of those
// neighbours; returns (8/9) (1.4826 MAD(e))^2 with MAD(e) = median(|e -
// median(e)|), or 0 if there is no e. The caller handles an invalid p.
real san_mad_variance(ivec2 p, ivec2 size)
{
    real e[SAN_MAX];
    int m = 0;
    for (int qy = max(p.y - 3, 0); qy <= min(p.y + 3, size.y - 1); ++qy) {
        for (int qx = max(p.x - 3, 0); qx <= min(p.x + 3, size.x - 1); ++qx) {
            ivec2 q = ivec2(qx, qy);
            if (!san_valid(q)) {
                continue;
            }
            real sum = real(0);
            int count = 0;
            for (int ry = max(qy - 1, 0); ry <= min(qy + 1, size.y - 1); ++ry) {
                for (int rx = max(qx - 1, 0); rx <= min(qx + 1, size.x - 1); ++rx) {
                    ivec2 r = ivec2(rx, ry);
                    if (r != q && san_valid(r)) {
                        sum += san_value(r);
                        ++count;
                    }
                }
            }
            if (count > 0) {
                e[m] = san_value(q) - sum / real(count);
                ++m;
            }
        }
    }
    if (m == 0) {
        return real(0);
    }
    real med = san_median(e, m);
    for (int i = 0; i < m; ++i) {
        e[i] = abs(e[i] - med);
    }
    // 1.4826 and 8/9 built from integers so the f64 variant stays exact.
    real s = real(14826) / real(10000) * san_median(e, m);
    return real(8) / real(9) * s * s;
}

#endif // MC_SANITIZE_GLSL
