/* sheen_table.h: the kernel that tabulates layered_brdf.h's sheen albedo E(mu, roughness) (sheen_albedo_lut),
 * built with surface_layers.cl and testing/layered_check.cl.
 */
#ifndef CLRENDER_SHEEN_TABLE_H
#define CLRENDER_SHEEN_TABLE_H
#include "layered_brdf.h"
#pragma OPENCL FP_CONTRACT OFF

/* ---- the sheen albedo table ---------------------------------------------------------------------------- */
/* E(mu, shr) = integral over the upper hemisphere of D_charlie(N.H) clamp01(V_sheen) (N.L) dL for V at cos mu,
 * in (t = N.L, phi) coordinates (2x the half phi in [0, pi], the integrand being even in phi):
 *   t: Gauss-Legendre 8 points on each of the panels LB_T_BREAKS (graded towards the horizon, where the
 *      lambdaSheen fit's pow(t, c) has an infinite slope and the low-roughness lobes live; a break at 0.5,
 *      where the fit switches branches), each panel split where 1/V_sheen crosses 1 (the clamp's kink: found
 *      by 40 bisections when the ends straddle it);
 *   phi: Gauss-Legendre 4 points on each of the panels pi {0, 0.5, 0.8, 0.93, 0.98, 0.995, 1} (graded towards
 *      phi = pi, where L + V is shortest and N.H changes fastest at grazing views).
 * Measured against a float64 integration on 60 geometric t panels x 24 points and 512 phi points (which agrees
 * with a twice finer one to 2e-6): max error 4e-6 (tests/test_layered_brdf_kernel.py). About 1 s on 2 CPU cores. */
#define LB_T_NBREAKS 11
#define LB_PHI_NBREAKS 7

static inline float lb_sheen_integrand_s(float mu, float sv, float shr, float lam_v, float ag, float t,
                                         float cphi, float sphi)
{
    const float st = sqrt(fmax(1.0f - t * t, 0.0f));
    const float hx = st * cphi + sv, hy = st * sphi, hz = t + mu;
    const float len2 = hx * hx + hy * hy + hz * hz;
    const float nh = hz / sqrt(fmax(len2, 1e-30f));
    const float vis = 1.0f / ((1.0f + lam_v + lb_lambda_sheen_s(t, ag)) * (4.0f * mu * t));
    return lb_d_charlie_s(shr, nh) * fmin(fmax(vis, 0.0f), 1.0f) * t;
}

/* 1/V_sheen - 1 at t (without the clamp): its sign changes where the clamp starts. */
static inline float lb_vclamp_s(float mu, float lam_v, float ag, float t)
{
    return (1.0f + lam_v + lb_lambda_sheen_s(t, ag)) * (4.0f * mu * t) - 1.0f;
}

kernel void sheen_albedo_lut(global float* lut)
{
    const int id = get_global_id(0);
    if (id >= SHEEN_LUT_SIZE * SHEEN_LUT_SIZE) return;
    const float t_breaks[LB_T_NBREAKS] = { 0.0f, 1e-4f, 1e-3f, 4e-3f, 0.015f, 0.05f, 0.15f, 0.3f, 0.5f, 0.75f, 1.0f };
    const float p_breaks[LB_PHI_NBREAKS] = { 0.0f, 0.5f, 0.8f, 0.93f, 0.98f, 0.995f, 1.0f };
    const float x8[4] = { 0.183434642f, 0.525532410f, 0.796666477f, 0.960289856f };
    const float w8[4] = { 0.362683783f, 0.313706646f, 0.222381034f, 0.101228536f };
    const float x4[2] = { 0.339981044f, 0.861136312f };
    const float w4[2] = { 0.652145155f, 0.347854845f };
    const float mu = ((float)(id % SHEEN_LUT_SIZE) + 0.5f) / (float)SHEEN_LUT_SIZE;
    const float shr = ((float)(id / SHEEN_LUT_SIZE) + 0.5f) / (float)SHEEN_LUT_SIZE;
    const float sv = sqrt(1.0f - mu * mu);
    const float s_ = fmax(shr, LB_MIN_SHEEN_ROUGHNESS), ag = s_ * s_;
    const float lam_v = lb_lambda_sheen_s(mu, ag);
    /* the phi nodes (cos, sin, weight) */
    float pc[(LB_PHI_NBREAKS - 1) * 4], ps[(LB_PHI_NBREAKS - 1) * 4], pw[(LB_PHI_NBREAKS - 1) * 4];
    for (int p = 0; p + 1 < LB_PHI_NBREAKS; ++p) {
        const float a = LB_PI * p_breaks[p], b = LB_PI * p_breaks[p + 1], h = 0.5f * (b - a), c = 0.5f * (a + b);
        for (int k = 0; k < 4; ++k) {
            const float phi = c + (k < 2 ? -h : h) * x4[k < 2 ? 1 - k : k - 2];
            pc[4 * p + k] = cos(phi); ps[4 * p + k] = sin(phi); pw[4 * p + k] = h * w4[k < 2 ? 1 - k : k - 2];
        }
    }
    float sum = 0.0f;
    for (int i = 0; i + 1 < LB_T_NBREAKS; ++i) {
        float ends[3];
        int n_ends = 0;
        ends[n_ends++] = t_breaks[i];
        const float ga = lb_vclamp_s(mu, lam_v, ag, t_breaks[i]), gb = lb_vclamp_s(mu, lam_v, ag, t_breaks[i + 1]);
        if ((ga < 0.0f) != (gb < 0.0f)) {
            float lo = t_breaks[i], hi = t_breaks[i + 1];
            for (int it = 0; it < 40; ++it) {
                const float mid = 0.5f * (lo + hi);
                if ((lb_vclamp_s(mu, lam_v, ag, mid) < 0.0f) == (ga < 0.0f)) lo = mid; else hi = mid;
            }
            ends[n_ends++] = 0.5f * (lo + hi);
        }
        ends[n_ends++] = t_breaks[i + 1];
        for (int j = 0; j + 1 < n_ends; ++j) {
            const float h = 0.5f * (ends[j + 1] - ends[j]), c = 0.5f * (ends[j + 1] + ends[j]);
            for (int k = 0; k < 8; ++k) {
                const float t = c + (k < 4 ? -h : h) * x8[k < 4 ? 3 - k : k - 4];
                const float wt = h * w8[k < 4 ? 3 - k : k - 4];
                float acc = 0.0f;
                for (int q = 0; q < (LB_PHI_NBREAKS - 1) * 4; ++q)
                    acc += pw[q] * lb_sheen_integrand_s(mu, sv, shr, lam_v, ag, t, pc[q], ps[q]);
                sum += wt * acc;
            }
        }
    }
    lut[id] = 2.0f * sum;
}

#endif
