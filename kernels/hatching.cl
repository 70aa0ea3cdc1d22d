/* hatching.cl: the report's hatching ("crayonnage", section IV.3) on the tone-mapped image, with
 * tonal art maps (Praun et al. 2001); the LDR chain's last effect before encode.cl (docs/post.md).
 *
 * Algorithm: one work-item per run of VEC pixels (vec.h). For a pixel (x, y) with tone-mapped
 * linear colour c = (r, g, b):
 *   Y    = clamp(0.2126 r + 0.7152 g + 0.0722 b, 0, 1)     linear Rec. 709 / sRGB luminance
 *   tone = (1 - Y) · 6 in [0, 6]; t = min(floor(tone), 5), f = tone - t
 *   ink  = T[t] + (T[t + 1] - T[t]) · f, where T[k] is tone k's map sampled at the pixel:
 *          T[k] = L0 + (L1 - L0) · LEVEL_FRAC, Li the bilinear, wrapped (tileable) lookup of mip
 *          level LEVEL_i at texel coordinates ((x + 0.5) · K_i, (y + 0.5) · K_i), K_i = 1 /
 *          (scale · 2^LEVEL_i): the screen mapped to the map at hatching_scale pixels per level-0
 *          texel, the level chosen by the host as log2(1 / scale) (0 when magnifying), trilinear
 *   out  = (1 + s · (c - 1)) · (1 - ink), s = hatching_saturation
 * i.e. the colour desaturated toward white paper ("désaturé mais pas complètement": s of its
 * chroma kept, 0 = black ink on white, 1 = the full colour), darkened by the strokes. The maps
 * are nested (clrender/tam.py), so ink never decreases as the tone darkens.
 *
 * Buffers: ldr float[3][H·W] tone-mapped linear planes (input); tam float[TONES][LEVEL_TEXELS]
 *          ink coverage in [0, 1] (clrender/tam.py's layout: per tone, level l at offset
 *          4·(TAM_SIZE² - (TAM_SIZE >> l)²)/3, row-major); out float[3][H·W] (a separate buffer).
 * Work-groups: 1-D, any size; no barriers.
 */
#include "vec.h"

#ifndef TAM_SIZE
#define TAM_SIZE 128          /* level-0 texels per side, a power of two */
#endif
#ifndef TONES
#define TONES 7
#endif
#define LEVEL_TEXELS ((4 * TAM_SIZE * TAM_SIZE - 1) / 3)

static inline int level_offset(int level)
{
    const int size = TAM_SIZE >> level;
    return 4 * (TAM_SIZE * TAM_SIZE - size * size) / 3;
}

/* Bilinear, wrapped lookup of one mip level for every lane; `tone_base` is each lane's tone
 * offset (tone · LEVEL_TEXELS); (u, v) in that level's texel units. */
static inline floatV bilinear(global const float* tam, intV tone_base, int level, floatV u, floatV v)
{
    const int size = TAM_SIZE >> level, mask = size - 1;
    global const float* lvl = tam + level_offset(level);
    const floatV su = u - 0.5f, sv = v - 0.5f;
    const floatV fu = floor(su), fv = floor(sv);
    const floatV wu = su - fu, wv = sv - fv;
    const intV u0 = convert_intV(fu) & mask, v0 = convert_intV(fv) & mask;
    const intV u1 = (u0 + 1) & mask, v1 = (v0 + 1) & mask;
    const intV r0 = tone_base + v0 * size, r1 = tone_base + v1 * size;
    const floatV a = GATHER_F(lvl, r0 + u0), b = GATHER_F(lvl, r0 + u1);
    const floatV c = GATHER_F(lvl, r1 + u0), d = GATHER_F(lvl, r1 + u1);
    const floatV top = a + (b - a) * wu, bottom = c + (d - c) * wu;
    return top + (bottom - top) * wv;
}

/* Tone map k (per lane) at the pixel: trilinear between levels level0 and level1. */
static inline floatV tone_ink(global const float* tam, intV tone, floatV x, floatV y, int level0, float k0,
                              int level1, float k1, float level_frac)
{
    const intV base = tone * LEVEL_TEXELS;
    const floatV l0 = bilinear(tam, base, level0, x * k0, y * k0);
    if (level_frac == 0.0f) return l0;
    const floatV l1 = bilinear(tam, base, level1, x * k1, y * k1);
    return l0 + (l1 - l0) * level_frac;
}

static inline void hatch(floatV* r, floatV* g, floatV* b, intV p, int width, global const float* tam,
                         int level0, float k0, int level1, float k1, float level_frac, float saturation)
{
    const floatV x = convert_floatV(p % width) + 0.5f, y = convert_floatV(p / width) + 0.5f;
    /* fmax/fmin, not clamp: a NaN colour gets tone 6 and in-bounds lookups. */
    const floatV luma = fmin(fmax(0.2126f * *r + 0.7152f * *g + 0.0722f * *b, 0.0f), 1.0f);
    const floatV tone = (1.0f - luma) * 6.0f;
    const intV t = min(convert_intV(floor(tone)), TONES - 2);
    const floatV f = tone - convert_floatV(t);
    const floatV ink0 = tone_ink(tam, t, x, y, level0, k0, level1, k1, level_frac);
    const floatV ink1 = tone_ink(tam, t + 1, x, y, level0, k0, level1, k1, level_frac);
    const floatV keep = 1.0f - (ink0 + (ink1 - ink0) * f);
    *r = (1.0f + saturation * (*r - 1.0f)) * keep;
    *g = (1.0f + saturation * (*g - 1.0f)) * keep;
    *b = (1.0f + saturation * (*b - 1.0f)) * keep;
}

kernel void hatching(global const float* ldr, int width, int npix, global const float* tam, int level0, float k0,
                     int level1, float k1, float level_frac, float saturation, global float* out)
{
    const int p0 = get_global_id(0) * VEC;
    if (p0 >= npix) return;
    if (p0 + VEC <= npix) {
        floatV r = vloadV(0, ldr + p0), g = vloadV(0, ldr + npix + p0), b = vloadV(0, ldr + 2 * npix + p0);
        hatch(&r, &g, &b, (intV)p0 + LANES, width, tam, level0, k0, level1, k1, level_frac, saturation);
        vstoreV(r, 0, out + p0);
        vstoreV(g, 0, out + npix + p0);
        vstoreV(b, 0, out + 2 * npix + p0);
    } else {
        for (int p = p0; p < npix; ++p) {
            /* Tail: one pixel at a time through lane 0 (the other lanes repeat it). */
            floatV r = ldr[p], g = ldr[npix + p], b = ldr[2 * npix + p];
            hatch(&r, &g, &b, (intV)p, width, tam, level0, k0, level1, k1, level_frac, saturation);
            out[p] = LANE_F(r, 0);
            out[npix + p] = LANE_F(g, 0);
            out[2 * npix + p] = LANE_F(b, 0);
        }
    }
}
