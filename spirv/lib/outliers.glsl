// Shared pieces of the outlier stage (spec §4.4): the push block of every
// outlier kernel, grey, and the merge of (count, mean, M2) summaries.
// Scalar twin: src/reference/outliers.rs.

// Mirrors mcdenoise::shared::OutlierPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint radius;    // 14 (detection) or 43 / 215 (redistribution)
    uint mode;      // box_rows: 0 = sum of valid values, 1 = count of valid pixels
    uint min_n;     // OUTLIER-MIN-N
    float k_sigma;  // 3
    float dark;     // DARK-WINDOW factor, 1e-8
    float wide;     // outlier_weights: OUTLIER-WIDE's fraction
} push;

// OutlierPush::mode of outlier_weights (mcdenoise::shared::WEIGHTS_*).
#define WEIGHTS_NARROW 1u
#define WEIGHTS_WIDE 2u
// OutlierPush::mode of outlier_detect (mcdenoise::shared::DETECT_RIM):
// OUTLIER-RIM.
#define DETECT_RIM 1u
// The queue entry's bit that marks an outlier for the wide window.
#define QUEUE_WIDE 0x80000000u

bool valid_at(float s) { return spp_of(s) >= 1.0; }

// The grey of outlier_grey's key k (its inverse, exact); false for k = 0
// (an invalid pixel).
bool key_grey(uint k, out real g)
{
    uint b = (k & 0x80000000u) != 0u ? (k & 0x7fffffffu) : ~k;
    g = real(uintBitsToFloat(b));
    return k != 0u;
}

// Entries of the queue of detected pixels (outlier_detect, outlier_median):
// OUTLIER-ISOLATED (and OUTLIER-RIM) never detects two 8-neighbours, so at
// most one pixel of each 2x2 block; entries past it (a near-tie the two
// tests round apart) are not queued.
uint queue_capacity() { return ((push.width + 1u) / 2u) * ((push.height + 1u) / 2u); }

// hi + lo += x without rounding error (Knuth's TwoSum; component-wise for
// vectors): the running box sums of box_rows and outlier_spread keep the
// exact sum as an unevaluated pair, so a large value that has left the
// window leaves no rounding behind (a window of zeros next to a light sums
// to 0, which DARK-WINDOW tests). hi and lo must be `precise`.
#define TWO_SUM_ADD(T, hi, lo, x)                       \
    {                                                   \
        T x_ = (x);                                     \
        precise T s_ = hi + x_;                         \
        precise T b_ = s_ - hi;                         \
        precise T e_ = (hi - (s_ - b_)) + (x_ - b_);    \
        hi = s_;                                        \
        lo += e_;                                       \
    }

// (count, mean, M2) of a set of values; merged exactly as Chan et al.'s
// parallel variance, so no sum of squares ever cancels.
struct Summary {
    real n;
    real mean;
    real m2;
};

Summary merge(Summary a, Summary b)
{
    if (b.n == real(0)) {
        return a;
    }
    if (a.n == real(0)) {
        return b;
    }
    real n = a.n + b.n;
    real d = b.mean - a.mean;
    Summary r;
    r.n = n;
    r.mean = a.mean + d * (b.n / n);
    r.m2 = a.m2 + b.m2 + d * d * (a.n * b.n / n);
    return r;
}
