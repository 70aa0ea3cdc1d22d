/* prim.h: evaluating a Prim at a sample point (docs/raster_contract.md §5-6).
 * Shared by raster.cl (coverage, depth, alpha mask) and gbuffer.cl (attributes). */
#ifndef CLRENDER_PRIM_H
#define CLRENDER_PRIM_H
#include "structs.h"

#ifndef ORTHO
#define ORTHO 0          /* 1: orthographic prims (setup.cl): inv_w holds depths, weights are affine */
#endif

/* Edge functions at fixed-point sample (sx, sy): e[k] for edge k -> k+1. */
static inline void prim_edges(const Prim* p, long sx, long sy, long e[3])
{
    for (int k = 0; k < 3; ++k) {
        int k1 = (k + 1) % 3;
        long dx = p->x[k1] - p->x[k], dy = p->y[k1] - p->y[k];
        e[k] = dx * (sy - p->y[k]) - dy * (sx - p->x[k]);
    }
}

static inline bool edge_is_top_left(const Prim* p, int k)
{
    int k1 = (k + 1) % 3;
    int dx = p->x[k1] - p->x[k], dy = p->y[k1] - p->y[k];
    return (dy == 0 && dx > 0) || dy < 0;
}

/* Perspective-correct weights of the prim's vertices from its edge values (may be outside
 * [0,1] when extrapolating to a neighbouring pixel for derivatives). */
static inline float3 prim_weights(const Prim* p, const long e[3])
{
#if ORTHO
    float w0 = (float)e[1], w1 = (float)e[2], w2 = (float)e[0];
#else
    float w0 = (float)e[1] * p->inv_w[0];
    float w1 = (float)e[2] * p->inv_w[1];
    float w2 = (float)e[0] * p->inv_w[2];
#endif
    float inv = 1.0f / ((w0 + w1) + w2);
    return (float3)(w0 * inv, w1 * inv, w2 * inv);
}

/* Barycentric coordinates (b0, b1, b2) in the input triangle from prim-vertex weights. */
static inline float3 triangle_barycentrics(const Prim* p, float3 w)
{
    float b1 = w.x * p->bary1[0] + w.y * p->bary1[1] + w.z * p->bary1[2];
    float b2 = w.x * p->bary2[0] + w.y * p->bary2[1] + w.z * p->bary2[2];
    return (float3)(1.0f - b1 - b2, b1, b2);
}

/* Barycentrics at the fixed-point sample (sx, sy) (a pixel centre is 256·px + 128) and one pixel
 * right and down of it, for derivatives. */
static inline void prim_barycentrics_with_derivatives(const Prim* p, long sx, long sy,
                                                      float3* b, float3* b_dx, float3* b_dy)
{
    long e[3], ex[3], ey[3];
    prim_edges(p, sx, sy, e);
    for (int k = 0; k < 3; ++k) {
        int k1 = (k + 1) % 3;
        ex[k] = e[k] - (long)(p->y[k1] - p->y[k]) * 256;
        ey[k] = e[k] + (long)(p->x[k1] - p->x[k]) * 256;
    }
    *b = triangle_barycentrics(p, prim_weights(p, e));
    *b_dx = triangle_barycentrics(p, prim_weights(p, ex)) - *b;
    *b_dy = triangle_barycentrics(p, prim_weights(p, ey)) - *b;
}
#endif
