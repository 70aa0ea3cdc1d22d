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
 *          scene, camera and lights: FORWARD_PARAMS; layers float[7][W·H] (abuffer.cl's layout:
 *          colour planes, transmittance, refraction offset, nearest triangle id), read (layer > 0)
 *          and written; layer 0 sets the nearest triangle. TRANSMISSION: a last argument tx_planes
 *          float[9][W·H] (forward.h store_tx), read (layer > 0) and written: the per-channel T and the
 *          lookup state (lod < -0.5: no fragment has set it yet) carry across layers.
 * Work-groups: 2-D, any shape; VEC pixels of a row per work-item (vec.h), inside one light
 * tile. No barriers, no local memory.
 */
#pragma OPENCL FP_CONTRACT OFF
#include "forward.h"

kernel void peel_shade(global const float* layer_depth, global const int* layer_prim, int layer,
                       FORWARD_PARAMS, global float* layers
#if TRANSMISSION
                       , global float* tx_planes
#endif
                       )
{
    const int px0 = get_global_id(0) * VEC, py = get_global_id(1);
    if (px0 >= width || py >= height) return;
    const int npix = width * height;
    floatV ar = 0.0f, ag = 0.0f, ab = 0.0f, t = 1.0f, ox = 0.0f, oy = 0.0f, z = 1.0f;
    intV pi = -1, nearest = -1;
#if TRANSMISSION   /* abuffer.cl's per-channel state, carried across layers in tx_planes */
    floatV tr = 1.0f, tg = 1.0f, tb = 1.0f, lod = -1.0f, oxr = 0.0f, oyr = 0.0f, oxb = 0.0f, oyb = 0.0f;
    floatV near_z = -1.0f;
    for (int l = 0; l < VEC && px0 + l < width; ++l) {
        const int q = py * width + px0 + l;
        LANE_I(pi, l) = layer_prim[q];
        LANE_F(z, l) = layer_depth[q];
        if (layer > 0) {
            LANE_F(ar, l) = layers[q];
            LANE_F(ag, l) = layers[npix + q];
            LANE_F(ab, l) = layers[2 * npix + q];
            LANE_F(ox, l) = layers[4 * npix + q];
            LANE_F(oy, l) = layers[5 * npix + q];
            LANE_I(nearest, l) = as_int(layers[6 * npix + q]);
            LANE_F(tr, l) = tx_planes[q];
            LANE_F(tg, l) = tx_planes[npix + q];
            LANE_F(tb, l) = tx_planes[2 * npix + q];
            LANE_F(lod, l) = tx_planes[3 * npix + q];
            LANE_F(oxr, l) = tx_planes[4 * npix + q];
            LANE_F(oyr, l) = tx_planes[5 * npix + q];
            LANE_F(oxb, l) = tx_planes[6 * npix + q];
            LANE_F(oyb, l) = tx_planes[7 * npix + q];
            LANE_F(near_z, l) = tx_planes[8 * npix + q];
        }
    }
    const intV active = (pi >= 0) & (fmax(tr, fmax(tg, tb)) >= TRANSMITTANCE_EPSILON);
    if (ANY(active)) {
        const Forward f = FORWARD_INIT;
        const FragmentsV fr = shade_fragments(&f, select((intV)0, pi, active), z, active, px0, py);
        if (layer == 0) {
            near_z = select((floatV)-1.0f, z, active & (fr.lod > -0.5f));
            for (int l = 0; l < VEC; ++l)
                if (LANE_I(active, l)) LANE_I(nearest, l) = f.scene.prims[LANE_I(pi, l)].tri;
        }
        take_lookup(fr, active, &lod, &ox, &oy, &oxr, &oyr, &oxb, &oyb);
        blend_under_tx(fr, active, &ar, &ag, &ab, &tr, &tg, &tb);
    } else if (layer > 0) {
        return;                          /* nothing peeled here: the layers stay as they are */
    }
    t = select((tr + tg + tb) / 3.0f, tr, (tr == tg) & (tg == tb));   /* untinted: T itself, bit for bit */
    for (int l = 0; l < VEC && px0 + l < width; ++l)
        store_tx(tx_planes, npix, py * width + px0 + l, l, tr, tg, tb, lod, oxr, oyr, oxb, oyb, near_z);
#else
    for (int l = 0; l < VEC && px0 + l < width; ++l) {
        const int q = py * width + px0 + l;
        LANE_I(pi, l) = layer_prim[q];
        LANE_F(z, l) = layer_depth[q];
        if (layer > 0) {
            LANE_F(ar, l) = layers[q];
            LANE_F(ag, l) = layers[npix + q];
            LANE_F(ab, l) = layers[2 * npix + q];
            LANE_F(t, l) = layers[3 * npix + q];
            LANE_F(ox, l) = layers[4 * npix + q];
            LANE_F(oy, l) = layers[5 * npix + q];
            LANE_I(nearest, l) = as_int(layers[6 * npix + q]);
        }
    }
    const intV active = (pi >= 0) & (t >= TRANSMITTANCE_EPSILON);
    if (ANY(active)) {
        const Forward f = FORWARD_INIT;
        const FragmentsV fr = shade_fragments(&f, select((intV)0, pi, active), z, active, px0, py);
        if (layer == 0) {
            ox = select((floatV)0.0f, fr.ox, active);
            oy = select((floatV)0.0f, fr.oy, active);
            for (int l = 0; l < VEC; ++l)
                if (LANE_I(active, l)) LANE_I(nearest, l) = f.scene.prims[LANE_I(pi, l)].tri;
        }
        blend_under(fr, active, &ar, &ag, &ab, &t);
    } else if (layer > 0) {
        return;                          /* nothing peeled here: the layers stay as they are */
    }
#endif
    for (int l = 0; l < VEC && px0 + l < width; ++l)
        store_layers(layers, npix, py * width + px0 + l, l, ar, ag, ab, t, ox, oy, nearest);
}
