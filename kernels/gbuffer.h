/* gbuffer.h: packing the G-buffer. The layout table lives in clrender/abi/gbuffer.py, which
 * passes these values with -D; the defaults below equal it (tests/test_gbuffer.py checks). */
#ifndef CLRENDER_GBUFFER_H
#define CLRENDER_GBUFFER_H

#ifndef GB_PLANES
#define GB_PLANES 6
#endif
#ifndef GB_ALBEDO_PLANE
#define GB_ALBEDO_PLANE 0
#endif
#ifndef GB_ALBEDO_SHIFT
#define GB_ALBEDO_SHIFT 0
#endif
#ifndef GB_SPECULAR_INTENSITY_PLANE
#define GB_SPECULAR_INTENSITY_PLANE 0
#endif
#ifndef GB_SPECULAR_INTENSITY_SHIFT
#define GB_SPECULAR_INTENSITY_SHIFT 24
#endif
#ifndef GB_LINEAR_DEPTH_PLANE
#define GB_LINEAR_DEPTH_PLANE 1
#endif
#ifndef GB_LINEAR_DEPTH_SHIFT
#define GB_LINEAR_DEPTH_SHIFT 0
#endif
#ifndef GB_NORMAL_PLANE
#define GB_NORMAL_PLANE 2
#endif
#ifndef GB_NORMAL_SHIFT
#define GB_NORMAL_SHIFT 0
#endif
#ifndef GB_SPECULAR_POWER_PLANE
#define GB_SPECULAR_POWER_PLANE 2
#endif
#ifndef GB_SPECULAR_POWER_SHIFT
#define GB_SPECULAR_POWER_SHIFT 24
#endif
#ifndef GB_VELOCITY_PLANE
#define GB_VELOCITY_PLANE 3
#endif
#ifndef GB_VELOCITY_SHIFT
#define GB_VELOCITY_SHIFT 0
#endif
#ifndef GB_TRIANGLE_ID_PLANE
#define GB_TRIANGLE_ID_PLANE 4
#endif
#ifndef GB_TRIANGLE_ID_SHIFT
#define GB_TRIANGLE_ID_SHIFT 0
#endif
#ifndef GB_EMISSIVE_PLANE
#define GB_EMISSIVE_PLANE 5
#endif
#ifndef GB_EMISSIVE_SHIFT
#define GB_EMISSIVE_SHIFT 0
#endif
#ifndef GB_OCCLUSION_PLANE
#define GB_OCCLUSION_PLANE 5
#endif
#ifndef GB_OCCLUSION_SHIFT
#define GB_OCCLUSION_SHIFT 24
#endif

#include "vec.h"

#define SPEC_POWER_LOG2_MAX 11.0f

/* Codecs, written for VEC-wide vectors (vec.h) so the resolve packs VEC pixels at once;
 * clrender/abi/gbuffer.py decodes them. */
static inline uintV unormV(floatV v, int bits)
{
    return convert_uintV(fmin(fmax(v, 0.0f), 1.0f) * (float)((1 << bits) - 1) + 0.5f);
}

/* The report's pack_float2 (section II.3), `bits` per value, rounded rather than truncated. */
static inline uintV pack_float2V(floatV a, floatV b, int bits)
{
    return (unormV(a, bits) << bits) | unormV(b, bits);
}

#ifndef SRGB_ENCODE_INTERVALS
#define SRGB_ENCODE_INTERVALS 4096
#endif

/* 8-bit sRGB encoding by table (clrender/abi/gbuffer.py srgb_encode_table): linear [0,1] in
 * SRGB_ENCODE_INTERVALS intervals, each with its base code and the one code boundary inside
 * it; exact rounding of the sRGB curve without pow(). */
static inline uintV pack_srgb8V(floatV x, constant float2* srgb_encode)
{
    floatV v = fmin(fmax(x, 0.0f), 1.0f);           /* fmax ignores NaN: NaN -> 0 */
    intV k = min(convert_intV(v * (float)SRGB_ENCODE_INTERVALS), SRGB_ENCODE_INTERVALS - 1);
    floatV threshold = GATHER_M(floatV, srgb_encode, k, x);
    uintV base = convert_uintV(GATHER_M(floatV, srgb_encode, k, y));
    return base + select((uintV)0u, (uintV)1u, as_uintV(v >= threshold));
}

static inline uintV pack_srgb8x3V(floatV r, floatV g, floatV b, constant float2* srgb_encode)
{
    return pack_srgb8V(r, srgb_encode) | (pack_srgb8V(g, srgb_encode) << 8) | (pack_srgb8V(b, srgb_encode) << 16);
}

/* Loads VEC consecutive words of a plane starting at pixel p0 (lanes past `valid` get `fill`). */
static inline uintV load_plane(global const uint* plane, int p0, int valid, uint fill)
{
    if (valid == VEC) return vloadV(0, plane + p0);
    uintV r = fill;
    for (int l = 0; l < valid; ++l) LANE_I(r, l) = (int)plane[p0 + l];
    return r;
}

/* Octahedral map of a unit vector onto [0,1]^2, 12 bits each, u in the low bits. */
static inline uintV pack_oct12x2V(floatV nx, floatV ny, floatV nz)
{
    floatV s = fabs(nx) + fabs(ny) + fabs(nz);
    floatV x = nx / s, y = ny / s;
    floatV sx = select((floatV)-1.0f, (floatV)1.0f, x >= 0.0f), sy = select((floatV)-1.0f, (floatV)1.0f, y >= 0.0f);
    floatV ox = select(x, (1.0f - fabs(y)) * sx, nz < 0.0f), oy = select(y, (1.0f - fabs(x)) * sy, nz < 0.0f);
    return unormV(ox * 0.5f + 0.5f, 12) | (unormV(oy * 0.5f + 0.5f, 12) << 12);
}

/* Inverse of pack_oct12x2V up to length: the caller normalizes (rsqrt where speed matters,
 * sqrt and divide where results must be bit-identical across devices). */
static inline void unpack_oct12x2V(uintV oct, floatV* x, floatV* y, floatV* z)
{
    floatV fx = convert_floatV(oct & 4095u) * (2.0f / 4095.0f) - 1.0f;
    floatV fy = convert_floatV((oct >> 12) & 4095u) * (2.0f / 4095.0f) - 1.0f;
    floatV fz = 1.0f - fabs(fx) - fabs(fy);
    floatV t = fmax(-fz, 0.0f);
    *x = fx + select(t, -t, fx >= 0.0f);
    *y = fy + select(t, -t, fy >= 0.0f);
    *z = fz;
}

static inline uintV pack_log2unorm8V(floatV power)
{
    return unormV(log2(clamp(power, 1.0f, 2048.0f)) / SPEC_POWER_LOG2_MAX, 8);
}

/* Two IEEE halves (round to nearest even), x in the low 16 bits. */
static inline uintV pack_half2V(floatV x, floatV y)
{
    ushort hx[VEC], hy[VEC];
    vstore_halfV(x, 0, (half*)hx);
    vstore_halfV(y, 0, (half*)hy);
    uintV r;
    for (int l = 0; l < VEC; ++l) LANE_I(r, l) = (int)((uint)hx[l] | ((uint)hy[l] << 16));
    return r;
}

/* planes[GB_<FIELD>_PLANE] |= value << GB_<FIELD>_SHIFT: where the table puts each field. */
#define GB_PUT(planes, FIELD, value) ((planes)[GB_##FIELD##_PLANE] |= (value) << GB_##FIELD##_SHIFT)
#endif
