/* brdf.h: the two shading models, evaluated by the same functions in every pipeline (deferred
 * shade.cl, the light pre-pass's light_buffer.cl + material.cl, light-indexed forward_shade.cl)
 * and by the transparent fragments (forward.h: A-buffer, depth peeling).
 *
 * Blinn-Phong (report II.4; OBJ/MTL and TOML materials, and everything with
 * RenderConfig.shading = "blinn_phong"): albedo·(ambient + ΣA·c·N·L) + Σ A·c·s·(N·H)^p.
 * glTF 2.0 BRDF (Appendix B; metallic-roughness materials, MAT_GLTF_BRDF): F0 = mix(0.04, base,
 * metallic), albedo = base·(1 − metallic), α = roughness², F = F0 + (1 − F0)·(1 − V·H)^5 (Schlick),
 * D = α² / (π ((N·H)²(α² − 1) + 1)²) (Trowbridge-Reitz/GGX), V = Smith height-correlated,
 *     f = (1 − F)·albedo/π + F·D·V,   radiance = Σ f · A·c · max(N·L, 0).
 *
 * The light loop (lighting.h) keeps three RGB sums per pixel that need the material's roughness
 * but not its colour or metallic (the report's light buffer idea; the light pre-pass stores them):
 *   Blinn-Phong lanes:  D = Σ A·c·max(N·L, 0),   S = Σ A·c·s·max(N·H, 0)^p where N·L > 0,   T = 0
 *   glTF lanes, w = (1 − V·H)^5, k = A·c·max(N·L, 0):
 *                       D = Σ k·(1 − w)/π,   S = Σ k·D·V·(1 − w),   T = Σ k·D·V·w
 * and since F = F0·(1 − w) + w and 1 − F = (1 − F0)(1 − w), the material composes them exactly:
 *   Blinn-Phong: albedo·D + S            glTF: albedo·(1 − F0)·D + F0·S + T.
 * The image-based ambient (ambient.h) adds its split-sum terms to the same sums.
 */
#ifndef CLRENDER_BRDF_H
#define CLRENDER_BRDF_H
#include "structs.h"
#include "vec.h"

#ifndef MIN_ROUGHNESS
#define MIN_ROUGHNESS 0.01f       /* clrender/scene/model.py MIN_ROUGHNESS: α >= 1e-4 keeps D finite */
#endif
#define DIELECTRIC_F0 0.04f
#define INV_PI 0.318309886f

/* What the light loop needs of the lanes' materials. */
typedef struct {
    intV gltf;                  /* lanes shaded with the glTF BRDF; the others Blinn-Phong */
    int any_gltf;               /* ANY(gltf): the glTF terms are evaluated at all */
    floatV alpha;               /* glTF lanes: roughness² */
    floatV nv;                  /* glTF lanes: max(N·V, 1e-4) */
    floatV spec_i, spec_p;      /* Blinn-Phong lanes: specular intensity (folded into S) and power */
} BrdfV;

/* The lanes `gltf` of materials flagged MAT_GLTF_BRDF. */
static inline intV gltf_lanes(intV mat_flags, intV fg)
{
    intV g = fg & ((mat_flags & (int)MAT_GLTF_BRDF) != 0);
#if VEC == 1
    g = g ? 1 : 0;
#endif
    return g;
}

/* BrdfV from the G-buffer's (or a fragment's) two material bytes: on glTF lanes spec_i holds the
 * metallic value (unused by the light loop) and spec_p the roughness; N and V unit. */
static inline BrdfV brdf_inputs(intV gltf, floatV spec_i, floatV spec_p, floatV nx, floatV ny, floatV nz,
                                floatV vx, floatV vy, floatV vz)
{
    BrdfV m;
    m.gltf = gltf;
    m.any_gltf = ANY(gltf) ? 1 : 0;
    m.spec_i = spec_i;
    m.spec_p = spec_p;
    const floatV r = fmax(spec_p, MIN_ROUGHNESS);
    m.alpha = r * r;
    m.nv = fmax(nx * vx + ny * vy + nz * vz, 1e-4f);
    return m;
}

/* One light's glTF factors at N·L = nl > 0 (the other lanes get garbage, selected away):
 * *kd = (1 − w)/π, *ks = D·V·(1 − w), *kt = D·V·w. */
static inline void gltf_light_terms(const BrdfV* m, floatV nl, floatV nh, floatV vh, floatV* kd, floatV* ks, floatV* kt)
{
    const floatV a2 = m->alpha * m->alpha;
    const floatV q = nh * nh * (a2 - 1.0f) + 1.0f;
    const floatV d = a2 * INV_PI / fmax(q * q, 1e-30f);
    const floatV nl_ = fmax(nl, 0.0f), nv = m->nv;
    const floatV vis = 0.5f / fmax(nl_ * sqrt(nv * nv * (1.0f - a2) + a2) + nv * sqrt(nl_ * nl_ * (1.0f - a2) + a2),
                                   1e-30f);
    const floatV u = 1.0f - clamp(vh, 0.0f, 1.0f), u2 = u * u;
    const floatV w = u2 * u2 * u;
    const floatV dv = d * vis;
    *kd = (1.0f - w) * INV_PI;
    *ks = dv * (1.0f - w);
    *kt = dv * w;
}

/* A material's G-buffer terms turned into what composition needs: on glTF lanes (base colour in
 * r, g, b; metallic m) the albedo base·(1 − m) replaces r, g, b and F0 = mix(0.04, base, m) goes
 * to f0; other lanes keep their albedo. */
static inline void gltf_albedo_f0(intV gltf, floatV m, floatV* r, floatV* g, floatV* b,
                                  floatV* f0r, floatV* f0g, floatV* f0b)
{
    const floatV kd = 1.0f - m;
    *f0r = DIELECTRIC_F0 * kd + *r * m;
    *f0g = DIELECTRIC_F0 * kd + *g * m;
    *f0b = DIELECTRIC_F0 * kd + *b * m;
    *r = select(*r, *r * kd, gltf); *g = select(*g, *g * kd, gltf); *b = select(*b, *b * kd, gltf);
}

/* One channel of a glTF lane's outgoing radiance from its sums (header) and its ambient sums
 * (ambient.h: ad, as, at; the constant ambient is ad alone), plus emission; unlit lanes: the
 * albedo (= base colour: unlit materials are not MAT_GLTF_BRDF). */
static inline floatV compose_gltf(floatV albedo, floatV f0, floatV d, floatV s, floatV t, floatV ad, floatV as,
                                  floatV at, floatV occlusion, floatV emission)
{
    return albedo * (1.0f - f0) * (ad * occlusion + d) + f0 * (as * occlusion + s) + (at * occlusion + t) + emission;
}
#endif
