/* abuffer.cl: resolve the A-buffer -- sort each pixel's transparent fragments, shade, blend.
 *
 * Algorithm (docs/transparency.md; the report's A-buffer, III.2):
 *  - `abuffer_sort`: one work-item per pixel sorts its list (written by fragments.cl
 *    `fragment_fill`) by the key (z, prim index), a total order, writing it back in place: an
 *    insertion sort in private memory for up to SORT_PRIVATE fragments, an in-place heap sort
 *    of the global list beyond (long lists are sorted exactly, never truncated).
 *  - `abuffer_resolve`: each work-item takes a run of VEC pixels of a row (inside one
 *    light-culling tile) and walks their sorted lists together, fragment i of every lane at a
 *    time: shaded by forward.h (the tile's light list, the sun, shadow maps) and blended under
 *    the fragments in front of it, lane by lane, until every lane's transmittance is below
 *    TRANSMITTANCE_EPSILON or its list ends. The nearest fragment's refraction offset is kept
 *    for composite.cl, and its triangle id (the nearest surface's: Frame.object_id).
 *
 * Buffers: list_len/list_offsets int[W·H]; frag_depth float[capacity], frag_prim int[capacity]
 *          (a pixel's list: [offset, offset + len)); scene, camera and lights: FORWARD_PARAMS.
 *          out: layers float[7][W·H] = blended colour (3 planes), transmittance, refraction
 *          offset x, y (pixels), the nearest fragment's triangle id (int bits, -1: none).
 *          TRANSMISSION (forward.h, transmission.h): a last argument tx_planes float[9][W·H] (forward.h
 *          store_tx); T per channel, the lookup set by the first transmissive or refracting fragment,
 *          the transmittance plane their mean, the refraction offset plane the G channel's.
 * Work-groups: 2-D, any shape; sort: a pixel per work-item; resolve: VEC pixels per work-item
 * (vec.h). No barriers, no local memory.
 */
#pragma OPENCL FP_CONTRACT OFF
#ifndef SORT_PRIVATE
#define SORT_PRIVATE 16
#endif
#include "forward.h"

#define KEY_LESS(d, p, d2, p2) ((d) < (d2) || ((d) == (d2) && (p) < (p2)))

/* Restores the max-heap below node i of the n-element heap (D, P). */
static void sift_down(global float* D, global int* P, int i, int n)
{
    const float d = D[i];
    const int p = P[i];
    for (;;) {
        int c = 2 * i + 1;
        if (c >= n) break;
        if (c + 1 < n && KEY_LESS(D[c], P[c], D[c + 1], P[c + 1])) ++c;
        if (!KEY_LESS(d, p, D[c], P[c])) break;
        D[i] = D[c];
        P[i] = P[c];
        i = c;
    }
    D[i] = d;
    P[i] = p;
}

kernel void abuffer_sort(global const int* list_len, global const int* list_offsets, int capacity,
                         int width, int height, global float* frag_depth, global int* frag_prim)
{
    const int px = get_global_id(0), py = get_global_id(1);
    if (px >= width || py >= height) return;
    const int q = py * width + px;
    const int offset = list_offsets[q], n = list_len[q];
    if (n < 2 || offset < 0 || n > capacity - offset) return;   /* overflow: the frame is redone */
    global float* D = frag_depth + offset;
    global int* P = frag_prim + offset;
    if (n <= SORT_PRIVATE) {
        float d[SORT_PRIVATE];
        int p[SORT_PRIVATE];
        for (int i = 0; i < n; ++i) {
            const float di = D[i];
            const int pi = P[i];
            int j = i;
            while (j > 0 && KEY_LESS(di, pi, d[j - 1], p[j - 1])) {
                d[j] = d[j - 1];
                p[j] = p[j - 1];
                --j;
            }
            d[j] = di;
            p[j] = pi;
        }
        for (int i = 0; i < n; ++i) {
            D[i] = d[i];
            P[i] = p[i];
        }
        return;
    }
    for (int i = n / 2 - 1; i >= 0; --i) sift_down(D, P, i, n);
    for (int end = n - 1; end > 0; --end) {
        const float d = D[0];
        const int p = P[0];
        D[0] = D[end];
        P[0] = P[end];
        D[end] = d;
        P[end] = p;
        sift_down(D, P, 0, end);
    }
}

kernel void abuffer_resolve(global const int* list_len, global const int* list_offsets, int capacity,
                            global const float* frag_depth, global const int* frag_prim, FORWARD_PARAMS,
                            global float* layers
#if TRANSMISSION
                            , global float* tx_planes
#endif
                            )
{
    const int px0 = get_global_id(0) * VEC, py = get_global_id(1);
    if (px0 >= width || py >= height) return;
    const int npix = width * height;
    intV n = 0, offset = 0;
    int longest = 0;
    for (int l = 0; l < VEC && px0 + l < width; ++l) {
        const int q = py * width + px0 + l;
        const int len = (list_offsets[q] >= 0 && list_len[q] <= capacity - list_offsets[q]) ? list_len[q] : 0;
        LANE_I(n, l) = len;
        LANE_I(offset, l) = list_offsets[q];
        longest = max(longest, len);
    }
    const Forward f = FORWARD_INIT;
    floatV ar = 0.0f, ag = 0.0f, ab = 0.0f, t = 1.0f, ox = 0.0f, oy = 0.0f;
    intV nearest = -1;
#if TRANSMISSION   /* per-channel T, the lookup (forward.h take_lookup), the nearest transmissive depth */
    floatV tr = 1.0f, tg = 1.0f, tb = 1.0f, lod = -1.0f, oxr = 0.0f, oyr = 0.0f, oxb = 0.0f, oyb = 0.0f;
    floatV near_z = -1.0f;
    for (int i = 0; i < longest; ++i) {
        const intV active = ((intV)i < n) & (fmax(tr, fmax(tg, tb)) >= TRANSMITTANCE_EPSILON);
        if (!ANY(active)) break;
        intV pi = 0;
        floatV z = 1.0f;
        for (int l = 0; l < VEC; ++l)
            if (LANE_I(active, l)) {
                LANE_I(pi, l) = frag_prim[LANE_I(offset, l) + i];
                LANE_F(z, l) = frag_depth[LANE_I(offset, l) + i];
            }
        const FragmentsV fr = shade_fragments(&f, pi, z, active, px0, py);
        if (i == 0) {
            near_z = select((floatV)-1.0f, z, active & (fr.lod > -0.5f));
            for (int l = 0; l < VEC; ++l)
                if (LANE_I(active, l)) LANE_I(nearest, l) = f.scene.prims[LANE_I(pi, l)].tri;
        }
        take_lookup(fr, active, &lod, &ox, &oy, &oxr, &oyr, &oxb, &oyb);
        blend_under_tx(fr, active, &ar, &ag, &ab, &tr, &tg, &tb);
    }
    t = select((tr + tg + tb) / 3.0f, tr, (tr == tg) & (tg == tb));   /* untinted: T itself, bit for bit */
    for (int l = 0; l < VEC && px0 + l < width; ++l)
        store_tx(tx_planes, npix, py * width + px0 + l, l, tr, tg, tb, lod, oxr, oyr, oxb, oyb, near_z);
#else
    for (int i = 0; i < longest; ++i) {
        const intV active = ((intV)i < n) & (t >= TRANSMITTANCE_EPSILON);
        if (!ANY(active)) break;
        intV pi = 0;
        floatV z = 1.0f;
        for (int l = 0; l < VEC; ++l)
            if (LANE_I(active, l)) {
                LANE_I(pi, l) = frag_prim[LANE_I(offset, l) + i];
                LANE_F(z, l) = frag_depth[LANE_I(offset, l) + i];
            }
        const FragmentsV fr = shade_fragments(&f, pi, z, active, px0, py);
        if (i == 0) {
            ox = select((floatV)0.0f, fr.ox, active);
            oy = select((floatV)0.0f, fr.oy, active);
            for (int l = 0; l < VEC; ++l)
                if (LANE_I(active, l)) LANE_I(nearest, l) = f.scene.prims[LANE_I(pi, l)].tri;
        }
        blend_under(fr, active, &ar, &ag, &ab, &t);
    }
#endif
    for (int l = 0; l < VEC && px0 + l < width; ++l)
        store_layers(layers, npix, py * width + px0 + l, l, ar, ag, ab, t, ox, oy, nearest);
}
