/* encode.cl: tone-mapped linear planes -> display image, at the end of the LDR post chain
 * (docs/post.md: tone map -> edge AA -> FXAA -> encode).
 *
 * Algorithm: one work-item per run of VEC pixels (vec.h): clamp to [0, 1] and sRGB-encode to 8
 * bits with gbuffer.h's exact table encoder, the same as tonemap.cl's fused path, so an image
 * made through the LDR planes equals the fused one where no effect changed a value.
 *
 * Buffers: ldr float[3][H·W]; srgb_encode float2[4096]; out: image uint[H·W] RGBA8 (R low byte,
 * alpha 255).
 * Work-groups: 1-D, any size; no barriers.
 */
#include "gbuffer.h"

kernel void encode_image(global const float* ldr, int npix, constant float2* srgb_encode, global uint* image)
{
    const int p0 = get_global_id(0) * VEC;
    if (p0 >= npix) return;
    if (p0 + VEC <= npix) {
        floatV r = vloadV(0, ldr + p0), g = vloadV(0, ldr + npix + p0), b = vloadV(0, ldr + 2 * npix + p0);
        uintV rgb = pack_srgb8x3V(clamp(r, 0.0f, 1.0f), clamp(g, 0.0f, 1.0f), clamp(b, 0.0f, 1.0f), srgb_encode);
        vstoreV(rgb | 0xff000000u, 0, image + p0);
    } else {
        for (int p = p0; p < npix; ++p) {
            floatV r = ldr[p], g = ldr[npix + p], b = ldr[2 * npix + p];
            uintV rgb = pack_srgb8x3V(clamp(r, 0.0f, 1.0f), clamp(g, 0.0f, 1.0f), clamp(b, 0.0f, 1.0f), srgb_encode);
            image[p] = (uint)LANE_I(rgb, 0) | 0xff000000u;
        }
    }
}
