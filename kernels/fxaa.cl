/* fxaa.cl: luminance-edge anti-aliasing of the tone-mapped linear planes, in the FXAA family
 * (Lottes 2009/2011, the "quality" variant of FXAA 3.11), written from the published
 * description; docs/post.md: tone map -> edge AA -> FXAA -> encode.
 *
 * Algorithm:
 *   fxaa_luma: L = sqrt(0.2126 R + 0.7152 G + 0.0722 B) per pixel (Rec. 709 luma of the linear
 *     values, square root as a perceptual curve), into its own plane so the search below can
 *     sample it bilinearly.
 *   fxaa: for each pixel M with direct neighbours N, S, W, E (coordinates clamped at the border):
 *   1. Local contrast: range = max - min of the five lumas; below max(FXAA_EDGE_THRESHOLD_MIN,
 *      FXAA_EDGE_THRESHOLD · max) the pixel is copied unchanged.
 *   2. Subpixel term: s = clamp(|(2(N+S+W+E) + NW+NE+SW+SE)/12 - M| / range, 0, 1),
 *      sub = (s²(3 - 2s))² · FXAA_SUBPIX (large on isolated single-pixel features).
 *   3. Orientation from second differences of the 3×3 lumas: horizontal edge when
 *      |NW+SW-2W| + 2|N+S-2M| + |NE+SE-2E| >= |NW+NE-2N| + 2|W+E-2M| + |SW+SE-2S|.
 *      The edge lies between M and the perpendicular neighbour with the larger luma step
 *      (N or S for a horizontal edge, W or E for a vertical one): side, step g = |L_side - M|.
 *   4. End search: start half a pixel towards that side (on the edge, where the bilinear luma is
 *      avg = (M + L_side)/2) and walk along the edge both ways with the FXAA_STEPS fixed steps
 *      1, 1.5, 2, 2, 2, 2, 4, 8 pixels (8 samples each way, reach 22.5 pixels), sampling
 *      the luma plane bilinearly, until |L - avg| >= g/4 (the edge ended: the pair of rows no
 *      longer straddles it). Unfinished searches end at the last step.
 *   5. Blend: with dN, dP the distances to the two ends, the nearer end decides: if its luma
 *      departs from avg in the direction opposite to M's (M - avg), M is on the short side of
 *      a stair step and the offset is 0.5 - min(dN, dP)/(dN + dP), else 0. The final offset is
 *      max(that, sub), and the pixel becomes (1 - offset)·M + offset·side colour (the linear
 *      planes sampled `offset` pixels towards the side).
 *
 * Buffers: ldr, out float[3][H·W] planes R, G, B (out is a separate buffer: neighbours are read);
 * luma float[H·W] (fxaa_luma out, fxaa in).
 * Work-groups: 2-D, one pixel per work-item, any size (clrender/passes/fxaa.py uses 8 × 8); the
 * global size is rounded up and work-items outside the image return; no barriers, no local memory.
 */
#pragma OPENCL FP_CONTRACT OFF

#ifndef FXAA_EDGE_THRESHOLD
#define FXAA_EDGE_THRESHOLD 0.125f       /* local contrast needed, relative to the max luma */
#endif
#ifndef FXAA_EDGE_THRESHOLD_MIN
#define FXAA_EDGE_THRESHOLD_MIN 0.0312f  /* ... and in absolute terms (dark regions) */
#endif
#ifndef FXAA_SUBPIX
#define FXAA_SUBPIX 0.75f                /* strength of the subpixel term, 0 (off) .. 1 */
#endif
#define FXAA_STEPS 8
constant float FXAA_STEP[FXAA_STEPS] = {1.0f, 1.5f, 2.0f, 2.0f, 2.0f, 2.0f, 4.0f, 8.0f};

kernel void fxaa_luma(global const float* ldr, int width, int height, global float* luma)
{
    const int x = get_global_id(0), y = get_global_id(1);
    if (x >= width || y >= height) return;
    const int npix = width * height, p = y * width + x;
    float r = clamp(ldr[p], 0.0f, 1.0f), g = clamp(ldr[npix + p], 0.0f, 1.0f), b = clamp(ldr[2 * npix + p], 0.0f, 1.0f);
    luma[p] = sqrt(0.2126f * r + 0.7152f * g + 0.0722f * b);
}

static inline float luma_at(global const float* luma, int x, int y, int width, int height)
{
    return luma[clamp(y, 0, height - 1) * width + clamp(x, 0, width - 1)];
}

/* Bilinear luma at (x, y) in pixel units (pixel centres at integers), clamped to the image. */
static inline float luma_bilinear(global const float* luma, float x, float y, int width, int height)
{
    float fx0 = floor(x), fy0 = floor(y);
    int x0 = (int)fx0, y0 = (int)fy0;
    float tx = x - fx0, ty = y - fy0;
    float a = luma_at(luma, x0, y0, width, height), b = luma_at(luma, x0 + 1, y0, width, height);
    float c = luma_at(luma, x0, y0 + 1, width, height), d = luma_at(luma, x0 + 1, y0 + 1, width, height);
    return (a + (b - a) * tx) + ((c + (d - c) * tx) - (a + (b - a) * tx)) * ty;
}

kernel void fxaa(global const float* ldr, global const float* luma, int width, int height, global float* out)
{
    const int x = get_global_id(0), y = get_global_id(1);
    if (x >= width || y >= height) return;
    const int npix = width * height, p = y * width + x;
    const float m = luma[p];
    const float n = luma_at(luma, x, y - 1, width, height), s = luma_at(luma, x, y + 1, width, height);
    const float w = luma_at(luma, x - 1, y, width, height), e = luma_at(luma, x + 1, y, width, height);
    const float hi = fmax(fmax(fmax(n, s), fmax(w, e)), m), lo = fmin(fmin(fmin(n, s), fmin(w, e)), m);
    const float range = hi - lo;
    if (range < fmax(FXAA_EDGE_THRESHOLD_MIN, hi * FXAA_EDGE_THRESHOLD)) {
        out[p] = ldr[p];
        out[npix + p] = ldr[npix + p];
        out[2 * npix + p] = ldr[2 * npix + p];
        return;
    }
    const float nw = luma_at(luma, x - 1, y - 1, width, height), ne = luma_at(luma, x + 1, y - 1, width, height);
    const float sw = luma_at(luma, x - 1, y + 1, width, height), se = luma_at(luma, x + 1, y + 1, width, height);

    /* 2. subpixel term */
    float sub = clamp(fabs((2.0f * (n + s + w + e) + (nw + ne + sw + se)) / 12.0f - m) / range, 0.0f, 1.0f);
    sub = sub * sub * (3.0f - 2.0f * sub);
    sub = sub * sub * FXAA_SUBPIX;

    /* 3. orientation and side */
    const float edge_h = fabs(nw + sw - 2.0f * w) + 2.0f * fabs(n + s - 2.0f * m) + fabs(ne + se - 2.0f * e);
    const float edge_v = fabs(nw + ne - 2.0f * n) + 2.0f * fabs(w + e - 2.0f * m) + fabs(sw + se - 2.0f * s);
    const int horizontal = edge_h >= edge_v;
    const float l_neg = horizontal ? n : w, l_pos = horizontal ? s : e;
    const int toward_pos = fabs(l_pos - m) > fabs(l_neg - m);
    const float l_side = toward_pos ? l_pos : l_neg;
    const int side = toward_pos ? 1 : -1;
    const int px = horizontal ? 0 : side, py = horizontal ? side : 0;       /* across, to the side */
    const float ax = horizontal ? 1.0f : 0.0f, ay = horizontal ? 0.0f : 1.0f;  /* along the edge */
    const float avg = 0.5f * (m + l_side);
    const float scaled = 0.25f * fabs(l_side - m);

    /* 4. end search from the edge (half a pixel towards the side) */
    const float bx = (float)x + 0.5f * (float)px, by = (float)y + 0.5f * (float)py;
    float d_neg = 0.0f, d_pos = 0.0f, end_neg = 0.0f, end_pos = 0.0f;
    int done_neg = 0, done_pos = 0;
    for (int i = 0; i < FXAA_STEPS && !(done_neg && done_pos); ++i) {
        if (!done_neg) {
            d_neg += FXAA_STEP[i];
            end_neg = luma_bilinear(luma, bx - ax * d_neg, by - ay * d_neg, width, height) - avg;
            done_neg = fabs(end_neg) >= scaled;
        }
        if (!done_pos) {
            d_pos += FXAA_STEP[i];
            end_pos = luma_bilinear(luma, bx + ax * d_pos, by + ay * d_pos, width, height) - avg;
            done_pos = fabs(end_pos) >= scaled;
        }
    }

    /* 5. blend towards the side */
    const int m_below = m - avg < 0.0f;
    const int nearer_neg = d_neg < d_pos;
    const float dist = nearer_neg ? d_neg : d_pos;
    const int good = ((nearer_neg ? end_neg : end_pos) < 0.0f) != m_below;
    const float offset = fmax(good ? 0.5f - dist / (d_neg + d_pos) : 0.0f, sub);
    const int q = clamp(y + py, 0, height - 1) * width + clamp(x + px, 0, width - 1);
    for (int c = 0; c < 3; ++c) {
        const float a = ldr[c * npix + p], b = ldr[c * npix + q];
        out[c * npix + p] = a + (b - a) * offset;
    }
}
