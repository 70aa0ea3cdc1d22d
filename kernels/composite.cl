/* composite.cl: the transparent layers over the shaded opaque image (docs/transparency.md).
 *
 * Algorithm: one work-item per pixel: color = acc + T·opaque(q), where acc and T come from the
 * A-buffer or depth peeling (the `layers` planes) and q is the pixel itself or, with
 * REFRACTION, the pixel displaced by the nearest transparent fragment's refraction offset
 * (the report's "dérivation des rayons": a cheap distortion of what lies behind, read
 * bilinearly from the opaque image, clamped to its edges). Pixels without a fragment
 * (T = 1, acc = 0, offset 0) copy the opaque colour unchanged.
 *
 * Buffers: opaque float[3][W·H] (shade.cl's HDR colour); layers float[7][W·H] (colour planes,
 *          transmittance, offset x, y). out: color float[3][W·H].
 * Work-groups: 1-D, any size; no barriers, no local memory.
 */
#pragma OPENCL FP_CONTRACT OFF
#ifndef REFRACTION
#define REFRACTION 0
#endif

kernel void composite(global const float* opaque, global const float* layers, int width, int height,
                      global float* color)
{
    const int q = get_global_id(0), npix = width * height;
    if (q >= npix) return;
    const float t = layers[3 * npix + q];
    float3 behind;
#if REFRACTION
    const float ox = layers[4 * npix + q], oy = layers[5 * npix + q];
    if (ox != 0.0f || oy != 0.0f) {
        /* Bilinear lookup at the displaced pixel center, clamped to the image. */
        const float sx = clamp((float)(q % width) + ox, 0.0f, (float)(width - 1));
        const float sy = clamp((float)(q / width) + oy, 0.0f, (float)(height - 1));
        const int x0 = (int)sx, y0 = (int)sy;
        const int x1 = min(x0 + 1, width - 1), y1 = min(y0 + 1, height - 1);
        const float ax = sx - (float)x0, ay = sy - (float)y0;
        float c[3];
        for (int k = 0; k < 3; ++k) {
            global const float* plane = opaque + k * npix;
            const float top = plane[y0 * width + x0] + (plane[y0 * width + x1] - plane[y0 * width + x0]) * ax;
            const float bot = plane[y1 * width + x0] + (plane[y1 * width + x1] - plane[y1 * width + x0]) * ax;
            c[k] = top + (bot - top) * ay;
        }
        behind = (float3)(c[0], c[1], c[2]);
    } else
#endif
    behind = (float3)(opaque[q], opaque[npix + q], opaque[2 * npix + q]);
    color[q] = layers[q] + t * behind.x;
    color[npix + q] = layers[npix + q] + t * behind.y;
    color[2 * npix + q] = layers[2 * npix + q] + t * behind.z;
}
