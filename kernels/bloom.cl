/* bloom.cl: the report's bloom ("glow", section IV.1) on the linear HDR colour (docs/post.md).
 *
 * Algorithm: what saturates is isolated, blurred and added back before tone mapping:
 *     bright = max(color - threshold, 0)                 per channel (R, G, B independently)
 *     out    = color + strength * blur(bright)
 *     blur   = (1/L) * sum_{l=1..L} U^l G_l D_l          (equal weights, total weight 1)
 * over a mip pyramid, so a large radius stays cheap:
 *   D_l  l successive 2x2 means (`bloom_bright_down` fuses the threshold with the first one,
 *        `bloom_down` the others). Level l has w_l = ceil(w_{l-1} / 2) columns (same for rows);
 *        its pixel i covers level-0 pixels [i*2^l, (i+1)*2^l). Odd sizes: the 2x2 block of the
 *        last column/row clamps to the edge (the missing pixel repeats the edge one).
 *   G_l  a separable Gaussian of SIGMA coarse pixels (the same at every level, so 2^l*SIGMA
 *        output pixels at level l), taps k = -R..R, w_k = exp(-k^2 / (2 SIGMA^2)) normalized
 *        to sum 1, computed by the host (clrender/passes/bloom.py) in `taps`; clamp-to-edge.
 *   U    a bilinear 2x upsample: fine pixel (x, y) reads the coarser level at
 *        u = (x + 0.5) / 2 - 0.5 (same for y), clamped to [0, w - 1] (clamp-to-edge): weights
 *        3/4, 1/4 per axis. U^l is l of them, level l -> level 0, applied as a cascade:
 *        acc_L = G_L D_L, acc_l = G_l D_l + U acc_{l+1}, blur = U acc_1 / L.
 * Kernels: `bloom_blur_rows` filters a level's rows into `tmp`; `bloom_blur_cols` its columns
 * and adds U acc_{l+1}, writing acc_l over the level (levels L..1, after every downsample);
 * `bloom_compose` writes color + (strength / L) * U acc_1.
 * The host maps bloom_radius r (output pixels) to L = clamp(ceil(log2 r) - 1, 1, 12) and
 * SIGMA = r / 2^(L+1), so level l's Gaussian has sigma r * 2^(l-L-1) output pixels: r/2 for the
 * coarsest, r/2^L for the finest; R = max(1, ceil(3 SIGMA)). One bright pixel becomes the mean
 * of L bumps; bump l, centred on the centre of the pixel's level-l block, has the per-axis
 * variance 4^l (s2 + 1/4) - 1/4 output pixels^2, where s2 = sum_k k^2 w_k (~ SIGMA^2) is the
 * taps' variance in coarse pixels and each U from level j adds 3/4 of a level-(j-1) pixel^2.
 * Energy: means (x 4^l), normalized taps, and U's weights totalling 4 per coarse pixel make
 * sum(blur(bright)) = sum(bright) exactly (up to rounding) for content whose blur stays away
 * from the image borders; at the borders the clamps lose or repeat a little.
 * A frame with nothing above threshold adds strength * 0: it is bit-identical to the input.
 *
 * Buffers: color float[3][W*H] (the HDR input, planes R, G, B); pyramid float[sum_l 3*w_l*h_l]
 *          (levels 1..L one after the other, each 3 planes of w_l*h_l, addressed by its offset in
 *          floats, passed to the kernels; overwritten by acc_l); tmp float[3*w_1*h_1] (one level's
 *          row pass); taps float[2R+1]; out float[3][W*H].
 *          Every level and tmp are fully written before they are read. threshold, R, the
 *          level offsets and sizes, and scale = strength / L are kernel arguments: no define, no rebuild.
 * Work-groups: 2-D, any shape, one destination pixel (all 3 channels) per work-item, global
 *          sizes rounded up and bounds-checked; no barriers, no local memory.
 */
#pragma OPENCL FP_CONTRACT OFF

/* 2x2 mean of bright = max(color - threshold, 0): W x H colour -> level 1 (w1 x h1). */
kernel void bloom_bright_down(global const float* color, int width, int height, float threshold,
                              global float* level, int w1, int h1)
{
    const int x = get_global_id(0), y = get_global_id(1);
    if (x >= w1 || y >= h1) return;
    const int x0 = 2 * x, y0 = 2 * y;
    const int x1 = min(x0 + 1, width - 1), y1 = min(y0 + 1, height - 1);
    const int plane = width * height, out_plane = w1 * h1;
    for (int c = 0; c < 3; ++c) {
        global const float* p = color + c * plane;
        const float a = fmax(p[y0 * width + x0] - threshold, 0.0f), b = fmax(p[y0 * width + x1] - threshold, 0.0f);
        const float d = fmax(p[y1 * width + x0] - threshold, 0.0f), e = fmax(p[y1 * width + x1] - threshold, 0.0f);
        level[c * out_plane + y * w1 + x] = ((a + b) + (d + e)) * 0.25f;
    }
}

/* 2x2 mean: level l-1 (w x h, at pyramid + src) -> level l (wo x ho, at pyramid + dst), clamp-to-edge
 * for odd sizes. */
kernel void bloom_down(global float* pyramid, int src, int w, int h, int dst, int wo, int ho)
{
    const int x = get_global_id(0), y = get_global_id(1);
    if (x >= wo || y >= ho) return;
    const int x0 = 2 * x, y0 = 2 * y;
    const int x1 = min(x0 + 1, w - 1), y1 = min(y0 + 1, h - 1);
    const int plane = w * h, out_plane = wo * ho;
    for (int c = 0; c < 3; ++c) {
        global const float* p = pyramid + src + c * plane;
        pyramid[dst + c * out_plane + y * wo + x] =
            ((p[y0 * w + x0] + p[y0 * w + x1]) + (p[y1 * w + x0] + p[y1 * w + x1])) * 0.25f;
    }
}

/* Horizontal Gaussian of one level (w x h, at pyramid + offset) into tmp, clamp-to-edge. */
kernel void bloom_blur_rows(global const float* pyramid, int offset, int w, int h, global const float* taps,
                            int radius, global float* tmp)
{
    global const float* src = pyramid + offset;
    const int x = get_global_id(0), y = get_global_id(1);
    if (x >= w || y >= h) return;
    const int plane = w * h;
    float3 sum = (float3)(0.0f, 0.0f, 0.0f);
    for (int k = -radius; k <= radius; ++k) {
        const int at = y * w + clamp(x + k, 0, w - 1);
        sum += taps[k + radius] * (float3)(src[at], src[plane + at], src[2 * plane + at]);
    }
    const int at = y * w + x;
    tmp[at] = sum.x;
    tmp[plane + at] = sum.y;
    tmp[2 * plane + at] = sum.z;
}

/* Bilinear 2x upsample of the coarser level (wc x hc at pyramid + coarse) at pixel (x, y) of the
 * finer grid: u = (x + 0.5) / 2 - 0.5, clamped to [0, wc - 1] (clamp-to-edge); same for y. */
static inline float3 up2(global const float* pyramid, int coarse, int wc, int hc, int x, int y)
{
    const float u = clamp(((float)x + 0.5f) * 0.5f - 0.5f, 0.0f, (float)(wc - 1));
    const float v = clamp(((float)y + 0.5f) * 0.5f - 0.5f, 0.0f, (float)(hc - 1));
    const int i0 = (int)u, j0 = (int)v;
    const int i1 = min(i0 + 1, wc - 1), j1 = min(j0 + 1, hc - 1);
    const float ax = u - (float)i0, ay = v - (float)j0;
    const int plane = wc * hc;
    global const float* p = pyramid + coarse;
    const int a = j0 * wc + i0, b = j0 * wc + i1, c = j1 * wc + i0, d = j1 * wc + i1;
    const float3 p00 = (float3)(p[a], p[plane + a], p[2 * plane + a]);
    const float3 p01 = (float3)(p[b], p[plane + b], p[2 * plane + b]);
    const float3 p10 = (float3)(p[c], p[plane + c], p[2 * plane + c]);
    const float3 p11 = (float3)(p[d], p[plane + d], p[2 * plane + d]);
    const float3 top = p00 + (p01 - p00) * ax, bot = p10 + (p11 - p10) * ax;
    return top + (bot - top) * ay;
}

/* Vertical Gaussian of one level (w x h) from tmp, plus (coarse >= 0) the 2x upsample of the
 * coarser level's accumulated bloom (wc x hc at pyramid + coarse), written into the level (at
 * pyramid + offset), clamp-to-edge. */
kernel void bloom_blur_cols(global const float* tmp, int w, int h, global const float* taps, int radius,
                            global float* pyramid, int offset, int coarse, int wc, int hc)
{
    const int x = get_global_id(0), y = get_global_id(1);
    if (x >= w || y >= h) return;
    const int plane = w * h;
    float3 sum = (float3)(0.0f, 0.0f, 0.0f);
    for (int k = -radius; k <= radius; ++k) {
        const int at = clamp(y + k, 0, h - 1) * w + x;
        sum += taps[k + radius] * (float3)(tmp[at], tmp[plane + at], tmp[2 * plane + at]);
    }
    if (coarse >= 0) sum += up2(pyramid, coarse, wc, hc, x, y);
    global float* dst = pyramid + offset;
    const int at = y * w + x;
    dst[at] = sum.x;
    dst[plane + at] = sum.y;
    dst[2 * plane + at] = sum.z;
}

/* out = color + scale * up2(level 1's accumulated bloom), scale = strength / L. */
kernel void bloom_compose(global const float* color, int width, int height, global const float* pyramid,
                          int w1, int h1, float scale, global float* out)
{
    const int x = get_global_id(0), y = get_global_id(1);
    if (x >= width || y >= height) return;
    const float3 acc = up2(pyramid, 0, w1, h1, x, y);
    const int plane = width * height, at = y * width + x;
    out[at] = color[at] + scale * acc.x;
    out[plane + at] = color[plane + at] + scale * acc.y;
    out[2 * plane + at] = color[2 * plane + at] + scale * acc.z;
}
