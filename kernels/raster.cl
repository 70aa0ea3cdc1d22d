/* raster.cl: fine rasterization of binned prims into a visibility buffer.
 *
 * Algorithm (docs/raster_contract.md §5-7): one work-group per TILE×TILE screen tile, one
 * work-item per pixel. Every work-item walks its tile's prim list in the same order (so PoCL
 * vectorizes the loop across the tile's pixels), evaluates the three integer edge functions at
 * its pixel center with the top-left rule, computes the perspective-correct view depth, and
 * keeps the nearest fragment (ties: lower triangle id, then lower prim index). Alpha-masked
 * prims sample their base color alpha only when they would win. No barriers, no local memory.
 *
 * Buffers: prims Prim[*]; tile_offsets/tile_counts int[tiles]; tile_prims int[list_capacity];
 *          scene uvs float[2V], triangles int[3T], materials Material[M]; textures (texture.h).
 *          out: vis_depth float[W·H] (view depth, +inf = nothing), vis_prim int[W·H] (-1).
 * Work-groups: (TILE, TILE), global size = tiles × TILE.
 */
#pragma OPENCL FP_CONTRACT OFF
#include "surface.h"

#ifndef TILE
#define TILE 16
#endif

kernel __attribute__((reqd_work_group_size(TILE, TILE, 1)))
void raster_tiles(global const Prim* prims, global const int* tile_offsets, global const int* tile_counts,
                  global const int* tile_prims, int list_capacity, int tiles_x,
                  int width, int height, float far,
                  global const float* uvs, global const int* triangles, global const Material* materials,
                  global const uint* texels, constant float* srgb_lut,
                  global const TexInfo* tex_infos, global const TexLevel* tex_levels,
                  global float* vis_depth, global int* vis_prim)
{
    const int px = get_global_id(0), py = get_global_id(1);
    const int tile = get_group_id(1) * tiles_x + get_group_id(0);
    const long sx = (long)px * 256 + 128, sy = (long)py * 256 + 128;
    const Textures tx = { texels, srgb_lut, tex_infos, tex_levels };

    float best_depth = INFINITY;
    int best_tri = INT_MAX, best_prim = -1;
    const int start = tile_offsets[tile];
    const int end = min(start + tile_counts[tile], list_capacity);
    for (int i = start; i < end; ++i) {
        const int pi = tile_prims[i];
        const Prim p = prims[pi];
        long e[3];
        prim_edges(&p, sx, sy, e);
        bool inside = true;
        for (int k = 0; k < 3; ++k)
            inside &= e[k] > 0 || (e[k] == 0 && edge_is_top_left(&p, k));
        if (!inside) continue;
        float num = ((float)e[1] * p.inv_w[0] + (float)e[2] * p.inv_w[1]) + (float)e[0] * p.inv_w[2];
        float depth = (float)p.area / num;
        bool wins = depth < best_depth ||
                    (depth == best_depth && (p.tri < best_tri || (p.tri == best_tri && pi < best_prim)));
        if (!wins || depth > far) continue;
        if (p.flags & PRIM_MASKED) {
            Material m = materials[p.material];
            if (surface_base_color(&p, px, py, m, uvs, triangles, tx).w < m.alpha_cutoff) continue;
        }
        best_depth = depth;
        best_tri = p.tri;
        best_prim = pi;
    }
    if (px < width && py < height) {
        vis_depth[py * width + px] = best_depth;
        vis_prim[py * width + px] = best_prim;
    }
}
