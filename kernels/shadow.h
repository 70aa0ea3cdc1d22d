/* shadow.h: shadow-map lookups for shade.cl (report II.4 "Ombres": the shadowed light is a
 * light like any other, its visibility multiplies its term in the light buffer).
 *
 * Algorithm: the receiver (world position p, unit normal n, cosine c = N·L) is first pushed
 * along n by normal_offset texels · sin θ (normal offset: surfaces facing the light move
 * least), projected by the view's matrix (structs.h ShadowView) to map texels (u, v) and a
 * linear depth, and compared with the depths stored in the atlas at
 *     ref = depth - texel · (bias + slope_bias · min(tan θ, 8) · reach)
 * (constant + slope-scaled bias; `reach` = how far the filter's taps lie from the sample, so
 * a tilted receiver never shadows itself through a neighbouring tap). A tap is lit when
 * ref <= stored depth. Filters (SHADOW_FILTER): 0 hard (the texel under the sample),
 * 1 pcf3x3 (a 3×3-texel box convolved with bilinear weights: 4×4 taps, smooth edges),
 * 2 poisson (16 taps of a Poisson disk of POISSON_RADIUS texels, rotated per pixel by an
 * integer hash of the pixel coordinates: noise instead of banding, the same on every run).
 * Samples outside the map's square, behind the light or beyond its far depth are lit (1).
 * Texel sizes: `texel` is the world size of a map texel at the receiver (perspective:
 * ShadowView.texel × view depth; orthographic: ShadowView.texel).
 *
 * Buffers: atlas float[stride × rows] (linear depths, +inf where nothing was drawn);
 *          ShadowView records (structs.h). VEC-wide (vec.h): one lookup serves a run of pixels,
 *          atlas reads are GATHERs; view records are uniform (scalar loads).
 */
#ifndef CLRENDER_SHADOW_H
#define CLRENDER_SHADOW_H
#include "structs.h"
#include "vec.h"

#ifndef SHADOW_FILTER
#define SHADOW_FILTER 1
#endif
#ifndef POISSON_RADIUS
#define POISSON_RADIUS 2.0f
#endif

#if SHADOW_FILTER == 0
#define FILTER_REACH 0.75f                    /* nearest texel center: up to √2/2 texels away */
#elif SHADOW_FILTER == 1
#define FILTER_REACH 2.0f                     /* 4×4 taps: up to 2 texels from the sample */
#else
#define FILTER_REACH (POISSON_RADIUS * 1.25f + 0.75f)   /* disk points reach 1.23 of the radius */
#endif

typedef struct {
    global const float* atlas;
    int stride;
    float bias;            /* texels */
    float slope_bias;      /* × tan θ × FILTER_REACH texels */
    float normal_offset;   /* texels × sin θ */
} ShadowParams;

#if SHADOW_FILTER == 2
constant float2 POISSON16[16] = {
    (float2)(-0.94201624f, -0.39906216f), (float2)(0.94558609f, -0.76890725f),
    (float2)(-0.09418410f, -0.92938870f), (float2)(0.34495938f, 0.29387760f),
    (float2)(-0.91588581f, 0.45771432f), (float2)(-0.81544232f, -0.87912464f),
    (float2)(-0.38277543f, 0.27676845f), (float2)(0.97484398f, 0.75648379f),
    (float2)(0.44323325f, -0.97511554f), (float2)(0.53742981f, -0.47373420f),
    (float2)(-0.26496911f, -0.41893023f), (float2)(0.79197514f, 0.19090188f),
    (float2)(-0.24188840f, 0.99706507f), (float2)(-0.81409955f, 0.91437590f),
    (float2)(0.19984126f, 0.78641367f), (float2)(0.14383161f, -0.14100790f)};
#endif

/* 1 where texel (iu, iv) of the view (clamped into its square) is at or behind `ref`. */
static inline floatV shadow_tap(const ShadowParams* sp, int x0, int y0, int size, intV iu, intV iv, floatV ref)
{
    intV idx = (clamp(iv, 0, size - 1) + y0) * sp->stride + clamp(iu, 0, size - 1) + x0;
    floatV d = GATHER_F(sp->atlas, idx);
    return select((floatV)0.0f, (floatV)1.0f, ref <= d);
}

/* Per-pixel rotation for the Poisson disk (integer hash: deterministic on every device). */
static inline uintV pixel_hash(intV px, int py)
{
    uintV h = as_uintV(px) * 0x8da6b343u ^ (uintV)((uint)py * 0xd8163841u);
    h ^= h >> 15;
    h *= 0x2c1b3c6du;
    h ^= h >> 12;
    return h;
}

/* Visibility in [0, 1] of the receivers (px, py, pz) with normals n and N·L = ndotl from the
 * view `vw`; `pix_x`/`pix_y` are the pixel coordinates (Poisson rotation). */
static floatV shadow_visibility(const ShadowParams* sp, global const ShadowView* vw,
                                floatV px, floatV py, floatV pz, floatV nx, floatV ny, floatV nz,
                                floatV ndotl, intV pix_x, int pix_y)
{
    const ShadowView v = *vw;
    const float size = (float)v.size;
    floatV texel = (floatV)v.texel;
    if (!v.ortho) texel *= fmax(v.m[12] * px + v.m[13] * py + v.m[14] * pz + v.m[15], 0.0f);
    floatV cos_t = clamp(ndotl, 0.0f, 1.0f);
    floatV sin_t = sqrt(fmax(1.0f - cos_t * cos_t, 0.0f));
    floatV off = (sp->normal_offset * texel) * sin_t;
    floatV qx = px + nx * off, qy = py + ny * off, qz = pz + nz * off;
    floatV hx = ((v.m[0] * qx + v.m[1] * qy) + v.m[2] * qz) + v.m[3];
    floatV hy = ((v.m[4] * qx + v.m[5] * qy) + v.m[6] * qz) + v.m[7];
    floatV d = ((v.m[8] * qx + v.m[9] * qy) + v.m[10] * qz) + v.m[11];
    floatV w = ((v.m[12] * qx + v.m[13] * qy) + v.m[14] * qz) + v.m[15];
    floatV inv_w = 1.0f / w;
    floatV u = ((hx * inv_w + 1.0f) * 0.5f) * size, t = ((1.0f - hy * inv_w) * 0.5f) * size;
    intV inside = (w > 0.0f) & (d < v.far) & (u >= 0.0f) & (u < size) & (t >= 0.0f) & (t < size);
    u = select((floatV)0.0f, u, inside);          /* NaN-free before converting to texel indices */
    t = select((floatV)0.0f, t, inside);
    floatV tan_t = fmin(sin_t / fmax(cos_t, 1e-3f), 8.0f);
    floatV ref = d - texel * (sp->bias + sp->slope_bias * tan_t * FILTER_REACH);
    floatV vis;
#if SHADOW_FILTER == 0
    vis = shadow_tap(sp, v.x0, v.y0, v.size, convert_intV(u), convert_intV(t), ref);
#elif SHADOW_FILTER == 1
    floatV fu = u - 0.5f, fv = t - 0.5f;
    floatV bu = floor(fu), bv = floor(fv);
    floatV au = fu - bu, av = fv - bv;
    intV iu = convert_intV(bu) - 1, iv = convert_intV(bv) - 1;
    vis = 0.0f;
    for (int j = 0; j < 4; ++j) {
        floatV wy = (j == 0) ? 1.0f - av : (j == 3) ? av : (floatV)1.0f;
        floatV row = (1.0f - au) * shadow_tap(sp, v.x0, v.y0, v.size, iu, iv + j, ref)
                   + shadow_tap(sp, v.x0, v.y0, v.size, iu + 1, iv + j, ref)
                   + shadow_tap(sp, v.x0, v.y0, v.size, iu + 2, iv + j, ref)
                   + au * shadow_tap(sp, v.x0, v.y0, v.size, iu + 3, iv + j, ref);
        vis += wy * row;
    }
    vis *= 1.0f / 9.0f;
#else
    floatV angle = convert_floatV(pixel_hash(pix_x, pix_y) >> 8) * (6.2831853f / 16777216.0f);
    floatV cs = cos(angle) * POISSON_RADIUS, sn = sin(angle) * POISSON_RADIUS;   /* not sincos: no private out */
    vis = 0.0f;
    for (int k = 0; k < 16; ++k) {
        const float2 o = POISSON16[k];
        floatV su = u + (cs * o.x - sn * o.y), sv = t + (sn * o.x + cs * o.y);
        vis += shadow_tap(sp, v.x0, v.y0, v.size, convert_intV(floor(su)), convert_intV(floor(sv)), ref);
    }
    vis *= 1.0f / 16.0f;
#endif
    return select((floatV)1.0f, vis, inside);
}
#endif
