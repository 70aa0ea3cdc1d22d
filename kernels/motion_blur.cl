/* motion_blur.cl: post-process motion blur of the linear HDR colour along the per-pixel
 * velocity (report IV.2), at the output resolution (docs/post.md: bloom -> motion blur -> tone map).
 *
 * Algorithm: the G-buffer velocity v (pixels, current position − previous position) is the
 * motion over one frame interval. The exposure is SHUTTER frame intervals centred on the
 * current frame, so a pixel's blur vector is b = v·shutter: the segment p + u·b, u in
 * [−1/2, 1/2], is where its surface travels while the shutter is open. Three stages:
 *  1. `mb_blur_vectors`: b per pixel; |b| < MB_MIN_LENGTH (half a pixel: invisible, and below
 *     it lies the rounding noise of a static reprojection, ~1e-3 px) or not finite is exactly
 *     0 -- static; a longer b is shortened to 2·MB_MAX_RADIUS pixels (the dilation's reach).
 *  2. `mb_dilate_x`, then `mb_dilate_y`: the velocity smoothing the report advises, as a
 *     reach-limited max: a pixel takes the longest blur vector among the pixels q whose blur
 *     reaches it, |q − p| ≤ |b_q|/2 + 1/2 per axis (the segment's bounding box grown by half a
 *     pixel), within MB_MAX_RADIUS. A moving surface's blur thereby extends over the static
 *     pixels it sweeps during the exposure (beyond its sharp silhouette), and nothing farther
 *     changes. Separable: the row pass keeps, per pixel, the longest vector reaching it along
 *     x; the column pass checks those along y (exact for axis-aligned motion; where different
 *     directions meet it may keep only the longer one). `mb_tile_reach` and
 *     `mb_neighbor_reach` bound, per MB_TILE² tile, how far the search must look (static
 *     regions: not at all).
 *  3. `mb_gather`: a pixel with b = 0 copies its colour (bit-identical); otherwise the mean of
 *     `samples` bilinear taps of the colour at p + u_i·b, u_i = (i + 1/2)/samples − 1/2, in
 *     pixel-index coordinates (x = pixel x's centre) clamped to [0, W − 1] × [0, H − 1].
 *
 * Buffers: gbuffer uint[GB_PLANES][W·H] (velocity plane: half2, x low); vectors, dilated
 *          float2[W·H] (stage outputs, ping-pong); reach, neighbor int[tiles]; color
 *          float[3][W·H] -> out float[3][W·H].
 * Work-groups: 2-D, any shape, one pixel (tile for the reach kernels) per work-item; no
 *          barriers, no local memory.
 */
#pragma OPENCL FP_CONTRACT OFF
#include "gbuffer.h"

#ifndef MB_MAX_RADIUS
#define MB_MAX_RADIUS 32      /* pixels: longest half blur (and the dilation's reach) */
#endif
#ifndef MB_TILE
#define MB_TILE MB_MAX_RADIUS /* pixels: side of the tiles bounding the dilation's search */
#endif
#ifndef MB_MIN_LENGTH
#define MB_MIN_LENGTH 0.5f    /* pixels: shorter exposure motion is static */
#endif

kernel void mb_blur_vectors(global const uint* gbuffer, int width, int height, float shutter,
                            global float2* vectors)
{
    const int x = get_global_id(0), y = get_global_id(1);
    if (x >= width || y >= height) return;
    const int at = y * width + x;
    global const half* vel = (global const half*)(gbuffer + GB_VELOCITY_PLANE * width * height);
    float2 b = vload_half2(at, vel) * shutter;
    const float len2 = b.x * b.x + b.y * b.y;
    const float max_len = 2.0f * (float)MB_MAX_RADIUS;
    if (!(len2 >= MB_MIN_LENGTH * MB_MIN_LENGTH && len2 < INFINITY))    /* NaN, inf: static too */
        b = (float2)(0.0f, 0.0f);
    else if (len2 > max_len * max_len)
        b *= max_len / sqrt(len2);
    vectors[at] = b;
}

/* The reach bound of each MB_TILE × MB_TILE tile: the largest integer distance any of its
 * vectors reaches along either axis, floor(max(|b.x|, |b.y|)/2 + 1/2) (0 where all are static).
 * One work-item per tile. */
kernel void mb_tile_reach(global const float2* vectors, int width, int height, int tiles_x, int tiles_y,
                          global int* reach)
{
    const int tx = get_global_id(0), ty = get_global_id(1);
    if (tx >= tiles_x || ty >= tiles_y) return;
    const int x0 = tx * MB_TILE, y0 = ty * MB_TILE;
    const int x1 = min(x0 + MB_TILE, width), y1 = min(y0 + MB_TILE, height);
    float m = 0.0f;
    for (int y = y0; y < y1; ++y)
        for (int x = x0; x < x1; ++x) {
            const float2 b = vectors[y * width + x];
            m = fmax(m, fmax(fabs(b.x), fabs(b.y)));
        }
    reach[ty * tiles_x + tx] = m > 0.0f ? min((int)floor(m * 0.5f + 0.5f), MB_MAX_RADIUS) : 0;
}

/* Per tile, the largest reach among the 3×3 tiles around it (MB_TILE >= MB_MAX_RADIUS: they hold
 * every pixel within MB_MAX_RADIUS of the tile's pixels). One work-item per tile. */
kernel void mb_neighbor_reach(global const int* reach, int tiles_x, int tiles_y, global int* neighbor)
{
    const int tx = get_global_id(0), ty = get_global_id(1);
    if (tx >= tiles_x || ty >= tiles_y) return;
    int r = 0;
    for (int j = max(ty - 1, 0); j <= min(ty + 1, tiles_y - 1); ++j)
        for (int i = max(tx - 1, 0); i <= min(tx + 1, tiles_x - 1); ++i)
            r = max(r, reach[j * tiles_x + i]);
    neighbor[ty * tiles_x + tx] = r;
}

/* One dilation pass: along x (mb_dilate_x) or y (mb_dilate_y, over mb_dilate_x's output). A
 * pixel looks only as far as its tile's neighbour reach (the vectors the x pass moved came from
 * those 3×3 tiles too): static regions cost two reads. Ties keep the first (lowest d) vector. */
#define MB_DILATE(NAME, AT, N, STRIDE, COMPONENT)                                               \
kernel void NAME(global const float2* src, global const int* neighbor_reach, int width,         \
                 int height, int tiles_x, global float2* dst)                                   \
{                                                                                              \
    const int x = get_global_id(0), y = get_global_id(1);                                      \
    if (x >= width || y >= height) return;                                                     \
    const int r = neighbor_reach[(y / MB_TILE) * tiles_x + x / MB_TILE];                       \
    const int at = (AT), n = (N), stride = (STRIDE);                                           \
    global const float2* line = src + (y * width + x) - at * stride;                           \
    float2 best = (float2)(0.0f, 0.0f);                                                        \
    float best2 = 0.0f;                                                                        \
    for (int d = -r; d <= r; ++d) {                                                            \
        const int q = at + d;                                                                  \
        if (q < 0 || q >= n) continue;                                                         \
        const float2 b = line[q * stride];                                                     \
        const float len2 = b.x * b.x + b.y * b.y;                                              \
        if ((float)abs(d) <= fabs(b.COMPONENT) * 0.5f + 0.5f && len2 > best2) {                \
            best = b;                                                                          \
            best2 = len2;                                                                      \
        }                                                                                      \
    }                                                                                          \
    dst[y * width + x] = best;                                                                 \
}

MB_DILATE(mb_dilate_x, x, width, 1, x)
MB_DILATE(mb_dilate_y, y, height, width, y)

kernel void mb_gather(global const float* color, global const float2* vectors, int width, int height,
                      int samples, global float* out)
{
    const int x = get_global_id(0), y = get_global_id(1);
    if (x >= width || y >= height) return;
    const int plane = width * height, at = y * width + x;
    const float2 b = vectors[at];
    if (b.x == 0.0f && b.y == 0.0f) {
        out[at] = color[at];
        out[plane + at] = color[plane + at];
        out[2 * plane + at] = color[2 * plane + at];
        return;
    }
    float3 sum = (float3)(0.0f, 0.0f, 0.0f);
    for (int i = 0; i < samples; ++i) {
        const float u = ((float)i + 0.5f) / (float)samples - 0.5f;
        const float sx = clamp((float)x + u * b.x, 0.0f, (float)(width - 1));
        const float sy = clamp((float)y + u * b.y, 0.0f, (float)(height - 1));
        const float fx0 = floor(sx), fy0 = floor(sy);
        const float fx = sx - fx0, fy = sy - fy0;
        const int x0 = (int)fx0, y0 = (int)fy0;
        const int x1 = min(x0 + 1, width - 1), y1 = min(y0 + 1, height - 1);
        const int a00 = y0 * width + x0, a10 = y0 * width + x1, a01 = y1 * width + x0, a11 = y1 * width + x1;
        const float w00 = (1.0f - fx) * (1.0f - fy), w10 = fx * (1.0f - fy), w01 = (1.0f - fx) * fy, w11 = fx * fy;
        sum.x += w00 * color[a00] + w10 * color[a10] + w01 * color[a01] + w11 * color[a11];
        sum.y += w00 * color[plane + a00] + w10 * color[plane + a10] + w01 * color[plane + a01]
                 + w11 * color[plane + a11];
        sum.z += w00 * color[2 * plane + a00] + w10 * color[2 * plane + a10] + w01 * color[2 * plane + a01]
                 + w11 * color[2 * plane + a11];
    }
    const float inv = 1.0f / (float)samples;
    out[at] = sum.x * inv;
    out[plane + at] = sum.y * inv;
    out[2 * plane + at] = sum.z * inv;
}
