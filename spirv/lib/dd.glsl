// Double-float ("dd") arithmetic (NO-64BIT): a value is hi + lo, two floats with
// |lo| <= ulp(hi)/2, about 44 significant bits. The `_dd` variant of a
// kernel (built with MC_DD, chosen by the context on a device without
// shaderFloat64) uses it where the f32 variant uses double (WLR steps 6-7,
// §0.3). Error-free transformations after Dekker and Knuth, with Dekker's
// split instead of fma (not every device fuses it); `precise` keeps the
// compiler from reassociating or contracting them.

#ifndef MC_DD_GLSL
#define MC_DD_GLSL

#define dd vec2

dd dd_from(float a) { return dd(a, 0.0); }

dd dd_quick_two_sum(float a, float b)
{
    precise float s = a + b;
    precise float e = b - (s - a);
    return dd(s, e);
}

dd dd_two_sum(float a, float b)
{
    precise float s = a + b;
    precise float bb = s - a;
    precise float e = (a - (s - bb)) + (b - bb);
    return dd(s, e);
}

dd dd_two_prod(float a, float b)
{
    precise float p = a * b;
    precise float ta = 4097.0 * a;
    precise float ah = ta - (ta - a);
    precise float al = a - ah;
    precise float tb = 4097.0 * b;
    precise float bh = tb - (tb - b);
    precise float bl = b - bh;
    precise float e = ((ah * bh - p) + ah * bl + al * bh) + al * bl;
    return dd(p, e);
}

dd dd_add(dd a, dd b)
{
    dd s = dd_two_sum(a.x, b.x);
    dd t = dd_two_sum(a.y, b.y);
    precise float sy = s.y + t.x;
    s = dd_quick_two_sum(s.x, sy);
    precise float sy2 = s.y + t.y;
    return dd_quick_two_sum(s.x, sy2);
}

dd dd_neg(dd a) { return dd(-a.x, -a.y); }

dd dd_sub(dd a, dd b) { return dd_add(a, dd_neg(b)); }

dd dd_mul(dd a, dd b)
{
    dd p = dd_two_prod(a.x, b.x);
    precise float e = p.y + (a.x * b.y + a.y * b.x);
    return dd_quick_two_sum(p.x, e);
}

// a / b: a float quotient refined twice (float division need not be
// correctly rounded on every device; the refinements absorb that).
dd dd_div(dd a, dd b)
{
    float q1 = a.x / b.x;
    dd r = dd_sub(a, dd_mul(b, dd_from(q1)));
    float q2 = r.x / b.x;
    r = dd_sub(r, dd_mul(b, dd_from(q2)));
    float q3 = r.x / b.x;
    return dd_add(dd_quick_two_sum(q1, q2), dd_from(q3));
}

bool dd_lt(dd a, dd b) { return a.x < b.x || (a.x == b.x && a.y < b.y); }
bool dd_gt(dd a, dd b) { return dd_lt(b, a); }

dd dd_max(dd a, dd b) { return dd_lt(a, b) ? b : a; }
dd dd_clamp(dd a, dd lo, dd hi) { return dd_lt(a, lo) ? lo : (dd_lt(hi, a) ? hi : a); }

float dd_to_float(dd a) { return a.x + a.y; }

// p / q for integers p, q (exact to dd precision): decimal constants.
dd dd_ratio(float p, float q) { return dd_div(dd_from(p), dd_from(q)); }

#endif
