/* composite.cl: the transparent layers over the shaded opaque image (docs/transparency.md,
 * docs/transmission.md).
 *
 * Algorithm: one work-item per pixel: color = acc + T·opaque(q), where acc and T come from the
 * A-buffer or depth peeling (the `layers` planes) and q is the pixel itself or, with
 * REFRACTION, the pixel displaced by the nearest transparent fragment's refraction offset
 * (the report's "dérivation des rayons": a cheap distortion of what lies behind, read
 * bilinearly from the opaque image, clamped to its edges). Pixels without a fragment
 * (T = 1, acc = 0, offset 0) copy the opaque colour unchanged.
 * TRANSMISSION=1 (a scene with transmissive materials): T is per channel (tx planes 0..2) and
 * the lookup is the tx planes' lod (plane 3): -1 the pixel itself (as above); -2 a BLEND
 * fragment's refraction offset (the REFRACTION lookup above; the pixel itself without
 * REFRACTION); >= 0 channel c reads the opaque colour's mip chain (transmission.cl) trilinearly
 * at (x + ox_c, y + oy_c), pixel-index coordinates (pixel x's centre at x), offsets R = tx 4, 5,
 * G = layers 4, 5, B = tx 6, 7; on level l that point is at (s + 0.5)/2^l - 0.5, clamped to the
 * level's pixel centres; lod is clamped to [0, levels - 1] and blends its two nearest levels.
 *
 * Buffers: opaque float[3][W·H] (shade.cl's HDR colour); layers float[7][W·H] (colour planes,
 *          transmittance, offset x, y). out: color float[3][W·H]. TRANSMISSION: tx float[9][W·H]
 *          (clrender/passes/forward.py TX_PLANES), mips float[] (levels 1.. of the chain, 3
 *          planes each), mip_table int[levels][4] (offset in floats, w, h, 0; level 0 is
 *          `opaque`), levels.
 * Work-groups: 1-D, any size; no barriers, no local memory.
 */
#pragma OPENCL FP_CONTRACT OFF
#ifndef REFRACTION
#define REFRACTION 0
#endif
#ifndef TRANSMISSION
#define TRANSMISSION 0
#endif

#if TRANSMISSION
/* Channel c of mip level l, bilinear at level-0 pixel position (sx, sy), clamped to the level. */
static float mip_bilinear(global const float* opaque, global const float* mips, global const int* table,
                          int l, int c, float sx, float sy)
{
    const int w = table[4 * l + 1], h = table[4 * l + 2];
    global const float* plane = (l == 0 ? opaque : mips) + table[4 * l] + c * w * h;
    const float scale = (float)(1 << l);          /* a power of two: the divisions are exact */
    /* fmin/fmax: a NaN coordinate lands on a pixel instead of an undefined index */
    const float u = fmin(fmax((sx + 0.5f) / scale - 0.5f, 0.0f), (float)(w - 1));
    const float v = fmin(fmax((sy + 0.5f) / scale - 0.5f, 0.0f), (float)(h - 1));
    const int x0 = (int)u, y0 = (int)v;
    const int x1 = min(x0 + 1, w - 1), y1 = min(y0 + 1, h - 1);
    const float ax = u - (float)x0, ay = v - (float)y0;
    const float top = plane[y0 * w + x0] + (plane[y0 * w + x1] - plane[y0 * w + x0]) * ax;
    const float bot = plane[y1 * w + x0] + (plane[y1 * w + x1] - plane[y1 * w + x0]) * ax;
    return top + (bot - top) * ay;
}

/* Channel c of the chain at level-0 position (sx, sy), level lod >= 0 (clamped to the chain). */
static float mip_trilinear(global const float* opaque, global const float* mips, global const int* table,
                           int levels, float lod, int c, float sx, float sy)
{
    const float l = fmin(lod, (float)(levels - 1));
    const int l0 = (int)l;
    const float f = l - (float)l0;
    const float s0 = mip_bilinear(opaque, mips, table, l0, c, sx, sy);
    if (f == 0.0f) return s0;
    const float s1 = mip_bilinear(opaque, mips, table, l0 + 1, c, sx, sy);
    return s0 + (s1 - s0) * f;
}
#define LEGACY_LOOKUP (lod == -2.0f)
#else
#define LEGACY_LOOKUP 1
#endif

kernel void composite(global const float* opaque, global const float* layers, int width, int height,
                      global float* color
#if TRANSMISSION
                      , global const float* tx, global const float* mips, global const int* mip_table,
                      int levels
#endif
                      )
{
    const int q = get_global_id(0), npix = width * height;
    if (q >= npix) return;
#if TRANSMISSION
    const float tr = tx[q], tg = tx[npix + q], tb = tx[2 * npix + q];
    const float lod = tx[3 * npix + q];
    if (lod >= 0.0f) {
        const float x = (float)(q % width), y = (float)(q / width);
        const float br = mip_trilinear(opaque, mips, mip_table, levels, lod, 0, x + tx[4 * npix + q],
                                       y + tx[5 * npix + q]);
        const float bg = mip_trilinear(opaque, mips, mip_table, levels, lod, 1, x + layers[4 * npix + q],
                                       y + layers[5 * npix + q]);
        const float bb = mip_trilinear(opaque, mips, mip_table, levels, lod, 2, x + tx[6 * npix + q],
                                       y + tx[7 * npix + q]);
        color[q] = layers[q] + tr * br;
        color[npix + q] = layers[npix + q] + tg * bg;
        color[2 * npix + q] = layers[2 * npix + q] + tb * bb;
        return;
    }
#else
    const float t = layers[3 * npix + q];
    const float tr = t, tg = t, tb = t;
#endif
    float3 behind;
#if REFRACTION
    const float ox = layers[4 * npix + q], oy = layers[5 * npix + q];
    if (LEGACY_LOOKUP && (ox != 0.0f || oy != 0.0f)) {
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
    color[q] = layers[q] + tr * behind.x;
    color[npix + q] = layers[npix + q] + tg * behind.y;
    color[2 * npix + q] = layers[2 * npix + q] + tb * behind.z;
}
