/* chunk_cull.cl: per-chunk bounding boxes and their trivial reject against a view
 * (host side: clrender/passes/chunk_cull.py; consumer: setup.cl CHUNK_CULL=1).
 *
 * Algorithm: triangles are grouped in chunks of CHUNK consecutive triangles. `chunk_bounds`
 * computes each chunk's world-space AABB (one work-item per chunk; rerun only when the scene's
 * positions or triangles buffers are replaced). `chunk_cull` tests every box against the planes
 * setup.cl trivially rejects a triangle on (all three vertices outside one of them): the near
 * plane (CLIP_DEPTH >= near), the guard band |x|,|y| <= G·w and the viewport sides |x|,|y| <= w.
 * The box is outside a plane a·p + b >= 0 when max over its corners of a·p + b is below
 * -CULL_TOLERANCE times the magnitude of the terms: the margin covers setup.cl's float rounding,
 * so every vertex of a culled chunk is rejected by setup.cl on the same plane (conservative:
 * a box that only nearly misses is kept). A culled chunk's verdict is the status setup.cl gives
 * every one of its triangles: STATUS_CULLED_NEAR (behind the near plane), STATUS_OFFSCREEN (in
 * front of it, outside a side) or CHUNK_STRADDLES (outside a side, crossing the near plane:
 * setup.cl decides per triangle). The same work-group then compacts the visible chunks, in
 * increasing order, at the front of chunk_list and the culled ones at its back, so that
 * setup.cl can launch over slots and keep the prims in triangle order.
 *
 * Buffers: positions float[3V]; triangles int[3T]; bounds float[8·C]: lo.xyz, 0, hi.xyz, 0
 *          (±INFINITY when a vertex is not finite: never culled, setup.cl reports it invalid);
 *          view_proj float[16] row-major (setup.cl); out chunk_status uchar[C] (0 = visible),
 *          chunk_list int[C] (visible chunks ascending, then the culled ones), chunk_count int[1].
 * ORTHO=1: orthographic view, clip.w = 1 and the depth tested against near is clip.z (setup.cl).
 * Work-groups: chunk_bounds 1-D, any size; chunk_cull exactly one work-group of CULL_WG
 * work-items (local prefix sum, barriers) looping over the chunks CULL_WG at a time.
 */
#pragma OPENCL FP_CONTRACT OFF
#include "structs.h"

#ifndef CHUNK
#define CHUNK 128                /* triangles per chunk; setup.cl must be built with the same */
#endif
#ifndef CULL_WG
#define CULL_WG 64
#endif
#ifndef ORTHO
#define ORTHO 0
#endif
#ifndef GUARD_PIXELS
#define GUARD_PIXELS 262144.0f   /* setup.cl's guard band */
#endif
#ifndef CULL_TOLERANCE
#define CULL_TOLERANCE 1e-5f     /* relative margin, ~170 float ulps of the largest term */
#endif
#define CHUNK_STRADDLES 7        /* same value in setup.cl */

kernel void chunk_bounds(global const float* positions, global const int* triangles, int n_tris,
                         global float* bounds)
{
    const int c = get_global_id(0);
    if (c >= (n_tris + CHUNK - 1) / CHUNK) return;
    float lo[3] = { INFINITY, INFINITY, INFINITY }, hi[3] = { -INFINITY, -INFINITY, -INFINITY };
    int finite = 1;
    const int t1 = min(c * CHUNK + CHUNK, n_tris);
    for (int t = c * CHUNK; t < t1; ++t) {
        for (int i = 0; i < 3; ++i) {
            const int vi = triangles[3 * t + i];
            for (int k = 0; k < 3; ++k) {
                const float v = positions[3 * vi + k];
                finite &= isfinite(v);
                lo[k] = fmin(lo[k], v);     /* fmin drops NaN: `finite` catches it */
                hi[k] = fmax(hi[k], v);
            }
        }
    }
    for (int k = 0; k < 3; ++k) {
        bounds[8 * c + k] = finite ? lo[k] : -INFINITY;
        bounds[8 * c + 4 + k] = finite ? hi[k] : INFINITY;
    }
    bounds[8 * c + 3] = 0.0f;
    bounds[8 * c + 7] = 0.0f;
}

/* Is a·p + b < 0 (with margin) for every p of the box? a = Σ k_j·row_j of the matrix, b its
 * constant column; `scale` bounds Σ |k_j|·(|row_j·p| terms) so the margin tracks setup.cl's
 * rounding of each clip component. NaN or infinite boxes compare false: kept. */
static int box_outside(const float* a, const float* s, const float* lo, const float* hi)
{
    float m = a[3], scale = s[3];
    for (int k = 0; k < 3; ++k) {
        m += (a[k] > 0.0f) ? a[k] * hi[k] : a[k] * lo[k];
        scale += s[k] * fmax(fabs(lo[k]), fabs(hi[k]));
    }
    return m < -CULL_TOLERANCE * scale;
}

/* The chunk's verdict (0 = visible) against the view of matrix m. */
static int chunk_verdict(global const float* box, global const float* m, float gx, float gy, float near)
{
    const float lo[3] = { box[0], box[1], box[2] }, hi[3] = { box[4], box[5], box[6] };
    const int depth_row = ORTHO ? 2 : 3;
    float a[4], s[4], na[4];
    for (int k = 0; k < 4; ++k) {       /* near plane: depth - near >= 0, and its negation */
        a[k] = m[4 * depth_row + k];
        s[k] = fabs(a[k]);
    }
    a[3] -= near;
    s[3] += fabs(near);
    if (box_outside(a, s, lo, hi)) return STATUS_CULLED_NEAR;
    for (int k = 0; k < 4; ++k) na[k] = -a[k];
    const int in_front = box_outside(na, s, lo, hi);     /* depth - near > 0 everywhere */
    /* Sides k·w ± x >= 0 (x or y row, k = 1 viewport, gx/gy guard band): 8 planes. */
    for (int p = 0; p < 8; ++p) {
        const int row = (p & 2) ? 1 : 0;                  /* x or y */
        const float sign = (p & 1) ? 1.0f : -1.0f;        /* w - x or w + x */
        const float g = (p < 4) ? 1.0f : (row ? gy : gx);
        for (int k = 0; k < 4; ++k) {
            a[k] = g * m[12 + k] + sign * m[4 * row + k];
            s[k] = g * fabs(m[12 + k]) + fabs(m[4 * row + k]);
        }
        if (box_outside(a, s, lo, hi)) return in_front ? STATUS_OFFSCREEN : CHUNK_STRADDLES;
    }
    return 0;
}

kernel __attribute__((reqd_work_group_size(CULL_WG, 1, 1)))
void chunk_cull(global const float* bounds, int n_chunks, global const float* view_proj, int width, int height,
                float near, global uchar* chunk_status, global int* chunk_list, global int* chunk_count)
{
    local int sum[CULL_WG];
    const int lid = get_local_id(0);
    const float gx = GUARD_PIXELS * 2.0f / (float)width, gy = GUARD_PIXELS * 2.0f / (float)height;
    int visible = 0, culled = 0;        /* chunks placed so far at the front / back of the list */
    for (int c0 = 0; c0 < n_chunks; c0 += CULL_WG) {
        const int c = c0 + lid;
        int v = 1;
        if (c < n_chunks) {
            v = chunk_verdict(bounds + 8 * c, view_proj, gx, gy, near);
            chunk_status[c] = (uchar)v;
        }
        sum[lid] = (v == 0);
        barrier(CLK_LOCAL_MEM_FENCE);
        for (int d = 1; d < CULL_WG; d <<= 1) {          /* inclusive Hillis-Steele scan */
            const int x = (lid >= d) ? sum[lid - d] : 0;
            barrier(CLK_LOCAL_MEM_FENCE);
            sum[lid] += x;
            barrier(CLK_LOCAL_MEM_FENCE);
        }
        const int before = sum[lid], block = sum[CULL_WG - 1];
        const int in_block = min(CULL_WG, n_chunks - c0);
        if (c < n_chunks) {
            if (v == 0) chunk_list[visible + before - 1] = c;
            else chunk_list[n_chunks - 1 - (culled + lid - before)] = c;
        }
        visible += block;
        culled += in_block - block;
        barrier(CLK_LOCAL_MEM_FENCE);                     /* sum[] is rewritten next block */
    }
    if (lid == 0) chunk_count[0] = visible;
}
