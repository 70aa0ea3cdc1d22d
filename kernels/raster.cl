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
 * sample their base-color alpha only for lanes they would win (screen-door BLEND prims compare it
 * with an ordered-dither threshold instead of the cutoff). No barriers, no local memory.
 *
 * Buffers: prims Prim[*]; tile_offsets/tile_counts int[tiles]; tile_prims int[list_capacity];
 *          scene uvs float[2V], triangles int[3T], materials Material[M]; textures (texture_vec.h).
 *          out: vis_depth float[out_offset + row·out_stride + column] (view depth, +inf = nothing:
 *          the camera passes offset 0 and stride W; a shadow map writes its region of the shadow
 *          atlas), vis_prim int[W·H] (-1; may be null: shadow maps keep only the depth).
 * ORTHO=1: orthographic prims (setup.cl) whose inv_w are vertex depths: depth = Σ e_k·d_k / area.
 * DEPTH_ONLY=1 (shadow maps): only the nearest depth is kept, so the visibility order's ties
 * (triangle id, prim index) are not tracked: the minimum of the same depths, bit-identical.
 * RROWS rows per work-item (CPUs: the tile's TILE rows; GPUs: 1): the work-item loads each prim
 * once, tests its bounding box once and walks only the rows of its run that the box spans, so a
 * small prim costs one test per tile column instead of one per run; the fragments each pixel
 * compares, and their order, are the same for any RROWS.
 * SAMPLES > 1 (the light pre-pass's msaa, docs/raster_contract.md §10): every pixel keeps a
 * nearest fragment per sample point P_s (samples.h), all from one walk of the prim list (a prim
 * is loaded and tested once for all samples), and vis_prim holds SAMPLES planes of W·H; the
 * setup and binning were widened by SAMPLE_SPREAD to keep prims that cover only a sample;
 * vis_depth is sample 0's.
 * Work-groups: (TILE/VEC, TILE/RROWS); global size = (tiles_x·TILE/VEC, tiles_y·TILE/RROWS).
 */
#pragma OPENCL FP_CONTRACT OFF
#include "alpha_mask.h"

#ifndef TILE
#define TILE 16
#endif
#ifndef DEPTH_ONLY
#define DEPTH_ONLY 0
#endif
#ifndef SAMPLES
#define SAMPLES 1        /* sample points per pixel: the msaa sub-samples (docs/raster_contract.md §10) */
#endif
#include "samples.h"
#ifndef RROWS
#define RROWS 1          /* rows per work-item, dividing TILE (clrender/passes/raster.py) */
#endif
#include "vec.h"
#include "coverage.h"


/* Screen-door transparency (docs/transparency.md): a BLEND fragment is kept where its alpha
 * reaches the threshold (r + 0.5) / 16 of its pixel, r a rank of the 4x4 Bayer matrix: every
 * 4x4 block keeps round(16·alpha) pixels, 17 opacity levels. Per material m the ranks rotate by
 * m and odd materials shift the pattern two rows, so overlapping layers of two materials keep
 * different pixels (over all pairs of materials 0..11 at alpha 1/4, 1/2, 3/4 the back layer
 * keeps at least 1/16 of the overlap; on average about alpha·(1 - alpha), as independent noise).
 * A transmissive (KHR_materials_transmission) fragment's alpha is scaled by Material.door_alpha =
 * 1 - transmission·(1 - metallic): it keeps the pixels it does not let through, shaded opaque. */
constant uchar BAYER4[16] = { 0, 8, 2, 10, 12, 4, 14, 6, 3, 11, 1, 9, 15, 7, 13, 5 };

static inline float screen_door_threshold(int px, int py, int material)
{
    const int rank = (BAYER4[((py + 2 * (material & 1)) & 3) * 4 + (px & 3)] + material) & 15;
    return ((float)rank + 0.5f) * (1.0f / 16.0f);
}

kernel __attribute__((reqd_work_group_size(TILE / VEC, TILE / RROWS, 1)))
void raster_tiles(global const Prim* prims, global const int* tile_offsets, global const int* tile_counts,
                  global const int* tile_prims, int list_capacity, int tiles_x,
                  int width, int height, float far,
                  global const float* uvs, global const int* triangles, global const Material* materials,
                  global const uint* texels,
                  global const TexInfo* tex_infos, global const TexLevel* tex_levels,
                  global const float* colors, int n_vertices, int has_colors,
                  global float* vis_depth, int out_offset, int out_stride, global int* vis_prim)
{
    const int px0 = get_global_id(0) * VEC, py0 = get_global_id(1) * RROWS;
    const int tile = get_group_id(1) * tiles_x + get_group_id(0);
    const int cx0 = px0 * 256 + 128, cy0 = py0 * 256 + 128;    /* first pixel centre of the run */
    const int cx_last = cx0 + (VEC - 1) * 256, cy_last = cy0 + (RROWS - 1) * 256;
    const Textures tx = { texels, tex_infos, tex_levels, colors, n_vertices, has_colors };

    floatV best_depth[SAMPLES][RROWS];
    intV best_tri[SAMPLES][RROWS], best_prim[SAMPLES][RROWS];
    for (int s = 0; s < SAMPLES; ++s)
        for (int r = 0; r < RROWS; ++r) {
            best_depth[s][r] = (floatV)INFINITY; best_tri[s][r] = (intV)INT_MAX; best_prim[s][r] = (intV)(-1);
        }
    const int start = tile_offsets[tile];
    const int end = min(start + tile_counts[tile], list_capacity);
    for (int i = start; i < end; ++i) {
        const int pi = tile_prims[i];
        const Prim p = prims[pi];
        const int min_x = min(min(p.x[0], p.x[1]), p.x[2]), max_x = max(max(p.x[0], p.x[1]), p.x[2]);
        const int min_y = min(min(p.y[0], p.y[1]), p.y[2]), max_y = max(max(p.y[0], p.y[1]), p.y[2]);
        if (cx_last + SAMPLE_SPREAD < min_x || cx0 - SAMPLE_SPREAD > max_x ||
            cy_last + SAMPLE_SPREAD < min_y || cy0 - SAMPLE_SPREAD > max_y) continue;
        for (int s = 0; s < SAMPLES; ++s) {
            const int sx0 = cx0 + SAMPLE_DX(s), sy0 = cy0 + SAMPLE_DY(s);     /* the run's sample points */
            if (SAMPLES > 1 && (sx0 + (VEC - 1) * 256 < min_x || sx0 > max_x ||
                                sy0 + (RROWS - 1) * 256 < min_y || sy0 > max_y)) continue;
            /* The rows r whose sample row sy0 + 256 r lies in [min_y, max_y]. */
            const int r0 = max(min_y - sy0 + 255, 0) / 256, r1 = min((max_y - sy0) / 256, RROWS - 1);
            for (int r = r0; r <= r1; ++r) {
                const int py = py0 + r;
                floatV depth;
                const intV inside_i = prim_cover_run_in(&p, sx0, sy0 + 256 * r, min_x, max_x, min_y, max_y, &depth);
                if (!ANY(inside_i)) continue;
#if DEPTH_ONLY
                intV wins = inside_i & (depth <= (floatV)far) & (depth < best_depth[s][r]);
#else
                intV wins = inside_i & (depth <= (floatV)far) &
                            ((depth < best_depth[s][r]) |
                             ((depth == best_depth[s][r]) & (((intV)p.tri < best_tri[s][r]) |
                                                             (((intV)p.tri == best_tri[s][r]) & ((intV)pi < best_prim[s][r])))));
#endif
                if (!ANY(wins)) continue;
                if (p.flags & PRIM_MASKED) {
                    const Material m = materials[p.material];
                    floatV alpha = prim_alpha_run(&p, sx0, sy0 + 256 * r, m, uvs, triangles, tx, wins);
                    floatV cutoff = m.alpha_cutoff;
                    if (p.flags & PRIM_DITHER) {
                        /* a transmissive surface keeps what it does not let through (door_alpha;
                         * 1 otherwise, and alpha · 1 is alpha: BLEND dithers as before) */
                        if ((m.flags & MAT_TRANSMISSION) && !(m.flags & MAT_TX_ALPHA)) {   /* coverage, not alpha */
                            if (m.flags & MAT_MASK) alpha = select((floatV)1.0f, (floatV)0.0f, alpha < cutoff);
                            else alpha = 1.0f;
                        }
                        alpha = alpha * m.door_alpha;
                        for (int l = 0; l < VEC; ++l) LANE_F(cutoff, l) = screen_door_threshold(px0 + l, py, p.material);
                    }
                    wins &= !(alpha < cutoff);             /* as the scalar test: NaN alpha keeps the fragment */
                }
                best_depth[s][r] = select(best_depth[s][r], depth, wins);
#if !DEPTH_ONLY
                best_tri[s][r] = select(best_tri[s][r], (intV)p.tri, wins);
                best_prim[s][r] = select(best_prim[s][r], (intV)pi, wins);
#endif
            }
        }
    }
    for (int r = 0; r < RROWS && py0 + r < height; ++r) {
        const int py = py0 + r;
        for (int l = 0; l < VEC; ++l) {
            int px = px0 + l;
            if (px < width) {
                vis_depth[out_offset + py * out_stride + px] = LANE_F(best_depth[0][r], l);
#if !DEPTH_ONLY
                if (vis_prim)
                    for (int s = 0; s < SAMPLES; ++s) vis_prim[s * width * height + py * width + px] = LANE_I(best_prim[s][r], l);
#endif
            }
        }
    }
}
