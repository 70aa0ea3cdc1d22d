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

/* Folds a texture coordinate into one period ([0,1) repeat, [0,1] mirror/clamp) in float
 * math, so texel indices need only an edge fix-up instead of an integer modulo per fetch. */
static inline float floor_fast(float u)   /* floor() for |u| < 2^31 without a library call */
{
    float t = (float)(int)u;
    return t > u ? t - 1.0f : t;
}

static inline float fold_coord(float u, int mode)
{
    u = fmin(fmax(u, -1.0e9f), 1.0e9f);          /* NaN-free (fmax ignores NaN), int-convertible */
    if (mode == WRAP_REPEAT) return u - floor_fast(u);
    if (mode == WRAP_MIRROR) {
        float t = u - 2.0f * floor_fast(u * 0.5f);     /* [0, 2) */
        return t > 1.0f ? 2.0f - t : t;
    }
    return clamp(u, 0.0f, 1.0f);
}

/* Texel index i in [-1, size] (a bilinear footprint around a folded coordinate) -> valid index. */
static inline int wrap_edge(int i, int size, int mode)
{
    if (mode == WRAP_REPEAT) return i < 0 ? size - 1 : (i >= size ? 0 : i);
    return clamp(i, 0, size - 1);      /* clamp; mirror repeats the edge texel at the fold */
}

/* lut: the decode tables (structs.h LUT_*), offset by the texture's TexInfo.lut. */
static inline float4 texel(global const uint* texels, constant float* lut, TexLevel lv, int x, int y)
{
    uint v = texels[lv.offset + y * lv.width + x];
    return (float4)(lut[v & 255u], lut[(v >> 8) & 255u], lut[(v >> 16) & 255u], (float)(v >> 24) * (1.0f / 255.0f));
}

static float4 sample_bilinear(global const uint* texels, constant float* srgb_lut, TexLevel lv,
                              int wrap_s, int wrap_t, float2 uv)
{
    float fx = fold_coord(uv.x, wrap_s) * (float)lv.width - 0.5f;
    float fy = fold_coord(uv.y, wrap_t) * (float)lv.height - 0.5f;
    int x0 = (int)(fx + 1.0f) - 1, y0 = (int)(fy + 1.0f) - 1;     /* floor: fx, fy >= -0.5 */
    float ax = fx - (float)x0, ay = fy - (float)y0;
    int xa = wrap_edge(x0, lv.width, wrap_s), xb = wrap_edge(x0 + 1, lv.width, wrap_s);
    int ya = wrap_edge(y0, lv.height, wrap_t), yb = wrap_edge(y0 + 1, lv.height, wrap_t);
    float4 t00 = texel(texels, srgb_lut, lv, xa, ya), t10 = texel(texels, srgb_lut, lv, xb, ya);
    float4 t01 = texel(texels, srgb_lut, lv, xa, yb), t11 = texel(texels, srgb_lut, lv, xb, yb);
    float4 top = t00 + (t10 - t00) * ax, bottom = t01 + (t11 - t01) * ax;
    return top + (bottom - top) * ay;
}

/* GL's LOD: log2 of the longer screen-space footprint axis, in level-0 texels. */
static float texture_lod(TexLevel base, float2 duv_dx, float2 duv_dy)
{
    float2 sx = duv_dx * (float2)((float)base.width, (float)base.height);
    float2 sy = duv_dy * (float2)((float)base.width, (float)base.height);
    float rho2 = fmax(sx.x * sx.x + sx.y * sx.y, sy.x * sy.x + sy.y * sy.y);
    /* log2 from the float's exponent and a linear mantissa, as texture units approximate it */
    rho2 = fmin(fmax(rho2, 1e-20f), 1e30f);      /* NaN -> 1e-20 */
    int bits = as_int(rho2);
    float log2_rho2 = (float)((bits >> 23) - 127) + (as_float((bits & 0x007fffff) | 0x3f800000) - 1.0f);
    return 0.5f * log2_rho2;
}

static float4 sample_trilinear(global const uint* texels, constant float* srgb_lut,
                               global const TexInfo* infos, global const TexLevel* levels,
                               int tex, float2 uv, float2 duv_dx, float2 duv_dy)
{
    TexInfo info = infos[tex];
    TexLevel base = levels[info.first_level];
    float lod = fmin(fmax(texture_lod(base, duv_dx, duv_dy), 0.0f), (float)(info.levels - 1));
    int l0 = (int)lod;
    int l1 = min(l0 + 1, info.levels - 1);
    float f = lod - (float)l0;
    constant float* lut = srgb_lut + info.lut;
    float4 a = sample_bilinear(texels, lut, levels[info.first_level + l0], info.wrap_s, info.wrap_t, uv);
    if (f == 0.0f) return a;
    float4 b = sample_bilinear(texels, lut, levels[info.first_level + l1], info.wrap_s, info.wrap_t, uv);
    return a + (b - a) * f;
}
#endif
