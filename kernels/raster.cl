/* raster.cl: fine rasterization of binned prims into a visibility buffer.
 *
 * Algorithm (docs/raster_contract.md §5-7): one work-group per TILE×TILE screen tile; each
 * work-item owns a run of VEC horizontally adjacent pixels (VEC = 1 on GPUs: one pixel per
 * work-item; 8 or 16 on CPUs, where explicit vectors replace the implicit vectorization that
 * PoCL cannot apply across a data-dependent loop). Every work-item walks its tile's prim list,
 * skips prims whose bounding box misses its run, evaluates the three integer edge functions
 * at its pixel centers with the top-left rule (32-bit lanes wherever the values fit, else
 * exact doubles on CPUs or 64-bit integers), computes the perspective-correct view depth,
 * and keeps the nearest fragment (ties: lower triangle id, then lower prim index). Alpha-masked prims
 * sample their base-color alpha only for lanes they would win. No barriers, no local memory.
 *
 * Buffers: prims Prim[*]; tile_offsets/tile_counts int[tiles]; tile_prims int[list_capacity];
 *          scene uvs float[2V], triangles int[3T], materials Material[M]; textures (texture.h).
 *          out: vis_depth float[out_offset + row·out_stride + column] (view depth, +inf = nothing:
 *          the camera passes offset 0 and stride W; a shadow map writes its region of the shadow
 *          atlas), vis_prim int[W·H] (-1; may be null: shadow maps keep only the depth).
 * ORTHO=1: orthographic prims (setup.cl) whose inv_w are vertex depths: depth = Σ e_k·d_k / area.
 * Work-groups: (TILE/VEC, TILE); global size = (tiles_x·TILE/VEC, tiles_y·TILE).
 */
#pragma OPENCL FP_CONTRACT OFF
#include "surface.h"

#ifndef TILE
#define TILE 16
#endif
#include "vec.h"

/* Prims whose bounding box is at most SMALL_EXTENT (24.8 units) on both axes have exact
 * 32-bit edge functions on any run inside their tile range: |d| < 2^14, |offset| < 2^15.
 * That common case needs no 64-bit arithmetic at all (scalar 64-bit math is slow on GPUs). */
#define SMALL_EXTENT (64 * 256)

kernel __attribute__((reqd_work_group_size(TILE / VEC, TILE, 1)))
void raster_tiles(global const Prim* prims, global const int* tile_offsets, global const int* tile_counts,
                  global const int* tile_prims, int list_capacity, int tiles_x,
                  int width, int height, float far,
                  global const float* uvs, global const int* triangles, global const Material* materials,
                  global const uint* texels, constant float* srgb_lut,
                  global const TexInfo* tex_infos, global const TexLevel* tex_levels,
                  global float* vis_depth, int out_offset, int out_stride, global int* vis_prim)
{
    const int px0 = get_global_id(0) * VEC, py = get_global_id(1);
    const int tile = get_group_id(1) * tiles_x + get_group_id(0);
    const int sx0 = px0 * 256 + 128, sy = py * 256 + 128;     /* first sample of the run */
    const int sx_last = sx0 + (VEC - 1) * 256;
    const Textures tx = { texels, srgb_lut, tex_infos, tex_levels };

    floatV best_depth = (floatV)INFINITY;
    intV best_tri = (intV)INT_MAX, best_prim = (intV)(-1);
    const int start = tile_offsets[tile];
    const int end = min(start + tile_counts[tile], list_capacity);
    for (int i = start; i < end; ++i) {
        const int pi = tile_prims[i];
        const Prim p = prims[pi];
        const int min_x = min(min(p.x[0], p.x[1]), p.x[2]), max_x = max(max(p.x[0], p.x[1]), p.x[2]);
        const int min_y = min(min(p.y[0], p.y[1]), p.y[2]), max_y = max(max(p.y[0], p.y[1]), p.y[2]);
        if (sy < min_y || sy > max_y || sx_last < min_x || sx0 > max_x) continue;

        /* E_k(lane) = base_k + step_k · lane; inside when E_k > thr_k (top-left: thr = -1). */
        intV inside_i;
        floatV e_f[3];
        if (max_x - min_x <= SMALL_EXTENT && max_y - min_y <= SMALL_EXTENT) {
            intV ok = (intV)(-1);
            for (int k = 0; k < 3; ++k) {
                int k1 = (k + 1) % 3;
                int dx = p.x[k1] - p.x[k], dy = p.y[k1] - p.y[k];
                int base = dx * (sy - p.y[k]) - dy * (sx0 - p.x[k]);
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
                long dx = p.x[k1] - p.x[k], dy = p.y[k1] - p.y[k];
                long base = dx * (long)(sy - p.y[k]) - dy * (long)(sx0 - p.x[k]);
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
        if (!ANY(inside_i)) continue;

        floatV num = (e_f[1] * (floatV)p.inv_w[0] + e_f[2] * (floatV)p.inv_w[1]) + e_f[0] * (floatV)p.inv_w[2];
#if ORTHO
        floatV depth = num / (floatV)((float)p.area);
#else
        floatV depth = (floatV)((float)p.area) / num;
#endif
        intV wins = inside_i & (depth <= (floatV)far) &
                    ((depth < best_depth) |
                     ((depth == best_depth) & (((intV)p.tri < best_tri) |
                                               (((intV)p.tri == best_tri) & ((intV)pi < best_prim)))));
        if (!ANY(wins)) continue;
        if (p.flags & PRIM_MASKED) {
            const Material m = materials[p.material];
            for (int l = 0; l < VEC; ++l) {
                if (LANE_I(wins, l) && px0 + l < width &&
                    surface_base_color(&p, px0 + l, py, m, uvs, triangles, tx).w < m.alpha_cutoff)
                    LANE_I(wins, l) = 0;
            }
        }
        best_depth = select(best_depth, depth, wins);
        best_tri = select(best_tri, (intV)p.tri, wins);
        best_prim = select(best_prim, (intV)pi, wins);
    }
    if (py >= height) return;
    for (int l = 0; l < VEC; ++l) {
        int px = px0 + l;
        if (px < width) {
            vis_depth[out_offset + py * out_stride + px] = LANE_F(best_depth, l);
            if (vis_prim) vis_prim[py * width + px] = LANE_I(best_prim, l);
        }
    }
}
