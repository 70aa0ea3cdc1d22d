/* texel_decode.cl: the texture pool decoded once, to float4 linear RGBA per texel
 * (texture_vec.h TEXELS_LINEAR; clrender/render/texture_pool.py linear_texels).
 *
 * Algorithm: what bilinear_fetch computes for every sample of the RGBA8 pool, done once per
 * texel: R, G, B through the texture's decode table (lut[lut0 + byte]: sRGB, or byte / 255
 * for linear textures) and A = byte · (1/255), so a sample of the decoded pool filters the same
 * floats and gives the same bits.
 * Buffers: texels uint[N] RGBA8 (R low byte); lut float[512] (LUT_SRGB, LUT_LINEAR);
 *          out float4[N]. One launch per texture: its mip chain is `count` texels from `first`.
 * Work-groups: 1-D, one texel per work-item, any size; no barriers.
 */
kernel void decode_texels(global const uint* texels, int first, int count, constant float* lut, int lut0,
                          global float4* out)
{
    const int i = get_global_id(0);
    if (i >= count) return;
    const uint w = texels[first + i];
    out[first + i] = (float4)(lut[lut0 + (w & 255u)], lut[lut0 + ((w >> 8) & 255u)], lut[lut0 + ((w >> 16) & 255u)],
                              (float)(w >> 24) * (1.0f / 255.0f));
}
