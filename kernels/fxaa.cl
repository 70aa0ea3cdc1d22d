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
 * Work-groups: 2-D, any size (clrender/passes/edge_aa.py: work_group(), one row of runs); work-item
 * (i, y) owns the run of VEC horizontally adjacent pixels x0 = i·VEC .. x0 + VEC - 1 of row y
 * (vec.h: VEC 8 or 16 on CPUs, 1 on GPUs), loaded and stored as vectors by row_run.h
 * (clamp-to-edge loads, stores of the lanes inside the row). fxaa copies a run with no pixel
 * above the contrast threshold; otherwise it evaluates steps 2-5 over the lanes without branches
 * (selects; the lanes below the threshold keep their colour) and steps the end search while any
 * lane searches. The distance walked is the same in every searching lane, so (VEC > 1) a lane's
 * four bilinear texels are its lanes of runs loaded at a column (horizontal edge) or row
 * (vertical edge) shifted by that distance: vector loads, not gathers. It prefetches row y + 1 of
 * ldr for the blend. The global size is rounded up; runs starting outside the image return; no
 * barriers, no local memory.
 */
#pragma OPENCL FP_CONTRACT OFF
#include "vec.h"
/* VEC-wide runs (CPUs): row_run.h's loads (and the helpers here) inlined, not calls that spill
 * every live vector. Not with VEC 1: Oclgrind cannot run the inlined code at -O0. */
#if VEC > 1 && defined(__clang__)
#define ROW_RUN_INLINE __attribute__((always_inline))
#endif
#include "row_run.h"

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
    const int x0 = get_global_id(0) * VEC, y = get_global_id(1);
    if (x0 >= width || y >= height) return;
    const int npix = width * height, row = y * width;
    floatV r = clamp(row_load_f(ldr + row, x0, width), 0.0f, 1.0f);
    floatV g = clamp(row_load_f(ldr + npix + row, x0, width), 0.0f, 1.0f);
    floatV b = clamp(row_load_f(ldr + 2 * npix + row, x0, width), 0.0f, 1.0f);
    row_store_f(sqrt(0.2126f * r + 0.7152f * g + 0.0722f * b), luma + row, x0, width);
}

/* The end search's bilinear luma at (bx, by) + s·(ax, ay) (pixel units, pixel centres at integers,
 * texels clamped to the image) for the lanes `searching`; s = ±(the walked distance), the same in
 * every lane. */
static inline ROW_RUN_INLINE floatV fxaa_sample(global const float* luma, int x0, int y, int width, int height,
                                                floatV bx, floatV by, floatV ax, floatV ay, float s,
                                                intV horizontal, intV toward_pos, intV searching)
{
    const floatV px = bx + ax * s, py = by + ay * s;
    const floatV fx0 = floor(px), fy0 = floor(py);
    const floatV tx = px - fx0, ty = py - fy0;
#if VEC == 1
    const int ix = convert_intV(fx0), iy = convert_intV(fy0);
    const int r0 = ROW_CLAMP(iy, height) * width, r1 = ROW_CLAMP(iy + 1, height) * width;
    const float a = luma[r0 + clamp(ix, 0, width - 1)], b = luma[r0 + clamp(ix + 1, 0, width - 1)];
    const float c = luma[r1 + clamp(ix, 0, width - 1)], d = luma[r1 + clamp(ix + 1, 0, width - 1)];
#else
    /* s is a multiple of 1/2, exact: a lane's texel column (horizontal edge) or row (vertical edge)
     * is its own shifted by floor(s), so the texels are lanes of runs loaded at that shift. */
    const int shift = (int)floor(s);
    floatV a = 0.0f, b = 0.0f, c = 0.0f, d = 0.0f;
    if (ANY(searching && horizontal)) {
        /* rows y - 1/2 ± 1/2 (towards N) or y + 1/2 ± 1/2 (towards S), columns x + shift, + 1 */
        const int up = ROW_CLAMP(y - 1, height) * width, row = y * width, down = ROW_CLAMP(y + 1, height) * width;
        const int x = x0 + shift;
        const floatV a_n = row_load_f(luma + up, x, width), b_n = row_load_f(luma + up, x + 1, width);
        const floatV a_m = row_load_f(luma + row, x, width), b_m = row_load_f(luma + row, x + 1, width);
        const floatV a_s = row_load_f(luma + down, x, width), b_s = row_load_f(luma + down, x + 1, width);
        a = select(a_n, a_m, toward_pos);
        b = select(b_n, b_m, toward_pos);
        c = select(a_m, a_s, toward_pos);
        d = select(b_m, b_s, toward_pos);
    }
    if (ANY(searching && !horizontal)) {
        /* rows y + shift, + 1, columns x - 1/2 ± 1/2 (towards W) or x + 1/2 ± 1/2 (towards E) */
        const int r0 = ROW_CLAMP(y + shift, height) * width, r1 = ROW_CLAMP(y + shift + 1, height) * width;
        const floatV w0 = row_load_f(luma + r0, x0 - 1, width), m0 = row_load_f(luma + r0, x0, width);
        const floatV e0 = row_load_f(luma + r0, x0 + 1, width), w1 = row_load_f(luma + r1, x0 - 1, width);
        const floatV m1 = row_load_f(luma + r1, x0, width), e1 = row_load_f(luma + r1, x0 + 1, width);
        a = select(select(w0, m0, toward_pos), a, horizontal);
        b = select(select(m0, e0, toward_pos), b, horizontal);
        c = select(select(w1, m1, toward_pos), c, horizontal);
        d = select(select(m1, e1, toward_pos), d, horizontal);
    }
#endif
    return (a + (b - a) * tx) + ((c + (d - c) * tx) - (a + (b - a) * tx)) * ty;
}

kernel void fxaa(global const float* ldr, global const float* luma, int width, int height, global float* out)
{
    const int x0 = get_global_id(0) * VEC, y = get_global_id(1);
    if (x0 >= width || y >= height) return;
    const int npix = width * height, row = y * width;
    const int up = ROW_CLAMP(y - 1, height) * width, down = ROW_CLAMP(y + 1, height) * width;
    for (int c = 0; c < 3; ++c) ROW_PREFETCH(ldr + c * npix + down + x0);   /* for the blend: rows y ± 1 */
    const floatV m = row_load_f(luma + row, x0, width);
    const floatV n = row_load_f(luma + up, x0, width), s = row_load_f(luma + down, x0, width);
    const floatV w = row_load_f(luma + row, x0 - 1, width), e = row_load_f(luma + row, x0 + 1, width);
    const floatV hi = fmax(fmax(fmax(n, s), fmax(w, e)), m), lo = fmin(fmin(fmin(n, s), fmin(w, e)), m);
    const floatV range = hi - lo;
    /* 1. local contrast: the lanes below the threshold keep their colour */
    const intV active = !(range < fmax(FXAA_EDGE_THRESHOLD_MIN, hi * FXAA_EDGE_THRESHOLD));
    if (!ANY(active)) {
        for (int c = 0; c < 3; ++c)
            row_store_f(row_load_f(ldr + c * npix + row, x0, width), out + c * npix + row, x0, width);
        return;
    }
    const floatV nw = row_load_f(luma + up, x0 - 1, width), ne = row_load_f(luma + up, x0 + 1, width);
    const floatV sw = row_load_f(luma + down, x0 - 1, width), se = row_load_f(luma + down, x0 + 1, width);

    /* 2. subpixel term */
    floatV sub = clamp(fabs((2.0f * (n + s + w + e) + (nw + ne + sw + se)) / 12.0f - m) / range, 0.0f, 1.0f);
    sub = sub * sub * (3.0f - 2.0f * sub);
    sub = sub * sub * FXAA_SUBPIX;

    /* 3. orientation and side */
    const floatV edge_h = fabs(nw + sw - 2.0f * w) + 2.0f * fabs(n + s - 2.0f * m) + fabs(ne + se - 2.0f * e);
    const floatV edge_v = fabs(nw + ne - 2.0f * n) + 2.0f * fabs(w + e - 2.0f * m) + fabs(sw + se - 2.0f * s);
    const intV horizontal = edge_h >= edge_v;
    const floatV l_neg = select(w, n, horizontal), l_pos = select(e, s, horizontal);
    const intV toward_pos = fabs(l_pos - m) > fabs(l_neg - m);
    const floatV l_side = select(l_neg, l_pos, toward_pos);
    const intV side = select((intV)-1, (intV)1, toward_pos);
    const intV px = select(side, (intV)0, horizontal), py = select((intV)0, side, horizontal);  /* across */
    const floatV ax = select((floatV)0.0f, (floatV)1.0f, horizontal);                           /* along */
    const floatV ay = select((floatV)1.0f, (floatV)0.0f, horizontal);
    const floatV avg = 0.5f * (m + l_side);
    const floatV scaled = 0.25f * fabs(l_side - m);

    /* 4. end search from the edge (half a pixel towards the side), while any lane searches */
    const intV xs = (intV)x0 + LANES;
    const floatV bx = convert_floatV(xs) + 0.5f * convert_floatV(px);
    const floatV by = (float)y + 0.5f * convert_floatV(py);
    floatV d_neg = 0.0f, d_pos = 0.0f, end_neg = 0.0f, end_pos = 0.0f;
    intV done_neg = !active, done_pos = !active;
    /* A lane still searching has walked FXAA_STEP[0] + .. + FXAA_STEP[i] (exact sums), the
     * same in every lane: the samples' positions do not wait for the previous samples. */
    float walked = 0.0f;
    for (int i = 0; i < FXAA_STEPS && ANY(!(done_neg && done_pos)); ++i) {
        walked += FXAA_STEP[i];
        if (ANY(!done_neg)) {
            const floatV l = fxaa_sample(luma, x0, y, width, height, bx, by, ax, ay, -walked, horizontal, toward_pos,
                                         !done_neg) - avg;
            d_neg = select((floatV)walked, d_neg, done_neg);
            end_neg = select(l, end_neg, done_neg);
            done_neg = done_neg || fabs(l) >= scaled;
        }
        if (ANY(!done_pos)) {
            const floatV l = fxaa_sample(luma, x0, y, width, height, bx, by, ax, ay, walked, horizontal, toward_pos,
                                         !done_pos) - avg;
            d_pos = select((floatV)walked, d_pos, done_pos);
            end_pos = select(l, end_pos, done_pos);
            done_pos = done_pos || fabs(l) >= scaled;
        }
    }

    /* 5. blend towards the side */
    const intV m_below = m - avg < 0.0f;
    const intV nearer_neg = d_neg < d_pos;
    const floatV dist = select(d_pos, d_neg, nearer_neg);
    const intV good = (select(end_pos, end_neg, nearer_neg) < 0.0f) != m_below;
    const floatV offset = fmax(select((floatV)0.0f, 0.5f - dist / (d_neg + d_pos), good), sub);
    for (int c = 0; c < 3; ++c) {
        global const float* plane = ldr + c * npix;
        const floatV a = row_load_f(plane + row, x0, width);
        /* the side's colour: N/S for a horizontal edge, W/E for a vertical one (clamped) */
        const floatV b = select(select(row_load_f(plane + row, x0 - 1, width), row_load_f(plane + row, x0 + 1, width),
                                       toward_pos),
                                select(row_load_f(plane + up, x0, width), row_load_f(plane + down, x0, width),
                                       toward_pos),
                                horizontal);
        row_store_f(select(a, a + (b - a) * offset, active), out + c * npix + row, x0, width);
    }
}
