// Unsigned 64-bit integers as uvec2 (NO-64BIT) (x: low word, y: high word), for the
// sampling allocation's exact integer arithmetic on devices without
// shaderInt64. A uvec2 array in a buffer or in shared memory has the
// layout of a uint64_t array (little-endian words, 8-byte stride), so the
// buffers and the scalar twins (src/reference/sample_*.rs, in u64) are the
// same as with native 64-bit integers. Every function is exact; callers keep
// results below 2^64 where a comment says so.

#define u64 uvec2

u64 u64_from(uint a) { return u64(a, 0u); }

bool u64_is_zero(u64 a) { return (a.x | a.y) == 0u; }

// a < b
bool u64_lt(u64 a, u64 b) { return a.y < b.y || (a.y == b.y && a.x < b.x); }

// a + b mod 2^64. (Plain 32-bit operations throughout: naga's SPIR-V
// reader, which checks every kernel's bindings, knows no IAddCarry,
// ISubBorrow or UMulExtended.)
u64 u64_add(u64 a, u64 b)
{
    uint lo = a.x + b.x;
    return u64(lo, a.y + b.y + (lo < a.x ? 1u : 0u));
}

// a - b mod 2^64
u64 u64_sub(u64 a, u64 b)
{
    return u64(a.x - b.x, a.y - b.y - (a.x < b.x ? 1u : 0u));
}

// a * b for 32-bit a and b (exact: < 2^64), by 16-bit halves.
u64 u64_mul32(uint a, uint b)
{
    uint a0 = a & 0xFFFFu;
    uint a1 = a >> 16;
    uint b0 = b & 0xFFFFu;
    uint b1 = b >> 16;
    uint p00 = a0 * b0;
    uint p01 = a0 * b1;
    uint p10 = a1 * b0;
    uint mid = p01 + p10;
    uint mid_carry = mid < p01 ? 1u : 0u;
    uint lo = p00 + (mid << 16);
    uint lo_carry = lo < p00 ? 1u : 0u;
    return u64(lo, a1 * b1 + (mid >> 16) + (mid_carry << 16) + lo_carry);
}

// a * b mod 2^64 for a 32-bit b.
u64 u64_mul_u32(u64 a, uint b)
{
    u64 p = u64_mul32(a.x, b);
    return u64(p.x, p.y + a.y * b);
}

// floor(a / b), b != 0: restoring long division, one bit per step. The
// remainder stays below b; when shifting it out of 64 bits (b > 2^63) the
// true value exceeds b, and the wrapping subtraction gives it exactly.
u64 u64_div(u64 a, u64 b)
{
    u64 q = u64(0u);
    u64 r = u64(0u);
    for (int k = 63; k >= 0; k--) {
        uint top = r.y >> 31;
        uint bit = k >= 32 ? (a.y >> uint(k - 32)) & 1u : (a.x >> uint(k)) & 1u;
        r = u64((r.x << 1) | bit, (r.y << 1) | (r.x >> 31));
        if (top != 0u || !u64_lt(r, b)) {
            r = u64_sub(r, b);
            if (k >= 32) {
                q.y |= 1u << uint(k - 32);
            } else {
                q.x |= 1u << uint(k);
            }
        }
    }
    return q;
}
