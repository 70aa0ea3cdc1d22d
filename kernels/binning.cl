/* binning.cl: sort prims into screen tiles (count, prefix sum, fill).
 *
 * Algorithm: one work-item per prim. Its pixel-center bounding box gives a tile range; for
 * prims spanning several tiles in both directions each tile is also tested against the
 * three edge functions at the tile's corner samples (a tile wholly outside one edge is
 * skipped). `bin_count` counts prims per tile with atomics; the prefix sum (scan.cl)
 * turns counts into offsets; `bin_fill` repeats the walk and appends each prim index
 * to its tiles' lists. Order inside a list is not deterministic, and need not be: visibility
 * is a total order (depth, triangle id, prim index), so the image is.
 *
 * Buffers: prims Prim[*], prim_total int[1] (written by the setup scan);
 *          tile_counts int[tiles], tile_offsets int[tiles], tile_cursor int[tiles] (zeroed),
 *          tile_prims int[capacity]: tile t's prims are tile_prims[offset[t] .. +count[t]).
 * Work-groups: 1-D, any size; global atomics only, no barriers.
 */
#include "structs.h"

#ifndef TILE
#define TILE 16
#endif
#include "samples.h"     /* SAMPLES (1): bin for sample points up to SAMPLE_SPREAD from the pixel centres */

/* Can any sample of tile (tx, ty) (a pixel center, moved by up to SAMPLE_SPREAD) be inside
 * every edge?  Conservative corner test. */
static bool tile_may_overlap(const Prim* p, int tx, int ty)
{
    long sx0 = (long)(tx * TILE) * 256 + 128 - SAMPLE_SPREAD, sx1 = sx0 + (long)(TILE - 1) * 256 + 2 * SAMPLE_SPREAD;
    long sy0 = (long)(ty * TILE) * 256 + 128 - SAMPLE_SPREAD, sy1 = sy0 + (long)(TILE - 1) * 256 + 2 * SAMPLE_SPREAD;
    for (int k = 0; k < 3; ++k) {
        int k1 = (k + 1) % 3;
        long dx = p->x[k1] - p->x[k], dy = p->y[k1] - p->y[k];
        /* E = dx·(y - Yk) - dy·(x - Xk) is largest at the corner picked by the signs. */
        long ex = (dy > 0) ? sx0 : sx1;
        long ey = (dx > 0) ? sy1 : sy0;
        if (dx * (ey - p->y[k]) - dy * (ex - p->x[k]) < 0) return false;
    }
    return true;
}

/* Tile range covered by the prim's pixel-center bounding box, widened by SAMPLE_SPREAD (inclusive). */
static int4 tile_range(const Prim* p, int width, int height)
{
    int min_x = min(min(p->x[0], p->x[1]), p->x[2]) - SAMPLE_SPREAD, max_x = max(max(p->x[0], p->x[1]), p->x[2]) + SAMPLE_SPREAD;
    int min_y = min(min(p->y[0], p->y[1]), p->y[2]) - SAMPLE_SPREAD, max_y = max(max(p->y[0], p->y[1]), p->y[2]) + SAMPLE_SPREAD;
    int px0 = max((min_x - 128 + 255) >> 8, 0), px1 = min((max_x - 128) >> 8, width - 1);
    int py0 = max((min_y - 128 + 255) >> 8, 0), py1 = min((max_y - 128) >> 8, height - 1);
    return (int4)(px0 / TILE, py0 / TILE, px1 / TILE, py1 / TILE);
}

/* Walks the tiles prim i overlaps. Count mode (tile_prims == 0): tile_counts[t]++.
 * Fill mode: append i to tile t's list at tile_offsets[t] + tile_cursor[t]++. */
static void walk_tiles(global const Prim* prims, global const int* prim_total, int capacity,
                       int width, int height, int tiles_x, global int* tile_counter,
                       global const int* tile_offsets, int list_capacity, global int* tile_prims)
{
    int i = get_global_id(0);
    if (i >= min(prim_total[0], capacity)) return;
    Prim p = prims[i];
    int4 r = tile_range(&p, width, height);
    bool test = (r.z > r.x) && (r.w > r.y);
    for (int ty = r.y; ty <= r.w; ++ty)
        for (int tx = r.x; tx <= r.z; ++tx) {
            if (test && !tile_may_overlap(&p, tx, ty)) continue;
            int t = ty * tiles_x + tx;
            int slot = atomic_inc(&tile_counter[t]);
            if (!tile_prims) continue;
            slot += tile_offsets[t];
            if (slot < list_capacity) tile_prims[slot] = i;   /* overflow: host grows and retries */
        }
}

kernel void bin_count(global const Prim* prims, global const int* prim_total, int capacity,
                      int width, int height, int tiles_x, global int* tile_counts)
{
    walk_tiles(prims, prim_total, capacity, width, height, tiles_x, tile_counts, 0, 0, 0);
}

kernel void bin_fill(global const Prim* prims, global const int* prim_total, int capacity,
                     int width, int height, int tiles_x,
                     global const int* tile_offsets, global int* tile_cursor,
                     int list_capacity, global int* tile_prims)
{
    walk_tiles(prims, prim_total, capacity, width, height, tiles_x, tile_cursor,
               tile_offsets, list_capacity, tile_prims);
}
