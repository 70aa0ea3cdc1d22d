/* texture_vec.h: trilinear texture sampling for VEC lanes at once (vec.h), each lane with its
 * own texture, coordinates and footprint: the vector twin of texture.h, used by the surface
 * evaluation (surface_vec.h, material_eval.h).
 *
 * Layout as texture.h: texels uint[*] RGBA8 (R low byte), TexInfo -> TexLevel runs (mip 0
 * first). Colour bytes decode through a 512-entry table (sRGB at LUT_SRGB, linear at
 * LUT_LINEAR: TexInfo.lut) before filtering, so sRGB textures filter in linear space as GL's
 * SRGB8_ALPHA8 textures do. LOD: GL's, log2 of the longer screen footprint axis in level-0
 * texels, with a float-exponent log2 as texture units compute it. Lanes outside `active` read
 * texel 0 and get garbage the caller masks.
 */
#ifndef CLRENDER_TEXTURE_VEC_H
#define CLRENDER_TEXTURE_VEC_H
#include "structs.h"
#include "vec.h"

/* TEXELS_LINEAR 1: the pool holds every texel decoded, float4 linear RGBA (R, G, B through the
 * texture's own table, A = byte · (1/255): the values the RGBA8 path computes per sample), so a
 * sample is four float4 loads per lane instead of a word and three table lookups
 * (clrender/render/texture_pool.py linear_texels; lut0 and LINEAR then go unused: the host reads a
 * slot through another texture's footprint only in that texture's own colour space). 0: RGBA8
 * words, decoded per sample. */
#ifndef TEXELS_LINEAR
#define TEXELS_LINEAR 0
#endif
#if TEXELS_LINEAR
typedef float4 texel_t;
#else
typedef uint texel_t;
#endif

/* GATHER_MS/TS/FS/IS: GATHER_M/T/F/I (vec.h) for the scene's per-prim, per-vertex and
 * per-material records, which a run's lanes mostly share (one triangle covers the run): where
 * every lane's index is the same, one scalar load broadcast instead of VEC lane-by-lane loads
 * and inserts (AVX2 CPUs have no fast gather). The same values either way. */
#if VEC == 1
#define GATHER_MS(T, p, i, m) GATHER_M(T, p, i, m)
#define GATHER_TS(T, p, i) GATHER_T(T, p, i)
#else
#define UNIFORM_V(i) all((i) == (intV)(i).s0)
#define GATHER_MS(T, p, i, m) (UNIFORM_V(i) ? (T)((p)[(i).s0].m) : GATHER_M(T, p, i, m))
#define GATHER_TS(T, p, i) (UNIFORM_V(i) ? (T)((p)[(i).s0]) : GATHER_T(T, p, i))
#endif
#define GATHER_FS(p, i) GATHER_TS(floatV, p, i)

/* VINLINE: always_inline on CPUs (VEC > 1) for the small helpers that take and return vectors,
 * which the inliner otherwise leaves as calls passing every vector through the stack. */
#if VEC > 1 && defined(__clang__)
#define VINLINE __attribute__((always_inline))
#else
#define VINLINE
#endif
#define GATHER_IS(p, i) GATHER_TS(intV, p, i)

/* Texture coordinate folded into one period: repeat [0,1), mirror/clamp [0,1]. */
static inline floatV foldV(floatV u, intV mode)
{
    u = fmin(fmax(u, -1.0e9f), 1.0e9f);     /* NaN -> -1e9 (fmax ignores NaN) */
    floatV rep = u - floor(u);
    floatV t = u - 2.0f * floor(u * 0.5f);
    floatV mir = select(t, 2.0f - t, t > 1.0f);
    floatV clm = clamp(u, (floatV)0.0f, (floatV)1.0f);
    return select(select(clm, mir, mode == WRAP_MIRROR), rep, mode == WRAP_REPEAT);
}

static inline intV wrap_edgeV(intV i, intV size, intV mode)
{
    intV rep = select(select(i, (intV)0, i >= size), size - 1, i < 0);
    return select(clamp(i, (intV)0, size - 1), rep, mode == WRAP_REPEAT);
}

typedef struct { floatV r, g, b, a; } rgbaV;

/* One mip level's bilinear footprint: the four texel indices and the weights. */
typedef struct { intV idx[4]; floatV ax, ay; } BilinearV;

/* The footprint in per-lane levels (offset/width/height) of folded coordinates. */
static inline VINLINE BilinearV bilinear_at(intV offset, intV width, intV height, intV wrap_s, intV wrap_t, floatV u, floatV v)
{
    BilinearV q;
    floatV fx = foldV(u, wrap_s) * convert_floatV(width) - 0.5f;
    floatV fy = foldV(v, wrap_t) * convert_floatV(height) - 0.5f;
    intV x0 = convert_intV(fx + 1.0f) - 1, y0 = convert_intV(fy + 1.0f) - 1;   /* floor, fx >= -0.5 */
    q.ax = fx - convert_floatV(x0); q.ay = fy - convert_floatV(y0);
    intV xa = wrap_edgeV(x0, width, wrap_s), xb = wrap_edgeV(x0 + 1, width, wrap_s);
    intV ya = wrap_edgeV(y0, height, wrap_t), yb = wrap_edgeV(y0 + 1, height, wrap_t);
    q.idx[0] = offset + ya * width + xa; q.idx[1] = offset + ya * width + xb;
    q.idx[2] = offset + yb * width + xa; q.idx[3] = offset + yb * width + xb;
    return q;
}

/* Filters the footprint q of the texture `delta` texels after the one it was computed for (a
 * texture with the same mip chain sizes). R, G, B bytes decode through lut[lut0 + byte] (sRGB or
 * linear table: structs.h LUT_*) or, with LINEAR, as byte / 255 (the LUT_LINEAR table's values,
 * computed); inactive lanes read texel 0. */
static inline VINLINE rgbaV bilinear_fetch(global const texel_t* texels, constant float* lut, intV lut0, int linear,
                                   intV active, const BilinearV* q, intV delta)
{
    rgbaV t[4];
    for (int k = 0; k < 4; ++k) {
        intV i = select((intV)0, q->idx[k] + delta, active);
#if TEXELS_LINEAR
        t[k].r = GATHER_M(floatV, texels, i, x);
        t[k].g = GATHER_M(floatV, texels, i, y);
        t[k].b = GATHER_M(floatV, texels, i, z);
        t[k].a = GATHER_M(floatV, texels, i, w);
#else
        uintV w = GATHER_U(texels, i);
        if (linear) {
            t[k].r = convert_floatV(w & 255u) / 255.0f;
            t[k].g = convert_floatV((w >> 8) & 255u) / 255.0f;
            t[k].b = convert_floatV((w >> 16) & 255u) / 255.0f;
        } else {
            t[k].r = GATHER_F(lut, lut0 + as_intV(w & 255u));
            t[k].g = GATHER_F(lut, lut0 + as_intV((w >> 8) & 255u));
            t[k].b = GATHER_F(lut, lut0 + as_intV((w >> 16) & 255u));
        }
        t[k].a = convert_floatV(w >> 24) * (1.0f / 255.0f);
#endif
    }
    rgbaV r;
    const floatV ax = q->ax, ay = q->ay;
#define BILERP(c) { floatV top = t[0].c + (t[1].c - t[0].c) * ax, bot = t[2].c + (t[3].c - t[2].c) * ax; \
                    r.c = top + (bot - top) * ay; }
    BILERP(r) BILERP(g) BILERP(b) BILERP(a)
#undef BILERP
    return r;
}

/* Per-lane mip level record `level` of texture `tex`. */
static inline void gather_level(global const TexLevel* levels, intV level, intV* offset, intV* w, intV* h)
{
    *offset = GATHER_MS(intV, levels, level, offset);
    *w = GATHER_MS(intV, levels, level, width);
    *h = GATHER_MS(intV, levels, level, height);
}

static inline floatV fast_log2V(floatV x)   /* exponent + linear mantissa, as texture units do */
{
    intV bits = as_intV(x);
    return convert_floatV((bits >> 23) - 127) + (as_floatV((bits & 0x007fffff) | 0x3f800000) - 1.0f);
}

/* A trilinear footprint: GL's LOD from the coordinates' screen derivatives, then the
 * bilinear footprints of levels floor(lod) and floor(lod) + 1 and the weight f of the second. */
typedef struct {
    BilinearV a, b;
    floatV f;
    intV active, active_b;      /* lanes sampled; lanes that read level b (f > 0) */
    intV base;                  /* the texture's level-0 texel offset (for deltas to other textures) */
    intV lut0;                  /* its decode table (TexInfo.lut) */
} FootprintV;

/* The footprint of texture tex (per lane; lanes outside `active` must still hold a valid index)
 * at (u, v) with screen derivatives (dux, dvx) along x and (duy, dvy) along y. */
static inline FootprintV footprint(global const TexInfo* tex_infos, global const TexLevel* tex_levels, intV tex,
                                   intV active, floatV u, floatV v, floatV dux, floatV dvx, floatV duy, floatV dvy)
{
    FootprintV fp;
    intV first = GATHER_MS(intV, tex_infos, tex, first_level), nlev = GATHER_MS(intV, tex_infos, tex, levels);
    intV wrap_s = GATHER_MS(intV, tex_infos, tex, wrap_s), wrap_t = GATHER_MS(intV, tex_infos, tex, wrap_t);
    fp.lut0 = GATHER_MS(intV, tex_infos, tex, lut);
    intV w0, h0;
    gather_level(tex_levels, first, &fp.base, &w0, &h0);
    floatV fw = convert_floatV(w0), fh = convert_floatV(h0);
    floatV rho2 = fmax((dux * fw) * (dux * fw) + (dvx * fh) * (dvx * fh),
                       (duy * fw) * (duy * fw) + (dvy * fh) * (dvy * fh));
    rho2 = fmin(fmax(rho2, 1e-20f), 1e30f);   /* NaN -> 1e-20: a finite LOD */
    floatV lod = fmin(fmax(0.5f * fast_log2V(rho2), 0.0f), convert_floatV(nlev - 1));
    intV l0 = convert_intV(lod), l1 = min(l0 + 1, nlev - 1);
    fp.f = lod - convert_floatV(l0);
    intV offa, wa, ha, offb, wb, hb;
    gather_level(tex_levels, first + l0, &offa, &wa, &ha);
    gather_level(tex_levels, first + l1, &offb, &wb, &hb);
    fp.a = bilinear_at(offa, wa, ha, wrap_s, wrap_t, u, v);
    fp.b = bilinear_at(offb, wb, hb, wrap_s, wrap_t, u, v);
    fp.active = active;
    fp.active_b = active & (fp.f > 0.0f);
    return fp;
}

/* The footprint fp filtered in the texture `delta` texels after fp's (same mip chain sizes and
 * wrap modes), decoded through lut0 or, with LINEAR, arithmetically. */
static inline rgbaV footprint_fetch(global const texel_t* texels, constant float* lut, intV lut0, int linear,
                                    const FootprintV* fp, intV delta)
{
    rgbaV ta = bilinear_fetch(texels, lut, lut0, linear, fp->active, &fp->a, delta);
    if (!ANY(fp->active_b)) return ta;      /* f = 0 on every active lane: ta + (tb - ta)·0 is ta */
    rgbaV tb = bilinear_fetch(texels, lut, lut0, linear, fp->active_b, &fp->b, delta);
    const floatV f = fp->f;
    rgbaV r = { ta.r + (tb.r - ta.r) * f, ta.g + (tb.g - ta.g) * f, ta.b + (tb.b - ta.b) * f,
                ta.a + (tb.a - ta.a) * f };
    return r;
}

/* Trilinear sample of texture tex: footprint() then footprint_fetch() through its own table. */
static inline rgbaV trilinearV(global const texel_t* texels, constant float* lut, global const TexInfo* tex_infos,
                               global const TexLevel* tex_levels, intV tex, intV active,
                               floatV u, floatV v, floatV dux, floatV dvx, floatV duy, floatV dvy, FootprintV* fp)
{
    *fp = footprint(tex_infos, tex_levels, tex, active, u, v, dux, dvx, duy, dvy);
    return footprint_fetch(texels, lut, fp->lut0, 0, fp, (intV)0);
}
#endif
