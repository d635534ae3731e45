#version 460
// AOS steps 2-8 (spec §5.3) at one pixel per workgroup of 64 invocations
// (§5.4): one pass over the window accumulates the Gram matrices of the raw
// order-5 power design (at most 51 columns) extended by colour; AOS-SCALE
// from their diagonal; one Cholesky whose leading blocks serve orders 1 and
// 3 (AOS-ONE-RIDGE); the bias, variance and MSE of each order as quadratic
// forms; the choice; the output. See src/reference/aos_fit.rs for the
// algebra; that file is the scalar twin.
//
// Dispatch: width * 64 invocations by the band's rows; workgroup (x, y) is
// pixel (x, base_row + row0 + y). Reads the projection of aos_space
// (SPACE floats per pixel, indexed from base_row). Writes OUTPUTS planes of
// `dst` (stride push.stride): colour RGB (clamped >= 0), the exported error
// (MSE + AOS-FEATNOISE), order, rank, bias1, var1, bias3, var3, sigma*^2,
// sd(bias1), sd(bias3), MSE (the sample map's E).
//
// Decision AOS-F64 (ours): an exception to §0.3's f32 default, like WLR's
// parametric fits, this kernel computes in f64 in both variants. The
// order-5 design's powers dz, dz^3, dz^5 are nearly collinear, so the ridge
// system is badly conditioned; in f32 the colour stays within §0.3 of the
// twin, but the error estimates and biases do not (tests/aos_kernels.rs).
// The `aos_fit_dd` variant (MC_DD), for devices without shaderFloat64, is
// that f32 arithmetic: the colour and the order as above, the error
// estimates within the looser bounds decision NO-64BIT records.
#if !defined(MC_F64) && !defined(MC_DD)
#define MC_F64 1
#endif
#include "lib/common.glsl"

#ifdef MC_F64
#define rmat4 dmat4
#else
#define rmat4 mat4
#endif

layout(local_size_x = 64) in;

// Mirrors mcdenoise::shared::AosPush.
layout(push_constant) uniform Push {
    uint width;
    uint height;
    uint row0;
    uint radius;
    uint channels;
    uint flags;
    uint base_row;
    uint stride;
} push;

// depth, albedo rgb, normal xyz, visibility (a zero plane when absent).
PLANE_IN(0, f0)
PLANE_IN(1, f1)
PLANE_IN(2, f2)
PLANE_IN(3, f3)
PLANE_IN(4, f4)
PLANE_IN(5, f5)
PLANE_IN(6, f6)
PLANE_IN(7, f7)
PLANE_IN(8, col_r)
PLANE_IN(9, col_g)
PLANE_IN(10, col_b)
PLANE_IN(11, vbar)
PLANE_IN(12, spp)
PLANE_IN(13, space)
// The features' variances, in the order of f0..f7 (AOS-FEATNOISE).
PLANE_IN(14, fv0)
PLANE_IN(15, fv1)
PLANE_IN(16, fv2)
PLANE_IN(17, fv3)
PLANE_IN(18, fv4)
PLANE_IN(19, fv5)
PLANE_IN(20, fv6)
PLANE_IN(21, fv7)
PLANE_OUT(22, dst)

#define AOS_SANDWICH 1u
#define AOS_BIAS_TEST 2u
#define AOS_IDENTITY 4u
#define AOS_OUTLIER_W 8u
#define AOS_RESIDUAL 16u
#define AOS_FEATNOISE 32u
#define AOS_IDENTITY_FLOOR 64u

#define NT 64        // invocations per pixel
#define D 10         // features
#define SPACE 101    // floats per pixel in `space`
#define NC 51        // most design columns: 1 + 5 D
#define XS 56        // extended row stride: 51 columns, 3 colours, padding
#define NE 1326      // NC (NC + 1) / 2: a packed lower triangle
#define NER 1485     // 54 * 55 / 2: the extended raw Gram's lower triangle
#define CH 32        // window rows per staged chunk
#define NSUM 7       // quadratic forms

#define RIDGE_F 1e-5
#define RMS_EPS 1e-12
#define BIAS_Z 2.0
#define RESIDUAL_VBAR_FLOOR 1e-20
#define SOLVE_RETRIES 3
#define RIDGE_FLOOR 1e-8

// One array of workgroup memory; regions are reused between phases
// (f64: 29.6 KiB, under lavapipe's 32 KiB).
#define S_N 0                 // raw extended Gram, then the compact N (packed lower)
#define S_L (S_N + NER)       // the Cholesky factor (packed lower); staging before
#define S_V (S_L + NE)        // compact vectors: rhs R G B, beta*, u*, u1, u3, q1, q3
#define V_RHS (S_V)
#define V_BETA (S_V + 3 * NC)
#define V_US (S_V + 4 * NC)
#define V_U1 (S_V + 5 * NC)
#define V_U3 (S_V + 6 * NC)
#define V_Q1 (S_V + 7 * NC)
#define V_Q3 (S_V + 8 * NC)
#define V_RAW (S_V + 9 * NC)  // u*, u1, u3, q1, q3 in the raw layout, scaled (stride XS)
#define S_SCALE (V_RAW + 5 * XS)  // raw column scale (0: dropped)
#define S_SC (S_SCALE + NC)   // scalars, below
#define V_B1 (S_SC + 8)       // beta_1, beta_3 on grey (AOS-FEATNOISE)
#define V_B3 (V_B1 + NC)
#define S_SIZE (V_B3 + NC)
// Staging (in S_N and S_L, free during the window pass): extended rows,
// dz rows, K, colour + vbar.
#define X_X (S_N)
#define X_DZ (X_X + CH * XS)
#define X_Y (X_DZ + CH * D)
#define X_K (X_Y + 4 * CH)    // per row (K, K^2, K^2 vbar, 0): one vec4
// Quadratic-form partial sums (in S_L, free after the solves).
#define QF_SUM (S_L)
// Scalars.
#define SC_KSUM 0
#define SC_THRESH 1
#define SC_LAMBDA 2
#define SC_BIAS1 3
#define SC_BIAS3 4
#define SC_MEAN_DIAG 5
#define SC_VC 6               // AOS-RESIDUAL's centre variance

// As vec4s (APR-STATE-VEC4's lesson: llvmpipe pays per load and lane, not
// per float): the window pass reads a staged row's blocks as whole vec4s
// (AOS-SHARED-VEC4); every other access is to one entry, S_AT(i).
shared real4 S4[(S_SIZE + 3) / 4];
#define S_AT(i) S4[(i) >> 2][(i) & 3]
shared int s_colv[NC];   // compact column -> power
shared int s_cidx[NC];   // raw column -> compact column, -1 if dropped
// p1, p3, p5, pivot flag, any column dropped
shared int s_int[5];

int lidx(int i, int j) { return i >= j ? i * (i + 1) / 2 + j : j * (j + 1) / 2 + i; }

// Packed lower-triangle index e -> (i, j), i >= j.
ivec2 tri(int e)
{
    int i = int((sqrt(8.0 * float(e) + 1.0) - 1.0) * 0.5);
    while ((i + 1) * (i + 2) / 2 <= e) {
        ++i;
    }
    while (i * (i + 1) / 2 > e) {
        --i;
    }
    return ivec2(i, e - i * (i + 1) / 2);
}

bool valid_at(uint i) { return spp_of(spp[i]) >= 1.0; }

// The centre's projection P (columns j: rows 0-3, 4-7, 8-9) and features,
// per invocation: constant indices, so lavapipe keeps them in vector
// registers instead of gathering them from workgroup memory for every row.
real4 g_pa[D];
real4 g_pb[D];
real2 g_pc[D];
real g_xc[D];
// AOS-RESIDUAL: this invocation's sum of K (ln max(vbar, floor) + ln n) (the
// per-sample variance) over the window rows it staged that are not
// all_black, and of their K (f32 logarithm: GLSL has no f64 one).
real g_lnsum = real(0);
real g_lnk = real(0);

// ALL-BLACK: pixel q's samples all came out black (variance 0, colour 0):
// AOS-RESIDUAL's window mean and AOS-IDENTITY-FLOOR's median leave it out.
// Twin: reference::aos::all_black.
bool all_black(uint q)
{
    return vbar[q] <= 0.0 && col_r[q] <= 0.0 && col_g[q] <= 0.0 && col_b[q] <= 0.0;
}

real feature(int j, uint q)
{
    switch (j) {
    case 0: return real(f0[q]);
    case 1: return real(f1[q]);
    case 2: return real(f2[q]);
    case 3: return real(f3[q]);
    case 4: return real(f4[q]);
    case 5: return real(f5[q]);
    case 6: return real(f6[q]);
    default: return real(f7[q]);
    }
}

real feature_var(int j, uint q)
{
    switch (j) {
    case 0: return real(fv0[q]);
    case 1: return real(fv1[q]);
    case 2: return real(fv2[q]);
    case 3: return real(fv3[q]);
    case 4: return real(fv4[q]);
    case 5: return real(fv5[q]);
    case 6: return real(fv6[q]);
    default: return real(fv7[q]);
    }
}

real powi(real z, int v)
{
    real p = real(1);
    for (int a = 0; a < v; ++a) {
        p *= z;
    }
    return p;
}

real4 load4(int o) { return real4(S_AT(o), S_AT(o + 1), S_AT(o + 2), S_AT(o + 3)); }
// The same at an offset that is a multiple of 4: one vec4 load.
real4 load4a(int o) { return S4[o >> 2]; }

// The window pixel at offset `off` from centre c: kernel weight (0 outside
// the image or invalid) and local coordinates.
void load_row(ivec2 c, ivec2 off, out real kw, out real dz[D], out uint q)
{
    int R = int(push.radius);
    ivec2 p = c + off;
    kw = real(0);
    q = 0u;
    for (int m = 0; m < D; ++m) {
        dz[m] = real(0);
    }
    if (p.x < 0 || p.y < 0 || p.x >= int(push.width) || p.y >= int(push.height)) {
        return;
    }
    q = uint(p.y) * push.width + uint(p.x);
    if (!valid_at(q)) {
        return;
    }
    real dx[D];
    dx[0] = real(p.x) - g_xc[0];
    dx[1] = real(p.y) - g_xc[1];
    for (int j = 0; j < 8; ++j) {
        dx[2 + j] = feature(j, q) - g_xc[2 + j];
    }
    real4 d0 = real4(0);
    real4 d1 = real4(0);
    real2 d2 = real2(0);
    for (int j = 0; j < D; ++j) {
        d0 += g_pa[j] * dx[j];
        d1 += g_pb[j] * dx[j];
        d2 += g_pc[j] * dx[j];
    }
    for (int m = 0; m < 4; ++m) {
        dz[m] = d0[m];
        dz[4 + m] = d1[m];
    }
    dz[8] = d2.x;
    dz[9] = d2.y;
    real bw = real(max(R, 1));
    real r2 = real((p.x - c.x) * (p.x - c.x) + (p.y - c.y) * (p.y - c.y));
    kw = real(exp(float(-r2 / (real(2) * bw * bw))));
    if ((push.flags & AOS_OUTLIER_W) != 0u) {
        // AOS-OUTLIER-W: K / max(vbar, 1).
        kw /= max(real(vbar[q]), real(1));
    }
}

// Stages rows [base, base + CH) of the window (raster order). Invocation
// t < CH loads row base + t, whose offset from the centre it keeps in
// `off` (advanced by CH rows per call: no integer division, which lavapipe
// does lane by lane). Then invocation t writes, for row t % 32, the powers
// of components j = t/32, t/32 + 2, ... < k into the extended raw row:
// column 0 = 1, column 1 + (v-1) k + j = dz_j^v, then R, G, B, then 0 up to
// a multiple of 4 (whole blocks of 4 are read).
void stage(ivec2 c, int base, int nrows, uint t, int k, inout ivec2 off)
{
    int R = int(push.radius);
    int wd = 2 * R + 1;
    ONLY(t < uint(CH))
    {
        int rr = int(t);
        real kw = real(0);
        real dz[D];
        uint q = 0u;
        if (base + rr < nrows) {
            load_row(c, off - ivec2(R), kw, dz, q);
        } else {
            for (int m = 0; m < D; ++m) {
                dz[m] = real(0);
            }
        }
        for (int m = 0; m < D; ++m) {
            S_AT(X_DZ + rr * D + m) = dz[m];
        }
        bool use = kw > real(0);
        // The row's three weights (0 for an unused row), read as one vec4
        // by chunk_blocks.
        real vb = use ? real(vbar[q]) : real(0);
        real k2 = kw * kw;
        S_AT(X_K + rr * 4) = kw;
        S_AT(X_K + rr * 4 + 1) = k2;
        S_AT(X_K + rr * 4 + 2) = k2 * vb;
        S_AT(X_K + rr * 4 + 3) = real(0);
        if (use && !all_black(q)) {
            g_lnsum += kw * real(log(max(vbar[q], float(RESIDUAL_VBAR_FLOOR))) + log(max(spp_of(spp[q]), 1.0)));
            g_lnk += kw;
        }
        S_AT(X_Y + rr * 4) = use ? real(col_r[q]) : real(0);
        S_AT(X_Y + rr * 4 + 1) = use ? real(col_g[q]) : real(0);
        S_AT(X_Y + rr * 4 + 2) = use ? real(col_b[q]) : real(0);
        S_AT(X_Y + rr * 4 + 3) = vb;
        off.x += CH;
        while (off.x >= wd) {
            off.x -= wd;
            off.y += 1;
        }
    }
    barrier();
    int pr = 1 + 5 * k;
    int pw = (pr + 3 + 3) / 4 * 4;
    int rr = int(t) & (CH - 1);
    int xr = X_X + rr * XS;
    for (int j = int(t) >> 5; j < k; j += NT / CH) {
        real z = S_AT(X_DZ + rr * D + j);
        real pv = z;
        for (int v = 0; v < 5; ++v) {
            S_AT(xr + 1 + v * k + j) = pv;
            pv *= z;
        }
    }
    ONLY((int(t) >> 5) == 0)
    {
        S_AT(xr) = real(1);
        for (int ch = 0; ch < 3; ++ch) {
            S_AT(xr + pr + ch) = S_AT(X_Y + rr * 4 + ch);
        }
        for (int i = pr + 3; i < pw; ++i) {
            S_AT(xr + i) = real(0);
        }
    }
    barrier();
}

// Solves (leading p x p block of L L^T) x = b in place at S_AT(at ..).
void tri_solve(int p, int at)
{
    for (int i = 0; i < p; ++i) {
        real s = S_AT(at + i);
        for (int k = 0; k < i; ++k) {
            s -= S_AT(S_L + i * (i + 1) / 2 + k) * S_AT(at + k);
        }
        S_AT(at + i) = s / S_AT(S_L + i * (i + 1) / 2 + i);
    }
    for (int i = p - 1; i >= 0; --i) {
        real s = S_AT(at + i);
        for (int k = i + 1; k < p; ++k) {
            s -= S_AT(S_L + k * (k + 1) / 2 + i) * S_AT(at + k);
        }
        S_AT(at + i) = s / S_AT(S_L + i * (i + 1) / 2 + i);
    }
}

void write_out(uint i, real o[14])
{
    for (int a = 0; a < 14; ++a) {
        dst[uint(a) * push.stride + i] = float(o[a]);
    }
}

// u^T M v over one 4x4 block (rows of M: block I, columns: block J).
real qform(rmat4 m, real4 u, real4 v) { return dot(u, m * v); }

void pick(uint ci, int k, int p1, int p3, real o[14]);

// Adds the staged chunk's rows to one owned block pair bp of the three Gram
// matrices: N (weight K), B (K^2) and G (K^2 vbar).
void chunk_blocks(ivec2 bp, inout rmat4 n, inout rmat4 b, inout rmat4 g)
{
    for (int rr = 0; rr < CH; ++rr) {
        real4 wk = load4a(X_K + 4 * rr);
        real kw = wk.x;
        if (kw > real(0)) {
            real k2 = wk.y;
            real kv = wk.z;
            int xr = X_X + rr * XS;
            // X_X and XS are multiples of 4.
            real4 xi = load4a(xr + 4 * bp.x);
            real4 xj = load4a(xr + 4 * bp.y);
            n += outerProduct(kw * xi, xj);
            b += outerProduct(k2 * xi, xj);
            g += outerProduct(kv * xi, xj);
        }
    }
}

void main()
{
    uint t = gl_LocalInvocationID.x;
    int w = int(push.width);
    int h = int(push.height);
    ivec2 c = ivec2(gl_WorkGroupID.x, int(push.base_row + push.row0 + gl_WorkGroupID.y));
    if (c.x >= w || c.y >= h) {
        return;
    }
    uint ci = uint(c.y * w + c.x);
    real o[14];
    for (int a = 0; a < 14; ++a) {
        o[a] = real(0);
    }
    // §0.2: an invalid centre takes the mean of its valid 3x3 neighbours.
    if (!valid_at(ci)) {
        if (t == 0u) {
            real3 s = real3(0);
            int n = 0;
            for (int qy = max(c.y - 1, 0); qy <= min(c.y + 1, h - 1); ++qy) {
                for (int qx = max(c.x - 1, 0); qx <= min(c.x + 1, w - 1); ++qx) {
                    uint q = uint(qy * w + qx);
                    if (valid_at(q)) {
                        s += real3(col_r[q], col_g[q], col_b[q]);
                        ++n;
                    }
                }
            }
            s = n > 0 ? s / real(n) : real3(0);
            o[0] = max(s.x, real(0));
            o[1] = max(s.y, real(0));
            o[2] = max(s.z, real(0));
            write_out(ci, o);
        }
        return;
    }
    // AOS-FALLBACK and AOS-IDENTITY output: the input, error vbar_c.
    o[0] = max(real(col_r[ci]), real(0));
    o[1] = max(real(col_g[ci]), real(0));
    o[2] = max(real(col_b[ci]), real(0));
    o[3] = real(vbar[ci]);
    o[13] = o[3];
    uint so = ((uint(c.y) - push.base_row) * push.width + uint(c.x)) * uint(SPACE);
    int k = int(space[so + uint(D * D)]);
    o[5] = real(k);
    if (k == 0) {
        if (t == 0u) {
            write_out(ci, o);
        }
        return;
    }
    for (int j = 0; j < D; ++j) {
        g_pa[j] = real4(space[so + uint(j)], space[so + uint(D + j)], space[so + uint(2 * D + j)], space[so + uint(3 * D + j)]);
        g_pb[j] = real4(space[so + uint(4 * D + j)], space[so + uint(5 * D + j)], space[so + uint(6 * D + j)], space[so + uint(7 * D + j)]);
        g_pc[j] = real2(space[so + uint(8 * D + j)], space[so + uint(9 * D + j)]);
    }
    g_xc[0] = real(c.x);
    g_xc[1] = real(c.y);
    for (int j = 0; j < 8; ++j) {
        g_xc[2 + j] = feature(j, ci);
    }
    int R = int(push.radius);
    int nrows = (2 * R + 1) * (2 * R + 1);
    int pr = 1 + 5 * k;

    // The one window pass: the Gram matrices of the raw rows extended by
    // colour, as 4x4 outer-product blocks (8 loads of workgroup memory per
    // 48 multiply-adds: loads dominate on lavapipe). Invocation t owns the
    // blocks t and t + 64 of the lower block triangle, with three weights:
    // N = sum K x x^T (and the right-hand sides sum K x y), B = sum K^2 x x^T,
    // G = sum K^2 vbar x x^T.
    int pe = pr + 3;
    int nb = (pe + 3) / 4;
    int npairs = nb * (nb + 1) / 2;
    bool own0 = int(t) < npairs;
    bool own1 = int(t) + NT < npairs;
    ivec2 bp0 = tri(min(int(t), npairs - 1));
    ivec2 bp1 = tri(min(int(t) + NT, npairs - 1));
    rmat4 n0 = rmat4(0), b0 = rmat4(0), g0 = rmat4(0);
    rmat4 n1 = rmat4(0), b1 = rmat4(0), g1 = rmat4(0);
    int wd = 2 * R + 1;
    ivec2 off = ivec2(int(t) % wd, int(t) / wd);
    // Each block slot's row loop is a loop over its ownership (0 or 1
    // times), not an `if`: llvmpipe runs both sides of a branch under a
    // mask, but leaves a loop once no lane of the SIMD vector iterates, so
    // vectors of invocations that own no block (most of the 64 at ranks
    // 2-4: 10-21 block pairs) skip the row loop instead of running it
    // masked. The sums and their order are unchanged.
    int run0 = own0 ? 1 : 0;
    int run1 = own1 ? 1 : 0;
    for (int base = 0; base < nrows; base += CH) {
        stage(c, base, nrows, t, k, off);
        for (int s0 = 0; s0 < run0; ++s0) {
            chunk_blocks(bp0, n0, b0, g0);
        }
        for (int s1 = 0; s1 < run1; ++s1) {
            chunk_blocks(bp1, n1, b1, g1);
        }
        barrier();
    }
    // The lanes' sums of K ln vbar and of K (S_L is free until the Cholesky).
    if (t < uint(CH)) {
        S_AT(S_L + int(t)) = g_lnsum;
        S_AT(S_L + CH + int(t)) = g_lnk;
    }
    // The raw N and right-hand sides to workgroup memory.
    for (int h2 = 0; h2 < 2; ++h2) {
        if (h2 == 0 ? own0 : own1) {
            ivec2 bp = h2 == 0 ? bp0 : bp1;
            for (int a = 0; a < 4; ++a) {
                for (int b = 0; b < 4; ++b) {
                    int i = 4 * bp.x + a;
                    int j = 4 * bp.y + b;
                    real v = h2 == 0 ? n0[b][a] : n1[b][a];
                    if (j < pr && i >= j && i < pr) {
                        S_AT(S_N + i * (i + 1) / 2 + j) = v;
                    } else if (j < pr && i >= pr && i < pe) {
                        S_AT(V_RHS + (i - pr) * NC + j) = v;
                    }
                }
            }
        }
    }
    barrier();
    // AOS-SCALE from the raw diagonal: rms_r = sqrt(N_rr / sum K); columns
    // below RMS_EPS are dropped; order by power, then component.
    ONLY(t == 0u)
    {
        real ksum = S_AT(S_N);
        S_AT(S_SC + SC_KSUM) = ksum;
        real lnsum = real(0);
        real lnk = real(0);
        for (int i = 0; i < CH; ++i) {
            lnsum += S_AT(S_L + i);
            lnk += S_AT(S_L + CH + i);
        }
        S_AT(S_SC + SC_VC) = lnk > real(0) ? max(real(vbar[ci]), real(exp(float(lnsum / lnk))) / max(real(spp_of(spp[ci])), real(1))) : real(vbar[ci]);
        S_AT(S_SCALE) = real(1);
        s_cidx[0] = 0;
        s_colv[0] = 0;
        int n = 1;
        for (int r = 1; r < pr; ++r) {
            real rms = sqrt(S_AT(S_N + r * (r + 1) / 2 + r) / ksum);
            int v = (r - 1) / k + 1;
            if (rms >= real(RMS_EPS)) {
                S_AT(S_SCALE + r) = real(1) / rms;
                s_cidx[r] = n;
                s_colv[n] = v;
                ++n;
            } else {
                S_AT(S_SCALE + r) = real(0);
                s_cidx[r] = -1;
            }
            if (r == k) {
                s_int[0] = n;
            } else if (r == 3 * k) {
                s_int[1] = n;
            }
        }
        s_int[2] = n;
        s_int[4] = n < pr ? 1 : 0;
    }
    barrier();
    int p1 = s_int[0];
    int p3 = s_int[1];
    int p5 = s_int[2];
    int ne = p5 * (p5 + 1) / 2;
    if (s_int[4] == 0) {
        // Usual case: nothing dropped, scale in place.
        for (int e = int(t); e < ne; e += NT) {
            ivec2 ij = tri(e);
            S_AT(S_N + e) *= S_AT(S_SCALE + ij.x) * S_AT(S_SCALE + ij.y);
        }
        for (int i = int(t); i < p5; i += NT) {
            real sc = S_AT(S_SCALE + i);
            S_AT(V_RHS + i) *= sc;
            S_AT(V_RHS + NC + i) *= sc;
            S_AT(V_RHS + 2 * NC + i) *= sc;
        }
    } else if (t == 0u) {
        // A dropped column: compact in place (targets never pass sources).
        for (int i = 0; i < pr; ++i) {
            int ci2 = s_cidx[i];
            if (ci2 < 0) {
                continue;
            }
            real si = S_AT(S_SCALE + i);
            for (int j = 0; j <= i; ++j) {
                int cj = s_cidx[j];
                if (cj >= 0) {
                    S_AT(S_N + ci2 * (ci2 + 1) / 2 + cj) = S_AT(S_N + i * (i + 1) / 2 + j) * si * S_AT(S_SCALE + j);
                }
            }
            for (int ch = 0; ch < 3; ++ch) {
                S_AT(V_RHS + ch * NC + ci2) = S_AT(V_RHS + ch * NC + i) * si;
            }
        }
    }
    barrier();

    // Ridge Cholesky of N + diag(0, lambda, ...) with SOLVE-FAIL retries
    // (§0.5), right-looking, one column per step.
    if (t == 0u) {
        real md = real(0);
        for (int i = 0; i < p5; ++i) {
            md += S_AT(S_N + i * (i + 1) / 2 + i);
        }
        S_AT(S_SC + SC_MEAN_DIAG) = md / real(p5);
        S_AT(S_SC + SC_LAMBDA) = real(RIDGE_F) * S_AT(S_SC + SC_KSUM);
    }
    barrier();
    bool ok = false;
    for (int attempt = 0; attempt <= SOLVE_RETRIES; ++attempt) {
        if (t == 0u) {
            real lam = S_AT(S_SC + SC_LAMBDA);
            if (attempt > 0) {
                lam = max(real(10) * lam, real(RIDGE_FLOOR) * S_AT(S_SC + SC_MEAN_DIAG));
                S_AT(S_SC + SC_LAMBDA) = lam;
            }
            real mx = real(0);
            for (int i = 0; i < p5; ++i) {
                mx = max(mx, S_AT(S_N + i * (i + 1) / 2 + i) + (i > 0 ? lam : real(0)));
            }
            S_AT(S_SC + SC_THRESH) = real(EPS_PIVOT) * mx;
        }
        barrier();
        real lam = S_AT(S_SC + SC_LAMBDA);
        for (int e = int(t); e < ne; e += NT) {
            ivec2 ij = tri(e);
            S_AT(S_L + e) = S_AT(S_N + e) + (ij.x == ij.y && ij.x > 0 ? lam : real(0));
        }
        barrier();
        for (int kk = 0; kk < p5; ++kk) {
            if (t == 0u) {
                int dk = kk * (kk + 1) / 2 + kk;
                real piv = S_AT(S_L + dk);
                bool good = piv > S_AT(S_SC + SC_THRESH) && !isnan(piv) && !isinf(piv);
                s_int[3] = good ? 1 : 0;
                if (good) {
                    S_AT(S_L + dk) = sqrt(piv);
                }
            }
            barrier();
            if (s_int[3] == 0) {
                break;
            }
            real lkk = S_AT(S_L + kk * (kk + 1) / 2 + kk);
            for (int i = kk + 1 + int(t); i < p5; i += NT) {
                S_AT(S_L + i * (i + 1) / 2 + kk) /= lkk;
            }
            barrier();
            int m = p5 - kk - 1;
            for (int e = int(t); e < m * (m + 1) / 2; e += NT) {
                ivec2 ab = tri(e);
                int i = kk + 1 + ab.x;
                int j = kk + 1 + ab.y;
                S_AT(S_L + i * (i + 1) / 2 + j) -= S_AT(S_L + i * (i + 1) / 2 + kk) * S_AT(S_L + j * (j + 1) / 2 + kk);
            }
            barrier();
        }
        if (s_int[3] != 0) {
            ok = true;
            break;
        }
        barrier();
    }
    if (!ok) {
        // AOS-FALLBACK: the input.
        if (t == 0u) {
            write_out(ci, o);
        }
        return;
    }

    // u* = A*^-1 e1, beta* = A*^-1 rhs_grey, u_l = A_l^-1 e1 (leading blocks).
    for (int i = int(t); i < NC; i += NT) {
        real e1 = i == 0 ? real(1) : real(0);
        S_AT(V_US + i) = e1;
        S_AT(V_U1 + i) = e1;
        S_AT(V_U3 + i) = e1;
        S_AT(V_BETA + i) = i < p5 ? (S_AT(V_RHS + i) + S_AT(V_RHS + NC + i) + S_AT(V_RHS + 2 * NC + i)) / real(3) : real(0);
        S_AT(V_B1 + i) = S_AT(V_BETA + i);
        S_AT(V_B3 + i) = S_AT(V_BETA + i);
    }
    barrier();
    ONLY(t < 6u)
    {
        int sp = t == 0u || t == 1u ? p5 : (t == 2u || t == 4u ? p1 : p3);
        int sa = t == 0u ? V_US : (t == 1u ? V_BETA : (t == 2u ? V_U1 : (t == 3u ? V_U3 : (t == 4u ? V_B1 : V_B3))));
        tri_solve(sp, sa);
    }
    barrier();
    // bias_l = u_l^T N[0..p_l, :] beta_high; t_l = N[:, 0..p_l] u_l on the
    // high powers (into V_Q*, solved next).
    for (int i = int(t); i < NC; i += NT) {
        real t1 = real(0);
        real t3 = real(0);
        if (i < p5) {
            int v = s_colv[i];
            if (v > 1 && v <= 3) {
                for (int j = 0; j < p1; ++j) {
                    t1 += S_AT(S_N + lidx(i, j)) * S_AT(V_U1 + j);
                }
            }
            if (v > 3 && v <= 5) {
                for (int j = 0; j < p3; ++j) {
                    t3 += S_AT(S_N + lidx(i, j)) * S_AT(V_U3 + j);
                }
            }
        }
        S_AT(V_Q1 + i) = t1;
        S_AT(V_Q3 + i) = t3;
    }
    ONLY(t == uint(NT - 1) || t == uint(NT - 2))
    {
        int lo = t == uint(NT - 1) ? 1 : 3;
        int pl = lo == 1 ? p1 : p3;
        int ua = lo == 1 ? V_U1 : V_U3;
        real b = real(0);
        for (int i = 0; i < pl; ++i) {
            real nb2 = real(0);
            for (int j = 0; j < p5; ++j) {
                int v = s_colv[j];
                if (v > lo && v <= lo + 2) {
                    nb2 += S_AT(S_N + lidx(i, j)) * S_AT(V_BETA + j);
                }
            }
            b += S_AT(ua + i) * nb2;
        }
        S_AT(S_SC + (lo == 1 ? SC_BIAS1 : SC_BIAS3)) = b;
    }
    barrier();
    ONLY(t < 2u)
    {
        tri_solve(p5, t == 0u ? V_Q1 : V_Q3);
    }
    barrier();

    // The vectors of the quadratic forms in the raw layout, scaled:
    // u.x_scaled = (s . u_raw).x_raw; 0 for dropped and colour columns.
    for (int r = int(t); r < XS; r += NT) {
        int cr = r < pr ? s_cidx[r] : -1;
        real sc = cr >= 0 ? S_AT(S_SCALE + r) : real(0);
        int cc = max(cr, 0);
        S_AT(V_RAW + r) = sc * S_AT(V_US + cc);
        S_AT(V_RAW + XS + r) = sc * S_AT(V_U1 + cc);
        S_AT(V_RAW + 2 * XS + r) = sc * S_AT(V_U3 + cc);
        S_AT(V_RAW + 3 * XS + r) = sc * S_AT(V_Q1 + cc);
        S_AT(V_RAW + 4 * XS + r) = sc * S_AT(V_Q3 + cc);
    }
    barrier();
    // sigma*^2 = u*^T G u*; per order l: u_l^T B u_l (the paper's
    // [A^-1 B A^-1]_00), u_l^T G u_l (sandwich), q_l^T G q_l (bias variance).
    real qs[NSUM];
    for (int a = 0; a < NSUM; ++a) {
        qs[a] = real(0);
    }
    for (int h2 = 0; h2 < 2; ++h2) {
        if (h2 == 0 ? own0 : own1) {
            ivec2 bp = h2 == 0 ? bp0 : bp1;
            rmat4 mb = h2 == 0 ? b0 : b1;
            rmat4 mg = h2 == 0 ? g0 : g1;
            real f = bp.x == bp.y ? real(1) : real(2);
            int oi = 4 * bp.x;
            int oj = 4 * bp.y;
            qs[0] += f * qform(mg, load4(V_RAW + oi), load4(V_RAW + oj));
            qs[1] += f * qform(mb, load4(V_RAW + XS + oi), load4(V_RAW + XS + oj));
            qs[2] += f * qform(mg, load4(V_RAW + XS + oi), load4(V_RAW + XS + oj));
            qs[3] += f * qform(mg, load4(V_RAW + 3 * XS + oi), load4(V_RAW + 3 * XS + oj));
            qs[4] += f * qform(mb, load4(V_RAW + 2 * XS + oi), load4(V_RAW + 2 * XS + oj));
            qs[5] += f * qform(mg, load4(V_RAW + 2 * XS + oi), load4(V_RAW + 2 * XS + oj));
            qs[6] += f * qform(mg, load4(V_RAW + 4 * XS + oi), load4(V_RAW + 4 * XS + oj));
        }
    }
    for (int a = 0; a < NSUM; ++a) {
        S_AT(QF_SUM + int(t) * NSUM + a) = qs[a];
    }
    barrier();
    ONLY(t == 0u)
    {
        pick(ci, k, p1, p3, o);
    }
}

// AOS-IDENTITY's candidate MSE: vbar_c, with AOS_IDENTITY_FLOOR at least
// the median over the valid pixels of c's 3x3 that are not all_black of the
// per-sample variances n_q vbar_q (the upper one of an even count), over n_c
// (AOS-IDENTITY-FLOOR).
// Twin: reference::aos::identity_mse.
real identity_mse(uint ci)
{
    real v = real(vbar[ci]);
    if ((push.flags & AOS_IDENTITY_FLOOR) == 0u) {
        return v;
    }
    int cx = int(ci % push.width);
    int cy = int(ci / push.width);
    float vv[9];
    int nv = 0;
    for (int qy = max(cy - 1, 0); qy <= min(cy + 1, int(push.height) - 1); ++qy) {
        for (int qx = max(cx - 1, 0); qx <= min(cx + 1, int(push.width) - 1); ++qx) {
            uint q = uint(qy) * push.width + uint(qx);
            if (!valid_at(q) || all_black(q)) {
                continue;
            }
            // Insertion into the sorted prefix vv[0..nv).
            float x = vbar[q] * spp_of(spp[q]);
            int m = nv;
            while (m > 0 && vv[m - 1] > x) {
                vv[m] = vv[m - 1];
                --m;
            }
            vv[m] = x;
            ++nv;
        }
    }
    return nv == 0 ? v : max(v, real(vv[nv / 2]) / real(max(spp_of(spp[ci]), 1.0)));
}

// The choice of order (thread 0, after the quadratic forms' partial sums are
// in QF_SUM): sigma*^2, each order's bias, variance and MSE, AOS-RESIDUAL,
// AOS-IDENTITY, the output and AOS-FEATNOISE.
void pick(uint ci, int k, int p1, int p3, real o[14])
{
    real tot[NSUM];
    for (int a = 0; a < NSUM; ++a) {
        tot[a] = real(0);
        for (int l = 0; l < NT; ++l) {
            tot[a] += S_AT(QF_SUM + l * NSUM + a);
        }
    }
    real sigma2 = tot[0];
    o[10] = sigma2;
    int best = -1;
    real best_mse = real(0);
    for (int oi = 0; oi < 2; ++oi) {
        int b0i = 1 + 3 * oi;
        real var = (push.flags & AOS_SANDWICH) != 0u ? tot[b0i + 1] : tot[b0i] * sigma2;
        real bias = S_AT(S_SC + (oi == 0 ? SC_BIAS1 : SC_BIAS3));
        real bvar = tot[b0i + 2];
        bool counts = (push.flags & AOS_BIAS_TEST) == 0u || bias * bias > real(BIAS_Z * BIAS_Z) * bvar;
        real cb = counts ? bias : real(0);
        real bias2 = cb * cb;
        if ((push.flags & AOS_RESIDUAL) != 0u) {
            // AOS-RESIDUAL: res = u_l . rhs_grey - grey_c, and its variance
            // u_l^T G u_l - l_c^2 vbar_c + (l_c - 1)^2 v_c, l_c = K_c u_l[0].
            int pl = oi == 0 ? p1 : p3;
            int ua = oi == 0 ? V_U1 : V_U3;
            real fit = real(0);
            for (int i = 0; i < pl; ++i) {
                fit += S_AT(ua + i) * ((S_AT(V_RHS + i) + S_AT(V_RHS + NC + i) + S_AT(V_RHS + 2 * NC + i)) / real(3));
            }
            real vc = real(vbar[ci]);
            real res = fit - (real(col_r[ci]) + real(col_g[ci]) + real(col_b[ci])) / real(3);
            real kc = (push.flags & AOS_OUTLIER_W) != 0u ? real(1) / max(vc, real(1)) : real(1);
            real lc = kc * S_AT(ua);
            real rv = tot[b0i + 1] - lc * lc * vc + (lc - real(1)) * (lc - real(1)) * S_AT(S_SC + SC_VC);
            real zn = t_threshold3(real(spp_of(spp[ci])));
            if (res * res > zn * zn * rv) {
                bias2 = max(bias2, res * res - rv);
            }
        }
        real mse = var + bias2;
        o[6 + 2 * oi] = bias;
        o[7 + 2 * oi] = var;
        o[11 + oi] = sqrt(max(bvar, real(0)));
        if (best < 0 || mse < best_mse) {
            best = oi;
            best_mse = mse;
        }
    }
    if ((push.flags & AOS_IDENTITY) != 0u) {
        real vid = identity_mse(ci);
        if (vid < best_mse) {
            o[3] = vid;
            o[13] = vid;
            write_out(ci, o);
            return;
        }
    }
    int pl = best == 0 ? p1 : p3;
    int ua = best == 0 ? V_U1 : V_U3;
    real3 m = real3(0);
    for (int i = 0; i < pl; ++i) {
        m += S_AT(ua + i) * real3(S_AT(V_RHS + i), S_AT(V_RHS + NC + i), S_AT(V_RHS + 2 * NC + i));
    }
    o[0] = max(m.x, real(0));
    o[1] = max(m.y, real(0));
    o[2] = max(m.z, real(0));
    o[3] = best_mse;
    o[13] = best_mse;
    if ((push.flags & AOS_FEATNOISE) != 0u) {
        // AOS-FEATNOISE: g_j = sum_m beta_(1,m) s_(1,m) P[m][j] and
        // (sum_j |g_j| sigma_j)^2 (pixel coordinates are noiseless).
        int ba = best == 0 ? V_B1 : V_B3;
        real4 ca = real4(0);
        real4 cb = real4(0);
        real2 cc = real2(0);
        for (int m = 0; m < k; ++m) {
            int cm = s_cidx[1 + m];
            real cv = cm >= 0 ? S_AT(ba + cm) * S_AT(S_SCALE + 1 + m) : real(0);
            if (m < 4) {
                ca[m] = cv;
            } else if (m < 8) {
                cb[m - 4] = cv;
            } else {
                cc[m - 8] = cv;
            }
        }
        real fs = real(0);
        for (int j = 2; j < D; ++j) {
            real gj = dot(ca, g_pa[j]) + dot(cb, g_pb[j]) + dot(cc, g_pc[j]);
            fs += abs(gj) * sqrt(max(feature_var(j - 2, ci), real(0)));
        }
        o[3] += fs * fs;
    }
    o[4] = real(best == 0 ? 1 : 3);
    write_out(ci, o);
}
