#version 460
// Outlier detection and replacement (spec §4.4 steps 1-3). Per valid pixel o:
// the (count, mean, M2) of grey over Ω_o(R) \ {o} merged from outlier_rows'
// half-row summaries (EXCL-CENTRE); o is an outlier when count >= min_n
// (OUTLIER-MIN-N), grey_o - m > k sd (SPIKE-SIDE, population sd) and
// grey_o - m <= k se_o (OUTLIER-NOISE, se from the pixel's variances) and
// no 8-neighbour is above m + k sd (OUTLIER-ISOLATED). An
// outlier takes the colour and variance of q*, the pixel of median grey in
// Ω_o(R) with o (lower median of an even count, lowest raster index among
// equal greys: OUTLIER-MEDIAN), found by a 32-step radix selection on the
// order-preserving bits of grey (no local array); e = y_o - y_q* per channel,
// 0 elsewhere. Every read is of the original planes (detections applied at
// once). Scalar twin: src/reference/outlier_detect.rs.
#include "lib/common.glsl"
#include "lib/outliers.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

PLANE_IN(0, cr)
PLANE_IN(1, cg)
PLANE_IN(2, cb)
PLANE_IN(3, vr)
PLANE_IN(4, vg)
PLANE_IN(5, vb)
PLANE_IN(6, spp)
PLANE_IN(7, ln)
PLANE_IN(8, lm)
PLANE_IN(9, lq)
PLANE_IN(10, rn)
PLANE_IN(11, rm)
PLANE_IN(12, rq)
layout(std430, set = 0, binding = 13) readonly buffer keys_blk { uint keys[]; };
PLANE_OUT(14, out_r)
PLANE_OUT(15, out_g)
PLANE_OUT(16, out_b)
PLANE_OUT(17, out_vr)
PLANE_OUT(18, out_vg)
PLANE_OUT(19, out_vb)
PLANE_OUT(20, er)
PLANE_OUT(21, eg)
PLANE_OUT(22, eb)

real grey_at(uint i) { return (real(cr[i]) + real(cg[i]) + real(cb[i])) / real(3); }

// Order-preserving unsigned key of grey (outlier_rows).
uint key_of(uint i) { return keys[i]; }

Summary half_row(uint q, bool left)
{
    Summary s;
    s.n = real(left ? ln[q] : rn[q]);
    s.mean = real(left ? lm[q] : rm[q]);
    s.m2 = real(left ? lq[q] : rq[q]);
    return s;
}

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    uint o = y * push.width + x;
    int r = int(push.radius);
    int x0 = max(int(x) - r, 0), x1 = min(int(x) + r, int(push.width) - 1);
    int y0 = max(int(y) - r, 0), y1 = min(int(y) + r, int(push.height) - 1);
    uint q = o;
    if (valid_at(spp[o])) {
        Summary s;
        s.n = real(0);
        s.mean = real(0);
        s.m2 = real(0);
        for (int qy = y0; qy <= y1; ++qy) {
            uint c = uint(qy) * push.width + x;
            Summary row = half_row(c, true);
            if (qy != int(y) && valid_at(spp[c])) {
                Summary one;
                one.n = real(1);
                one.mean = grey_at(c);
                one.m2 = real(0);
                row = merge(row, one);
            }
            row = merge(row, half_row(c, false));
            s = merge(s, row);
        }
        real sd = sqrt(max(s.m2 / max(s.n, real(1)), real(0)));
        // OUTLIER-NOISE: the excess must also be within k standard errors of
        // the pixel's own mean (a directly seen small light is not noise).
        real se = (sqrt(max(real(vr[o]), real(0))) + sqrt(max(real(vg[o]), real(0)))
                   + sqrt(max(real(vb[o]), real(0)))) / real(3);
        real excess = grey_at(o) - s.mean;
        bool outlier = s.n >= real(push.min_n) && excess > real(push.k_sigma) * sd
            && excess <= real(push.k_sigma) * se;
        // OUTLIER-ISOLATED: a bright 8-neighbour makes o part of a feature.
        for (int qy = max(int(y) - 1, 0); outlier && qy <= min(int(y) + 1, int(push.height) - 1); ++qy) {
            for (int qx = max(int(x) - 1, 0); qx <= min(int(x) + 1, int(push.width) - 1); ++qx) {
                uint j = uint(qy) * push.width + uint(qx);
                if (j != o && valid_at(spp[j]) && grey_at(j) - s.mean > real(push.k_sigma) * sd) {
                    outlier = false;
                }
            }
        }
        if (outlier) {
            // Rank of the median among the valid pixels of the window, o included.
            uint n = 0u;
            for (int qy = y0; qy <= y1; ++qy) {
                for (int qx = x0; qx <= x1; ++qx) {
                    n += valid_at(spp[uint(qy) * push.width + uint(qx)]) ? 1u : 0u;
                }
            }
            uint k = (n - 1u) / 2u;
            uint prefix = 0u;
            for (int bit = 31; bit >= 0; --bit) {
                uint hi = bit == 31 ? 0u : (0xFFFFFFFFu << uint(bit + 1));
                uint zeros = 0u;
                for (int qy = y0; qy <= y1; ++qy) {
                    for (int qx = x0; qx <= x1; ++qx) {
                        uint j = uint(qy) * push.width + uint(qx);
                        if (valid_at(spp[j])) {
                            uint kj = key_of(j);
                            zeros += ((kj & hi) == prefix && (kj & (1u << uint(bit))) == 0u) ? 1u : 0u;
                        }
                    }
                }
                if (k >= zeros) {
                    k -= zeros;
                    prefix |= 1u << uint(bit);
                }
            }
            // The lowest raster index holding the median key.
            bool found = false;
            for (int qy = y0; qy <= y1 && !found; ++qy) {
                for (int qx = x0; qx <= x1 && !found; ++qx) {
                    uint j = uint(qy) * push.width + uint(qx);
                    if (valid_at(spp[j]) && key_of(j) == prefix) {
                        q = j;
                        found = true;
                    }
                }
            }
        }
    }
    out_r[o] = cr[q];
    out_g[o] = cg[q];
    out_b[o] = cb[q];
    out_vr[o] = vr[q];
    out_vg[o] = vg[q];
    out_vb[o] = vb[q];
    er[o] = float(real(cr[o]) - real(cr[q]));
    eg[o] = float(real(cg[o]) - real(cg[q]));
    eb[o] = float(real(cb[o]) - real(cb[q]));
}
