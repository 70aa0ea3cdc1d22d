/* gbuffer.h: packing the G-buffer. The layout table lives in clrender/gbuffer.py, which
 * passes these values with -D; the defaults below equal it (tests/test_gbuffer.py checks). */
#ifndef CLRENDER_GBUFFER_H
#define CLRENDER_GBUFFER_H

#ifndef GB_PLANES
#define GB_PLANES 5
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

#define SPEC_POWER_LOG2_MAX 11.0f

static inline uint unorm(float v, int bits)
{
    return (uint)(clamp(v, 0.0f, 1.0f) * (float)((1 << bits) - 1) + 0.5f);
}

/* The report's pack_float2 (section II.3), generalised to `bits` per value and rounded. */
static inline uint pack_float2(float2 f, int bits)
{
    return (unorm(f.x, bits) << bits) | unorm(f.y, bits);
}

/* sRGB encoding without pow(): srgb_bounds[k] is the linear value halfway between codes
 * k and k+1 (host-computed), so the code is the number of bounds below x (binary search). */
static inline uint srgb8_encode(float x, constant float* srgb_bounds)
{
    uint code = 0;
    for (uint step = 128; step > 0; step >>= 1)
        if (x >= srgb_bounds[code + step - 1]) code += step;
    return code;
}

static inline uint pack_srgb8x3(float3 c, constant float* srgb_bounds)
{
    return srgb8_encode(c.x, srgb_bounds) | (srgb8_encode(c.y, srgb_bounds) << 8)
         | (srgb8_encode(c.z, srgb_bounds) << 16);
}

static inline uint pack_unorm8(float v) { return unorm(v, 8); }

/* Octahedral map of a unit vector to [0,1]^2, 12 bits each, u in the low bits. */
static inline uint pack_oct12x2(float3 n)
{
    n /= fabs(n.x) + fabs(n.y) + fabs(n.z);
    float2 o = n.xy;
    if (n.z < 0.0f)
        o = (float2)((1.0f - fabs(n.y)) * (n.x >= 0.0f ? 1.0f : -1.0f),
                     (1.0f - fabs(n.x)) * (n.y >= 0.0f ? 1.0f : -1.0f));
    return unorm(o.x * 0.5f + 0.5f, 12) | (unorm(o.y * 0.5f + 0.5f, 12) << 12);
}

static inline uint pack_log2unorm8(float power)
{
    return unorm(log2(clamp(power, 1.0f, 2048.0f)) / SPEC_POWER_LOG2_MAX, 8);
}

static inline uint pack_half2(float2 v)
{
    ushort h[2];
    vstore_half2_rte(v, 0, (half*)h);
    return (uint)h[0] | ((uint)h[1] << 16);
}

#define GB_PUT(planes, FIELD, value) ((planes)[GB_##FIELD##_PLANE] |= (value) << GB_##FIELD##_SHIFT)
#endif
