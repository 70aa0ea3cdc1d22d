/* tonemap.cl: HDR color -> display image (post-processing).
 *
 * Algorithm: one work-item per run of VEC pixels (vec.h): c = color · exposure, then the
 * operator `op`, a runtime argument (0: clamp, 1: Reinhard c/(1+c), 2: ACES fitted, Narkowicz
 * 2015; one program for all three, the branch is uniform over the launch and cost nothing
 * measurable, docs/programs.md), then sRGB encoding to 8 bits (gbuffer.h's encoder).
 *
 * `tonemap_ldr` stops before the encoding when LDR post effects follow (docs/post.md).
 *
 * Buffers: color float[3][H·W] linear HDR planes; srgb_encode float2[4096]; out: image uint[H·W] RGBA8 (R low byte,
 * alpha 255), or (tonemap_ldr) ldr float[3][H·W] tone-mapped linear values in [0, 1].
 * Work-groups: 1-D, any size; no barriers.
 */
#include "gbuffer.h"

static inline floatV tonemap(floatV c, int op)
{
    c = fmax(c, 0.0f);
    if (op == 1)
        return c / (1.0f + c);
    if (op == 2)
        return clamp((c * (2.51f * c + 0.03f)) / (c * (2.43f * c + 0.59f) + 0.14f), 0.0f, 1.0f);
    return clamp(c, 0.0f, 1.0f);
}

kernel void tonemap_image(global const float* color, int npix, float exposure, int op,
                          constant float2* srgb_encode, global uint* image)
{
    const int p0 = get_global_id(0) * VEC;
    if (p0 >= npix) return;
    if (p0 + VEC <= npix) {
        floatV r = vloadV(0, color + p0), g = vloadV(0, color + npix + p0), b = vloadV(0, color + 2 * npix + p0);
        uintV rgb = pack_srgb8x3V(tonemap(r * exposure, op), tonemap(g * exposure, op), tonemap(b * exposure, op),
                                  srgb_encode);
        vstoreV(rgb | 0xff000000u, 0, image + p0);
    } else {
        for (int p = p0; p < npix; ++p) {
            /* Tail: one pixel at a time through lane 0. */
            floatV r = color[p], g = color[npix + p], b = color[2 * npix + p];
            uintV rgb = pack_srgb8x3V(tonemap(r * exposure, op), tonemap(g * exposure, op), tonemap(b * exposure, op),
                                      srgb_encode);
            image[p] = (uint)LANE_I(rgb, 0) | 0xff000000u;
        }
    }
}

/* With LDR post effects (edge AA, FXAA; docs/post.md): the tone-mapped values, still linear,
 * as float planes for those passes; encode.cl makes the image afterwards. */
kernel void tonemap_ldr(global const float* color, int npix, float exposure, int op, global float* ldr)
{
    const int p0 = get_global_id(0) * VEC;
    if (p0 >= npix) return;
    for (int c = 0; c < 3; ++c) {
        if (p0 + VEC <= npix) {
            vstoreV(tonemap(vloadV(0, color + c * npix + p0) * exposure, op), 0, ldr + c * npix + p0);
        } else {
            for (int p = p0; p < npix; ++p) {
                floatV v = tonemap((floatV)(color[c * npix + p] * exposure), op);
                ldr[c * npix + p] = LANE_F(v, 0);
            }
        }
    }
}
