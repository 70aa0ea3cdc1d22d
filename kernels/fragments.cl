/* fragments.cl: the walks over transparent fragments (count, A-buffer fill, next peel layer).
 *
 * Algorithm (docs/transparency.md): the BLEND prims, set up and binned like the opaque ones in
 * lists of their own, are walked per TILE×TILE tile exactly as raster.cl walks the opaque
 * ones (coverage.h: same coverage and depth). A fragment is a covered pixel center whose view
 * depth z satisfies z < the opaque depth (vis_depth: strictly in front, +inf = background) and
 * z <= far; fragments are ordered by the key (z, prim index) -- prim indices follow triangle
 * ids, so this is (z, triangle id, piece): a total order, the same on every device and run.
 *  - `fragment_count`: per pixel the count (Frame.fragment_count; the A-buffer's list lengths,
 *    clamped to MAX_FRAGMENTS when that is set) and the nearest and farthest fragment depths,
 *    which light culling adds to its tiles' depth ranges so a light reaching only a
 *    transparent surface is still listed.
 *  - `fragment_fill` (A-buffer): writes each pixel's fragments (depth, prim) at its list offset
 *    (prefix sum of list_len); with MAX_FRAGMENTS, keeps the nearest ones sorted (insertion,
 *    the farthest evicted). Unsorted otherwise: abuffer.cl sorts.
 *  - `fragment_next_layer` (depth peeling): the fragment with the smallest key greater than
 *    the previous layer's, per pixel (prim -1: none left).
 *
 * Buffers: prims Prim[*] (BLEND only); tile_offsets/tile_counts int[tiles], tile_prims int[cap];
 *          vis_depth float[W·H] (opaque view depth). out: frag_count int[W·H], list_len int[W·H]
 *          (min(count, MAX_FRAGMENTS)), t_range float[2][W·H] (nearest, farthest linear depth
 *          z/far; +inf/-inf where there is none). A-buffer: list_offsets int[W·H],
 *          frag_depth float[capacity], frag_prim int[capacity]. Peeling: layer_depth float[W·H],
 *          layer_prim int[W·H] (read: the previous layer; written: this one).
 * Work-groups: (TILE/VEC, TILE), one per tile; each work-item owns a run of VEC pixels (vec.h).
 * No barriers, no local memory.
 */
#pragma OPENCL FP_CONTRACT OFF
#include "structs.h"

#ifndef TILE
#define TILE 8
#endif
#ifndef MAX_FRAGMENTS
#define MAX_FRAGMENTS 0      /* 0: no cap */
#endif
#include "vec.h"
#include "coverage.h"

/* Lanes of the run whose pixel is covered by `p` in front of the opaque surface; *depth. */
static inline intV fragment_lanes(const Prim* p, int sx0, int sy, floatV opaque, float far, floatV* depth)
{
    const intV inside = prim_cover_run(p, sx0, sy, depth);
    if (!ANY(inside)) return inside;
    return inside & (*depth < opaque) & (*depth <= (floatV)far);
}

/* The run's opaque depths (+inf past the image's right edge). */
static inline floatV load_opaque(global const float* vis_depth, int px0, int py, int width)
{
    floatV d = (floatV)INFINITY;
    for (int l = 0; l < VEC; ++l)
        if (px0 + l < width) LANE_F(d, l) = vis_depth[py * width + px0 + l];
    return d;
}

kernel __attribute__((reqd_work_group_size(TILE / VEC, TILE, 1)))
void fragment_count(global const Prim* prims, global const int* tile_offsets, global const int* tile_counts,
                    global const int* tile_prims, int tile_list_capacity, int tiles_x, int width, int height,
                    float far, global const float* vis_depth,
                    global int* frag_count, global int* list_len, global float* t_range)
{
    const int px0 = get_global_id(0) * VEC, py = get_global_id(1);
    if (py >= height || px0 >= width) return;
    const int tile = get_group_id(1) * tiles_x + get_group_id(0);
    const int sx0 = px0 * 256 + 128, sy = py * 256 + 128;
    const floatV opaque = load_opaque(vis_depth, px0, py, width);

    intV count = 0;
    floatV nearest = (floatV)INFINITY, farthest = (floatV)(-INFINITY);
    const int start = tile_offsets[tile];
    const int end = min(start + tile_counts[tile], tile_list_capacity);
    for (int i = start; i < end; ++i) {
        const Prim p = prims[tile_prims[i]];
        floatV depth;
        const intV front = fragment_lanes(&p, sx0, sy, opaque, far, &depth);
        if (!ANY(front)) continue;
        count += select((intV)0, (intV)1, front);
        nearest = select(nearest, fmin(nearest, depth), front);
        farthest = select(farthest, fmax(farthest, depth), front);
    }
    const int npix = width * height;
    for (int l = 0; l < VEC && px0 + l < width; ++l) {
        const int q = py * width + px0 + l;
        const int c = LANE_I(count, l);
        frag_count[q] = c;
        list_len[q] = MAX_FRAGMENTS > 0 ? min(c, MAX_FRAGMENTS) : c;
        t_range[q] = LANE_F(nearest, l) / far;
        t_range[npix + q] = LANE_F(farthest, l) / far;
    }
}

/* Is key (d, p) before key (d2, p2)? */
#define KEY_LESS(d, p, d2, p2) ((d) < (d2) || ((d) == (d2) && (p) < (p2)))

kernel __attribute__((reqd_work_group_size(TILE / VEC, TILE, 1)))
void fragment_fill(global const Prim* prims, global const int* tile_offsets, global const int* tile_counts,
                   global const int* tile_prims, int tile_list_capacity, int tiles_x, int width, int height,
                   float far, global const float* vis_depth, global const int* list_len,
                   global const int* list_offsets, int capacity, global float* frag_depth, global int* frag_prim)
{
    const int px0 = get_global_id(0) * VEC, py = get_global_id(1);
    if (py >= height || px0 >= width) return;
    const int tile = get_group_id(1) * tiles_x + get_group_id(0);
    const int sx0 = px0 * 256 + 128, sy = py * 256 + 128;
    const floatV opaque = load_opaque(vis_depth, px0, py, width);
    intV base, room;             /* per lane: list offset; lanes whose list does not fit get room 0 */
    for (int l = 0; l < VEC; ++l) {
        const int q = py * width + min(px0 + l, width - 1);
        LANE_I(base, l) = list_offsets[q];
        LANE_I(room, l) = (px0 + l < width && list_offsets[q] >= 0 && list_len[q] <= capacity - list_offsets[q])
                          ? list_len[q] : 0;          /* past 2^31 fragments offsets wrap: nothing written */
    }
    intV filled = 0;
    const int start = tile_offsets[tile];
    const int end = min(start + tile_counts[tile], tile_list_capacity);
    for (int i = start; i < end; ++i) {
        const int pi = tile_prims[i];
        const Prim p = prims[pi];
        floatV depth;
        const intV front = fragment_lanes(&p, sx0, sy, opaque, far, &depth);
        if (!ANY(front)) continue;
        for (int l = 0; l < VEC; ++l) {
            if (!LANE_I(front, l) || LANE_I(room, l) == 0) continue;
            const float d = LANE_F(depth, l);
            global float* D = frag_depth + LANE_I(base, l);
            global int* P = frag_prim + LANE_I(base, l);
            const int n = LANE_I(filled, l);
#if MAX_FRAGMENTS > 0
            /* Keep the nearest MAX_FRAGMENTS sorted: insert, evicting the farthest when full. */
            if (n == MAX_FRAGMENTS && !KEY_LESS(d, pi, D[n - 1], P[n - 1])) continue;
            int j = min(n, MAX_FRAGMENTS - 1);
            while (j > 0 && KEY_LESS(d, pi, D[j - 1], P[j - 1])) {
                D[j] = D[j - 1];
                P[j] = P[j - 1];
                --j;
            }
            D[j] = d;
            P[j] = pi;
            LANE_I(filled, l) = min(n + 1, MAX_FRAGMENTS);
#else
            if (n < LANE_I(room, l)) {
                D[n] = d;
                P[n] = pi;
                LANE_I(filled, l) = n + 1;
            }
#endif
        }
    }
}

kernel __attribute__((reqd_work_group_size(TILE / VEC, TILE, 1)))
void fragment_next_layer(global const Prim* prims, global const int* tile_offsets, global const int* tile_counts,
                         global const int* tile_prims, int tile_list_capacity, int tiles_x, int width, int height,
                         float far, global const float* vis_depth, int layer,
                         global float* layer_depth, global int* layer_prim)
{
    const int px0 = get_global_id(0) * VEC, py = get_global_id(1);
    if (py >= height || px0 >= width) return;
    const int tile = get_group_id(1) * tiles_x + get_group_id(0);
    const int sx0 = px0 * 256 + 128, sy = py * 256 + 128;
    floatV prev_d = (floatV)(-INFINITY);
    intV prev_p = (intV)(-1);
    if (layer > 0)
        for (int l = 0; l < VEC && px0 + l < width; ++l) {
            LANE_F(prev_d, l) = layer_depth[py * width + px0 + l];
            LANE_I(prev_p, l) = layer_prim[py * width + px0 + l];
        }
    /* Classic peeling: every layer walks every prim of the tile (nothing says how many layers
     * a pixel has left), as the report's depth peeling re-renders the transparent geometry. */
    const floatV opaque = load_opaque(vis_depth, px0, py, width);
    floatV best_d = (floatV)INFINITY;
    intV best_p = (intV)(-1);
    const int start = tile_offsets[tile];
    const int end = min(start + tile_counts[tile], tile_list_capacity);
    for (int i = start; i < end; ++i) {
        const int pi = tile_prims[i];
        const Prim p = prims[pi];
        floatV depth;
        intV take = fragment_lanes(&p, sx0, sy, opaque, far, &depth);
        if (!ANY(take)) continue;
        const intV vpi = (intV)pi;
        take &= ((depth > prev_d) | ((depth == prev_d) & (vpi > prev_p)))
              & ((depth < best_d) | ((depth == best_d) & (vpi < best_p)));
        best_d = select(best_d, depth, take);
        best_p = select(best_p, vpi, take);
    }
    for (int l = 0; l < VEC && px0 + l < width; ++l) {
        const int q = py * width + px0 + l;
        layer_depth[q] = LANE_F(best_d, l);
        layer_prim[q] = LANE_I(best_p, l);
    }
}
