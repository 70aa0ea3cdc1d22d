/* environment.h: image-based lighting lookups for the shading kernels (docs/ibl.md), VEC lanes
 * at once (vec.h; VEC = 1 on GPUs and Oclgrind). The maps are made once per environment by
 * kernels/ibl.cl (clrender/passes/ibl.py).
 *
 * Direction convention (exact; the tests depend on it): world direction d = (x, y, z), +Y up,
 *     u = 0.5 + atan2(x, -z) / (2 pi),   v = acos(y / |d|) / pi,
 * texel (i, j) of a w x h level has its centre at ((i + 0.5) / w, (j + 0.5) / h); bilinear
 * filtering, wrapping in u, clamped in v; row 0 looks straight up. The image centre lies along
 * -Z, u = 0.75 along +X. A rotation of R degrees looks up at u + R/360 (wrapped): the
 * environment turns by -R about +Y (for radiance lookups the u offset; for the irradiance the
 * normal turns by the matching rotation: x' = c x - s z, z' = s x + c z, c, s = cos, sin(2 pi R/360)).
 *
 * Buffers (ENV_PARAMS, this order; clrender.passes.ibl.IblMaps.args()):
 *   env_texels float[3 * texels]  linear RGB, texel t at [3t, 3t + 3); every level one after the other
 *   env_levels int[4 * levels]    per level (offset in texels, width, height, 0) -- TexLevel's layout:
 *                                 level 0 the full-resolution environment (what the background shows),
 *                                 levels 1 .. K the specular chain: level 1 + k prefiltered for
 *                                 roughness k / (K - 1) (level 1: roughness 0, at most 512 wide)
 *   env_sh     float[27]          order-2 spherical harmonics of E(n) / pi, coefficient-major
 *                                 (coefficient k, channel c at 3k + c), basis order (world axes):
 *                                 1, y, z, x, xy, yz, 3z^2 - 1, xz, x^2 - y^2 times ENV_SH_K* below
 *   env_dfg    float[3 * n * n]   split-sum table, texel (i, j) at 3 (j n + i): A, B, C at
 *                                 n.v = (i + 0.5) / n, roughness = j / (n - 1), bilinear, clamped
 *   env_params float[ENV_P_COUNT] ENV_P_* below: intensity, rotation, counts
 *
 * Usage:  kernel void shade(..., ENV_PARAMS) { const EnvMaps env = ENV_INIT; env_backgroundV(&env, ...); }
 * Results are multiplied by the intensity. Non-finite directions or parameters give finite
 * indices (no out-of-bounds read) and unspecified values.
 */
#ifndef CLRENDER_ENVIRONMENT_H
#define CLRENDER_ENVIRONMENT_H
#include "vec.h"

/* env_params entries */
#define ENV_P_INTENSITY   0   /* radiance scale */
#define ENV_P_ROTATION_U  1   /* R / 360 wrapped into [0, 1): the u offset of every lookup */
#define ENV_P_SPEC_LEVELS 2   /* K, the specular chain's levels (env_levels holds K + 1) */
#define ENV_P_DFG_SIZE    3   /* n, the DFG table's side */
#define ENV_P_ROT_COS     4   /* cos(2 pi R / 360) */
#define ENV_P_ROT_SIN     5   /* sin(2 pi R / 360) */
#define ENV_P_LEVELS      6   /* K + 1 */
#define ENV_P_COUNT       8

#define ENV_LEVEL_STRIDE  4   /* ints per env_levels record */

/* Real SH basis constants (Ramamoorthi & Hanrahan 2001) */
#define ENV_SH_K0 0.282094791773878f    /* 1 / (2 sqrt(pi)) */
#define ENV_SH_K1 0.488602511902920f    /* sqrt(3 / (4 pi)) */
#define ENV_SH_K2 1.092548430592079f    /* sqrt(15 / (4 pi)) */
#define ENV_SH_K3 0.315391565252520f    /* sqrt(5 / (16 pi)) */
#define ENV_SH_K4 0.546274215296040f    /* sqrt(15 / (16 pi)) */

#define ENV_INV_PI  0.318309886183791f
#define ENV_INV_2PI 0.159154943091895f

#define ENV_PARAMS global const float* env_texels, global const int* env_levels, global const float* env_sh, \
                   global const float* env_dfg, global const float* env_params
#define ENV_INIT { env_texels, env_levels, env_sh, env_dfg, env_params }

typedef struct {
    global const float* texels;
    global const int* levels;
    global const float* sh;
    global const float* dfg;
    global const float* params;
} EnvMaps;

/* ENV_INLINE: always_inline on CPUs (VEC > 1), as texture_vec.h's VINLINE (vectors passed to a
 * call go through the stack); nothing for VEC = 1 (Oclgrind runs -O0 code). */
#if VEC > 1 && defined(__clang__)
#define ENV_INLINE __attribute__((always_inline))
#else
#define ENV_INLINE
#endif

/* (u, v) of direction d (any length > 0) with the u offset rot_u, both in [0, 1]. NaN -> 0. */
static inline ENV_INLINE void env_dir_uvV(floatV dx, floatV dy, floatV dz, float rot_u, floatV* u, floatV* v)
{
    const floatV len = sqrt(dx * dx + dy * dy + dz * dz);
    const floatV y = fmin(fmax(dy / fmax(len, 1e-30f), -1.0f), 1.0f);     /* NaN -> -1 */
    *v = acos(y) * ENV_INV_PI;
    floatV uu = 0.5f + atan2(dx, -dz) * ENV_INV_2PI + rot_u;
    uu = uu - floor(uu);
    *u = fmin(fmax(uu, 0.0f), 1.0f);                                       /* NaN -> 0 */
}

/* Bilinear RGB of a w x h level at texel offset `offset` (per lane), (u, v) in [0, 1]: wraps in
 * u, clamps in v. */
static inline ENV_INLINE void env_bilinearV(global const float* texels, intV offset, intV w, intV h,
                                            floatV u, floatV v, floatV* r, floatV* g, floatV* b)
{
    const floatV fx = u * convert_floatV(w) - 0.5f, fy = v * convert_floatV(h) - 0.5f;
    const intV x0 = convert_intV(fx + 1.0f) - 1, y0 = convert_intV(fy + 1.0f) - 1;   /* floor: fx, fy >= -0.5 */
    const floatV ax = fx - convert_floatV(x0), ay = fy - convert_floatV(y0);
    const intV xa = select(x0, x0 + w, x0 < 0);                                   /* x0 in [-1, w - 1] */
    const intV xb = select(x0 + 1, (intV)0, x0 + 1 >= w);
    const intV ya = max(y0, (intV)0), yb = min(y0 + 1, h - 1);
    const intV ra = offset + ya * w, rb = offset + yb * w;
    const intV i00 = 3 * (ra + xa), i01 = 3 * (ra + xb), i10 = 3 * (rb + xa), i11 = 3 * (rb + xb);
#define ENV_BILERP(out, c) { \
        const floatV t00 = GATHER_F(texels, i00 + c), t01 = GATHER_F(texels, i01 + c); \
        const floatV t10 = GATHER_F(texels, i10 + c), t11 = GATHER_F(texels, i11 + c); \
        const floatV top = t00 + (t01 - t00) * ax, bot = t10 + (t11 - t10) * ax; \
        *(out) = top + (bot - top) * ay; }
    ENV_BILERP(r, 0) ENV_BILERP(g, 1) ENV_BILERP(b, 2)
#undef ENV_BILERP
}

/* Per-lane level record `level` (index into env_levels). */
static inline ENV_INLINE void env_levelV(global const int* levels, intV level, intV* offset, intV* w, intV* h)
{
    const intV at = level * ENV_LEVEL_STRIDE;
    *offset = GATHER_I(levels, at);
    *w = GATHER_I(levels, at + 1);
    *h = GATHER_I(levels, at + 2);
}

/* Bilinear radiance x intensity of env_levels level `level` (0: the background image, 1 + k:
 * specular level k) along d (unnormalized or unit). */
static inline void env_radianceV(const EnvMaps* e, int level, floatV dx, floatV dy, floatV dz,
                                 floatV* r, floatV* g, floatV* b)
{
    floatV u, v;
    env_dir_uvV(dx, dy, dz, e->params[ENV_P_ROTATION_U], &u, &v);
    const int nlev = (int)e->params[ENV_P_LEVELS];
    const int l = clamp(level, 0, nlev - 1);
    const global int* rec = e->levels + l * ENV_LEVEL_STRIDE;
    env_bilinearV(e->texels, (intV)rec[0], (intV)rec[1], (intV)rec[2], u, v, r, g, b);
    const float s = e->params[ENV_P_INTENSITY];
    *r *= s; *g *= s; *b *= s;
}

/* What the background shows along d: level 0, the full-resolution image. */
static inline void env_backgroundV(const EnvMaps* e, floatV dx, floatV dy, floatV dz, floatV* r, floatV* g, floatV* b)
{
    env_radianceV(e, 0, dx, dy, dz, r, g, b);
}

/* E(n) / pi x intensity (what a white Lambertian surface with normal n reflects) from the SH,
 * clamped at 0 (order 2 rings below 0 behind very bright small sources). */
static inline void env_irradianceV(const EnvMaps* e, floatV nx, floatV ny, floatV nz, floatV* r, floatV* g, floatV* b)
{
    const floatV inv = 1.0f / fmax(sqrt(nx * nx + ny * ny + nz * nz), 1e-30f);
    const float c = e->params[ENV_P_ROT_COS], s = e->params[ENV_P_ROT_SIN];
    const floatV x0 = nx * inv, y = ny * inv, z0 = nz * inv;
    const floatV x = c * x0 - s * z0, z = s * x0 + c * z0;
    floatV Y[9];
    Y[0] = (floatV)ENV_SH_K0;
    Y[1] = ENV_SH_K1 * y;
    Y[2] = ENV_SH_K1 * z;
    Y[3] = ENV_SH_K1 * x;
    Y[4] = ENV_SH_K2 * (x * y);
    Y[5] = ENV_SH_K2 * (y * z);
    Y[6] = ENV_SH_K3 * (3.0f * z * z - 1.0f);
    Y[7] = ENV_SH_K2 * (x * z);
    Y[8] = ENV_SH_K4 * (x * x - y * y);
    floatV acc[3];
    for (int ch = 0; ch < 3; ++ch) {
        floatV sum = e->sh[ch] * Y[0];
        for (int k = 1; k < 9; ++k) sum += e->sh[3 * k + ch] * Y[k];
        acc[ch] = fmax(sum, 0.0f) * e->params[ENV_P_INTENSITY];
    }
    *r = acc[0]; *g = acc[1]; *b = acc[2];
}

/* Prefiltered radiance x intensity along the reflection direction d for `roughness` (per lane,
 * clamped to [0, 1]): linear between the two nearest of the K levels (roughness k / (K - 1)). */
static inline void env_specularV(const EnvMaps* e, floatV rx, floatV ry, floatV rz, floatV roughness,
                                 floatV* r, floatV* g, floatV* b)
{
    floatV u, v;
    env_dir_uvV(rx, ry, rz, e->params[ENV_P_ROTATION_U], &u, &v);
    const int K = (int)e->params[ENV_P_SPEC_LEVELS];
    const floatV f = fmin(fmax(roughness, 0.0f), 1.0f) * (float)(K - 1);   /* NaN -> 0 */
    const intV k0 = min(convert_intV(f), (intV)max(K - 2, 0));
    const intV k1 = min(k0 + 1, (intV)(K - 1));
    const floatV t = f - convert_floatV(k0);
    intV off, w, h;
    env_levelV(e->levels, 1 + k0, &off, &w, &h);
    env_bilinearV(e->texels, off, w, h, u, v, r, g, b);
    if (ANY(t > 0.0f)) {
        floatV r1, g1, b1;
        env_levelV(e->levels, 1 + k1, &off, &w, &h);
        env_bilinearV(e->texels, off, w, h, u, v, &r1, &g1, &b1);
        *r += (r1 - *r) * t; *g += (g1 - *g) * t; *b += (b1 - *b) * t;
    }
    const float s = e->params[ENV_P_INTENSITY];
    *r *= s; *g *= s; *b *= s;
}

/* The split-sum terms at (n.v, roughness), bilinear in the table (n.v clamped to the texel centres,
 * roughness rows at j / (n - 1)):
 * specular = prefiltered * (F0 A + B), diffuse = albedo (1 - F0) C E / pi (glTF 2.0 Appendix B). */
static inline void env_dfgV(const EnvMaps* e, floatV nv, floatV roughness, floatV* A, floatV* B, floatV* C)
{
    const int n = (int)e->params[ENV_P_DFG_SIZE];
    const float top = (float)(n - 1);
    const floatV fx = fmin(fmax(fmin(fmax(nv, 0.0f), 1.0f) * (float)n - 0.5f, 0.0f), top);   /* NaN -> 0 */
    const floatV fy = fmin(fmax(roughness, 0.0f), 1.0f) * top;                              /* rows at j/(n-1) */
    const intV x0 = convert_intV(fx), y0 = convert_intV(fy);
    const intV x1 = min(x0 + 1, (intV)(n - 1)), y1 = min(y0 + 1, (intV)(n - 1));
    const floatV ax = fx - convert_floatV(x0), ay = fy - convert_floatV(y0);
    const intV i00 = 3 * (y0 * n + x0), i01 = 3 * (y0 * n + x1), i10 = 3 * (y1 * n + x0), i11 = 3 * (y1 * n + x1);
#define ENV_BILERP(out, c) { \
        const floatV t00 = GATHER_F(e->dfg, i00 + c), t01 = GATHER_F(e->dfg, i01 + c); \
        const floatV t10 = GATHER_F(e->dfg, i10 + c), t11 = GATHER_F(e->dfg, i11 + c); \
        const floatV top_ = t00 + (t01 - t00) * ax, bot_ = t10 + (t11 - t10) * ax; \
        *(out) = top_ + (bot_ - top_) * ay; }
    ENV_BILERP(A, 0) ENV_BILERP(B, 1) ENV_BILERP(C, 2)
#undef ENV_BILERP
}

#endif
