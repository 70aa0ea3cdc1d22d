/* layered_math.h: VEC-wide inline forms of log2, exp2, pow and exp for layered_brdf.h's per-light terms.
 */
#ifndef CLRENDER_LAYERED_MATH_H
#define CLRENDER_LAYERED_MATH_H
#include "vec.h"
#include "environment.h"       /* ENV_INLINE */
#pragma OPENCL FP_CONTRACT OFF

/* PoCL calls its libm's pow, exp and log once per lane, out of line: in the light loop those calls cost more
 * than the rest of the layered model. These polynomial forms (the technique of lighting.h's spec_powV) take
 * their place in the per-light sheen terms; the sheen table kernel keeps the library functions.
 * lb_log2V(x), x > 0 normal: e + 2 atanh(t)/ln 2 with t = (m - 1)/(m + 1), m in [sqrt(1/2), sqrt(2)) (the
 *   cubic fit of atanh(t)/t in t^2 of spec_powV, error < 1e-9); x below FLT_MIN gives about -126.
 * lb_exp2V(y), y in [-126, 127]: 2^round(y) times a degree-6 fit of 2^f on f in [-1/2, 1/2] (error < 2e-9).
 * lb_powV(x, p) = lb_exp2V(p lb_log2V(x)): its relative error grows with |y| = |p log2 x| (the rounding of y),
 *   about 1e-7 (1 + |y|/2): absolute error below 1e-7 for x in [0, 1].
 * lb_expV(z): Cody-Waite reduction z = n ln 2 + r (ln 2 split so that n ln2_hi is exact), e^r by its degree-7
 *   Taylor polynomial on |r| <= 0.35 (error < 6e-9), z clamped to [-87, 88].
 * Measured against float64 on 1.6M seeded points (x uniform in [0, 1] and log-uniform in [1e-30, 1], p in
 * [0.01, 1], z in [-50, 50]): log2 relative error 1.1e-7 (|log2 x| > 1); pow absolute error 1.0e-7, relative
 * 5.3e-6 at the smallest results (|y| near 100); exp relative error 1.0e-7. The sheen terms they feed are
 * checked whole at rtol 1e-4 (tests/test_layered_brdf_kernel.py). */
static inline ENV_INLINE floatV lb_log2V(floatV x)
{
    const intV bits = as_intV(fmax(x, 1.17549435e-38f));
    intV e = (bits >> 23) - 127;
    floatV m = as_floatV((bits & 0x007fffff) | 0x3f800000);
    const intV big = m > 1.41421356f;
    m = select(m, m * 0.5f, big);
    e = select(e, e + 1, big);
    const floatV t = (m - 1.0f) / (m + 1.0f), t2 = t * t;
    const floatV q = 1.0f + t2 * (0.333334084f + t2 * (0.199873468f + t2 * 0.149642197f));
    return convert_floatV(e) + (2.0f * t * q) * 1.44269504f;
}
static inline ENV_INLINE floatV lb_exp2V(floatV y)
{
    y = fmin(fmax(y, -126.0f), 127.0f);
    const intV biased = convert_intV(y + 127.5f);                 /* round(y) + 127, y + 127.5 > 0 */
    const floatV f = y - (convert_floatV(biased) - 127.0f);
    const floatV q = 1.0f + f * (0.693147207f + f * (0.240226512f + f * (0.0555032721f + f * (0.0096180256f
                     + f * (0.00134004322f + f * 0.00015469732f)))));
    return q * as_floatV(biased << 23);
}
/* x^p for x in [0, 1], p > 0: 0 where x < FLT_MIN or the result is below 2^-126 (as spec_powV). */
static inline ENV_INLINE floatV lb_powV(floatV x, floatV p)
{
    const floatV y = p * lb_log2V(x);
    return select(lb_exp2V(y), (floatV)0.0f, (x < 1.17549435e-38f) | (y <= -126.0f));
}
static inline ENV_INLINE floatV lb_expV(floatV z)
{
    z = fmin(fmax(z, -87.0f), 88.0f);
    const floatV nf = convert_floatV(convert_intV(z * 1.44269504f + 128.5f)) - 128.0f;   /* round(z / ln 2) */
    const floatV r = (z - nf * 0.693359375f) - nf * -2.12194440e-4f;
    const floatV q = 1.0f + r * (1.0f + r * (0.5f + r * (0.166666667f + r * (0.0416666667f + r * (0.00833333333f
                     + r * (0.00138888889f + r * 0.000198412698f))))));
    return q * as_floatV((convert_intV(nf) + 127) << 23);
}

#endif
