/* ambient.h: the ambient light from an HDR environment (the report's ambient pass, III.1, which
 * initializes the light buffer; docs/shading.md), for every pipeline's composition (compose.h).
 *
 * Blinn-Phong lanes: the diffuse light E(n)/π (what albedo multiplies), from the environment's
 * order-2 spherical harmonics. glTF lanes: Appendix B integrated over the environment with the
 * split-sum approximation (Karis 2013): with the DFG table's (A, B, C) at (N·V, roughness),
 *     diffuse  = albedo·(1 − F0)·C·E(n)/π     (C: the lobe average of Appendix B's (1 − (1 − V·H)^5))
 *     specular = prefiltered(R, roughness)·(F0·A + B),   R = 2(N·V)N − V,
 * returned as AmbientV (ad = C·E/π, as = pref·A, at = pref·B) for compose_gltf. Every term is
 * multiplied by `ao` (SSAO; the material's occlusion is applied by the composition); shadows do
 * not touch it. Background lanes: the environment along the view ray (env_backgroundV).
 */
#ifndef CLRENDER_AMBIENT_H
#define CLRENDER_AMBIENT_H
#include "environment.h"
#include "compose.h"

/* The ambient light of the lanes: the environment's when has_env, else the constant
 * `ambient`·ao. N, V unit; m: the lanes' BRDF inputs (roughness in spec_p on glTF lanes). */
static inline AmbientV ambient_light(int has_env, const EnvMaps* env, const BrdfV* m, floatV ambient_ao, floatV ao,
                                     floatV nx, floatV ny, floatV nz, floatV vx, floatV vy, floatV vz)
{
    if (!has_env) return constant_ambient(ambient_ao);
    AmbientV amb;
    floatV er, eg, eb;
    env_irradianceV(env, nx, ny, nz, &er, &eg, &eb);
    amb.dr = er * ao; amb.dg = eg * ao; amb.db = eb * ao;
    amb.sr = 0.0f; amb.sg = 0.0f; amb.sb = 0.0f;
    amb.tr = 0.0f; amb.tg = 0.0f; amb.tb = 0.0f;
    if (!m->any_gltf) return amb;
    const floatV rough = clamp(m->spec_p, 0.0f, 1.0f);
    floatV A, B, C;
    env_dfgV(env, m->nv, rough, &A, &B, &C);
    const floatV k = 2.0f * (nx * vx + ny * vy + nz * vz);
    floatV pr, pg, pb;
    env_specularV(env, k * nx - vx, k * ny - vy, k * nz - vz, rough, &pr, &pg, &pb);
    const intV g = m->gltf;
    const floatV Cao = C * ao, Aao = A * ao, Bao = B * ao;
    amb.dr = select(amb.dr, er * Cao, g); amb.dg = select(amb.dg, eg * Cao, g); amb.db = select(amb.db, eb * Cao, g);
    amb.sr = select((floatV)0.0f, pr * Aao, g); amb.sg = select((floatV)0.0f, pg * Aao, g);
    amb.sb = select((floatV)0.0f, pb * Aao, g);
    amb.tr = select((floatV)0.0f, pr * Bao, g); amb.tg = select((floatV)0.0f, pg * Bao, g);
    amb.tb = select((floatV)0.0f, pb * Bao, g);
    return amb;
}

#ifndef ORTHO
#define ORTHO 0
#endif
/* The unit vectors towards the eye at pixel centres (px, py) (lighting.h pixel_positions' rays;
 * ORTHO: -F everywhere), for passes that have no G-buffer position (material.cl). */
static inline void view_vectors(global const float* camera, int width, int height, intV px, intV py,
                                floatV* vx, floatV* vy, floatV* vz)
{
    const float3 F = vload4(1, camera).xyz;
#if ORTHO
    *vx = -F.x; *vy = -F.y; *vz = -F.z;
#else
    const float3 Rs = vload4(2, camera).xyz, Us = vload4(3, camera).xyz;
    const floatV xn = (convert_floatV(px) + 0.5f) * (2.0f / (float)width) - (1.0f + camera[3]);
    const floatV yn = (1.0f - camera[7]) - (convert_floatV(py) + 0.5f) * (2.0f / (float)height);
    const floatV dx = F.x + xn * Rs.x + yn * Us.x, dy = F.y + xn * Rs.y + yn * Us.y, dz = F.z + xn * Rs.z + yn * Us.z;
    const floatV inv_d = RSQRT(dx * dx + dy * dy + dz * dz);
    *vx = -dx * inv_d; *vy = -dy * inv_d; *vz = -dz * inv_d;
#endif
}

/* Background lanes (not fg) get the environment along the view ray -V when `background`. */
static inline void environment_background(int has_env, int background, const EnvMaps* env, intV fg,
                                          floatV vx, floatV vy, floatV vz, floatV* cr, floatV* cg, floatV* cb)
{
    if (!has_env || !background || !ANY(!fg)) return;
    floatV r, g, b;
    env_backgroundV(env, -vx, -vy, -vz, &r, &g, &b);
    *cr = select(r, *cr, fg); *cg = select(g, *cg, fg); *cb = select(b, *cb, fg);
}
#endif
