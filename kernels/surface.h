/* surface.h: a visible triangle's attributes at a pixel: UVs and base color.
 * Shared by raster.cl (alpha mask) and gbuffer.cl. */
#ifndef CLRENDER_SURFACE_H
#define CLRENDER_SURFACE_H
#include "prim.h"
#include "texture.h"

typedef struct {
    global const uint* texels;
    constant float* srgb_lut;         /* texel decode tables (structs.h LUT_*) */
    global const TexInfo* infos;
    global const TexLevel* levels;
    global const float* colors;       /* float4 per vertex (COLOR_0), read if has_colors */
    int n_vertices;                   /* uv set k of vertex i at uvs[2 (k·n_vertices + i)] */
    int has_colors;
} Textures;

/* The uv set `set` interpolated at barycentrics b, through a slot's texture transform. */
static inline float2 interp_uv(global const float* uvs, global const int* triangles, int tri, float3 b,
                               int set_offset, const float* m)
{
    int i0 = triangles[3 * tri], i1 = triangles[3 * tri + 1], i2 = triangles[3 * tri + 2];
    float2 uv0 = vload2(set_offset + i0, uvs), uv1 = vload2(set_offset + i1, uvs), uv2 = vload2(set_offset + i2, uvs);
    float2 uv = b.x * uv0 + b.y * uv1 + b.z * uv2;
    return (float2)(m[0] * uv.x + m[1] * uv.y + m[2], m[3] * uv.x + m[4] * uv.y + m[5]);
}

/* Base color (linear RGBA) of the prim's material at the fixed-point sample (sx, sy) (a pixel
 * centre is 256·px + 128): factor × vertex colour × texture, as material_eval.h computes it (the
 * alpha MASK and shadow-map alpha tests). */
static float4 surface_base_color(const Prim* p, long sx, long sy, Material m,
                                 global const float* uvs, global const int* triangles, Textures tx)
{
    float4 color = vload4(0, m.base_color);
    const TexSlot slot = m.slots[SLOT_BASE];
    if (slot.texture < 0 && !tx.has_colors) return color;
    float3 b, b_dx, b_dy;
    prim_barycentrics_with_derivatives(p, sx, sy, &b, &b_dx, &b_dy);
    if (tx.has_colors) {
        const int i0 = triangles[3 * p->tri], i1 = triangles[3 * p->tri + 1], i2 = triangles[3 * p->tri + 2];
        color *= b.x * vload4(i0, tx.colors) + b.y * vload4(i1, tx.colors) + b.z * vload4(i2, tx.colors);
    }
    if (slot.texture < 0) return color;
    const int set = slot.texcoord * tx.n_vertices;
    float2 uv = interp_uv(uvs, triangles, p->tri, b, set, slot.uv);
    float2 uv_dx = interp_uv(uvs, triangles, p->tri, b + b_dx, set, slot.uv) - uv;
    float2 uv_dy = interp_uv(uvs, triangles, p->tri, b + b_dy, set, slot.uv) - uv;
    return color * sample_trilinear(tx.texels, tx.srgb_lut, tx.infos, tx.levels, slot.texture, uv, uv_dx, uv_dy);
}
#endif
