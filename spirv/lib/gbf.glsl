// Per-pixel routines of the G-buffer prefilter (spec §6), shared by
// gbf_sure.comp and gbf_filter.comp. Scalar twin: src/reference/gbf.rs.
//
// The including kernel defines, before the include:
//   real3 gbf_position(uint q);   position of pixel q
//   real3 gbf_cov_a(uint q);      smoothed covariance entries (XX, XY, XZ)
//   real3 gbf_cov_b(uint q);      and (YY, YZ, ZZ)
//   bool gbf_valid(uint q);       spp_of >= 1

#ifndef MC_GBF_GLSL
#define MC_GBF_GLSL

#define GBF_RADIUS 3
#define GBF_H0 1e-3

#ifdef MC_F64
#define realmat3 dmat3
#else
#define realmat3 mat3
#endif

// exp in float (GLSL has no double exp; as gauss_smooth does): the weights
// of the f64 variant carry f32 relative precision.
real gbf_exp(real a)
{
    return real(exp(float(a)));
}

// S-PSD (step 1): negative diagonal entries -> 0, then
// S~ = S + eps I, eps = max(1e-3 tr(S)/3, 1e-10 (1 + |p|^2)); returned inverted
// by adjugate / determinant.
realmat3 gbf_inv_cov(uint q)
{
    real3 a = gbf_cov_a(q);
    real3 b = gbf_cov_b(q);
    real3 p = gbf_position(q);
    real sxx = max(a.x, real(0));
    real syy = max(b.x, real(0));
    real szz = max(b.z, real(0));
    real tr = sxx + syy + szz;
    real eps = max(real(1e-3) * tr / real(3), real(1e-10) * (real(1) + dot(p, p)));
    real sa = sxx + eps, sb = a.y, sc = a.z, sd = syy + eps, se = b.y, sf = szz + eps;
    real ia = sd * sf - se * se;
    real ib = sc * se - sb * sf;
    real ic = sb * se - sc * sd;
    real id = sa * sf - sc * sc;
    real ie = sb * sc - sa * se;
    real if_ = sa * sd - sb * sb;
    real r = real(1) / (sa * ia + sb * ib + sc * ic);
    return realmat3(ia, ib, ic, ib, id, ie, ic, ie, if_) * r;
}

#endif // MC_GBF_GLSL
