/* light_cull.cl: tiled light culling into per-tile light index lists (light-indexed style).
 *
 * Algorithm (report II.4 "limiting the number of pixels", done in compute):
 *  1. `light_view_bounds`: one work-item per light: its culling sphere (the light's sphere for
 *     points, the cone's bounding sphere for spots) in view space, as SoA arrays padded to a
 *     multiple of VEC with radius -1 (never hits).
 *  2. `tile_depth_bounds`: one work-item per LTILE×LTILE tile: min/max view depth of its
 *     foreground pixels from the G-buffer (+inf/-inf for an empty tile: no light touches it),
 *     widened by the transparent fragments' depth range (fragments.cl) when there are any,
 *     and with DEPTH_MASK Harada's 2.5D culling mask: which of 32 slices of [min, max] hold a
 *     pixel, so a light floating in the empty gap of a depth discontinuity is rejected.
 *  3. `light_cull_count` / `light_cull_fill`: one work-item per tile tests every light, VEC
 *     lights at a time, against the tile's four side planes (through the eye; ORTHO: the
 *     tile's box, planes x = u·tan_x, y = v·tan_y parallel to the view axis; u, v: NDC less the
 *     principal point shift_x, shift_y, 0 but for an off-centre pinhole camera) and its depth
 *     range; count, prefix sum (scan.cl), then fill in light-index order, so
 *     lists (and the shading sums over them) are the same on every run. No cap: the list
 *     buffer grows when the total says it must.
 *
 * Buffers: lights Light[n]; view float[16] world->view row-major; gbuffer uint[GB_PLANES][H·W];
 *          t_range float[2][H·W] (nearest, farthest transparent fragment, linear; read if has_fragments);
 *          sphere_x/y/z/r float[n_padded]; tile_depth float4[tiles] (min, max, mask bits, 0);
 *          tile_light_counts/offsets int[tiles]; tile_lights int[list_capacity].
 * Work-groups: 1-D, any size; no barriers, no local memory.
 */
#pragma OPENCL FP_CONTRACT OFF
#include "structs.h"
#include "gbuffer.h"

#ifndef LTILE
#define LTILE 16
#endif
#ifndef DEPTH_MASK
#define DEPTH_MASK 0
#endif
#ifndef ORTHO
#define ORTHO 0      /* 1: orthographic camera: tan_x, tan_y are the view box's half-extents */
#endif

kernel void light_view_bounds(global const Light* lights, int n_lights, int n_padded, global const float* view,
                              global float* sphere_x, global float* sphere_y, global float* sphere_z,
                              global float* sphere_r)
{
    int i = get_global_id(0);
    if (i >= n_padded) return;
    if (i >= n_lights) {
        sphere_x[i] = 0.0f; sphere_y[i] = 0.0f; sphere_z[i] = 0.0f; sphere_r[i] = -1.0f;
        return;
    }
    Light l = lights[i];
    float3 c = vload3(0, l.position);
    float r = l.radius;
    if (l.type == LIGHT_SPOT) {
        /* Bounding sphere of a cone of length r and half-angle θ (cos θ = cos_outer). */
        float3 dir = vload3(0, l.direction);
        float cos_t = clamp(l.cos_outer, 1e-4f, 1.0f);
        if (cos_t <= 0.70710678f) {           /* θ >= 45°: the base circle's sphere */
            c += dir * (cos_t * r);
            r *= sqrt(1.0f - cos_t * cos_t);
        } else {
            float half_len = r / (2.0f * cos_t);
            c += dir * half_len;
            r = half_len;
        }
    }
    sphere_x[i] = view[0] * c.x + view[1] * c.y + view[2] * c.z + view[3];
    sphere_y[i] = view[4] * c.x + view[5] * c.y + view[6] * c.z + view[7];
    sphere_z[i] = view[8] * c.x + view[9] * c.y + view[10] * c.z + view[11];
    sphere_r[i] = r;
}

kernel void tile_depth_bounds(global const uint* gbuffer, int width, int height, float far,
                              int tiles_x, int tiles_y, int has_fragments, global const float* t_range,
                              global float4* tile_depth)
{
    int t = get_global_id(0);
    if (t >= tiles_x * tiles_y) return;
    int x0 = (t % tiles_x) * LTILE, y0 = (t / tiles_x) * LTILE;
    int x1 = min(x0 + LTILE, width), y1 = min(y0 + LTILE, height);
    global const float* depth = (global const float*)(gbuffer + GB_LINEAR_DEPTH_PLANE * width * height);
    global const float* t_near = t_range;
    global const float* t_far = t_range + width * height;
    float lo = INFINITY, hi = -INFINITY;
    for (int y = y0; y < y1; ++y)
        for (int x = x0; x < x1; ++x) {
            float z = depth[y * width + x];
            if (z < INFINITY) { lo = fmin(lo, z); hi = fmax(hi, z); }
            if (has_fragments) {          /* transparent fragments in front (fragments.cl) */
                lo = fmin(lo, t_near[y * width + x]);
                hi = fmax(hi, t_far[y * width + x]);
            }
        }
    uint mask = 0xffffffffu;
#if DEPTH_MASK
    mask = 0u;
    float scale = hi > lo ? 32.0f / (hi - lo) : 0.0f;
    for (int y = y0; y < y1; ++y)
        for (int x = x0; x < x1; ++x) {
            float z = depth[y * width + x];
            if (z < INFINITY) mask |= 1u << min((int)((z - lo) * scale), 31);
            if (has_fragments && t_near[y * width + x] < INFINITY) {
                /* every slice between the pixel's nearest and farthest fragment: conservative */
                int s0 = min((int)((t_near[y * width + x] - lo) * scale), 31);
                int s1 = min((int)((t_far[y * width + x] - lo) * scale), 31);
                mask |= (0xffffffffu >> (31 - s1)) & ~((1u << s0) - 1u);
            }
        }
#endif
    tile_depth[t] = (float4)(lo * far, hi * far, as_float(mask), 0.0f);
}

/* The tile's side planes in view space: inside when dot(n, p) >= 0; n unit (ORTHO: when
 * dot(n, p) + w >= 0, the planes at the tile's edges x = u·tan_x, y = v·tan_y). */
typedef struct { float4 left, right, bottom, top; } TilePlanes;

static TilePlanes tile_planes(int t, int tiles_x, int width, int height, float tan_x, float tan_y,
                              float shift_x, float shift_y)
{
    /* the tile's edges in NDC less the principal point (shift: 0 but for an off-centre pinhole) */
    float u0 = (float)((t % tiles_x) * LTILE) / (float)width * 2.0f - (1.0f + shift_x);
    float u1 = (float)min((t % tiles_x) * LTILE + LTILE, width) / (float)width * 2.0f - (1.0f + shift_x);
    float v_top = (1.0f - shift_y) - (float)((t / tiles_x) * LTILE) / (float)height * 2.0f;
    float v_bottom = (1.0f - shift_y) - (float)min((t / tiles_x) * LTILE + LTILE, height) / (float)height * 2.0f;
    TilePlanes p;
#if ORTHO
    p.left = (float4)(1.0f, 0.0f, 0.0f, -u0 * tan_x);
    p.right = (float4)(-1.0f, 0.0f, 0.0f, u1 * tan_x);
    p.bottom = (float4)(0.0f, 1.0f, 0.0f, -v_bottom * tan_y);
    p.top = (float4)(0.0f, -1.0f, 0.0f, v_top * tan_y);
#else
    p.left = (float4)(normalize((float3)(1.0f, 0.0f, u0 * tan_x)), 0.0f);
    p.right = (float4)(normalize((float3)(-1.0f, 0.0f, -u1 * tan_x)), 0.0f);
    p.bottom = (float4)(normalize((float3)(0.0f, 1.0f, v_bottom * tan_y)), 0.0f);
    p.top = (float4)(normalize((float3)(0.0f, -1.0f, -v_top * tan_y)), 0.0f);
#endif
    return p;
}

static inline intV sphere_in_tile(const TilePlanes* p, float4 depth, floatV x, floatV y, floatV z, floatV r)
{
    floatV neg_r = -r;
    intV hit = r >= 0.0f;
#if ORTHO
    hit &= (p->left.x * x + p->left.w) >= neg_r;
    hit &= (p->right.x * x + p->right.w) >= neg_r;
    hit &= (p->bottom.y * y + p->bottom.w) >= neg_r;
    hit &= (p->top.y * y + p->top.w) >= neg_r;
#else
    hit &= (p->left.x * x + p->left.z * z) >= neg_r;
    hit &= (p->right.x * x + p->right.z * z) >= neg_r;
    hit &= (p->bottom.y * y + p->bottom.z * z) >= neg_r;
    hit &= (p->top.y * y + p->top.z * z) >= neg_r;
#endif
    floatV near_z = -z - r, far_z = -z + r;                 /* the sphere's view-depth range */
    hit &= (far_z >= depth.x) & (near_z <= depth.y);
#if DEPTH_MASK
    /* The light's slices of the tile's [min, max] must meet an occupied one. */
    float scale = depth.y > depth.x ? 32.0f / (depth.y - depth.x) : 0.0f;
    intV s0 = convert_intV(clamp((near_z - depth.x) * scale, 0.0f, 31.0f));
    intV s1 = convert_intV(clamp((far_z - depth.x) * scale, 0.0f, 31.0f));
    uintV light_mask = ((uintV)0xffffffffu >> as_uintV(31 - s1)) & ((uintV)0xffffffffu << as_uintV(s0));
    hit &= (light_mask & as_uint(depth.z)) != 0u;
#endif
    return hit;
}

#define CULL_ARGS global const float* sphere_x, global const float* sphere_y, global const float* sphere_z, \
    global const float* sphere_r, int n_padded, global const float4* tile_depth, int tiles_x, int tiles_y, \
    int width, int height, float tan_x, float tan_y, float shift_x, float shift_y

kernel void light_cull_count(CULL_ARGS, global int* tile_light_counts)
{
    int t = get_global_id(0);
    if (t >= tiles_x * tiles_y) return;
    float4 depth = tile_depth[t];
    int count = 0;
    if (depth.x <= depth.y) {
        TilePlanes p = tile_planes(t, tiles_x, width, height, tan_x, tan_y, shift_x, shift_y);
        for (int i = 0; i < n_padded; i += VEC) {
            intV hit = sphere_in_tile(&p, depth, vloadV(0, sphere_x + i), vloadV(0, sphere_y + i),
                                      vloadV(0, sphere_z + i), vloadV(0, sphere_r + i));
#if VEC == 1
            count += hit ? 1 : 0;
#else
            count -= (int)(hit.s0 + hit.s1 + hit.s2 + hit.s3
#if VEC >= 8
                           + hit.s4 + hit.s5 + hit.s6 + hit.s7
#endif
#if VEC == 16
                           + hit.s8 + hit.s9 + hit.sa + hit.sb + hit.sc + hit.sd + hit.se + hit.sf
#endif
                           );
#endif
        }
    }
    tile_light_counts[t] = count;
}

kernel void light_cull_fill(CULL_ARGS, global const int* tile_light_offsets, int list_capacity,
                            global int* tile_lights)
{
    int t = get_global_id(0);
    if (t >= tiles_x * tiles_y) return;
    float4 depth = tile_depth[t];
    if (!(depth.x <= depth.y)) return;
    TilePlanes p = tile_planes(t, tiles_x, width, height, tan_x, tan_y, shift_x, shift_y);
    int slot = tile_light_offsets[t];
    for (int i = 0; i < n_padded; i += VEC) {
        intV hit = sphere_in_tile(&p, depth, vloadV(0, sphere_x + i), vloadV(0, sphere_y + i),
                                  vloadV(0, sphere_z + i), vloadV(0, sphere_r + i));
        if (!ANY(hit)) continue;
        for (int l = 0; l < VEC; ++l) {
            if (LANE_I(hit, l)) {
                if (slot < list_capacity) tile_lights[slot] = i + l;   /* overflow: host grows, retries */
                ++slot;
            }
        }
    }
}
