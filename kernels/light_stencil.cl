/* light_stencil.cl: per-pixel light masks over the tile lists (report V.1, the stencil
 * variant: front faces of a light volume increment, back faces decrement, and only pixels
 * inside the volume are lit; done exactly, per pixel, instead of by rasterizing volumes).
 *
 * Algorithm: `light_stencil`: one work-group per LTILE×LTILE light tile (as shade.cl); each
 * work-item takes a run of VEC adjacent pixels, rebuilds their world positions from the
 * G-buffer's linear depth exactly as shade.cl does (lighting.h pixel_positions), and for every
 * entry k of its tile's list (light_cull.cl) sets bit k%32 of word k/32 where the light reaches
 * the pixel (lighting.h light_reach: d² < r², and inside a spot's outer cone, the same float
 * arithmetic as shade.cl's light loop). Background pixels get no bits. shade.cl (STENCIL 1)
 * then walks only the set bits. Unlike a rasterized stencil this has no trouble with the eye
 * inside a volume and needs no closed mesh.
 * `stencil_words_needed`: one work-item per tile, the words its list needs, ceil(count/32),
 * and their maximum over tiles (atomic_max on one int): the words per pixel the frame needs.
 * With more than `stencil_words` the kernel writes the first `stencil_words` words, the host
 * grows the buffer and renders again (never a silent cap).
 *
 * Buffers: gbuffer uint[GB_PLANES][H·W]; camera float[16] (eye, F, R·tan_x, U·tan_y); lights
 *          Light[n]; tile_light_offsets/counts int[tiles], tile_lights int[list_capacity];
 *          stencil uint[stencil_words][H·W] (word-major planes: word w of pixel p at
 *          w·H·W + p; a pixel's words past its tile's ceil(count/32) are not written);
 *          words_needed int[1] (zeroed by the host each frame).
 * Work-groups: light_stencil (LTILE/VEC, LTILE), global (tiles_x·LTILE/VEC, tiles_y·LTILE);
 *          stencil_words_needed 1-D, any size. No local memory.
 */
#pragma OPENCL FP_CONTRACT OFF
#include "structs.h"
#include "gbuffer.h"

#ifndef LTILE
#define LTILE 16
#endif
#include "lighting.h"

kernel __attribute__((reqd_work_group_size(LTILE / VEC, LTILE, 1)))
void light_stencil(global const uint* gbuffer, int width, int height, float far, global const float* camera,
                   global const Light* lights, global const int* tile_light_offsets,
                   global const int* tile_light_counts, global const int* tile_lights, int list_capacity,
                   int tiles_x, int stencil_words, global uint* stencil)
{
    const int px0 = get_global_id(0) * VEC, py = get_global_id(1);
    if (py >= height || px0 >= width) return;
    const int npix = width * height;
    const int p0 = py * width + px0;
    const int valid = min(VEC, width - px0);
    const int tile = get_group_id(1) * tiles_x + get_group_id(0);

    /* The G-buffer's depth and the position on the view ray, as shade.cl computes them. */
    intV tri = as_intV(load_plane(gbuffer + GB_TRIANGLE_ID_PLANE * npix, p0, valid, 0xffffffffu));
    intV fg = tri >= 0;
    floatV lin = as_floatV(load_plane(gbuffer + GB_LINEAR_DEPTH_PLANE * npix, p0, valid, 0u));
    floatV depth = select((floatV)0.0f, lin * far, fg);
    floatV dx, dy, dz, px, py_, pz;
    pixel_positions(camera, width, height, px0, py, depth, &dx, &dy, &dz, &px, &py_, &pz);

    const int first = tile_light_offsets[tile];
    const int count = max(min(tile_light_counts[tile], list_capacity - first), 0);
    const int words = min((count + 31) / 32, stencil_words);
    const int lit = ANY(fg);
    for (int w = 0; w < words; ++w) {
        uintV bits = 0u;
        const int n = min(32, count - 32 * w);
        for (int j = 0; lit && j < n; ++j) {
            const Light lt = lights[tile_lights[first + 32 * w + j]];
            bits |= select((uintV)0u, (uintV)(1u << j), fg & light_reach(&lt, px, py_, pz));
        }
        global uint* plane = stencil + w * npix;
        if (valid == VEC) {
            vstoreV(bits, 0, plane + p0);
        } else {
            for (int l = 0; l < valid; ++l) plane[p0 + l] = (uint)LANE_I(bits, l);
        }
    }
}

kernel void stencil_words_needed(global const int* tile_light_counts, int n_tiles, global int* words_needed)
{
    const int t = get_global_id(0);
    if (t >= n_tiles) return;
    const int words = (tile_light_counts[t] + 31) / 32;
    if (words > 0) atomic_max(words_needed, words);
}
