/* light_quads.cl: per-tile light lists from each light's screen-space quad (report V.1, the
 * geometry-shader sprites: a camera-facing quad per light, drawn in one call, done in compute).
 *
 * Algorithm:
 *  1. (light_cull.cl's light_view_bounds: each light's culling sphere in view space, the point
 *     light's sphere or a spot cone's bounding sphere, SoA, padded to VEC with radius -1.)
 *  2. `light_quad_rects`: one work-item per light: the tight screen rectangle of the sphere's
 *     perspective projection, from exact tangent-plane bounds. Per image axis (x, then y) the
 *     sphere seen along the other axis is a disk of centre (c, D) (lateral offset, view depth
 *     D = -z) and radius r, and the rectangle's sides are the planes through the eye touching
 *     it (axis_slopes below): slopes s = (c·t ± D·r)/(D·t ∓ c·r), t = sqrt(c² + D² - r²), the
 *     roots of (D² - r²)s² - 2cDs + c² - r² = 0; pixel x = (s/tan_x + ox + 1)·W/2,
 *     y = (1 - oy - s/tan_y)·H/2, (ox, oy) the principal point in NDC (0 but for a pinhole K).
 *     A sphere that crosses the near plane is clipped by it first (Mara & McGuire 2013): a
 *     tangent point in front of the near plane gives way to the end of the disk's chord on it,
 *     so a sphere that holds the eye covers the whole screen and one beside the camera only
 *     its side; a sphere wholly before the near plane or beyond the far plane covers nothing
 *     (no pixel lies there). ORTHO (orthographic camera, parallel rays): the rectangle is the
 *     sphere's box, x = ((cx ± r)/tan_x + 1)·W/2, y = (1 - (cy ± r)/tan_y)·H/2. r is widened
 *     by 1e-4·r plus 1e-5 of the distances involved (float rounding of the centre and of the pixels' rebuilt positions), so every pixel whose
 *     position shade.cl finds inside the sphere (d² < r²) has its centre in the rectangle. The
 *     rectangle is kept (quad_rect, for tests and tools) and turned into the inclusive range of
 *     light tiles holding a pixel centre inside it (quad_tiles; empty: x0 > x1).
 *  3. `light_quads_count` / `light_quads_fill`: one work-item per tile tests every light's tile
 *     range, VEC lights at a time (the quad "rasterized" at tile resolution, no depth test);
 *     count, prefix sum (scan.cl), fill in light-index order, so the lists and the shading
 *     sums are the same on every run. The list buffer grows when the total says it must.
 *
 * Buffers: sphere_x/y/z/r float[n_padded] (view space); quad_rect float[4][n_padded] (pixel x0,
 *          y0, x1, y1; empty: x0 > x1); quad_tiles int[4][n_padded] (tile x0, y0, x1, y1,
 *          inclusive); tile_light_counts/offsets int[tiles]; tile_lights int[list_capacity]
 *          (the same layout as light_cull.cl's, read unchanged by shade.cl).
 * Work-groups: 1-D, any size; no barriers, no local memory.
 */
#pragma OPENCL FP_CONTRACT OFF
#include "vec.h"

#ifndef LTILE
#define LTILE 16
#endif
#ifndef ORTHO
#define ORTHO 0      /* 1: orthographic camera: tan_x, tan_y are the view box's half-extents */
#endif

/* The range (lo, hi) of u/D' over the points (u, D') of the disk of centre (c, D), radius r,
 * that lie at D' >= near: the sphere seen along one image axis (u = x or y, D' = view depth),
 * so lo/hi are the slopes of the planes through the eye that bound the sphere's part in front
 * of the near plane. From the eye outside the disk the tangents touch it at
 *     T = t·(c·t ± D·r, D·t ∓ c·r)/L²,  t = sqrt(L² - r²),  L² = c² + D²,
 *     slope (c·t ± D·r)/(D·t ∓ c·r);
 * a tangent point the near plane cuts away (or none, the eye inside the disk) leaves the
 * chord's end on D' = near, (c ± h)/near with h = sqrt(r² - (near - D)²). */
static inline float2 axis_slopes(float c, float D, float r, float near)
{
    const float L2 = c * c + D * D, r2 = r * r;
    const int clipped = D - r < near;
    const float h = clipped ? sqrt(fmax(r2 - (near - D) * (near - D), 0.0f)) : 0.0f;
    float2 s = (float2)((c - h) / near, (c + h) / near);
    if (L2 > r2) {
        const float t = sqrt(L2 - r2);
        const float den_lo = D * t + c * r, den_hi = D * t - c * r;
        if (!clipped || t * den_lo >= near * L2) s.x = (c * t - D * r) / den_lo;
        if (!clipped || t * den_hi >= near * L2) s.y = (c * t + D * r) / den_hi;
    }
    return s;
}

/* The inclusive range of pixels whose centre p + 0.5 lies in [lo, hi], clamped to [0, n). */
static inline int2 pixel_range(float lo, float hi, int n)
{
    const float first = ceil(clamp(lo - 0.5f, -1.0f, (float)n));
    const float last = floor(clamp(hi - 0.5f, -1.0f, (float)n));
    return (int2)(max((int)first, 0), min((int)last, n - 1));
}

kernel void light_quad_rects(global const float* sphere_x, global const float* sphere_y,
                             global const float* sphere_z, global const float* sphere_r, int n_padded,
                             int width, int height, float tan_x, float tan_y, float shift_x, float shift_y,
                             float near, float far,
                             float eye_distance, int tiles_x, int tiles_y,
                             global float* quad_rect, global int* quad_tiles)
{
    const int i = get_global_id(0);
    if (i >= n_padded) return;
    const float cx = sphere_x[i], cy = sphere_y[i], D = -sphere_z[i], r0 = sphere_r[i];
    float4 rect = (float4)(INFINITY, INFINITY, -INFINITY, -INFINITY);     /* empty */
    if (r0 >= 0.0f) {
        const float r = r0 + 1e-4f * r0 + 1e-5f * (fabs(cx) + fabs(cy) + fabs(D) + eye_distance);
        if (!(D + r < near || D - r > far)) {    /* else wholly before the near or beyond the far plane */
#if ORTHO
            const float2 sx = (float2)(cx - r, cx + r), sy = (float2)(cy - r, cy + r);
#else
            const float2 sx = axis_slopes(cx, D, r, near), sy = axis_slopes(cy, D, r, near);
#endif
            rect = (float4)((sx.x / tan_x + (1.0f + shift_x)) * 0.5f * (float)width,
                            ((1.0f - shift_y) - sy.y / tan_y) * 0.5f * (float)height,
                            (sx.y / tan_x + (1.0f + shift_x)) * 0.5f * (float)width,
                            ((1.0f - shift_y) - sy.x / tan_y) * 0.5f * (float)height);
        }
    }
    quad_rect[i] = rect.x;
    quad_rect[n_padded + i] = rect.y;
    quad_rect[2 * n_padded + i] = rect.z;
    quad_rect[3 * n_padded + i] = rect.w;
    int4 t = (int4)(0, 0, -1, -1);
    if (rect.x <= rect.z) {
        const int2 xs = pixel_range(rect.x, rect.z, width), ys = pixel_range(rect.y, rect.w, height);
        if (xs.x <= xs.y && ys.x <= ys.y) t = (int4)(xs.x / LTILE, ys.x / LTILE, xs.y / LTILE, ys.y / LTILE);
    }
    quad_tiles[i] = t.x;
    quad_tiles[n_padded + i] = t.y;
    quad_tiles[2 * n_padded + i] = t.z;
    quad_tiles[3 * n_padded + i] = t.w;
}

/* Lanes whose quad covers tile (tx, ty). */
static inline intV quad_hits(global const int* quad_tiles, int n_padded, int i, int tx, int ty)
{
    const intV x0 = vloadV(0, quad_tiles + i), y0 = vloadV(0, quad_tiles + n_padded + i);
    const intV x1 = vloadV(0, quad_tiles + 2 * n_padded + i), y1 = vloadV(0, quad_tiles + 3 * n_padded + i);
    return (x0 <= tx) & (tx <= x1) & (y0 <= ty) & (ty <= y1);
}

kernel void light_quads_count(global const int* quad_tiles, int n_padded, int tiles_x, int tiles_y,
                              global int* tile_light_counts)
{
    const int t = get_global_id(0);
    if (t >= tiles_x * tiles_y) return;
    const int tx = t % tiles_x, ty = t / tiles_x;
    intV count = 0;
    for (int i = 0; i < n_padded; i += VEC)
        count += select((intV)0, (intV)1, quad_hits(quad_tiles, n_padded, i, tx, ty));
#if VEC == 1
    tile_light_counts[t] = count;
#else
    int total = 0;
    for (int l = 0; l < VEC; ++l) total += LANE_I(count, l);
    tile_light_counts[t] = total;
#endif
}

kernel void light_quads_fill(global const int* quad_tiles, int n_padded, int tiles_x, int tiles_y,
                             global const int* tile_light_offsets, int list_capacity, global int* tile_lights)
{
    const int t = get_global_id(0);
    if (t >= tiles_x * tiles_y) return;
    const int tx = t % tiles_x, ty = t / tiles_x;
    int slot = tile_light_offsets[t];
    for (int i = 0; i < n_padded; i += VEC) {
        const intV hit = quad_hits(quad_tiles, n_padded, i, tx, ty);
        if (!ANY(hit)) continue;
        for (int l = 0; l < VEC; ++l) {
            if (LANE_I(hit, l)) {
                if (slot < list_capacity) tile_lights[slot] = i + l;   /* overflow: host grows, retries */
                ++slot;
            }
        }
    }
}
