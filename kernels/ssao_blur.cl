/* ssao_blur.cl: depth-aware (bilateral) blur of the raw SSAO term, one axis per launch.
 *
 * Algorithm: separable; launched along x, then along y. Along the axis, the neighbours
 * q = p + i, |i| <= SSAO_BLUR_RADIUS, are averaged with weights
 *     w = (SSAO_BLUR_RADIUS + 1 - |i|) · max(0, 1 - ((d_q - d_p) / (SSAO_BLUR_DEPTH_TOLERANCE · d_p))²)
 * (a tent in space times a depth term, d the G-buffer linear depth): a neighbour whose depth
 * differs by SSAO_BLUR_DEPTH_TOLERANCE of the pixel's own or more gets weight exactly 0, so the
 * occlusion of one surface does not bleed onto another across a depth discontinuity. The
 * per-pixel rotation noise of ssao.cl averages out. Neighbours off the image or on the
 * background weigh 0; background pixels stay 1. out = Σ w·ao / Σ w (the pixel itself always
 * weighs SSAO_BLUR_RADIUS + 1). tests/reference/ao.py holds the NumPy version.
 *
 * Buffers: src, out float[H·W]; gbuffer uint[GB_PLANES][H·W] (linear depth plane only).
 * Work-groups: (SSAO_WG_X, SSAO_WG_Y), each work-item a run of VEC pixels of one row (vec.h);
 *          no barriers, no local memory.
 */
#pragma OPENCL FP_CONTRACT OFF
#include "gbuffer.h"

#ifndef SSAO_BLUR_RADIUS
#define SSAO_BLUR_RADIUS 4
#endif
#ifndef SSAO_BLUR_DEPTH_TOLERANCE
#define SSAO_BLUR_DEPTH_TOLERANCE 0.05f
#endif
#ifndef SSAO_WG_X
#define SSAO_WG_X 2
#endif
#ifndef SSAO_WG_Y
#define SSAO_WG_Y 8
#endif

/* VEC consecutive floats from pixel (x0, y) on: a vector load when the run lies inside the
 * image, else lane by lane, lanes outside reading `fill`. */
static inline floatV load_run_clipped(global const float* plane, int x0, int y, int valid, int width,
                                      int height, float fill)
{
    if (y < 0 || y >= height) return (floatV)fill;
    if (valid == VEC && x0 >= 0 && x0 + VEC <= width) return vloadV(0, plane + y * width + x0);
    floatV r = fill;
    for (int l = 0; l < valid; ++l) {
        if (x0 + l >= 0 && x0 + l < width) LANE_F(r, l) = plane[y * width + x0 + l];
    }
    return r;
}

/* (axis_x, axis_y) = (1, 0) blurs along rows, (0, 1) along columns. */
kernel __attribute__((reqd_work_group_size(SSAO_WG_X, SSAO_WG_Y, 1)))
void ssao_blur(global const float* src, global const uint* gbuffer, int width, int height, int axis_x,
               int axis_y, global float* out)
{
    const int px0 = get_global_id(0) * VEC, py = get_global_id(1);
    if (py >= height || px0 >= width) return;
    const int valid = min(VEC, width - px0);
    global const float* depth_plane = (global const float*)(gbuffer + GB_LINEAR_DEPTH_PLANE * width * height);

    /* Background depth is +inf: its weight is 0 as a neighbour, and it keeps 1 as a pixel. */
    floatV d_p = load_run_clipped(depth_plane, px0, py, valid, width, height, INFINITY);
    intV fg = isfinite(d_p);
    floatV result = 1.0f;
    if (ANY(fg)) {
        floatV inv_tol = 1.0f / (SSAO_BLUR_DEPTH_TOLERANCE * select((floatV)1.0f, d_p, fg));
        floatV sum_w = 0.0f, sum_wa = 0.0f;
        for (int i = -SSAO_BLUR_RADIUS; i <= SSAO_BLUR_RADIUS; ++i) {
            const int qx0 = px0 + i * axis_x, qy = py + i * axis_y;
            floatV d_q = load_run_clipped(depth_plane, qx0, qy, valid, width, height, INFINITY);
            floatV a_q = load_run_clipped(src, qx0, qy, valid, width, height, 1.0f);
            floatV rel = (d_q - d_p) * inv_tol;
            /* Not abs(i): Intel's CPU runtime 2021.2 (opencl-rt) optimizes abs() of this loop
             * counter to 0 in the one-pixel (VEC 1) build, a flat instead of a tent. */
            const int tent = SSAO_BLUR_RADIUS + 1 - (i < 0 ? -i : i);
            floatV w = (float)tent * fmax(1.0f - rel * rel, 0.0f);
            w = select((floatV)0.0f, w, fg & isfinite(d_q));
            sum_w += w;
            sum_wa += w * a_q;
        }
        result = select((floatV)1.0f, sum_wa / sum_w, fg);
    }
    if (valid == VEC) {
        vstoreV(result, 0, out + py * width + px0);
    } else {
        for (int l = 0; l < valid; ++l) out[py * width + px0 + l] = LANE_F(result, l);
    }
}
