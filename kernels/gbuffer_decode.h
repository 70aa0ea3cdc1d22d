/* gbuffer_decode.h: what the lighting passes read back from the G-buffer's planes, decoded as
 * shade.cl, the light pre-pass's light buffer (light_buffer.cl) and the light-indexed forward
 * pass (forward_shade.cl, which decodes the planes it has just packed, so every pipeline lights
 * the same quantized surface).
 */
#ifndef CLRENDER_GBUFFER_DECODE_H
#define CLRENDER_GBUFFER_DECODE_H
#include "structs.h"
#include "gbuffer.h"
#include "brdf.h"

typedef struct {
    floatV nx, ny, nz;          /* unit normal */
    floatV spec_p;              /* specular power */
    floatV depth;               /* view depth (linear depth · far), 0 on background */
} LitPointV;

/* Normal, power and depth from the normal/power and linear-depth words of foreground lanes fg;
 * on the glTF-BRDF lanes `gltf` the power byte is the roughness (clrender/abi/gbuffer.py). */
static inline LitPointV decode_lit_point(uintV w_nrm, uintV w_depth, intV fg, float far, intV gltf)
{
    LitPointV s;
    s.depth = select((floatV)0.0f, as_floatV(w_depth) * far, fg);
    const floatV byte = convert_floatV((w_nrm >> GB_SPECULAR_POWER_SHIFT) & 255u);
    s.spec_p = exp2(byte * (SPEC_POWER_LOG2_MAX / 255.0f));
    if (ANY(gltf)) s.spec_p = select(s.spec_p, byte * (1.0f / 255.0f), gltf);
    floatV fx, fy, fz;
    unpack_oct12x2V(w_nrm >> GB_NORMAL_SHIFT, &fx, &fy, &fz);
    const floatV inv_n = RSQRT(fx * fx + fy * fy + fz * fz);
    s.nx = fx * inv_n; s.ny = fy * inv_n; s.nz = fz * inv_n;
    return s;
}

/* The lanes shaded with the glTF BRDF, from their triangles' materials (none unless the scene
 * has such materials: `gltf_scene`). */
static inline intV gltf_lanes_of(intV tri, intV fg, int gltf_scene, global const int* tri_material,
                                 global const Material* materials)
{
    if (!gltf_scene) return (intV)0;
    const intV mat = GATHER_I(tri_material, select((intV)0, tri, fg));
    return gltf_lanes(as_intV(GATHER_M(uintV, materials, mat, flags)), fg);
}

/* Linear albedo and specular intensity from the albedo/specular word (on glTF-BRDF lanes: the
 * base colour and metallic). */
static inline void decode_albedo(uintV w_alb, constant float* srgb_lut, floatV* ar, floatV* ag, floatV* ab,
                                 floatV* spec_i)
{
    const uintV alb = w_alb >> GB_ALBEDO_SHIFT;
    *ar = GATHER_F(srgb_lut, as_intV(alb & 255u));
    *ag = GATHER_F(srgb_lut, as_intV((alb >> 8) & 255u));
    *ab = GATHER_F(srgb_lut, as_intV((alb >> 16) & 255u));
    *spec_i = convert_floatV((w_alb >> GB_SPECULAR_INTENSITY_SHIFT) & 255u) * (1.0f / 255.0f);
}

/* What the emissive_occlusion plane and the material add to the lighting (docs/materials.md):
 * emissive e × emissive_strength, the occlusion multiplying the ambient term, and the unlit
 * lanes. The strength and the unlit flag are per material, read through the triangle id. */
typedef struct {
    floatV er, eg, eb;          /* HDR emission */
    floatV occlusion;
    intV unlit;
} SurfaceExtrasV;

/* From the emissive_occlusion word and the lanes' materials. */
static inline SurfaceExtrasV material_extras(uintV w_eo, intV mat, intV fg, global const Material* materials,
                                             constant float* srgb_lut)
{
    SurfaceExtrasV x;
    const floatV strength = GATHER_M(floatV, materials, mat, emissive_strength);
    const uintV e = w_eo >> GB_EMISSIVE_SHIFT;
    x.er = GATHER_F(srgb_lut, as_intV(e & 255u)) * strength;
    x.eg = GATHER_F(srgb_lut, as_intV((e >> 8) & 255u)) * strength;
    x.eb = GATHER_F(srgb_lut, as_intV((e >> 16) & 255u)) * strength;
    x.occlusion = convert_floatV((w_eo >> GB_OCCLUSION_SHIFT) & 255u) * (1.0f / 255.0f);
    x.unlit = fg & ((as_intV(GATHER_M(uintV, materials, mat, flags)) & (int)MAT_UNLIT) != 0);
#if VEC == 1
    x.unlit = x.unlit ? 1 : 0;
#endif
    return x;
}

/* From the emissive_occlusion word and the triangle ids (-> tri_material -> Material). */
static inline SurfaceExtrasV decode_extras(uintV w_eo, intV tri, intV fg, global const int* tri_material,
                                           global const Material* materials, constant float* srgb_lut)
{
    return material_extras(w_eo, GATHER_I(tri_material, select((intV)0, tri, fg)), fg, materials, srgb_lut);
}

#endif
