/* gbuffer.cl: resolve the visibility buffer into the packed G-buffer.
 *
 * Algorithm: each work-item owns VEC consecutive pixels (see vec.h). Per lane it takes the
 * winning prim; surface_vec.h evaluates, as VEC-wide vector math, its surface there (the
 * barycentrics from the prim's edge functions at the pixel center and its right and lower
 * neighbours, the interpolated world normal flipped on visible back faces, a trilinear
 * base-color sample with the LOD from the derivatives, the material's specular terms: the
 * same code shades transparent fragments, forward.h); then linear depth = view depth / far
 * and the motion: the surface point interpolated from the previous frame's vertex positions
 * (prev_positions: the scene's own positions unless objects moved, Scene.set_transform) and
 * projected by the previous frame's view-projection. Everything is packed per
 * the layout table (clrender/abi/gbuffer.py, kernels/gbuffer.h; gbuffer_pack.h).
 * GB_WRITE (bit i: plane i) selects the planes written: all for the deferred pipeline; the
 * light pre-pass's thin G-buffer skips albedo/specular intensity and emission/occlusion (built
 * with SURFACE_TEXTURES 0 and SURFACE_EXTRAS 0: none of those textures is read); light-indexed
 * writes depth and id only, and evaluates no surface.
 *
 * Buffers: vis_depth float[W·H], vis_prim int[W·H]; the scene (SCENE_PARAMS, surface_vec.h:
 *          prims Prim[*], positions/normals float[3V], uv sets float[K][2V], triangles int[3T],
 *          materials Material[M], textures, tangents/colors float[4V], decode tables float[512]);
 *          srgb_encode float2[4096]; prev_view_proj float[16], prev_positions float[3V].
 *          out: gbuffer uint[GB_PLANES][H·W].
 * Work-groups: 2-D, work-item (i, y) covers pixels [i·VEC, i·VEC + VEC) of row y (a run never
 * crosses a row); a group is a GB_TILE_W × GB_TILE_H block of pixels (clrender/passes/gbuffer.py),
 * so neighbouring rows' texture footprints are fetched while still in cache; no barriers.
 */
#pragma OPENCL FP_CONTRACT OFF
#include "structs.h"
#include "gbuffer.h"
#include "vec.h"

#include "gbuffer_pack.h"

kernel void gbuffer_resolve(global const float* vis_depth, global const int* vis_prim, int width, int height,
                            float far, SCENE_PARAMS(prims), constant float2* srgb_encode,
                            global const float* prev_view_proj, global const float* prev_positions, int has_prev,
                            global uint* gbuffer)
{
    const int npix = width * height;
    const int px0 = get_global_id(0) * VEC, row = get_global_id(1);
    if (px0 >= width || row >= height) return;
    const int pix0 = row * width + px0;
    const int valid = min(VEC, width - px0);

    /* The winning prims of the run (background lanes read prim 0 and are masked out). */
    const intV px = px0 + LANES, py = row;
    intV pidx;
    floatV depth;
    if (valid == VEC) {
        pidx = vloadV(0, vis_prim + pix0);
        depth = vloadV(0, vis_depth + pix0);
    } else {
        pidx = -1; depth = INFINITY;
        for (int l = 0; l < valid; ++l) { LANE_I(pidx, l) = vis_prim[pix0 + l]; LANE_F(depth, l) = vis_depth[pix0 + l]; }
    }
    intV fg = pidx >= 0;
#if VEC == 1
    fg = fg ? 1 : 0;
#endif
    intV w = select((intV)0, pidx, fg);
    uintV planes[GB_PLANES];            /* background unless a lane has a prim */
    gbuffer_background(planes);
    if (ANY(fg)) {
        uintV planes_fg[GB_PLANES];
#if GB_WRITE & ~((1 << GB_LINEAR_DEPTH_PLANE) | (1 << GB_TRIANGLE_ID_PLANE))
        const SceneV scene = SCENE_INIT(prims);
        const SurfaceV sf = surface_at(&scene, w, fg, px, py);
        const uintV vel = pack_velocity(&sf, prev_view_proj, prev_positions, has_prev, width, height, px, py);
        gbuffer_pack(&sf, depth / far, vel, srgb_encode, planes_fg);
#else                                   /* depth and id only (light-indexed): no surface */
        for (int i = 0; i < GB_PLANES; ++i) planes_fg[i] = 0;
        GB_PUT(planes_fg, LINEAR_DEPTH, as_uintV(depth / far));
        GB_PUT(planes_fg, TRIANGLE_ID, as_uintV(GATHER_MS(intV, prims, w, tri)));
#endif
        uintV ufg = as_uintV(fg);
#if VEC == 1
        ufg = fg ? 0xffffffffu : 0u;
#endif
        for (int i = 0; i < GB_PLANES; ++i) planes[i] = select(planes[i], planes_fg[i], ufg);
    }
    gbuffer_store(gbuffer, npix, pix0, valid, planes);
}
