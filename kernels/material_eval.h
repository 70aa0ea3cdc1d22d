/* material_eval.h: a material evaluated at VEC lanes' surface points (docs/materials.md),
 * included by surface_vec.h; the types it fills are surface_types.h's.
 *
 * Per lane: base colour = factor × vertex colour × base texture; metallic-roughness
 * (MAT_METALLIC_ROUGHNESS) mapped into the report's terms: albedo = base·(1 − m), specular
 * intensity = mix(0.04, luminance(base), m), power = clamp(2/r⁴ − 2, 1, 2048), except on materials
 * shaded with the glTF BRDF (MAT_GLTF_BRDF), which keep base colour, metallic and roughness in the
 * albedo, specular intensity and power fields (brdf.h, clrender/abi/gbuffer.py); a tangent-space
 * normal map rotating the unit normal through the Gram-Schmidt TBN frame; occlusion =
 * 1 + strength·(R − 1); emissive = factor × texture; unlit: albedo = base, no specular.
 * Every texture slot reads its own uv set through its KHR_texture_transform matrix, with the
 * LOD from the transformed derivatives. A slot is sampled only where a lane's material has a
 * texture there (ANY over the run), so scenes without a feature pay a gather of the slot's
 * texture index and nothing else.
 */
#ifndef CLRENDER_MATERIAL_EVAL_H
#define CLRENDER_MATERIAL_EVAL_H

#include "surface_types.h"     /* SceneV, BaryV, SurfaceV, vec3V */
#include "texture_vec.h"       /* trilinearV, FootprintV */
#include "brdf.h"              /* DIELECTRIC_F0, MIN_ROUGHNESS (clrender/scene/model.py), gltf_lanes */

#ifndef SURFACE_TEXTURES
#define SURFACE_TEXTURES 1        /* 0: base colour = material factor only, no texture read */
#endif
#ifndef SURFACE_EXTRAS
#define SURFACE_EXTRAS 1          /* 0: emissive and occlusion left at their factors, no texture read */
#endif

/* The lanes `on` whose material has a texture in slot `slot` (*tex: its index, per lane). */
static inline intV slot_lanes(const SceneV* sc, intV mat, int slot, intV on, intV* tex)
{
    *tex = GATHER_MS(intV, sc->materials, mat, slots[slot].texture);
    intV active = on & (*tex >= 0);
#if VEC == 1
    active = active ? 1 : 0;
#endif
    return active;
}

/* Texture `tex` (per lane) sampled trilinearly where `active` through uv set `texcoord` and the
 * KHR_texture_transform matrix m0..m5 (uv' = (m0 u + m1 v + m2, m3 u + m4 v + m5)), the LOD from
 * the transformed screen derivatives; its footprint to *fp. Shared by the base slots and the
 * surface layers' slots (layer_shading.h). */
static inline rgbaV sample_uv_set(const SceneV* sc, const BaryV* b, intV tex, intV texcoord, floatV m0, floatV m1,
                                  floatV m2, floatV m3, floatV m4, floatV m5, intV active, FootprintV* fp)
{
    const intV set = texcoord * sc->n_vertices;
    const intV j0 = 2 * (set + b->i0), j1 = 2 * (set + b->i1), j2 = 2 * (set + b->i2);
    global const float* uvs = sc->uvs;
    const floatV u0 = GATHER_FS(uvs, j0), v0 = GATHER_FS(uvs, j0 + 1);
    const floatV u1 = GATHER_FS(uvs, j1), v1 = GATHER_FS(uvs, j1 + 1);
    const floatV u2 = GATHER_FS(uvs, j2), v2 = GATHER_FS(uvs, j2 + 1);
    const floatV u = b->c0 * u0 + b->c1 * u1 + b->c2 * u2, v = b->c0 * v0 + b->c1 * v1 + b->c2 * v2;
    const floatV dux = (b->c1x - b->c1) * (u1 - u0) + (b->c2x - b->c2) * (u2 - u0);
    const floatV dvx = (b->c1x - b->c1) * (v1 - v0) + (b->c2x - b->c2) * (v2 - v0);
    const floatV duy = (b->c1y - b->c1) * (u1 - u0) + (b->c2y - b->c2) * (u2 - u0);
    const floatV dvy = (b->c1y - b->c1) * (v1 - v0) + (b->c2y - b->c2) * (v2 - v0);
    const floatV tu = m0 * u + m1 * v + m2, tv = m3 * u + m4 * v + m5;
    return trilinearV(sc->texels, sc->srgb_lut, sc->tex_infos, sc->tex_levels, max(tex, 0), active, tu, tv,
                      m0 * dux + m1 * dvx, m3 * dux + m4 * dvx, m0 * duy + m1 * dvy, m3 * duy + m4 * dvy, fp);
}

/* Texture slot `slot` of materials mat, sampled where `on` and the slot has a texture (*hit
 * set there); (1, 1, 1, 1) elsewhere. Its footprint goes to *fp_out (when not NULL) for the
 * slots that share it (sample_slot_shared). */
static rgbaV sample_slot(const SceneV* sc, const BaryV* b, intV mat, int slot, intV on, intV* hit,
                         FootprintV* fp_out)
{
    global const Material* materials = sc->materials;
    intV tex;
    const intV active = slot_lanes(sc, mat, slot, on, &tex);
    *hit = active;
    rgbaV out = { 1.0f, 1.0f, 1.0f, 1.0f };
    if (!ANY(active)) return out;
    FootprintV fp;
    const rgbaV t = sample_uv_set(sc, b, tex, GATHER_MS(intV, materials, mat, slots[slot].texcoord),
                                  GATHER_MS(floatV, materials, mat, slots[slot].uv[0]),
                                  GATHER_MS(floatV, materials, mat, slots[slot].uv[1]),
                                  GATHER_MS(floatV, materials, mat, slots[slot].uv[2]),
                                  GATHER_MS(floatV, materials, mat, slots[slot].uv[3]),
                                  GATHER_MS(floatV, materials, mat, slots[slot].uv[4]),
                                  GATHER_MS(floatV, materials, mat, slots[slot].uv[5]), active, &fp);
    if (fp_out) *fp_out = fp;
    out.r = select(out.r, t.r, active); out.g = select(out.g, t.g, active);
    out.b = select(out.b, t.b, active); out.a = select(out.a, t.a, active);
    return out;
}

/* Texture slot `slot` as sample_slot gives it, read through the base colour's footprint `base`
 * where the host found it the same (MAT_SHARES(slot): the same mip chain sizes, wrap modes, uv
 * set and transform, and the slot's usual colour space: clrender/render/scene_upload.py), so only its texels are
 * fetched: the same bits for a fraction of the work. Falls back to sample_slot unless every lane
 * with a texture in the slot shares. */
static rgbaV sample_slot_shared(const SceneV* sc, const BaryV* b, intV mat, intV flags, int slot, intV on,
                                const FootprintV* base, intV* hit)
{
    intV tex;
    const intV active = slot_lanes(sc, mat, slot, on, &tex);
    *hit = active;
    rgbaV out = { 1.0f, 1.0f, 1.0f, 1.0f };
    if (!ANY(active)) return out;
    intV shares = active & base->active & ((flags & (int)MAT_SHARES(slot)) != 0);
#if VEC == 1
    shares = shares ? 1 : 0;
#endif
    if (ANY(active & ~shares)) return sample_slot(sc, b, mat, slot, on, hit, 0);
    intV offset, w, h;
    gather_level(sc->tex_levels, GATHER_MS(intV, sc->tex_infos, max(tex, 0), first_level), &offset, &w, &h);
    FootprintV fp = *base;
    fp.active = active;
    fp.active_b = active & base->active_b;
    const int linear = slot != SLOT_EMISSIVE;     /* glTF: only base colour and emissive are sRGB */
    const rgbaV t = footprint_fetch(sc->texels, sc->srgb_lut, (intV)LUT_SRGB, linear, &fp, offset - base->base);
    out.r = select(out.r, t.r, active); out.g = select(out.g, t.g, active);
    out.b = select(out.b, t.b, active); out.a = select(out.a, t.a, active);
    return out;
}

/* Rotates the unit normal sf->n by the normal map of the lanes `on` whose material has one. */
static void apply_normal_map(const SceneV* sc, const BaryV* b, intV mat, intV flags, intV on, const FootprintV* base,
                             SurfaceV* sf)
{
    intV hit;
    const rgbaV t = sample_slot_shared(sc, b, mat, flags, SLOT_NORMAL, on, base, &hit);
    if (!ANY(hit)) return;
    const floatV scale = GATHER_MS(floatV, sc->materials, mat, normal_scale);
    const floatV tx = (2.0f * t.r - 1.0f) * scale, ty = (2.0f * t.g - 1.0f) * scale, tz = 2.0f * t.b - 1.0f;
    global const float* tangents = sc->tangents;
    const intV k0 = 4 * b->i0, k1 = 4 * b->i1, k2 = 4 * b->i2;
#define TAN(c) (b->c0 * GATHER_FS(tangents, k0 + c) + b->c1 * GATHER_FS(tangents, k1 + c) + b->c2 * GATHER_FS(tangents, k2 + c))
    vec3V T = { TAN(0), TAN(1), TAN(2) };
    const floatV hand = TAN(3);
#undef TAN
    const vec3V N = sf->n;
    const floatV nt = dot3V(N, T);                   /* Gram-Schmidt: T orthogonal to N, unit */
    T.x -= N.x * nt; T.y -= N.y * nt; T.z -= N.z * nt;
    const floatV t2 = dot3V(T, T);
    const floatV inv_t = RSQRT(fmax(t2, 1e-30f));
    T.x *= inv_t; T.y *= inv_t; T.z *= inv_t;
    const floatV sign = select((floatV)1.0f, (floatV)-1.0f, hand < 0.0f);
    const vec3V B = { (N.y * T.z - N.z * T.y) * sign, (N.z * T.x - N.x * T.z) * sign, (N.x * T.y - N.y * T.x) * sign };
    vec3V n = { tx * T.x + ty * B.x + tz * N.x, tx * T.y + ty * B.y + tz * N.y, tx * T.z + ty * B.z + tz * N.z };
    const floatV n2 = dot3V(n, n);
    const intV use = hit & (t2 > 1e-12f) & (n2 > 1e-12f);   /* a degenerate tangent or map texel: no map */
    const floatV inv_n = RSQRT(fmax(n2, 1e-30f));
    sf->n.x = select(N.x, n.x * inv_n, use); sf->n.y = select(N.y, n.y * inv_n, use);
    sf->n.z = select(N.z, n.z * inv_n, use);
}

/* Fills sf's colours, alpha, specular terms, emissive and occlusion, and applies the normal map,
 * for the lanes fg (sf->mat, sf->n and the barycentrics b already set). */
static void evaluate_material(const SceneV* sc, const BaryV* b, intV fg, SurfaceV* sf)
{
    global const Material* materials = sc->materials;
    const intV mat = sf->mat;
    floatV cr = GATHER_MS(floatV, materials, mat, base_color[0]);
    floatV cg = GATHER_MS(floatV, materials, mat, base_color[1]);
    floatV cb = GATHER_MS(floatV, materials, mat, base_color[2]);
    floatV ca = GATHER_MS(floatV, materials, mat, base_color[3]);
    if (sc->has_colors) {                            /* COLOR_0 multiplies base colour and alpha */
        global const float* colors = sc->colors;
        const intV k0 = 4 * b->i0, k1 = 4 * b->i1, k2 = 4 * b->i2;
#define COL(c) (b->c0 * GATHER_FS(colors, k0 + c) + b->c1 * GATHER_FS(colors, k1 + c) + b->c2 * GATHER_FS(colors, k2 + c))
        cr *= COL(0); cg *= COL(1); cb *= COL(2); ca *= COL(3);
#undef COL
    }
    intV hit;
    FootprintV base;                                 /* the base colour's, for the slots that share it */
    base.active = 0;
    base.active_b = 0;
#if SURFACE_TEXTURES
    {
        const rgbaV t = sample_slot(sc, b, mat, SLOT_BASE, fg, &hit, &base);
        base.active = hit;
        cr = select(cr, cr * t.r, hit); cg = select(cg, cg * t.g, hit);
        cb = select(cb, cb * t.b, hit); ca = select(ca, ca * t.a, hit);
    }
#endif
    const intV flags = as_intV(GATHER_MS(uintV, materials, mat, flags));
    floatV spec_i = GATHER_MS(floatV, materials, mat, spec_intensity);
    floatV spec_p = GATHER_MS(floatV, materials, mat, spec_power);
    floatV ar = cr, ag = cg, ab = cb;                /* diffuse albedo */

    intV mr = fg & ((flags & (int)MAT_METALLIC_ROUGHNESS) != 0);
#if VEC == 1
    mr = mr ? 1 : 0;
#endif
    rgbaV t_mr;                                      /* kept: an ORM texture's R is the occlusion */
    intV hit_mr = 0;
    if (ANY(mr)) {
        floatV m = GATHER_MS(floatV, materials, mat, metallic);
        floatV r = GATHER_MS(floatV, materials, mat, roughness);
        t_mr = sample_slot_shared(sc, b, mat, flags, SLOT_MR, mr, &base, &hit_mr);
        m = select(m, m * t_mr.b, hit_mr);
        r = select(r, r * t_mr.g, hit_mr);
        const floatV lum = 0.2126f * cr + 0.7152f * cg + 0.0722f * cb;
        const floatV si = clamp(DIELECTRIC_F0 * (1.0f - m) + lum * m, 0.0f, 1.0f);
        const floatV rr = fmax(r, MIN_ROUGHNESS), a2 = (rr * rr) * (rr * rr);
        const floatV sp = clamp(2.0f / a2 - 2.0f, 1.0f, 2048.0f);
        const floatV kd = 1.0f - m;
        spec_i = select(spec_i, si, mr); spec_p = select(spec_p, sp, mr);
        ar = select(ar, cr * kd, mr); ag = select(ag, cg * kd, mr); ab = select(ab, cb * kd, mr);
        /* The glTF BRDF's lanes keep what it needs: base colour, metallic, roughness (brdf.h). */
        const intV gltf = gltf_lanes(flags, mr);
        if (ANY(gltf)) {
            spec_i = select(spec_i, clamp(m, 0.0f, 1.0f), gltf); spec_p = select(spec_p, clamp(r, 0.0f, 1.0f), gltf);
            ar = select(ar, cr, gltf); ag = select(ag, cg, gltf); ab = select(ab, cb, gltf);
        }
    }
    intV unlit = fg & ((flags & (int)MAT_UNLIT) != 0);
#if VEC == 1
    unlit = unlit ? 1 : 0;
#endif
    if (ANY(unlit)) {
        ar = select(ar, cr, unlit); ag = select(ag, cg, unlit); ab = select(ab, cb, unlit);
        spec_i = select(spec_i, (floatV)0.0f, unlit);
    }
    apply_normal_map(sc, b, mat, flags, fg & !unlit, &base, sf);

    floatV occ = 1.0f;
#if SURFACE_EXTRAS
    const intV tex_occ = GATHER_MS(intV, materials, mat, slots[SLOT_OCCLUSION].texture);
    intV want = fg & (tex_occ >= 0);
#if VEC == 1
    want = want ? 1 : 0;
#endif
    if (ANY(want)) {
        /* Occlusion in the R of the metallic-roughness texture (glTF's ORM packing, or the upload's
         * merge of equal-sized AO and MR images: clrender/render/scene_upload.py), both through the base colour's
         * footprint: the texel is already fetched. */
        intV same = hit_mr & (tex_occ == GATHER_MS(intV, materials, mat, slots[SLOT_MR].texture))
                    & ((flags & (int)(MAT_SHARES(SLOT_MR) | MAT_SHARES(SLOT_OCCLUSION)))
                       == (int)(MAT_SHARES(SLOT_MR) | MAT_SHARES(SLOT_OCCLUSION)));
#if VEC == 1
        same = same ? 1 : 0;
#endif
        rgbaV t;
        if (ANY(want & ~same)) {
            t = sample_slot_shared(sc, b, mat, flags, SLOT_OCCLUSION, fg, &base, &hit);
        } else {
            t = t_mr;
            hit = want;
        }
        const floatV strength = GATHER_MS(floatV, materials, mat, occlusion_strength);
        occ = select(occ, 1.0f + strength * (t.r - 1.0f), hit);
    }
#endif
    floatV er = GATHER_MS(floatV, materials, mat, emissive[0]);
    floatV eg = GATHER_MS(floatV, materials, mat, emissive[1]);
    floatV eb = GATHER_MS(floatV, materials, mat, emissive[2]);
#if SURFACE_EXTRAS
    {
        const rgbaV t = sample_slot_shared(sc, b, mat, flags, SLOT_EMISSIVE, fg, &base, &hit);
        er = select(er, er * t.r, hit); eg = select(eg, eg * t.g, hit); eb = select(eb, eb * t.b, hit);
    }
#endif
    sf->mat_flags = flags;
    sf->r = ar; sf->g = ag; sf->b = ab; sf->a = ca;
    sf->spec_i = spec_i; sf->spec_p = spec_p;
    sf->er = er; sf->eg = eg; sf->eb = eb;
    sf->occlusion = occ;
}
#endif
