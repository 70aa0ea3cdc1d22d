/* row_run.h: loads and stores of a run of VEC horizontally adjacent pixels, the unit of work of
 * the VEC-wide image kernels (vec.h): work-item (i, y) owns pixels x0 .. x0 + VEC - 1 of row y,
 * x0 = i * VEC. `row` points at the first pixel of a row of `width` pixels.
 *
 * Loads clamp the column to [0, width - 1] lane by lane (clamp-to-edge): a run inside the row
 * is one contiguous vector load, a run that crosses an edge a gather. Stores write only the
 * lanes inside the row. Rows are clamped by the caller (ROW_CLAMP).
 */
#ifndef CLRENDER_ROW_RUN_H
#define CLRENDER_ROW_RUN_H
#include "vec.h"

#define ROW_CLAMP(y, height) clamp((y), 0, (height) - 1)

/* ROW_RUN_INLINE: empty by default. A kernel making many run loads may define it as
 * __attribute__((always_inline)) before including this header (edge_aa.cl, fxaa.cl, for VEC > 1):
 * each load's edge gather makes it too big for the inliner, and a call spills every live vector.
 * (Not for Oclgrind: at -O0 the inlined code uses an intrinsic it cannot run.) */
#ifndef ROW_RUN_INLINE
#define ROW_RUN_INLINE
#endif

/* ROW_PREFETCH(p): on CPUs (VEC > 1, clang), a hint to bring the cache line at p in; a kernel that
 * reads the next row only for some runs prefetches it for every run (a line that is read a row
 * later anyway), so those reads do not wait for memory. Nothing elsewhere. */
#if VEC > 1 && defined(__clang__)
#define ROW_PREFETCH(p) __builtin_prefetch(p)
#else
#define ROW_PREFETCH(p) ((void)0)
#endif

/* floatV of row[clamp(x + lane, 0, width - 1)] */
static inline ROW_RUN_INLINE floatV row_load_f(global const float* row, int x, int width)
{
#if VEC == 1
    return row[clamp(x, 0, width - 1)];
#else
    if (x >= 0 && x + VEC <= width) return vloadV(0, row + x);
    const intV xs = clamp((intV)x + LANES, 0, width - 1);
    return GATHER_F(row, xs);
#endif
}

/* uintV of row[clamp(x + lane, 0, width - 1)] */
static inline ROW_RUN_INLINE uintV row_load_u(global const uint* row, int x, int width)
{
#if VEC == 1
    return row[clamp(x, 0, width - 1)];
#else
    if (x >= 0 && x + VEC <= width) return vloadV(0, row + x);
    const intV xs = clamp((intV)x + LANES, 0, width - 1);
    return GATHER_U(row, xs);
#endif
}

/* row[x + lane] = v for the lanes with x + lane < width (x >= 0) */
static inline ROW_RUN_INLINE void row_store_f(floatV v, global float* row, int x, int width)
{
#if VEC == 1
    if (x < width) row[x] = v;
#else
    if (x + VEC <= width) {
        vstoreV(v, 0, row + x);
        return;
    }
    for (int i = 0; i < VEC && x + i < width; ++i) row[x + i] = LANE_F(v, i);
#endif
}

/* uintV of the bytes row[clamp(x + lane, 0, width - 1)] (masks, flags) */
static inline ROW_RUN_INLINE uintV row_load_uc(global const uchar* row, int x, int width)
{
#if VEC == 1
    return row[clamp(x, 0, width - 1)];
#else
    if (x >= 0 && x + VEC <= width) return convert_uintV(vloadV(0, row + x));
    const intV xs = clamp((intV)x + LANES, 0, width - 1);
    return GATHER_U(row, xs);
#endif
}

/* row[x + lane] = (uchar)v (low byte) for the lanes with x + lane < width (x >= 0) */
static inline ROW_RUN_INLINE void row_store_uc(uintV v, global uchar* row, int x, int width)
{
#if VEC == 1
    if (x < width) row[x] = (uchar)v;
#else
    if (x + VEC <= width) {
        vstoreV(CAT(convert_uchar, VEC)(v), 0, row + x);
        return;
    }
    for (int i = 0; i < VEC && x + i < width; ++i) row[x + i] = (uchar)LANE_I(v, i);
#endif
}

#endif
