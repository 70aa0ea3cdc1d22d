/* abuffer.cl: resolve the A-buffer -- sort each pixel's transparent fragments, shade, blend.
 *
 * Algorithm (docs/transparency.md; the report's A-buffer, III.2): one work-item per pixel
 * takes its list (written by fragments.cl `fragment_fill`) and sorts it by the key
 * (z, prim index), a total order: an insertion sort in private memory for up to SORT_PRIVATE
 * fragments, an in-place heap sort of the global list beyond (long lists are sorted exactly,
 * never truncated). Then front to back: each fragment is shaded by forward.h (the tile's light
 * list, the sun, shadow maps) and blended under the layers in front of it, until the
 * transmittance falls below TRANSMITTANCE_EPSILON. The nearest fragment's refraction offset is
 * kept for composite.cl.
 *
 * Buffers: list_len/list_offsets int[W·H]; frag_depth float[capacity], frag_prim int[capacity]
 *          (a pixel's list: [offset, offset + len)); scene, camera and lights: FORWARD_PARAMS.
 *          out: layers float[6][W·H] = blended colour (3 planes), transmittance, refraction
 *          offset x, y (pixels).
 * Work-groups: 2-D (any shape), one pixel per work-item (VEC = 1); no barriers, no local memory.
 */
#pragma OPENCL FP_CONTRACT OFF
#ifndef VEC
#define VEC 1
#endif
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

static void heap_sort(global float* D, global int* P, int n)
{
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
                            global float* frag_depth, global int* frag_prim, FORWARD_PARAMS,
                            global float* layers)
{
    const int px = get_global_id(0), py = get_global_id(1);
    if (px >= width || py >= height) return;
    const int q = py * width + px;
    const int offset = list_offsets[q];
    const int n = (offset + list_len[q] <= capacity) ? list_len[q] : 0;   /* overflow: the frame is redone */
    const Forward f = FORWARD_INIT;
    float4 acc = (float4)(0.0f, 0.0f, 0.0f, 1.0f);
    float2 refract = (float2)(0.0f, 0.0f);
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
        for (int i = 0; i < n && acc.w >= TRANSMITTANCE_EPSILON; ++i) {
            const Fragment fr = shade_fragment(&f, p[i], d[i], px, py);
            if (i == 0) refract = fr.offset;
            acc = blend_under(acc, fr);
        }
    } else {
        heap_sort(D, P, n);
        for (int i = 0; i < n && acc.w >= TRANSMITTANCE_EPSILON; ++i) {
            const Fragment fr = shade_fragment(&f, P[i], D[i], px, py);
            if (i == 0) refract = fr.offset;
            acc = blend_under(acc, fr);
        }
    }
    store_layers(layers, width * height, q, acc, refract);
}
