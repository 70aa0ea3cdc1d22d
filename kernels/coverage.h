/* coverage.h: which pixels of a run of VEC horizontally adjacent pixel centers a prim covers,
 * and its view depth there (docs/raster_contract.md §5-6): integer edge functions with the
 * top-left rule -- 32-bit lanes wherever the values fit, else exact doubles on CPUs
 * (RASTER_FP64) or 64-bit integers -- and the perspective-correct depth (ORTHO=1: linear).
 * Shared by raster.cl (opaque visibility) and the transparent fragment walks (fragments.cl,
 * abuffer.cl, peel.cl), so every pass sees the same fragments with the same depths.
 */
#ifndef CLRENDER_COVERAGE_H
#define CLRENDER_COVERAGE_H
#include "structs.h"
#include "vec.h"

#ifndef ORTHO
#define ORTHO 0          /* 1: orthographic prims (setup.cl): inv_w holds vertex depths, interpolated linearly */
#endif

/* Prims whose bounding box is at most SMALL_EXTENT (24.8 units) on both axes have exact
 * 32-bit edge functions on any run inside their tile range: |d| < 2^14, |offset| < 2^15.
 * That common case needs no 64-bit arithmetic at all (scalar 64-bit math is slow on GPUs). */
#define SMALL_EXTENT (64 * 256)

/* Mask of the lanes of the run starting at fixed-point sample (sx0, sy), one pixel (256) apart,
 * whose centers `p` covers; where any does, *depth holds the lanes' view depths. */
static inline intV prim_cover_run_in(const Prim* p, int sx0, int sy, int min_x, int max_x, int min_y, int max_y,
                                     floatV* depth);

static inline intV prim_cover_run(const Prim* p, int sx0, int sy, floatV* depth)
{
    const int min_x = min(min(p->x[0], p->x[1]), p->x[2]), max_x = max(max(p->x[0], p->x[1]), p->x[2]);
    const int min_y = min(min(p->y[0], p->y[1]), p->y[2]), max_y = max(max(p->y[0], p->y[1]), p->y[2]);
    if (sy < min_y || sy > max_y || sx0 + (VEC - 1) * 256 < min_x || sx0 > max_x) return (intV)0;
    return prim_cover_run_in(p, sx0, sy, min_x, max_x, min_y, max_y, depth);
}

/* prim_cover_run for a run inside the prim's bounding box (min_x .. max_y, fixed point), which
 * the caller has tested (raster.cl tests it once per prim for all the rows it walks). */
static inline intV prim_cover_run_in(const Prim* p, int sx0, int sy, int min_x, int max_x, int min_y, int max_y,
                                     floatV* depth)
{

    /* E_k(lane) = base_k + step_k · lane; inside when E_k > thr_k (top-left: thr = -1). */
    intV inside_i;
    floatV e_f[3];
    if (max_x - min_x <= SMALL_EXTENT && max_y - min_y <= SMALL_EXTENT) {
        intV ok = (intV)(-1);
        for (int k = 0; k < 3; ++k) {
            int k1 = (k + 1) % 3;
            int dx = p->x[k1] - p->x[k], dy = p->y[k1] - p->y[k];
            int base = dx * (sy - p->y[k]) - dy * (sx0 - p->x[k]);
            intV e = (intV)base + (intV)(-dy * 256) * LANES;
            int thr = ((dy == 0 && dx > 0) || dy < 0) ? -1 : 0;
            ok &= e > (intV)thr;
            e_f[k] = convert_floatV(e);
        }
        inside_i = ok;
    } else {
        /* Large prim: exact 64-bit edge values at the run's ends, then per edge 32-bit lanes
         * whenever both ends fit (E is linear in the lane, so every lane does; the wrapping
         * uint arithmetic is exact) -- 64-bit lanes, whose compare and float conversion
         * CPUs without AVX-512 emulate, only for runs far from a long edge. */
        inside_i = (intV)(-1);
        for (int k = 0; k < 3; ++k) {
            int k1 = (k + 1) % 3;
            long dx = p->x[k1] - p->x[k], dy = p->y[k1] - p->y[k];
            long base = dx * (long)(sy - p->y[k]) - dy * (long)(sx0 - p->x[k]);
            long step = -dy * 256, last = base + step * (VEC - 1);
            int thr = ((dy == 0 && dx > 0) || dy < 0) ? -1 : 0;
            if (min(base, last) >= INT_MIN && max(base, last) <= INT_MAX) {
                intV e = as_intV((uintV)(uint)base + (uintV)(uint)step * as_uintV(LANES));
                inside_i &= e > (intV)thr;
                e_f[k] = convert_floatV(e);
            }
#if RASTER_FP64
            else if (max(base, last) < (1L << 52) && min(base, last) > -(1L << 52)) {
                /* base, step·lane and their sum are integers below 2^53: exact doubles */
                doubleV e = (doubleV)((double)base) + (doubleV)((double)step) * CONVERT_V(LANES, doubleV);
                inside_i &= CONVERT_V(e > (doubleV)thr, intV);
                e_f[k] = CONVERT_V(e, floatV);
            }
#endif
            else {
                longV e = (longV)base + (longV)step * CONVERT_V(LANES, longV);
                inside_i &= CONVERT_V(e > (longV)thr, intV);
                e_f[k] = CONVERT_V(e, floatV);
            }
        }
    }
    if (!ANY(inside_i)) return inside_i;

    floatV num = (e_f[1] * (floatV)p->inv_w[0] + e_f[2] * (floatV)p->inv_w[1]) + e_f[0] * (floatV)p->inv_w[2];
#if ORTHO
    *depth = num / (floatV)((float)p->area);
#else
    *depth = (floatV)((float)p->area) / num;
#endif
    return inside_i;
}
#endif
