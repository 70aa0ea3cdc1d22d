/* surface.h: a visible triangle's attributes at a pixel: UVs and base color.
 * Shared by raster.cl (alpha mask) and gbuffer.cl. */
#ifndef CLRENDER_SURFACE_H
#define CLRENDER_SURFACE_H
#include "prim.h"
#include "texture.h"

typedef struct {
    global const uint* texels;
    constant float* srgb_lut;
    global const TexInfo* infos;
    global const TexLevel* levels;
} Textures;

static inline float2 interp_uv(global const float* uvs, global const int* triangles, int tri, float3 b)
{
    int i0 = triangles[3 * tri], i1 = triangles[3 * tri + 1], i2 = triangles[3 * tri + 2];
    float2 uv0 = vload2(i0, uvs), uv1 = vload2(i1, uvs), uv2 = vload2(i2, uvs);
    return b.x * uv0 + b.y * uv1 + b.z * uv2;
}

/* Base color (linear RGBA) of the prim's material at pixel (px, py). */
static float4 surface_base_color(const Prim* p, int px, int py, Material m,
                                 global const float* uvs, global const int* triangles, Textures tx)
{
    float4 color = vload4(0, m.base_color);
    if (m.texture < 0) return color;
    float3 b, b_dx, b_dy;
    prim_barycentrics_with_derivatives(p, px, py, &b, &b_dx, &b_dy);
    float2 uv = interp_uv(uvs, triangles, p->tri, b);
    float2 uv_dx = interp_uv(uvs, triangles, p->tri, b + b_dx) - uv;
    float2 uv_dy = interp_uv(uvs, triangles, p->tri, b + b_dy) - uv;
    return color * sample_trilinear(tx.texels, tx.srgb_lut, tx.infos, tx.levels, m.texture, uv, uv_dx, uv_dy);
}
#endif
