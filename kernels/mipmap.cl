/* mipmap.cl: one mip level of the texture pool from the level above (clrender/render/texture_pool.py).
 *
 * Algorithm: bit-identical to the host definition `texture_pool.mip_chain` (PIL's BOX resize of
 * float32 linear channels, then 8-bit encoding). PIL resizes in two passes, each output a sum, in
 * double and in tap order, of float inputs times double weights, rounded to float after each
 * pass; rows first, or columns first when the image is much taller than wide (`vertical_first`,
 * from the host's `pil_vertical_first`). `mip_level` does that with the host's taps (`box_taps`);
 * `mip_half`, for the usual axes (halved from an even size: 2 taps of 0.5, or staying 1), uses
 * floats: a * 0.5 + b * 0.5 of two floats is exact, so one float rounding equals PIL's.
 * Level 1 (from_texels = 1, a runtime argument: one program for every level) decodes the 8-bit
 * level 0 through the decode tables (the host's float32 values); later levels read the float values
 * the previous launch kept. Encoding: linear codes as the host computes them, in float; sRGB codes
 * from a table of ENCODE_INTERVALS equal intervals of [0, 1], entry (threshold, base): code = base +
 * (x >= threshold), built by the host from its own encoder's exact thresholds (`encode_table`; at
 * most one code boundary per interval). No pow. FP_CONTRACT is off so that no multiply-add fuses
 * into an fma the host does not do. Needs cl_khr_fp64 (mip_level).
 *
 * Buffers: texels uint[] the pool, RGBA8 per uint (R low byte): level 0 read at src_offset (level 1
 * only), the new level written at dst_offset (dst_w x dst_h); src float4[] the level above's linear
 * values (rows of src_w), dst float4[dst_w * dst_h] the new level's (read by the next launch);
 * taps int4[] (first input, count, first weight, 0): dst_w entries from col_base, dst_h from
 * row_base; weights double[]; decode float[512]: sRGB[256] then linear[256];
 * encode float2[ENCODE_INTERVALS].
 * Work-groups: 2-D over (dst_w, dst_h) rounded up, any size; one work-item per output texel, no barriers.
 */
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
#pragma OPENCL FP_CONTRACT OFF

#ifndef ENCODE_INTERVALS
#define ENCODE_INTERVALS 4096
#endif

/* Texel (x, y) of the level above as float linear values. */
static inline float4 fetch(global const uint* texels, global const float4* src, int src_offset, int src_w,
                           int x, int y, int srgb, global const float* decode, int from_texels)
{
    if (from_texels) {
        const uint t = texels[src_offset + y * src_w + x];
        global const float* c = decode + (srgb ? 0 : 256);
        return (float4)(c[t & 0xffu], c[(t >> 8) & 0xffu], c[(t >> 16) & 0xffu], decode[256 + (t >> 24)]);
    }
    return src[y * src_w + x];
}

/* round(clip(x) * 255), in float as NumPy computes it. */
static inline uint encode_linear(float x)
{
    return (uint)floor(clamp(x, 0.0f, 1.0f) * 255.0f + 0.5f);
}

static inline uint encode_srgb(float x, global const float2* table)
{
    if (x >= 1.0f) return 255u;
    const float2 e = table[clamp((int)(x * (float)ENCODE_INTERVALS), 0, ENCODE_INTERVALS - 1)];
    return (uint)e.y + (x >= e.x ? 1u : 0u);
}

static inline uint encode4(float4 f, int srgb, global const float2* table)
{
    if (!srgb)
        return encode_linear(f.x) | (encode_linear(f.y) << 8) | (encode_linear(f.z) << 16) | (encode_linear(f.w) << 24);
    return encode_srgb(f.x, table) | (encode_srgb(f.y, table) << 8) | (encode_srgb(f.z, table) << 16)
           | (encode_linear(f.w) << 24);
}

kernel void mip_level(global uint* texels, global const float4* src, int srgb, int src_offset, int src_w,
                      global float4* dst, int dst_offset, int dst_w, int dst_h, global const int4* taps,
                      int col_base, int row_base, int vertical_first, global const double* weights,
                      global const float* decode, global const float2* encode, int from_texels)
{
    const int x = get_global_id(0), y = get_global_id(1);
    if (x >= dst_w || y >= dst_h) return;
    const int4 col = taps[col_base + x], row = taps[row_base + y];
    const int4 outer = vertical_first ? col : row, inner = vertical_first ? row : col;
    double4 v = (double4)(0.0);
    for (int j = 0; j < outer.y; j++) {
        double4 h = (double4)(0.0);
        for (int i = 0; i < inner.y; i++) {
            const int sx = vertical_first ? outer.x + j : inner.x + i, sy = vertical_first ? inner.x + i : outer.x + j;
            h += convert_double4(fetch(texels, src, src_offset, src_w, sx, sy, srgb, decode, from_texels)) * weights[inner.z + i];
        }
        v += convert_double4(convert_float4(h)) * weights[outer.z + j];
    }
    const float4 f = convert_float4(v);
    dst[y * dst_w + x] = f;
    texels[dst_offset + y * dst_w + x] = encode4(f, srgb, encode);
}

kernel void mip_half(global uint* texels, global const float4* src, int srgb, int src_offset, int src_w,
                     global float4* dst, int dst_offset, int dst_w, int dst_h, int nx, int ny, int vertical_first,
                     global const float* decode, global const float2* encode, int from_texels)
{
    const int x = get_global_id(0), y = get_global_id(1);
    if (x >= dst_w || y >= dst_h) return;
    const int x0 = nx * x, y0 = ny * y, x1 = x0 + nx - 1, y1 = y0 + ny - 1;
    const float4 a = fetch(texels, src, src_offset, src_w, x0, y0, srgb, decode, from_texels);
    const float4 b = fetch(texels, src, src_offset, src_w, x1, y0, srgb, decode, from_texels);
    const float4 c = fetch(texels, src, src_offset, src_w, x0, y1, srgb, decode, from_texels);
    const float4 d = fetch(texels, src, src_offset, src_w, x1, y1, srgb, decode, from_texels);
    float4 f;
    if (vertical_first) {
        const float4 l = ny == 2 ? a * 0.5f + c * 0.5f : a, r = ny == 2 ? b * 0.5f + d * 0.5f : b;
        f = nx == 2 ? l * 0.5f + r * 0.5f : l;
    } else {
        const float4 t = nx == 2 ? a * 0.5f + b * 0.5f : a, u = nx == 2 ? c * 0.5f + d * 0.5f : c;
        f = ny == 2 ? t * 0.5f + u * 0.5f : t;
    }
    dst[y * dst_w + x] = f;
    texels[dst_offset + y * dst_w + x] = encode4(f, srgb, encode);
}
