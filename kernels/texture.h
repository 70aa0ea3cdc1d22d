/* texture.h: trilinear sampling of RGBA8 textures stored in one texel buffer.
 *
 * Layout: texels uint[*], RGBA8 with R in the low byte, row 0 = top of the image; TexInfo
 * points at a run of TexLevel records (mip 0 first), each giving its texel offset and size.
 * Color channels are sRGB-encoded and decoded through a 256-entry table before filtering,
 * so filtering happens in linear space as with GL's SRGB8_ALPHA8 textures.
 * Coordinates follow GL: texel centers at (i + 0.5) / size, uv (0,0) = first texel. */
#ifndef CLRENDER_TEXTURE_H
#define CLRENDER_TEXTURE_H
#include "structs.h"

static inline int wrap_coord(int i, int size, int mode)
{
    if (mode == WRAP_CLAMP) return clamp(i, 0, size - 1);
    if (mode == WRAP_MIRROR) {
        int period = 2 * size;
        int m = i % period; if (m < 0) m += period;
        return m < size ? m : period - 1 - m;
    }
    int m = i % size;
    return m < 0 ? m + size : m;
}

static inline float4 texel(global const uint* texels, constant float* srgb_lut, TexLevel lv, int x, int y)
{
    uint v = texels[lv.offset + y * lv.width + x];
    return (float4)(srgb_lut[v & 255u], srgb_lut[(v >> 8) & 255u], srgb_lut[(v >> 16) & 255u],
                    (float)(v >> 24) * (1.0f / 255.0f));
}

static float4 sample_bilinear(global const uint* texels, constant float* srgb_lut, TexLevel lv,
                              int wrap_s, int wrap_t, float2 uv)
{
    float fx = uv.x * (float)lv.width - 0.5f, fy = uv.y * (float)lv.height - 0.5f;
    float x0f = floor(fx), y0f = floor(fy);
    float ax = fx - x0f, ay = fy - y0f;
    /* Keep huge coordinates (wrapping UVs far from 0) inside int range. */
    int x0 = (int)clamp(x0f, -1.0e9f, 1.0e9f), y0 = (int)clamp(y0f, -1.0e9f, 1.0e9f);
    int xa = wrap_coord(x0, lv.width, wrap_s), xb = wrap_coord(x0 + 1, lv.width, wrap_s);
    int ya = wrap_coord(y0, lv.height, wrap_t), yb = wrap_coord(y0 + 1, lv.height, wrap_t);
    float4 t00 = texel(texels, srgb_lut, lv, xa, ya), t10 = texel(texels, srgb_lut, lv, xb, ya);
    float4 t01 = texel(texels, srgb_lut, lv, xa, yb), t11 = texel(texels, srgb_lut, lv, xb, yb);
    return mix(mix(t00, t10, ax), mix(t01, t11, ax), ay);
}

/* GL's LOD: log2 of the longer screen-space footprint axis, in level-0 texels. */
static float texture_lod(TexLevel base, float2 duv_dx, float2 duv_dy)
{
    float2 sx = duv_dx * (float2)((float)base.width, (float)base.height);
    float2 sy = duv_dy * (float2)((float)base.width, (float)base.height);
    float rho2 = fmax(dot(sx, sx), dot(sy, sy));
    return 0.5f * log2(fmax(rho2, 1e-20f));
}

static float4 sample_trilinear(global const uint* texels, constant float* srgb_lut,
                               global const TexInfo* infos, global const TexLevel* levels,
                               int tex, float2 uv, float2 duv_dx, float2 duv_dy)
{
    TexInfo info = infos[tex];
    TexLevel base = levels[info.first_level];
    float lod = clamp(texture_lod(base, duv_dx, duv_dy), 0.0f, (float)(info.levels - 1));
    int l0 = (int)lod;
    int l1 = min(l0 + 1, info.levels - 1);
    float f = lod - (float)l0;
    float4 a = sample_bilinear(texels, srgb_lut, levels[info.first_level + l0], info.wrap_s, info.wrap_t, uv);
    if (f == 0.0f) return a;
    float4 b = sample_bilinear(texels, srgb_lut, levels[info.first_level + l1], info.wrap_s, info.wrap_t, uv);
    return mix(a, b, f);
}
#endif
