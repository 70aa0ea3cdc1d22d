/* resolve.cl: over-sampling resolve -- the k·W × k·H frame filtered down to W × H (docs/post.md).
 *
 * Algorithm (report III.3 "Over-Sampling"): the HDR colour, in linear light, is filtered
 * separably: `resolve_rows` filters each internal row to the output columns, `resolve_cols`
 * the columns to the output rows. A sample's weight is FILTER's function of the distance d, in
 * output pixels, between its centre ((i + 0.5) / K) and the output pixel's centre: box
 * (|d| < 1/2: the K samples of the pixel), Lanczos-2 (sinc(d)·sinc(d/2), |d| < 2) or Mitchell-
 * Netravali with B = C = 1/3 (|d| < 2); weights are normalized over the samples inside the
 * image. `decimate_gbuffer` keeps, for every G-buffer plane, the sample nearest the output
 * pixel's centre, (K·x + K/2, K·y + K/2), and divides its velocity by K (output pixels).
 *
 * Buffers: color float[3][KW·KH]; rows float[3][W·KH] (between the passes); out color
 *          float[3][W·H]. gbuffer uint[GB_PLANES][KW·KH] -> out uint[GB_PLANES][W·H].
 * Work-groups: 2-D, any shape, one output value (column × row) per work-item; no barriers.
 */
#pragma OPENCL FP_CONTRACT OFF
#include "gbuffer.h"

#ifndef K
#define K 2                   /* samples per output pixel along each axis */
#endif
#ifndef FILTER
#define FILTER 0              /* 0: box, 1: Lanczos-2, 2: Mitchell (B = C = 1/3) */
#endif

#if FILTER == 0
#define RADIUS 0.5f
#else
#define RADIUS 2.0f
#endif
#define TAPS ((int)(2.0f * RADIUS * K) + 2)     /* samples within the support, with margin */

static inline float sinc_pi(float x)
{
    return fabs(x) < 1e-6f ? 1.0f : sinpi(x) / (M_PI_F * x);
}

static inline float filter_weight(float d)
{
    d = fabs(d);
#if FILTER == 0
    return d < 0.5f ? 1.0f : 0.0f;
#elif FILTER == 1
    return d < 2.0f ? sinc_pi(d) * sinc_pi(0.5f * d) : 0.0f;
#else
    const float B = 1.0f / 3.0f, C = 1.0f / 3.0f;
    if (d < 1.0f)
        return ((12.0f - 9.0f * B - 6.0f * C) * d * d * d + (-18.0f + 12.0f * B + 6.0f * C) * d * d
                + (6.0f - 2.0f * B)) / 6.0f;
    if (d < 2.0f)
        return ((-B - 6.0f * C) * d * d * d + (6.0f * B + 30.0f * C) * d * d + (-12.0f * B - 48.0f * C) * d
                + (8.0f * B + 24.0f * C)) / 6.0f;
    return 0.0f;
#endif
}

/* Filters n_in samples (stride `step`) to output position o: the weighted mean over the support. */
static inline float3 filter_1d(global const float* src, int plane, int base, int step, int n_in, int o)
{
    const float centre = (float)o + 0.5f;
    const int first = (int)floor((centre - RADIUS) * (float)K);
    float3 sum = (float3)(0.0f, 0.0f, 0.0f);
    float wsum = 0.0f;
    for (int t = 0; t < TAPS; ++t) {
        const int i = first + t;
        if (i < 0 || i >= n_in) continue;
        const float w = filter_weight(((float)i + 0.5f) / (float)K - centre);
        if (w == 0.0f) continue;
        const int at = base + i * step;
        sum += w * (float3)(src[at], src[plane + at], src[2 * plane + at]);
        wsum += w;
    }
    return wsum != 0.0f ? sum / wsum : sum;
}

kernel void resolve_rows(global const float* color, int width, int height, global float* rows)
{
    const int x = get_global_id(0), y = get_global_id(1);    /* output column, internal row */
    if (x >= width || y >= K * height) return;
    const float3 c = filter_1d(color, K * width * K * height, y * K * width, 1, K * width, x);
    const int plane = width * K * height, at = y * width + x;
    rows[at] = c.x;
    rows[plane + at] = c.y;
    rows[2 * plane + at] = c.z;
}

kernel void resolve_cols(global const float* rows, int width, int height, global float* out)
{
    const int x = get_global_id(0), y = get_global_id(1);
    if (x >= width || y >= height) return;
    const float3 c = filter_1d(rows, width * K * height, x, width, K * height, y);
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
