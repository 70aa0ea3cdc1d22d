/* layered_film.h: the thin-film Fresnel of KHR_materials_iridescence for layered_brdf.h, and the small scalar
 * helpers both use (the model and its sources: layered_brdf.h's header comment). */
#ifndef CLRENDER_LAYERED_FILM_H
#define CLRENDER_LAYERED_FILM_H
#include "vec.h"
#include "environment.h"       /* ENV_INLINE */
#pragma OPENCL FP_CONTRACT OFF

#define LB_PI 3.14159265358979f
static inline ENV_INLINE floatV lb_pow5(floatV x) { const floatV x2 = x * x; return x2 * x2 * x; }
static inline ENV_INLINE floatV lb_clamp01(floatV x) { return fmin(fmax(x, 0.0f), 1.0f); }
static inline ENV_INLINE floatV lb_mix(floatV a, floatV b, floatV t) { return a * (1.0f - t) + b * t; }
static inline ENV_INLINE floatV lb_max3(floatV a, floatV b, floatV c) { return fmax(fmax(a, b), c); }

/* ---- iridescence (KHR_materials_iridescence README; see the header comment) ------------------------------ */
/* R23 of the film-base interface (base IOR from F0, Schlick at cosTheta2: w2 = (1 - cosTheta2)^5) and whether
 * its phase shift phi23 is pi. */
static inline ENV_INLINE floatV lb_irid_r23(floatV f0, floatV eta2, floatV w2, intV* phi23_pi)
{
    const floatV s = sqrt(fmin(fmax(f0, 0.0f), 0.9999f));
    const floatV base_ior = (1.0f + s) / (1.0f - s);
    const floatV q = (base_ior - eta2) / (base_ior + eta2);
    const floatV r1 = q * q;
    *phi23_pi = base_ior < eta2;
    return r1 + (1.0f - r1) * w2;
}

/* What a film shares between the two bases: R12, T121 (first interface), eta2, w2, whether phi21 is pi, and
 * the sensitivity terms (cosine times Gaussian, m = 1, 2) of X (two), Y and Z without their phase shifts. */
typedef struct { floatV r12, t121, eta2, w2; intV phi21_pi; floatV cx[2], cx2[2], cy[2], cz[2]; } LbFilm;

/* Fi for one base F0 (per channel), clamped at 0. */
static inline void lb_irid_eval(const LbFilm* f, floatV f0r, floatV f0g, floatV f0b,
                                floatV* out_r, floatV* out_g, floatV* out_b)
{
    intV pr, pg, pb;
    const floatV r23[3] = { lb_irid_r23(f0r, f->eta2, f->w2, &pr), lb_irid_r23(f0g, f->eta2, f->w2, &pg),
                            lb_irid_r23(f0b, f->eta2, f->w2, &pb) };
    /* phi = phi21 + phi23 per channel: an odd multiple of pi where exactly one of them is pi */
    const intV odd[3] = { (f->phi21_pi != 0) ^ (pr != 0), (f->phi21_pi != 0) ^ (pg != 0), (f->phi21_pi != 0) ^ (pb != 0) };
    floatV I[3], Cm[3], rr[3];
    for (int ch = 0; ch < 3; ++ch) {
        const floatV R123 = fmin(fmax(f->r12 * r23[ch], 1e-5f), 0.9999f);
        rr[ch] = sqrt(R123);
        const floatV Rs = f->t121 * f->t121 * r23[ch] / (1.0f - R123);
        I[ch] = f->r12 + Rs;
        Cm[ch] = Rs - f->t121;
    }
    for (int m = 0; m < 2; ++m) {
        /* cos(pos phase + (m + 1) phi_ch): -cos(pos phase) for m + 1 = 1 and phi_ch an odd multiple of pi */
        const floatV sr = m == 0 ? select((floatV)1.0f, (floatV)-1.0f, odd[0]) : (floatV)1.0f;
        const floatV sg = m == 0 ? select((floatV)1.0f, (floatV)-1.0f, odd[1]) : (floatV)1.0f;
        const floatV sb = m == 0 ? select((floatV)1.0f, (floatV)-1.0f, odd[2]) : (floatV)1.0f;
        const floatV x = sr * (f->cx[m] + f->cx2[m]), y = sg * f->cy[m], z = sb * f->cz[m];
        /* XYZ -> linear Rec.709 (the README's XYZ_TO_REC709), times 2 */
        const floatV S[3] = { 2.0f * (3.2404542f * x - 1.5371385f * y - 0.4985314f * z),
                              2.0f * (-0.9692660f * x + 1.8760108f * y + 0.0415560f * z),
                              2.0f * (0.0556434f * x - 0.2040259f * y + 1.0572252f * z) };
        for (int ch = 0; ch < 3; ++ch) {
            Cm[ch] *= rr[ch];
            I[ch] += Cm[ch] * S[ch];
        }
    }
    *out_r = fmax(I[0], 0.0f); *out_g = fmax(I[1], 0.0f); *out_b = fmax(I[2], 0.0f);
}

/* The terms of the film (IOR eta2_in, thickness d nm) at cosTheta1 = cos1 shared by both bases. */
static inline LbFilm lb_irid_film(floatV cos1, floatV eta2_in, floatV d)
{
    LbFilm f;
    const floatV t = lb_clamp01(d * (1.0f / 0.03f));
    f.eta2 = lb_mix((floatV)1.0f, eta2_in, t * t * (3.0f - 2.0f * t));            /* smoothstep(0, 0.03, d) */
    const floatV k = 1.0f / f.eta2;
    const floatV cos2 = sqrt(fmax(1.0f - k * k * (1.0f - cos1 * cos1), 0.0f));    /* eta2 >= 1: no TIR */
    const floatV q = (f.eta2 - 1.0f) / (f.eta2 + 1.0f), r0 = q * q;
    f.r12 = r0 + (1.0f - r0) * lb_pow5(1.0f - cos1);
    f.t121 = 1.0f - f.r12;
    f.w2 = lb_pow5(1.0f - cos2);
    f.phi21_pi = f.eta2 >= 1.0f;                                                   /* phi12 = 0 unless eta2 < 1 */
    const floatV opd = 2.0f * f.eta2 * d * cos2;
    /* m = 1 at the phase p, m = 2 at 2p from the same cosines and Gaussians: cos(2x) = 2 cos(x)^2 - 1 and
     * exp(-k (2p)^2) = exp(-k p^2)^4 (half the library calls; differences of a few ulp) */
    const floatV phase = (2.0f * LB_PI * 1.0e-9f) * opd;
    const floatV p2 = phase * phase;
    /* val sqrt(2 pi var) / 1.0685e-7 per term (the README's constants) */
#define LB_SENS(out, val, pos, var) { \
        const floatV c1 = cos((pos) * phase), g1 = exp(-(var) * p2), g2 = g1 * g1; \
        out[0] = (val) * c1 * g1; \
        out[1] = (val) * (2.0f * c1 * c1 - 1.0f) * (g2 * g2); }
    LB_SENS(f.cx, 0.846590002f, 1.6810e+06f, 4.3278e+09f)
    LB_SENS(f.cx2, 0.153868307f, 2.2399e+06f, 4.5282e+09f)
    LB_SENS(f.cy, 1.000221894f, 1.7953e+06f, 9.3046e+09f)
    LB_SENS(f.cz, 1.001122486f, 2.2084e+06f, 6.6121e+09f)
#undef LB_SENS
    return f;
}

#endif
