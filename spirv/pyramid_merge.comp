#version 460
// The pyramid's merge (PYRAMID-LOWBAND, ours): the fine reconstruction f
// takes its low band from the coarse reconstruction c of the 2x2-pooled
// statistics, as a ratio and in proportion to the two error estimates.
// Per fine pixel and channel, with the bilinear weights of the coarse
// pixels around it (pixel centres aligned, clamped at the border; only
// coarse pixels with n >= 1, renormalised):
//   L  = up(down(f)),   Ef = up(down(E_f)),  (down: the mean over the
//   C  = up(c),         Ec = up(E_c)          block's valid fine pixels,
//                                             weighted by their counts)
//   a  = Ef / (Ef + Ec)
//   out = max(f * (1 - a + a * (max(C, 0) + eps) / (max(L, 0) + eps)), 0)
//   E_out = E_f - a * min(E_f, Ef)
// An invalid fine pixel, or one with no valid coarse pixel around it,
// keeps f and E_f.
// Scalar twin: src/reference/pyramid_merge.rs.
#include "lib/common.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Mirrors mcdenoise::shared::PyramidPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint kind;
    uint other_width;
    uint other_height;
    float eps;
    uint pad0;
} push;

PLANE_IN(0, fr)
PLANE_IN(1, fg)
PLANE_IN(2, fb)
PLANE_IN(3, er)
PLANE_IN(4, eg)
PLANE_IN(5, eb)
PLANE_IN(6, fspp)
PLANE_IN(7, cr)
PLANE_IN(8, cg)
PLANE_IN(9, cb)
PLANE_IN(10, cer)
PLANE_IN(11, ceg)
PLANE_IN(12, ceb)
PLANE_IN(13, cspp)
PLANE_OUT(14, outr)
PLANE_OUT(15, outg)
PLANE_OUT(16, outb)
PLANE_OUT(17, oer)
PLANE_OUT(18, oeg)
PLANE_OUT(19, oeb)

real3 fine_colour(uint j) { return real3(fr[j], fg[j], fb[j]); }
real3 fine_error(uint j) { return real3(er[j], eg[j], eb[j]); }

void main()
{
    uint x = gl_GlobalInvocationID.x;
    uint y = push.row0 + gl_GlobalInvocationID.y;
    if (x >= push.width || y >= push.height) {
        return;
    }
    uint i = y * push.width + x;
    uint cw = push.other_width;
    uint ch = push.other_height;
    real3 f = fine_colour(i);
    real3 ef = fine_error(i);
    real3 lf = real3(0);
    real3 df = real3(0);
    real3 cu = real3(0);
    real3 ec = real3(0);
    real wsum = real(0);
    real gx = clamp((real(x) + real(0.5)) * real(0.5) - real(0.5), real(0), real(cw - 1u));
    real gy = clamp((real(y) + real(0.5)) * real(0.5) - real(0.5), real(0), real(ch - 1u));
    uint x0 = uint(gx);
    uint y0 = uint(gy);
    real tx = gx - real(x0);
    real ty = gy - real(y0);
    for (uint k = 0u; k < 4u; ++k) {
        uint kx = min(x0 + (k & 1u), cw - 1u);
        uint ky = min(y0 + (k >> 1u), ch - 1u);
        real w = ((k & 1u) == 1u ? tx : real(1) - tx) * ((k >> 1u) == 1u ? ty : real(1) - ty);
        uint c = ky * cw + kx;
        if (w <= real(0) || spp_of(cspp[c]) <= 0.0) {
            continue;
        }
        // down(f) and down(E_f) over the block's valid fine pixels,
        // weighted by their counts as the pooled means are.
        real3 bf = real3(0);
        real3 be = real3(0);
        real nb = real(0);
        for (uint q = 0u; q < 4u; ++q) {
            uint bx = 2u * kx + (q & 1u);
            uint by = 2u * ky + (q >> 1u);
            if (bx < push.width && by < push.height) {
                uint j = by * push.width + bx;
                real n = real(spp_of(fspp[j]));
                if (n > real(0)) {
                    bf += n * fine_colour(j);
                    be += n * fine_error(j);
                    nb += n;
                }
            }
        }
        wsum += w;
        lf += w * bf / nb;
        df += w * be / nb;
        cu += w * real3(cr[c], cg[c], cb[c]);
        ec += w * real3(cer[c], ceg[c], ceb[c]);
    }
    real3 o = f;
    real3 e = ef;
    if (spp_of(fspp[i]) > 0.0 && wsum > real(0)) {
        lf /= wsum;
        df = max(df / wsum, real3(0));
        cu /= wsum;
        ec = max(ec / wsum, real3(0));
        real eps = real(push.eps);
        for (int k = 0; k < 3; ++k) {
            real den = df[k] + ec[k];
            real a = den > real(0) ? df[k] / den : real(0);
            real ratio = (max(cu[k], real(0)) + eps) / (max(lf[k], real(0)) + eps);
            o[k] = max(f[k] * (real(1) - a + a * ratio), real(0));
            real efk = max(ef[k], real(0));
            e[k] = efk - a * min(efk, df[k]);
        }
    }
    outr[i] = float(o.x);
    outg[i] = float(o.y);
    outb[i] = float(o.z);
    oer[i] = float(e.x);
    oeg[i] = float(e.y);
    oeb[i] = float(e.z);
}
