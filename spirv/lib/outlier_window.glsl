// The statistics of grey over Ω_o(R) \ {o} (spec §4.4 step 1), merged from
// outlier_rows' row summaries, and a pixel's standard error of grey:
// included by outlier_detect and outlier_clip after their bindings wn, wm,
// wq (rows with the pixel of column x), xn, xm, xq (without it) and vr, vg,
// vb (the colour's variance). Scalar twin: src/reference/outliers.rs.

// The row summary at q, with the pixel of column x or without it.
Summary row_summary(uint q, bool with_x)
{
    Summary s;
    s.n = real(with_x ? wn[q] : xn[q]);
    s.mean = real(with_x ? wm[q] : xm[q]);
    s.m2 = real(with_x ? wq[q] : xq[q]);
    return s;
}

// Rows y - R .. y + R (clipped) in order, o's own without o (EXCL-CENTRE).
Summary window_summary(uint x, uint y)
{
    int r = int(push.radius);
    int y0 = max(int(y) - r, 0), y1 = min(int(y) + r, int(push.height) - 1);
    Summary s;
    s.n = real(0);
    s.mean = real(0);
    s.m2 = real(0);
    for (int qy = y0; qy < int(y); ++qy) {
        s = merge(s, row_summary(uint(qy) * push.width + x, true));
    }
    s = merge(s, row_summary(y * push.width + x, false));
    for (int qy = int(y) + 1; qy <= y1; ++qy) {
        s = merge(s, row_summary(uint(qy) * push.width + x, true));
    }
    return s;
}

// The population standard deviation of a summary.
real summary_sd(Summary s) { return sqrt(max(s.m2 / max(s.n, real(1)), real(0))); }

// The standard error of grey_o when the channels move together, as a
// spike's do (OUTLIER-NOISE): (sqrt v_R + sqrt v_G + sqrt v_B) / 3.
real grey_se(uint o)
{
    return (sqrt(max(real(vr[o]), real(0))) + sqrt(max(real(vg[o]), real(0)))
            + sqrt(max(real(vb[o]), real(0)))) / real(3);
}
