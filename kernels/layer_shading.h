/* layer_shading.h: the surface layers of a run of VEC lanes, for the opaque pixels (surface_layers.cl)
 * and the transparent fragments (forward.h with SURFACE_LAYERS): the layer parameters read from the
 * lanes' MaterialExt records and layer textures (the same uv sets, transforms and trilinear
 * filtering as material_eval.h's base slots), the geometric frame the clearcoat normal map and
 * the anisotropy direction live in, and the light walk of layered_brdf.h's model with lighting.h's
 * falloff, spot cone and shadow maps (docs/shading.md "Surface layers").
 */
#ifndef CLRENDER_LAYER_SHADING_H
#define CLRENDER_LAYER_SHADING_H
#include "structs.h"
#include "lighting.h"
#include "surface_vec.h"
#include "layered_brdf.h"

/* Layer slot `slot` of the lanes `on` whose MaterialExt `ext` has a texture there (*hit), read as
 * material_eval.h's sample_slot reads a base slot (uv set, KHR_texture_transform, trilinear LOD
 * from the transformed derivatives); (1, 1, 1, 1) elsewhere. */
static rgbaV sample_layer_slot_tex(const SceneV* sc, const BaryV* b, global const MaterialExt* ext_records, intV ext,
                                   int slot, intV tex, intV active);
/* (the test for a texture inline, the sampling out of line: most layer slots of a run have none) */
static inline VINLINE rgbaV sample_layer_slot(const SceneV* sc, const BaryV* b, global const MaterialExt* ext_records,
                                              intV ext, int slot, intV on, intV* hit)
{
    const intV tex = GATHER_MS(intV, ext_records, ext, slots[slot].texture);
    intV active = on & (tex >= 0);
#if VEC == 1
    active = active ? 1 : 0;
#endif
    *hit = active;
    if (!ANY(active)) return (rgbaV){ 1.0f, 1.0f, 1.0f, 1.0f };
    return sample_layer_slot_tex(sc, b, ext_records, ext, slot, tex, active);
}

static rgbaV sample_layer_slot_tex(const SceneV* sc, const BaryV* b, global const MaterialExt* ext_records, intV ext,
                                   int slot, intV tex, intV active)
{
    rgbaV out = { 1.0f, 1.0f, 1.0f, 1.0f };
    FootprintV fp;
    const rgbaV t = sample_uv_set(sc, b, tex, GATHER_MS(intV, ext_records, ext, slots[slot].texcoord),
                                  GATHER_MS(floatV, ext_records, ext, slots[slot].uv[0]),
                                  GATHER_MS(floatV, ext_records, ext, slots[slot].uv[1]),
                                  GATHER_MS(floatV, ext_records, ext, slots[slot].uv[2]),
                                  GATHER_MS(floatV, ext_records, ext, slots[slot].uv[3]),
                                  GATHER_MS(floatV, ext_records, ext, slots[slot].uv[4]),
                                  GATHER_MS(floatV, ext_records, ext, slots[slot].uv[5]), active, &fp);
    out.r = select(out.r, t.r, active); out.g = select(out.g, t.g, active);
    out.b = select(out.b, t.b, active); out.a = select(out.a, t.a, active);
    return out;
}

static inline vec3V normalize3V(vec3V a, vec3V fallback)
{
    const floatV l2 = dot3V(a, a);
    const intV ok = l2 > 1e-20f;
    const floatV k = RSQRT(fmax(l2, 1e-30f));
    vec3V r = { select(fallback.x, a.x * k, ok), select(fallback.y, a.y * k, ok), select(fallback.z, a.z * k, ok) };
    return r;
}

static inline vec3V cross3V(vec3V a, vec3V b)
{
    vec3V r = { a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x };
    return r;
}

/* The unit geometric frame of the lanes: Ng (interpolated vertex normal before any map, flipped on
 * back faces like the shading normal), T (the vertex tangent made orthogonal to Ng; any
 * perpendicular without tangents) and Bt = cross(Ng, T)·handedness. */
static void geometric_frame(const SceneV* sc, const BaryV* b, const SurfaceV* sf, int has_tangents,
                            vec3V* ng, vec3V* t, vec3V* bt)
{
    const vec3V n0 = interp3(gather3(sc->normals, b->i0), gather3(sc->normals, b->i1), gather3(sc->normals, b->i2),
                             b->c0, b->c1, b->c2);
    vec3V n = normalize3V(n0, sf->n);
    const intV back = (sf->flags & (int)PRIM_BACKFACE) != 0;
    n.x = select(n.x, -n.x, back); n.y = select(n.y, -n.y, back); n.z = select(n.z, -n.z, back);
    *ng = n;
    /* any perpendicular: the axis least aligned with n, crossed */
    const vec3V ax = { select((floatV)1.0f, (floatV)0.0f, fabs(n.x) > 0.9f), select((floatV)0.0f, (floatV)1.0f,
                       fabs(n.x) > 0.9f), (floatV)0.0f };
    vec3V tt = cross3V(ax, n);
    floatV hand = 1.0f;
    if (has_tangents) {
        global const float* tangents = sc->tangents;
        const intV k0 = 4 * b->i0, k1 = 4 * b->i1, k2 = 4 * b->i2;
#define TAN(c) (b->c0 * GATHER_FS(tangents, k0 + c) + b->c1 * GATHER_FS(tangents, k1 + c) + b->c2 * GATHER_FS(tangents, k2 + c))
        const vec3V tv = { TAN(0), TAN(1), TAN(2) };
        hand = select((floatV)1.0f, (floatV)-1.0f, TAN(3) < 0.0f);
#undef TAN
        const floatV nt = dot3V(n, tv);
        const vec3V ortho = { tv.x - n.x * nt, tv.y - n.y * nt, tv.z - n.z * nt };
        const intV ok = dot3V(ortho, ortho) > 1e-12f;
        tt.x = select(tt.x, ortho.x, ok); tt.y = select(tt.y, ortho.y, ok); tt.z = select(tt.z, ortho.z, ok);
    }
    *t = normalize3V(tt, tt);
    const vec3V bb = cross3V(n, *t);
    bt->x = bb.x * hand; bt->y = bb.y * hand; bt->z = bb.z * hand;
}

/* The layer parameters of the lanes `on` (ext: their MaterialExt index) and layered_prepare(); dw: the
 * diffuse BSDF's weight (1 - transmission). */
static LayeredV layer_inputs(const SceneV* sc, const BaryV* b, global const MaterialExt* x, intV ext, intV on,
                             const SurfaceV* sf, int has_tangents, vec3V v, floatV dw, global const float* sheen_lut)
{
    vec3V ng, t, bt;
    geometric_frame(sc, b, sf, has_tangents, &ng, &t, &bt);
    intV hit;
    rgbaV s;
#define XF(m) GATHER_MS(floatV, x, ext, m)
    floatV sw = XF(specular_factor);
    s = sample_layer_slot(sc, b, x, ext, XSLOT_SPECULAR, on, &hit);
    sw *= s.a;
    floatV scr = XF(specular_color[0]), scg = XF(specular_color[1]), scb = XF(specular_color[2]);
    s = sample_layer_slot(sc, b, x, ext, XSLOT_SPECULAR_COLOR, on, &hit);
    scr *= s.r; scg *= s.g; scb *= s.b;
    floatV cc = XF(clearcoat), ccr = XF(clearcoat_roughness);
    cc *= sample_layer_slot(sc, b, x, ext, XSLOT_CLEARCOAT, on, &hit).r;
    ccr *= sample_layer_slot(sc, b, x, ext, XSLOT_CLEARCOAT_ROUGHNESS, on, &hit).g;
    vec3V ncc = ng;                         /* the coat does not take the base normal map */
    s = sample_layer_slot(sc, b, x, ext, XSLOT_CLEARCOAT_NORMAL, on, &hit);
    if (ANY(hit)) {
        const floatV scale = XF(clearcoat_normal_scale);
        vec3V tn = { (2.0f * s.r - 1.0f) * scale, (2.0f * s.g - 1.0f) * scale, 2.0f * s.b - 1.0f };
        tn = normalize3V(tn, tn);
        const vec3V m = { tn.x * t.x + tn.y * bt.x + tn.z * ng.x, tn.x * t.y + tn.y * bt.y + tn.z * ng.y,
                          tn.x * t.z + tn.y * bt.z + tn.z * ng.z };
        const vec3V mm = normalize3V(m, ng);
        ncc.x = select(ng.x, mm.x, hit); ncc.y = select(ng.y, mm.y, hit); ncc.z = select(ng.z, mm.z, hit);
    }
    floatV shr = XF(sheen_color[0]), shg = XF(sheen_color[1]), shb = XF(sheen_color[2]), sh_rough = XF(sheen_roughness);
    s = sample_layer_slot(sc, b, x, ext, XSLOT_SHEEN_COLOR, on, &hit);
    shr *= s.r; shg *= s.g; shb *= s.b;
    sh_rough *= sample_layer_slot(sc, b, x, ext, XSLOT_SHEEN_ROUGHNESS, on, &hit).a;
    floatV irid = XF(iridescence);
    irid *= sample_layer_slot(sc, b, x, ext, XSLOT_IRIDESCENCE, on, &hit).r;
    floatV thickness = XF(iridescence_thickness_max);
    s = sample_layer_slot(sc, b, x, ext, XSLOT_IRIDESCENCE_THICKNESS, on, &hit);
    thickness = select(thickness, XF(iridescence_thickness_min) * (1.0f - s.g) + thickness * s.g, hit);
    floatV aniso = XF(anisotropy_strength);
    s = sample_layer_slot(sc, b, x, ext, XSLOT_ANISOTROPY, on, &hit);
    aniso = clamp(aniso * s.b, 0.0f, 1.0f);
    const floatV dx = select((floatV)1.0f, 2.0f * s.r - 1.0f, hit), dy = select((floatV)0.0f, 2.0f * s.g - 1.0f, hit);
    const floatV rc = XF(anisotropy_cos), rs = XF(anisotropy_sin);
    const floatV ax = rc * dx - rs * dy, ay = rs * dx + rc * dy;   /* counter-clockwise in tangent space */
    const vec3V at = { t.x * ax + bt.x * ay, t.y * ax + bt.y * ay, t.z * ax + bt.z * ay };
    const floatV ior = XF(ior), irid_ior = XF(iridescence_ior);
    floatV dt = XF(diffuse_transmission);
    dt *= sample_layer_slot(sc, b, x, ext, XSLOT_DIFFUSE_TRANSMISSION, on, &hit).a;
    floatV dtr = XF(diffuse_transmission_color[0]), dtg = XF(diffuse_transmission_color[1]);
    floatV dtb = XF(diffuse_transmission_color[2]);
    s = sample_layer_slot(sc, b, x, ext, XSLOT_DIFFUSE_TRANSMISSION_COLOR, on, &hit);
    dtr *= s.r; dtg *= s.g; dtb *= s.b;
#undef XF
    return layered_prepare(on, sf->n, ng, ncc, at, v, sf->r, sf->g, sf->b, sf->spec_i, sf->spec_p, ior, sw,
                           scr, scg, scb, clamp(cc, 0.0f, 1.0f), clamp(ccr, 0.0f, 1.0f), shr, shg, shb,
                           clamp(sh_rough, 0.0f, 1.0f), clamp(irid, 0.0f, 1.0f), irid_ior, thickness, aniso,
                           clamp(dt, 0.0f, 1.0f), dtr, dtg, dtb, dw, sheen_lut);
}

/* Σ over the tile's lights and the sun of layered_light(), with lighting.h's falloff, spot cone
 * and shadow visibility; for the lanes a light reaches from behind through the surface (dt > 0,
 * N·L < 0) the shadow is looked up a second time from that side (the flipped normal: the normal
 * offset and slope bias of the side the light enters). */
static void layered_lights(const LightEnv* env, int first, int count, const LayeredV* s, intV on,
                           floatV px, floatV py_, floatV pz, floatV depth, intV pix_x, int pix_y,
                           global const float* sheen_lut, floatV* r, floatV* g, floatV* b)
{
    const floatV nx = s->n.x, ny = s->n.y, nz = s->n.z;
    const intV through = on & (s->dt > 0.0f);       /* lanes that let light through */
    for (int k = 0; k < count; ++k) {
        floatV lx, ly, lz, atten;
        intV near_enough;
        const Light lt = light_at(env, first, k, on, px, py_, pz, &near_enough, &lx, &ly, &lz, &atten);
        if (!ANY(near_enough)) continue;
        floatV atten_b = s->any_dt ? select((floatV)0.0f, atten, through) : (floatV)0.0f;   /* from behind */
#if SHADOWS
        if (lt.shadow >= 0) {
            const intV lit = near_enough & (atten > 0.0f);
            const floatV ndotl = nx * lx + ny * ly + nz * lz;
            global const ShadowView* vw = env->views + env->spot_view0 + lt.shadow;
            if (s->any_dt && ANY(lit & through & (ndotl < 0.0f)))
                atten_b *= shadow_visibility(&env->sp, vw, px, py_, pz, -nx, -ny, -nz, -ndotl, pix_x, pix_y);
            if (ANY(lit))
                atten *= shadow_visibility(&env->sp, vw, px, py_, pz, nx, ny, nz, ndotl, pix_x, pix_y);
        }
#endif
        if (!ANY((atten > 0.0f) | (atten_b > 0.0f))) continue;
        layered_light(s, sheen_lut, lx, ly, lz, atten * lt.color[0], atten * lt.color[1], atten * lt.color[2],
                      atten_b * lt.color[0], atten_b * lt.color[1], atten_b * lt.color[2], r, g, b);
    }
    if (env->has_sun) {
        global const float* sun = env->sun;
        const floatV lx = -sun[0], ly = -sun[1], lz = -sun[2];
        floatV vis = 1.0f, vis_b = 1.0f;
#if SHADOWS
        if (env->sun_cascades > 0) {
            const floatV ndotl = nx * lx + ny * ly + nz * lz;
            const intV back = through & (ndotl < 0.0f);
            const int any_back = s->any_dt && ANY(back);
            intV cascade = 0;
            for (int c = 0; c + 1 < env->sun_cascades; ++c)
                cascade += select((intV)0, (intV)1, depth > env->views[c].split);
            for (int c = 0; c < env->sun_cascades; ++c) {
                const intV mine = on & (cascade == c);
                if (ANY(mine))
                    vis = select(vis, shadow_visibility(&env->sp, env->views + c, px, py_, pz, nx, ny, nz, ndotl,
                                                        pix_x, pix_y), mine);
                if (any_back && ANY(mine & back))
                    vis_b = select(vis_b, shadow_visibility(&env->sp, env->views + c, px, py_, pz, -nx, -ny, -nz,
                                                            -ndotl, pix_x, pix_y), mine & back);
            }
        }
#endif
        layered_light(s, sheen_lut, lx, ly, lz, vis * sun[3], vis * sun[4], vis * sun[5], vis_b * sun[3],
                      vis_b * sun[4], vis_b * sun[5], r, g, b);
    }
}

/* The layered colour of the lanes `on` (ext: their MaterialExt index): Σ lights (the tile's
 * `count` from `first`, the sun) + ambient·occlusion·ao + emission·(1 − cc·Fc). P on the view ray
 * at view depth `depth`, v towards the eye. diffuse_weight: what weights the diffuse BSDF
 * (reflected and transmitted), 1 − transmission for KHR_materials_transmission (forward.h), else 1. */
static void shade_layered(const SceneV* sc, const BaryV* bary, const SurfaceV* sf, global const MaterialExt* x,
                          intV ext, intV on, int has_tangents, global const float* sheen_lut,
                          const LightEnv* env, int first, int count, floatV px, floatV py_, floatV pz, floatV depth,
                          vec3V v, intV pix_x, int pix_y, int has_env, const EnvMaps* envmaps, float ambient,
                          floatV ao, floatV diffuse_weight, int multiscatter, floatV* cr, floatV* cg, floatV* cb)
{
    const LayeredV s = layer_inputs(sc, bary, x, max(ext, 0), on, sf, has_tangents, v, diffuse_weight, sheen_lut);
    floatV r = 0.0f, g = 0.0f, b = 0.0f;
    layered_lights(env, first, count, &s, on, px, py_, pz, depth, pix_x, pix_y, sheen_lut, &r, &g, &b);
    floatV ar = 0.0f, ag = 0.0f, ab = 0.0f;        /* layered_ambient adds */
    layered_ambient(&s, has_env, envmaps, ambient, ao, sf->occlusion, multiscatter, &ar, &ag, &ab);
    const floatV strength = GATHER_MS(floatV, sc->materials, sf->mat, emissive_strength) * layered_emission_scale(&s);
    *cr = r + ar + sf->er * strength; *cg = g + ag + sf->eg * strength; *cb = b + ab + sf->eb * strength;
}
#endif
