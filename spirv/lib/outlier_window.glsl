// The statistics of grey over Ω_o(R) \ {o} (spec §4.4 step 1), merged from
// outlier_rows' row summaries: included by outlier_detect and outlier_clip
// after their bindings wn, wm, wq (rows with the pixel of column x) and xn,
// xm, xq (without it). Scalar twin: src/reference/outliers.rs.

Summary row_with_x(uint q)
{
    Summary s;
    s.n = real(wn[q]);
    s.mean = real(wm[q]);
    s.m2 = real(wq[q]);
    return s;
}

Summary row_without_x(uint q)
{
    Summary s;
    s.n = real(xn[q]);
    s.mean = real(xm[q]);
    s.m2 = real(xq[q]);
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
        s = merge(s, row_with_x(uint(qy) * push.width + x));
    }
    s = merge(s, row_without_x(y * push.width + x));
    for (int qy = int(y) + 1; qy <= y1; ++qy) {
        s = merge(s, row_with_x(uint(qy) * push.width + x));
    }
    return s;
}

// The population standard deviation of a summary.
real summary_sd(Summary s) { return sqrt(max(s.m2 / max(s.n, real(1)), real(0))); }
