/* forward_shade.cl: the light-indexed pipeline's forward pass (report V.3, Trebilco's
 * Light-Indexed Deferred lighting; docs/variants.md): the second geometry pass's visible
 * fragments shaded with their tile's light list and their material directly.
 *
 * Algorithm: pass 1 rasterized depth only (gbuffer.cl writes the depth and id planes); the
 * tiled light culling made the per-tile light index lists from that depth; the raster then ran
 * again and this kernel takes, per pixel, the fragment it kept. One work-group per LTILE×LTILE
 * light tile, a run of VEC adjacent pixels per work-item (vec.h). Per lane: the surface
 * (surface_vec.h), packed into the G-buffer's remaining planes as AOVs (albedo/specular,
 * normal/power, velocity: gbuffer_pack.h, the bits gbuffer.cl would write) and decoded back,
 * so the light loop (lighting.h, the tile's list, the sun, shadow maps) lights the same
 * quantized surface as deferred shading does, with the same arithmetic:
 *     color = albedo·(ambient + diffuse) + specular;  background: 0.
 * No SSAO (it needs the normals of neighbouring pixels, which this pipeline never stores).
 * The light count and shadow visibility AOVs are written as shade.cl does.
 *
 * Buffers: vis_prim int[W·H], vis_depth float[W·H] (the second raster's); prims Prim[*]; scene
 *          buffers and textures; prev_view_proj float[16], prev_positions float[3V]; camera,
 *          lights, tile lists, shadow atlas and views, sun: as shade.cl; srgb_lut float[256],
 *          srgb_encode float2[4096]. out: color float[3][W·H]; gbuffer uint[GB_PLANES][W·H]
 *          (GB_WRITE planes); light_count int[W·H]; shadow_out float[planes][W·H]; light_pairs
 *          int[2][W·H] (pairs evaluated, useful: as shade.cl).
 * Work-groups: (LTILE/VEC, LTILE); global size = (tiles_x·LTILE/VEC, tiles_y·LTILE); no barriers.
 */
#pragma OPENCL FP_CONTRACT OFF
#include "structs.h"
#include "gbuffer.h"

#ifndef LTILE
#define LTILE 16
#endif
#ifndef GB_WRITE
#define GB_WRITE ((1 << GB_ALBEDO_PLANE) | (1 << GB_NORMAL_PLANE) | (1 << GB_VELOCITY_PLANE))
#endif
#include "lighting.h"
#include "gbuffer_pack.h"
#include "gbuffer_decode.h"
#include "ambient.h"

kernel __attribute__((reqd_work_group_size(LTILE / VEC, LTILE, 1)))
void forward_shade(global const int* vis_prim, global const float* vis_depth, int width, int height, float far,
                   SCENE_PARAMS(prims), constant float2* srgb_encode,
                   global const float* prev_view_proj, global const float* prev_positions, int has_prev,
                   global const float* camera, global const Light* lights, int n_lights, float ambient,
                   global const int* tile_light_offsets, global const int* tile_light_counts,
                   global const int* tile_lights, int list_capacity, int tiles_x,
                   global const float* shadow_atlas, int atlas_stride, global const ShadowView* shadow_views,
                   float shadow_bias, float shadow_slope_bias, float shadow_normal_offset,
                   int has_sun, global const float* sun, int sun_cascades, int spot_view0, int spot_plane0,
                   int has_env, int env_background, ENV_PARAMS,
                   global float* color, global uint* gbuffer, global int* light_count, global float* shadow_out,
                   global int* light_pairs)
{
    const int px0 = get_global_id(0) * VEC, py = get_global_id(1);
    if (py >= height || px0 >= width) return;
    const int npix = width * height;
    const int p0 = py * width + px0;
    const int valid = min(VEC, width - px0);
    const int tile = get_group_id(1) * tiles_x + get_group_id(0);

    const intV pidx = as_intV(load_plane((global const uint*)vis_prim, p0, valid, 0xffffffffu));
    intV fg = pidx >= 0;
#if VEC == 1
    fg = fg ? 1 : 0;
#endif
    uintV planes[GB_PLANES];
    gbuffer_background(planes);
    floatV cr = 0.0f, cg = 0.0f, cb = 0.0f;
    const EnvMaps envmaps = ENV_INIT;
    intV evaluated = 0, useful = 0;           /* (pixel, light) pairs: walked, reached (light_pairs) */
    const int2 range = tile_light_range(tile_light_offsets, tile_light_counts, list_capacity, tile, n_lights);
    const int first = range.x, count = range.y;
    if (ANY(fg)) {
        const SceneV scene = SCENE_INIT(prims);
        const intV px = px0 + LANES, pyv = (intV)py;
        const SurfaceV sf = surface_at(&scene, select((intV)0, pidx, fg), fg, px, pyv);
        const floatV z = as_floatV(load_plane((global const uint*)vis_depth, p0, valid, 0u));
        uintV packed[GB_PLANES];
        gbuffer_pack(&sf, z / far, pack_velocity(&sf, prev_view_proj, prev_positions, has_prev, width, height, px, pyv),
                     srgb_encode, packed);
        const intV ufg = fg != 0;
        for (int i = 0; i < GB_PLANES; ++i) planes[i] = select(planes[i], packed[i], ufg);

        /* Decoded back, as shade.cl reads them. */
        const intV gltf = gltf_lanes(sf.mat_flags, fg);
        const LitPointV s = decode_lit_point(planes[GB_NORMAL_PLANE], planes[GB_LINEAR_DEPTH_PLANE], fg, far, gltf);
        floatV ar, ag, ab, spec_i;
        decode_albedo(planes[GB_ALBEDO_PLANE], srgb_lut, &ar, &ag, &ab, &spec_i);
        const ViewPointV v = view_point(camera, width, height, px0, py, s.depth);
        const BrdfV m = brdf_inputs(gltf, spec_i, s.spec_p, s.nx, s.ny, s.nz, v.vx, v.vy, v.vz);
        const LightEnv env = LIGHT_ENV_INIT;
        floatV dr = 0.0f, dg = 0.0f, db = 0.0f, sr = 0.0f, sg = 0.0f, sb = 0.0f, tr = 0.0f, tg = 0.0f, tb = 0.0f;
        accumulate_lights_counted(&env, first, count, fg, 0, 0, &evaluated, &useful, v.px, v.py, v.pz, s.nx, s.ny,
                                  s.nz, v.vx, v.vy, v.vz, &m, s.depth, px, py, shadow_out, p0, valid,
                                  npix, &dr, &dg, &db, &sr, &sg, &sb, &tr, &tg, &tb);
        const SurfaceExtrasV x = material_extras(planes[GB_EMISSIVE_PLANE], sf.mat, fg, materials, srgb_lut);
        const AmbientV amb = ambient_light(has_env, &envmaps, &m, (floatV)ambient, 1.0f, s.nx, s.ny, s.nz, v.vx, v.vy,
                                           v.vz);
        compose_lit(&m, fg, ar, ag, ab, spec_i, &amb, 1, x.er, x.eg, x.eb, x.occlusion, x.unlit,
                    dr, dg, db, sr, sg, sb, tr, tg, tb, &cr, &cg, &cb);
    }
    if (has_env && env_background && ANY(!fg)) {   /* the environment behind the geometry */
        floatV vx, vy, vz;
        view_vectors(camera, width, height, px0 + LANES, (intV)py, &vx, &vy, &vz);
        environment_background(1, 1, &envmaps, fg, vx, vy, vz, &cr, &cg, &cb);
    }
    gbuffer_store(gbuffer, npix, p0, valid, planes);
    store_plane(color, p0, valid, cr);
    store_plane(color + npix, p0, valid, cg);
    store_plane(color + 2 * npix, p0, valid, cb);
    store_light_counts(light_count, light_pairs, npix, p0, valid, count, evaluated, useful);
}
