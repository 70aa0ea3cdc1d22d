/* hatching.cl: the report's hatching ("crayonnage", section IV.3) on the tone-mapped image, with
 * tonal art maps (Praun et al. 2001) and ink outlines from the G-buffer; the LDR chain's last
 * effect before encode.cl (docs/post.md "Hatching"). One kernel, one launch.
 *
 * Algorithm: work-item (i, y) owns the run of VEC horizontally adjacent pixels x0 = i·VEC ..
 * x0 + VEC - 1 of row y (vec.h: 8 or 16 on CPUs, 1 on GPUs). Per pixel, three cases:
 *   paper    the pixel has no geometry (G-buffer triangle id -1): out = (1, 1, 1), the white of
 *            the paper, whatever the tone-mapped background holds (black, bloom, a sky); a run
 *            without geometry writes paper and reads nothing else.
 *   outline  a foreground pixel with a discontinuity against one of its 4 direct neighbours
 *            (coordinates clamped at the border: there a pixel is its own neighbour, never an
 *            edge), on the pixel's side: out = (0, 0, 0), black ink. The test is edge_aa.cl's
 *            edge_detect, on the same G-buffer fields and thresholds (RenderConfig
 *            edge_depth_threshold, edge_normal_threshold_deg): the neighbour n is background, or,
 *            both foreground, |z_n - z| > depth_threshold · min(z, z_n) (z the linear depth
 *            z_view/far) or dot(n_n, n) < cos_threshold (the decoded, normalized octahedral normals;
 *            equal codes are an angle of 0). A pair of foreground pixels is inked on its nearer side
 *            only (z <= z_n; both on a tie), a silhouette on its foreground side, so every outline
 *            is one pixel wide: the occluding contour draws the line, the surface behind keeps its
 *            strokes up to it.
 *   hatched  the other foreground pixels, with tone-mapped linear colour c = (r, g, b):
 *     Y    = clamp(0.2126 r + 0.7152 g + 0.0722 b, 0, 1)     linear Rec. 709 / sRGB luminance
 *     tone = (1 - Y) · 6 in [0, 6]; t = min(floor(tone), 5), f = tone - t
 *     ink  = T[t] + (T[t + 1] - T[t]) · f, where T[k] is tone k's map sampled at the pixel:
 *            T[k] = L0 + (L1 - L0) · LEVEL_FRAC, Li the bilinear, wrapped (tileable) lookup of mip
 *            level LEVEL_i at texel coordinates ((x + 0.5) · K_i, (y + 0.5) · K_i), K_i = 1 /
 *            (scale · 2^LEVEL_i): the screen mapped to the map at hatching_scale pixels per level-0
 *            texel, the level chosen by the host as log2(1 / scale) (0 when magnifying), trilinear
 *     out  = (1 + s · (c - 1)) · (1 - ink), s = hatching_saturation
 *   i.e. the colour desaturated toward white paper ("désaturé mais pas complètement": s of its
 *   chroma kept, 0 = black ink on white, 1 = the full colour), darkened by the strokes. The maps
 *   are nested (clrender/passes/tam.py), so ink never decreases as the tone darkens.
 *   The outline test runs without branches over the lanes (selects); normals are decoded only
 *   when a lane's cheaper tests (background, depth) left the question open, and only those of
 *   the neighbours that need them. The tonal art map is read only for runs with a foreground pixel.
 *
 * Buffers: ldr float[3][H·W] tone-mapped linear planes (input); gbuffer uint[GB_PLANES][H·W]
 *          (linear depth, normal, triangle id planes; layout by gbuffer.h's GB_* defines, the
 *          output-resolution G-buffer after any supersample resolve); tam float[TONES][LEVEL_TEXELS]
 *          ink coverage in [0, 1] (clrender/passes/tam.py's layout: per tone, level l at offset
 *          4·(TAM_SIZE² - (TAM_SIZE >> l)²)/3, row-major); out float[3][H·W] (a separate buffer).
 * Work-groups: 2-D, any shape (clrender/passes/hatching.py: launch_2d's fixed 8×8 work-items over
 *          ceil(W / VEC) × H, the global size rounded up; runs starting outside the image return).
 *          Loads clamp to the row (row_run.h), stores write only the lanes inside it. No barriers,
 *          no local memory.
 */
#pragma OPENCL FP_CONTRACT OFF
#include "gbuffer.h"
/* VEC-wide runs (CPUs): row_run.h's loads inlined, as in edge_aa.cl (not with VEC 1: Oclgrind
 * cannot run the inlined code at -O0). */
#if VEC > 1 && defined(__clang__)
#define ROW_RUN_INLINE __attribute__((always_inline))
#endif
#include "row_run.h"
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

/* The strokes over the desaturated colour at pixel centres (x, y) (see the header). */
static inline void hatch(floatV* r, floatV* g, floatV* b, floatV x, floatV y, global const float* tam,
                         int level0, float k0, int level1, float k1, float level_frac, float saturation)
{
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

/* The G-buffer fields of one run (row clamped by the caller, columns clamped lane by lane). */
typedef struct {
    intV fg;                         /* foreground mask (triangle id >= 0) */
    floatV z;                        /* linear depth */
    uintV oct;                       /* 24-bit normal code */
} HatchRun;

static inline ROW_RUN_INLINE HatchRun hatch_load(global const uint* gbuffer, int npix, int row, int x, int width)
{
    HatchRun r;
    r.fg = as_intV(row_load_u(gbuffer + GB_TRIANGLE_ID_PLANE * npix + row, x, width) >> GB_TRIANGLE_ID_SHIFT) >= 0;
    r.z = as_floatV(row_load_u(gbuffer + GB_LINEAR_DEPTH_PLANE * npix + row, x, width) >> GB_LINEAR_DEPTH_SHIFT);
    r.oct = (row_load_u(gbuffer + GB_NORMAL_PLANE * npix + row, x, width) >> GB_NORMAL_SHIFT) & 0xffffffu;
    return r;
}

/* Unit normals from their 24-bit octahedral codes: decode, then divide by the length (as edge_aa.cl). */
typedef struct {
    floatV x, y, z;
} HatchNormal;

static inline HatchNormal hatch_normal(uintV oct)
{
    HatchNormal n;
    unpack_oct12x2V(oct, &n.x, &n.y, &n.z);
    const floatV inv = 1.0f / sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
    n.x *= inv;
    n.y *= inv;
    n.z *= inv;
    return n;
}

static inline floatV hatch_cos(HatchNormal a, uintV oct)
{
    const HatchNormal b = hatch_normal(oct);
    return a.x * b.x + a.y * b.y + a.z * b.z;
}

kernel void hatching(global const float* ldr, global const uint* gbuffer, int width, int height,
                     global const float* tam, int level0, float k0, int level1, float k1, float level_frac,
                     float saturation, float depth_threshold, float cos_threshold, global float* out)
{
    const int x0 = get_global_id(0) * VEC, y = get_global_id(1);
    if (x0 >= width || y >= height) return;
    const int npix = width * height, row = y * width;
    const HatchRun p = hatch_load(gbuffer, npix, row, x0, width);
    if (!ANY(p.fg)) {                                   /* no geometry in the run: paper */
        for (int c = 0; c < 3; ++c) row_store_f((floatV)1.0f, out + c * npix + row, x0, width);
        return;
    }
    floatV r = row_load_f(ldr + row, x0, width), g = row_load_f(ldr + npix + row, x0, width);
    floatV b = row_load_f(ldr + 2 * npix + row, x0, width);
    const floatV xs = convert_floatV((intV)x0 + LANES) + 0.5f;
    hatch(&r, &g, &b, xs, (floatV)((float)y + 0.5f), tam, level0, k0, level1, k1, level_frac, saturation);

    /* The outline: the 4 direct neighbours, left, right (the runs at x0 ∓ 1), up, down, clamped to
     * the image: at the border a pixel is its own neighbour (same id, depth and normal code), never
     * an edge. Masks are -1/0 per lane (VEC 1: 1/0), combined bitwise (`~m & x` is !m && x for
     * either kind). */
    const HatchRun nl = hatch_load(gbuffer, npix, row, x0 - 1, width);
    const HatchRun nr = hatch_load(gbuffer, npix, row, x0 + 1, width);
    const HatchRun nu = hatch_load(gbuffer, npix, ROW_CLAMP(y - 1, height) * width, x0, width);
    const HatchRun nd = hatch_load(gbuffer, npix, ROW_CLAMP(y + 1, height) * width, x0, width);
    /* ink_k: decided by the cheap tests (a background neighbour; a depth jump to a neighbour not
     * nearer than the pixel); need_k: both foreground, the pixel not behind, no depth jump,
     * different normal codes: the normals decide. */
#define OUTLINE_CHEAP(k, n)                                                                         \
    const intV dz##k = fabs(n.z - p.z) > depth_threshold * fmin(p.z, n.z);                          \
    const intV front##k = p.fg & n.fg & (n.z >= p.z);                                               \
    intV ink##k = (p.fg & (n.fg == 0)) | (front##k & dz##k);                                        \
    const intV need##k = front##k & ~dz##k & (n.oct != p.oct)
    OUTLINE_CHEAP(0, nl);
    OUTLINE_CHEAP(1, nr);
    OUTLINE_CHEAP(2, nu);
    OUTLINE_CHEAP(3, nd);
#undef OUTLINE_CHEAP
    if (ANY(need0 | need1 | need2 | need3)) {
        const HatchNormal n_p = hatch_normal(p.oct);
#define OUTLINE_NORMAL(k, n) \
        if (ANY(need##k)) ink##k |= need##k & (hatch_cos(n_p, n.oct) < cos_threshold)
        OUTLINE_NORMAL(0, nl);
        OUTLINE_NORMAL(1, nr);
        OUTLINE_NORMAL(2, nu);
        OUTLINE_NORMAL(3, nd);
    }
#undef OUTLINE_NORMAL
    const intV outline = ink0 | ink1 | ink2 | ink3;
    /* paper where there is no geometry, ink on the outline, the strokes elsewhere */
    row_store_f(select(select(r, (floatV)0.0f, outline), (floatV)1.0f, p.fg == 0), out + row, x0, width);
    row_store_f(select(select(g, (floatV)0.0f, outline), (floatV)1.0f, p.fg == 0), out + npix + row, x0, width);
    row_store_f(select(select(b, (floatV)0.0f, outline), (floatV)1.0f, p.fg == 0), out + 2 * npix + row, x0, width);
}
