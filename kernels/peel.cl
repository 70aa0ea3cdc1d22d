/* peel.cl: depth peeling -- shade one peeled layer and blend it under the layers before it.
 *
 * Algorithm (docs/transparency.md; the report's depth peeling, III.2): fragments.cl
 * `fragment_next_layer` finds, per pixel, layer k's fragment (the smallest key (z, prim) after
 * layer k-1's: the same total order as the A-buffer's sort, so coplanar fragments peel one by
 * one); this kernel shades it with forward.h and blends it front to back ("under": the same
 * result as compositing the stored layers back to front, without storing them). Layer 0
 * starts from T = 1 and keeps its fragment's refraction offset. A pixel whose transmittance is
 * already below TRANSMITTANCE_EPSILON is left as it is, as the A-buffer stops there too: with
 * peel_layers >= the largest fragment count the result equals the A-buffer bit for bit.
 *
 * Buffers: layer_depth float[W·H], layer_prim int[W·H] (-1: nothing at this layer);
 *          scene, camera and lights: FORWARD_PARAMS; layers float[6][W·H] (abuffer.cl's layout:
 *          colour planes, transmittance, refraction offset), read and written.
 * Work-groups: 2-D (any shape), one pixel per work-item (VEC = 1); no barriers, no local memory.
 */
#pragma OPENCL FP_CONTRACT OFF
#ifndef VEC
#define VEC 1
#endif
#include "forward.h"

kernel void peel_shade(global const float* layer_depth, global const int* layer_prim, int layer,
                       FORWARD_PARAMS, global float* layers)
{
    const int px = get_global_id(0), py = get_global_id(1);
    if (px >= width || py >= height) return;
    const int q = py * width + px, npix = width * height;
    float4 acc = (float4)(0.0f, 0.0f, 0.0f, 1.0f);
    float2 refract = (float2)(0.0f, 0.0f);
    if (layer > 0) {
        acc = (float4)(layers[q], layers[npix + q], layers[2 * npix + q], layers[3 * npix + q]);
        refract = (float2)(layers[4 * npix + q], layers[5 * npix + q]);
    }
    const int pi = layer_prim[q];
    if (pi >= 0 && acc.w >= TRANSMITTANCE_EPSILON) {
        const Forward f = FORWARD_INIT;
        const Fragment fr = shade_fragment(&f, pi, layer_depth[q], px, py);
        if (layer == 0) refract = fr.offset;
        acc = blend_under(acc, fr);
    } else if (layer > 0) {
        return;                          /* unchanged */
    }
    store_layers(layers, npix, q, acc, refract);
}
