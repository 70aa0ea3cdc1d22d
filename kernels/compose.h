/* compose.h: a lit pixel's colour from the light sums and its material, the last step of every
 * pipeline (shade.cl, material.cl, forward_shade.cl) and of transparent fragments (forward.h).
 *
 * The report's "global multiply" for Blinn-Phong lanes: albedo·(ambient·occlusion + D) + S +
 * emission; the glTF BRDF's for the others (brdf.h): albedo·(1 − F0)·(ad·occlusion + D) +
 * F0·(as·occlusion + S) + (at·occlusion + T) + emission, where (ad, as, at) is the ambient light:
 * the constant `scene.ambient` (ad alone) or the environment's split-sum terms (ambient.h),
 * already multiplied by SSAO where it runs. Unlit lanes: their albedo.
 */
#ifndef CLRENDER_COMPOSE_H
#define CLRENDER_COMPOSE_H
#include "brdf.h"

/* The report's global multiply with the material's extras: albedo·(ambient·ao + diffuse) +
 * specular + emission; unlit lanes: the albedo alone. */
static inline floatV compose_extras(floatV albedo, floatV ambient_ao, floatV diffuse, floatV specular, floatV emission,
                                    floatV occlusion, intV unlit)
{
    return select(albedo * (ambient_ao * occlusion + diffuse) + specular + emission, albedo, unlit);
}
/* The ambient light of a run of lanes: diffuse light per channel (what albedo multiplies) and,
 * on glTF lanes with an environment, the split-sum specular terms. */
typedef struct {
    floatV dr, dg, db;
    floatV sr, sg, sb, tr, tg, tb;
} AmbientV;

/* The constant ambient term (no environment): a·(1, 1, 1), no specular. */
static inline AmbientV constant_ambient(floatV a)
{
    AmbientV amb = { a, a, a, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f };
    return amb;
}

/* The lanes' HDR colour; fg: foreground lanes (the others get 0). extras: emission (er, eg, eb),
 * occlusion and unlit are the material's (surface_extras); otherwise none. (ar, ag, ab) is the
 * decoded albedo word: diffuse albedo on Blinn-Phong lanes, base colour on glTF lanes (whose
 * metallic is `metallic`). The light sums (d, s, t) are brdf.h's. */
static inline void compose_lit(const BrdfV* m, intV fg, floatV ar, floatV ag, floatV ab, floatV metallic,
                               const AmbientV* amb, int extras, floatV er, floatV eg, floatV eb, floatV occlusion,
                               intV unlit, floatV dr, floatV dg, floatV db, floatV sr, floatV sg, floatV sb,
                               floatV tr, floatV tg, floatV tb, floatV* cr, floatV* cg, floatV* cb)
{
    if (extras) {
        *cr = select((floatV)0.0f, compose_extras(ar, amb->dr, dr, sr, er, occlusion, unlit), fg);
        *cg = select((floatV)0.0f, compose_extras(ag, amb->dg, dg, sg, eg, occlusion, unlit), fg);
        *cb = select((floatV)0.0f, compose_extras(ab, amb->db, db, sb, eb, occlusion, unlit), fg);
    } else {
        *cr = select((floatV)0.0f, ar * (amb->dr + dr) + sr, fg);
        *cg = select((floatV)0.0f, ag * (amb->dg + dg) + sg, fg);
        *cb = select((floatV)0.0f, ab * (amb->db + db) + sb, fg);
    }
    if (!m->any_gltf) return;
    floatV f0r, f0g, f0b;
    gltf_albedo_f0(m->gltf, metallic, &ar, &ag, &ab, &f0r, &f0g, &f0b);
    if (!extras) {
        er = 0.0f; eg = 0.0f; eb = 0.0f;
        occlusion = 1.0f;
    }
    const intV on = m->gltf & fg;
    *cr = select(*cr, compose_gltf(ar, f0r, dr, sr, tr, amb->dr, amb->sr, amb->tr, occlusion, er), on);
    *cg = select(*cg, compose_gltf(ag, f0g, dg, sg, tg, amb->dg, amb->sg, amb->tg, occlusion, eg), on);
    *cb = select(*cb, compose_gltf(ab, f0b, db, sb, tb, amb->db, amb->sb, amb->tb, occlusion, eb), on);
}
#endif
