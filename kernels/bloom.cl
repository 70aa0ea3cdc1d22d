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
 *          level offsets and sizes, and scale = strength / L are kernel arguments: the only define
 *          is VEC (vec.h, one build per device), no rebuild per option.
 * Work-groups: 2-D, any shape; work-item (i, y) computes the run of VEC horizontally adjacent
 *          destination pixels from x0 = i * VEC of row y (all 3 channels; VEC = 1 on GPUs and
 *          Oclgrind, 8 or 16 on CPUs), global sizes (ceil(w / VEC), h) rounded up and bounds-checked;
 *          no barriers, no local memory. Runs: the 2x2 means load 2*VEC pixels of each of two rows and
 *          take the even/odd lanes; the row blur loads the run shifted by each tap, the column blur
 *          the run of each tap's row; U loads the VEC/2 + 2 coarse pixels under a run from each of two
 *          coarse rows and spreads them with fixed shuffles and the fixed weights 3/4, 1/4.
 *          Work-items whose runs all lie inside their rows use plain vector loads and stores; the
 *          others clamp lane by lane (row_run.h).
 *          Every pixel's value is the same float expression, in the same order, for every VEC.
 */
#pragma OPENCL FP_CONTRACT OFF
#include "row_run.h"

/* The run helpers below are inlined into each kernel twice, once with inside = true and once with
 * false, so that the interior work-items run straight-line vector loads and stores (without the
 * attribute, LLVM merges the two calls into one with a run-time flag). */
#if defined(__clang__)
#define INLINE static inline __attribute__((always_inline))
#else
#define INLINE static inline
#endif

/* A run of VEC pixels at x of a row of `width` pixels (row_run.h): `inside` (known by the caller for
 * the whole work-item, so every load and store of the run takes one path) skips the edge checks. */
#define LOAD_RUN(inside, row, x, width) ((inside) ? vloadV(0, (row) + (x)) : row_load_f((row), (x), (width)))
#define STORE_RUN(inside, v, row, x, width) \
    do { if (inside) vstoreV((v), 0, (row) + (x)); else row_store_f((v), (row), (x), (width)); } while (0)

/* A 2x2 mean's run of VEC outputs at x0 reads the 2*VEC inputs from 2*x0 as two runs `lo`, `hi`
 * (for VEC = 1 the pixels 2*x0 and 2*x0 + 1): EVENS/ODDS are the left/right pixel of each pair.
 * Clamp-to-edge loads repeat the last column for odd widths. */
#if VEC == 1
#define PAIR_STEP 1
#define EVENS(lo, hi) (lo)
#define ODDS(lo, hi) (hi)
#else
#define PAIR_STEP VEC
#define EVENS(lo, hi) ((floatV)((lo).even, (hi).even))
#define ODDS(lo, hi) ((floatV)((lo).odd, (hi).odd))
#endif

/* ((a + b) + (d + e)) * 0.25 of the pairs of two rows' loads (lo0, hi0 row 0; lo1, hi1 row 1). */
INLINE floatV mean2x2(floatV lo0, floatV hi0, floatV lo1, floatV hi1)
{
    return ((EVENS(lo0, hi0) + ODDS(lo0, hi0)) + (EVENS(lo1, hi1) + ODDS(lo1, hi1))) * 0.25f;
}

/* One run of bloom_bright_down (bright = 1) or bloom_down (bright = 0): rows r0, r1 of the finer
 * level (width w) -> the run at x0 of a coarser row (wo pixels) at dst. */
INLINE void down_run(global const float* r0, global const float* r1, int w, float threshold, bool bright,
                     global float* dst, int x0, int wo, bool inside)
{
    floatV lo0 = LOAD_RUN(inside, r0, 2 * x0, w), hi0 = LOAD_RUN(inside, r0, 2 * x0 + PAIR_STEP, w);
    floatV lo1 = LOAD_RUN(inside, r1, 2 * x0, w), hi1 = LOAD_RUN(inside, r1, 2 * x0 + PAIR_STEP, w);
    if (bright) {
        lo0 = fmax(lo0 - threshold, 0.0f);
        hi0 = fmax(hi0 - threshold, 0.0f);
        lo1 = fmax(lo1 - threshold, 0.0f);
        hi1 = fmax(hi1 - threshold, 0.0f);
    }
    STORE_RUN(inside, mean2x2(lo0, hi0, lo1, hi1), dst, x0, wo);
}

/* 2x2 mean of bright = max(color - threshold, 0): W x H colour -> level 1 (w1 x h1). */
kernel void bloom_bright_down(global const float* color, int width, int height, float threshold,
                              global float* level, int w1, int h1)
{
    const int x0 = get_global_id(0) * VEC, y = get_global_id(1);
    if (x0 >= w1 || y >= h1) return;
    const int y0 = 2 * y, y1 = min(y0 + 1, height - 1);
    const int plane = width * height, out_plane = w1 * h1;
    const bool inside = 2 * (x0 + VEC) <= width && x0 + VEC <= w1;
    for (int c = 0; c < 3; ++c) {
        global const float* p = color + c * plane;
        global float* dst = level + c * out_plane + y * w1;
        if (inside)
            down_run(p + y0 * width, p + y1 * width, width, threshold, true, dst, x0, w1, true);
        else
            down_run(p + y0 * width, p + y1 * width, width, threshold, true, dst, x0, w1, false);
    }
}

/* 2x2 mean: level l-1 (w x h, at pyramid + src) -> level l (wo x ho, at pyramid + dst), clamp-to-edge
 * for odd sizes. */
kernel void bloom_down(global float* pyramid, int src, int w, int h, int dst, int wo, int ho)
{
    const int x0 = get_global_id(0) * VEC, y = get_global_id(1);
    if (x0 >= wo || y >= ho) return;
    const int y0 = 2 * y, y1 = min(y0 + 1, h - 1);
    const int plane = w * h, out_plane = wo * ho;
    const bool inside = 2 * (x0 + VEC) <= w && x0 + VEC <= wo;
    for (int c = 0; c < 3; ++c) {
        global const float* p = pyramid + src + c * plane;
        global float* out = pyramid + dst + c * out_plane + y * wo;
        if (inside)
            down_run(p + y0 * w, p + y1 * w, w, 0.0f, false, out, x0, wo, true);
        else
            down_run(p + y0 * w, p + y1 * w, w, 0.0f, false, out, x0, wo, false);
    }
}

/* Horizontal Gaussian of one level (w x h, at pyramid + offset) into tmp, clamp-to-edge: per channel
 * sum += taps[k + R] * pixel(x + k), k = -R..R in order, from 0. */
INLINE void blur_row_run(global const float* r, int plane, int x0, int w, global const float* taps,
                         int radius, global float* out, bool inside)
{
    floatV s0 = 0.0f, s1 = 0.0f, s2 = 0.0f;
    for (int k = -radius; k <= radius; ++k) {
        const float t = taps[k + radius];
        s0 += t * LOAD_RUN(inside, r, x0 + k, w);
        s1 += t * LOAD_RUN(inside, r + plane, x0 + k, w);
        s2 += t * LOAD_RUN(inside, r + 2 * plane, x0 + k, w);
    }
    STORE_RUN(inside, s0, out, x0, w);
    STORE_RUN(inside, s1, out + plane, x0, w);
    STORE_RUN(inside, s2, out + 2 * plane, x0, w);
}

kernel void bloom_blur_rows(global const float* pyramid, int offset, int w, int h, global const float* taps,
                            int radius, global float* tmp)
{
    const int x0 = get_global_id(0) * VEC, y = get_global_id(1);
    if (x0 >= w || y >= h) return;
    global const float* r = pyramid + offset + y * w;
    if (x0 - radius >= 0 && x0 + VEC + radius <= w)
        blur_row_run(r, w * h, x0, w, taps, radius, tmp + y * w, true);
    else
        blur_row_run(r, w * h, x0, w, taps, radius, tmp + y * w, false);
}

/* Bilinear 2x upsample along x of one coarse row (wc pixels) at the fine pixels x0 .. x0 + VEC - 1:
 * fine x reads u = (x + 0.5) / 2 - 0.5 clamped to [0, wc - 1]. Even x = 2i: 3/4 of pixel i - 1 plus
 * 1/4 of i, odd x = 2i + 1: 3/4 of i plus 1/4 of i + 1, evaluated as left + (right - left) * a with
 * a = 3/4 or 1/4 (u's fraction); at the clamped ends left = right (clamp-to-edge loads), which gives
 * the edge pixel exactly, as u's clamp does. For VEC > 1, x0 is even and the VEC/2 + 2 coarse pixels
 * k_0.. from x0/2 - 1 (clamped) hold every lane's pair: lane j takes k_((j+1)/2) and the next one.
 * `inside` (UP_INSIDE): the middle VEC/2 of them lie in the row, one vector load; the first and the
 * last are clamped scalar loads, so a fine run at the row's end still takes this path. */
INLINE floatV up_row(global const float* row, int wc, int x0, bool inside)
{
#if VEC == 1
    const int i = x0 >> 1, odd = x0 & 1;
    const float left = row[clamp(i - 1 + odd, 0, wc - 1)], right = row[clamp(i + odd, 0, wc - 1)];
    return left + (right - left) * (odd ? 0.25f : 0.75f);
#else
    const int kx = x0 / 2 - 1;
    floatV k;
    if (inside) {
        const float first = row[max(kx, 0)], last = row[min(kx + VEC / 2 + 1, wc - 1)];
#if VEC == 4
        k = (floatV)(first, vload2(0, row + kx + 1), last);
#elif VEC == 8
        k = (floatV)(first, vload4(0, row + kx + 1), last, last, last);
#else
        k = (floatV)(first, vload8(0, row + kx + 1), last, last, last, last, last, last, last);
#endif
    } else {
        k = row_load_f(row, kx, wc);
    }
#if VEC == 4
    const floatV left = (floatV)(k.s0, k.s1, k.s1, k.s2);
    const floatV right = (floatV)(k.s1, k.s2, k.s2, k.s3);
#elif VEC == 8
    const floatV left = (floatV)(k.s0, k.s1, k.s1, k.s2, k.s2, k.s3, k.s3, k.s4);
    const floatV right = (floatV)(k.s1, k.s2, k.s2, k.s3, k.s3, k.s4, k.s4, k.s5);
#else
    const floatV left = (floatV)(k.s0, k.s1, k.s1, k.s2, k.s2, k.s3, k.s3, k.s4,
                                 k.s4, k.s5, k.s5, k.s6, k.s6, k.s7, k.s7, k.s8);
    const floatV right = (floatV)(k.s1, k.s2, k.s2, k.s3, k.s3, k.s4, k.s4, k.s5,
                                  k.s5, k.s6, k.s6, k.s7, k.s7, k.s8, k.s8, k.s9);
#endif
    const floatV a = 0.75f - 0.5f * convert_floatV(LANES & 1);         /* 3/4 on even lanes, 1/4 on odd */
    return left + (right - left) * a;
#endif
}

/* Whether up_row's middle VEC/2 coarse pixels for the fine run at x0 lie in a coarse row of wc pixels
 * (true for every full fine run, as wc = ceil(w / 2)). */
#define UP_INSIDE(x0, wc) ((x0) / 2 + VEC / 2 <= (wc))

/* Bilinear 2x upsample of one coarse plane (wc x hc) at the fine run (x0 .., y): the two coarse rows
 * are interpolated along x, then between them as v = (y + 0.5) / 2 - 0.5 (the same weights). */
INLINE floatV up2(global const float* plane, int wc, int hc, int x0, int y, bool inside)
{
    const int i = y >> 1, odd = y & 1;
    const int j0 = clamp(i - 1 + odd, 0, hc - 1), j1 = clamp(i + odd, 0, hc - 1);
    const floatV top = up_row(plane + j0 * wc, wc, x0, inside), bot = up_row(plane + j1 * wc, wc, x0, inside);
    return top + (bot - top) * (odd ? 0.25f : 0.75f);
}

/* Vertical Gaussian of one level (w x h) from tmp, plus (coarse >= 0) the 2x upsample of the
 * coarser level's accumulated bloom (wc x hc at pyramid + coarse), written into the level (at
 * pyramid + offset), clamp-to-edge. */
INLINE void blur_col_run(global const float* tmp, int w, int h, global const float* taps, int radius,
                         global float* pyramid, int offset, int coarse, int wc, int hc, int x0, int y,
                         bool inside)
{
    const int plane = w * h;
    floatV s0 = 0.0f, s1 = 0.0f, s2 = 0.0f;
    for (int k = -radius; k <= radius; ++k) {
        const float t = taps[k + radius];
        global const float* r = tmp + ROW_CLAMP(y + k, h) * w;
        s0 += t * LOAD_RUN(inside, r, x0, w);
        s1 += t * LOAD_RUN(inside, r + plane, x0, w);
        s2 += t * LOAD_RUN(inside, r + 2 * plane, x0, w);
    }
    if (coarse >= 0) {
        const int cplane = wc * hc;
        s0 += up2(pyramid + coarse, wc, hc, x0, y, inside);
        s1 += up2(pyramid + coarse + cplane, wc, hc, x0, y, inside);
        s2 += up2(pyramid + coarse + 2 * cplane, wc, hc, x0, y, inside);
    }
    global float* dst = pyramid + offset + y * w;
    STORE_RUN(inside, s0, dst, x0, w);
    STORE_RUN(inside, s1, dst + plane, x0, w);
    STORE_RUN(inside, s2, dst + 2 * plane, x0, w);
}

kernel void bloom_blur_cols(global const float* tmp, int w, int h, global const float* taps, int radius,
                            global float* pyramid, int offset, int coarse, int wc, int hc)
{
    const int x0 = get_global_id(0) * VEC, y = get_global_id(1);
    if (x0 >= w || y >= h) return;
    if (x0 + VEC <= w && (coarse < 0 || UP_INSIDE(x0, wc)))
        blur_col_run(tmp, w, h, taps, radius, pyramid, offset, coarse, wc, hc, x0, y, true);
    else
        blur_col_run(tmp, w, h, taps, radius, pyramid, offset, coarse, wc, hc, x0, y, false);
}

/* out = color + scale * up2(level 1's accumulated bloom), scale = strength / L. */
INLINE void compose_run(global const float* color, int width, int plane, global const float* pyramid,
                        int w1, int h1, float scale, global float* out, int x0, int y, bool inside)
{
    for (int c = 0; c < 3; ++c) {
        const int row = c * plane + y * width;
        const floatV acc = up2(pyramid + c * w1 * h1, w1, h1, x0, y, inside);
        STORE_RUN(inside, LOAD_RUN(inside, color + row, x0, width) + scale * acc, out + row, x0, width);
    }
}

kernel void bloom_compose(global const float* color, int width, int height, global const float* pyramid,
                          int w1, int h1, float scale, global float* out)
{
    const int x0 = get_global_id(0) * VEC, y = get_global_id(1);
    if (x0 >= width || y >= height) return;
    if (x0 + VEC <= width && UP_INSIDE(x0, w1))
        compose_run(color, width, width * height, pyramid, w1, h1, scale, out, x0, y, true);
    else
        compose_run(color, width, width * height, pyramid, w1, h1, scale, out, x0, y, false);
}
