// Per-pixel routines of the G-buffer prefilter (spec §6), shared by
// gbf_sure.comp and gbf_filter.comp. Scalar twin: src/reference/gbf.rs.
//
// gbf_regularised_inverse is step 1's S-PSD regularisation and inverse of
// a smoothed covariance (used by gbf_prepare.comp); the other kernels read
// its output planes.

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

// 2^a in float, for weights whose log2(e) / (2 h^2) factor is folded into
// one constant or one per-pixel factor: no division per neighbour (a
// divider is several times slower than a multiply on CPUs and GPUs) and no
// separate log2(e) multiply (exp is exp2 of a scaled argument in llvmpipe).
real gbf_exp2(real a)
{
    return real(exp2(float(a)));
}

#define GBF_LOG2E 1.4426950408889634

// S-PSD (step 1): negative diagonal entries -> 0, then
// S~ = S + eps I, eps = max(1e-3 tr(S)/3, 1e-10 (1 + |p|^2)); returned inverted
// by adjugate / determinant as (XX, XY, XZ) and (YY, YZ, ZZ); a matrix that
// is not safely positive definite gives 1e20 I (GBF-PD: the pixel passes
// through).
void gbf_regularised_inverse(real3 a, real3 b, real3 p, out real3 ia3, out real3 ib3)
{
    real sxx = max(a.x, real(0));
    real syy = max(b.x, real(0));
    real szz = max(b.z, real(0));
    real tr = sxx + syy + szz;
    real eps = max(real(1e-3) * tr / real(3), real(1e-10) * (real(1) + dot(p, p)));
    real sa = sxx + eps, sb = a.y, sc = a.z, sd = syy + eps, se = b.y, sf = szz + eps;
    // GBF-PD: not safely positive definite (leading minors above 1e-4 of
    // their diagonal products) -> an unusable covariance: inverse 1e20 I, so
    // every distance through it is huge and the pixel passes through (its
    // determinant could be <= 0 and the weights NaN).
    real m2 = sa * sd - sb * sb;
    real det0 = sa * (sd * sf - se * se) - sb * (sb * sf - sc * se) + sc * (sb * se - sc * sd);
    if (!(m2 > real(1e-4) * sa * sd && det0 > real(1e-4) * sa * sd * sf)) {
        ia3 = real3(1e20, 0, 0);
        ib3 = real3(1e20, 0, 1e20);
        return;
    }
    real ia = sd * sf - se * se;
    real ib = sc * se - sb * sf;
    real ic = sb * se - sc * sd;
    real id = sa * sf - sc * sc;
    real ie = sb * sc - sa * se;
    real if_ = sa * sd - sb * sb;
    real r = real(1) / (sa * ia + sb * ib + sc * ic);
    ia3 = real3(ia, ib, ic) * r;
    ib3 = real3(id, ie, if_) * r;
}

// The symmetric matrix with entries (XX, XY, XZ) and (YY, YZ, ZZ).
realmat3 gbf_sym(real3 a, real3 b)
{
    return realmat3(a.x, a.y, a.z, a.y, b.x, b.y, a.z, b.y, b.z);
}

#endif // MC_GBF_GLSL
