// Spec §10.1, the LP temporal filter at one pixel: the reprojection search,
// RESET and the update, shared by lp_temporal.comp (the filter) and
// lp_temporal_gain.comp (what the filter will do, for the sample map).
// Scalar twin: src/reference/lp_temporal.rs (`step`).
//
// The including kernel declares the planes yr yg yb (the method's colour),
// px py pz (position), vx vy vz (its variance), depth, spp, er eg eb (the
// method's error estimate), prev (the
// previous frame's TEMPORAL_STATE planes: b0 b1 per channel R G B,
// P00 P01 P11, W X Y Z, valid) and mx my (TEMPORAL-MOTION's offsets,
// temporal_motion.comp's level 0), and a push block `push` with
// width, height, flags, lambda, p00, p11, error_scale and inflate_scale.

#ifndef MC_TEMPORAL_GLSL
#define MC_TEMPORAL_GLSL

// mcdenoise::shared: TEMPORAL_RESET, TEMPORAL_NO_SEARCH, TEMPORAL_MOTION,
// TEMPORAL_SEARCH, TEMPORAL_RESET_REL, TEMPORAL_DEPTH_FLOOR,
// TEMPORAL_RESET_NOISE, TEMPORAL_SUBPIXEL_GATE, TEMPORAL_SUBPIXEL_REACH,
// TEMPORAL_RIM_TOL, TEMPORAL_RIM_CONTRAST, TEMPORAL_RIM_HISTORY.
#define TEMPORAL_RESET 1u
#define TEMPORAL_NO_SEARCH 2u
#define TEMPORAL_MOTION 4u
#define SEARCH 3
#define RESET_REL 0.01
#define DEPTH_FLOOR 1e-3
#define RESET_NOISE 18.0
#define SUBPIXEL_GATE 4.0
#define SUBPIXEL_REACH 0.5
#define RIM_TOL 0.25
#define RIM_CONTRAST 8.0
#define RIM_HISTORY 0.5

// What temporal_step did.
#define STEP_PASS 0
#define STEP_RESET 1
#define STEP_CONTINUE 2

// The state of pixel j (n pixels), shifted to the current frame's origin:
// beta as (b0, b1) per channel, P as (p00, p01, p11).
void load_shifted(uint j, uint n, out real2 b[3], out real3 p, out real3 w)
{
    for (int c = 0; c < 3; ++c) {
        real b0 = real(prev[(2 * c) * n + j]);
        real b1 = real(prev[(2 * c + 1) * n + j]);
        b[c] = real2(b0 + b1, b1);
    }
    real a = real(prev[6 * n + j]);
    real o = real(prev[7 * n + j]);
    real d = real(prev[8 * n + j]);
    p = real3(a + real(2) * o + d, o + d, d);
    w = real3(prev[9 * n + j], prev[10 * n + j], prev[11 * n + j]);
}

bool valid_at(uint j, uint n) { return prev[12 * n + j] == 1.0; }

// A push constant's factor on the error estimate: 0 (or less) reads as 1.
real factor_or_one(float v) { return v > 0.0 ? real(v) : real(1); }

// The intercepts R, G, B of the previous state at (jx, jy), shifted to the
// current frame; `fallback` where that pixel is outside the image or has no
// state.
real3 intercept_at(int jx, int jy, uint n, real3 fallback)
{
    if (jx < 0 || jy < 0 || jx >= int(push.width) || jy >= int(push.height)) {
        return fallback;
    }
    uint j = uint(jy) * push.width + uint(jx);
    if (!valid_at(j, n)) {
        return fallback;
    }
    return real3(prev[j] + prev[n + j], prev[2 * n + j] + prev[3 * n + j],
                 prev[4 * n + j] + prev[5 * n + j]);
}

// The position W of pixel k's previous state.
real3 w_of(ivec2 k, uint n)
{
    uint m = uint(k.y) * push.width + uint(k.x);
    return real3(prev[9 * n + m], prev[10 * n + m], prev[11 * n + m]);
}

// TEMPORAL-SUBPIXEL: whether pixel k of the previous frame has a state on
// the surface of the state at position wj (within `gate`, squared); w is
// its position where it has a state.
bool near_state(ivec2 k, uint n, real3 wj, real gate, out real3 w)
{
    w = real3(0);
    if (k.x < 0 || k.y < 0 || k.x >= int(push.width) || k.y >= int(push.height)) {
        return false;
    }
    if (!valid_at(uint(k.y) * push.width + uint(k.x), n)) {
        return false;
    }
    w = w_of(k, n);
    real3 d = w - wj;
    return dot(d, d) <= gate;
}

// TEMPORAL-SUBPIXEL: the previous state's position derivative along one
// axis at j (central where both neighbours are on j's surface, else the
// one-sided difference); false where neither is.
bool w_derivative(ivec2 j, ivec2 axis, uint n, real3 wj, real gate, out real3 dw)
{
    real3 wu, wd;
    bool up = near_state(j + axis, n, wj, gate, wu);
    bool down = near_state(j - axis, n, wj, gate, wd);
    dw = real3(0);
    if (up && down) {
        dw = (wu - wd) * real(0.5);
    } else if (up) {
        dw = wu - wj;
    } else if (down) {
        dw = wj - wd;
    }
    return up || down;
}

// TEMPORAL-SUBPIXEL: the state carried from pixel j resampled where the
// surface point at position wi lies between pixels of the previous frame:
// the offset d solving W(j + d) = wi to first order (least squares on the
// previous positions' derivatives, clamped to SUBPIXEL_REACH), then the
// shifted beta interpolated bilinearly between j and its neighbours
// towards d, a neighbour not on j's surface (`gate`) reading j's. b holds
// j's shifted beta on entry.
void resample(ivec2 j, real3 wi, real gate, uint n, inout real2 b[3])
{
    real3 wj = w_of(j, n);
    real3 ex, ey;
    if (!w_derivative(j, ivec2(1, 0), n, wj, gate, ex)
        || !w_derivative(j, ivec2(0, 1), n, wj, gate, ey)) {
        return;
    }
    real a = dot(ex, ex), o = dot(ex, ey), c = dot(ey, ey);
    real det = a * c - o * o;
    if (!(det > real(1e-6) * a * c)) {
        return;
    }
    real3 dw = wi - wj;
    real rx = dot(ex, dw), ry = dot(ey, dw);
    real dx = clamp((c * rx - o * ry) / det, -real(SUBPIXEL_REACH), real(SUBPIXEL_REACH));
    real dy = clamp((a * ry - o * rx) / det, -real(SUBPIXEL_REACH), real(SUBPIXEL_REACH));
    ivec2 s = ivec2(dx < real(0) ? -1 : 1, dy < real(0) ? -1 : 1);
    real fx = abs(dx), fy = abs(dy);
    ivec2 corner[3] = ivec2[3](j + ivec2(s.x, 0), j + ivec2(0, s.y), j + s);
    real weight[3] = real[3](fx * (real(1) - fy), (real(1) - fx) * fy, fx * fy);
    real2 acc[3];
    real w0 = (real(1) - fx) * (real(1) - fy);
    for (int ch = 0; ch < 3; ++ch) {
        acc[ch] = w0 * b[ch];
    }
    for (int k = 0; k < 3; ++k) {
        real2 cb[3];
        real3 cw;
        if (near_state(corner[k], n, wj, gate, cw)) {
            real3 cp;
            load_shifted(uint(corner[k].y) * push.width + uint(corner[k].x), n, cb, cp, cw);
        } else {
            cb = b;
        }
        for (int ch = 0; ch < 3; ++ch) {
            acc[ch] += weight[k] * cb[ch];
        }
    }
    b = acc;
}

// TEMPORAL-RIM: the miss of prediction b0 at pixel (x, y) becomes its
// distance from the range of this frame's colours in the 3x3 window where
// the window's brightest pixel (the greatest R + G + B, the first in raster
// order) is at least RIM_CONTRAST times as bright as this pixel and has a
// previous state at the same pixel whose intercepts are within RIM_TOL of
// its colour (summed over the channels), and the prediction is at most
// RIM_HISTORY of its brightness: a static bright neighbour makes a history
// between this pixel's colour and the neighbour's plausible, as on the rim
// of a light seen directly, whose frames are quiet or lit; a history as
// bright as the light is of a pixel the light has left.
void rim_miss(uint x, uint y, uint n, real3 yi, real3 b0, inout real3 miss)
{
    real3 lo = yi, hi = yi;
    real best = real(-1);
    ivec2 bk = ivec2(x, y);
    for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
            int kx = int(x) + dx, ky = int(y) + dy;
            if (kx < 0 || ky < 0 || kx >= int(push.width) || ky >= int(push.height)) {
                continue;
            }
            uint m = uint(ky) * push.width + uint(kx);
            vec3 ck = vec3(yr[m], yg[m], yb[m]);
            if (spp_of(spp[m]) < 1.0 || !is_finite(ck.x) || !is_finite(ck.y) || !is_finite(ck.z)) {
                continue;
            }
            real3 c = real3(ck);
            lo = min(lo, c);
            hi = max(hi, c);
            real l = c.x + c.y + c.z;
            if (l > best) {
                best = l;
                bk = ivec2(kx, ky);
            }
        }
    }
    if (!(best > real(RIM_CONTRAST) * (yi.x + yi.y + yi.z + real(0.01)))
        || b0.x + b0.y + b0.z > real(RIM_HISTORY) * best) {
        return;
    }
    uint bm = uint(bk.y) * push.width + uint(bk.x);
    if (!valid_at(bm, n)) {
        return;
    }
    real3 cb = real3(vec3(yr[bm], yg[bm], yb[bm]));
    real3 d = abs(intercept_at(bk.x, bk.y, n, cb) - cb);
    if (d.x + d.y + d.z <= real(RIM_TOL) * best) {
        miss = max(lo - b0, real3(0)) + max(b0 - hi, real3(0));
    }
}

// The filter at pixel (x, y): STEP_PASS for an invalid pixel or a
// non-finite colour; STEP_RESET with beta = (y, 0), P = diag(p00, p11)
// (TEMPORAL-PRIOR); or
// STEP_CONTINUE with the state reprojected from offset index `off`
// ((dy + 3) * 7 + dx + 3, from the window's centre) and updated. Among the
// valid previous states in the 7x7 window (centred on the pixel, or with
// TEMPORAL_MOTION on the pixel plus its offset in mx my) whose position is
// within RESET's distance (TEMPORAL-GATE, RESET-NOISE), the one with the least (eW + epsW)(ey + epsy), the first in
// raster order on a tie; its P inflated where its prediction misses the
// colour by more than the noise allows (TEMPORAL-INFLATE).
int temporal_step(uint x, uint y, out real2 b[3], out real3 p, out int off)
{
    uint n = push.width * push.height;
    uint i = y * push.width + x;
    vec3 col = vec3(yr[i], yg[i], yb[i]);
    off = 0;
    p = real3(0);
    b[0] = real2(0); b[1] = real2(0); b[2] = real2(0);
    if (spp_of(spp[i]) < 1.0 || !is_finite(col.x) || !is_finite(col.y) || !is_finite(col.z)) {
        return STEP_PASS;
    }
    real3 yi = real3(col);
    real3 wi = real3(px[i], py[i], pz[i]);
    real3 ei = max(real3(er[i], eg[i], eb[i]), real3(0));
    real t3 = t_threshold3(real(spp_of(spp[i])));
    real t2 = t3 * t3;
    real3 w;
    bool found = false;
    // TEMPORAL-RIM applies where the window is centred on the pixel.
    bool still = (push.flags & TEMPORAL_MOTION) == 0u
        || (push.flags & (TEMPORAL_RESET | TEMPORAL_NO_SEARCH)) != 0u
        || (int(mx[i]) == 0 && int(my[i]) == 0);
    if ((push.flags & TEMPORAL_RESET) == 0u) {
        if ((push.flags & TEMPORAL_NO_SEARCH) != 0u) {
            if (valid_at(i, n)) {
                load_shifted(i, n, b, p, w);
                found = true;
                off = SEARCH * (2 * SEARCH + 1) + SEARCH;
            }
        } else {
            ivec2 best_j = ivec2(-1);
            real ew_floor = real(1e-12) * (real(1) + dot(wi, wi));
            real limit = real(RESET_REL) * max(real(depth[i]), real(DEPTH_FLOOR));
            limit = limit * limit + real(RESET_NOISE) * (real(vx[i]) + real(vy[i]) + real(vz[i]));
            real best_cost = real(0);
            ivec2 c = ivec2(x, y);
            if ((push.flags & TEMPORAL_MOTION) != 0u) {
                c += ivec2(int(mx[i]), int(my[i]));
            }
            int x0 = max(c.x - SEARCH, 0), x1 = min(c.x + SEARCH, int(push.width) - 1);
            int y0 = max(c.y - SEARCH, 0), y1 = min(c.y + SEARCH, int(push.height) - 1);
            for (int jy = y0; jy <= y1; ++jy) {
                for (int jx = x0; jx <= x1; ++jx) {
                    uint j = uint(jy) * push.width + uint(jx);
                    if (!valid_at(j, n)) {
                        continue;
                    }
                    real2 cb[3];
                    real3 cp;
                    real3 cw;
                    load_shifted(j, n, cb, cp, cw);
                    real3 dw = cw - wi;
                    real ew = dot(dw, dw);
                    if (ew > limit) {
                        continue;
                    }
                    real3 dy3 = yi - real3(cb[0].x, cb[1].x, cb[2].x);
                    real ey = dot(dy3, dy3);
                    real cost = (ew + ew_floor) * (ey + real(1e-12));
                    if (!found || cost < best_cost) {
                        found = true;
                        best_cost = cost;
                        off = (jy - c.y + SEARCH) * (2 * SEARCH + 1) + (jx - c.x + SEARCH);
                        best_j = ivec2(jx, jy);
                        b = cb;
                        p = cp;
                    }
                }
            }
            // TEMPORAL-MISREG: where the surface moved on screen (a motion
            // offset), a state from another pixel predicts this one's colour
            // up to where the two pixels' footprints differ: P00 grows by the
            // variance of a shift uniform over a pixel along the state's
            // gradient, (gx^2 + gy^2)/12, in units of the error (times the
            // method's error scale, which corrects its average bias).
            if (found && c != ivec2(x, y) && best_j != ivec2(x, y)) {
                real3 b0 = real3(b[0].x, b[1].x, b[2].x);
                real3 gx = (intercept_at(best_j.x + 1, best_j.y, n, b0)
                    - intercept_at(best_j.x - 1, best_j.y, n, b0)) * real(0.5);
                real3 gy = (intercept_at(best_j.x, best_j.y + 1, n, b0)
                    - intercept_at(best_j.x, best_j.y - 1, n, b0)) * real(0.5);
                real scale = factor_or_one(push.error_scale);
                real3 mis = (gx * gx + gy * gy) / (real(12) * scale * ei + real3(1e-12));
                p.x += max(mis.x, max(mis.y, mis.z));
                resample(best_j, wi, real(SUBPIXEL_GATE) * limit, n, b);
            }
        }
    }
    if (!found) {
        for (int c = 0; c < 3; ++c) {
            b[c] = real2(yi[c], real(0));
        }
        p = real3(real(push.p00), real(0), real(push.p11));
        return STEP_RESET;
    }
    // TEMPORAL-INFLATE: P grows by the prediction's largest miss over
    // t3^2 E (1 + P00) where that exceeds 1; the miss beside a static bright
    // pixel as TEMPORAL-RIM has it.
    real3 miss = yi - real3(b[0].x, b[1].x, b[2].x);
    if (still) {
        rim_miss(x, y, n, yi, real3(b[0].x, b[1].x, b[2].x), miss);
    }
    // TEMPORAL-TEST-SCALE: E times the method's factor, its output's noise over
    // its estimate relative to WLR's, on which the threshold was set.
    real tscale = factor_or_one(push.inflate_scale);
    real3 ratio = (miss * miss) / (t2 * tscale * ei * (real(1) + p.x) + real3(1e-12));
    p *= max(max(real(1), ratio.x), max(ratio.y, ratio.z));
    real lambda = real(push.lambda);
    real den = lambda + p.x;
    real2 g = real2(p.x, p.y) / den;
    // (P00 - g0 P00)/lambda written as P00/den (and P01 alike): the same
    // in exact arithmetic, but it does not cancel to 0 when an inflated
    // P00 makes g0 round to 1 (TEMPORAL-INFLATE).
    p = real3(p.x / den, p.y / den, (p.z - g.y * p.y) / lambda);
    for (int c = 0; c < 3; ++c) {
        real r = yi[c] - b[c].x;
        b[c] += g * r;
    }
    return STEP_CONTINUE;
}

#endif
