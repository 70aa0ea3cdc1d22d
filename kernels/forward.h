/* forward.h: forward shading and blending of transparent fragments (docs/transparency.md),
 * shared by the A-buffer resolve (abuffer.cl) and depth peeling (peel.cl), so both give the
 * same bits for the same fragment.
 *
 * shade_fragments(): a run of VEC pixels of one row, each lane with its own fragment (prim,
 * view depth z). The surface is surface_vec.h's -- the G-buffer resolve's own code, unquantized
 * here (no packing): barycentrics, normal (flipped on back faces), base colour × texture and
 * alpha (the material's opacity included), specular terms -- at P = eye + z·dir(pixel) on the
 * pixel's view ray as shade.cl rebuilds it (ORTHO: lighting.h's parallel rays). Lit by
 * lighting.h with the lights of the run's light-culling tile (the report's light-indexed lists
 * consumed by a forward pass; the run lies in one tile: VEC divides LIGHT_TILE), the sun and shadow maps; no SSAO:
 *     c = albedo·(ambient·occlusion + diffuse) + specular + emission (unlit: albedo; docs/materials.md);
 * with SURFACE_LAYERS, the lanes whose material has layers: layer_shading.h's shade_layered().
 * Blending, front to back per lane: acc += T·alpha·c, T *= 1 - alpha.
 * With TRANSMISSION (a scene with transmissive materials; every change below is under #if TRANSMISSION,
 * so the variant without it is today's code): the transmissive lanes' diffuse albedo (compose_gltf's
 * diffuse term, or shade_layered's diffuse_weight) × (1 - t), their transmitted weight w_c, refracted
 * lookup offsets per channel and blur level from transmission.h; blending per channel:
 * acc_c += T_c·alpha·c_c, T_c *= (1 - alpha) + w_c (exit faces of volumes skipped), early stop on
 * max T_c < TRANSMITTANCE_EPSILON; the first fragment front to back that is transmissive or has a
 * legacy refraction strength sets the lookup (store_tx: the tx planes, docs/transmission.md); the punctual
 * lights behind a transmissive lane seen through it (transmission_lights) add to its colour.
 *
 * Kernel arguments: FORWARD_PARAMS below, in that order (clrender/passes/forward.py); TRANSMISSION adds
 * `material_tx, tri_volume_scale` at its end.
 */
#ifndef CLRENDER_FORWARD_H
#define CLRENDER_FORWARD_H
#include "surface_vec.h"
#include "lighting.h"
#include "ambient.h"

#ifndef LIGHT_TILE
#define LIGHT_TILE 32             /* light-culling tile side (RenderConfig.light_tile_size) */
#endif
#ifndef TRANSMITTANCE_EPSILON
#define TRANSMITTANCE_EPSILON 1e-4f   /* fragments behind T < epsilon are not shaded */
#endif
#if LIGHT_TILE % VEC
#error "a run of VEC pixels must lie in one light tile"
#endif
#ifndef SURFACE_LAYERS
#define SURFACE_LAYERS 0          /* 1: a scene with layered materials (layer_shading.h; built only for one) */
#endif
#ifndef MULTISCATTER
#define MULTISCATTER 0
#endif
#if SURFACE_LAYERS
#include "layer_shading.h"
#define FORWARD_LAYER_PARAMS , global const MaterialExt* material_ext, int has_tangents, global const float* sheen_lut
#define FORWARD_LAYER_INIT , material_ext, has_tangents, sheen_lut
#else
#define FORWARD_LAYER_PARAMS
#define FORWARD_LAYER_INIT
#endif
#ifndef TRANSMISSION
#define TRANSMISSION 0            /* 1: a scene with transmissive materials (transmission.h; built only for one) */
#endif
#if TRANSMISSION
#include "transmission.h"
#define FORWARD_TX_PARAMS , global const MaterialTx* material_tx, global const float* tri_volume_scale
#define FORWARD_TX_INIT , material_tx, tri_volume_scale
#else
#define FORWARD_TX_PARAMS
#define FORWARD_TX_INIT
#endif

#define FORWARD_PARAMS \
    SCENE_PARAMS(prims), global const float* camera, int width, int height, float ambient, \
    global const Light* lights, int n_lights, global const int* tile_light_offsets, \
    global const int* tile_light_counts, global const int* tile_lights, int list_capacity, int light_tiles_x, \
    global const float* shadow_atlas, int atlas_stride, global const ShadowView* shadow_views, \
    float shadow_bias, float shadow_slope_bias, float shadow_normal_offset, \
    int has_sun, global const float* sun, int sun_cascades, int spot_view0, int spot_plane0, \
    int has_env, int env_background, ENV_PARAMS FORWARD_LAYER_PARAMS FORWARD_TX_PARAMS

typedef struct {
    SceneV scene;
    global const float* camera;       /* eye, F, R·tan_x, U·tan_y (float4 each) */
    int width, height;
    float ambient;
    int n_lights;
    global const int* tile_light_offsets;
    global const int* tile_light_counts;
    int list_capacity, light_tiles_x;
    LightEnv env;
    int has_env;                      /* the environment's ambient light (ambient.h) */
    EnvMaps envmaps;
#if SURFACE_LAYERS
    global const MaterialExt* material_ext;
    int has_tangents;
    global const float* sheen_lut;
#endif
#if TRANSMISSION
    global const MaterialTx* material_tx;
    global const float* tri_volume_scale;
#endif
} Forward;

/* A `Forward` from FORWARD_PARAMS. */
#define FORWARD_INIT { SCENE_INIT(prims), camera, width, height, ambient, n_lights, \
                       tile_light_offsets, tile_light_counts, list_capacity, light_tiles_x, \
                       LIGHT_ENV_INIT, has_env, ENV_INIT FORWARD_LAYER_INIT FORWARD_TX_INIT }

typedef struct {
    floatV r, g, b;    /* albedo·(ambient + diffuse) + specular, linear HDR */
    floatV a;          /* alpha in [0, 1] */
    floatV ox, oy;     /* refraction: displacement of the lookup behind, pixels (x right, y down); G with TRANSMISSION */
#if TRANSMISSION
    floatV wr, wg, wb;             /* transmitted weight per channel (0: not transmissive) */
    floatV oxr, oyr, oxb, oyb;     /* the R and B channels' lookup offsets (dispersion) */
    floatV lod;                    /* the lookup this fragment sets: >= 0 transmissive (blur level), -2 the legacy
                                      refraction strength (offset only), -1 none */
    intV exit;                     /* exit face of a volume: skipped by the blending */
#endif
} FragmentsV;

/* The lanes' fragments (prim pi, depth z) at pixels px0 + lane of row py; lanes outside
 * `active` are garbage (pi must still index a prim). */
static FragmentsV shade_fragments(const Forward* f, intV pi, floatV z, intV active, int px0, int py)
{
    const intV px = px0 + LANES;
    BaryV bary;
    const SurfaceV sf = surface_bary_at(&f->scene, pi, active, px, (intV)py, &bary);

    const float3 eye = vload4(0, f->camera).xyz, F = vload4(1, f->camera).xyz;
    const float3 Rs = vload4(2, f->camera).xyz, Us = vload4(3, f->camera).xyz;
    /* NDC less the principal point (lighting.h pixel_positions) */
    const floatV xn = (convert_floatV(px) + 0.5f) * (2.0f / (float)f->width) - (1.0f + f->camera[3]);
    const float yn = (1.0f - f->camera[7]) - ((float)py + 0.5f) * (2.0f / (float)f->height);
#if ORTHO   /* parallel rays from the eye plane (lighting.h pixel_positions) */
    const floatV dx = F.x, dy = F.y, dz = F.z;
    const floatV wx = (eye.x + xn * Rs.x + yn * Us.x) + z * F.x, wy = (eye.y + xn * Rs.y + yn * Us.y) + z * F.y;
    const floatV wz = (eye.z + xn * Rs.z + yn * Us.z) + z * F.z;
#else
    const floatV dx = F.x + xn * Rs.x + yn * Us.x, dy = F.y + xn * Rs.y + yn * Us.y, dz = F.z + xn * Rs.z + yn * Us.z;
    const floatV wx = eye.x + z * dx, wy = eye.y + z * dy, wz = eye.z + z * dz;
#endif
    const floatV inv_d = RSQRT(dx * dx + dy * dy + dz * dz);

#if BRUTE_FORCE
    const int first = 0, count = f->n_lights;
#else
    const int tile = (py / LIGHT_TILE) * f->light_tiles_x + px0 / LIGHT_TILE;
    const int first = f->tile_light_offsets[tile];
    const int count = max(min(f->tile_light_counts[tile], f->list_capacity - first), 0);
#endif
    const intV gltf = gltf_lanes(sf.mat_flags, active);
    const BrdfV m = brdf_inputs(gltf, sf.spec_i, sf.spec_p, sf.n.x, sf.n.y, sf.n.z, -dx * inv_d, -dy * inv_d,
                                -dz * inv_d);
    floatV dr = 0.0f, dg = 0.0f, db = 0.0f, sr = 0.0f, sg = 0.0f, sb = 0.0f, tr = 0.0f, tg = 0.0f, tb = 0.0f;
    accumulate_lights(&f->env, first, count, active, wx, wy, wz, sf.n.x, sf.n.y, sf.n.z,
                      -dx * inv_d, -dy * inv_d, -dz * inv_d, &m, z, px, py,
                      0, 0, VEC, 0, &dr, &dg, &db, &sr, &sg, &sb, &tr, &tg, &tb);
    FragmentsV out;
#if TRANSMISSION
    /* transmission.h: what the transmissive lanes let through; their alpha is the coverage: alpha for
     * alphaMode BLEND (MAT_TX_ALPHA), 0 or 1 at the cutoff for MASK, 1 for OPAQUE (glTF ignores alpha). */
    intV txl = select((intV)-1, GATHER_M(intV, f->scene.materials, sf.mat, tx), gltf) >= 0;
#if VEC == 1
    txl = txl ? 1 : 0;
#endif
    floatV cov = clamp(sf.a, 0.0f, 1.0f);
    TransmissionV tx;
    tx.kd = 1.0f;
    tx.wr = 0.0f; tx.wg = 0.0f; tx.wb = 0.0f;
    tx.oxr = 0.0f; tx.oyr = 0.0f; tx.oxg = 0.0f; tx.oyg = 0.0f; tx.oxb = 0.0f; tx.oyb = 0.0f;
    tx.lod = -1.0f;
    tx.exit = 0;
    tx.ur = 0.0f; tx.ug = 0.0f; tx.ub = 0.0f; tx.a2 = 1.0f; tx.ex = 0.0f; tx.ey = 0.0f; tx.ez = 0.0f;
    if (ANY(txl)) {
        intV masked = txl & ((sf.mat_flags & (int)MAT_MASK) != 0);
#if VEC == 1
        masked = masked ? 1 : 0;
#endif
        const floatV cutoff = GATHER_M(floatV, f->scene.materials, sf.mat, alpha_cutoff);
        cov = select(cov, select((floatV)1.0f, (floatV)0.0f, sf.a < cutoff), masked);
        intV opaque = txl & ((sf.mat_flags & (int)(MAT_MASK | MAT_TX_ALPHA)) == 0);
#if VEC == 1
        opaque = opaque ? 1 : 0;
#endif
        cov = select(cov, (floatV)1.0f, opaque);
        const vec3V v = { -dx * inv_d, -dy * inv_d, -dz * inv_d };
        tx = transmission_lanes(&f->scene, &bary, &sf, f->material_tx, f->tri_volume_scale,
                                GATHER_M(intV, f->scene.materials, sf.mat, tx), txl, cov, v, f->camera, f->width,
                                f->height, xn, (floatV)yn, z);
    }
#endif
    const floatV strength = GATHER_M(floatV, f->scene.materials, sf.mat, emissive_strength);
    const intV unlit = (sf.mat_flags & (int)MAT_UNLIT) != 0;
    const AmbientV amb = ambient_light(f->has_env, &f->envmaps, &m, (floatV)f->ambient, 1.0f, sf.n.x, sf.n.y, sf.n.z,
                                       -dx * inv_d, -dy * inv_d, -dz * inv_d);
    out.r = select(sf.r * (amb.dr * sf.occlusion + dr) + sr + sf.er * strength, sf.r, unlit);
    out.g = select(sf.g * (amb.dg * sf.occlusion + dg) + sg + sf.eg * strength, sf.g, unlit);
    out.b = select(sf.b * (amb.db * sf.occlusion + db) + sb + sf.eb * strength, sf.b, unlit);
    if (m.any_gltf) {                  /* brdf.h: the glTF lanes from base colour and metallic */
        floatV ar = sf.r, ag = sf.g, ab = sf.b, f0r, f0g, f0b;
        gltf_albedo_f0(gltf, sf.spec_i, &ar, &ag, &ab, &f0r, &f0g, &f0b);
#if TRANSMISSION   /* mix(diffuse, btdf, t): the diffuse albedo (compose_gltf's diffuse term alone) × (1 - t) */
        ar = select(ar, ar * tx.kd, txl); ag = select(ag, ag * tx.kd, txl); ab = select(ab, ab * tx.kd, txl);
#endif
        out.r = select(out.r, compose_gltf(ar, f0r, dr, sr, tr, amb.dr, amb.sr, amb.tr, sf.occlusion, sf.er * strength),
                       gltf);
        out.g = select(out.g, compose_gltf(ag, f0g, dg, sg, tg, amb.dg, amb.sg, amb.tg, sf.occlusion, sf.eg * strength),
                       gltf);
        out.b = select(out.b, compose_gltf(ab, f0b, db, sb, tb, amb.db, amb.sb, amb.tb, sf.occlusion, sf.eb * strength),
                       gltf);
    }
#if SURFACE_LAYERS
    const intV ext = select((intV)-1, GATHER_M(intV, f->scene.materials, sf.mat, ext), active);
    intV layered = ext >= 0;
#if VEC == 1
    layered = layered ? 1 : 0;
#endif
    if (ANY(layered)) {                /* the surface layers (docs/shading.md), no SSAO */
        const vec3V v = { -dx * inv_d, -dy * inv_d, -dz * inv_d };
        floatV lr, lg, lb;
        shade_layered(&f->scene, &bary, &sf, f->material_ext, ext, layered, f->has_tangents, f->sheen_lut, &f->env,
                      first, count, wx, wy, wz, z, v, px, py, f->has_env, &f->envmaps, f->ambient, 1.0f,
#if TRANSMISSION
                      select((floatV)1.0f, tx.kd, txl),     /* the diffuse weight 1 - t (mix with the btdf) */
#else
                      1.0f,
#endif
                      MULTISCATTER, &lr, &lg, &lb);
        out.r = select(out.r, lr, layered); out.g = select(out.g, lg, layered); out.b = select(out.b, lb, layered);
    }
#endif
#if TRANSMISSION   /* the lights behind the transmissive lanes, seen through them (transmission.h) */
    intV lit_through = txl & !tx.exit;
#if VEC == 1
    lit_through = lit_through ? 1 : 0;
#endif
    if (ANY(lit_through)) {
        const vec3V v = { -dx * inv_d, -dy * inv_d, -dz * inv_d };
        transmission_lights(&f->env, first, count, lit_through, &tx, wx, wy, wz, sf.n, v, &out.r, &out.g, &out.b);
    }
#endif
    out.a = clamp(sf.a, 0.0f, 1.0f);
    out.ox = 0.0f;
    out.oy = 0.0f;
    const floatV refraction = GATHER_M(floatV, f->scene.materials, sf.mat, refraction);
    if (ANY(active & (refraction > 0.0f))) {   /* view-space normal (x right, y up) -> pixels, y down */
        const float3 R = normalize(Rs), U = normalize(Us);
        const floatV k = refraction * (float)f->height;
        out.ox = (sf.n.x * R.x + sf.n.y * R.y + sf.n.z * R.z) * k;
        out.oy = -(sf.n.x * U.x + sf.n.y * U.y + sf.n.z * U.z) * k;
    }
#if TRANSMISSION   /* the lookup: transmissive lanes their refraction, others their legacy strength's offset */
    intV legacy = active & (refraction > 0.0f) & !txl;
#if VEC == 1
    legacy = legacy ? 1 : 0;
#endif
    out.a = cov;
    out.wr = tx.wr; out.wg = tx.wg; out.wb = tx.wb;
    out.ox = select(out.ox, tx.oxg, txl); out.oy = select(out.oy, tx.oyg, txl);
    out.oxr = select(out.ox, tx.oxr, txl); out.oyr = select(out.oy, tx.oyr, txl);
    out.oxb = select(out.ox, tx.oxb, txl); out.oyb = select(out.oy, tx.oyb, txl);
    out.lod = select(select((floatV)-1.0f, (floatV)-2.0f, legacy), tx.lod, txl);
    out.exit = tx.exit;
#endif
    return out;
}

#if TRANSMISSION
/* Front-to-back blending per channel of the active lanes (transmission.h): acc_c += T_c·alpha·c_c,
 * T_c *= (1 - alpha) + w_c; exit faces of volumes are skipped. */
static inline void blend_under_tx(FragmentsV fr, intV active, floatV* ar, floatV* ag, floatV* ab, floatV* tr,
                                  floatV* tg, floatV* tb)
{
    const intV on = active & !fr.exit;
    *ar = select(*ar, *ar + (*tr * fr.a) * fr.r, on);
    *ag = select(*ag, *ag + (*tg * fr.a) * fr.g, on);
    *ab = select(*ab, *ab + (*tb * fr.a) * fr.b, on);
    *tr = select(*tr, *tr * ((1.0f - fr.a) + fr.wr), on);
    *tg = select(*tg, *tg * ((1.0f - fr.a) + fr.wg), on);
    *tb = select(*tb, *tb * ((1.0f - fr.a) + fr.wb), on);
}

/* The lookup state of the lanes `active`: the first fragment front to back that sets one (fr.lod != -1)
 * sets it, later ones keep it (state lod < -0.5: not set yet). */
static inline void take_lookup(FragmentsV fr, intV active, floatV* lod, floatV* ox, floatV* oy, floatV* oxr,
                               floatV* oyr, floatV* oxb, floatV* oyb)
{
    intV sets = active & (*lod < -0.5f) & ((fr.lod < -1.5f) | (fr.lod > -0.5f));
#if VEC == 1
    sets = sets ? 1 : 0;
#endif
    *lod = select(*lod, fr.lod, sets);
    *ox = select(*ox, fr.ox, sets); *oy = select(*oy, fr.oy, sets);
    *oxr = select(*oxr, fr.oxr, sets); *oyr = select(*oyr, fr.oyr, sets);
    *oxb = select(*oxb, fr.oxb, sets); *oyb = select(*oyb, fr.oyb, sets);
}

/* Stores lane l's transmission planes at pixel q (TX_PLANES = 9 planes of npix, clrender/passes/forward.py):
 * T_r, T_g, T_b, lod, offset R (x, y), offset B (x, y), the nearest fragment's depth (-1: not transmissive). */
static inline void store_tx(global float* tx_planes, int npix, int q, int l, floatV tr, floatV tg, floatV tb,
                            floatV lod, floatV oxr, floatV oyr, floatV oxb, floatV oyb, floatV near_z)
{
    tx_planes[q] = LANE_F(tr, l);
    tx_planes[npix + q] = LANE_F(tg, l);
    tx_planes[2 * npix + q] = LANE_F(tb, l);
    tx_planes[3 * npix + q] = LANE_F(lod, l);
    tx_planes[4 * npix + q] = LANE_F(oxr, l);
    tx_planes[5 * npix + q] = LANE_F(oyr, l);
    tx_planes[6 * npix + q] = LANE_F(oxb, l);
    tx_planes[7 * npix + q] = LANE_F(oyb, l);
    tx_planes[8 * npix + q] = LANE_F(near_z, l);
}
#endif

/* Front-to-back "under" blending of the active lanes: acc += T·alpha·c, T *= 1 - alpha. */
static inline void blend_under(FragmentsV fr, intV active, floatV* ar, floatV* ag, floatV* ab, floatV* t)
{
    const floatV t_alpha = *t * fr.a;
    *ar = select(*ar, *ar + t_alpha * fr.r, active);
    *ag = select(*ag, *ag + t_alpha * fr.g, active);
    *ab = select(*ab, *ab + t_alpha * fr.b, active);
    *t = select(*t, *t * (1.0f - fr.a), active);
}

/* Stores lane l of the blended layers at pixel q: colour planes, transmittance, refraction offset,
 * and the nearest fragment's triangle id (int bits, -1: none; Frame.object_id's nearest rule). */
static inline void store_layers(global float* layers, int npix, int q, int l, floatV ar, floatV ag, floatV ab,
                                floatV t, floatV ox, floatV oy, intV nearest)
{
    layers[q] = LANE_F(ar, l);
    layers[npix + q] = LANE_F(ag, l);
    layers[2 * npix + q] = LANE_F(ab, l);
    layers[3 * npix + q] = LANE_F(t, l);
    layers[4 * npix + q] = LANE_F(ox, l);
    layers[5 * npix + q] = LANE_F(oy, l);
    layers[6 * npix + q] = as_float(LANE_I(nearest, l));
}
#endif
