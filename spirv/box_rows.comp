#version 460
// Row part of a box sum over valid pixels (spec §0.2 windows, clipped): per
// pixel (x, y) and plane, the sum of the plane's values, or the number of
// valid pixels, over row y, |qx - x| <= push.radius. A column pass over
// 2R + 1 rows of this gives the sum over the square window Ω(R); used by the
// outlier redistribution (§4.4 step 4, R = 43). Scalar twin:
// src/reference/box_rows.rs.
//
// One dispatch sums several planes (push.mode: their number, 2 or 4, plus
// BOX_COUNT_LAST when the fourth is the count of valid pixels, whose value
// binding is not read): each tap's validity is loaded once for all of them
// (lavapipe pays per lane and float loaded). Each plane's sums are those of
// one dispatch per plane. One loop per variant, the others' ranges empty
// (lavapipe runs both sides of a branch, and would load every binding).
//
// Dispatched over ceil(width / SPAN) x height invocations. Each invocation
// covers SPAN consecutive pixels of a row: one full window sum, then a
// running sum (add the entering tap, drop the leaving one), both kept
// exactly as a pair (TWO_SUM_ADD, lib/outliers.glsl): a plain running sum
// keeps the rounding of every large value it passed, and a window of zeros
// beside a light must sum to 0 (DARK-WINDOW).
#include "lib/common.glsl"
#include "lib/outliers.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

PLANE_IN(0, v0)
PLANE_IN(1, v1)
PLANE_IN(2, v2)
PLANE_IN(3, v3)
PLANE_IN(4, spp)
PLANE_OUT(5, o0)
PLANE_OUT(6, o1)
PLANE_OUT(7, o2)
PLANE_OUT(8, o3)

#define SPAN 32
// mcdenoise::shared::BOX_COUNT_LAST.
#define BOX_COUNT_LAST 8u

// The pixel of row y, column qx, when it exists and is valid.
bool box_tap(uint y, int qx, out uint q)
{
    q = 0u;
    if (qx < 0 || qx >= int(push.width)) {
        return false;
    }
    q = y * push.width + uint(qx);
    return valid_at(spp[q]);
}

real4 tap4(uint y, int qx)
{
    uint q;
    return box_tap(y, qx, q) ? real4(v0[q], v1[q], v2[q], v3[q]) : real4(0);
}

real4 tap3c(uint y, int qx)
{
    uint q;
    return box_tap(y, qx, q) ? real4(v0[q], v1[q], v2[q], 1.0) : real4(0);
}

real2 tap2(uint y, int qx)
{
    uint q;
    return box_tap(y, qx, q) ? real2(v0[q], v1[q]) : real2(0);
}

void store4(uint i, real4 s)
{
    o0[i] = float(s.x);
    o1[i] = float(s.y);
    o2[i] = float(s.z);
    o3[i] = float(s.w);
}

void store2(uint i, real2 s)
{
    o0[i] = float(s.x);
    o1[i] = float(s.y);
}

// The full window sum at x0, then the running sum along the span, as the
// exact pair hi + lo.
#define BOX_SPAN(T, TAP, STORE)                                          \
    {                                                                    \
        precise T hi = T(0);                                             \
        precise T lo = T(0);                                             \
        for (int qx = int(x0) - r; qx <= int(x0) + r; ++qx) {            \
            TWO_SUM_ADD(T, hi, lo, TAP(y, qx))                           \
        }                                                                \
        for (uint x = x0; x < x1; ++x) {                                 \
            STORE(y * push.width + x, hi + lo);                          \
            TWO_SUM_ADD(T, hi, lo, TAP(y, int(x) + r + 1))               \
            TWO_SUM_ADD(T, hi, lo, -TAP(y, int(x) - r))                  \
        }                                                                \
    }

void main()
{
    uint x0 = gl_GlobalInvocationID.x * SPAN;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x0 >= push.width || y >= push.height) {
        return;
    }
    int r = int(push.radius);
    uint x1 = min(x0 + SPAN, push.width);
    uint planes = push.mode & 7u;
    bool count = (push.mode & BOX_COUNT_LAST) != 0u;
    for (int once = 0; once < ((planes == 4u && !count) ? 1 : 0); ++once) {
        BOX_SPAN(real4, tap4, store4)
    }
    for (int once = 0; once < ((planes == 4u && count) ? 1 : 0); ++once) {
        BOX_SPAN(real4, tap3c, store4)
    }
    for (int once = 0; once < (planes == 2u ? 1 : 0); ++once) {
        BOX_SPAN(real2, tap2, store2)
    }
}
