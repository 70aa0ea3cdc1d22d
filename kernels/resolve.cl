/* resolve.cl: over-sampling resolve -- the k·W × k·H frame filtered down to W × H (docs/post.md).
 *
 * Algorithm (report III.3 "Over-Sampling"): the HDR colour, in linear light, is filtered
 * separably: `resolve_rows` filters each internal row to the output columns, `resolve_cols`
 * the columns to the output rows. A sample's weight is the filter's function of the distance
 * d, in output pixels, between its centre ((i + 0.5) / K) and the output pixel's centre: box
 * (|d| < 1/2: the K samples of the pixel), Lanczos-2 (sinc(d)·sinc(d/2), |d| < 2) or Mitchell-
 * Netravali with B = C = 1/3 (|d| < 2). d takes the same TAPS values for every output pixel, so
 * the host computes the weights once (clrender/passes/resolve.py); they are normalized over the
 * samples inside the image. `decimate_gbuffer` keeps, for every G-buffer plane, the sample nearest the output
 * pixel's centre, (K·x + K/2, K·y + K/2), and divides its velocity by K (output pixels).
 *
 * Buffers: color float[3][KW·KH]; weights float[TAPS]; rows float[3][W·KH] (between the passes); out color
 *          float[3][W·H]. gbuffer uint[GB_PLANES][KW·KH] -> out uint[GB_PLANES][W·H].
 * Work-groups: 2-D, any shape, one output value (column × row) per work-item; no barriers.
 */
#pragma OPENCL FP_CONTRACT OFF
#include "gbuffer.h"

#ifndef K
#define K 2                   /* samples per output pixel along each axis */
#endif

#ifndef TAPS
#define TAPS K                /* samples within the filter's support (the box: the K of the pixel) */
#endif
#ifndef FIRST_TAP
#define FIRST_TAP 0           /* the support's first sample is K·o + FIRST_TAP for output position o */
#endif

/* Filters n_in samples (stride `step`) to output position o with `weights` (TAPS of them, the
 * same for every o: sample K·o + FIRST_TAP + t lies at a fixed distance from o's centre),
 * normalized over the samples inside the image. */
static inline float3 filter_1d(global const float* src, int plane, int base, int step, int n_in, int o,
                               constant float* weights)
{
    const int first = K * o + FIRST_TAP;
    float3 sum = (float3)(0.0f, 0.0f, 0.0f);
    float wsum = 0.0f;
    for (int t = 0; t < TAPS; ++t) {
        const int i = first + t;
        if (i < 0 || i >= n_in) continue;
        const float w = weights[t];
        const int at = base + i * step;
        sum += w * (float3)(src[at], src[plane + at], src[2 * plane + at]);
        wsum += w;
    }
    return wsum != 0.0f ? sum / wsum : sum;
}

kernel void resolve_rows(global const float* color, int width, int height, constant float* weights,
                         global float* rows)
{
    const int x = get_global_id(0), y = get_global_id(1);    /* output column, internal row */
    if (x >= width || y >= K * height) return;
    const float3 c = filter_1d(color, K * width * K * height, y * K * width, 1, K * width, x, weights);
    const int plane = width * K * height, at = y * width + x;
    rows[at] = c.x;
    rows[plane + at] = c.y;
    rows[2 * plane + at] = c.z;
}

kernel void resolve_cols(global const float* rows, int width, int height, constant float* weights,
                         global float* out)
{
    const int x = get_global_id(0), y = get_global_id(1);
    if (x >= width || y >= height) return;
    const float3 c = filter_1d(rows, width * K * height, x, width, K * height, y, weights);
    const int plane = width * height, at = y * width + x;
    out[at] = c.x;
    out[plane + at] = c.y;
    out[2 * plane + at] = c.z;
}

kernel void decimate_gbuffer(global const uint* gbuffer, int width, int height, global uint* out)
{
    const int x = get_global_id(0), y = get_global_id(1);
    if (x >= width || y >= height) return;
    const int in_plane = K * width * K * height, out_plane = width * height;
    const int src = (K * y + K / 2) * K * width + K * x + K / 2, dst = y * width + x;
    for (int p = 0; p < GB_PLANES; ++p) out[p * out_plane + dst] = gbuffer[p * in_plane + src];
    /* velocity: internal pixels -> output pixels */
    global const half* v_in = (global const half*)(gbuffer + GB_VELOCITY_PLANE * in_plane);
    global half* v_out = (global half*)(out + GB_VELOCITY_PLANE * out_plane);
    vstore_half2_rte(vload_half2(src, v_in) * (1.0f / (float)K), dst, v_out);
}
