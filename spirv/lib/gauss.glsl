// The 1-D Gaussian weights of the separable map smoothing G_sigma (spec
// §0.5), shared by gauss_rows.comp (along x) and the column passes
// (gauss_smooth.comp, gbf_prepare.comp). Scalar twin:
// src/reference/gauss_rows.rs.
//
// Along a line the weights g(d) = exp(-d^2 k), k = 1/(2 sigma^2), follow the
// recurrence g(d+1) = g(d) q(d), q(d+1) = q(d) c with q(d) = exp(-(2d+1)k)
// and c = exp(-2k): three exps per line instead of one per tap (exp in
// float: GLSL has no double exp; far below tolerance). sigma <= 0: every
// weight 1 (the caller's radius is then 0: the identity on valid pixels).

#ifndef MC_GAUSS_GLSL
#define MC_GAUSS_GLSL

struct GaussLine {
    real g;  // weight at the current tap
    real q;  // ratio to the next tap
    real c;  // ratio of successive q
};

// The weights of a line starting at offset d0 (<= 0) from its centre.
GaussLine gauss_line(real sigma, int d0)
{
    GaussLine l;
    if (sigma <= real(0)) {
        l.g = real(1);
        l.q = real(1);
        l.c = real(1);
        return l;
    }
    real k = real(1) / (real(2) * sigma * sigma);
    real d = real(d0);
    l.c = real(exp(float(-real(2) * k)));
    l.g = real(exp(float(-d * d * k)));
    l.q = real(exp(float(-(real(2) * d + real(1)) * k)));
    return l;
}

// Moves to the next tap.
void gauss_step(inout GaussLine l)
{
    l.g *= l.q;
    l.q *= l.c;
}

#endif // MC_GAUSS_GLSL
